//! The plant on the airframe's serial link through an emulated UART (`sitl::serial_line`: 10 bits a byte
//! at the baud rate, bytes counted each way): `sitl serve --serial --free-run --rate R` on one end, as the
//! board times its link, and `autopilot --plant serial: --rate R` on the other; the ground station (this
//! test) on UDP. Each flight takes off to 1.5 m, hovers 20 s and is judged on the plant's truth (its
//! SIM_ port) against the point commanded: home at arming + 1.5 m. Free-running flights run at real time,
//! so their waits are on vehicle time and a wall-clock limit only stops a hung run. Unix only (ptys).
#![cfg(unix)]

mod common;

use std::io::Read;
use std::net::UdpSocket;
use std::os::unix::process::CommandExt;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use autopilot::core::mavlink::common::{MavCmd, MavResult};
use autopilot::core::plant_link::budget::{LinkBudget, PlantStreams};
use common::{Gcs, Guard, armed, free_instance, sitl_binary};
use nalgebra::Vector3;
use sitl::serial_line::{LineConfig, LineStats, SerialLine};

/// How the plant reaches the autopilot.
#[derive(Debug, Clone, Copy)]
enum PlantLink {
    /// `sitl run --rate R`: UDP, lockstep at real time.
    Udp,
    /// The emulated serial line at this baud rate, the plant free-running.
    Serial { baud: u32 },
}

/// What a flight measured.
#[derive(Debug)]
struct Flight {
    /// RMS and largest distance of the truth from the commanded point over the 20 s hover (m).
    hover_rms_m: f64,
    hover_max_m: f64,
    samples: usize,
    /// Bytes per wall second on the line over the hover, plant to autopilot and back (serial only).
    wire_bytes_per_s: Option<(f64, f64)>,
}

/// Sticks centred, throttle low, switches low: the safety pilot's radio, held by the plant once sent.
fn rc_datagram() -> Vec<u8> {
    [1500_u16, 1500, 1000, 1500, 1000, 1000, 1000, 1000].iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn autopilot_binary() -> std::path::PathBuf {
    std::path::Path::new(sitl_binary()).with_file_name("autopilot")
}

/// Wire bytes per wall second between two snapshots of the line.
fn rates(before: (Instant, LineStats), after: (Instant, LineStats)) -> (f64, f64) {
    let s = (after.0 - before.0).as_secs_f64();
    (
        (after.1.a_to_b.bytes_in - before.1.a_to_b.bytes_in) as f64 / s,
        (after.1.b_to_a.bytes_in - before.1.b_to_a.bytes_in) as f64 / s,
    )
}

fn fly(rate_hz: u32, link: PlantLink) -> Flight {
    let (n, socket) = free_instance();
    let (rate, inst) = (rate_hz.to_string(), n.to_string());
    let mut line = None;
    let mut guards: Vec<Guard> = Vec::new();
    match link {
        PlantLink::Udp => {
            let child = Command::new(sitl_binary())
                .args(["run", "-i", &inst, "--state-dir", "off", "--no-ulog", "--rate", &rate])
                .stderr(Stdio::null())
                .process_group(0)
                .spawn()
                .expect("spawn sitl run");
            guards.push(Guard(child));
        }
        PlantLink::Serial { baud } => {
            let l = SerialLine::open(LineConfig { baud, ..LineConfig::default() }).expect("the emulated line");
            let plant_end = format!("{}:{baud}", l.a_path());
            let autopilot_end = format!("serial:{}:{baud}", l.b_path());
            let plant = Command::new(sitl_binary())
                .args(["serve", "--serial", &plant_end, "--rate", &rate, "--free-run", "-i", &inst])
                .stderr(Stdio::null())
                .process_group(0)
                .spawn()
                .expect("spawn sitl serve");
            guards.push(Guard(plant));
            let autopilot = Command::new(autopilot_binary())
                .args(["--plant", &autopilot_end, "--rate", &rate, "-i", &inst, "--state-dir", "off", "--no-ulog"])
                .arg("--stop-on-stdin-eof")
                .stdin(Stdio::piped())
                .stderr(Stdio::null())
                .process_group(0)
                .spawn()
                .expect("spawn autopilot");
            guards.push(Guard(autopilot));
            line = Some(l);
        }
    }
    let rc_port = sitl::link::rc::RC_IN_PORT + n;
    let rc_socket = UdpSocket::bind("127.0.0.1:0").expect("bind the radio");
    let mut gcs = Gcs::new(n, socket);

    // GIVEN the vehicle talking, the safety pilot's radio on (the plant sends RC_CHANNELS at 50 Hz, part
    // of the budget), the estimator converged and the plant's truth flowing.
    while gcs.seen.heartbeats < 2 || !gcs.seen.rc {
        rc_socket.send_to(&rc_datagram(), ("127.0.0.1", rc_port)).expect("radio");
        gcs.pump();
    }
    gcs.wait_until(60.0, "estimator convergence", |s| s.converged && s.pos_ned_m.is_some());
    while gcs.truth.samples.is_empty() {
        gcs.pump();
    }
    let home = gcs.seen.pos_ned_m.expect("position");
    // WHEN it takes off to 1.5 m.
    let nan = f32::NAN;
    let accepted = MavResult::MAV_RESULT_ACCEPTED;
    assert_eq!(gcs.command(MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, nan, nan, nan, 1.5]), accepted);
    assert_eq!(gcs.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]), accepted);
    gcs.wait_until(2.0, "HEARTBEAT armed", armed);
    let hover_truth_ned_m = gcs.truth_at(gcs.seen.time_ms) - Vector3::new(0.0, 0.0, 1.5);
    gcs.wait_until(15.0, "climb to 1.5 m", |s| s.pos_ned_m.is_some_and(|p| (p[2] - (home[2] - 1.5)).abs() < 0.05));
    // THEN it holds for 20 s, the line counting the bytes each way meanwhile.
    let hover_start_ms = gcs.seen.time_ms;
    let wire_start = line.as_ref().map(|l| (Instant::now(), l.stats()));
    gcs.run_s(20.0, |_| {});
    let wire = line.as_ref().zip(wire_start).map(|(l, start)| rates(start, (Instant::now(), l.stats())));
    let hover_end_ms = gcs.seen.time_ms;
    gcs.truth_at(hover_end_ms);
    assert!(armed(&gcs.seen), "still armed in the hover");
    let errors: Vec<f64> = gcs
        .truth
        .samples
        .iter()
        .filter(|(t, _)| (hover_start_ms..=hover_end_ms).contains(t))
        .map(|(_, p)| (p - hover_truth_ned_m).norm())
        .collect();
    assert!(errors.len() >= 900, "{} truth samples over the 20 s hover (50 Hz)", errors.len());
    let hover_rms_m = (errors.iter().map(|e| e * e).sum::<f64>() / errors.len() as f64).sqrt();
    let hover_max_m = errors.iter().copied().fold(0.0, f64::max);
    // AND it lands and disarms by itself.
    assert_eq!(gcs.command(MavCmd::MAV_CMD_NAV_LAND, [0.0; 7]), accepted);
    gcs.wait_until(25.0, "auto-disarm after landing", |s| !armed(s));
    drop(guards);
    Flight { hover_rms_m, hover_max_m, samples: errors.len(), wire_bytes_per_s: wire }
}

/// The budget both ends print for a board at `rate_hz` on `baud` (GPS 10 Hz, the radio, the pack, no truth).
fn budget(rate_hz: u32, baud: u32) -> LinkBudget {
    LinkBudget::of(&PlantStreams::board(f64::from(rate_hz)), baud)
}

/// Each direction's measured bytes per second within 5 % of the budget's (the budget, and so
/// docs/board.md, which a unit test holds to it).
fn assert_wire_matches_budget(flight: &Flight, budget: &LinkBudget) {
    let (down, up) = flight.wire_bytes_per_s.expect("a serial flight measures its line");
    for (what, measured, expected) in
        [("plant -> autopilot", down, budget.down.bytes_per_s()), ("autopilot -> plant", up, budget.up.bytes_per_s())]
    {
        let off = (measured - expected) / expected;
        println!("{what}: {measured:.0} B/s on the wire, {expected:.0} B/s in the budget ({:+.1} %)", off * 100.0);
        assert!(off.abs() <= 0.05, "{what}: {measured:.0} B/s on the wire against {expected:.0} B/s budgeted");
    }
}

#[test]
fn at_921600_baud_and_250_hz_the_board_link_hovers_within_10_percent_of_udp_and_carries_its_budget_within_5_percent() {
    let udp = fly(250, PlantLink::Udp);
    let serial = fly(250, PlantLink::Serial { baud: 921_600 });
    println!(
        "UDP 250 Hz: hover truth error RMS {:.4} m, max {:.4} m ({} samples)",
        udp.hover_rms_m, udp.hover_max_m, udp.samples
    );
    println!(
        "serial 921600 baud, 250 Hz free-running: RMS {:.4} m, max {:.4} m ({} samples)",
        serial.hover_rms_m, serial.hover_max_m, serial.samples
    );
    let off = (serial.hover_rms_m - udp.hover_rms_m) / udp.hover_rms_m;
    assert!(
        off.abs() <= 0.10,
        "serial RMS {:.4} m is {:+.1} % of UDP's {:.4} m",
        serial.hover_rms_m,
        off * 100.0,
        udp.hover_rms_m
    );
    assert_wire_matches_budget(&serial, &budget(250, 921_600));
}

/// Runs `program args`, which must refuse to start; its standard error.
fn refused(program: &std::path::Path, args: &[&str]) -> String {
    let mut child = Command::new(program)
        .args(args)
        .stdin(Stdio::piped())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("spawn");
    let deadline = Instant::now() + Duration::from_secs(20);
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait") {
            break status;
        }
        assert!(Instant::now() < deadline, "{} {args:?} did not stop", program.display());
        std::thread::sleep(Duration::from_millis(20));
    };
    let mut stderr = String::new();
    child.stderr.take().expect("piped").read_to_string(&mut stderr).expect("stderr");
    assert!(!status.success(), "{} {args:?} started: {stderr}", program.display());
    stderr
}

#[test]
fn at_115200_baud_both_ends_refuse_500_hz_naming_80_hz_and_at_80_hz_it_flies_on_its_budget() {
    let line = SerialLine::open(LineConfig { baud: 115_200, ..LineConfig::default() }).expect("the emulated line");
    let (n, _socket) = free_instance();
    let inst = n.to_string();
    let expected = budget(500, 115_200).refusal("--rate").expect("500 Hz does not fit");
    assert!(expected.ends_with("80 Hz fits: --rate 80"), "{expected}");
    let plant_end = format!("{}:115200", line.a_path());
    let plant = refused(std::path::Path::new(sitl_binary()), &["serve", "--serial", &plant_end, "-i", &inst]);
    let last = plant.lines().last().unwrap_or_default();
    assert_eq!(last, format!("sitl: error: the plant stream does not fit the serial line: {expected}"), "{plant}");
    let autopilot_end = format!("serial:{}:115200", line.b_path());
    let ap = refused(&autopilot_binary(), &["--plant", &autopilot_end, "-i", &inst, "--state-dir", "off"]);
    assert!(
        ap.lines().any(|l| l == format!("autopilot: error: the plant link does not fit its line: {expected}")),
        "{ap}"
    );
    drop(line);

    let flight = fly(80, PlantLink::Serial { baud: 115_200 });
    println!(
        "serial 115200 baud, 80 Hz free-running: hover truth error RMS {:.4} m, max {:.4} m ({} samples)",
        flight.hover_rms_m, flight.hover_max_m, flight.samples
    );
    assert!(flight.hover_max_m <= 0.15, "hover truth error {:.3} m at 80 Hz over 115200 baud", flight.hover_max_m);
    assert_wire_matches_budget(&flight, &budget(80, 115_200));
}
