"""The verdict rules of scripts/fault_results_table.py: each comes out "met" only where ACO is better than every
baseline, "not met" where it is not (equal at the printed digits included), "not judged" where a baseline has
no tuned gains and none that has beats ACO, and "no verdict: physics" outside the airframe's envelope."""

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]
_spec = importlib.util.spec_from_file_location("fault_results_table", ROOT / "scripts" / "fault_results_table.py")
assert _spec is not None and _spec.loader is not None
ft = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(ft)

MET, NOT_MET, NOT_JUDGED, NO_VERDICT, MISSING = ft.MET, ft.NOT_MET, ft.NOT_JUDGED, ft.NO_VERDICT, ft.MISSING


def test_lower_is_met_only_below_every_baseline_and_not_met_when_equal_at_the_printed_digits():
    assert ft.rule_lower(0.160, [0.271, 0.410]) == MET
    # payload-step-5's peak tilt: ACO above both.
    assert ft.rule_lower(0.012, [0.008, 0.009]) == NOT_MET
    # below one baseline, above the other (rotor at 90 %: PID's final error is smaller).
    assert ft.rule_lower(0.012, [0.035, 0.009]) == NOT_MET
    # equal where the table prints 3 decimals: not lower.
    assert ft.rule_lower(0.0012, [0.0014, 0.5]) == NOT_MET
    assert ft.rule_lower(0.0012, [0.0014], digits=4) == MET


def test_lower_against_a_baseline_without_gains_is_not_judged_unless_another_beats_aco():
    assert ft.rule_lower(0.065, [0.138, MISSING]) == NOT_JUDGED
    assert ft.rule_lower(0.065, [MISSING]) == NOT_JUDGED
    assert ft.rule_lower(0.200, [0.138, MISSING]) == NOT_MET
    assert ft.rule_lower(MISSING, [0.138]) == NOT_MET


def test_sooner_counts_never_as_later_than_any_time_and_never_against_never_as_not_met():
    assert ft.rule_sooner(1.98, [3.42, 2.776]) == MET
    assert ft.rule_sooner(1.98, [None, 2.776]) == MET
    assert ft.rule_sooner(None, [None, None]) == NOT_MET
    assert ft.rule_sooner(None, [3.0]) == NOT_MET
    assert ft.rule_sooner(0.0, [0.0, 2.394]) == NOT_MET
    assert ft.rule_sooner(0.0, [1.5, MISSING]) == NOT_JUDGED


def test_flag_rules_need_aco_on_the_better_side_and_every_baseline_on_the_worse():
    # within 0.3 m: yes is better.
    assert ft.rule_flag(True, [False, False], True) == MET
    assert ft.rule_flag(True, [True, False], True) == NOT_MET
    assert ft.rule_flag(False, [False, False], True) == NOT_MET
    # lost control: no is better.
    assert ft.rule_flag(False, [True, True], False) == MET
    assert ft.rule_flag(False, [False, False], False) == NOT_MET
    assert ft.rule_flag(True, [True, True], False) == NOT_MET
    assert ft.rule_flag(False, [True, MISSING], False) == NOT_JUDGED


def test_more_runs_within_is_strict():
    assert ft.rule_more(18, [16, 11]) == MET
    assert ft.rule_more(18, [18, 12]) == NOT_MET
    assert ft.rule_more(10, [16, 11]) == NOT_MET
    assert ft.rule_more(18, [16, MISSING]) == NOT_JUDGED


def test_boundary_is_met_only_for_a_larger_loss_held_and_the_same_boundary_is_not_met():
    assert ft.rule_boundary(0.11, [0.11, 0.11]) == NOT_MET
    assert ft.rule_boundary(0.11, [0.10, 0.05]) == MET
    assert ft.rule_boundary(0.11, [None, 0.05]) == MET
    assert ft.rule_boundary(None, [None]) == NOT_MET
    assert ft.rule_boundary(0.11, [0.10, MISSING]) == NOT_JUDGED


def test_held_boundary_is_the_largest_loss_up_to_which_every_run_kept_control():
    runs = [(0.0, False), (0.0, False), (0.05, False), (0.11, False), (0.12, True), (0.12, False), (0.2, False)]
    assert ft.held_boundary(runs) == 0.11
    assert ft.held_boundary([(0.0, True), (0.05, False)]) is None


def test_outside_the_full_envelope_is_no_verdict_whatever_the_metrics_say():
    assert ft.rule_inside("full", MET) == MET
    assert ft.rule_inside("full", NOT_MET) == NOT_MET
    assert ft.rule_inside("without-yaw", MET) == NO_VERDICT
    assert ft.rule_inside("infeasible", NOT_MET) == NO_VERDICT


def test_every_rule_has_a_docstring():
    for name in dir(ft):
        if name.startswith("rule_"):
            assert getattr(ft, name).__doc__, name


def test_a_comparison_not_won_is_worse_only_when_some_baseline_beats_aco():
    def lower(x, ys):
        return ft.rule_lower(x, ys, 3)

    # payload-step-5's peak tilt: CA and PID both lower, so ACO is worse, not level.
    assert ft.beaten_by_some(lower, 0.012, [0.008, 0.009])
    # Level at the printed digits with the best baseline: not met, and not worse.
    assert ft.rule_lower(0.0121, [0.0124, 0.020]) == NOT_MET
    assert not ft.beaten_by_some(lower, 0.0121, [0.0124, 0.020])
    # A missing baseline beats nobody; a missing ACO is beaten by nobody (it is not judged at all).
    assert not ft.beaten_by_some(lower, 0.012, [MISSING, 0.020])
    assert not ft.beaten_by_some(lower, MISSING, [0.001])
    # Flags: the same outcome is level; the better outcome on a baseline's side is worse.
    assert not ft.beaten_by_some(lambda x, ys: ft.rule_flag(x, ys, True), True, [True, True])
    assert ft.beaten_by_some(lambda x, ys: ft.rule_flag(x, ys, True), False, [True, False])
