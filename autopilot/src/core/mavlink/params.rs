//! The PARAM microservice (MAVLink parameter protocol) as a sans-I/O handler, over any table of
//! parameters: the vehicle's [`ParamStore`] (component 1, [`ParamService::new`]) or another component's
//! (the SITL plant's SIM_ parameters, [`ParamService::for_component`]).
//!
//! In: PARAM_REQUEST_LIST, PARAM_REQUEST_READ (by `param_index` when >= 0, by `param_id` when negative)
//! and PARAM_SET, each only when addressed to us (our system or 0, our component or 0), with the store;
//! and once per vehicle step (2 ms at 500 Hz) a call to [`ParamService::due`]. Out: PARAM_VALUE messages (every
//! parameter REAL32, `param_count` = the table size, `param_index` = its table index, `param_id` its name,
//! not NUL-terminated when it has exactly 16 characters), STATUSTEXT (WARNING) for a refused set, and for a
//! set that changed a value a [`ParamChange`] so the vehicle can apply it to its config and persist the
//! store.
//!
//! A read is answered at once; a read of an unknown name or index gets no answer (clients time out, as
//! with PX4, without a warning on the ground station's screen). A list is streamed, at most
//! [`PARAMS_PER_STEP`] PARAM_VALUE per [`ParamService::due`] (8 per 2 ms: the whole table in ~20 ms
//! without a burst that overflows a serial link or a client's socket buffer); a new PARAM_REQUEST_LIST
//! restarts the stream from index 0. A set is checked by the table's
//! [`ParamDef::check`](crate::core::params::ParamDef::check) (finite, in range, whole or 0/1 by kind) and
//! stored by [`ParamStore::set_index`]: on success the new value is echoed in a PARAM_VALUE (also when it
//! equals the current value); on a refusal nothing changes, a STATUSTEXT gives the reason and, for a known
//! name, a PARAM_VALUE repeats the current value (clients resend a set until they see a PARAM_VALUE for
//! it). The `param_type` of a set is not checked: every
//! parameter is declared REAL32 and its value is read as the f32 it carries.
//!
//! A table whose owner acts on its values (the plant applies a SIM_ set to its wind) passes that action to
//! [`ParamService::on_message_with`]: it runs after the range check and before the value is stored, may
//! refuse (a STATUSTEXT `NAME: reason`, then the current value, as for a range refusal), may add a note
//! (a STATUSTEXT INFO sent before the echo) and may change other parameters of the store, whose
//! PARAM_VALUEs follow the echo.

use ::mavlink::MavHeader;
use ::mavlink::dialects::common::{MavMessage, MavParamType, MavSeverity, PARAM_SET_DATA, PARAM_VALUE_DATA};
use ::mavlink::types::CharArray;

use super::{AUTOPILOT_COMPONENT_ID, statustext};
use crate::core::params::{ParamError, ParamStore};

/// PARAM_VALUE messages a list stream emits per [`ParamService::due`] call.
pub const PARAMS_PER_STEP: usize = 8;

/// A value a PARAM_SET changed.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ParamChange {
    /// Table index.
    pub index: usize,
    pub name: &'static str,
    /// The new value (already in the store).
    pub value: f32,
    /// The value takes effect only at the next start.
    pub restart_required: bool,
}

/// The answer to one message.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ParamReply {
    /// PARAM_VALUE and STATUSTEXT to send, in order.
    pub messages: Vec<MavMessage>,
    /// Set when a PARAM_SET changed a value: apply the store to the config and persist it.
    pub changed: Option<ParamChange>,
}

/// What the owner of a table did with a set its range check accepted (see
/// [`ParamService::on_message_with`]).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Applied {
    /// A line for the ground station (STATUSTEXT INFO), sent before the echo.
    pub note: Option<String>,
    /// Other parameters (indices) the set changed in the store; their PARAM_VALUEs follow the echo.
    pub also_changed: Vec<usize>,
}

/// The parameter protocol's state: which component it answers for and where a list stream is.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ParamService {
    component_id: u8,
    /// The next index of a list stream in progress.
    list_cursor: Option<usize>,
}

impl Default for ParamService {
    fn default() -> Self {
        Self::new()
    }
}

impl ParamService {
    /// The autopilot's service (component [`AUTOPILOT_COMPONENT_ID`]) with no stream in progress.
    #[must_use]
    pub fn new() -> Self {
        Self::for_component(AUTOPILOT_COMPONENT_ID)
    }

    /// The service of component `component_id` (requests for it or for component 0 are ours).
    #[must_use]
    pub fn for_component(component_id: u8) -> Self {
        Self { component_id, list_cursor: None }
    }

    fn addressed_to_us(&self, sysid: u8, target_system: u8, target_component: u8) -> bool {
        (target_system == sysid || target_system == 0)
            && (target_component == self.component_id || target_component == 0)
    }

    /// True while a PARAM_REQUEST_LIST is being answered.
    #[must_use]
    pub fn list_in_progress(&self) -> bool {
        self.list_cursor.is_some()
    }

    /// A received message for system `sysid`. `header` is the sender's; the replies are for every ground
    /// station (PARAM_VALUE is broadcast, so that all of them see a change). Anything that is not a PARAM
    /// request addressed to us gets an empty reply.
    pub fn on_message<G, B>(
        &mut self,
        sysid: u8,
        header: &MavHeader,
        msg: &MavMessage,
        store: &mut ParamStore<G, B>,
    ) -> ParamReply {
        let _ = header;
        self.on_message_with(sysid, msg, store, |_, _, _| Ok(Applied::default()))
    }

    /// [`on_message`](Self::on_message) for a table whose owner acts on a set: `apply(store, index,
    /// value)` runs once the value passed the table's check and before it is stored. It may change other
    /// parameters of the store (listed in [`Applied::also_changed`]) and may refuse with a reason; then
    /// the value is not stored (what `apply` changed before refusing stays: refuse first).
    pub fn on_message_with<G, B>(
        &mut self,
        sysid: u8,
        msg: &MavMessage,
        store: &mut ParamStore<G, B>,
        apply: impl FnOnce(&mut ParamStore<G, B>, usize, f32) -> Result<Applied, String>,
    ) -> ParamReply {
        match msg {
            MavMessage::PARAM_REQUEST_LIST(m) if self.addressed_to_us(sysid, m.target_system, m.target_component) => {
                self.list_cursor = Some(0);
                ParamReply::default()
            }
            MavMessage::PARAM_REQUEST_READ(m) if self.addressed_to_us(sysid, m.target_system, m.target_component) => {
                let index = match usize::try_from(m.param_index) {
                    Ok(index) => Some(index),
                    Err(_) => store.index_of(&param_name(&m.param_id)),
                };
                ParamReply { messages: index.and_then(|i| param_value(store, i)).into_iter().collect(), changed: None }
            }
            MavMessage::PARAM_SET(m) if self.addressed_to_us(sysid, m.target_system, m.target_component) => {
                Self::on_set(m, store, apply)
            }
            _ => ParamReply::default(),
        }
    }

    /// The next PARAM_VALUEs of a list stream, at most [`PARAMS_PER_STEP`]; empty when none is running.
    /// Call once per vehicle step.
    pub fn due<G, B>(&mut self, store: &ParamStore<G, B>) -> Vec<MavMessage> {
        let Some(start) = self.list_cursor else {
            return Vec::new();
        };
        let end = (start + PARAMS_PER_STEP).min(store.len());
        self.list_cursor = (end < store.len()).then_some(end);
        (start..end).filter_map(|i| param_value(store, i)).collect()
    }

    fn on_set<G, B>(
        m: &PARAM_SET_DATA,
        store: &mut ParamStore<G, B>,
        apply: impl FnOnce(&mut ParamStore<G, B>, usize, f32) -> Result<Applied, String>,
    ) -> ParamReply {
        let name = param_name(&m.param_id);
        let Some((index, d)) = store.index_of(&name).and_then(|i| Some((i, store.def(i)?))) else {
            let refusal = ParamError::Unknown { name };
            return ParamReply { messages: vec![warning(&refusal)], changed: None };
        };
        let before = store.get_index(index);
        let value = m.param_value;
        let outcome = d
            .check(value)
            .and_then(|()| apply(store, index, value).map_err(|reason| ParamError::Refused { name: d.name, reason }))
            .and_then(|applied| store.set_index(index, value).map(|()| applied));
        match outcome {
            Ok(applied) => {
                let changed = match before {
                    Some(old) if old.to_bits() != value.to_bits() => {
                        Some(ParamChange { index, name: d.name, value, restart_required: d.restart })
                    }
                    _ => None,
                };
                let mut messages: Vec<MavMessage> =
                    applied.note.map(|text| statustext(MavSeverity::MAV_SEVERITY_INFO, &text)).into_iter().collect();
                messages
                    .extend(std::iter::once(index).chain(applied.also_changed).filter_map(|i| param_value(store, i)));
                ParamReply { messages, changed }
            }
            Err(refusal) => {
                let mut messages = vec![warning(&refusal)];
                messages.extend(param_value(store, index));
                ParamReply { messages, changed: None }
            }
        }
    }
}

/// A PARAM_VALUE for the parameter at `index` with its current value (None past the table).
#[must_use]
pub fn param_value<G, B>(store: &ParamStore<G, B>, index: usize) -> Option<MavMessage> {
    let d = store.def(index)?;
    let value = store.get_index(index)?;
    Some(MavMessage::PARAM_VALUE(PARAM_VALUE_DATA {
        param_value: value,
        param_count: u16::try_from(store.len()).unwrap_or(u16::MAX),
        param_index: u16::try_from(index).unwrap_or(u16::MAX),
        param_id: CharArray::from(d.name),
        param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
    }))
}

/// The name in a `param_id`: up to the first NUL, or all 16 bytes (not NUL-terminated when exactly 16
/// long); invalid UTF-8 is replaced (such a name is unknown anyway).
#[must_use]
pub fn param_name(id: &CharArray<16>) -> String {
    let bytes: &[u8; 16] = id;
    let len = bytes.iter().position(|&b| b == 0).unwrap_or(bytes.len());
    String::from_utf8_lossy(&bytes[..len]).into_owned()
}

fn warning(refusal: &ParamError) -> MavMessage {
    statustext(MavSeverity::MAV_SEVERITY_WARNING, &refusal.to_string())
}

#[cfg(test)]
mod tests {
    use ::mavlink::dialects::common::{HEARTBEAT_DATA, PARAM_REQUEST_LIST_DATA, PARAM_REQUEST_READ_DATA};

    use super::*;
    use crate::core::params::PARAMS;

    const US: u8 = 1;
    const GCS: MavHeader = MavHeader { system_id: 255, component_id: 190, sequence: 0 };

    fn list(target_system: u8) -> MavMessage {
        MavMessage::PARAM_REQUEST_LIST(PARAM_REQUEST_LIST_DATA { target_system, target_component: 1 })
    }

    fn read_name(name: &str) -> MavMessage {
        MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
            param_index: -1,
            target_system: US,
            target_component: 1,
            param_id: CharArray::from(name),
        })
    }

    fn read_index(index: i16) -> MavMessage {
        MavMessage::PARAM_REQUEST_READ(PARAM_REQUEST_READ_DATA {
            param_index: index,
            target_system: US,
            target_component: 0,
            param_id: CharArray::from(""),
        })
    }

    fn set_to(target_system: u8, name: &str, value: f32) -> MavMessage {
        MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: value,
            target_system,
            target_component: 1,
            param_id: CharArray::from(name),
            param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
        })
    }

    /// `(name, value, index, count)` of a PARAM_VALUE, checking its type is REAL32.
    fn value_of(msg: &MavMessage) -> (String, f32, u16, u16) {
        let MavMessage::PARAM_VALUE(v) = msg else { panic!("not a PARAM_VALUE: {msg:?}") };
        assert_eq!(v.param_type, MavParamType::MAV_PARAM_TYPE_REAL32);
        (param_name(&v.param_id), v.param_value, v.param_index, v.param_count)
    }

    fn text_of(msg: &MavMessage) -> (MavSeverity, String) {
        let MavMessage::STATUSTEXT(t) = msg else { panic!("not a STATUSTEXT: {msg:?}") };
        (t.severity, t.text.to_str().expect("utf-8").to_owned())
    }

    #[test]
    fn given_request_list_when_stepped_then_every_index_once_with_the_count_at_most_8_a_step() {
        let (mut svc, mut store) = (ParamService::new(), ParamStore::defaults());
        assert!(svc.on_message(US, &GCS, &list(US), &mut store).messages.is_empty(), "streamed, not a burst");
        let mut seen = vec![0; store.len()];
        let mut steps = 0;
        while svc.list_in_progress() {
            let batch = svc.due(&store);
            assert!(!batch.is_empty() && batch.len() <= PARAMS_PER_STEP);
            for msg in &batch {
                let (name, value, index, count) = value_of(msg);
                assert_eq!(usize::from(count), PARAMS.len());
                let i = usize::from(index);
                assert_eq!((name.as_str(), value), (PARAMS[i].name, PARAMS[i].default));
                seen[i] += 1;
            }
            steps += 1;
        }
        assert!(seen.iter().all(|&n| n == 1), "{seen:?}");
        assert_eq!(steps, PARAMS.len().div_ceil(PARAMS_PER_STEP));
        assert!(svc.due(&store).is_empty(), "done");
    }

    #[test]
    fn given_a_stream_in_progress_when_listed_again_then_restarts_from_index_0() {
        let (mut svc, mut store) = (ParamService::new(), ParamStore::defaults());
        svc.on_message(US, &GCS, &list(0), &mut store);
        svc.due(&store);
        svc.due(&store);
        svc.on_message(US, &GCS, &list(US), &mut store);
        let first = svc.due(&store);
        assert_eq!(value_of(&first[0]).2, 0);
        let mut total = first.len();
        while svc.list_in_progress() {
            total += svc.due(&store).len();
        }
        assert_eq!(total, PARAMS.len());
    }

    #[test]
    fn given_read_by_name_or_index_when_received_then_answered_at_once() {
        let (mut svc, mut store) = (ParamService::new(), ParamStore::defaults());
        let reply = svc.on_message(US, &GCS, &read_name("MIS_TAKEOFF_ALT"), &mut store);
        let index = store.index_of("MIS_TAKEOFF_ALT").expect("declared");
        assert_eq!(reply.messages.len(), 1);
        assert_eq!(value_of(&reply.messages[0]), ("MIS_TAKEOFF_ALT".into(), 2.5, index as u16, PARAMS.len() as u16));
        let reply = svc.on_message(US, &GCS, &read_index(3), &mut store);
        assert_eq!(value_of(&reply.messages[0]).0, PARAMS[3].name);
        assert_eq!(reply.changed, None);
        // Unknown name or index: no answer.
        assert!(svc.on_message(US, &GCS, &read_name("SYS_AUTOSTART"), &mut store).messages.is_empty());
        assert!(svc.on_message(US, &GCS, &read_index(PARAMS.len() as i16), &mut store).messages.is_empty());
        assert!(!svc.list_in_progress());
    }

    #[test]
    fn given_set_in_range_when_received_then_stored_echoed_and_reported_changed() {
        let (mut svc, mut store) = (ParamService::new(), ParamStore::defaults());
        let reply = svc.on_message(US, &GCS, &set_to(US, "MPC_XY_CRUISE", 2.5), &mut store);
        assert_eq!(store.get("MPC_XY_CRUISE"), Some(2.5));
        assert_eq!(reply.messages.len(), 1);
        assert_eq!(value_of(&reply.messages[0]).1, 2.5);
        let index = store.index_of("MPC_XY_CRUISE").expect("declared");
        assert_eq!(
            reply.changed,
            Some(ParamChange { index, name: "MPC_XY_CRUISE", value: 2.5, restart_required: false })
        );
        // The same value again: accepted and echoed, nothing changed.
        let again = svc.on_message(US, &GCS, &set_to(0, "MPC_XY_CRUISE", 2.5), &mut store);
        assert_eq!((again.messages.len(), again.changed), (1, None));
        let restart = svc.on_message(US, &GCS, &set_to(US, "LOOP_INNER_HZ", 1000.0), &mut store);
        assert!(restart.changed.is_some_and(|c| c.restart_required));
    }

    #[test]
    fn given_set_out_of_range_or_nan_when_received_then_refused_warned_and_current_value_repeated() {
        let (mut svc, mut store) = (ParamService::new(), ParamStore::defaults());
        for (value, text) in [(99.0, "MPC_XY_CRUISE: 99 not in 0.1..5"), (f32::NAN, "MPC_XY_CRUISE: NaN is not finite")]
        {
            let reply = svc.on_message(US, &GCS, &set_to(US, "MPC_XY_CRUISE", value), &mut store);
            assert_eq!(store, ParamStore::defaults(), "nothing changes");
            assert_eq!(reply.changed, None);
            assert_eq!(reply.messages.len(), 2);
            assert_eq!(text_of(&reply.messages[0]), (MavSeverity::MAV_SEVERITY_WARNING, text.to_owned()));
            assert_eq!(value_of(&reply.messages[1]).1, 1.0, "the unchanged value");
        }
    }

    #[test]
    fn given_set_of_unknown_name_when_received_then_warning_only() {
        let (mut svc, mut store) = (ParamService::new(), ParamStore::defaults());
        let reply = svc.on_message(US, &GCS, &set_to(US, "NO_SUCH_PARAM", 1.0), &mut store);
        assert_eq!(reply.messages.len(), 1);
        assert_eq!(
            text_of(&reply.messages[0]),
            (MavSeverity::MAV_SEVERITY_WARNING, "unknown parameter NO_SUCH_PARAM".into())
        );
        assert_eq!((reply.changed, store), (None, ParamStore::defaults()));
    }

    #[test]
    fn given_messages_for_another_system_or_not_params_when_received_then_ignored() {
        let (mut svc, mut store) = (ParamService::new(), ParamStore::defaults());
        for msg in [list(2), set_to(2, "MPC_XY_CRUISE", 2.0), MavMessage::HEARTBEAT(HEARTBEAT_DATA::default())] {
            assert_eq!(svc.on_message(US, &GCS, &msg, &mut store), ParamReply::default());
        }
        let mut other_read = read_name("MIS_TAKEOFF_ALT");
        if let MavMessage::PARAM_REQUEST_READ(m) = &mut other_read {
            m.target_component = 100;
        }
        assert_eq!(svc.on_message(US, &GCS, &other_read, &mut store), ParamReply::default());
        assert!(!svc.list_in_progress());
        assert_eq!(store, ParamStore::defaults());
    }

    #[test]
    fn given_16_character_names_when_read_set_and_encoded_then_kept_whole_without_nul() {
        let (mut svc, mut store) = (ParamService::new(), ParamStore::defaults());
        for name in PARAMS.iter().map(|d| d.name).filter(|n| n.len() == 16) {
            let reply = svc.on_message(US, &GCS, &read_name(name), &mut store);
            let MavMessage::PARAM_VALUE(v) = &reply.messages[0] else { panic!("{reply:?}") };
            let raw: &[u8; 16] = &v.param_id;
            assert_eq!(raw, name.as_bytes(), "all 16 bytes, no NUL");
            let reply = svc.on_message(US, &GCS, &set_to(US, name, 1.5), &mut store);
            assert_eq!(
                value_of(&reply.messages[0]),
                (name.to_owned(), 1.5, store.index_of(name).expect("known") as u16, PARAMS.len() as u16)
            );
            // Through the wire format and back, as a client sees it.
            let mut buf = Vec::new();
            ::mavlink::write_v2_msg(&mut buf, GCS, &reply.messages[0]).expect("encodes");
            let mut reader = ::mavlink::MavlinkReader::new(buf.as_slice());
            let (_, decoded): (_, MavMessage) = reader.read_any_message().expect("decodes");
            assert_eq!(value_of(&decoded).0, name);
        }
        assert_eq!(store.get("COM_DISARM_PRFLT"), Some(1.5));
    }
}
