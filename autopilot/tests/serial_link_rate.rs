//! The serial ground-station link fits a 57600-baud line: the runtime's [`SerialLink`] on one end of a
//! pseudo-terminal pair, fed the vehicle's stream synthetically (the ids and default rates of
//! `telemetry.rs`, the five ACO weight vectors, HEARTBEAT at 1 Hz: about 2.9 kB/s), a parameter list burst
//! (the vehicle's 228 PARAM_VALUEs at once) with a COMMAND_ACK right after it, and a radio's RADIO_STATUS
//! written on the far end. Measured on the far end, on the producer's clock (the messages' `time_boot_ms`)
//! for rates and on arrival for bytes: the bytes in any second fit 5760 B/s, HEARTBEAT keeps 1 Hz, the
//! COMMAND_ACK does not wait behind the burst, a RADIO_STATUS with txbuf 20 halves ATTITUDE within a
//! second, and txbuf 100 at 1 Hz brings it back to 20 Hz. Unix only (a pty pair); about 15 s of wall time.
#![cfg(unix)]

use std::io::{Read, Write};
use std::net::SocketAddr;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use autopilot::core::mavlink::common::{
    ATTITUDE_DATA, ATTITUDE_QUATERNION_DATA, BATTERY_STATUS_DATA, COMMAND_ACK_DATA, DEBUG_VECT_DATA,
    EXTENDED_SYS_STATE_DATA, GLOBAL_POSITION_INT_DATA, GPS_RAW_INT_DATA, GpsFixType, HEARTBEAT_DATA,
    HOME_POSITION_DATA, LOCAL_POSITION_NED_DATA, MISSION_CURRENT_DATA, MavCmd, MavMessage, MavParamType, MavResult,
    PARAM_VALUE_DATA, RADIO_STATUS_DATA, RC_CHANNELS_DATA, SYS_STATUS_DATA, VFR_HUD_DATA,
};
use autopilot::core::mavlink::telemetry::WEIGHT_VECTORS;
use autopilot::core::mavlink::{MavHeader, Stream};
use autopilot::core::plant_link::budget::bytes_per_s_of_baud;
use autopilot::core::plant_link::{FrameDecoder, encode_frame_v2};
use autopilot::runtime::link::{CHANNEL_CAPACITY, Destination, Outgoing};
use autopilot::runtime::serial::{SerialConfig, SerialLink};
use autopilot::runtime::shutdown;
use serialport::{SerialPort, TTYPort};
use tokio::sync::mpsc;

const BAUD: u32 = 57_600;
/// When the parameter list is queued (s from the start), and the COMMAND_ACK after it.
const PARAMS_AT: f64 = 4.0;
const ACK_AT: f64 = 4.02;
const PARAMS: u16 = 228;
/// The radio's reports: (s from the start, txbuf %).
const RADIO: [(f64, u8); 8] =
    [(7.0, 20), (8.0, 40), (9.0, 40), (10.0, 100), (11.0, 100), (12.0, 100), (13.0, 100), (14.0, 100)];
const END: f64 = 15.3;
const VEHICLE: MavHeader = MavHeader { system_id: 1, component_id: 1, sequence: 0 };
const SERIAL_PEER: SocketAddr = SocketAddr::V4(std::net::SocketAddrV4::new(std::net::Ipv4Addr::UNSPECIFIED, 0));

/// One emission of `stream` at `ms` of vehicle time, its fields filled as the vehicle fills them.
fn emission(stream: Stream, ms: u32) -> Vec<MavMessage> {
    let us = u64::from(ms) * 1000;
    let m = match stream {
        Stream::SysStatus => MavMessage::SYS_STATUS(SYS_STATUS_DATA {
            load: 250,
            voltage_battery: 16_200,
            current_battery: 1200,
            drop_rate_comm: 1,
            errors_comm: 2,
            errors_count1: 3,
            battery_remaining: 87,
            ..SYS_STATUS_DATA::default()
        }),
        Stream::Attitude => MavMessage::ATTITUDE(ATTITUDE_DATA {
            time_boot_ms: ms,
            roll: 0.01,
            pitch: -0.02,
            yaw: 1.5,
            rollspeed: 0.001,
            pitchspeed: 0.002,
            yawspeed: 0.003,
        }),
        Stream::AttitudeQuaternion => MavMessage::ATTITUDE_QUATERNION(ATTITUDE_QUATERNION_DATA {
            time_boot_ms: ms,
            q1: 0.7,
            q2: 0.01,
            q3: 0.02,
            q4: 0.7,
            rollspeed: 0.001,
            pitchspeed: 0.002,
            yawspeed: 0.003,
            ..ATTITUDE_QUATERNION_DATA::default()
        }),
        Stream::LocalPositionNed => MavMessage::LOCAL_POSITION_NED(LOCAL_POSITION_NED_DATA {
            time_boot_ms: ms,
            x: 1.0,
            y: 2.0,
            z: -1.5,
            vx: 0.1,
            vy: 0.2,
            vz: 0.3,
        }),
        Stream::GlobalPositionInt => MavMessage::GLOBAL_POSITION_INT(GLOBAL_POSITION_INT_DATA {
            time_boot_ms: ms,
            lat: 473_977_420,
            lon: 85_455_940,
            alt: 489_500,
            relative_alt: 1500,
            vx: 10,
            vy: 20,
            vz: 30,
            hdg: 9000,
        }),
        Stream::GpsRawInt => MavMessage::GPS_RAW_INT(GPS_RAW_INT_DATA {
            time_usec: us,
            lat: 473_977_420,
            lon: 85_455_940,
            alt: 489_500,
            eph: 70,
            epv: 120,
            vel: 22,
            cog: 9000,
            fix_type: GpsFixType::GPS_FIX_TYPE_3D_FIX,
            satellites_visible: 12,
            ..GPS_RAW_INT_DATA::default()
        }),
        Stream::ExtendedSysState => MavMessage::EXTENDED_SYS_STATE(EXTENDED_SYS_STATE_DATA::default()),
        Stream::HomePosition => MavMessage::HOME_POSITION(HOME_POSITION_DATA {
            latitude: 473_977_420,
            longitude: 85_455_940,
            altitude: 488_000,
            q: [1.0, 0.0, 0.0, 0.0],
            time_usec: us,
            ..HOME_POSITION_DATA::default()
        }),
        Stream::VfrHud => MavMessage::VFR_HUD(VFR_HUD_DATA {
            airspeed: 0.2,
            groundspeed: 0.2,
            alt: 489.5,
            climb: 0.1,
            heading: 90,
            throttle: 45,
        }),
        Stream::BatteryStatus => MavMessage::BATTERY_STATUS(BATTERY_STATUS_DATA {
            current_consumed: 120,
            energy_consumed: -1,
            temperature: i16::MAX,
            voltages: [4050, 4050, 4050, 4050, u16::MAX, u16::MAX, u16::MAX, u16::MAX, u16::MAX, u16::MAX],
            current_battery: 1200,
            id: 0,
            battery_remaining: 87,
            ..BATTERY_STATUS_DATA::default()
        }),
        Stream::MissionCurrent => {
            MavMessage::MISSION_CURRENT(MISSION_CURRENT_DATA { seq: 3, total: 20, ..MISSION_CURRENT_DATA::default() })
        }
        Stream::AdaptiveWeights => {
            // ACO's five vectors.
            return WEIGHT_VECTORS
                .iter()
                .filter(|(name, _)| name.starts_with("aco."))
                .map(|(name, _)| {
                    MavMessage::DEBUG_VECT(DEBUG_VECT_DATA {
                        time_usec: us,
                        x: 0.1,
                        y: 0.2,
                        z: 0.3,
                        name: (*name).into(),
                    })
                })
                .collect();
        }
        Stream::RcChannels => MavMessage::RC_CHANNELS(RC_CHANNELS_DATA::default()),
    };
    vec![m]
}

/// A received frame: arrival (s from the start), size, message.
type Arrival = (f64, usize, MavMessage);

/// The far end: reads and decodes everything, and writes the radio's reports on their schedule.
/// The port is handed back, not closed: a pty whose other end closes hangs up on the link.
fn far_end(mut port: TTYPort, start: Instant, stop: &AtomicBool) -> (Vec<Arrival>, TTYPort) {
    port.set_timeout(Duration::from_millis(5)).expect("timeout");
    let radio_header = MavHeader { system_id: 51, component_id: 68, sequence: 0 };
    let mut decoder = FrameDecoder::new();
    let mut buf = [0_u8; 4096];
    let mut got = Vec::new();
    let mut reports = RADIO.iter().peekable();
    while !stop.load(Ordering::Relaxed) {
        let now = start.elapsed().as_secs_f64();
        if let Some(&&(at, txbuf)) = reports.peek()
            && now >= at
        {
            let radio =
                RADIO_STATUS_DATA { rssi: 200, remrssi: 190, txbuf, noise: 40, remnoise: 42, ..Default::default() };
            port.write_all(&encode_frame_v2(radio_header, &MavMessage::RADIO_STATUS(radio))).expect("radio report");
            reports.next();
        }
        let n = match port.read(&mut buf) {
            Ok(n) => n,
            Err(e) if e.kind() == std::io::ErrorKind::TimedOut => continue,
            Err(e) => panic!("reading the pty: {e}"),
        };
        let now = start.elapsed().as_secs_f64();
        for f in decoder.push(&buf[..n]) {
            let bytes = encode_frame_v2(f.header, &f.message).len();
            got.push((now, bytes, f.message));
        }
    }
    (got, port)
}

fn attitude_count(got: &[Arrival], from_s: f64, to_s: f64) -> usize {
    got.iter()
        .filter(|(_, _, m)| match m {
            MavMessage::ATTITUDE(a) => (from_s..to_s).contains(&(f64::from(a.time_boot_ms) / 1000.0)),
            _ => false,
        })
        .count()
}

#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn given_a_57600_line_then_the_streams_fit_heartbeats_and_acks_go_first_and_the_radio_thins_the_streams() {
    let (far, near) = TTYPort::pair().expect("a pty pair");
    let path = near.name().expect("the near end's path");
    let config = SerialConfig { link: 0, path, baud: BAUD, data_rate: bytes_per_s_of_baud(BAUD) };
    let link = SerialLink::open(&config).expect("open the link");
    let (in_tx, mut in_rx) = mpsc::channel(CHANNEL_CAPACITY);
    let (out_tx, out_rx) = mpsc::channel(CHANNEL_CAPACITY);
    let (trigger, shutdown) = shutdown::channel();
    let start = Instant::now();
    let task = tokio::spawn(link.run(in_tx, out_rx, shutdown));
    let stop = Arc::new(AtomicBool::new(false));
    let reader = {
        let stop = stop.clone();
        std::thread::spawn(move || far_end(far, start, &stop))
    };

    // The vehicle: every 2 ms of its clock, what is due.
    let send = |message: MavMessage, to: Destination| {
        out_tx.try_send(Outgoing { to, header: VEHICLE, message }).expect("the link keeps up with its queue");
    };
    let streams: Vec<Stream> = Stream::ALL.into_iter().filter(|s| *s != Stream::RcChannels).collect();
    let mut due_ms = vec![0_u64; streams.len()];
    let mut heartbeat_due_ms = 0;
    let (mut params_sent, mut ack_sent) = (false, false);
    let mut tick = tokio::time::interval(Duration::from_millis(2));
    let mut offered_bytes = 0;
    loop {
        tick.tick().await;
        let t = start.elapsed().as_secs_f64();
        if t >= END {
            break;
        }
        let ms = (t * 1000.0) as u64;
        if ms >= heartbeat_due_ms {
            send(MavMessage::HEARTBEAT(HEARTBEAT_DATA::default()), Destination::All);
            heartbeat_due_ms += 1000;
        }
        for (s, due) in streams.iter().zip(due_ms.iter_mut()) {
            if ms >= *due {
                for m in emission(*s, ms as u32) {
                    offered_bytes += encode_frame_v2(VEHICLE, &m).len();
                    send(m, Destination::All);
                }
                *due += s.default_interval_us() / 1000;
            }
        }
        if t >= PARAMS_AT && !params_sent {
            for index in 0..PARAMS {
                let value = PARAM_VALUE_DATA {
                    param_value: 0.5,
                    param_count: PARAMS,
                    param_index: index,
                    param_id: format!("MPC_XY_VEL_{index:03}").as_str().into(),
                    param_type: MavParamType::MAV_PARAM_TYPE_REAL32,
                };
                send(MavMessage::PARAM_VALUE(value), Destination::All);
            }
            params_sent = true;
        }
        if t >= ACK_AT && !ack_sent {
            let ack = COMMAND_ACK_DATA {
                command: MavCmd::MAV_CMD_REQUEST_MESSAGE,
                result: MavResult::MAV_RESULT_ACCEPTED,
                ..COMMAND_ACK_DATA::default()
            };
            send(MavMessage::COMMAND_ACK(ack), Destination::Peer(SERIAL_PEER));
            ack_sent = true;
        }
    }
    tokio::time::sleep(Duration::from_millis(200)).await;
    stop.store(true, Ordering::Relaxed);
    let (got, far) = reader.join().expect("the far end");
    trigger.fire();
    task.await.expect("the link task").expect("the link stops cleanly");
    drop((near, far));

    // The radio's reports went to the core as well.
    let mut radio_in = 0;
    while let Ok(incoming) = in_rx.try_recv() {
        radio_in += usize::from(matches!(incoming.message, MavMessage::RADIO_STATUS(_)));
    }
    assert_eq!(radio_in, RADIO.len(), "every RADIO_STATUS reaches the core too");

    let offered_rate = offered_bytes as f64 / END;
    // Bytes per second of arrival, over every 1 s window on a 100 ms grid: the data rate, plus the
    // pacer's one frame, plus 5 % for the reader's scheduling (a late read bunches what was paced).
    let mut worst = 0;
    for k in 0..((END - 1.0) * 10.0) as usize {
        let from = k as f64 / 10.0;
        let bytes: usize = got.iter().filter(|(t, _, _)| (from..from + 1.0).contains(t)).map(|(_, b, _)| b).sum();
        worst = worst.max(bytes);
    }
    let steady: usize = got.iter().filter(|(t, _, _)| (1.0..4.0).contains(t)).map(|(_, b, _)| b).sum();
    let steady_rate = steady as f64 / 3.0;
    let heartbeats: Vec<f64> =
        got.iter().filter(|(_, _, m)| matches!(m, MavMessage::HEARTBEAT(_))).map(|(t, _, _)| *t).collect();
    let longest_heartbeat_gap = heartbeats.windows(2).map(|w| w[1] - w[0]).fold(0.0, f64::max);
    let params: Vec<f64> =
        got.iter().filter(|(_, _, m)| matches!(m, MavMessage::PARAM_VALUE(_))).map(|(t, _, _)| *t).collect();
    let ack_at =
        got.iter().find(|(_, _, m)| matches!(m, MavMessage::COMMAND_ACK(_))).map(|(t, _, _)| *t).expect("the ACK");
    let params_done = params.last().copied().unwrap_or(f64::NAN);
    let attitude_before = attitude_count(&got, 1.0, 4.0) as f64 / 3.0;
    let attitude_halved = attitude_count(&got, 8.0, 10.0) as f64 / 2.0;
    let attitude_back = attitude_count(&got, 13.2, 15.2) as f64 / 2.0;
    eprintln!(
        "57600 baud: offered {offered_rate:.0} B/s; received {steady_rate:.0} B/s steady, at most {worst} B in any \
         1 s; heartbeats {} (longest gap {longest_heartbeat_gap:.2} s); {} PARAM_VALUE done {:.2} s after queueing; \
         COMMAND_ACK {:.0} ms after queueing; ATTITUDE {attitude_before} Hz, {attitude_halved} Hz after txbuf 20, \
         {attitude_back} Hz after txbuf 100",
        heartbeats.len(),
        params.len(),
        params_done - PARAMS_AT,
        (ack_at - ACK_AT) * 1000.0,
    );

    assert!(offered_rate > 2500.0, "the synthetic stream is the vehicle's size: {offered_rate:.0} B/s");
    assert!(worst as f64 <= 5760.0 * 1.05 + 280.0, "at most {worst} B in one second");
    assert!(steady_rate > 2500.0, "the streams fit a 57600 line whole: {steady_rate:.0} B/s");
    assert!(heartbeats.len() >= 15 && longest_heartbeat_gap < 1.2, "{heartbeats:?}");
    assert_eq!(params.len(), usize::from(PARAMS), "every PARAM_VALUE arrives");
    assert!(ack_at - ACK_AT < 0.15, "the COMMAND_ACK waited {:.3} s", ack_at - ACK_AT);
    assert!(ack_at < params_done, "the COMMAND_ACK went before the rest of the burst");
    assert!((19.0..=21.0).contains(&attitude_before), "{attitude_before} Hz");
    assert!((9.0..=11.0).contains(&attitude_halved), "{attitude_halved} Hz");
    assert!((19.0..=21.0).contains(&attitude_back), "{attitude_back} Hz");
}
