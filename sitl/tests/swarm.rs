//! `sitl run -n 3`: a swarm from one command, checked as a ground station sees it. Each vehicle's API port
//! carries that vehicle only (its system id), the vehicles report positions on the spawn grid, and the run
//! ends with one summary. Waits are bounded by a wall-clock deadline; the swarm runs in lockstep for a
//! fixed simulated duration.

use std::collections::BTreeMap;
use std::net::UdpSocket;
use std::process::Command;
use std::time::{Duration, Instant};

use autopilot::core::mavlink::common::MavMessage;
use autopilot::core::plant_link::FrameDecoder;
use autopilot::runtime::ports::InstancePorts;

const VEHICLES: u16 = 3;
const EARTH_RADIUS_M: f64 = 6_371_000.0;

/// A first instance whose swarm's API ports are all free, with those ports bound.
fn free_swarm() -> (u16, Vec<UdpSocket>) {
    let salt = u16::try_from(std::process::id() % 50).expect("small");
    for attempt in 0..50u16 {
        let first = 150 + (salt + attempt * 7) % 90;
        let sockets: Vec<UdpSocket> = (first..first + VEHICLES)
            .filter_map(|n| UdpSocket::bind(("127.0.0.1", InstancePorts::of(n).expect("in range").api_udp)).ok())
            .collect();
        if sockets.len() == usize::from(VEHICLES) {
            for s in &sockets {
                s.set_nonblocking(true).expect("nonblocking");
            }
            return (first, sockets);
        }
    }
    panic!("no free API ports for a swarm of {VEHICLES}");
}

#[test]
fn a_swarm_of_three_sends_each_vehicle_to_its_own_api_port_from_its_own_spawn_point() {
    let (first, sockets) = free_swarm();
    fly_swarm(first, &sockets, &[]);
}

#[test]
fn a_truth_fed_swarm_puts_each_vehicle_where_it_spawned_too() {
    // The truth feed's positions are about the plant's origin: a vehicle spawned away from it must not
    // count its offset twice.
    let (first, sockets) = free_swarm();
    fly_swarm(first, &sockets, &["--estimator", "truth"]);
}

fn fly_swarm(first: u16, sockets: &[UdpSocket], extra: &[&str]) {
    // GIVEN three vehicles from one command, 4 m apart, for 20 s of simulated time.
    let mut child = Command::new(env!("CARGO_BIN_EXE_sitl"))
        .args(["run", "-n", "3", "-i", &first.to_string(), "--spacing", "4", "--speed", "max"])
        .args(["--duration", "20", "--state-dir", "off"])
        .args(extra)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .expect("sitl runs");
    // WHEN a ground station listens on each vehicle's API port.
    let mut decoders: Vec<FrameDecoder> = (0..VEHICLES).map(|_| FrameDecoder::new()).collect();
    let mut senders: Vec<BTreeMap<u32, usize>> = vec![BTreeMap::new(); usize::from(VEHICLES)];
    let mut positions: Vec<Option<(i32, i32)>> = vec![None; usize::from(VEHICLES)];
    let mut buf = [0u8; 65_536];
    let deadline = Instant::now() + Duration::from_secs(120);
    while child.try_wait().expect("wait").is_none() {
        assert!(Instant::now() < deadline, "the swarm did not finish 20 sim s within 120 s");
        let mut idle = true;
        for (k, socket) in sockets.iter().enumerate() {
            while let Ok(len) = socket.recv(&mut buf) {
                idle = false;
                for frame in decoders[k].decode_datagram(&buf[..len]) {
                    *senders[k].entry(frame.header.system_id).or_default() += 1;
                    if let MavMessage::GLOBAL_POSITION_INT(p) = frame.message {
                        positions[k] = Some((p.lat, p.lon));
                    }
                }
            }
        }
        if idle {
            std::thread::sleep(Duration::from_millis(2));
        }
    }
    let output = child.wait_with_output().expect("output");
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    // THEN each API port carried its own vehicle only: system id N+1.
    for (k, seen) in senders.iter().enumerate() {
        let sysid = u32::from(first) + 1 + u32::try_from(k).expect("small");
        assert_eq!(seen.keys().copied().collect::<Vec<_>>(), [sysid], "API port of vehicle {k}: {seen:?}");
        assert!(seen[&sysid] > 100, "vehicle {k} sent {} messages", seen[&sysid]);
    }
    // AND the vehicles stand where the grid put them: 0 (origin), 1 (4 m east), 2 (4 m north).
    let at: Vec<(i32, i32)> = positions.iter().map(|p| p.expect("a GLOBAL_POSITION_INT")).collect();
    let offset_m = |(lat, lon): (i32, i32)| {
        let (lat0, lon0) = at[0];
        let north = f64::from(lat - lat0) * 1e-7_f64.to_radians() * EARTH_RADIUS_M;
        let east = f64::from(lon - lon0)
            * 1e-7_f64.to_radians()
            * EARTH_RADIUS_M
            * (f64::from(lat0) * 1e-7).to_radians().cos();
        (north, east)
    };
    let (n1, e1) = offset_m(at[1]);
    let (n2, e2) = offset_m(at[2]);
    assert!(n1.abs() < 0.3 && (e1 - 4.0).abs() < 0.3, "vehicle 1 at ({n1:.2}, {e1:.2}) m from vehicle 0");
    assert!((n2 - 4.0).abs() < 0.3 && e2.abs() < 0.3, "vehicle 2 at ({n2:.2}, {e2:.2}) m from vehicle 0");
    // AND one summary for the whole swarm.
    assert_eq!(stderr.lines().filter(|l| l.starts_with("sitl: swarm of 3:")).count(), 1, "{stderr}");
}

#[test]
fn a_swarm_refuses_what_it_cannot_fly_before_anything_starts() {
    let sitl = |args: &[&str]| Command::new(env!("CARGO_BIN_EXE_sitl")).args(args).output().expect("sitl runs");
    let o = sitl(&["run", "-n", "2", "-i", "254"]);
    assert_eq!(o.status.code(), Some(1));
    assert_eq!(String::from_utf8_lossy(&o.stderr).trim(), "sitl: error: -i 254 -n 2: instances are 0..=254");
    let o = sitl(&["run", "-n", "0"]);
    assert_eq!(o.status.code(), Some(2), "clap refuses 0 vehicles");
    let o = sitl(&["run", "-n", "2", "--scenario", "gust-hover"]);
    assert_eq!(o.status.code(), Some(2), "a scenario flies one vehicle");
}
