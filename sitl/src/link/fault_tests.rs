//! Lockstep tests of the plant link's faults over UDP: the answer to a forwarded MAV_CMD_INJECT_FAILURE
//! (one COMMAND_ACK before the next HIL_SENSOR, the fault acting from the step it came with), the empty
//! pack as the autopilot decodes it, and the added delay and loss (deterministic, never a deadlock).

use std::collections::HashMap;
use std::net::{SocketAddr, UdpSocket};
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::thread;
use std::time::Duration;

use autopilot::core::battery::{BatteryConfig, BatteryMonitor, BatteryWarning};
use autopilot::core::mavlink::command_long;
use autopilot::core::plant_link::{
    ActuatorCommand, FrameDecoder, HilInput, decode_hil_message, encode_actuator_controls,
};
use mavlink::MavHeader;
use mavlink::dialects::common::{COMMAND_ACK_DATA, MavCmd, MavMessage, MavResult};
use nalgebra::Vector3;

use super::{LinkConfig, PlantServer, UdpTransport, encode_frame_v2};
use crate::plant::{Fault, InitialState, Plant, PlantConfig, Sensor};
use crate::sim_params::SimParamLink;

const AP: MavHeader = MavHeader { system_id: 1, component_id: 1, sequence: 0 };

fn hover_plant(seed: u64) -> Plant {
    let initial = InitialState { pos_ned_m: Vector3::new(0.0, 0.0, -10.0), ..InitialState::default() };
    Plant::new(PlantConfig::default(), &initial, seed).expect("plant")
}

fn server(seed: u64) -> PlantServer<UdpTransport> {
    PlantServer::bind_udp(hover_plant(seed), "127.0.0.1:0", LinkConfig::default()).expect("bind plant")
}

/// A test autopilot: announces itself, answers every HIL_SENSOR with hover PWM (with a COMMAND_LONG 420 of
/// `inject[k]` before the k-th answer's HIL_ACTUATOR_CONTROLS, in the same datagram, as the autopilot
/// forwards one) until `stop`; returns every datagram it received, decoded.
fn autopilot(
    plant_addr: SocketAddr,
    pwm_us: f64,
    inject: HashMap<usize, [f32; 3]>,
    stop: Arc<AtomicBool>,
) -> thread::JoinHandle<Vec<Vec<MavMessage>>> {
    let socket = UdpSocket::bind("127.0.0.1:0").expect("bind autopilot");
    socket.set_read_timeout(Some(Duration::from_millis(10))).expect("timeout");
    thread::spawn(move || {
        let heartbeat = MavMessage::HEARTBEAT(mavlink::dialects::common::HEARTBEAT_DATA::default());
        socket.send_to(&encode_frame_v2(AP, &heartbeat), plant_addr).expect("announce");
        let mut decoder = FrameDecoder::new();
        let mut buf = vec![0; 65_536];
        let mut datagrams = Vec::new();
        while !stop.load(Ordering::Relaxed) {
            let Ok((len, _)) = socket.recv_from(&mut buf) else { continue };
            let messages: Vec<MavMessage> =
                decoder.decode_datagram(&buf[..len]).into_iter().map(|f| f.message).collect();
            if let Some(MavMessage::HIL_SENSOR(sensor)) = messages.last() {
                let k = datagrams.len();
                let mut reply = Vec::new();
                if let Some([unit, failure_type, instance]) = inject.get(&k) {
                    let params = [*unit, *failure_type, *instance, 0.0, 0.0, 0.0, 0.0];
                    reply.extend(encode_frame_v2(AP, &command_long(0, 0, MavCmd::MAV_CMD_INJECT_FAILURE, params)));
                }
                let cmd =
                    ActuatorCommand { time_us: sensor.time_usec, pwm_us: [pwm_us; 4], armed: true, motor_test: false };
                reply.extend(encode_frame_v2(AP, &MavMessage::HIL_ACTUATOR_CONTROLS(encode_actuator_controls(&cmd))));
                socket.send_to(&reply, plant_addr).expect("reply");
            }
            datagrams.push(messages);
        }
        datagrams
    })
}

/// Run `server` for `steps` lockstep steps against [`autopilot`] with `inject`; the datagrams it got.
fn run(server: &mut PlantServer<UdpTransport>, steps: u64, inject: &[(usize, [f32; 3])]) -> Vec<Vec<MavMessage>> {
    let stop = Arc::new(AtomicBool::new(false));
    let pwm = server.plant().config().airframe.hover_pwm_us();
    let plant_addr = server.transport().local_addr().expect("addr");
    let ap = autopilot(plant_addr, pwm, inject.iter().copied().collect(), stop.clone());
    let ran = server.run(Some(steps), &AtomicBool::new(false)).expect("lockstep run");
    stop.store(true, Ordering::Relaxed);
    let datagrams = ap.join().expect("autopilot");
    assert_eq!(ran, steps);
    datagrams
}

fn acks(datagram: &[MavMessage]) -> Vec<COMMAND_ACK_DATA> {
    datagram
        .iter()
        .filter_map(|m| match m {
            MavMessage::COMMAND_ACK(a) => Some(a.clone()),
            _ => None,
        })
        .collect()
}

fn has_gps(datagram: &[MavMessage]) -> bool {
    datagram.iter().any(|m| matches!(m, MavMessage::HIL_GPS(_)))
}

#[test]
fn given_forwarded_injections_then_each_gets_one_command_ack_before_the_next_hil_sensor_and_acts_from_its_step() {
    let mut server = server(7);
    // Answers 10 (GPS off), 100 (accel off: unsupported), 150 (a NaN instance: denied), 200 (baro off),
    // 250 (battery off), 300 (GPS back).
    let inject = [
        (10, [4.0, 1.0, 0.0]),
        (100, [1.0, 1.0, 0.0]),
        (150, [4.0, 2.0, f32::NAN]),
        (200, [3.0, 1.0, 0.0]),
        (250, [100.0, 1.0, 0.0]),
        (300, [4.0, 0.0, 0.0]),
    ];
    let datagrams = run(&mut server, 400, &inject);
    assert_eq!(datagrams.len(), 400, "one datagram per step, none lost");
    let want = HashMap::from([
        (11, MavResult::MAV_RESULT_ACCEPTED),
        (101, MavResult::MAV_RESULT_UNSUPPORTED),
        (151, MavResult::MAV_RESULT_DENIED),
        (201, MavResult::MAV_RESULT_ACCEPTED),
        (251, MavResult::MAV_RESULT_ACCEPTED),
        (301, MavResult::MAV_RESULT_ACCEPTED),
    ]);
    for (k, d) in datagrams.iter().enumerate() {
        let got = acks(d);
        match want.get(&k) {
            Some(result) => {
                assert_eq!(got.len(), 1, "datagram {k}: exactly one ACK");
                let ack = &got[0];
                assert_eq!((ack.command, ack.result), (MavCmd::MAV_CMD_INJECT_FAILURE, *result), "datagram {k}");
                assert_eq!((ack.target_system, ack.target_component), (1, 1), "to the autopilot");
                assert!(matches!(d.first(), Some(MavMessage::COMMAND_ACK(_))), "first in the datagram");
            }
            None => assert!(got.is_empty(), "datagram {k}: no ACK"),
        }
        assert!(matches!(d.last(), Some(MavMessage::HIL_SENSOR(_))), "HIL_SENSOR stays last");
    }
    assert_eq!(server.stats().injections, 6);
    // GPS: fixes every 50 datagrams at 0, 50 (before the injection, answered with datagram 10), none while
    // off, again from 350 (the first fix time after the clear at 300).
    let fixes: Vec<usize> = (0..400).filter(|&k| has_gps(&datagrams[k])).collect();
    assert_eq!(fixes, [0, 350]);
    // Baro: in HIL_SENSOR until the injection answered with datagram 200; absent from 201 on.
    let home = autopilot::core::estimator::GeoOrigin { lat_deg: 0.0, lon_deg: 0.0, alt_amsl_m: 0.0 };
    for (k, d) in datagrams.iter().enumerate() {
        let Some(HilInput::Sensor(s)) = d.last().and_then(|m| decode_hil_message(m, &home)) else { panic!("sensor") };
        assert_eq!(s.baro.is_some(), k <= 200, "datagram {k}");
        assert!(s.mag_frd_gauss.is_some() && s.accel_frd_mps2.z < -9.0, "the rest as it was (accel not off)");
    }
    // Battery: BATTERY_STATUS every 0.1 s; from the injection on the autopilot's decoder reads it empty,
    // and its monitor says emergency.
    let mut monitor = BatteryMonitor::new(BatteryConfig::default()).expect("monitor");
    let mut seen = 0;
    for (k, d) in datagrams.iter().enumerate() {
        for m in d {
            if let Some(HilInput::Battery(b)) = decode_hil_message(m, &home) {
                if k > 250 {
                    assert_eq!(b.remaining, Some(0.0), "datagram {k}");
                    assert!((b.voltage_v - 6.0 * 3.27).abs() < 0.01, "the empty pack: {} V", b.voltage_v);
                    monitor.update(k as u64 * 2000, Some(b), true);
                    seen += 1;
                } else {
                    assert!(b.remaining.is_some_and(|r| r >= 0.99), "datagram {k}: full (whole percent, truncated)");
                }
            }
        }
    }
    assert_eq!(seen, 2, "BATTERY_STATUS at 0.6 and 0.7 s");
    assert_eq!(monitor.status(800_000).level, BatteryWarning::Emergency);
    let faults = server.plant().sensor_faults();
    assert_eq!((faults.fault(Sensor::Gps), faults.fault(Sensor::Baro)), (Fault::Ok, Fault::Off));
    assert_eq!(faults.fault(Sensor::Accel), Fault::Ok, "the unsupported injection changed nothing");
}

#[test]
fn given_the_sim_port_as_hook_then_an_injection_is_applied_through_it_and_its_clients_see_the_new_value() {
    let mut server = server(7);
    let sim = SimParamLink::bind("127.0.0.1:0", 1, server.plant()).expect("bind SIM_ port");
    let sim_addr = sim.local_addr().expect("addr");
    server.set_sim_port(sim);
    // A ground station on the SIM_ port, heard before the injection.
    let gcs = UdpSocket::bind("127.0.0.1:0").expect("gcs");
    gcs.set_read_timeout(Some(Duration::from_secs(2))).expect("timeout");
    let heartbeat = MavMessage::HEARTBEAT(mavlink::dialects::common::HEARTBEAT_DATA::default());
    gcs.send_to(&encode_frame_v2(MavHeader { system_id: 255, component_id: 190, sequence: 0 }, &heartbeat), sim_addr)
        .expect("send");
    // GPS stuck with the 3rd answer; 120 steps so the hook is polled after it (every 50 steps).
    let datagrams = run(&mut server, 120, &[(3, [4.0, 2.0, 1.0])]);
    let ack = acks(&datagrams[4]);
    assert_eq!(ack.len(), 1);
    assert_eq!(ack[0].result, MavResult::MAV_RESULT_ACCEPTED);
    assert_eq!(server.plant().sensor_faults().fault(Sensor::Gps), Fault::Stuck);
    let mut decoder = FrameDecoder::new();
    let mut buf = [0_u8; 2048];
    let mut value = None;
    while value.is_none() {
        let (n, _) = gcs.recv_from(&mut buf).expect("the SIM_ port's messages");
        for f in decoder.decode_datagram(&buf[..n]) {
            if let MavMessage::PARAM_VALUE(v) = f.message
                && autopilot::core::mavlink::params::param_name(&v.param_id) == "SIM_GPS_FAIL"
            {
                value = autopilot::core::mavlink::params::decode_value(v.param_type, v.param_value);
            }
        }
    }
    assert_eq!(value, Some(2.0), "the port shows SIM_GPS_FAIL = 2 (stuck)");
}

/// Step `server` `steps` times one by one against the test autopilot, setting the link's faults with
/// `at(k, plant)` before step k; each step's (plant time, time of the command applied).
fn stepped(server: &mut PlantServer<UdpTransport>, steps: usize, at: impl Fn(usize, &mut Plant)) -> Vec<(u64, u64)> {
    let stop = Arc::new(AtomicBool::new(false));
    let pwm = server.plant().config().airframe.hover_pwm_us();
    let plant_addr = server.transport().local_addr().expect("addr");
    let ap = autopilot(plant_addr, pwm, HashMap::new(), stop.clone());
    let never = AtomicBool::new(false);
    let mut out = Vec::with_capacity(steps);
    for k in 0..steps {
        at(k, server.plant_mut());
        let t = server.plant().time_us();
        let cmd = server.step(&never).expect("a step, never a deadlock");
        out.push((t, cmd.time_us));
    }
    stop.store(true, Ordering::Relaxed);
    let datagrams = ap.join().expect("autopilot");
    let times: Vec<u64> = datagrams
        .iter()
        .filter_map(|d| match d.last() {
            Some(MavMessage::HIL_SENSOR(s)) => Some(s.time_usec),
            _ => None,
        })
        .collect();
    assert!(times.windows(2).all(|w| w[0] < w[1]), "the autopilot's clock never goes back");
    out
}

#[test]
fn given_link_delay_and_loss_then_the_plant_steps_on_held_commands_deterministically_without_a_deadlock() {
    // 10 ms delay from step 200, 20 % loss from 500, no delay from 900, no loss from 1200.
    let faults = |k: usize, plant: &mut Plant| {
        let link = plant.link_faults_mut();
        match k {
            200 => link.set_delay_us(10_000),
            500 => link.set_loss_pct(20.0),
            900 => link.set_delay_us(0),
            1200 => link.set_loss_pct(0.0),
            _ => {}
        }
    };
    let mut first = server(11);
    let steps = stepped(&mut first, 1500, faults);
    let stats = first.stats();
    assert_eq!(stats.resends, 0, "a lost datagram is never waited for: {stats:?}");
    assert_eq!(stats.steps, 1500);
    let mut held = [0_usize; 4];
    for (k, (t, cmd_t)) in steps.iter().enumerate() {
        let fresh = k == 0 || *cmd_t != steps[k - 1].1;
        let phase = match k {
            0..200 => 0,
            200..900 => 1,
            900..1200 => 2,
            _ => 3,
        };
        if !fresh {
            held[phase] += 1;
            continue;
        }
        let age_us = t - cmd_t;
        match phase {
            1 => assert_eq!(age_us, 10_000, "step {k}: the command answers the sample of 10 ms ago"),
            _ => assert_eq!(age_us, 0, "step {k}: the command answers this step's sample"),
        }
    }
    println!("held steps per phase {held:?}; {stats:?}");
    assert_eq!(held[0], 0);
    // Delay on: 5 steps (10 ms) with nothing to deliver; then 20 % of 400 steps lost.
    let lost_delay_phase = held[1] - 5;
    assert!((50..=110).contains(&lost_delay_phase), "{held:?}");
    // Loss alone (and the delay falling at 900: the 5 samples in flight dropped for the newest).
    assert!((35..=90).contains(&held[2]), "{held:?}");
    assert_eq!(held[3], 0, "no loss, no delay: nothing held");
    assert_eq!(stats.held_steps as usize, held.iter().sum::<usize>());
    // The same seed loses the same datagrams.
    let mut second = server(11);
    assert_eq!(stepped(&mut second, 1500, faults), steps, "bit-identical rerun");
    assert_eq!(second.stats().lost, stats.lost);
}
