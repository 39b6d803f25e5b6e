//! Sensor faults against the kinematic simulator ([`super::sim`]): each source lost, stuck or jumping in
//! flight, judged on the truth (what is flagged, how fast, the fallback, the announcement), and healthy
//! runs, noisy or noise-free, that must never raise a flag.

use nalgebra::Vector3;
use proptest::prelude::*;

use super::sim::{HOME, Profile, STEP_US, Sim, Step};
use super::*;

/// One step's samples as the estimator is fed them (any may be dropped).
#[derive(Debug, Clone, Copy)]
struct Inputs {
    imu: ImuSample,
    mag: Option<MagSample>,
    baro: Option<BaroSample>,
    gps: Option<GpsSample>,
}

/// What a step left: time (s), flags, events raised, and errors against the truth once there is an
/// origin: position (m, NED, estimate minus truth) and heading (rad).
#[derive(Debug, Clone)]
struct Record {
    t_s: f64,
    flags: EstimatorFlags,
    events: Vec<EstimatorEvent>,
    pos_err_ned_m: Option<Vector3<f64>>,
    yaw_err_rad: f64,
}

/// Flies `profile` for `duration_s`, letting `alter` change each step's inputs (time in µs) before they
/// are fed; records every step.
fn fly(profile: Profile, seed: u64, duration_s: f64, alter: impl FnMut(u64, &mut Inputs)) -> (Estimator, Vec<Record>) {
    fly_sim(Sim::new(profile, seed), duration_s, alter)
}

/// [`fly`] with a prepared simulator.
fn fly_sim(mut sim: Sim, duration_s: f64, mut alter: impl FnMut(u64, &mut Inputs)) -> (Estimator, Vec<Record>) {
    let mut est = Estimator::new(EstimatorConfig::default());
    let mut records = Vec::new();
    let steps = (duration_s * 1e6 / STEP_US as f64).round() as u64;
    for _ in 0..steps {
        let s: Step = sim.step();
        let mut inputs = Inputs { imu: s.imu, mag: Some(s.mag), baro: s.baro, gps: s.gps };
        alter(s.time_us, &mut inputs);
        est.update_imu(&inputs.imu);
        if let Some(mag) = inputs.mag {
            est.update_mag(&mag);
        }
        if let Some(baro) = inputs.baro {
            est.update_baro(&baro);
        }
        if let Some(gps) = inputs.gps {
            est.update_gps(&gps);
        }
        let state = est.state();
        let pos_err_ned_m = state.origin.map(|o| {
            let (lat, lon, alt) = HOME.geodetic_from_ned(&s.truth.pos_ned_m);
            state.pos_ned_m - o.ned_from_geodetic(lat, lon, alt)
        });
        let yaw_err_rad =
            crate::core::control::frames::wrap_pi(state.euler_rad.z - s.truth.q_ned_frd.euler_angles().2).abs();
        records.push(Record {
            t_s: s.time_us as f64 * 1e-6,
            flags: state.flags,
            events: est.take_events(),
            pos_err_ned_m,
            yaw_err_rad,
        });
    }
    (est, records)
}

/// The first record at or after `t_s` where `cond` holds.
fn first(records: &[Record], t_s: f64, cond: impl Fn(&Record) -> bool) -> Option<&Record> {
    records.iter().find(|r| r.t_s >= t_s - 1e-9 && cond(r))
}

/// Every event raised, with its time (s).
fn events(records: &[Record]) -> Vec<(f64, EstimatorEvent)> {
    records.iter().flat_map(|r| r.events.iter().map(move |e| (r.t_s, *e))).collect()
}

/// The worst of `f` over records in [from_s, to_s).
fn worst(records: &[Record], from_s: f64, to_s: f64, f: impl Fn(&Record) -> f64) -> f64 {
    records.iter().filter(|r| r.t_s >= from_s && r.t_s < to_s).map(f).fold(0.0, f64::max)
}

fn hor_err_m(r: &Record) -> f64 {
    r.pos_err_ned_m.map_or(f64::INFINITY, |e| e.x.hypot(e.y))
}

fn no_fault_ever(records: &[Record]) -> Result<(), String> {
    match records.iter().find(|r| !r.flags.health.all_healthy() || !r.events.is_empty()) {
        Some(r) => Err(format!("at {:.3} s: {:?} {:?}", r.t_s, r.flags.health, r.events)),
        None => Ok(()),
    }
}

#[test]
fn given_gps_stopping_mid_translation_then_lost_is_flagged_within_0_6_s_position_invalid_at_once_and_regained() {
    // The last fix before the outage is valid (and arrives) at 9.9 s; the next at 15.0 s.
    let (_, records) = fly(Profile::Manoeuvre, 31, 20.0, |t_us, i| {
        if (9_950_000..15_000_000).contains(&t_us) {
            i.gps = None;
        }
    });
    let lost = first(&records, 9.9, |r| r.flags.health.gps.is_some()).expect("flagged");
    println!("GPS lost flagged {:.3} s after the last fix", lost.t_s - 9.9);
    assert_eq!(lost.flags.health.gps, Some(SourceFault::Lost));
    assert!(lost.t_s - 9.9 <= 0.6, "flagged {:.3} s after the last fix", lost.t_s - 9.9);
    // At once: the step that flags it has no valid position or velocity, and the step before had both.
    assert!(!lost.flags.position_valid && !lost.flags.velocity_valid && !lost.flags.gps_ok, "{:?}", lost.flags);
    let before = records.iter().rev().find(|r| r.t_s < lost.t_s).unwrap();
    assert!(before.flags.position_valid && before.flags.health.gps.is_none(), "{:?}", before.flags);
    // Dead reckoning: the height keeps its baro, the heading its magnetometer.
    assert_eq!(lost.flags.height_source, HeightSource::Baro);
    assert!(lost.flags.attitude_valid && lost.flags.baro_ok && lost.flags.mag_ok);
    let back = first(&records, 15.0, |r| r.flags.position_valid).expect("position valid again");
    assert!(back.t_s < 15.01, "valid again only at {:.3} s", back.t_s);
    assert!(back.flags.health.all_healthy());
    let texts: Vec<(f64, String)> = events(&records).iter().map(|(t, e)| (*t, e.text())).collect();
    assert_eq!(texts.len(), 2, "{texts:?}");
    assert_eq!((texts[0].0, texts[0].1.as_str()), (lost.t_s, "GPS lost: dead reckoning"));
    assert_eq!(texts[1].1, "GPS regained");
    assert!(worst(&records, 16.0, 20.0, hor_err_m) < 0.3);
}

#[test]
fn given_gps_stuck_while_moving_at_1_mps_then_stuck_is_flagged_within_1_2_s_not_fused_and_regained_when_it_moves() {
    // From 8 s the fix of 7.9 s is repeated with fresh time stamps (as the plant's SIM_GPS_FAIL 2) until 12 s.
    let mut frozen: Option<GpsSample> = None;
    let (_, records) = fly(Profile::Manoeuvre, 32, 16.0, |t_us, i| {
        if let Some(gps) = i.gps.as_mut() {
            if (8_000_000..12_000_000).contains(&t_us) {
                let held = frozen.expect("a fix before 8 s");
                *gps = GpsSample { time_us: gps.time_us, ..held };
            } else {
                frozen = Some(*gps);
            }
        }
    });
    let stuck = first(&records, 8.0, |r| r.flags.health.gps.is_some()).expect("flagged");
    println!(
        "GPS stuck flagged at {:.3} s (frozen from 7.9 s); worst horizontal error 8-12 s {:.3} m, 13-16 s {:.3} m",
        stuck.t_s,
        worst(&records, 8.0, 12.0, hor_err_m),
        worst(&records, 13.0, 16.0, hor_err_m)
    );
    assert_eq!(stuck.flags.health.gps, Some(SourceFault::Stuck));
    assert!(stuck.t_s <= 9.2, "flagged at {:.3} s", stuck.t_s);
    assert!(!stuck.flags.position_valid && !stuck.flags.velocity_valid);
    assert!(records.iter().filter(|r| r.t_s >= stuck.t_s && r.t_s < 12.0).all(|r| !r.flags.position_valid));
    let texts: Vec<String> = events(&records).iter().map(|(_, e)| e.text()).collect();
    assert_eq!(texts, ["GPS stuck: dead reckoning", "GPS regained"]);
    // Back at 12 s: reset to the fix, valid again, accurate.
    let back = first(&records, 12.0, |r| r.flags.position_valid).expect("valid again");
    assert!(back.t_s < 12.01, "valid again at {:.3} s", back.t_s);
    assert!(worst(&records, 13.0, 16.0, hor_err_m) < 0.3);
}

/// `gps` moved `offset_ned_m` (the plant's SIM_GPS_FAIL 4).
fn jumped(gps: &GpsSample, offset_ned_m: &Vector3<f64>) -> GpsSample {
    let ned = HOME.ned_from_geodetic(gps.lat_deg, gps.lon_deg, gps.alt_amsl_m) + offset_ned_m;
    let (lat_deg, lon_deg, alt_amsl_m) = HOME.geodetic_from_ned(&ned);
    GpsSample { lat_deg, lon_deg, alt_amsl_m, ..*gps }
}

#[test]
fn given_a_50_m_gps_jump_in_flight_then_rejected_within_0_6_s_the_estimate_stays_within_0_5_m_of_the_truth() {
    // The jump lasts from 8 s to 14 s, during the 1 m/s translation and its turn.
    let (est, records) = fly(Profile::Manoeuvre, 33, 20.0, |t_us, i| {
        if (8_000_000..14_000_000).contains(&t_us)
            && let Some(gps) = i.gps.as_mut()
        {
            *gps = jumped(gps, &Vector3::new(50.0, 0.0, 0.0));
        }
    });
    let rejected = first(&records, 8.0, |r| r.flags.health.gps.is_some()).expect("flagged");
    let during = worst(&records, 8.0, 14.0, hor_err_m);
    let after = worst(&records, 14.0, 20.0, hor_err_m);
    println!(
        "GPS jump of 50 m at 8 s: rejected at {:.3} s; worst horizontal error 8-14 s {during:.3} m, 14-20 s {after:.3} m",
        rejected.t_s
    );
    assert_eq!(rejected.flags.health.gps, Some(SourceFault::Rejected));
    assert!(rejected.t_s - 8.0 <= 0.6, "flagged at {:.3} s", rejected.t_s);
    assert!(!rejected.flags.position_valid && !rejected.flags.velocity_valid);
    // The estimate never follows the jump (GPS velocity, consistent, is still fused).
    assert!(during < 0.5, "followed the jump: {during} m");
    assert!(after < 0.5, "{after} m");
    let texts: Vec<String> = events(&records).iter().map(|(_, e)| e.text()).collect();
    assert_eq!(texts, ["GPS rejected: position jump", "GPS regained"]);
    let back = first(&records, 14.0, |r| r.flags.position_valid).expect("valid again");
    assert!(back.t_s < 14.01, "valid again at {:.3} s", back.t_s);
    assert!(est.state().flags.converged);
}

#[test]
fn given_the_baro_stuck_at_the_start_of_a_climb_then_stuck_within_1_2_s_height_from_gps_and_height_error_below_0_5_m() {
    // The climb of the manoeuvre: 0.5 m/s up from 30 s to 34 s (1.5 m); the baro repeats its 30 s value.
    let mut frozen: Option<BaroSample> = None;
    let (_, records) = fly(Profile::Manoeuvre, 34, 50.0, |t_us, i| {
        if let Some(baro) = i.baro.as_mut() {
            if t_us >= 30_000_000 {
                *baro = frozen.expect("a sample before 30 s");
            } else {
                frozen = Some(*baro);
            }
        }
    });
    let stuck = first(&records, 30.0, |r| r.flags.health.baro.is_some()).expect("flagged");
    let height_err = worst(&records, 30.0, 50.0, |r| r.pos_err_ned_m.map_or(f64::INFINITY, |e| e.z.abs()));
    let before = worst(&records, 20.0, 30.0, |r| r.pos_err_ned_m.map_or(f64::INFINITY, |e| e.z.abs()));
    println!(
        "baro stuck from 30 s: flagged at {:.3} s; worst height error 30-50 s {height_err:.3} m (20-30 s with the baro \
         {before:.3} m)",
        stuck.t_s
    );
    assert_eq!(stuck.flags.health.baro, Some(SourceFault::Stuck));
    assert!(stuck.t_s <= 31.2, "flagged at {:.3} s", stuck.t_s);
    assert!(
        records
            .iter()
            .filter(|r| r.t_s >= stuck.t_s)
            .all(|r| { r.flags.height_source == HeightSource::Gps && !r.flags.baro_ok && r.flags.position_valid })
    );
    assert!(height_err < 0.5, "height error {height_err} m");
    let texts: Vec<String> = events(&records).iter().map(|(_, e)| e.text()).collect();
    assert_eq!(texts, ["Baro stuck: height from GPS"]);
}

#[test]
fn given_the_mag_stuck_during_a_yaw_turn_then_stuck_within_0_3_s_and_the_heading_holds_on_the_gyro_within_0_02_rad() {
    // The full yaw turn at hover from 20 s to 30 s; the magnetometer repeats its 21 s value.
    let mut frozen: Option<MagSample> = None;
    let (_, records) = fly(Profile::Manoeuvre, 35, 40.0, |t_us, i| {
        if t_us >= 21_000_000 {
            i.mag = frozen;
        } else {
            frozen = i.mag;
        }
    });
    let stuck = first(&records, 21.0, |r| r.flags.health.mag.is_some()).expect("flagged");
    let yaw_err = worst(&records, 21.0, 40.0, |r| r.yaw_err_rad);
    println!("mag stuck from 21 s: flagged at {:.3} s; worst heading error 21-40 s {yaw_err:.4} rad", stuck.t_s);
    assert_eq!(stuck.flags.health.mag, Some(SourceFault::Stuck));
    assert!(stuck.t_s <= 21.3, "flagged at {:.3} s", stuck.t_s);
    assert!(records.iter().filter(|r| r.t_s >= stuck.t_s).all(|r| !r.flags.mag_ok && r.flags.position_valid));
    // Each stuck heading fused while turning teaches the filter a wrong gyro bias, so the detection time
    // (mag_stuck_time_s) is what the heading pays for afterwards.
    assert!(yaw_err < 0.02, "heading error {yaw_err} rad");
    let texts: Vec<String> = events(&records).iter().map(|(_, e)| e.text()).collect();
    assert_eq!(texts, ["Mag stuck: heading on gyro"]);
}

#[test]
fn given_a_stuck_or_garbage_imu_in_flight_then_it_is_flagged_critical_within_0_3_s() {
    let mut frozen: Option<ImuSample> = None;
    let (_, stuck) = fly(Profile::Manoeuvre, 36, 12.0, |t_us, i| {
        if t_us >= 10_000_000 {
            i.imu = ImuSample { time_us: t_us, ..frozen.expect("a sample before 10 s") };
        } else {
            frozen = Some(i.imu);
        }
    });
    // Garbage: uniform within ±16 g and ±35 rad/s per axis (the plant's SIM_ACC_FAIL / SIM_GYRO_FAIL 3).
    let mut rng = sim::Lcg::new(99);
    let (_, garbage) = fly(Profile::Manoeuvre, 36, 12.0, |t_us, i| {
        if t_us >= 10_000_000 {
            let mut u = || 2.0 * rng.uniform() - 1.0;
            let accel = Vector3::new(u(), u(), u()) * MAX_ACCEL_MPS2;
            let gyro = Vector3::new(u(), u(), u()) * MAX_GYRO_RADPS;
            i.imu = ImuSample { time_us: t_us, accel_frd_mps2: accel, gyro_frd_radps: gyro };
        }
    });
    for (records, fault) in [(&stuck, SourceFault::Stuck), (&garbage, SourceFault::Rejected)] {
        let flagged = first(records, 10.0, |r| r.flags.health.imu.is_some()).expect("flagged");
        println!("IMU {fault} from 10 s: flagged at {:.3} s", flagged.t_s);
        assert_eq!(flagged.flags.health.imu, Some(fault));
        assert!(flagged.t_s <= 10.3, "flagged at {:.3} s", flagged.t_s);
        assert!(!flagged.flags.converged);
        let (_, event) = events(records).into_iter().find(|(t, _)| *t >= 10.0).expect("announced");
        assert_eq!(event.severity(), EventSeverity::Critical);
        assert_eq!(event.text(), format!("IMU {fault}: attitude unreliable"));
    }
}

#[test]
fn given_healthy_noisy_runs_then_no_source_is_ever_flagged() {
    for (profile, seed, latency_us) in
        [(Profile::Manoeuvre, 41, 0), (Profile::Manoeuvre, 42, 100_000), (Profile::Hover, 43, 0)]
    {
        let mut sim = Sim::new(profile, seed);
        sim.gps_latency_us = latency_us;
        let (_, records) = fly_sim(sim, 60.0, |_, _| {});
        assert_eq!(no_fault_ever(&records), Ok(()), "{profile:?} seed {seed}");
        assert!(records.last().unwrap().flags.converged);
    }
}

#[test]
fn given_a_still_vehicle_with_noise_free_sensors_then_identical_samples_everywhere_are_never_flagged() {
    // Every sensor repeats itself bit for bit (the IMU too): nothing tells a stuck sensor from a still one.
    let mut sim = Sim::new(Profile::Hover, 44);
    let s = sim.step();
    let gps = s.gps.expect("a fix at 0 s");
    let (imu, mag, baro) = (s.imu, s.mag, s.baro.expect("a baro sample at 0 s"));
    let mut est = Estimator::new(EstimatorConfig::default());
    for k in 0..(60 * 500_u64) {
        let time_us = k * STEP_US;
        est.update_imu(&ImuSample { time_us, ..imu });
        est.update_mag(&mag);
        if k % 10 == 0 {
            est.update_baro(&baro);
        }
        if k % 50 == 0 {
            est.update_gps(&GpsSample { time_us, ..gps });
        }
        let f = est.state().flags;
        assert!(f.health.all_healthy(), "at {time_us} µs: {:?}", f.health);
        assert!(est.take_events().is_empty());
    }
    let f = est.state().flags;
    assert!(f.gps_ok && f.baro_ok && f.mag_ok && f.position_valid && f.height_source == HeightSource::Baro, "{f:?}");
}

/// How one source is fed in the property test.
#[derive(Debug, Clone, Copy)]
enum Feed {
    Healthy,
    /// Dropped for `len` steps every `period` steps.
    Dropouts {
        period: u64,
        len: u64,
    },
    /// Its sample held for `len` steps every `period` steps.
    Repeats {
        period: u64,
        len: u64,
    },
}

fn feed_strategy() -> impl Strategy<Value = Feed> {
    prop_oneof![
        Just(Feed::Healthy),
        (200_u64..3000, 1_u64..1500).prop_map(|(period, len)| Feed::Dropouts { period, len }),
        (200_u64..3000, 1_u64..1500).prop_map(|(period, len)| Feed::Repeats { period, len }),
    ]
}

/// Applies `feed` at step `k` to one source's sample, holding its last healthy one in `held`.
fn apply<T: Copy>(feed: Feed, k: u64, sample: &mut Option<T>, held: &mut Option<T>) {
    match feed {
        Feed::Healthy => {}
        Feed::Dropouts { period, len } => {
            if k % period < len {
                *sample = None;
            }
        }
        Feed::Repeats { period, len } => {
            if k % period < len {
                if sample.is_some() {
                    *sample = *held;
                }
            } else if sample.is_some() {
                *held = *sample;
            }
        }
    }
}

proptest! {
    // 12 cases of the default 256: PROPTEST_CASES scales them with every other property test.
    #![proptest_config(ProptestConfig::with_cases(ProptestConfig::default().cases * 12 / 256))]

    /// Random dropouts and repeats on the barometer and magnetometer (and GPS dropouts) never panic, keep
    /// the state finite, and never flag a source fed healthy, varying data (the IMU always; the others when
    /// drawn healthy).
    #[test]
    fn given_random_dropouts_and_repeats_then_no_panic_and_no_healthy_source_is_flagged(
        seed in 0_u64..1000,
        hover in any::<bool>(),
        baro in feed_strategy(),
        mag in feed_strategy(),
        gps_gap in prop_oneof![Just(None), (500_u64..5000, 1_u64..1000).prop_map(Some)],
    ) {
        let profile = if hover { Profile::Hover } else { Profile::Manoeuvre };
        let (mut held_baro, mut held_mag) = (None, None);
        let (est, records) = fly(profile, seed, 25.0, |t_us, i| {
            let k = t_us / STEP_US;
            apply(baro, k, &mut i.baro, &mut held_baro);
            apply(mag, k, &mut i.mag, &mut held_mag);
            if let Some((period, len)) = gps_gap && k % period < len {
                i.gps = None;
            }
        });
        let s = est.state();
        prop_assert!(s.pos_ned_m.iter().chain(s.vel_ned_mps.iter()).all(|x| x.is_finite()));
        for r in &records {
            prop_assert!(r.flags.health.imu.is_none(), "IMU flagged at {:.3} s: {:?}", r.t_s, r.flags.health);
            if matches!(baro, Feed::Healthy) {
                prop_assert!(r.flags.health.baro.is_none(), "baro flagged at {:.3} s: {:?}", r.t_s, r.flags.health);
            }
            if matches!(mag, Feed::Healthy) {
                prop_assert!(r.flags.health.mag.is_none(), "mag flagged at {:.3} s: {:?}", r.t_s, r.flags.health);
            }
            if gps_gap.is_none() {
                prop_assert!(r.flags.health.gps.is_none(), "GPS flagged at {:.3} s: {:?}", r.t_s, r.flags.health);
            }
        }
    }
}
