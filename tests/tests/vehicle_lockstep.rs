//! The whole vehicle core flown in-process, in lockstep with the real plant (`sitl::plant`, nominal
//! airframe, modest sensor noise) at 500 Hz, scripted with MAVLink messages as a ground station would send
//! them through `Vehicle::handle_message`: wait for the estimator to converge, NAV_TAKEOFF to 1.5 m, arm,
//! climb, hold 20 s, NAV_LAND, and see the auto-disarm in HEARTBEAT and EXTENDED_SYS_STATE. Pure simulated
//! time: no sleeps. Sensor samples are converted directly (no HIL encode/decode round trip).

use std::time::Instant as WallClock;

use autopilot::core::estimator::{
    BaroSample, EstimatorSource, GeoOrigin, GpsSample, ImuSample, MagSample, TruthSample,
};
use autopilot::core::mavlink::MavHeader;
use autopilot::core::mavlink::command_long;
use autopilot::core::mavlink::common::{MavCmd, MavLandedState, MavMessage, MavModeFlag, MavResult};
use autopilot::core::vehicle::{Vehicle, VehicleConfig, VehicleInputs};
use sitl::plant::{InitialState, Plant, PlantConfig, SensorConfig};

const DT_US: u64 = 2_000;
const GCS: MavHeader = MavHeader { system_id: 255, component_id: 190, sequence: 0 };

struct Rig {
    plant: Plant,
    vehicle: Vehicle,
    now_us: u64,
    /// Last HEARTBEAT base_mode and EXTENDED_SYS_STATE landed_state seen.
    base_mode: MavModeFlag,
    landed_state: Option<MavLandedState>,
}

impl Rig {
    fn new(source: EstimatorSource) -> Self {
        let config = PlantConfig { sensors: SensorConfig::modest_noise(), ..PlantConfig::default() };
        let home = config.sensors.home;
        let plant = Plant::new(config, &InitialState::default(), 7).expect("plant");
        let mut vc = VehicleConfig::default();
        vc.estimator.source = source;
        vc.estimator.truth_origin =
            Some(GeoOrigin { lat_deg: home.lat_deg, lon_deg: home.lon_deg, alt_amsl_m: home.alt_amsl_m });
        let vehicle = Vehicle::new(vc).expect("vehicle");
        Self { plant, vehicle, now_us: 0, base_mode: MavModeFlag::empty(), landed_state: None }
    }

    /// One lockstep tick: sensors -> vehicle -> plant.
    fn tick(&mut self) {
        let s = self.plant.sample_sensors();
        let t = self.plant.truth();
        let inputs = VehicleInputs {
            imu: Some(ImuSample {
                time_us: s.time_us,
                accel_frd_mps2: s.accel_frd_mps2,
                gyro_frd_radps: s.gyro_frd_radps,
            }),
            mag: Some(MagSample { field_frd_gauss: s.mag_frd_gauss }),
            baro: Some(BaroSample { pressure_alt_m: s.baro.pressure_alt_m }),
            gps: s.gps.map(|g| GpsSample {
                time_us: g.time_us,
                lat_deg: g.lat_deg,
                lon_deg: g.lon_deg,
                alt_amsl_m: g.alt_amsl_m,
                vel_ned_mps: g.vel_ned_mps,
                fix_type: g.fix_type,
                satellites: g.satellites_visible,
                eph_m: g.eph_m,
                epv_m: g.epv_m,
            }),
            truth: Some(TruthSample {
                time_us: t.time_us,
                pos_ned_m: t.pos_ned_m,
                vel_ned_mps: t.vel_ned_mps,
                q_ned_frd: t.q_ned_frd,
                rate_frd_radps: t.rate_frd_radps,
                specific_force_frd_mps2: t.specific_force_frd_mps2,
            }),
        };
        self.now_us = s.time_us;
        let out = self.vehicle.step(self.now_us, &inputs);
        assert!(out.pwm_us.iter().all(|p| p.is_finite() && (1000.0..=2000.0).contains(p)), "pwm {:?}", out.pwm_us);
        for m in &out.messages {
            match m {
                MavMessage::HEARTBEAT(h) => self.base_mode = h.base_mode,
                MavMessage::EXTENDED_SYS_STATE(e) => self.landed_state = Some(e.landed_state),
                _ => {}
            }
        }
        self.plant.step(out.pwm_us, DT_US);
    }

    fn run_s(&mut self, seconds: f64, mut each: impl FnMut(&Self)) {
        let end = self.now_us + (seconds * 1e6) as u64;
        while self.now_us < end {
            self.tick();
            each(self);
        }
    }

    /// Ticks until `cond` holds, at most `timeout_s` of vehicle time; returns the vehicle time it took (s).
    fn wait_until(&mut self, timeout_s: f64, what: &str, cond: impl Fn(&Self) -> bool) -> f64 {
        let start = self.now_us;
        while !cond(self) {
            assert!(self.now_us - start < (timeout_s * 1e6) as u64, "timed out waiting for {what}");
            self.tick();
        }
        (self.now_us - start) as f64 * 1e-6
    }

    fn command(&mut self, command: MavCmd, params: [f32; 7]) -> MavResult {
        let msg = command_long(1, 1, command, params);
        let replies = self.vehicle.handle_message(self.now_us, &GCS, &msg);
        match replies.first() {
            Some(MavMessage::COMMAND_ACK(a)) if a.command == command => a.result,
            other => panic!("no ACK for {command:?}: {other:?}"),
        }
    }
}

/// Figures of one flight.
#[derive(Debug)]
struct Flight {
    converge_s: f64,
    climb_s: f64,
    hover_est_err_m: f64,
    hover_truth_err_m: f64,
    land_s: f64,
}

fn fly(source: EstimatorSource) -> Flight {
    let mut rig = Rig::new(source);
    // GIVEN a vehicle on the ground, waiting (on vehicle time) until the estimator says it is armable.
    let converge_s = rig.wait_until(30.0, "estimator convergence", |r| r.vehicle.estimate().flags.converged);
    rig.run_s(0.5, |_| {});
    let ground_d_m = rig.vehicle.estimate().pos_ned_m.z;

    // WHEN the ground station sends NAV_TAKEOFF 1.5 m (NaN lat/lon, a relative altitude) and arms.
    let nan = f32::NAN;
    assert_eq!(
        rig.command(MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, nan, nan, nan, 1.5]),
        MavResult::MAV_RESULT_ACCEPTED
    );
    assert_eq!(
        rig.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
        MavResult::MAV_RESULT_ACCEPTED
    );
    rig.run_s(0.1, |_| {});
    assert!(rig.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED), "HEARTBEAT shows armed");

    // THEN it climbs to 1.5 m and the commander completes the takeoff into Hold.
    let target_d_m = ground_d_m - 1.5;
    let climb_s = rig.wait_until(15.0, "takeoff complete", |r| {
        r.vehicle.commander_output().state == autopilot::core::commander::State::Hold
    });
    rig.run_s(3.0, |_| {});
    let mut hover = rig.vehicle.estimate().pos_ned_m;
    hover.z = target_d_m;
    let mut truth_hover = rig.plant.truth().pos_ned_m;
    truth_hover.z = target_d_m;
    let (mut est_err, mut truth_err) = (0.0_f64, 0.0_f64);
    // AND holds within 0.10 m (estimated) of the hover point for 20 s.
    rig.run_s(20.0, |r| {
        est_err = est_err.max((r.vehicle.estimate().pos_ned_m - hover).norm());
        truth_err = truth_err.max((r.plant.truth().pos_ned_m - truth_hover).norm());
    });

    // WHEN it is told to land, THEN it descends, lands and disarms by itself.
    assert_eq!(rig.command(MavCmd::MAV_CMD_NAV_LAND, [0.0; 7]), MavResult::MAV_RESULT_ACCEPTED);
    let land_s = rig.wait_until(20.0, "auto-disarm after landing", |r| {
        !r.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED)
    });
    rig.run_s(1.1, |_| {});
    assert_eq!(rig.landed_state, Some(MavLandedState::MAV_LANDED_STATE_ON_GROUND));
    assert!(!rig.vehicle.commander().armed());
    assert!((rig.plant.truth().pos_ned_m.z).abs() < 0.05, "on the ground: {}", rig.plant.truth().pos_ned_m.z);
    let f = Flight { converge_s, climb_s, hover_est_err_m: est_err, hover_truth_err_m: truth_err, land_s };
    println!("{source:?}: {f:?}");
    assert!(f.hover_est_err_m <= 0.10, "estimated hover error > 0.10 m: {f:?}");
    assert!(f.converge_s < 30.0 && f.climb_s > 1.0 && f.land_s > 1.0, "implausible phase times: {f:?}");
    f
}

#[test]
fn given_fused_estimator_when_gcs_takes_off_holds_and_lands_then_hover_within_10cm_and_auto_disarm() {
    let wall = WallClock::now();
    let f = fly(EstimatorSource::Fused);
    println!("fused flight: {f:?}, wall {:.2} s", wall.elapsed().as_secs_f64());
    assert!(f.hover_truth_err_m < 0.5, "truth error {f:?}");
}

#[test]
fn given_truth_estimator_when_gcs_takes_off_holds_and_lands_then_hover_within_10cm_and_auto_disarm() {
    let wall = WallClock::now();
    let f = fly(EstimatorSource::Truth);
    println!("truth flight: {f:?}, wall {:.2} s", wall.elapsed().as_secs_f64());
    assert!(f.hover_truth_err_m <= 0.10, "truth error {f:?}");
}
