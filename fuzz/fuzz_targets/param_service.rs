//! The parameter boundary: a stored parameter file (`params.txt` in the state directory) read the lenient
//! way the runtime reads it at start, then any sequence of parameter-protocol messages (PARAM_SET with
//! any name, type and value, reads by name and index, list requests) to the vehicle, stepped between
//! them. Nothing panics; the vehicle's configuration stays valid whatever was set (a refused set changes
//! nothing); every PARAM_SET is answered; the parameters in the store are finite and in their ranges.
#![no_main]

use aco_fuzz::{ParamMessage, check_step};
use arbitrary::Arbitrary;
use autopilot::core::mavlink::MavHeader;
use autopilot::core::mavlink::common::MavMessage;
use autopilot::core::params::{PARAMS, ParamStore};
use autopilot::core::vehicle::{Vehicle, VehicleConfig, VehicleInputs};
use libfuzzer_sys::fuzz_target;

#[derive(Debug, Arbitrary)]
struct Input {
    stored: String,
    messages: Vec<(u8, ParamMessage)>,
}

const GCS: MavHeader = MavHeader { system_id: 255, component_id: 190, sequence: 0 };

fuzz_target!(|input: Input| {
    let loaded = ParamStore::from_text_lenient(&input.stored, ParamStore::defaults());
    let mut vehicle = match Vehicle::with_params(VehicleConfig::default(), loaded.store) {
        Ok(v) => v,
        // The runtime falls back to the defaults when the stored set cannot make a vehicle.
        Err(_) => Vehicle::new(VehicleConfig::default()).expect("the defaults are valid"),
    };
    let mut now_us = 0;
    for (steps, message) in input.messages.iter().take(128) {
        let msg = message.to_message();
        let replies = vehicle.handle_message(now_us, &GCS, &msg);
        if matches!(msg, MavMessage::PARAM_SET(_)) {
            assert!(
                replies.iter().any(|r| matches!(r, MavMessage::PARAM_VALUE(_) | MavMessage::STATUSTEXT(_))),
                "a PARAM_SET unanswered: {msg:?}"
            );
        }
        for _ in 0..*steps % 16 {
            now_us += 2_000;
            let out = vehicle.step(now_us, &VehicleInputs::default());
            check_step(&vehicle, &out);
        }
        vehicle.config().validate().expect("the configuration stays valid");
    }
    let store = vehicle.params();
    for (i, def) in PARAMS.iter().enumerate() {
        let v = store.get_index(i).expect("every parameter has a value");
        assert!(v.is_finite() && v >= def.min && v <= def.max, "{} = {v} outside {}..{}", def.name, def.min, def.max);
    }
});
