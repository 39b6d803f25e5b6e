"""docs/fault-results.md is what its generator writes: scripts/fault_results_doc flies every fault experiment
again (default gains, the committed tuned gains, the rotor-loss sweep and its tuned variants) and must print
the committed document byte for byte, so a hand edit, a stale table or a changed generator fails here."""

from sitl_harness import assert_generated_doc


def test_docs_fault_results_md_is_byte_for_byte_what_fault_results_doc_prints_from_fresh_runs(tmp_path):
    assert_generated_doc("fault_results_doc", "fault-results.md", tmp_path)
