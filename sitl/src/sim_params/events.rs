//! Timed SIM_ parameter sets: a scenario's `[[event]]` (`at_s = 5.0`, `set = { SIM_MOT1_EFF = 0.9 }`).
//! In, the events as written; out, a validated schedule ([`resolve`]: every name a SIM_ parameter, every
//! value within its range, every time within the run, refused at load with the event and key named) and
//! its driver ([`SimEvents`], plain data: the schedule, the next event and the refusals), which whoever
//! steps the plant runs just before each step ([`SimEvents::step`]): the sets of every event whose time
//! has come (the first plant step that starts at or after `at_s`) go through the SIM_ parameter service
//! ([`SimParamService::set_now`]), exactly as a PARAM_SET on the plant's SIM_ port would, so the port
//! shows the values an event set. The same driver runs in the in-process runner (`sitl scenario`) and
//! the plant server (`sitl run --scenario`), with the service each of them holds; the plant itself knows
//! nothing of the events.
//!
//! Within one event the sets go in [`super::SIM_PARAMS`] table order (a gust's speed before its switch);
//! events at the same time go in file order.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::{SIM_PARAMS, SimParamService};
use crate::plant::Plant;

/// One `[[event]]` as written in a scenario.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct EventSpec {
    /// Plant time (s) from which the sets act: the first plant step starting at or after it.
    pub at_s: f64,
    /// SIM_ parameter names and the values to set them to.
    pub set: BTreeMap<String, f64>,
}

/// A validated event: its plant time (µs) and its sets as (table index, value) in table order.
#[derive(Debug, Clone, PartialEq)]
pub struct SimEvent {
    pub at_us: u64,
    pub sets: Vec<(usize, f32)>,
}

/// The index of SIM_ parameter `name`.
#[must_use]
pub fn param_index(name: &str) -> Option<usize> {
    SIM_PARAMS.iter().position(|d| d.name == name)
}

/// The schedule of `events` for a run of `duration_s`, ordered by time (file order at equal times).
///
/// # Errors
/// The first bad event, named by its number (1-based, file order) and time, and the key: a time that is
/// not finite, negative or past the run's end; no sets; an unknown parameter; a value the parameter's
/// range, kind (whole numbers for switches) or f32 representation refuses.
pub fn resolve(events: &[EventSpec], duration_s: f64) -> Result<Vec<SimEvent>, String> {
    let mut schedule = Vec::with_capacity(events.len());
    for (n, event) in events.iter().enumerate() {
        let at_s = event.at_s;
        let name = format!("[[event]] {} (at_s = {at_s})", n + 1);
        if !(at_s.is_finite() && at_s >= 0.0 && at_s <= duration_s) {
            return Err(format!("{name}: at_s must be within the run, 0..={duration_s} s"));
        }
        if event.set.is_empty() {
            return Err(format!("{name}: `set` names no SIM_ parameter"));
        }
        let mut sets = Vec::with_capacity(event.set.len());
        for (key, &value) in &event.set {
            let Some(index) = param_index(key) else {
                let known: Vec<&str> = SIM_PARAMS.iter().map(|d| d.name).collect();
                return Err(format!("{name}: unknown SIM_ parameter `{key}` (known: {})", known.join(", ")));
            };
            let v = value as f32;
            // The port's own check: range, kind, and a failure type the sensor has.
            super::check_set(key, v).map_err(|e| format!("{name}: {key} = {}: {e}", shown(value)))?;
            sets.push((index, v));
        }
        sets.sort_by_key(|(index, _)| *index);
        schedule.push(SimEvent { at_us: (at_s * 1e6).round() as u64, sets });
    }
    schedule.sort_by_key(|e| e.at_us);
    Ok(schedule)
}

/// A value as a file writes it: `1e300`, not its three hundred digits.
fn shown(value: f64) -> String {
    if value.is_finite() && value.abs() >= 1e15 { format!("{value:e}") } else { format!("{value}") }
}

/// A set the plant refused when its event fired (validation at load leaves only the plant's own
/// reasons, e.g. a wind it cannot blow).
#[derive(Debug, Clone, PartialEq)]
pub struct Refusal {
    pub at_us: u64,
    pub name: &'static str,
    pub reason: String,
}

/// The driver of a schedule on one plant: the next event to fire and the sets the plant refused. The
/// sets go through the SIM_ parameter service its stepper lends ([`SimEvents::step`]). No schedule (the
/// default) never fires.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SimEvents {
    schedule: Vec<SimEvent>,
    next: usize,
    refusals: Vec<Refusal>,
}

impl SimEvents {
    /// The driver of `schedule` (from [`resolve`]).
    #[must_use]
    pub fn new(schedule: Vec<SimEvent>) -> Self {
        Self { schedule, next: 0, refusals: Vec::new() }
    }

    /// Whether an event is due at plant time `time_us` (at or after its time and not yet fired).
    #[must_use]
    pub fn due(&self, time_us: u64) -> bool {
        self.schedule.get(self.next).is_some_and(|e| e.at_us <= time_us)
    }

    /// Fire every event due at the plant's current time, in order, through `service`.
    pub fn fire_due(&mut self, service: &mut SimParamService, plant: &mut Plant) {
        let now_us = plant.time_us();
        while let Some(event) = self.schedule.get(self.next).filter(|e| e.at_us <= now_us) {
            for &(index, value) in &event.sets {
                if let Err(reason) = service.set_now(index, value, plant) {
                    self.refusals.push(Refusal { at_us: event.at_us, name: SIM_PARAMS[index].name, reason });
                }
            }
            self.next += 1;
        }
    }

    /// One plant step with the schedule: the events due at the plant's time fire through `service` first
    /// (none at a zero-length step, which is no step), then the plant steps by `dt_us` with `pwm_us` held.
    pub fn step(&mut self, service: &mut SimParamService, plant: &mut Plant, pwm_us: [f64; 4], dt_us: u64) {
        if dt_us != 0 && self.due(plant.time_us()) {
            self.fire_due(service, plant);
        }
        plant.step(pwm_us, dt_us);
    }

    /// Events fired so far.
    #[must_use]
    pub fn fired(&self) -> usize {
        self.next
    }

    /// The sets the plant refused so far.
    #[must_use]
    pub fn refusals(&self) -> &[Refusal] {
        &self.refusals
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::plant::{InitialState, PlantConfig};
    use proptest::prelude::*;

    fn event(at_s: f64, set: &[(&str, f64)]) -> EventSpec {
        EventSpec { at_s, set: set.iter().map(|(k, v)| ((*k).to_owned(), *v)).collect() }
    }

    /// The driver of `schedule` and a SIM_ parameter service of system 1 read from `plant`, as a stepper
    /// holds them.
    fn install(plant: &Plant, schedule: Result<Vec<SimEvent>, String>) -> (SimEvents, SimParamService) {
        (SimEvents::new(schedule.unwrap()), SimParamService::new(1, plant))
    }

    fn hover_plant() -> Plant {
        let initial = InitialState { pos_ned_m: nalgebra::Vector3::new(0.0, 0.0, -10.0), ..InitialState::default() };
        Plant::new(PlantConfig::default(), &initial, 1).expect("plant")
    }

    #[test]
    fn given_bad_events_then_each_is_refused_at_load_naming_the_event_and_the_key() {
        let ok = event(1.0, &[("SIM_MOT1_EFF", 0.9)]);
        let cases = [
            (
                vec![ok.clone(), event(2.0, &[("SIM_MOTX_EFF", 0.9)])],
                "[[event]] 2 (at_s = 2): unknown SIM_ parameter `SIM_MOTX_EFF`",
            ),
            (vec![event(2.0, &[("SIM_MOT1_EFF", 1.5)])], "[[event]] 1 (at_s = 2): SIM_MOT1_EFF = 1.5"),
            (vec![event(2.0, &[("SIM_PAYLOAD_KG", -0.1)])], "SIM_PAYLOAD_KG = -0.1"),
            (vec![event(2.0, &[("SIM_RC_FAIL", 0.5)])], "SIM_RC_FAIL = 0.5"),
            (
                vec![event(2.0, &[("SIM_ACC_FAIL", 1.0)])],
                "SIM_ACC_FAIL = 1: SIM_ACC_FAIL: only 0 ok, 2 stuck, 3 garbage",
            ),
            (vec![event(2.0, &[("SIM_MOT2_EFF", f64::NAN)])], "SIM_MOT2_EFF = NaN"),
            (vec![event(2.0, &[("SIM_CG_OFS_X", 1e300)])], "SIM_CG_OFS_X = 1e300"),
            (vec![event(-1.0, &[("SIM_MOT1_EFF", 0.9)])], "[[event]] 1 (at_s = -1): at_s must be within the run"),
            (vec![event(11.0, &[("SIM_MOT1_EFF", 0.9)])], "at_s must be within the run, 0..=10 s"),
            (vec![event(f64::INFINITY, &[("SIM_MOT1_EFF", 0.9)])], "at_s must be within the run"),
            (vec![event(1.0, &[])], "[[event]] 1 (at_s = 1): `set` names no SIM_ parameter"),
        ];
        for (events, needle) in cases {
            let e = resolve(&events, 10.0).expect_err(needle);
            assert!(e.contains(needle), "{needle}: {e}");
        }
        // Good ones: ordered by time (file order at equal times), sets in table order.
        let schedule = resolve(
            &[
                event(5.0, &[("SIM_PAYLOAD_KG", 0.3), ("SIM_MOT1_EFF", 0.9)]),
                event(1.0, &[("SIM_GUST_ON", 1.0), ("SIM_GUST_SPD", 4.0)]),
                event(5.0, &[("SIM_MOT1_EFF", 1.0)]),
            ],
            10.0,
        )
        .unwrap();
        let idx = |n: &str| param_index(n).unwrap();
        assert_eq!(
            schedule,
            [
                SimEvent { at_us: 1_000_000, sets: vec![(idx("SIM_GUST_SPD"), 4.0), (idx("SIM_GUST_ON"), 1.0)] },
                SimEvent { at_us: 5_000_000, sets: vec![(idx("SIM_MOT1_EFF"), 0.9), (idx("SIM_PAYLOAD_KG"), 0.3)] },
                SimEvent { at_us: 5_000_000, sets: vec![(idx("SIM_MOT1_EFF"), 1.0)] },
            ]
        );
    }

    #[test]
    fn given_an_event_at_5_ms_when_stepping_2_ms_then_it_acts_from_the_step_starting_at_6_ms_and_not_before() {
        let mut plant = hover_plant();
        let (mut events, mut service) = install(&plant, resolve(&[event(0.005, &[("SIM_MOT1_EFF", 0.5)])], 1.0));
        let pwm = plant.last_pwm_us();
        let health = |p: &Plant| p.config().airframe.rotor_health[0];
        for start_us in [0, 2000, 4000] {
            assert_eq!((plant.time_us(), health(&plant)), (start_us, 1.0));
            events.step(&mut service, &mut plant, pwm, 2000);
        }
        // The step from 4 ms ended at 6 ms with the rotor healthy; the next one starts at 6 ms >= 5 ms.
        assert_eq!(events.fired(), 0);
        let lift_before = plant.truth().rotor_lift_n[0];
        events.step(&mut service, &mut plant, pwm, 2000);
        assert_eq!((health(&plant), events.fired()), (0.5, 1));
        // And it acted within that step: rotor 1's lift falls toward half (lag 40 ms), the others hold.
        let t = plant.truth();
        assert!(t.rotor_lift_n[0] < lift_before - 0.1, "{:?}", t.rotor_lift_n);
        assert!((t.rotor_lift_n[1] - lift_before).abs() < 1e-9, "{:?}", t.rotor_lift_n);
        // A zero-length step is no step: nothing fires at it.
        let mut idle = hover_plant();
        let (mut events, mut service) = install(&idle, resolve(&[event(0.0, &[("SIM_MOT1_EFF", 0.5)])], 1.0));
        events.step(&mut service, &mut idle, pwm, 0);
        assert_eq!(health(&idle), 1.0);
        events.step(&mut service, &mut idle, pwm, 2000);
        assert_eq!(health(&idle), 0.5);
    }

    #[test]
    fn given_events_with_a_sim_port_then_the_port_shows_their_values_and_tells_its_peers() {
        // The service the events go through is the one the SIM_ port answers from and empties to its peers.
        let mut plant = hover_plant();
        let (mut events, mut service) =
            install(&plant, resolve(&[event(0.0, &[("SIM_PAYLOAD_KG", 0.25), ("SIM_CG_OFS_X", 0.05)])], 1.0));
        let pwm = plant.last_pwm_us();
        events.step(&mut service, &mut plant, pwm, 2000);
        let payload = plant.config().airframe.payload;
        assert_eq!((payload.mass_kg, payload.offset_frd_m.x), (f64::from(0.25_f32), f64::from(0.05_f32)));
        let payload_kg = service.get("SIM_PAYLOAD_KG");
        let offset_x_m = service.get("SIM_CG_OFS_X");
        assert_eq!((payload_kg, offset_x_m), (Some(0.25), Some(0.05)));
        let echoes = service.take_outbox();
        let names: Vec<String> = echoes
            .iter()
            .filter_map(|m| match m {
                mavlink::dialects::common::MavMessage::PARAM_VALUE(v) => {
                    Some(autopilot::core::mavlink::params::param_name(&v.param_id))
                }
                _ => None,
            })
            .collect();
        assert_eq!(names, ["SIM_PAYLOAD_KG", "SIM_CG_OFS_X"]);
    }

    /// An event key: a real SIM_ parameter or a near miss.
    fn any_key() -> impl Strategy<Value = String> {
        prop_oneof![
            (0..SIM_PARAMS.len()).prop_map(|i| SIM_PARAMS[i].name.to_owned()),
            Just("SIM_MOT5_EFF".to_owned()),
            Just("sim_mot1_eff".to_owned()),
            Just(String::new()),
            "[A-Z_]{0,20}",
        ]
    }

    fn any_value() -> impl Strategy<Value = f64> {
        prop_oneof![
            Just(f64::NAN),
            Just(f64::INFINITY),
            Just(-1.0),
            Just(1e39),
            0.0..1.0,
            -40.0..100_000.0f64,
            (0u8..10).prop_map(f64::from),
        ]
    }

    fn any_events() -> impl Strategy<Value = Vec<EventSpec>> {
        let at = prop_oneof![Just(f64::NAN), Just(-0.5), Just(30.0), 0.0..2.0f64];
        prop::collection::vec(
            (at, prop::collection::btree_map(any_key(), any_value(), 0..4))
                .prop_map(|(at_s, set)| EventSpec { at_s, set }),
            0..6,
        )
    }

    proptest! {
        // 96 cases of the default 256: PROPTEST_CASES scales them with every other property test.
        #![proptest_config(ProptestConfig::with_cases(ProptestConfig::default().cases * 96 / 256))]

        /// Any event list: resolving never panics; a list is accepted exactly when every event is inside
        /// the run and every set is a SIM_ parameter its check accepts; an accepted list then flies.
        #[test]
        fn given_random_event_lists_then_invalid_ones_are_refused_at_load_and_valid_ones_run(events in any_events()) {
            let valid = events.iter().all(|e| {
                e.at_s.is_finite() && (0.0..=2.0).contains(&e.at_s) && !e.set.is_empty()
                    && e.set.iter().all(|(k, v)| param_index(k).is_some_and(|i| SIM_PARAMS[i].check(*v as f32).is_ok()))
            });
            match resolve(&events, 2.0) {
                Ok(schedule) => {
                    prop_assert!(valid);
                    prop_assert!(schedule.windows(2).all(|w| w[0].at_us <= w[1].at_us));
                    let mut plant = hover_plant();
                    let (mut events, mut service) = install(&plant, Ok(schedule));
                    let pwm = plant.last_pwm_us();
                    for _ in 0..1100 {
                        events.step(&mut service, &mut plant, pwm, 2000);
                    }
                    prop_assert_eq!(events.fired(), events.schedule.len());
                    prop_assert!(plant.config().airframe.validate().is_ok());
                }
                Err(e) => {
                    prop_assert!(!valid, "refused a valid list: {}", e);
                    prop_assert!(e.starts_with("[[event]] "), "{}", e);
                }
            }
        }
    }
}
