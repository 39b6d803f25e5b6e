//! Step metrics of a finished run: the segments of every axis a step schedule moves (attitude, position
//! or rates), each with overshoot, settling and error integrals, and the whole-run RMS per axis.

use std::collections::BTreeMap;

use super::Scenario;
use super::metrics::{self, SegmentMetrics, StepSegment};
use super::reference::ReferenceSpec;
use super::runner::Series;

/// The three axes a step schedule moves: their names, recorded values and references, initial values,
/// and the schedule as (time, targets).
struct StepAxes<'a> {
    names: [&'static str; 3],
    values: &'a [Vec<f64>; 3],
    refs: &'a [Vec<f64>; 3],
    starts: [f64; 3],
    schedule: Vec<(f64, [f64; 3])>,
}

/// Step segments of every axis that the schedule moves, and whole-run RMS per axis.
pub(super) fn step_metrics(scenario: &Scenario, s: &Series) -> (Vec<SegmentMetrics>, BTreeMap<&'static str, f64>) {
    let end = scenario.duration_s;
    let axes = match &scenario.reference {
        ReferenceSpec::Attitude { steps, .. } => StepAxes {
            names: ["roll", "pitch", "yaw"],
            values: &s.euler,
            refs: &s.ref_euler,
            starts: scenario.initial.euler_rad,
            schedule: steps.iter().map(|st| (st.t_s, st.euler_rad)).collect(),
        },
        ReferenceSpec::Position { steps } => StepAxes {
            names: ["n", "e", "d"],
            values: &s.pos,
            refs: &s.ref_pos,
            starts: scenario.initial.pos_ned_m,
            schedule: steps.iter().map(|st| (st.t_s, st.pos_ned_m)).collect(),
        },
        ReferenceSpec::Rates { steps, .. } => StepAxes {
            names: ["p", "q", "r"],
            values: &s.rate,
            refs: &s.ref_rate,
            starts: scenario.initial.rate_frd_radps,
            schedule: steps.iter().map(|st| (st.t_s, st.rate_frd_radps)).collect(),
        },
        ReferenceSpec::Track(_) => return (Vec::new(), BTreeMap::new()),
    };
    let StepAxes { names, values, refs, starts, schedule } = axes;
    let mut segments = Vec::new();
    let mut previous = starts;
    for (i, (t0, target)) in schedule.iter().enumerate() {
        for axis in 0..3 {
            if (target[axis] - previous[axis]).abs() <= 1e-9 {
                continue;
            }
            // An axis's step lasts until that axis's setpoint changes again.
            let later = &schedule[i + 1..];
            let t1 = later.iter().find(|next| (next.1[axis] - target[axis]).abs() > 1e-9).map_or(end, |next| next.0);
            let wrap = names[axis] == "yaw";
            let seg = StepSegment {
                axis: names[axis],
                t0_s: *t0,
                t1_s: t1,
                start: previous[axis],
                target: target[axis],
                wrap,
            };
            segments.push(metrics::step_metrics_in(&s.t, &values[axis], &seg, scenario.metric_windows.step_sse_s));
        }
        previous = *target;
    }
    let rms = (0..3)
        .map(|axis| (names[axis], metrics::tracking_rms(&values[axis], &refs[axis], names[axis] == "yaw")))
        .collect();
    (segments, rms)
}
