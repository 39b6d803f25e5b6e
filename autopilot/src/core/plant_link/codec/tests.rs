//! The plant protocol's codecs: round trips within the stated precision, edge cases and saturation.

use super::*;
use crate::core::estimator::{GeoOrigin, GpsSample, TruthSample};
use crate::core::manual::RcFrame;
use crate::core::mavlink::units::{
    MPS2_PER_G, UNKNOWN_U16, centi_u16_to, deg_to_dege7, mps_to_cmps_i16, mps2_to_mg, to_centi_u16,
};
use mavlink::MavHeader;
use mavlink::dialects::common::{MavBatteryChargeState, MavFrame, MavMessage, MavModeFlag};
use nalgebra::{UnitQuaternion, Vector3};
use proptest::prelude::*;

const HOME: GeoOrigin = GeoOrigin { lat_deg: 47.397_742, lon_deg: 8.545_594, alt_amsl_m: 488.0 };

fn header() -> MavHeader {
    MavHeader { system_id: 1, component_id: 1, sequence: 7 }
}

/// Half an f32 ulp of `x` plus a denormal floor: the error bound of one f64 -> f32 rounding.
fn f32_tol(x: f64) -> f64 {
    x.abs() * f64::from(f32::EPSILON) * 0.5 + 1e-30
}

fn vec_close_f32(a: &Vector3<f64>, b: &Vector3<f64>) -> bool {
    a.iter().zip(b.iter()).all(|(x, y)| (x - y).abs() <= f32_tol(*x))
}

fn sensor_fields(v: [f64; 12], t: u64, mag: bool, baro: bool) -> HilSensorFields {
    HilSensorFields {
        time_us: t,
        accel_frd_mps2: Vector3::new(v[0], v[1], v[2]),
        gyro_frd_radps: Vector3::new(v[3], v[4], v[5]),
        mag_frd_gauss: mag.then(|| Vector3::new(v[6], v[7], v[8])),
        baro: baro.then_some(HilBaroFields { pressure_hpa: v[9], pressure_alt_m: v[10], temperature_degc: v[11] }),
    }
}

fn gps_sample(t: u64, lat: f64, lon: f64, alt: f64, vel: [f64; 3], eph: f64) -> GpsSample {
    GpsSample {
        time_us: t,
        lat_deg: lat,
        lon_deg: lon,
        alt_amsl_m: alt,
        vel_ned_mps: Vector3::from(vel),
        fix_type: 3,
        satellites: 12,
        eph_m: eph,
        epv_m: eph * 1.5,
    }
}

#[test]
fn odometry_of_another_frame_is_not_the_plants_truth() {
    let truth = TruthSample {
        time_us: 1,
        pos_ned_m: Vector3::zeros(),
        vel_ned_mps: Vector3::zeros(),
        q_ned_frd: UnitQuaternion::identity(),
        rate_frd_radps: Vector3::zeros(),
        specific_force_frd_mps2: Vector3::zeros(),
    };
    let mut msg = encode_odometry(&truth);
    assert!(decode_odometry(&msg).is_some());
    msg.frame_id = MavFrame::MAV_FRAME_LOCAL_FRD;
    assert_eq!(decode_odometry(&msg), None);
}

proptest! {
    #[test]
    fn rc_channels_round_trip_exactly(
        channels in prop::array::uniform18(any::<u16>()), count in 0_u8..=18, rssi in any::<u8>(),
    ) {
        let frame = RcFrame { channels_us: channels, count, rssi };
        let bytes = encode_frame_v2(header(), &MavMessage::RC_CHANNELS(encode_rc_channels(&frame, 1234)));
        let decoded = FrameDecoder::new().decode_datagram(&bytes);
        prop_assert_eq!(decoded.len(), 1);
        prop_assert_eq!(decode_hil_message(&decoded[0].message, &HOME), Some(HilInput::Rc(frame)));
    }

    #[test]
    fn hil_sensor_round_trips_within_f32(
        v in prop::array::uniform12(-2000.0_f64..2000.0), t in any::<u64>(), mag in any::<bool>(),
        baro in any::<bool>(),
    ) {
        let fields = sensor_fields(v, t, mag, baro);
        let frame = encode_frame_v2(header(), &MavMessage::HIL_SENSOR(encode_hil_sensor(&fields)));
        let decoded = FrameDecoder::new().decode_datagram(&frame);
        prop_assert_eq!(decoded.len(), 1);
        let MavMessage::HIL_SENSOR(msg) = &decoded[0].message else { panic!("not HIL_SENSOR") };
        let back = decode_hil_sensor(msg);
        prop_assert_eq!(back.time_us, t);
        prop_assert!(vec_close_f32(&fields.accel_frd_mps2, &back.accel_frd_mps2));
        prop_assert!(vec_close_f32(&fields.gyro_frd_radps, &back.gyro_frd_radps));
        prop_assert_eq!(back.mag_frd_gauss.is_some(), mag);
        if let (Some(a), Some(b)) = (fields.mag_frd_gauss, back.mag_frd_gauss) {
            prop_assert!(vec_close_f32(&a, &b));
        }
        prop_assert_eq!(back.baro.is_some(), baro);
        if let (Some(a), Some(b)) = (fields.baro, back.baro) {
            prop_assert!((a.pressure_hpa - b.pressure_hpa).abs() <= f32_tol(a.pressure_hpa));
            prop_assert!((a.pressure_alt_m - b.pressure_alt_m).abs() <= f32_tol(a.pressure_alt_m));
            prop_assert!((a.temperature_degc - b.temperature_degc).abs() <= f32_tol(a.temperature_degc));
        }
        let samples = SensorSamples::from(&back);
        prop_assert_eq!(samples.imu.time_us, t);
        prop_assert_eq!(samples.mag.is_some(), mag);
        prop_assert_eq!(samples.baro.is_some(), baro);
    }

    #[test]
    fn hil_gps_round_trips_within_stated_precision(
        lat in -89.9_f64..89.9, lon in -179.9_f64..179.9, alt in -400.0_f64..9000.0,
        vel in prop::array::uniform3(-300.0_f64..300.0), eph in 0.0_f64..400.0, t in any::<u64>(),
    ) {
        let gps = gps_sample(t, lat, lon, alt, vel, eph);
        let msg = encode_hil_gps(&gps);
        let frame = encode_frame_v2(header(), &MavMessage::HIL_GPS(msg));
        let decoded = FrameDecoder::new().decode_datagram(&frame);
        let MavMessage::HIL_GPS(msg) = &decoded[0].message else { panic!("not HIL_GPS") };
        let back = decode_hil_gps(msg);
        prop_assert_eq!(back.time_us, t);
        prop_assert!((back.lat_deg - lat).abs() <= 0.5e-7 + 1e-12);
        prop_assert!((back.lon_deg - lon).abs() <= 0.5e-7 + 1e-12);
        prop_assert!((back.alt_amsl_m - alt).abs() <= 0.5e-3 + 1e-9);
        prop_assert!((back.vel_ned_mps - gps.vel_ned_mps).amax() <= 0.005 + 1e-9);
        prop_assert!((back.eph_m - eph).abs() <= 0.005 + 1e-9);
        prop_assert!((back.epv_m - gps.epv_m).abs() <= 0.005 + 1e-9);
        prop_assert_eq!((back.fix_type, back.satellites), (3, 12));
        prop_assert!(msg.cog < 36_000);
        let speed = vel[0].hypot(vel[1]);
        prop_assert!((f64::from(msg.vel) * 0.01 - speed).abs() <= 0.005 + 1e-9);
    }

    #[test]
    fn hil_state_quaternion_round_trips_within_stated_precision(
        pos in prop::array::uniform3(-3000.0_f64..3000.0), vel in prop::array::uniform3(-300.0_f64..300.0),
        axis_angle in prop::array::uniform3(-3.0_f64..3.0), rate in prop::array::uniform3(-30.0_f64..30.0),
        acc in prop::array::uniform3(-300.0_f64..300.0), t in any::<u64>(),
    ) {
        let truth = TruthSample {
            time_us: t,
            pos_ned_m: Vector3::from(pos),
            vel_ned_mps: Vector3::from(vel),
            q_ned_frd: UnitQuaternion::from_scaled_axis(Vector3::from(axis_angle)),
            rate_frd_radps: Vector3::from(rate),
            specific_force_frd_mps2: Vector3::from(acc),
        };
        let msg = encode_hil_state_quaternion(&truth, &HOME, 12.34);
        let frame = encode_frame_v2(header(), &MavMessage::HIL_STATE_QUATERNION(msg));
        let decoded = FrameDecoder::new().decode_datagram(&frame);
        let MavMessage::HIL_STATE_QUATERNION(msg) = &decoded[0].message else { panic!("not HIL_STATE_QUATERNION") };
        let back = decode_hil_state_quaternion(msg, &HOME);
        prop_assert_eq!(back.time_us, t);
        // degE7 rounding: ≤ 5.6 mm north, ≤ 5.6 mm·cos φ east (+ f64 noise of the map); mm altitude.
        let dp = back.pos_ned_m - truth.pos_ned_m;
        prop_assert!(dp.x.abs() <= 5.6e-3 && dp.y.abs() <= 5.6e-3 && dp.z.abs() <= 0.5e-3 + 1e-9, "dp {:?}", dp);
        prop_assert!((back.vel_ned_mps - truth.vel_ned_mps).amax() <= 0.005 + 1e-9);
        prop_assert!(back.q_ned_frd.angle_to(&truth.q_ned_frd) <= 2.5e-7);
        prop_assert!(vec_close_f32(&truth.rate_frd_radps, &back.rate_frd_radps));
        prop_assert!((back.specific_force_frd_mps2 - truth.specific_force_frd_mps2).amax() <= 0.5e-3 * MPS2_PER_G + 1e-9);
        prop_assert_eq!((msg.ind_airspeed, msg.true_airspeed), (1234, 1234));
    }

    #[test]
    fn odometry_refines_truth_to_f32_precision(
        pos in prop::array::uniform3(-300.0_f64..300.0), vel in prop::array::uniform3(-30.0_f64..30.0),
        axis_angle in prop::array::uniform3(-3.0_f64..3.0), t in any::<u64>(),
    ) {
        let truth = TruthSample {
            time_us: t,
            pos_ned_m: Vector3::from(pos),
            vel_ned_mps: Vector3::from(vel),
            q_ned_frd: UnitQuaternion::from_scaled_axis(Vector3::from(axis_angle)),
            rate_frd_radps: Vector3::new(0.1, -0.2, 0.3),
            specific_force_frd_mps2: Vector3::new(0.0, 0.0, -9.8),
        };
        let frame = encode_frame_v2(header(), &MavMessage::ODOMETRY(encode_odometry(&truth)));
        let decoded = FrameDecoder::new().decode_datagram(&frame);
        let Some(HilInput::LocalTruth(local)) = decode_hil_message(&decoded[0].message, &HOME) else {
            panic!("not the plant's ODOMETRY")
        };
        let coarse = TruthSample { pos_ned_m: truth.pos_ned_m.add_scalar(0.005), ..truth };
        let back = local.refine(&coarse);
        prop_assert!(vec_close_f32(&truth.pos_ned_m, &back.pos_ned_m), "{:?}", back.pos_ned_m - truth.pos_ned_m);
        prop_assert!(vec_close_f32(&truth.vel_ned_mps, &back.vel_ned_mps));
        prop_assert!(back.q_ned_frd.angle_to(&truth.q_ned_frd) <= 2.5e-7);
        prop_assert_eq!(back.specific_force_frd_mps2, truth.specific_force_frd_mps2);
    }

    #[test]
    fn pwm_round_trips_within_f32(
        pwm in prop::array::uniform4(1000.0_f64..=2000.0), t in any::<u64>(), armed in any::<bool>(),
        motor_test in any::<bool>(),
    ) {
        let cmd = ActuatorCommand { time_us: t, pwm_us: pwm, armed, motor_test };
        let frame = encode_frame_v2(header(), &MavMessage::HIL_ACTUATOR_CONTROLS(encode_actuator_controls(&cmd)));
        let decoded = FrameDecoder::new().decode_datagram(&frame);
        let MavMessage::HIL_ACTUATOR_CONTROLS(msg) = &decoded[0].message else { panic!("not HIL_ACTUATOR_CONTROLS") };
        let back = decode_actuator_controls(msg);
        prop_assert_eq!((back.time_us, back.armed, back.motor_test), (t, armed, motor_test));
        for (a, b) in back.pwm_us.iter().zip(pwm) {
            prop_assert!((a - b).abs() <= 3e-5, "{} vs {}", a, b);
        }
    }


}

#[test]
fn pwm_mapping_edge_cases() {
    assert_eq!(pwm_us_to_control(1000.0), 0.0);
    assert_eq!(pwm_us_to_control(2000.0), 1.0);
    assert_eq!(pwm_us_to_control(1500.0), 0.5);
    assert_eq!(pwm_us_to_control(999.0), 0.0);
    assert_eq!(pwm_us_to_control(-1e300), 0.0);
    assert_eq!(pwm_us_to_control(2500.0), 1.0);
    assert_eq!(pwm_us_to_control(f64::NAN), 0.0);
    assert_eq!(pwm_us_to_control(f64::INFINITY), 0.0);
    assert_eq!(pwm_us_to_control(f64::NEG_INFINITY), 0.0);
    assert_eq!(control_to_pwm_us(0.0), 1000.0);
    assert_eq!(control_to_pwm_us(1.0), 2000.0);
    assert_eq!(control_to_pwm_us(-1.0), 1000.0);
    assert_eq!(control_to_pwm_us(1.5), 2000.0);
    assert_eq!(control_to_pwm_us(f32::NAN), 1000.0);
    assert_eq!(control_to_pwm_us(f32::INFINITY), 1000.0);
    let cmd = ActuatorCommand { time_us: 5, pwm_us: [f64::NAN, 3000.0, 500.0, 1234.5], armed: true, motor_test: false };
    let msg = encode_actuator_controls(&cmd);
    assert_eq!(&msg.controls[..4], &[0.0, 1.0, 0.0, 0.2345]);
    assert!(msg.controls[4..].iter().all(|&c| c == 0.0));
    assert_eq!(msg.mode.bits(), MODE_FLAG_SAFETY_ARMED);
    let back = decode_actuator_controls(&msg);
    assert_eq!(back.pwm_us[..3], [1000.0, 2000.0, 1000.0]);
    assert!((back.pwm_us[3] - 1234.5).abs() < 3e-5);
    let disarmed = decode_actuator_controls(&encode_actuator_controls(&ActuatorCommand { armed: false, ..cmd }));
    assert!(!disarmed.armed);
    assert_eq!(encode_actuator_controls(&disarmed).mode.bits(), 0);
    assert_eq!(disarmed.effective_pwm_us(), [1000.0; 4]);
    // A motor test on the disarmed vehicle: its own flag, and the plant runs the motors on the PWM.
    let test = ActuatorCommand { armed: false, motor_test: true, pwm_us: [1000.0, 1000.0, 1200.0, 1000.0], ..cmd };
    let msg = encode_actuator_controls(&test);
    assert_eq!(msg.mode, MavModeFlag::MAV_MODE_FLAG_TEST_ENABLED);
    let back = decode_actuator_controls(&msg);
    assert!(back.motor_test && !back.armed && back.motors_running());
    assert!((back.effective_pwm_us()[2] - 1200.0).abs() < 3e-5);
}

#[test]
fn integer_fields_saturate_and_unknowns_decode_as_infinite() {
    assert_eq!(mps_to_cmps_i16(1e9), i16::MAX);
    assert_eq!(mps_to_cmps_i16(-1e9), i16::MIN);
    assert_eq!(mps_to_cmps_i16(f64::NAN), 0);
    assert_eq!(mps2_to_mg(1e9), i16::MAX);
    assert_eq!(to_centi_u16(1e9), UNKNOWN_U16 - 1);
    assert_eq!(to_centi_u16(f64::NAN), UNKNOWN_U16);
    assert_eq!(to_centi_u16(-1.0), UNKNOWN_U16);
    assert_eq!(centi_u16_to(UNKNOWN_U16), f64::INFINITY);
    assert_eq!(deg_to_dege7(47.397_742_3), 473_977_423);
    assert_eq!(course_deg(&Vector3::new(0.0, -1.0, 0.0)), 270.0);
    let msg = encode_hil_gps(&gps_sample(1, 0.0, 0.0, 0.0, [f64::NAN, 0.0, 0.0], f64::NAN));
    assert_eq!((msg.cog, msg.eph), (UNKNOWN_U16, UNKNOWN_U16));
    assert_eq!(decode_hil_gps(&msg).eph_m, f64::INFINITY);
}

#[test]
fn hil_sensor_encodes_pressure_units_and_flags() {
    let fields =
        sensor_fields([0.0, 0.0, -9.80665, 0.1, 0.2, 0.3, 0.2, 0.0, 0.4, 955.0, 488.0, 11.8], 2000, true, true);
    let msg = encode_hil_sensor(&fields);
    assert_eq!(msg.fields_updated.bits(), 0x1FFF & !0x400); // all but diff_pressure
    assert_eq!((msg.abs_pressure, msg.pressure_alt, msg.temperature), (955.0, 488.0, 11.8));
    let imu_only = encode_hil_sensor(&sensor_fields([0.0; 12], 0, false, false));
    assert_eq!(imu_only.fields_updated.bits(), 0x3F);
}

#[test]
fn given_a_pack_reading_when_battery_status_round_trips_then_within_the_wire_resolution() {
    use crate::core::battery::BatterySample;
    for cells in [0_u8, 6, 12, 14] {
        let b = BatterySample {
            voltage_v: 22.2,
            current_a: Some(31.234),
            remaining: Some(0.4567),
            consumed_mah: Some(5432.4),
            consumed_j: Some(123_456.0),
            cells,
        };
        let msg =
            MavMessage::BATTERY_STATUS(encode_battery_status(&b, MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_OK));
        let frame = encode_frame_v2(header(), &msg);
        let decoded = FrameDecoder::new().push(&frame);
        let Some(HilInput::Battery(got)) = decode_hil_message(&decoded[0].message, &HOME) else {
            panic!("not a battery")
        };
        assert_eq!(got.cells, cells);
        assert!((got.voltage_v - 22.2).abs() <= 0.0005 * f64::from(cells.max(1)), "{cells} cells: {}", got.voltage_v);
        assert_eq!(got.current_a, Some(31.23));
        assert_eq!(got.remaining, Some(0.45), "truncated to whole percent");
        assert_eq!(got.consumed_mah, Some(5432.0));
        assert_eq!(got.consumed_j, Some(123_500.0));
    }
    let unknown = BatterySample { voltage_v: 12.0, ..BatterySample::default() };
    let got = decode_battery_status(&encode_battery_status(
        &unknown,
        MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_UNDEFINED,
    ));
    assert_eq!((got.current_a, got.remaining, got.consumed_mah, got.consumed_j), (None, None, None, None));
}
