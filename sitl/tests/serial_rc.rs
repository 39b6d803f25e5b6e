//! The plant on a serial line sends the pilot's radio: `sitl serve --serial`'s server on one end of a
//! pseudo-terminal pair (the plant's own [`SerialTransport`], as on the airframe's ARM board), a test
//! autopilot on the other end reading the byte stream with the autopilot's frame decoder and its plant
//! protocol (`decode_hil_message`, whose `HilInput::Rc` the autopilot's host puts into
//! `VehicleInputs.rc`) and answering every `HIL_SENSOR` in lockstep. Unix only (a pty pair).
#![cfg(unix)]

use std::io::{Read, Write};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use autopilot::core::estimator::GeoOrigin;
use autopilot::core::manual::RcFrame;
use autopilot::core::mavlink::MavHeader;
use autopilot::core::mavlink::common::MavMessage;
use autopilot::core::plant_link::{
    ActuatorCommand, FrameDecoder, HilInput, decode_hil_message, encode_actuator_controls, encode_frame_v2,
};
use autopilot::runtime::transport::{POLL_INTERVAL, SerialTransport};
use serialport::{SerialPort, TTYPort};
use sitl::link::{LinkConfig, PlantServer};
use sitl::plant::{InitialState, Plant, PlantConfig};

/// Plant steps the test runs: 0.5 s of plant time at 2 ms.
const STEPS: u64 = 250;

#[test]
fn given_a_radio_frame_when_the_plant_serves_over_a_pty_then_the_autopilot_decodes_rc_channels_at_50_hz() {
    let (mut autopilot_end, plant_end) = TTYPort::pair().expect("a pty pair");
    let path = plant_end.name().expect("the plant end's device path");
    let transport = SerialTransport::open(&path, 921_600, POLL_INTERVAL).expect("open the plant end");
    let mut plant = Plant::new(PlantConfig::default(), &InitialState::default(), 1).expect("plant");
    let frame = RcFrame::of(&[1000, 1500, 1000, 2000, 1500, 1500, 1900, 1100, 1300, 1700, 1500, 1500]);
    plant.radio_mut().set_port_frame(frame);
    let mut server = PlantServer::new(plant, transport, LinkConfig::default());
    autopilot_end.set_timeout(Duration::from_millis(100)).expect("timeout");

    let autopilot = std::thread::spawn(move || {
        let home = GeoOrigin { lat_deg: 0.0, lon_deg: 0.0, alt_amsl_m: 0.0 };
        let mut decoder = FrameDecoder::new();
        let mut buf = [0_u8; 4096];
        // Each radio frame with its RC_CHANNELS' time_boot_ms and the time of the HIL_SENSOR after it.
        let mut rc: Vec<(u32, RcFrame, u64)> = Vec::new();
        let mut pending: Option<(u32, RcFrame)> = None;
        let mut answered = 0;
        let deadline = Instant::now() + Duration::from_secs(60);
        while answered < STEPS && Instant::now() < deadline {
            let n = match autopilot_end.read(&mut buf) {
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
                Err(e) => panic!("reading the pty: {e}"),
            };
            for decoded in decoder.push(&buf[..n]) {
                match (decode_hil_message(&decoded.message, &home), &decoded.message) {
                    (Some(HilInput::Rc(got)), MavMessage::RC_CHANNELS(m)) => pending = Some((m.time_boot_ms, got)),
                    (Some(HilInput::Sensor(fields)), _) => {
                        if let Some((ms, got)) = pending.take() {
                            rc.push((ms, got, fields.time_us));
                        }
                        let cmd = ActuatorCommand {
                            time_us: fields.time_us,
                            pwm_us: [1000.0; 4],
                            armed: false,
                            motor_test: false,
                        };
                        let header = MavHeader { system_id: 1, component_id: 1, sequence: 0 };
                        let reply = MavMessage::HIL_ACTUATOR_CONTROLS(encode_actuator_controls(&cmd));
                        autopilot_end.write_all(&encode_frame_v2(header, &reply)).expect("reply");
                        answered += 1;
                    }
                    _ => {}
                }
            }
        }
        // The end is handed back, not closed: a pty whose other end closes hangs up on the plant.
        (rc, decoder.stats().malformed(), autopilot_end)
    });
    let steps = server.run(Some(STEPS), &AtomicBool::new(false)).expect("the plant serves over the pty");
    let (rc, malformed, _autopilot_end) = autopilot.join().expect("the autopilot end");
    assert_eq!(steps, STEPS);
    assert_eq!(malformed, 0, "a clean byte stream");
    let times_ms: Vec<u32> = rc.iter().map(|r| r.0).collect();
    assert_eq!(times_ms, (0..25).map(|k| k * 20).collect::<Vec<_>>(), "every 20 ms of plant time");
    for (ms, got, sensor_us) in &rc {
        assert_eq!(got, &frame, "at {ms} ms: the frame's channels, count and RSSI exactly");
        assert_eq!(u64::from(*ms) * 1000, *sensor_us, "before the HIL_SENSOR of its own time");
    }
    assert_eq!(server.stats().rc_sent, 25);
}
