"""The verdict rules of scripts/results_table.py: each comes out "met" only where the claim holds, "not met"
where it fails, and never holds vacuously (a 0 against a 0 is "both within band")."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("results_table", ROOT / "scripts" / "results_table.py")
assert _spec is not None and _spec.loader is not None
rt = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(rt)

MET, NOT_MET, WITHIN_BAND = rt.MET, rt.NOT_MET, rt.WITHIN_BAND


def test_overshoot_third_is_met_at_a_third_and_not_met_above_it():
    assert rt.rule_overshoot_third([(0.0, 3.1), (1.0, 3.0)]) == MET
    assert rt.rule_overshoot_third([(0.0, 3.1), (1.1, 3.0)]) == NOT_MET
    assert rt.rule_overshoot_third([(5.0, 2.0)]) == NOT_MET


def test_overshoot_third_of_two_zeros_is_within_band_not_met():
    assert rt.rule_overshoot_third([(0.0, 0.0), (0.1, 0.4)]) == WITHIN_BAND
    # CA within the band and ACO outside it: ACO is worse, whatever the ratio.
    assert rt.rule_overshoot_third([(0.6, 0.0)]) == NOT_MET


def test_gust_recovery_needs_aco_within_5_s_and_ca_half_as_slow_again():
    assert rt.rule_gust_recovery(2.4, 6.6, 0.5, 1.5) == MET
    assert rt.rule_gust_recovery(2.4, 3.0, 0.5, 1.5) == NOT_MET
    assert rt.rule_gust_recovery(5.5, 9.0, 0.5, 1.5) == NOT_MET
    assert rt.rule_gust_recovery(2.4, None, 0.5, 1.5) == MET
    assert rt.rule_gust_recovery(None, 6.6, 0.5, 1.5) == NOT_MET


def test_gust_recovery_of_zero_is_judged_on_iae_or_is_within_band():
    # ACO never left the band: a 0 s recovery against anything is no verdict by itself; the IAE decides.
    assert rt.rule_gust_recovery(0.0, 3.7, 0.20, 0.90) == MET
    assert rt.rule_gust_recovery(0.0, 3.7, 0.70, 0.90) == NOT_MET
    assert rt.rule_gust_recovery(0.0, 0.0, 0.20, 0.90) == WITHIN_BAND


def test_settles_faster_needs_every_pair_and_aco_settling():
    assert rt.rule_settles_faster([(2.4, 5.9), (2.9, 5.8)], 2.5) == MET
    assert rt.rule_settles_faster([(2.4, 5.9), (2.9, 2.8)], 2.5) == NOT_MET
    assert rt.rule_settles_faster([(None, None)], 2.5) == NOT_MET
    assert rt.rule_settles_faster([(2.4, None)], 2.5) == MET


def test_half_overshoot_and_faster_is_not_met_on_the_papers_roll_pitch_numbers_and_within_band_when_all_zero():
    # docs/experiments.md's numbers: both at 0-0.6 % overshoot, settling within 0.25 s of each other.
    pairs = [
        ((0.0, 1.22), (0.0, 1.10)),
        ((0.1, 0.86), (0.0, 1.11)),
        ((0.0, 1.13), (0.4, 0.92)),
        ((0.0, 0.82), (0.6, 0.95)),
    ]
    assert rt.rule_half_overshoot_and_faster(pairs) == NOT_MET
    assert rt.rule_half_overshoot_and_faster([((0.0, 1.0), (0.1, 2.5))]) == WITHIN_BAND
    assert rt.rule_half_overshoot_and_faster([((1.0, 1.0), (4.0, 2.5))]) == MET
    assert rt.rule_half_overshoot_and_faster([((1.0, 1.0), (4.0, 1.5))]) == NOT_MET


def test_lower_is_never_met_over_a_baseline_without_safe_gains_nor_without_aco():
    assert rt.rule_lower(0.5, [0.9, 0.7]) == MET
    assert rt.rule_lower(0.8, [0.9, 0.7]) == NOT_MET
    # A baseline without safe gains cannot be beaten or lost to: the claim "against each" is not judged,
    # never met over the others alone.
    assert rt.rule_lower(0.5, [None, 0.7]) == rt.NOT_JUDGED
    assert rt.rule_lower(0.5, [None, None]) == rt.NOT_JUDGED
    # Beaten by a baseline that has gains: not met, whatever the missing one would do.
    assert rt.rule_lower(0.8, [None, 0.7]) == NOT_MET
    assert rt.rule_lower(0.5, []) == "no tuned baseline"
    assert rt.rule_lower(None, [0.9]) == NOT_MET


def test_tunings_under_different_budgets_or_seeds_are_refused_not_compared(tmp_path):
    import json
    import shutil

    import pytest

    for ctrl in ("aco", "pid"):
        shutil.copytree(ROOT / "docs" / "tuning" / ctrl, tmp_path / ctrl)
    dirs = [str(tmp_path / "aco"), str(tmp_path / "pid")]
    assert any("Tuned against tuned" in line for line in rt.tuned_tables(dirs))
    result = json.loads((tmp_path / "pid" / "result.json").read_text())
    result["budget"] = 200
    (tmp_path / "pid" / "result.json").write_text(json.dumps(result))
    with pytest.raises(SystemExit, match="differ in budget or seeds"):
        rt.tuned_tables(dirs)


def test_corners_needs_aco_no_worse_at_every_turning_point_and_is_not_met_on_our_figure8():
    # docs/results.md's first corners, feed-forward: ACO runs 0.17 m past a corner CA cuts.
    assert rt.rule_corners([(0.170, 1.70), (0.014, 0.0)], [(0.0, None), (0.027, 0.07)]) == NOT_MET
    # ACO overshoots less but returns later at one point: not met.
    assert rt.rule_corners([(0.02, 1.0), (0.02, 2.0)], [(0.10, 1.5), (0.10, 1.5)]) == NOT_MET
    # ACO never back where CA is: not met; CA never back where ACO is: ACO sooner.
    assert rt.rule_corners([(0.02, None)], [(0.10, 9.0)]) == NOT_MET
    assert rt.rule_corners([(0.02, 1.0), (0.005, 0.0)], [(0.10, None), (0.002, 0.0)]) == MET
    assert rt.rule_corners([], []) == rt.NOT_JUDGED
    assert rt.rule_corners([(0.0, 0.0)], [(0.0, 0.0), (0.0, 0.0)]) == rt.NOT_JUDGED


def test_pulse_recovery_needs_aco_within_5_s_every_time_and_ca_8_s_median_and_is_not_met_on_our_hover():
    # docs/results.md's hover: everyone back within about a second.
    assert rt.rule_pulse_recovery([1.08, 0.0, 1.15, 0.0], [0.33, 0.02, 0.46, 0.41]) == NOT_MET
    assert rt.rule_pulse_recovery([4.0, 3.0, 2.0], [8.5, 9.0, 2.0]) == MET
    assert rt.rule_pulse_recovery([4.0, 5.5, 2.0], [8.5, 9.0, 9.0]) == NOT_MET
    assert rt.rule_pulse_recovery([4.0, None], [9.0, 9.0]) == NOT_MET
    # CA never back counts as slower than 8 s.
    assert rt.rule_pulse_recovery([4.0, 3.0], [None, None]) == MET
    assert rt.rule_pulse_recovery([0.0, 0.0], [0.0, 0.0]) == rt.NOT_JUDGED
    assert rt.rule_pulse_recovery([], [1.0]) == rt.NOT_JUDGED
