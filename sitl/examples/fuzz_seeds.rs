//! Writes the seed corpora of the fuzz targets (`fuzz/`) into `OUT_DIR/<target>/seed-*` (run by
//! `scripts/fuzz seeds`): ground-station frames cut from `.tlog` files (the autopilot's own, written with `--log-dir`,
//! or any other MAVLink tlog) for `frame_decode`; plant datagrams as `sitl`'s plant link builds them, from
//! the real plant hovering and climbing, for `plant_decode`; the scenario files for `scenario_toml`; and
//! configuration files for `config_toml`. The structured targets start from the fuzzer's own inputs.
//!
//! `cargo run -p sitl --example fuzz_seeds -- OUT_DIR [TLOG...]`

use std::path::{Path, PathBuf};

use autopilot::core::mavlink::MavHeader;
use autopilot::core::mavlink::common::{MavBatteryChargeState, MavMessage};
use autopilot::core::plant_link::{
    encode_battery_status, encode_frame_v2, encode_hil_gps, encode_hil_sensor, encode_hil_state_quaternion,
};
use sitl::link::{battery_due, battery_fields, home_origin, sensor_fields, truth_fields};
use sitl::plant::{InitialState, Plant, PlantConfig, SensorConfig};

/// Frames per `frame_decode` seed, and seeds per tlog at most.
const FRAMES_PER_SEED: usize = 24;
const SEEDS_PER_TLOG: usize = 24;

/// The frames of a tlog: each record is an 8-byte big-endian timestamp, then one MAVLink frame.
fn tlog_frames(bytes: &[u8]) -> Vec<&[u8]> {
    let mut frames = Vec::new();
    let mut at = 0;
    while at + 8 + 3 <= bytes.len() {
        let frame = &bytes[at + 8..];
        let len = match frame[0] {
            0xFD => 10 + usize::from(frame[1]) + 2 + if frame[2] & 0x01 != 0 { 13 } else { 0 },
            0xFE => 6 + usize::from(frame[1]) + 2,
            _ => break,
        };
        if frame.len() < len {
            break;
        }
        frames.push(&frame[..len]);
        at += 8 + len;
    }
    frames
}

fn write(dir: &Path, name: &str, bytes: &[u8]) {
    std::fs::create_dir_all(dir).expect("corpus directory");
    std::fs::write(dir.join(name), bytes).expect("seed");
}

/// `plant_decode` takes a separator byte, then datagrams separated by it: a byte no datagram holds.
fn join_datagrams(datagrams: &[Vec<u8>]) -> Option<Vec<u8>> {
    let separator = (0..=255u8).find(|b| datagrams.iter().all(|d| !d.contains(b)))?;
    let mut out = vec![separator];
    for (i, d) in datagrams.iter().enumerate() {
        if i > 0 {
            out.push(separator);
        }
        out.extend_from_slice(d);
    }
    Some(out)
}

/// Plant datagrams as `sitl::link` sends them (GPS when released, truth, battery when due, sensors last),
/// the plant driven at `pwm_us` for `steps` steps of 2 ms.
fn plant_datagrams(pwm_us: f64, steps: usize) -> Vec<Vec<u8>> {
    let config = PlantConfig { sensors: SensorConfig::modest_noise(), ..PlantConfig::default() };
    let home = home_origin(&config.sensors.home);
    let mut plant = Plant::new(config, &InitialState::default(), 7).expect("plant");
    plant.set_motors_running(true);
    let header = |sequence: usize| MavHeader { system_id: 1, component_id: 51, sequence: sequence as u8 };
    let mut seq = 0;
    let mut frame = |msg: MavMessage| {
        seq += 1;
        encode_frame_v2(header(seq), &msg)
    };
    let mut out = Vec::new();
    for _ in 0..steps {
        let truth = plant.truth();
        let sample = plant.sample_sensors();
        let mut datagram = Vec::new();
        if let Some(gps) = &sample.gps {
            datagram.extend(frame(MavMessage::HIL_GPS(encode_hil_gps(gps))));
        }
        let airspeed_mps = (truth.vel_ned_mps - truth.wind_ned_mps).norm();
        datagram.extend(frame(MavMessage::HIL_STATE_QUATERNION(encode_hil_state_quaternion(
            &truth_fields(&truth),
            &home,
            airspeed_mps,
        ))));
        if let Some(battery) = plant.battery()
            && battery_due(truth.time_us, 2_000)
        {
            datagram.extend(frame(MavMessage::BATTERY_STATUS(encode_battery_status(
                &battery_fields(&battery.reading()),
                MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_UNDEFINED,
            ))));
        }
        datagram.extend(frame(MavMessage::HIL_SENSOR(encode_hil_sensor(&sensor_fields(&sample)))));
        out.push(datagram);
        plant.step([pwm_us; 4], 2_000);
    }
    out
}

fn main() {
    let mut args = std::env::args_os().skip(1);
    let out = PathBuf::from(args.next().expect("usage: fuzz_seeds OUT_DIR [TLOG...]"));

    let mut frame_seeds = 0;
    for (t, tlog) in args.enumerate() {
        let bytes = std::fs::read(&tlog).unwrap_or_else(|e| panic!("{}: {e}", Path::new(&tlog).display()));
        let frames = tlog_frames(&bytes);
        let step = (frames.len() / FRAMES_PER_SEED / SEEDS_PER_TLOG).max(1) * FRAMES_PER_SEED;
        for (i, chunk) in
            frames.chunks(FRAMES_PER_SEED).step_by(step / FRAMES_PER_SEED).take(SEEDS_PER_TLOG).enumerate()
        {
            // The first byte is the target's read size; 61 cuts frames across reads.
            let mut seed = vec![61u8];
            seed.extend(chunk.iter().flat_map(|f| f.iter().copied()));
            write(&out.join("frame_decode"), &format!("seed-tlog{t}-{i:02}"), &seed);
            frame_seeds += 1;
        }
    }

    let mut plant_seeds = 0;
    for (name, pwm_us, skip) in [("ground", 1000.0, 0), ("spin-up", 1500.0, 100), ("climb", 1700.0, 400)] {
        let datagrams = plant_datagrams(pwm_us, skip + 60);
        for (i, chunk) in datagrams[skip..].chunks(20).enumerate() {
            if let Some(seed) = join_datagrams(chunk) {
                write(&out.join("plant_decode"), &format!("seed-{name}-{i}"), &seed);
                plant_seeds += 1;
            }
        }
    }

    let scenarios = Path::new(env!("CARGO_MANIFEST_DIR")).join("scenarios");
    for entry in std::fs::read_dir(&scenarios).expect("scenarios") {
        let path = entry.expect("entry").path();
        let name = path.file_name().expect("name").to_string_lossy().into_owned();
        write(&out.join("scenario_toml"), &format!("seed-{name}"), &std::fs::read(&path).expect("scenario"));
    }

    // The configuration example of `runtime/config.rs`'s documentation, and a minimal and a full file; the
    // first byte is the instance.
    let configs = [
        ("empty", String::new()),
        ("udp", "[gcs]\nudp_bind = \"127.0.0.1:20000\"\nudp_targets = [\"127.0.0.1:20001\"]\nudp_max_peers = 8\nudp_secure = true\n".to_owned()),
        (
            "full",
            "[plant]\nlink = \"udp://127.0.0.1:4560\"\n[gcs]\nudp_bind = \"0.0.0.0:18570\"\n\
             udp_targets = [\"127.0.0.1:14550\", \"127.0.0.1:14540\"]\ntcp_bind = \"0.0.0.0:5760\"\n\
             tcp_max_clients = 16\nserial = \"/dev/ttyUSB0:57600\"\n[log]\ndir = \"logs\"\n[state]\ndir = \"off\"\n\
             [vehicle]\ncontroller = \"aco\"\n[vehicle.estimator]\nsource = \"fused\"\n"
                .to_owned(),
        ),
        ("serial-plant", "[plant]\nlink = \"serial:/dev/ttyACM0:921600\"\n[vehicle]\ncontroller = \"pid\"\n".to_owned()),
    ];
    for (name, text) in &configs {
        let mut seed = vec![0u8];
        seed.extend_from_slice(text.as_bytes());
        write(&out.join("config_toml"), &format!("seed-{name}"), &seed);
    }
    println!(
        "seeds: {frame_seeds} frame_decode, {plant_seeds} plant_decode, scenario_toml and config_toml in {}",
        out.display()
    );
}
