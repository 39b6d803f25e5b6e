//! The plant protocol as the autopilot reads it (`runtime::plant_link`): any datagrams from the plant's
//! address, decoded by the frame decoder, turned into samples by `core::plant_link::decode_hil_message`, and
//! each HIL_SENSOR stepping a vehicle with what came before it in the datagram, as the plant link does.
//! The input is split into datagrams at a fuzzer-chosen separator. Nothing panics, and every step keeps
//! the vehicle's invariants (motor commands finite and in range, estimate finite); the plant's end of the
//! same decoder also reads every datagram.
#![no_main]

use aco_fuzz::check_step;
use autopilot::core::estimator::GeoOrigin;
use autopilot::core::plant_link::{FrameDecoder, HilInput, SensorSamples, decode_hil_message};
use autopilot::core::mavlink::common::MavMessage;
use autopilot::core::vehicle::{Vehicle, VehicleConfig, VehicleInputs};
use libfuzzer_sys::fuzz_target;

/// Steps per input at most: a long input must not turn into a long flight.
const MAX_STEPS: usize = 400;

fuzz_target!(|data: &[u8]| {
    let Some((&separator, bytes)) = data.split_first() else { return };
    let mut vehicle = Vehicle::new(VehicleConfig::default()).expect("the default configuration is valid");
    let mut decoder = FrameDecoder::new();
    let mut home: Option<GeoOrigin> = None;
    let mut inputs = VehicleInputs::default();
    let mut last_time_us: Option<u64> = None;
    let mut steps = 0;
    for datagram in bytes.split(|b| *b == separator) {
        for frame in decoder.decode_datagram(datagram) {
            if home.is_none()
                && let MavMessage::HIL_STATE_QUATERNION(m) = &frame.message
            {
                home = Some(GeoOrigin {
                    lat_deg: autopilot::core::mavlink::units::dege7_to_deg(m.lat),
                    lon_deg: autopilot::core::mavlink::units::dege7_to_deg(m.lon),
                    alt_amsl_m: autopilot::core::mavlink::units::mm_to_m(m.alt),
                });
            }
            let origin = home.unwrap_or(GeoOrigin { lat_deg: 0.0, lon_deg: 0.0, alt_amsl_m: 0.0 });
            match decode_hil_message(&frame.message, &origin) {
                Some(HilInput::Gps(gps)) => inputs.gps = Some(gps),
                Some(HilInput::Battery(b)) => inputs.battery = Some(b),
                Some(HilInput::Rc(frame)) => inputs.rc = Some(frame),
                Some(HilInput::CommandAck(ack)) => inputs.plant_ack = Some(ack),
                Some(HilInput::Truth(t)) if home.is_some() => inputs.truth = Some(t),
                Some(HilInput::LocalTruth(local)) => {
                    if let Some(t) = inputs.truth.as_mut().filter(|t| t.time_us == local.time_us) {
                        *t = local.refine(t);
                    }
                }
                Some(HilInput::Sensor(fields)) => {
                    let samples = SensorSamples::from(&fields);
                    inputs.imu = Some(samples.imu);
                    inputs.mag = samples.mag;
                    inputs.baro = samples.baro;
                    let now_us = fields.time_us;
                    if last_time_us.is_some_and(|last| now_us < last) {
                        // The plant link restarts the vehicle when the plant's clock goes back.
                        vehicle = Vehicle::new(VehicleConfig::default()).expect("valid");
                    }
                    last_time_us = Some(now_us);
                    let out = vehicle.step(now_us, &std::mem::take(&mut inputs));
                    check_step(&vehicle, &out);
                    steps += 1;
                    if steps >= MAX_STEPS {
                        return;
                    }
                }
                Some(HilInput::Actuators(_)) | Some(HilInput::Truth(_)) | None => {}
            }
        }
    }
});
