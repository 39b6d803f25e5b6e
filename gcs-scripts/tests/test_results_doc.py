"""docs/results.md is what its generator writes: scripts/results_doc flies every experiment again (and the
paper's scenarios with the committed tuned gains) and must print the committed document byte for byte, so
a hand edit, a stale table or a changed generator fails here."""

from sitl_harness import assert_generated_doc


def test_docs_results_md_is_byte_for_byte_what_results_doc_prints_from_fresh_runs(tmp_path):
    assert_generated_doc("results_doc", "results.md", tmp_path)
