//! Timed SIM_ parameter sets: a scenario's `[[event]]` (`at_s = 5.0`, `set = { SIM_MOT1_EFF = 0.9 }`).
//! In, the events as written; out, a validated schedule ([`resolve`]: every name a SIM_ parameter, every
//! value within its range, every time within the run, refused at load with the event and key named) and
//! its driver ([`SimEvents`]), which the plant runs at the start of each step: the sets of every event whose
//! time has come (the first plant step that starts at or after `at_s`) go through the SIM_ parameter
//! service ([`SimParamService::set_now`]), exactly as a PARAM_SET on the plant's SIM_ port would, so the
//! port shows the values an event set. The same driver runs in the in-process runner (`sitl scenario`)
//! and the plant server (`sitl run --scenario`).
//!
//! Within one event the sets go in [`super::SIM_PARAMS`] table order (a gust's speed before its switch);
//! events at the same time go in file order.

use std::collections::BTreeMap;
use std::sync::{Arc, Mutex, PoisonError};

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
            SIM_PARAMS[index].check(v).map_err(|e| format!("{name}: {key} = {value}: {e}"))?;
            sets.push((index, v));
        }
        sets.sort_by_key(|(index, _)| *index);
        schedule.push(SimEvent { at_us: (at_s * 1e6).round() as u64, sets });
    }
    schedule.sort_by_key(|e| e.at_us);
    Ok(schedule)
}

/// A set the plant refused when its event fired (validation at load leaves only the plant's own
/// reasons, e.g. a wind it cannot blow).
#[derive(Debug, Clone, PartialEq)]
pub struct Refusal {
    pub at_us: u64,
    pub name: &'static str,
    pub reason: String,
}

/// The driver of a schedule on one plant: the next event to fire and the SIM_ parameter service the sets
/// go through (shared with the plant's SIM_ port when it has one, see [`SimEvents::share_service`]).
/// Cloning a plant clones its events with a service of its own.
#[derive(Debug)]
pub struct SimEvents {
    schedule: Arc<[SimEvent]>,
    next: usize,
    service: Arc<Mutex<SimParamService>>,
    refusals: Vec<Refusal>,
}

impl Clone for SimEvents {
    fn clone(&self) -> Self {
        let service = self.service.lock().unwrap_or_else(PoisonError::into_inner).clone();
        Self {
            schedule: Arc::clone(&self.schedule),
            next: self.next,
            service: Arc::new(Mutex::new(service)),
            refusals: self.refusals.clone(),
        }
    }
}

impl SimEvents {
    /// The driver of `schedule` (from [`resolve`]), its sets going through `service`.
    #[must_use]
    pub fn new(schedule: Vec<SimEvent>, service: SimParamService) -> Self {
        Self { schedule: schedule.into(), next: 0, service: Arc::new(Mutex::new(service)), refusals: Vec::new() }
    }

    /// Whether an event is due at plant time `time_us` (at or after its time and not yet fired).
    #[must_use]
    pub fn due(&self, time_us: u64) -> bool {
        self.schedule.get(self.next).is_some_and(|e| e.at_us <= time_us)
    }

    /// Fire every event due at the plant's current time, in order, through the service.
    pub fn fire_due(&mut self, plant: &mut Plant) {
        let now_us = plant.time_us();
        let mut service = self.service.lock().unwrap_or_else(PoisonError::into_inner);
        while let Some(event) = self.schedule.get(self.next).filter(|e| e.at_us <= now_us) {
            for &(index, value) in &event.sets {
                if let Err(reason) = service.set_now(index, value, plant) {
                    self.refusals.push(Refusal { at_us: event.at_us, name: SIM_PARAMS[index].name, reason });
                }
            }
            self.next += 1;
        }
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

    /// Send the sets through `service` from now on (the plant's SIM_ port's, so both see the same values).
    pub fn share_service(&mut self, service: Arc<Mutex<SimParamService>>) {
        self.service = service;
    }
}

/// Give `plant` the schedule `schedule`, its sets through a SIM_ parameter service of system `system_id`
/// read from the plant (replaced by the SIM_ port's, [`super::SimParamLink::carry_events_of`]).
pub fn install(plant: &mut Plant, system_id: u8, schedule: Vec<SimEvent>) {
    let service = SimParamService::new(system_id, plant);
    plant.set_sim_events(Some(SimEvents::new(schedule, service)));
}
