//! The PARAM microservice (MAVLink parameter protocol) as a sans-I/O handler, over any table of
//! parameters: the vehicle's [`ParamStore`] (component 1, [`ParamService::new`]) or another component's
//! (the SITL plant's SIM_ parameters, [`ParamService::for_component`]).
//!
//! In: PARAM_REQUEST_LIST, PARAM_REQUEST_READ (by `param_index` when >= 0, by `param_id` when negative)
//! and PARAM_SET, each only when addressed to us (our system or 0, our component or 0), with the store;
//! and once per vehicle step (2 ms at 500 Hz) a call to [`ParamService::due`]. Out: PARAM_VALUE messages
//! (`param_type` the parameter's [`ParamKind::mav_param_type`], its value encoded by [`encode_value`];
//! `param_count` = the table size, `param_index` = its table index, `param_id` its name, not
//! NUL-terminated when it has exactly 16 characters), STATUSTEXT (WARNING) for a refused set, and for a
//! set that changed a value a [`ParamChange`] so the vehicle can apply it to its config and persist the
//! store. Every PARAM_VALUE, answer or not (the vehicle's repeat of a value it undid), is made by
//! [`param_value`].
//!
//! A read is answered at once; a read of an unknown index gets no answer (clients time out, as with PX4),
//! and a read of an unknown name gets an INFO STATUSTEXT `unknown parameter NAME` to the asker only and no
//! PARAM_VALUE, so a script can say why instead of timing out in silence. A list is streamed, at most
//! [`PARAMS_PER_STEP`] PARAM_VALUE per [`ParamService::due`] (8 per 2 ms: the whole table in ~20 ms
//! without a burst that overflows a serial link or a client's socket buffer); a new PARAM_REQUEST_LIST
//! restarts the stream from index 0. A set is decoded by [`decode_set`], checked by the table's
//! [`ParamDef::check`] (finite, in range, whole or 0/1 by kind) and stored by [`ParamStore::set_index`]:
//! on success the new value is echoed in a PARAM_VALUE (also when it equals the current value); on a
//! refusal nothing changes, a STATUSTEXT gives the reason and, for a known name, a PARAM_VALUE repeats
//! the current value (clients resend a set until they see a PARAM_VALUE for it).
//!
//! Types on the wire, as PX4 has them. A real parameter travels as REAL32, the f32 itself. An integer or a
//! boolean travels as INT32 in PX4's bytewise encoding: the int32's four bytes stand as they are in the
//! float field `param_value` (`f32::from_bits(i as u32)`: 2 is the denormal 2.8e-45, not 2.0), and
//! AUTOPILOT_VERSION declares MAV_PROTOCOL_CAPABILITY_PARAM_ENCODE_BYTEWISE (not PARAM_ENCODE_C_CAST, the
//! ArduPilot convention of a float-converted value), so MAVSDK's `get_param_int` / `set_param_int`,
//! QGroundControl and pymavlink scripts written for PX4 read and write them. PX4's PARAM_SET handler
//! (`MavlinkParametersManager`, `src/modules/mavlink/mavlink_parameters.cpp`) takes a set only when its
//! `param_type` is the parameter's own (INT32 for an int32, REAL32 for a float; any type for its few bool
//! parameters) and drops any other with an error on its own console: the client hears nothing and times
//! out (older PX4 ignored the type and stored the four bytes, so a REAL32 2.0 became the int 1073741824).
//! Here a PARAM_SET is taken as:
//!
//! - for a REAL32 parameter, REAL32 only;
//! - for an INT32 parameter, INT32 decoded bytewise; the narrower integer types PX4's bytewise encoding
//!   has (UINT8, INT8, UINT16, INT16, UINT32) decoded bytewise too, the bytes past the type's width 0;
//!   and REAL32 carrying the value as a float (2.0), as older scripts send it (pymavlink's
//!   `param_set_send(..., 2.0, MAV_PARAM_TYPE_REAL32)`); the value must then be whole, as any integer's;
//! - any other type (an integer type for a REAL32 parameter, a 64-bit type for any) is refused, like an
//!   out-of-range value, with a STATUSTEXT (`MPC_XY_CRUISE: sent as INT32, it is REAL32`) and the
//!   unchanged value repeated: where PX4 is silent, the client learns at once why. An integer sent to a
//!   REAL32 parameter is not converted: a client that has the type wrong may have the value wrong too.
//!
//! A mix-up of the two encodings is refused, never misread: every integer parameter's range lies within
//! ±2^23 (a table test), so a float sent as INT32 (ArduPilot's C cast: 2.0 = 0x4000_0000) reads as an
//! int32 out of range, and an int32 sent as REAL32 (bytewise 2 = a denormal) is not a whole number. Only 0
//! reads the same either way.
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
use crate::core::params::{ParamDef, ParamError, ParamKind, ParamStore};

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
                let (index, name) = match usize::try_from(m.param_index) {
                    Ok(index) => (Some(index), None),
                    Err(_) => {
                        let name = param_name(&m.param_id);
                        (store.index_of(&name), Some(name))
                    }
                };
                let messages = match (index.and_then(|i| param_value(store, i)), name) {
                    (Some(value), _) => vec![value],
                    // A read by a name the vehicle does not have: its reason, to the asker only (an INFO, so
                    // a ground station probing for optional names shows no warning).
                    (None, Some(name)) => {
                        vec![statustext(MavSeverity::MAV_SEVERITY_INFO, &format!("unknown parameter {name}"))]
                    }
                    (None, None) => Vec::new(),
                };
                ParamReply { messages, changed: None }
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
        let outcome = decode_set(d, m.param_type, m.param_value).and_then(|value| {
            d.check(value)?;
            let applied = apply(store, index, value).map_err(|reason| ParamError::Refused { name: d.name, reason })?;
            store.set_index(index, value)?;
            Ok((value, applied))
        });
        match outcome {
            Ok((value, applied)) => {
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
        param_value: encode_value(d.kind, value),
        param_count: u16::try_from(store.len()).unwrap_or(u16::MAX),
        param_index: u16::try_from(index).unwrap_or(u16::MAX),
        param_id: CharArray::from(d.name),
        param_type: d.kind.mav_param_type(),
    }))
}

/// The `param_value` field that carries `value` of a parameter of `kind` (type
/// [`ParamKind::mav_param_type`]): a real's f32 as it is; an integer's or a boolean's whole value as an
/// int32 whose four bytes stand in the field as they are (PX4's bytewise encoding: a reinterpretation, not
/// a conversion). A value past the int32 range saturates (none is in range).
#[must_use]
pub fn encode_value(kind: ParamKind, value: f32) -> f32 {
    match kind {
        ParamKind::Real => value,
        ParamKind::Integer | ParamKind::Boolean => f32::from_le_bytes((value as i32).to_le_bytes()),
    }
}

/// The value in a `param_value` field of type `param_type` (a PARAM_VALUE's or a PARAM_SET's), decoded
/// bytewise, the inverse of [`encode_value`]: REAL32 is the f32 itself; an integer type of 1, 2 or 4 bytes
/// is read from the field's first bytes (little-endian, as on the wire), and the bytes past its width
/// must be 0. None for a 64-bit type (it does not fit in the field) or bytes that are not a value of the
/// type. An integer is exact up to 2^24 in magnitude, rounded to the nearest f32 beyond.
#[must_use]
pub fn decode_value(param_type: MavParamType, field: f32) -> Option<f32> {
    use MavParamType as T;
    let bytes = field.to_le_bytes();
    let [b0, b1, b2, b3] = bytes;
    let fits_1_byte = [b1, b2, b3] == [0; 3];
    let fits_2_bytes = [b2, b3] == [0; 2];
    match param_type {
        T::MAV_PARAM_TYPE_REAL32 => Some(field),
        T::MAV_PARAM_TYPE_UINT8 => fits_1_byte.then(|| f32::from(b0)),
        T::MAV_PARAM_TYPE_INT8 => fits_1_byte.then(|| f32::from(i8::from_le_bytes([b0]))),
        T::MAV_PARAM_TYPE_UINT16 => fits_2_bytes.then(|| f32::from(u16::from_le_bytes([b0, b1]))),
        T::MAV_PARAM_TYPE_INT16 => fits_2_bytes.then(|| f32::from(i16::from_le_bytes([b0, b1]))),
        T::MAV_PARAM_TYPE_UINT32 => Some(u32::from_le_bytes(bytes) as f32),
        T::MAV_PARAM_TYPE_INT32 => Some(i32::from_le_bytes(bytes) as f32),
        T::MAV_PARAM_TYPE_UINT64 | T::MAV_PARAM_TYPE_INT64 | T::MAV_PARAM_TYPE_REAL64 => None,
    }
}

/// The value a PARAM_SET of `param_type` and field `field` carries for parameter `d`, not yet checked
/// against its range (see the module docs for which types each parameter takes).
///
/// # Errors
/// [`ParamError::WrongType`] for a type the parameter does not take, [`ParamError::NotBytewise`] for an
/// integer type whose bytes past its width are not 0.
pub fn decode_set<G, B>(d: &ParamDef<G, B>, param_type: MavParamType, field: f32) -> Result<f32, ParamError> {
    use MavParamType as T;
    let expected = d.kind.mav_param_type();
    let wrong = ParamError::WrongType { name: d.name, sent: param_type, expected };
    match (d.kind, param_type) {
        (ParamKind::Real, T::MAV_PARAM_TYPE_REAL32) => Ok(field),
        (ParamKind::Real, _) | (_, T::MAV_PARAM_TYPE_UINT64 | T::MAV_PARAM_TYPE_INT64 | T::MAV_PARAM_TYPE_REAL64) => {
            Err(wrong)
        }
        (ParamKind::Integer | ParamKind::Boolean, _) => decode_value(param_type, field)
            .ok_or(ParamError::NotBytewise { name: d.name, sent: param_type, bits: field.to_bits() }),
    }
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

    fn set_typed(name: &str, field: f32, param_type: MavParamType) -> MavMessage {
        MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: field,
            target_system: US,
            target_component: 1,
            param_id: CharArray::from(name),
            param_type,
        })
    }

    /// The `param_value` field of `i` in PX4's bytewise INT32 encoding, written out independently of
    /// [`encode_value`].
    fn int32_field(i: i32) -> f32 {
        f32::from_bits(i as u32)
    }

    /// `(name, value, index, count)` of a PARAM_VALUE, checking its type is the parameter's (REAL32 for a
    /// real, INT32 for an integer or a boolean) and decoding its value by that type.
    fn value_of(msg: &MavMessage) -> (String, f32, u16, u16) {
        let MavMessage::PARAM_VALUE(v) = msg else { panic!("not a PARAM_VALUE: {msg:?}") };
        let name = param_name(&v.param_id);
        let def = PARAMS.iter().find(|d| d.name == name).unwrap_or_else(|| panic!("{name} is not a parameter"));
        let value = match def.kind {
            ParamKind::Real => {
                assert_eq!(v.param_type, MavParamType::MAV_PARAM_TYPE_REAL32, "{name}");
                v.param_value
            }
            ParamKind::Integer | ParamKind::Boolean => {
                assert_eq!(v.param_type, MavParamType::MAV_PARAM_TYPE_INT32, "{name}");
                v.param_value.to_bits() as i32 as f32
            }
        };
        (name, value, v.param_index, v.param_count)
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
        // Unknown name: no value, and the reason as an INFO to the asker; unknown index: no answer.
        let unknown = svc.on_message(US, &GCS, &read_name("SYS_AUTOSTART"), &mut store);
        assert_eq!(unknown.messages.len(), 1);
        assert_eq!(
            text_of(&unknown.messages[0]),
            (MavSeverity::MAV_SEVERITY_INFO, "unknown parameter SYS_AUTOSTART".to_owned())
        );
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

    const INT32: MavParamType = MavParamType::MAV_PARAM_TYPE_INT32;
    const REAL32: MavParamType = MavParamType::MAV_PARAM_TYPE_REAL32;

    /// The PARAM_VALUE of a reply at `i` as it is on the wire: `(type, field bits)`.
    fn raw(reply: &ParamReply, i: usize) -> (MavParamType, u32) {
        let Some(MavMessage::PARAM_VALUE(v)) = reply.messages.get(i) else {
            panic!("no PARAM_VALUE at {i}: {reply:?}")
        };
        (v.param_type, v.param_value.to_bits())
    }

    #[test]
    fn given_each_kind_when_listed_then_reals_travel_real32_and_integers_and_booleans_int32_bytewise() {
        let (mut svc, mut store) = (ParamService::new(), ParamStore::defaults());
        svc.on_message(US, &GCS, &list(US), &mut store);
        let mut kinds = Vec::new();
        while svc.list_in_progress() {
            for msg in svc.due(&store) {
                let MavMessage::PARAM_VALUE(v) = &msg else { panic!("{msg:?}") };
                let d = &PARAMS[usize::from(v.param_index)];
                let expected = match d.kind {
                    ParamKind::Real => (REAL32, d.default.to_bits()),
                    ParamKind::Integer | ParamKind::Boolean => (INT32, d.default as i32 as u32),
                };
                assert_eq!((v.param_type, v.param_value.to_bits()), expected, "{}", d.name);
                kinds.push(d.kind);
            }
        }
        for kind in [ParamKind::Real, ParamKind::Integer, ParamKind::Boolean] {
            assert!(kinds.contains(&kind), "{kind:?} is exercised");
        }
        // LOOP_INNER_HZ = 500 is the int32 500 in the field (a denormal as a float), not 500.0.
        let reply = svc.on_message(US, &GCS, &read_name("LOOP_INNER_HZ"), &mut store);
        assert_eq!(raw(&reply, 0), (INT32, 500));
        assert_ne!(raw(&reply, 0).1, 500.0_f32.to_bits());
    }

    #[test]
    fn given_an_int32_parameter_when_set_as_an_integer_type_or_a_whole_real32_then_taken_and_echoed_int32() {
        use MavParamType as T;
        let two = f32::from_bits(2);
        for (field, param_type) in [
            (int32_field(2), INT32),
            (2.0, REAL32),
            (two, T::MAV_PARAM_TYPE_UINT8),
            (two, T::MAV_PARAM_TYPE_INT8),
            (two, T::MAV_PARAM_TYPE_UINT16),
            (two, T::MAV_PARAM_TYPE_INT16),
            (two, T::MAV_PARAM_TYPE_UINT32),
        ] {
            let (mut svc, mut store) = (ParamService::new(), ParamStore::defaults());
            let reply = svc.on_message(US, &GCS, &set_typed("NAV_DLL_ACT", field, param_type), &mut store);
            assert_eq!(store.get("NAV_DLL_ACT"), Some(2.0), "{param_type:?}");
            assert_eq!(reply.messages.len(), 1, "{param_type:?}: {reply:?}");
            assert_eq!(raw(&reply, 0), (INT32, 2), "{param_type:?}: echoed as the int32 2");
            let index = store.index_of("NAV_DLL_ACT").expect("declared");
            assert_eq!(
                reply.changed,
                Some(ParamChange { index, name: "NAV_DLL_ACT", value: 2.0, restart_required: false })
            );
        }
        // A boolean is INT32 too: 0 switches the adaptation off.
        let (mut svc, mut store) = (ParamService::new(), ParamStore::defaults());
        let reply = svc.on_message(US, &GCS, &set_typed("ACO_ADAPT_EN", int32_field(0), INT32), &mut store);
        assert_eq!((store.get("ACO_ADAPT_EN"), raw(&reply, 0)), (Some(0.0), (INT32, 0)));
    }

    #[test]
    fn given_an_int32_parameter_when_set_with_a_bad_value_or_type_then_refused_and_the_int32_repeated() {
        use MavParamType as T;
        let cases: [(&str, f32, MavParamType, &str); 12] = [
            ("NAV_DLL_ACT", 2.5, REAL32, "NAV_DLL_ACT: 2.5 is not a whole number"),
            ("NAV_DLL_ACT", f32::NAN, REAL32, "NAV_DLL_ACT: NaN is not finite"),
            // An int32 sent as REAL32 is a denormal, not a whole number.
            ("NAV_DLL_ACT", int32_field(2), REAL32, "NAV_DLL_ACT: 3e-45 is not a whole number"),
            // A float sent as INT32 (ArduPilot's C cast) is an int32 far out of range.
            ("NAV_DLL_ACT", 2.0, INT32, "NAV_DLL_ACT: 1.0737418e9 not in 0..5"),
            ("NAV_DLL_ACT", int32_field(7), INT32, "NAV_DLL_ACT: 7 not in 0..5"),
            ("NAV_DLL_ACT", int32_field(-1), INT32, "NAV_DLL_ACT: -1 not in 0..5"),
            (
                "NAV_DLL_ACT",
                f32::from_bits(0x0100_0002),
                T::MAV_PARAM_TYPE_UINT8,
                "NAV_DLL_ACT: 0x01000002 not a bytewise UINT8",
            ),
            (
                "NAV_DLL_ACT",
                f32::from_bits(0x0001_0002),
                T::MAV_PARAM_TYPE_INT16,
                "NAV_DLL_ACT: 0x00010002 not a bytewise INT16",
            ),
            ("NAV_DLL_ACT", 2.0, T::MAV_PARAM_TYPE_REAL64, "NAV_DLL_ACT: sent as REAL64, it is INT32"),
            ("NAV_DLL_ACT", int32_field(2), T::MAV_PARAM_TYPE_INT64, "NAV_DLL_ACT: sent as INT64, it is INT32"),
            ("ACO_ADAPT_EN", int32_field(2), INT32, "ACO_ADAPT_EN: 2 must be 0 or 1"),
            ("LOOP_INNER_HZ", int32_field(49), INT32, "LOOP_INNER_HZ: 49 not in 50..2000"),
        ];
        for (name, field, param_type, text) in cases {
            let (mut svc, mut store) = (ParamService::new(), ParamStore::defaults());
            let reply = svc.on_message(US, &GCS, &set_typed(name, field, param_type), &mut store);
            assert_eq!(store, ParamStore::defaults(), "{text}: nothing changes");
            assert_eq!(reply.changed, None);
            assert_eq!(reply.messages.len(), 2, "{reply:?}");
            assert_eq!(text_of(&reply.messages[0]), (MavSeverity::MAV_SEVERITY_WARNING, text.to_owned()));
            let default = store.get(name).expect("declared");
            assert_eq!(raw(&reply, 1), (INT32, default as i32 as u32), "{text}: the unchanged value");
        }
    }

    #[test]
    fn given_a_real32_parameter_when_set_with_any_other_type_then_refused_not_converted() {
        use MavParamType as T;
        for param_type in [
            INT32,
            T::MAV_PARAM_TYPE_UINT8,
            T::MAV_PARAM_TYPE_INT8,
            T::MAV_PARAM_TYPE_UINT16,
            T::MAV_PARAM_TYPE_INT16,
            T::MAV_PARAM_TYPE_UINT32,
            T::MAV_PARAM_TYPE_UINT64,
            T::MAV_PARAM_TYPE_INT64,
            T::MAV_PARAM_TYPE_REAL64,
        ] {
            let (mut svc, mut store) = (ParamService::new(), ParamStore::defaults());
            let reply = svc.on_message(US, &GCS, &set_typed("MPC_XY_CRUISE", int32_field(2), param_type), &mut store);
            assert_eq!((store.get("MPC_XY_CRUISE"), reply.changed), (Some(1.0), None), "{param_type:?}");
            let sent = crate::core::params::param_type_name(param_type);
            let text = format!("MPC_XY_CRUISE: sent as {sent}, it is REAL32");
            assert_eq!(text_of(&reply.messages[0]), (MavSeverity::MAV_SEVERITY_WARNING, text));
            assert_eq!(raw(&reply, 1), (REAL32, 1.0_f32.to_bits()), "the unchanged value");
        }
    }

    /// A table with a signed integer (the vehicle's integers are all >= 0).
    static SIGNED: [ParamDef<(), ()>; 1] = [ParamDef {
        name: "TEST_OFFSET",
        group: (),
        kind: ParamKind::Integer,
        default: -3.0,
        min: -100.0,
        max: 100.0,
        unit: "",
        restart: false,
        description: "A signed integer.",
        binding: (),
    }];

    #[test]
    fn given_a_negative_integer_when_read_and_set_then_its_twos_complement_bytes_travel_as_they_are() {
        use MavParamType as T;
        let (mut svc, mut store) = (ParamService::new(), ParamStore::with_defaults(&SIGNED));
        let reply = svc.on_message(US, &GCS, &read_index(0), &mut store);
        assert_eq!(raw(&reply, 0), (INT32, 0xFFFF_FFFD), "-3");
        for (field, param_type, value) in [
            (int32_field(-42), INT32, -42.0),
            (f32::from_bits(0xD6), T::MAV_PARAM_TYPE_INT8, -42.0),
            (f32::from_bits(0xFFD6), T::MAV_PARAM_TYPE_INT16, -42.0),
            (-7.0, REAL32, -7.0),
            (int32_field(100), INT32, 100.0),
        ] {
            let reply = svc.on_message(US, &GCS, &set_typed("TEST_OFFSET", field, param_type), &mut store);
            assert_eq!(store.get("TEST_OFFSET"), Some(value), "{param_type:?}");
            assert_eq!(raw(&reply, 0), (INT32, value as i32 as u32), "{param_type:?}");
        }
        // Sign-extended past the type's width, or out of range: refused.
        for (field, param_type, text) in [
            (f32::from_bits(0xFFFF_FFD6), T::MAV_PARAM_TYPE_INT8, "TEST_OFFSET: 0xffffffd6 not a bytewise INT8"),
            (int32_field(-101), INT32, "TEST_OFFSET: -101 not in -100..100"),
            (f32::from_bits(0xFFD6), T::MAV_PARAM_TYPE_UINT16, "TEST_OFFSET: 65494 not in -100..100"),
        ] {
            let reply = svc.on_message(US, &GCS, &set_typed("TEST_OFFSET", field, param_type), &mut store);
            assert_eq!(text_of(&reply.messages[0]).1, text);
            assert_eq!((store.get("TEST_OFFSET"), raw(&reply, 1)), (Some(100.0), (INT32, 100)));
        }
    }

    #[test]
    fn given_the_widest_values_of_each_integer_type_when_decoded_then_exact_or_refused() {
        use MavParamType as T;
        let cases: [(MavParamType, u32, Option<f32>); 12] = [
            (T::MAV_PARAM_TYPE_UINT8, 0xFF, Some(255.0)),
            (T::MAV_PARAM_TYPE_UINT8, 0x100, None),
            (T::MAV_PARAM_TYPE_INT8, 0x80, Some(-128.0)),
            (T::MAV_PARAM_TYPE_UINT16, 0xFFFF, Some(65_535.0)),
            (T::MAV_PARAM_TYPE_INT16, 0x8000, Some(-32_768.0)),
            (T::MAV_PARAM_TYPE_INT16, 0x1_0000, None),
            (T::MAV_PARAM_TYPE_UINT32, 0xFFFF_FFFF, Some(4_294_967_296.0)),
            (T::MAV_PARAM_TYPE_INT32, 0x8000_0000, Some(-2_147_483_648.0)),
            (T::MAV_PARAM_TYPE_INT32, 0x7FFF_FFFF, Some(2_147_483_648.0)),
            (T::MAV_PARAM_TYPE_UINT64, 2, None),
            (T::MAV_PARAM_TYPE_INT64, 2, None),
            (T::MAV_PARAM_TYPE_REAL64, 2, None),
        ];
        for (param_type, bits, value) in cases {
            assert_eq!(decode_value(param_type, f32::from_bits(bits)), value, "{param_type:?} {bits:#x}");
        }
        assert_eq!(decode_value(REAL32, 2.5), Some(2.5));
    }

    proptest::proptest! {
        #[test]
        fn given_any_integer_within_2_pow_24_when_encoded_then_its_int32_bytes_and_decoded_back_exactly(
            i in -(1_i32 << 24)..=(1 << 24),
        ) {
            let value = i as f32;
            for kind in [ParamKind::Integer, ParamKind::Boolean] {
                let field = encode_value(kind, value);
                proptest::prop_assert_eq!(field.to_le_bytes(), i.to_le_bytes());
                proptest::prop_assert_eq!(decode_value(kind.mav_param_type(), field), Some(value));
            }
        }

        #[test]
        fn given_any_real_when_encoded_then_the_f32_itself_and_decoded_bit_exactly(bits in proptest::prelude::any::<u32>()) {
            let x = f32::from_bits(bits);
            let field = encode_value(ParamKind::Real, x);
            proptest::prop_assert_eq!(field.to_bits(), bits);
            let back = decode_value(ParamKind::Real.mav_param_type(), field).map(f32::to_bits);
            proptest::prop_assert_eq!(back, Some(bits));
        }
    }
}
