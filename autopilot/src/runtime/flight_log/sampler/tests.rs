//! The flight log's sampler over flights of the vehicle: one file per flight, every topic at its rate,
//! texts as logged strings, drops when the writer falls behind; and the helpers other log tests share.

use super::*;
use crate::core::commander::State;
use crate::core::config::VehicleConfig;
use crate::core::estimator::{EstimatorSource, GeoOrigin};
use crate::core::manual::RcFrame;
use crate::core::mavlink::MavHeader;
use crate::core::mavlink::command_long;
use crate::core::mavlink::common::{MavCmd, MavMessage};
use crate::core::vehicle::VehicleInputs;
use crate::runtime::flight_log::{ULOG_CHANNEL_CAPACITY, UlogWriter};
use crate::runtime::ulog::read_messages;

const GCS: MavHeader = MavHeader { system_id: 255, component_id: 190, sequence: 0 };

pub(crate) fn scratch(test: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("autopilot-ulog-{test}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

pub(crate) fn vehicle() -> Vehicle {
    let mut config = VehicleConfig::default();
    config.estimator.source = EstimatorSource::Truth;
    config.estimator.truth_origin = Some(GeoOrigin { lat_deg: 47.4, lon_deg: 8.5, alt_amsl_m: 488.0 });
    Vehicle::new(config).expect("valid")
}

fn at_rest(time_us: u64) -> VehicleInputs {
    VehicleInputs::at_rest_truth(time_us)
}

/// Steps the vehicle for `seconds` as the plant link does, the logger around each step.
fn fly(v: &mut Vehicle, log: &mut FlightLogger, t_us: &mut u64, seconds: f64) {
    fly_with(v, log, t_us, seconds, None);
}

/// As [`fly`], with the radio frame `rc` arriving at every step.
fn fly_with(v: &mut Vehicle, log: &mut FlightLogger, t_us: &mut u64, seconds: f64, rc: Option<RcFrame>) {
    let end = *t_us + (seconds * 1e6) as u64;
    while *t_us < end {
        let out = v.step(*t_us, &VehicleInputs { rc, ..at_rest(*t_us) });
        log.begin_step(*t_us, v);
        for m in &out.messages {
            if let MavMessage::STATUSTEXT(s) = m {
                log.text(*t_us, s.severity, s.text.to_str().unwrap_or(""));
            }
        }
        log.end_step(*t_us, v);
        *t_us += 2_000;
    }
}

fn drain(rx: &mut mpsc::Receiver<LogItem>, writer: &mut UlogWriter) -> Vec<PathBuf> {
    let mut closed = Vec::new();
    while let Ok(item) = rx.try_recv() {
        closed.extend(writer.handle(item).expect("written"));
    }
    closed
}

/// Data messages of a file, per topic name: (timestamp, payload).
fn topics_of(bytes: &[u8]) -> std::collections::HashMap<String, Vec<Vec<u8>>> {
    let (_, msgs) = read_messages(bytes).expect("parses");
    let mut names = std::collections::HashMap::new();
    let mut data: std::collections::HashMap<String, Vec<Vec<u8>>> = std::collections::HashMap::new();
    for m in &msgs {
        match m.kind {
            b'A' => {
                let id = u16::from_le_bytes([m.body[1], m.body[2]]);
                names.insert(id, String::from_utf8(m.body[3..].to_vec()).expect("utf8"));
            }
            b'D' => {
                let id = u16::from_le_bytes([m.body[0], m.body[1]]);
                data.entry(names[&id].clone()).or_default().push(m.body[2..].to_vec());
            }
            _ => {}
        }
    }
    data
}

#[test]
fn an_armed_flight_is_one_file_with_every_topic_at_its_rate_and_the_texts_as_logged_strings() {
    let root = scratch("flight");
    let (tx, mut rx) = mpsc::channel(ULOG_CHANNEL_CAPACITY);
    let mut log = FlightLogger::new(Some(tx), root.clone(), 1);
    let mut writer = UlogWriter::default();
    let (mut v, mut t) = (vehicle(), 0);
    // GIVEN a vehicle on the ground: nothing is written while it is disarmed.
    fly(&mut v, &mut log, &mut t, 1.0);
    assert!(!log.logging());
    assert!(drain(&mut rx, &mut writer).is_empty() && !root.exists());
    // WHEN it arms, idles 2 s and disarms.
    let arm = command_long(1, 0, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    v.handle_message(t, &GCS, &arm);
    let armed_at = t;
    fly(&mut v, &mut log, &mut t, 2.0);
    assert!(log.logging());
    assert_eq!(v.commander().state(), State::ArmedIdle);
    let disarm = command_long(1, 0, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [0.0; 7]);
    v.handle_message(t, &GCS, &disarm);
    fly(&mut v, &mut log, &mut t, 0.5);
    // THEN one file, finalized, under <root>/<date>/<time>.ulg.
    let closed = drain(&mut rx, &mut writer);
    assert_eq!(closed.len(), 1, "{closed:?}");
    assert!(!log.logging());
    let path = &closed[0];
    assert_eq!(path.extension().and_then(|e| e.to_str()), Some("ulg"));
    let date_dir = path.parent().expect("dir");
    assert_eq!(date_dir.parent(), Some(root.as_path()));
    assert_eq!(date_dir.file_name().and_then(|n| n.to_str()).map(str::len), Some(10), "YYYY-MM-DD");
    assert!(!path.with_extension("ulg.tmp").exists());
    let bytes = std::fs::read(path).expect("read");
    let (start_us, msgs) = read_messages(&bytes).expect("parses");
    assert_eq!(start_us, armed_at);
    assert_eq!(msgs[0].kind, b'B', "flag bits right after the header");
    let first_a = msgs.iter().position(|m| m.kind == b'A').expect("subscriptions");
    assert!(msgs[..first_a].iter().all(|m| b"BFIPQ".contains(&m.kind)), "definitions first");
    let params = msgs.iter().filter(|m| m.kind == b'P').count();
    assert_eq!(params, v.params().len(), "every parameter");
    let key = |m: &ulog::ReadMessage| String::from_utf8_lossy(&m.body[1..1 + usize::from(m.body[0])]).into_owned();
    assert!(msgs.iter().any(|m| m.kind == b'P' && key(m) == "int32_t SDLOG_MODE"));
    assert!(msgs.iter().any(|m| m.kind == b'P' && key(m) == "float MPC_XY_CRUISE"));
    let data = topics_of(&bytes);
    let count = |name: &str| data.get(name).map_or(0, Vec::len);
    // 2 s armed (and the disarming step): 50 Hz topics about 100 records, 10 Hz about 20, 5 Hz about 10.
    for (name, hz) in [("vehicle_attitude", 50), ("actuator_outputs", 50), ("controller_status", 50)] {
        assert!((2 * hz..=2 * hz + 2).contains(&count(name)), "{name}: {}", count(name));
    }
    for (name, hz) in
        [("aco_weights", 10), ("estimator_innovations", 10), ("estimator_status_flags", 10), ("battery_status", 5)]
    {
        assert!((2 * hz..=2 * hz + 2).contains(&count(name)), "{name}: {}", count(name));
    }
    // vehicle_status: at arming, once a second, and at the disarm: armed then disarmed (1).
    let status = &data["vehicle_status"];
    assert!(status.len() >= 3, "{}", status.len());
    assert_eq!(status[0][16], 2, "armed");
    assert_eq!(u64::from_le_bytes(status[0][8..16].try_into().expect("8")), armed_at, "armed_time");
    assert_eq!(status.last().map(|s| s[16]), Some(1), "disarmed at the end");
    // Every record is its format's size; attitude is the identity quaternion (w first).
    assert!(data["vehicle_attitude"].iter().all(|r| r[16..20] == 1.0f32.to_le_bytes()));
    let texts: Vec<String> =
        msgs.iter().filter(|m| m.kind == b'L').map(|m| String::from_utf8_lossy(&m.body[9..]).into_owned()).collect();
    assert_eq!(texts.first().map(String::as_str), Some("Armed"), "{texts:?}");
    assert!(texts.iter().any(|t| t == "Disarmed"), "{texts:?}");
    assert!(msgs.iter().any(|m| m.kind == b'S'), "sync markers");
    // A second flight is a second file.
    v.handle_message(t, &GCS, &arm);
    fly(&mut v, &mut log, &mut t, 0.2);
    log.close();
    assert_eq!(drain(&mut rx, &mut writer).len(), 1);
    assert_eq!(log.stats().flights, 2);
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn sdlog_mode_minus_one_logs_nothing() {
    let root = scratch("off");
    let (tx, mut rx) = mpsc::channel(16);
    let mut log = FlightLogger::new(Some(tx), root.clone(), 1);
    let (mut v, mut t) = (vehicle(), 0);
    let set = MavMessage::PARAM_SET(crate::core::mavlink::common::PARAM_SET_DATA {
        param_value: f32::from_le_bytes((-1i32).to_le_bytes()),
        target_system: 1,
        target_component: 1,
        param_id: "SDLOG_MODE".into(),
        param_type: crate::core::mavlink::common::MavParamType::MAV_PARAM_TYPE_INT32,
    });
    v.handle_message(t, &GCS, &set);
    assert_eq!(v.params().sdlog_mode(), -1);
    fly(&mut v, &mut log, &mut t, 0.5);
    let arm = command_long(1, 0, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    v.handle_message(t, &GCS, &arm);
    fly(&mut v, &mut log, &mut t, 0.5);
    assert!(v.commander_output().armed && !log.logging());
    assert!(rx.try_recv().is_err());
}

#[test]
fn a_writer_that_falls_behind_costs_records_not_the_loop_and_says_so_with_a_dropout() {
    let root = scratch("behind");
    let (tx, mut rx) = mpsc::channel(4);
    let mut log = FlightLogger::new(Some(tx), root.clone(), 1);
    let (mut v, mut t) = (vehicle(), 0);
    fly(&mut v, &mut log, &mut t, 0.5);
    let arm = command_long(1, 0, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    v.handle_message(t, &GCS, &arm);
    // Nobody drains the queue for 1 s: of the 50 batches (one per step with a 50 Hz topic due), all but
    // the four the queue holds are dropped, and no step waits.
    fly(&mut v, &mut log, &mut t, 1.0);
    assert!(log.stats().dropped >= 45, "{:?}", log.stats());
    let mut writer = UlogWriter::default();
    assert!(drain(&mut rx, &mut writer).is_empty());
    fly(&mut v, &mut log, &mut t, 0.04);
    log.close();
    let closed = drain(&mut rx, &mut writer);
    let bytes = std::fs::read(&closed[0]).expect("read");
    let (_, msgs) = read_messages(&bytes).expect("a file with a gap still parses");
    assert!(msgs.iter().any(|m| m.kind == b'O'), "a dropout marker");
    let _ = std::fs::remove_dir_all(&root);
}

fn f32_at(r: &[u8], at: usize) -> f32 {
    f32::from_le_bytes(r[at..at + 4].try_into().expect("4 bytes"))
}

#[test]
fn a_flight_with_a_radio_logs_input_rc_and_manual_control_setpoint_as_px4_names_them_and_one_without_logs_neither() {
    let root = scratch("radio");
    let (tx, mut rx) = mpsc::channel(ULOG_CHANNEL_CAPACITY);
    let mut log = FlightLogger::new(Some(tx), root.clone(), 1);
    let mut writer = UlogWriter::default();
    let (mut v, mut t) = (vehicle(), 0);
    let arm = command_long(1, 0, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    let disarm = command_long(1, 0, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [0.0; 7]);
    // GIVEN a flight without a radio: neither topic has a record.
    fly(&mut v, &mut log, &mut t, 0.5);
    v.handle_message(t, &GCS, &arm);
    fly(&mut v, &mut log, &mut t, 1.0);
    v.handle_message(t, &GCS, &disarm);
    fly(&mut v, &mut log, &mut t, 0.1);
    let closed = drain(&mut rx, &mut writer);
    let data = topics_of(&std::fs::read(&closed[0]).expect("read"));
    assert!(!data.contains_key("input_rc") && !data.contains_key("manual_control_setpoint"), "{:?}", data.keys());
    // WHEN a radio (AETR: roll right of centre, throttle a quarter, RSSI 200 of 254) sends every step
    // through an armed flight of 2 s.
    let mut frame = RcFrame::of(&[1600, 1500, 1250, 1500, 1000, 2000, 1000, 1000]);
    frame.rssi = 200;
    fly_with(&mut v, &mut log, &mut t, 0.5, Some(frame));
    v.handle_message(t, &GCS, &arm);
    fly_with(&mut v, &mut log, &mut t, 2.0, Some(frame));
    let sticks = v.log_snapshot().manual.sticks.expect("the radio's sticks in use");
    v.handle_message(t, &GCS, &disarm);
    fly_with(&mut v, &mut log, &mut t, 0.1, Some(frame));
    let closed = drain(&mut rx, &mut writer);
    let data = topics_of(&std::fs::read(&closed[0]).expect("read"));
    // THEN input_rc every 500 ms: the frame's channels, count, RSSI on PX4's 0-100 scale, the last
    // signal this step's, not lost.
    let rc = &data["input_rc"];
    assert!((4..=5).contains(&rc.len()), "{}", rc.len());
    for r in rc {
        let stamp = u64::from_le_bytes(r[..8].try_into().expect("8"));
        assert_eq!(u64::from_le_bytes(r[8..16].try_into().expect("8")), stamp, "timestamp_last_signal");
        assert_eq!((r[16], i32::from_le_bytes(r[17..21].try_into().expect("4"))), (8, 79), "count, rssi");
        assert_eq!((r[21], r[22]), (0, 0), "not in failsafe, not lost");
        let values: Vec<u16> = (0..18).map(|i| u16::from_le_bytes([r[23 + 2 * i], r[24 + 2 * i]])).collect();
        assert_eq!(values, frame.channels_us);
    }
    // AND manual_control_setpoint every 200 ms: valid, from the radio (1), the sticks in use with PX4's
    // throttle in [-1, 1].
    let mc = &data["manual_control_setpoint"];
    assert!((10..=11).contains(&mc.len()), "{}", mc.len());
    for r in mc {
        assert_eq!((r[8], r[9]), (1, 1), "valid, SOURCE_RC");
        let logged = [f32_at(r, 10), f32_at(r, 14), f32_at(r, 18), f32_at(r, 22)];
        let want = [sticks.roll, sticks.pitch, sticks.yaw, 2.0 * sticks.throttle - 1.0].map(|x| x as f32);
        assert_eq!(logged, want);
    }
    assert!(sticks.roll > 0.1 && sticks.throttle < 0.5, "{sticks:?}");
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_flight_logs_plant_link_status_once_a_second_with_the_links_bytes_bad_frames_and_samples_missing_and_late() {
    use crate::core::plant_link::health::PlantLinkCounters;
    let root = scratch("plantlink");
    let (tx, mut rx) = mpsc::channel(ULOG_CHANNEL_CAPACITY);
    let mut log = FlightLogger::new(Some(tx), root.clone(), 1);
    let mut writer = UlogWriter::default();
    let (mut v, mut t) = (vehicle(), 0);
    fly(&mut v, &mut log, &mut t, 0.5);
    let arm = command_long(1, 0, MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]);
    v.handle_message(t, &GCS, &arm);
    // GIVEN an armed flight of 3 s whose link carries 120 bytes in and 60 out per sample period, loses
    // every tenth sample, resends one sample a second and has a bad frame every 100 periods.
    let k0 = t / 2_000;
    let counters = |k: u64| PlantLinkCounters { rx_bytes: 120 * k, tx_bytes: 60 * k, bad_frames: k / 100 };
    for k in k0..k0 + 1_500 {
        let t_us = k * 2_000;
        if k % 10 == 5 {
            continue;
        }
        let repeats = if k % 500 == 7 { 2 } else { 1 };
        for _ in 0..repeats {
            let inputs = VehicleInputs { plant_link: Some(counters(k)), ..at_rest(t_us) };
            let out = v.step(t_us, &inputs);
            log.begin_step(t_us, &v);
            for m in &out.messages {
                if let MavMessage::STATUSTEXT(s) = m {
                    log.text(t_us, s.severity, s.text.to_str().unwrap_or(""));
                }
            }
            log.end_step(t_us, &v);
        }
    }
    log.close();
    let closed = drain(&mut rx, &mut writer);
    let data = topics_of(&std::fs::read(&closed[0]).expect("read"));
    // THEN plant_link_status once a second: the shell's counts, the byte rates over the last second,
    // and the samples missing and late so far with the last second's drop rate.
    let records = &data["plant_link_status"];
    assert!((3..=4).contains(&records.len()), "{}", records.len());
    let u64_at = |r: &[u8], at: usize| u64::from_le_bytes(r[at..at + 8].try_into().expect("8 bytes"));
    for r in records {
        assert_eq!(r.len(), 8 + 8 + 4 + 8 + 4 + 8 * 4 + 4, "timestamp and nine fields");
        let k = u64_at(r, 0) / 2_000;
        let c = counters(k);
        assert_eq!([u64_at(r, 8), u64_at(r, 20), u64_at(r, 32)], [c.rx_bytes, c.tx_bytes, c.bad_frames]);
        let stepped = (k0..=k).filter(|j| j % 10 != 5);
        let missing = (k0..k).filter(|j| j % 10 == 5).count() as u64;
        let late = (k0..=k).filter(|j| j % 500 == 7).count() as u64;
        assert_eq!(u64_at(r, 48), missing, "missing_samples at {k}");
        assert_eq!(u64_at(r, 56), late, "late_samples at {k}");
        assert_eq!(u64_at(r, 40), 250 + stepped.count() as u64, "received_samples: 0.5 s before, then these");
        if k >= k0 + 500 {
            // A whole second of the flight behind it: 60000 and 30000 bytes/s, 10 % missing.
            assert_eq!([f32_at(r, 16), f32_at(r, 28), f32_at(r, 64)], [60_000.0, 30_000.0, 10.0], "at {k}");
        }
    }
    let _ = std::fs::remove_dir_all(&root);
}

#[test]
fn a_motor_test_on_the_disarmed_vehicle_is_logged_with_actuator_outputs_showing_the_motor_at_its_pwm() {
    let root = scratch("motortest");
    let (tx, mut rx) = mpsc::channel(ULOG_CHANNEL_CAPACITY);
    let mut log = FlightLogger::new(Some(tx), root.clone(), 1);
    let mut writer = UlogWriter::default();
    let (mut v, mut t) = (vehicle(), 0);
    fly(&mut v, &mut log, &mut t, 0.2);
    // WHEN motor 3 is tested at 20 % for 1 s on the disarmed vehicle.
    let test = command_long(1, 0, MavCmd::MAV_CMD_DO_MOTOR_TEST, [3.0, 0.0, 20.0, 1.0, 0.0, 0.0, 0.0]);
    v.handle_message(t, &GCS, &test);
    fly(&mut v, &mut log, &mut t, 1.5);
    // THEN one file, closed when the test ended, whose actuator_outputs show output 3 at 1200 µs and
    // the others at 1000 µs, for the test's second (50 Hz: 50 records, one more at each end at most).
    assert!(!log.logging() && !v.commander_output().armed);
    let closed = drain(&mut rx, &mut writer);
    assert_eq!(closed.len(), 1, "{closed:?}");
    let data = topics_of(&std::fs::read(&closed[0]).expect("read"));
    let outputs: Vec<[f32; 4]> =
        data["actuator_outputs"].iter().map(|r| [f32_at(r, 12), f32_at(r, 16), f32_at(r, 20), f32_at(r, 24)]).collect();
    let spinning = outputs.iter().filter(|o| **o == [1000.0, 1000.0, 1200.0, 1000.0]).count();
    assert!((50..=51).contains(&spinning), "{spinning} of {outputs:?}");
    assert!(outputs.iter().all(|o| *o == [1000.0, 1000.0, 1200.0, 1000.0] || *o == [1000.0; 4]), "{outputs:?}");
    let _ = std::fs::remove_dir_all(&root);
}
