//! Tests of the view's plumbing: the bridge's options, the forwarder's placement of an autopilot's frames,
//! and the ready line and the stream through a stand-in bridge.

use super::*;

#[test]
fn given_options_then_the_bridge_gets_them_on_its_command_line() {
    let opts = ViewerOptions {
        kind: ViewerKind::Web,
        web_port: 9191,
        grpc_port: 9977,
        record: Some(PathBuf::from("/tmp/run.rrd")),
        exit_at_eof: true,
        ulog: None,
    };
    assert_eq!(
        bridge_args(&opts).join(" "),
        "-m aco_gcs.view --web --web-port 9191 --grpc-port 9977 --record /tmp/run.rrd --exit-at-eof"
    );
}

fn vehicle_line(src: &str, origin: Option<[f64; 3]>) -> Vec<u8> {
    let frame = ViewFrame::Vehicle(VehicleFrame {
        src: src.into(),
        t_us: 40_000,
        armed: true,
        mode: "Position".into(),
        pos_ned_m: [0.0, 0.0, -2.0],
        vel_ned_mps: [0.0; 3],
        q_ned_frd: [1.0, 0.0, 0.0, 0.0],
        euler_rad: [0.0; 3],
        sp_pos_ned_m: Some([1.0, 0.0, -2.0]),
        sp_euler_rad: None,
        pwm_us: [1500.0; 4],
        battery_v: Some(24.0),
        battery_pct: Some(90.0),
        telemetry: std::collections::BTreeMap::new(),
        origin,
    });
    frame.to_json().into_bytes()
}

#[test]
fn given_frames_of_two_vehicles_then_each_lands_in_the_plant_frame_at_its_origin() {
    let map = GeoOrigin { lat_deg: 47.397_742, lon_deg: 8.545_594, alt_amsl_m: 488.0 };
    let (tx, rx) = sync_channel(16);
    let sender = ViewSender { tx, dropped: Arc::default(), delivery: Delivery::Complete };
    let placements = vec![
        ("v0".to_string(), VehiclePlacement { map, start_ned_m: Vector3::zeros() }),
        ("v1".to_string(), VehiclePlacement { map, start_ned_m: Vector3::new(0.0, 3.0, 0.0) }),
    ];
    let forwarder = Forwarder::start(sender, placements).unwrap();
    let out = UdpSocket::bind("127.0.0.1:0").unwrap();
    // v1 before its estimator has an origin: at its start; v0 with an origin 2 m north of the map's.
    let north = map.geodetic_from_ned(&Vector3::new(2.0, 0.0, 0.0));
    out.send_to(&vehicle_line("v1", None), forwarder.addr()).unwrap();
    out.send_to(&vehicle_line("v0", Some([north.0, north.1, north.2])), forwarder.addr()).unwrap();
    out.send_to(b"not json", forwarder.addr()).unwrap();
    out.send_to(&vehicle_line("v7", None), forwarder.addr()).unwrap();
    let mut got = Vec::new();
    for _ in 0..2 {
        let line = rx.recv_timeout(Duration::from_secs(5)).unwrap();
        let ViewFrame::Vehicle(v) = serde_json::from_str::<ViewFrame>(&line).unwrap() else { panic!("{line}") };
        got.push((v.src, v.pos_ned_m, v.sp_pos_ned_m.unwrap()));
    }
    got.sort_by(|a, b| a.0.cmp(&b.0));
    assert_eq!(got[1], ("v1".to_string(), [0.0, 3.0, -2.0], [1.0, 3.0, -2.0]));
    let (src, pos, _) = &got[0];
    assert_eq!(src, "v0");
    assert!((pos[0] - 2.0).abs() < 1e-6 && pos[1].abs() < 1e-6 && (pos[2] + 2.0).abs() < 1e-6, "{pos:?}");
    drop(forwarder);
    assert!(rx.try_recv().is_err(), "the malformed line and the unknown source are not forwarded");
}

#[cfg(unix)]
#[test]
fn given_a_bridge_that_says_ready_then_every_frame_reaches_its_input_in_order() {
    let dir = std::env::temp_dir().join(format!("sitl-view-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let got = dir.join("stream.jsonl");
    let script = dir.join("bridge.sh");
    std::fs::write(&script, format!("#!/bin/sh\necho ready http://127.0.0.1:1/\nexec cat > '{}'\n", got.display()))
        .unwrap();
    let fake_python = dir.join("python");
    std::fs::write(&fake_python, format!("#!/bin/sh\nexec sh '{}'\n", script.display())).unwrap();
    std::fs::set_permissions(&fake_python, std::os::unix::fs::PermissionsExt::from_mode(0o755)).unwrap();
    let viewer = Viewer::start_with(&fake_python, &ViewerOptions::default(), Delivery::Complete).unwrap();
    assert_eq!(viewer.url, "http://127.0.0.1:1/");
    let sender = viewer.sender();
    let plant =
        crate::plant::Plant::new(crate::plant::PlantConfig::default(), &crate::plant::InitialState::default(), 1)
            .unwrap();
    for _ in 0..5000 {
        assert!(sender.send(&truth_frame("v0", &plant.truth())));
    }
    drop(sender);
    let report = viewer.finish().unwrap();
    assert_eq!(report, ViewReport { written: 5000, dropped: 0 });
    let text = std::fs::read_to_string(&got).unwrap();
    assert_eq!(text.lines().count(), 5000);
    assert!(text.lines().all(|l| l.starts_with(r#"{"kind":"truth","src":"v0","t_us":0,"#)), "{}", &text[..200]);
    std::fs::remove_dir_all(&dir).unwrap();
}

#[test]
fn given_a_bridge_that_stops_before_it_is_ready_then_the_error_says_so() {
    let err = Viewer::start_with(Path::new("false"), &ViewerOptions::default(), Delivery::Live).err().unwrap();
    assert!(matches!(err, ViewError::NotReady { .. }), "{err}");
    let err =
        Viewer::start_with(Path::new("/nonexistent/python"), &ViewerOptions::default(), Delivery::Live).err().unwrap();
    assert!(err.to_string().contains("rerun-sdk"), "{err}");
}

#[test]
fn given_a_scenario_in_the_view_then_its_run_is_the_run_without_it_and_every_50_hz_instant_is_sent_once() {
    use crate::scenario::runner::{RunOptions, run};
    let mut scenario = crate::scenario::Scenario::load("gust-hover").unwrap();
    scenario.duration_s = 4.0;
    let opts = RunOptions::new(autopilot::core::control::ControllerKind::ACO);
    let (tx, rx) = sync_channel(100_000);
    let sender = ViewSender { tx, dropped: Arc::default(), delivery: Delivery::Complete };
    let viewed = scenario::run_viewed(&scenario, &opts, "aco", &sender).unwrap();
    let plain = run(&scenario, &opts).unwrap();
    assert_eq!(viewed.trace.to_csv(), plain.trace.to_csv(), "the view changes nothing of the run");
    assert_eq!(serde_json::to_value(&viewed.metrics.gust).unwrap(), serde_json::to_value(&plain.metrics.gust).unwrap());
    drop(sender);
    let frames: Vec<ViewFrame> = rx.try_iter().map(|l| serde_json::from_str(&l).unwrap()).collect();
    let times = |kind: &str| -> Vec<u64> {
        frames
            .iter()
            .filter_map(|f| match (kind, f) {
                ("truth", ViewFrame::Truth(t)) => Some(t.t_us),
                ("vehicle", ViewFrame::Vehicle(v)) => Some(v.t_us),
                _ => None,
            })
            .collect()
    };
    let expected: Vec<u64> = (0..200).map(|k| k * VIEW_PERIOD_US).collect();
    assert_eq!(times("truth"), expected, "4 s at 50 Hz: 0, 20 ms, ..., 3.98 s");
    assert_eq!(times("vehicle"), expected);
    let first_vehicle = frames.iter().find_map(|f| if let ViewFrame::Vehicle(v) = f { Some(v) } else { None });
    let v = first_vehicle.unwrap();
    assert_eq!(v.sp_pos_ned_m, Some([0.0, 0.0, -1.5]), "gust-hover holds 1.5 m");
    assert!(v.telemetry.contains_key("aco.w_t_n") && v.telemetry.contains_key("aco.c_r_x"), "{:?}", v.telemetry);
    assert!(v.pwm_us.iter().all(|p| (1000.0..=2000.0).contains(p)), "{:?}", v.pwm_us);
    let ahead = frames.iter().filter(|f| matches!(f, ViewFrame::Ahead(_))).count();
    assert_eq!(ahead, 20, "the path ahead five times a second");
}
