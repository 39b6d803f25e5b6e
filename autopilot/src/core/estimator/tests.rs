//! Closed scenarios of the estimator against the kinematic simulator ([`super::sim`]): 500 Hz IMU and
//! magnetometer, 50 Hz barometer, 10 Hz GPS, with the brief's noises and constant IMU biases.

use nalgebra::{UnitQuaternion, Vector3};

use super::sim::{self, HOME, Profile, STEP_US, Sim, Step};
use super::*;

fn feed(est: &mut Estimator, s: &Step) {
    est.update_imu(&s.imu);
    est.update_mag(&s.mag);
    if let Some(baro) = s.baro {
        est.update_baro(&baro);
    }
    if let Some(gps) = s.gps {
        est.update_gps(&gps);
    }
}

/// Flies `sim` for `duration_s`, calling `each` after every step with the time (s), step and state.
fn fly(sim: &mut Sim, est: &mut Estimator, duration_s: f64, mut each: impl FnMut(f64, &Step, &EstimatorState)) {
    let steps = (duration_s * 1e6 / STEP_US as f64).round() as u64;
    for _ in 0..steps {
        let s = sim.step();
        feed(est, &s);
        each(s.time_us as f64 * 1e-6, &s, est.state());
    }
}

/// Estimation errors against the truth, once the origin is latched: position (m, with the truth moved into
/// the estimator's NED about its own origin), velocity (m/s) and attitude (rad, rotation angle).
#[derive(Debug, Clone, Copy)]
struct Errors {
    /// Estimate minus truth (m, NED).
    pos_ned_m: Vector3<f64>,
    pos_m: f64,
    vel_mps: f64,
    att_rad: f64,
}

fn errors(state: &EstimatorState, truth: &TruthSample) -> Option<Errors> {
    let origin = state.origin?;
    let (lat, lon, alt) = HOME.geodetic_from_ned(&truth.pos_ned_m);
    let truth_pos_ned_m = origin.ned_from_geodetic(lat, lon, alt);
    Some(Errors {
        pos_ned_m: state.pos_ned_m - truth_pos_ned_m,
        pos_m: (state.pos_ned_m - truth_pos_ned_m).norm(),
        vel_mps: (state.vel_ned_mps - truth.vel_ned_mps).norm(),
        att_rad: state.q_ned_frd.angle_to(&truth.q_ned_frd),
    })
}

fn rms(values: &[f64]) -> f64 {
    (values.iter().map(|v| v * v).sum::<f64>() / values.len() as f64).sqrt()
}

fn state_bits(s: &EstimatorState) -> Vec<u64> {
    let mut bits = vec![s.time_us];
    for v in [
        s.pos_ned_m,
        s.vel_ned_mps,
        s.euler_rad,
        s.rate_frd_radps,
        s.specific_force_frd_mps2,
        s.accel_bias_frd_mps2,
        s.gyro_bias_frd_radps,
    ] {
        bits.extend(v.iter().map(|x| x.to_bits()));
    }
    bits.extend(s.q_ned_frd.coords.iter().map(|x| x.to_bits()));
    if let Some(o) = s.origin {
        bits.extend([o.lat_deg.to_bits(), o.lon_deg.to_bits(), o.alt_amsl_m.to_bits()]);
    }
    let f = s.flags;
    bits.push(u64::from(
        [f.attitude_valid, f.velocity_valid, f.position_valid, f.converged, f.gps_ok, f.baro_ok, f.mag_ok]
            .iter()
            .fold(0u8, |acc, &b| (acc << 1) | u8::from(b)),
    ));
    bits
}

fn all_finite(s: &EstimatorState) -> bool {
    [s.pos_ned_m, s.vel_ned_mps, s.euler_rad, s.rate_frd_radps, s.specific_force_frd_mps2, s.accel_bias_frd_mps2]
        .iter()
        .all(|v| v.iter().all(|x| x.is_finite()))
        && s.q_ned_frd.coords.iter().all(|x| x.is_finite())
}

#[test]
fn given_a_level_zero_start_when_flying_with_noise_and_biases_then_it_converges_within_10_s_and_not_before_gps() {
    let mut sim = Sim::new(Profile::Manoeuvre, 11);
    sim.gps_start_us = 2_000_000;
    let mut est = Estimator::new(EstimatorConfig::default());
    assert_eq!(est.state().q_ned_frd, UnitQuaternion::identity());
    assert_eq!(est.state().pos_ned_m, Vector3::zeros());

    let mut first_gps_ok_s = None;
    let mut first_converged_s = None;
    let (mut worst_att_after_10, mut worst_pos_after_10) = (0.0_f64, 0.0_f64);
    fly(&mut sim, &mut est, 20.0, |t, step, state| {
        if state.flags.gps_ok && first_gps_ok_s.is_none() {
            first_gps_ok_s = Some(t);
        }
        if state.flags.converged && first_converged_s.is_none() {
            first_converged_s = Some(t);
        }
        if t >= 10.0 {
            let e = errors(state, &step.truth).expect("origin latched");
            worst_att_after_10 = worst_att_after_10.max(e.att_rad);
            worst_pos_after_10 = worst_pos_after_10.max(e.pos_m);
            assert!(state.flags.converged, "converged dropped at {t:.3} s");
        }
    });
    let gps_s = first_gps_ok_s.expect("GPS fused");
    let converged_s = first_converged_s.expect("converged");
    println!(
        "first GPS fused {gps_s:.3} s, converged {converged_s:.3} s; after 10 s: worst attitude error {worst_att_after_10:.4} rad, worst position error {worst_pos_after_10:.3} m"
    );
    assert!(gps_s >= 2.0);
    assert!(converged_s > gps_s, "converged at {converged_s} s before GPS at {gps_s} s");
    assert!(converged_s <= 10.0, "converged only at {converged_s} s");
    assert!(worst_att_after_10 < 0.02, "attitude error {worst_att_after_10} rad");
    assert!(worst_pos_after_10 < 0.3, "position error {worst_pos_after_10} m");
}

#[test]
fn given_60_s_of_motion_when_flown_then_the_imu_biases_are_estimated() {
    let mut sim = Sim::new(Profile::Manoeuvre, 12);
    let mut est = Estimator::new(EstimatorConfig::default());
    fly(&mut sim, &mut est, 60.0, |_, _, _| {});
    let s = est.state();
    let accel_err = s.accel_bias_frd_mps2 - sim::ACCEL_BIAS_FRD_MPS2;
    let gyro_err = s.gyro_bias_frd_radps - sim::GYRO_BIAS_FRD_RADPS;
    println!("accel bias {:.4?} (error {:.4?}) m/s²", s.accel_bias_frd_mps2.as_slice(), accel_err.as_slice());
    println!("gyro bias {:.5?} (error {:.5?}) rad/s", s.gyro_bias_frd_radps.as_slice(), gyro_err.as_slice());
    assert!(accel_err.amax() < 0.03, "accelerometer bias error {accel_err}");
    assert!(gyro_err.amax() < 0.002, "gyro bias error {gyro_err}");
}

#[test]
fn given_a_hover_with_noise_when_converged_then_position_and_velocity_errors_are_small_rms() {
    let mut sim = Sim::new(Profile::Hover, 13);
    let mut est = Estimator::new(EstimatorConfig::default());
    let (mut pos, mut vel, mut att) = (Vec::new(), Vec::new(), Vec::new());
    fly(&mut sim, &mut est, 60.0, |t, step, state| {
        if t >= 10.0 {
            let e = errors(state, &step.truth).expect("origin latched");
            pos.push(e.pos_m);
            vel.push(e.vel_mps);
            att.push(e.att_rad);
        }
    });
    let (pos_rms, vel_rms, att_rms) = (rms(&pos), rms(&vel), rms(&att));
    println!(
        "hover 10-60 s: position {pos_rms:.4} m RMS, velocity {vel_rms:.4} m/s RMS, attitude {att_rms:.4} rad RMS"
    );
    assert!(pos_rms < 0.15, "position RMS {pos_rms} m");
    assert!(vel_rms < 0.1, "velocity RMS {vel_rms} m/s");
    // At a constant heading the horizontal accelerometer bias (0.14 m/s²) is indistinguishable from a tilt of
    // b/g = 0.0144 rad, and the heading levelled with that tilt is off by up to tan(63.6 deg) times it: the
    // attitude error is bounded by 0.0144 * sqrt(1 + tan²(dip)) = 0.032 rad until the vehicle turns.
    assert!(att_rms < 0.032, "attitude RMS {att_rms} rad");
}

/// Position errors during the first 1 m/s translation (5-16 s): worst (m), RMS (m) and mean along-track
/// error (m, negative = behind the vehicle).
fn translation_errors(gps_latency_us: u64, latency_compensation: bool) -> (f64, f64, f64) {
    let mut sim = Sim::new(Profile::Manoeuvre, 14);
    sim.gps_latency_us = gps_latency_us;
    let mut est = Estimator::new(EstimatorConfig { latency_compensation, ..EstimatorConfig::default() });
    let (mut errs, mut along) = (Vec::new(), Vec::new());
    fly(&mut sim, &mut est, 16.0, |t, step, state| {
        if t >= 5.0 {
            let e = errors(state, &step.truth).expect("origin latched");
            errs.push(e.pos_m);
            along.push(e.pos_ned_m.dot(&step.truth.vel_ned_mps.normalize()));
        }
    });
    (errs.iter().copied().fold(0.0, f64::max), rms(&errs), along.iter().sum::<f64>() / along.len() as f64)
}

#[test]
fn given_100_ms_gps_latency_when_translating_then_compensation_keeps_the_error_below_0_2_m_and_without_it_lags() {
    // The same noise in all three runs: the zero-latency run is the reference for the along-track error.
    let (_, rms_ref, along_ref) = translation_errors(0, true);
    let (max_on, rms_on, along_on) = translation_errors(100_000, true);
    let (max_off, rms_off, along_off) = translation_errors(100_000, false);
    println!(
        "5-16 s at 1 m/s: no latency RMS {rms_ref:.3} m along-track {along_ref:+.3} m; 100 ms compensated max \
         {max_on:.3} m RMS {rms_on:.3} m along-track {along_on:+.3} m; uncompensated max {max_off:.3} m RMS \
         {rms_off:.3} m along-track {along_off:+.3} m"
    );
    assert!(max_on < 0.2, "compensated worst error {max_on} m");
    assert!((along_on - along_ref).abs() < 0.02, "compensated along-track {along_on} m vs {along_ref} m");
    // Uncompensated, the estimate is pulled back towards where the vehicle was 0.1 s (0.1 m) before.
    assert!(along_off - along_ref < -0.06, "uncompensated along-track {along_off} m vs {along_ref} m");
    assert!(rms_off > rms_on && max_off > max_on);
}

#[test]
fn given_gps_lost_when_0_5_s_of_vehicle_time_passes_then_gps_ok_and_position_valid_drop_and_recover_when_it_returns() {
    let mut sim = Sim::new(Profile::Manoeuvre, 15);
    // In the middle of the 1 m/s translation: the last fix before the outage is valid (and arrives) at
    // 9.9 s, the next at 15.0 s.
    sim.gps_outage_us = Some((9_950_000, 15_000_000));
    let mut est = Estimator::new(EstimatorConfig::default());
    let mut flags_at = Vec::new();
    let mut worst_pos_after_return: f64 = 0.0;
    fly(&mut sim, &mut est, 20.0, |t, step, state| {
        flags_at.push((step.time_us, state.flags));
        if t >= 16.0 {
            worst_pos_after_return = worst_pos_after_return.max(errors(state, &step.truth).unwrap().pos_m);
        }
    });
    let flags = |time_us: u64| flags_at.iter().find(|(t, _)| *t == time_us).unwrap().1;
    let before = flags(9_900_000);
    assert!(before.gps_ok && before.position_valid && before.velocity_valid && before.converged, "{before:?}");
    let last_ok = flags(10_400_000);
    assert!(last_ok.gps_ok && last_ok.position_valid, "still within 0.5 s: {last_ok:?}");
    let lost = flags(10_402_000);
    assert!(!lost.gps_ok && !lost.position_valid && !lost.velocity_valid && !lost.converged, "{lost:?}");
    assert!(lost.attitude_valid && lost.baro_ok && lost.mag_ok, "other sensors unaffected: {lost:?}");
    let back = flags(15_000_000);
    assert!(back.gps_ok && back.position_valid && back.velocity_valid, "{back:?}");
    println!("GPS back at 15 s: worst position error 16-20 s {worst_pos_after_return:.3} m");
    assert!(worst_pos_after_return < 0.3, "{worst_pos_after_return} m");
    // Convergence comes back once GPS has been fused long enough again.
    assert!(!flags(15_000_000).converged && flags(19_998_000).converged);
}

#[test]
fn given_a_sudden_accelerometer_bias_step_when_converged_then_convergence_drops_until_the_filter_resettles() {
    // A 0.5 m/s² step on x at 12 s (2.5 sigma of the bias prior) acts like a sudden 0.05 rad tilt error: the
    // GPS velocity innovations grow, the attitude is no longer settled, and it takes the yaw turn at
    // 20-30 s to relearn the bias.
    let mut sim = Sim::new(Profile::Manoeuvre, 21);
    let mut est = Estimator::new(EstimatorConfig::default());
    let mut transitions = Vec::new();
    let mut converged = false;
    for _ in 0..(40 * 500) {
        let mut s = sim.step();
        if s.time_us >= 12_000_000 {
            s.imu.accel_frd_mps2.x += 0.5;
        }
        feed(&mut est, &s);
        if est.state().flags.converged != converged {
            converged = est.state().flags.converged;
            transitions.push((s.time_us as f64 * 1e-6, converged));
        }
    }
    println!("converged transitions (s, state): {transitions:?}");
    let first_drop = transitions.iter().find(|(t, c)| *t >= 12.0 && !c).expect("convergence dropped").0;
    assert!(transitions.iter().any(|(t, c)| *t < 12.0 && *c), "converged before the step: {transitions:?}");
    assert!(first_drop < 15.0, "dropped only at {first_drop} s");
    assert!(est.state().flags.converged, "not back by 40 s: {transitions:?}");
}

#[test]
fn given_silent_baro_and_imu_when_time_passes_then_their_flags_drop_on_the_sample_clock() {
    let mut sim = Sim::new(Profile::Hover, 16);
    let mut est = Estimator::new(EstimatorConfig::default());
    fly(&mut sim, &mut est, 10.0, |_, _, _| {});
    assert!(est.state().flags.baro_ok && est.state().flags.attitude_valid);
    // Barometer silent: still ok 0.5 s after its last sample, not after.
    let mut last_baro_us = 0;
    for _ in 0..300 {
        let s = sim.step();
        est.update_imu(&s.imu);
        est.update_mag(&s.mag);
        if let Some(baro) = s.baro.filter(|_| last_baro_us == 0) {
            est.update_baro(&baro);
            last_baro_us = s.time_us;
        }
        let expect_ok = last_baro_us == 0 || s.time_us <= last_baro_us + 500_000;
        assert_eq!(est.state().flags.baro_ok, expect_ok, "at {} µs", s.time_us);
    }
    assert!(!est.state().flags.baro_ok);
    // IMU silent: the clock alone moves on.
    let last_imu_us = est.state().time_us;
    est.update_clock(last_imu_us + 100_000);
    assert!(est.state().flags.attitude_valid);
    est.update_clock(last_imu_us + 100_001);
    let f = est.state().flags;
    assert!(!f.attitude_valid && !f.velocity_valid && !f.position_valid && !f.converged, "{f:?}");
    // Back: the IMU returns after the gap (the filter coasts over it) and the attitude is valid again.
    let mut s = sim.step();
    s.imu.time_us = last_imu_us + 150_000;
    est.update_imu(&s.imu);
    assert!(est.state().flags.attitude_valid);
    assert!(all_finite(est.state()));
}

#[test]
fn given_the_truth_source_when_truth_arrives_then_the_state_copies_it_exactly_and_sensors_are_ignored() {
    let origin = GeoOrigin { lat_deg: 1.0, lon_deg: 2.0, alt_amsl_m: 3.0 };
    let config = EstimatorConfig { source: EstimatorSource::Truth, truth_origin: Some(origin), ..Default::default() };
    let mut est = Estimator::new(config);
    let mut sim = Sim::new(Profile::Manoeuvre, 17);
    for _ in 0..10_000 {
        let s = sim.step();
        feed(&mut est, &s);
        est.update_truth(&s.truth);
        let st = est.state();
        assert_eq!(st.time_us, s.truth.time_us);
        assert_eq!(st.pos_ned_m, s.truth.pos_ned_m);
        assert_eq!(st.vel_ned_mps, s.truth.vel_ned_mps);
        assert_eq!(st.q_ned_frd, s.truth.q_ned_frd);
        assert_eq!(st.rate_frd_radps, s.truth.rate_frd_radps);
        assert_eq!(st.specific_force_frd_mps2, s.truth.specific_force_frd_mps2);
        assert_eq!(st.accel_bias_frd_mps2, Vector3::zeros());
        assert_eq!(st.origin, Some(origin));
        let f = st.flags;
        assert!(f.attitude_valid && f.velocity_valid && f.position_valid && f.converged);
        assert!(f.gps_ok && f.baro_ok && f.mag_ok);
        let back = UnitQuaternion::from_euler_angles(st.euler_rad.x, st.euler_rad.y, st.euler_rad.z);
        assert!(back.angle_to(&st.q_ned_frd) < 1e-9);
    }
    assert_eq!(est.rejected_samples(), 0);

    // And the fused source ignores truth entirely.
    let mut fused = Estimator::new(EstimatorConfig::default());
    let s = sim.step();
    fused.update_truth(&s.truth);
    assert_eq!(*fused.state(), EstimatorState::default());
}

#[test]
fn given_nan_and_absurd_samples_when_fed_then_they_are_rejected_counted_and_change_nothing() {
    let nan = f64::NAN;
    let mut clean = Estimator::new(EstimatorConfig::default());
    let mut dirty = Estimator::new(EstimatorConfig::default());
    let mut sim_clean = Sim::new(Profile::Manoeuvre, 18);
    let mut sim_dirty = Sim::new(Profile::Manoeuvre, 18);
    let mut injected = 0;
    for k in 0..7_500_u64 {
        let s = sim_clean.step();
        feed(&mut clean, &s);
        let s = sim_dirty.step();
        feed(&mut dirty, &s);
        if k % 500 == 250 {
            // Every bad kind once per second of the run (12.5 s after alignment, with GPS and baro fused).
            let mut bad_imu = [s.imu; 6];
            bad_imu[0].accel_frd_mps2.x = nan;
            bad_imu[1].gyro_frd_radps.z = f64::INFINITY;
            bad_imu[2].accel_frd_mps2 = Vector3::new(0.0, 0.0, -17.0 * eskf::GRAVITY_MPS2);
            bad_imu[3].gyro_frd_radps = Vector3::new(36.0, 0.0, 0.0);
            bad_imu[4].time_us += 1_000;
            bad_imu[4].accel_frd_mps2.y = nan;
            bad_imu[5].gyro_frd_radps.x += 1e-3; // Plausible, but not after the previous sample.
            for imu in &bad_imu {
                dirty.update_imu(imu);
            }
            dirty.update_mag(&MagSample { field_frd_gauss: Vector3::new(nan, 0.2, 0.4) });
            dirty.update_mag(&MagSample { field_frd_gauss: Vector3::new(50.0, 0.0, 0.0) });
            dirty.update_mag(&MagSample { field_frd_gauss: Vector3::zeros() });
            dirty.update_baro(&BaroSample { pressure_alt_m: nan });
            dirty.update_baro(&BaroSample { pressure_alt_m: 1.0e6 });
            let good_gps = GpsSample {
                time_us: s.time_us,
                lat_deg: HOME.lat_deg,
                lon_deg: HOME.lon_deg,
                alt_amsl_m: 500.0,
                vel_ned_mps: Vector3::zeros(),
                fix_type: 3,
                satellites: 10,
                eph_m: 0.5,
                epv_m: 0.8,
            };
            let bad_gps = [
                GpsSample { fix_type: 2, ..good_gps },
                GpsSample { lat_deg: nan, ..good_gps },
                GpsSample { lon_deg: 200.0, ..good_gps },
                GpsSample { alt_amsl_m: f64::INFINITY, ..good_gps },
                GpsSample { vel_ned_mps: Vector3::new(0.0, nan, 0.0), ..good_gps },
                GpsSample { eph_m: nan, ..good_gps },
                GpsSample { time_us: s.time_us.saturating_sub(600_000), ..good_gps }, // Older than the history.
            ];
            for gps in &bad_gps {
                dirty.update_gps(gps);
            }
            injected += bad_imu.len() + 3 + 2 + bad_gps.len();
        }
        assert!(all_finite(dirty.state()));
    }
    assert_eq!(dirty.rejected_samples(), injected as u64);
    assert_eq!(clean.rejected_samples(), 0);
    assert_eq!(state_bits(dirty.state()), state_bits(clean.state()), "a rejected sample changed the state");
    assert!(dirty.state().flags.converged);
}

#[test]
fn given_the_same_inputs_when_run_twice_or_after_reset_then_the_states_are_bit_identical() {
    let run = |est: &mut Estimator| {
        let mut sim = Sim::new(Profile::Manoeuvre, 19);
        sim.gps_latency_us = 100_000;
        let mut trace = Vec::new();
        fly(&mut sim, est, 20.0, |_, _, state| trace.push(state_bits(state)));
        trace
    };
    let mut a = Estimator::new(EstimatorConfig::default());
    let mut b = Estimator::new(EstimatorConfig::default());
    let trace_a = run(&mut a);
    let trace_b = run(&mut b);
    assert!(trace_a == trace_b, "two estimators diverged");
    a.reset();
    assert_eq!(a, Estimator::new(EstimatorConfig::default()));
    let trace_reset = run(&mut a);
    assert!(trace_a == trace_reset, "reset did not restore the initial state");
}

#[test]
fn given_default_and_broken_configs_when_validated_then_only_the_broken_ones_fail() {
    assert_eq!(EstimatorConfig::default().validate(), Ok(()));
    let broken = EstimatorConfig { gps_timeout_s: f64::NAN, ..Default::default() };
    assert_eq!(broken.validate().unwrap_err().field, "gps_timeout_s");
    let broken = EstimatorConfig { accel_noise_mps2: 0.0, ..Default::default() };
    assert_eq!(broken.validate().unwrap_err().field, "accel_noise_mps2");
    let broken = EstimatorConfig { mag_declination_deg: f64::INFINITY, ..Default::default() };
    assert!(broken.validate().unwrap_err().to_string().contains("mag_declination_deg"));
}
