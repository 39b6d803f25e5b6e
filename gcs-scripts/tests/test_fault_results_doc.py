"""docs/fault-results.md is what its generator writes: scripts/fault_results_doc flies every fault experiment
again (default gains, the committed tuned gains, the rotor-loss sweep and its tuned variants) and must print
the committed document byte for byte, so a hand edit, a stale table or a changed generator fails here."""

import subprocess

from sitl_harness import ROOT, binary


def test_docs_fault_results_md_is_byte_for_byte_what_fault_results_doc_prints_from_fresh_runs(tmp_path):
    sitl = binary("sitl")
    run = subprocess.run(
        [str(ROOT / "scripts" / "fault_results_doc"), str(sitl), str(tmp_path)],
        cwd=ROOT,
        capture_output=True,
        text=True,
        timeout=900,
    )
    assert run.returncode == 0, run.stderr[-3000:]
    committed = (ROOT / "docs" / "fault-results.md").read_text()
    generated = run.stdout
    if generated != committed:
        diff = [
            f"line {i + 1}:\n  docs:      {a[:300]}\n  generated: {b[:300]}"
            for i, (a, b) in enumerate(zip(committed.splitlines(), generated.splitlines(), strict=False))
            if a != b
        ]
        raise AssertionError(
            "docs/fault-results.md is stale or was edited by hand (regenerate it with scripts/reproduce):\n"
            + "\n".join(diff[:10])
            + (f"\n({len(committed.splitlines())} lines in docs, {len(generated.splitlines())} generated)")
        )
