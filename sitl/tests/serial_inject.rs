//! The plant on a serial line answers a forwarded MAV_CMD_INJECT_FAILURE as it does over UDP: the plant's
//! own [`SerialTransport`] on one end of a pseudo-terminal pair, a test autopilot on the other writing a
//! `COMMAND_LONG` 420 before its `HIL_ACTUATOR_CONTROLS` in one write, and reading exactly one
//! `COMMAND_ACK` before the next `HIL_SENSOR` of the byte stream. Unix only (a pty pair).
#![cfg(unix)]

use std::io::{Read, Write};
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use autopilot::core::mavlink::common::{MavCmd, MavMessage, MavResult};
use autopilot::core::mavlink::{MavHeader, command_long};
use autopilot::core::plant_link::{ActuatorCommand, FrameDecoder, encode_actuator_controls, encode_frame_v2};
use autopilot::runtime::transport::{POLL_INTERVAL, SerialTransport};
use serialport::{SerialPort, TTYPort};
use sitl::link::{LinkConfig, PlantServer};
use sitl::plant::{Fault, InitialState, Plant, PlantConfig, Sensor, SensorConfig};

/// Plant steps the test runs: 0.2 s of plant time at 2 ms.
const STEPS: u64 = 100;
/// The answer that carries the injection (mag stuck).
const INJECT_AT: usize = 20;

#[test]
fn given_an_injection_over_a_pty_then_one_command_ack_arrives_before_the_next_hil_sensor_and_the_mag_sticks() {
    let (mut autopilot_end, plant_end) = TTYPort::pair().expect("a pty pair");
    let path = plant_end.name().expect("the plant end's device path");
    let transport = SerialTransport::open(&path, 921_600, POLL_INTERVAL).expect("open the plant end");
    // A noisy magnetometer, so that a stuck one is told from a still vehicle's.
    let config = PlantConfig { sensors: SensorConfig::modest_noise(), ..PlantConfig::default() };
    let plant = Plant::new(config, &InitialState::default(), 1).expect("plant");
    let mut server = PlantServer::new(plant, transport, LinkConfig::default());
    autopilot_end.set_timeout(Duration::from_millis(100)).expect("timeout");

    let autopilot = std::thread::spawn(move || {
        let header = MavHeader { system_id: 1, component_id: 1, sequence: 0 };
        let mut decoder = FrameDecoder::new();
        let mut buf = [0_u8; 4096];
        // The stream as (number of HIL_SENSORs answered before it, message).
        let mut stream: Vec<(usize, MavMessage)> = Vec::new();
        let mut answered = 0;
        let deadline = Instant::now() + Duration::from_secs(60);
        while (answered as u64) < STEPS && Instant::now() < deadline {
            let n = match autopilot_end.read(&mut buf) {
                Ok(n) => n,
                Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
                Err(e) => panic!("reading the pty: {e}"),
            };
            for decoded in decoder.push(&buf[..n]) {
                stream.push((answered, decoded.message.clone()));
                let MavMessage::HIL_SENSOR(sensor) = decoded.message else { continue };
                let mut write = Vec::new();
                if answered == INJECT_AT {
                    let params = [2.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0];
                    write.extend(encode_frame_v2(header, &command_long(0, 0, MavCmd::MAV_CMD_INJECT_FAILURE, params)));
                }
                let cmd =
                    ActuatorCommand { time_us: sensor.time_usec, pwm_us: [1000.0; 4], armed: false, motor_test: false };
                write.extend(encode_frame_v2(
                    header,
                    &MavMessage::HIL_ACTUATOR_CONTROLS(encode_actuator_controls(&cmd)),
                ));
                autopilot_end.write_all(&write).expect("reply");
                answered += 1;
            }
        }
        // The end is handed back, not closed: a pty whose other end closes hangs up on the plant.
        (stream, autopilot_end)
    });
    let steps = server.run(Some(STEPS), &AtomicBool::new(false)).expect("the plant serves over the pty");
    let (stream, _autopilot_end) = autopilot.join().expect("the autopilot end");
    assert_eq!(steps, STEPS);
    let acks: Vec<(usize, MavResult)> = stream
        .iter()
        .filter_map(|(k, m)| match m {
            MavMessage::COMMAND_ACK(a) if a.command == MavCmd::MAV_CMD_INJECT_FAILURE => Some((*k, a.result)),
            _ => None,
        })
        .collect();
    assert_eq!(acks, [(INJECT_AT + 1, MavResult::MAV_RESULT_ACCEPTED)], "one ACK, in the next step's write");
    let ack_at = stream.iter().position(|(_, m)| matches!(m, MavMessage::COMMAND_ACK(_))).expect("the ACK");
    let next_sensor = stream[ack_at..].iter().position(|(_, m)| matches!(m, MavMessage::HIL_SENSOR(_)));
    let previous_sensor = stream[..ack_at].iter().rposition(|(_, m)| matches!(m, MavMessage::HIL_SENSOR(_)));
    assert!(next_sensor.is_some() && previous_sensor.is_some(), "between two HIL_SENSORs");
    assert_eq!(server.plant().sensor_faults().fault(Sensor::Mag), Fault::Stuck);
    // The magnetometer repeats the value of the sample before the injection, bit for bit.
    let mags: Vec<[f32; 3]> = stream
        .iter()
        .filter_map(|(_, m)| match m {
            MavMessage::HIL_SENSOR(s) => Some([s.xmag, s.ymag, s.zmag]),
            _ => None,
        })
        .collect();
    assert!(mags[INJECT_AT..].iter().all(|m| *m == mags[INJECT_AT]), "stuck from the injection's step");
    assert!(mags[..INJECT_AT].iter().all(|m| *m != mags[INJECT_AT]), "noisy before it");
}
