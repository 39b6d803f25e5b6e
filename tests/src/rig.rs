//! The whole vehicle core in-process, in lockstep with the real plant (`sitl::plant`) at 500 Hz, driven
//! by MAVLink messages as a ground station sends them (`Vehicle::handle_message`). Sensor samples and the
//! pack's readings (10 Hz, as the plant link sends them) are converted directly (no HIL encode/decode
//! round trip). The plant link's delay and loss (`SIM_LINK_DELAY`, `SIM_LINK_LOSS`) are applied as
//! `sitl::link` applies them: a tick delivers the newest sample at least the delay old, or none (lost,
//! or still on its way), and then the plant steps on the last command. Pure simulated time: no sleeps.

use std::collections::VecDeque;

use autopilot::core::commander::FlightMode;
use autopilot::core::estimator::{BaroSample, EstimatorSource, GeoOrigin, ImuSample, MagSample, TruthSample};
use autopilot::core::mavlink::MavHeader;
use autopilot::core::mavlink::command_long;
use autopilot::core::mavlink::common::{
    FailureType, FailureUnit, MavCmd, MavLandedState, MavMessage, MavModeFlag, MavResult, PARAM_SET_DATA,
};
use autopilot::core::mavlink::failure::FailureRequest;
use autopilot::core::mavlink::params::{decode_value, encode_value};
use autopilot::core::params::PARAMS;
use autopilot::core::plant_link::PlantCommandAck;
use autopilot::core::vehicle::{Vehicle, VehicleConfig, VehicleInputs};
use sitl::plant::{InitialState, Plant, PlantConfig, SensorConfig};
use sitl::sim_params::SimParamService;

/// The plant step and control period (µs).
pub const DT_US: u64 = 2_000;
/// The ground station the rig speaks as.
pub const GCS: MavHeader = MavHeader { system_id: 255, component_id: 190, sequence: 0 };

/// Plant and vehicle in lockstep.
pub struct Rig {
    pub plant: Plant,
    pub vehicle: Vehicle,
    /// The vehicle time: the time of the last sample the vehicle stepped on (the plant's, but for the
    /// link's delay).
    pub now_us: u64,
    /// Last HEARTBEAT base_mode and EXTENDED_SYS_STATE landed_state seen.
    pub base_mode: MavModeFlag,
    pub landed_state: Option<MavLandedState>,
    /// Every message the vehicle sent, with its time (µs), since the last `take_messages`.
    pub messages: Vec<(u64, MavMessage)>,
    /// The radio as the board reads it: this frame goes to the vehicle with every tick (None: no radio).
    pub rc: Option<autopilot::core::manual::RcFrame>,
    /// The plant's SIM_ parameters (faults, rotor multipliers, payload), as the plant's SIM_ port and the
    /// plant link serve them: `sim_set` and a forwarded MAV_CMD_INJECT_FAILURE go through it.
    pub sim: SimParamService,
    /// The plant's answer to a forwarded injection, for the vehicle's next tick (as the plant link sends
    /// its COMMAND_ACK first in the next sensor datagram).
    plant_ack: Option<PlantCommandAck>,
    /// The link's delay line: samples on their way, with their plant time.
    link_line: VecDeque<(u64, VehicleInputs)>,
    /// The plant time of every sample the link lost (`SIM_LINK_LOSS`, or overtaken when the delay fell):
    /// what the plant's `LinkStats::lost` counts, with the times.
    pub link_lost_us: Vec<u64>,
    /// The last command: the plant steps on it when no sample was delivered (as ESCs hold theirs).
    last_pwm_us: [f64; 4],
}

impl Rig {
    /// The nominal plant with modest sensor noise, seed 7, and a default vehicle with `source`.
    #[must_use]
    pub fn new(source: EstimatorSource) -> Self {
        Self::with(PlantConfig { sensors: SensorConfig::modest_noise(), ..PlantConfig::default() }, source, |_| {})
    }

    /// `config` for the plant, a vehicle with `source` adjusted by `adjust`.
    #[must_use]
    pub fn with(config: PlantConfig, source: EstimatorSource, adjust: impl FnOnce(&mut VehicleConfig)) -> Self {
        let home = config.sensors.home;
        let plant = Plant::new(config, &InitialState::default(), 7).expect("plant");
        let mut vc = VehicleConfig::default();
        vc.estimator.source = source;
        vc.estimator.truth_origin =
            Some(GeoOrigin { lat_deg: home.lat_deg, lon_deg: home.lon_deg, alt_amsl_m: home.alt_amsl_m });
        adjust(&mut vc);
        let vehicle = Vehicle::new(vc).expect("vehicle");
        let sim = SimParamService::new(1, &plant);
        Self {
            plant,
            vehicle,
            now_us: 0,
            base_mode: MavModeFlag::empty(),
            landed_state: None,
            messages: Vec::new(),
            rc: None,
            sim,
            plant_ack: None,
            link_line: VecDeque::new(),
            link_lost_us: Vec::new(),
            last_pwm_us: [autopilot::core::vehicle::MOTOR_PWM_MIN_US; 4],
        }
    }

    /// The fused estimator converged, armed, taken off to 2.5 m and holding in Hold for 5 s, its messages
    /// taken: the start of the fault flights.
    ///
    /// # Panics
    /// When a command is refused or a stage times out.
    #[must_use]
    pub fn hovering() -> Self {
        let mut rig = Self::new(EstimatorSource::Fused);
        rig.wait_until(30.0, "estimator convergence", |r| r.vehicle.estimate().flags.converged);
        let nan = f32::NAN;
        let accepted = MavResult::MAV_RESULT_ACCEPTED;
        assert_eq!(rig.command(MavCmd::MAV_CMD_NAV_TAKEOFF, [0.0, 0.0, 0.0, nan, nan, nan, 2.5]), accepted);
        assert_eq!(rig.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]), accepted);
        rig.wait_until(20.0, "takeoff complete", |r| r.vehicle.commander_output().mode == FlightMode::Hold);
        rig.run_s(5.0, |_| {});
        rig.take_messages();
        rig
    }

    /// One lockstep tick: sensors -> the link (delay, loss) -> vehicle -> plant; without a sample
    /// delivered, the plant steps on the last command.
    ///
    /// # Panics
    /// If the vehicle commands a PWM outside 1000-2000 µs or not finite.
    pub fn tick(&mut self) {
        let s = self.plant.sample_sensors();
        let t = self.plant.truth();
        let inputs = VehicleInputs {
            imu: Some(ImuSample {
                time_us: s.time_us,
                accel_frd_mps2: s.accel_frd_mps2,
                gyro_frd_radps: s.gyro_frd_radps,
            }),
            mag: s.mag_frd_gauss.map(|field_frd_gauss| MagSample { field_frd_gauss }),
            baro: s.baro.map(|b| BaroSample { pressure_alt_m: b.pressure_alt_m }),
            gps: s.gps,
            truth: Some(TruthSample {
                time_us: t.time_us,
                pos_ned_m: t.pos_ned_m,
                vel_ned_mps: t.vel_ned_mps,
                q_ned_frd: t.q_ned_frd,
                rate_frd_radps: t.rate_frd_radps,
                specific_force_frd_mps2: t.specific_force_frd_mps2,
            }),
            battery: self
                .plant
                .battery()
                .filter(|_| sitl::link::battery_due(s.time_us, DT_US))
                .map(|b| sitl::link::battery_fields(&b.reading())),
            rc: self.rc,
            plant_ack: None,
            plant_link: None,
        };
        let Some((sample_us, mut inputs)) = self.deliver(s.time_us, inputs) else {
            self.plant.step(self.last_pwm_us, DT_US);
            return;
        };
        inputs.plant_ack = self.plant_ack.take();
        self.now_us = sample_us;
        let out = self.vehicle.step(self.now_us, &inputs);
        assert!(out.pwm_us.iter().all(|p| p.is_finite() && (1000.0..=2000.0).contains(p)), "pwm {:?}", out.pwm_us);
        for m in out.messages {
            match &m {
                MavMessage::HEARTBEAT(h) => self.base_mode = h.base_mode,
                MavMessage::EXTENDED_SYS_STATE(e) => self.landed_state = Some(e.landed_state),
                _ => {}
            }
            self.messages.push((self.now_us, m));
        }
        for m in &out.plant_messages {
            if let MavMessage::COMMAND_LONG(c) = m
                && c.command == MavCmd::MAV_CMD_INJECT_FAILURE
            {
                let injection = self.sim.inject_forwarded([c.param1, c.param2, c.param3], &mut self.plant);
                self.plant_ack = Some(PlantCommandAck {
                    command_id: MavCmd::MAV_CMD_INJECT_FAILURE as u32,
                    result: injection.result,
                });
            }
        }
        self.plant.set_motors_running(out.armed || out.motor_test);
        self.last_pwm_us = out.pwm_us;
        self.plant.step(out.pwm_us, DT_US);
    }

    /// What the link delivers at plant time `t` of the sample `inputs` taken then, as `sitl::link`'s
    /// `deliver`: without delay and loss, that sample; else the newest sample at least the delay old (one
    /// it overtakes is lost), or `None`. One loss draw per tick while the loss is above 0.
    fn deliver(&mut self, t: u64, inputs: VehicleInputs) -> Option<(u64, VehicleInputs)> {
        let faults = self.plant.link_faults_mut();
        if faults.is_clear() && self.link_line.is_empty() {
            return Some((t, inputs));
        }
        if faults.draw_lost() {
            self.link_lost_us.push(t);
        } else {
            self.link_line.push_back((t, inputs));
        }
        let delay_us = faults.delay_us();
        let mut delivered = None;
        while self.link_line.front().is_some_and(|(s, _)| s + delay_us <= t) {
            if let Some((overtaken_us, _)) = delivered.replace(self.link_line.pop_front()).flatten() {
                self.link_lost_us.push(overtaken_us);
            }
        }
        delivered.flatten()
    }

    /// Sets the plant's SIM_ parameter `name` (a fault, a rotor multiplier, the payload) from the next
    /// plant step, as a ground station's PARAM_SET on the plant's SIM_ port would.
    ///
    /// # Panics
    /// When the plant refuses the set.
    pub fn sim_set(&mut self, name: &str, value: f32) {
        if let Err(e) = self.sim.set(name, value, &mut self.plant) {
            panic!("{name} = {value}: {e}");
        }
    }

    /// Ticks for `seconds` of vehicle time, calling `each` after every tick.
    pub fn run_s(&mut self, seconds: f64, mut each: impl FnMut(&Self)) {
        let end = self.now_us + (seconds * 1e6) as u64;
        while self.now_us < end {
            self.tick();
            each(self);
        }
    }

    /// Ticks until `cond` holds, at most `timeout_s` of vehicle time; returns the vehicle time it took (s).
    ///
    /// # Panics
    /// When `cond` does not hold within `timeout_s`.
    pub fn wait_until(&mut self, timeout_s: f64, what: &str, cond: impl Fn(&Self) -> bool) -> f64 {
        let start = self.now_us;
        while !cond(self) {
            assert!(self.now_us - start < (timeout_s * 1e6) as u64, "timed out waiting for {what}");
            self.tick();
        }
        (self.now_us - start) as f64 * 1e-6
    }

    /// MAV_CMD_INJECT_FAILURE as a ground station sends it (`failure_type` of `unit` `instance`, 0 = all):
    /// the vehicle forwards it to the plant, which answers on the
    /// next tick; ticks until the vehicle's ACK and returns its result (the messages stay in `messages`).
    ///
    /// # Panics
    /// When no ACK comes within 1 s.
    pub fn inject(&mut self, unit: FailureUnit, failure_type: FailureType, instance: u8) -> MavResult {
        let [unit, failure_type, instance] = FailureRequest::new(unit, failure_type, u32::from(instance)).params();
        let params = [unit, failure_type, instance, 0.0, 0.0, 0.0, 0.0];
        let msg = command_long(1, 1, MavCmd::MAV_CMD_INJECT_FAILURE, params);
        let replies = self.vehicle.handle_message(self.now_us, &GCS, &msg);
        let ack = |m: &MavMessage| match m {
            MavMessage::COMMAND_ACK(a) if a.command == MavCmd::MAV_CMD_INJECT_FAILURE => Some(a.result),
            _ => None,
        };
        if let Some(result) = replies.iter().find_map(ack) {
            return result;
        }
        let from = self.messages.len();
        let start = self.now_us;
        loop {
            assert!(self.now_us - start < 1_000_000, "no ACK for the injection within 1 s");
            self.tick();
            if let Some(result) = self.messages[from..].iter().find_map(|(_, m)| ack(m)) {
                return result;
            }
        }
    }

    /// A COMMAND_LONG to the vehicle; its ACK result.
    ///
    /// # Panics
    /// When the first reply is not the command's ACK.
    pub fn command(&mut self, command: MavCmd, params: [f32; 7]) -> MavResult {
        let msg = command_long(1, 1, command, params);
        let replies = self.vehicle.handle_message(self.now_us, &GCS, &msg);
        match replies.first() {
            Some(MavMessage::COMMAND_ACK(a)) if a.command == command => a.result,
            other => panic!("no ACK for {command:?}: {other:?}"),
        }
    }

    /// A message to the vehicle now; its replies.
    pub fn send(&mut self, msg: &MavMessage) -> Vec<MavMessage> {
        self.vehicle.handle_message(self.now_us, &GCS, msg)
    }

    /// PARAM_SET as a PX4 ground station sends it, in the parameter's own type (an INT32 in PX4's bytewise
    /// encoding, as MAVSDK's `set_param_int`), and the echo, decoded by its type, checked.
    ///
    /// # Panics
    /// When `name` is not a parameter, or the vehicle does not echo the value.
    pub fn set_param(&mut self, name: &str, value: f32) {
        let kind = PARAMS.iter().find(|d| d.name == name).expect("a parameter").kind;
        let replies = self.send(&MavMessage::PARAM_SET(PARAM_SET_DATA {
            param_value: encode_value(kind, value),
            target_system: 1,
            target_component: 1,
            param_id: name.into(),
            param_type: kind.mav_param_type(),
        }));
        assert!(
            replies.iter().any(|m| matches!(m, MavMessage::PARAM_VALUE(p)
                if p.param_type == kind.mav_param_type() && decode_value(p.param_type, p.param_value) == Some(value))),
            "{name} = {value}: {replies:?}"
        );
    }

    /// The messages sent since the last call.
    pub fn take_messages(&mut self) -> Vec<(u64, MavMessage)> {
        std::mem::take(&mut self.messages)
    }

    /// Whether the last HEARTBEAT showed the vehicle armed.
    #[must_use]
    pub fn armed(&self) -> bool {
        self.base_mode.contains(MavModeFlag::MAV_MODE_FLAG_SAFETY_ARMED)
    }
}

/// A mission item as a ground station builds it: `command` at `lat_deg`/`lon_deg` (NaN: unset) and
/// `alt_m` above home (MAV_FRAME_GLOBAL_RELATIVE_ALT_INT), params 1-4.
#[must_use]
// The *_INT frames are deprecated in the dialect, but MAVSDK and QGroundControl send them.
#[allow(deprecated)]
pub fn mission_item(
    seq: u16,
    command: MavCmd,
    params: [f32; 4],
    lat_deg: f64,
    lon_deg: f64,
    alt_m: f32,
) -> autopilot::core::mavlink::common::MISSION_ITEM_INT_DATA {
    let dege7 = |deg: f64| if deg.is_nan() { i32::MAX } else { (deg * 1e7).round() as i32 };
    autopilot::core::mavlink::common::MISSION_ITEM_INT_DATA {
        param1: params[0],
        param2: params[1],
        param3: params[2],
        param4: params[3],
        x: dege7(lat_deg),
        y: dege7(lon_deg),
        z: alt_m,
        seq,
        command,
        target_system: 1,
        target_component: 1,
        frame: autopilot::core::mavlink::common::MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT,
        current: 0,
        autocontinue: 1,
        ..Default::default()
    }
}

impl Rig {
    /// Uploads `items` with the mission protocol as a ground station does (COUNT, then each requested
    /// item, until the ACK); returns the ACK result.
    ///
    /// # Panics
    /// When the vehicle asks for something else than the next item, or does not answer.
    pub fn upload(
        &mut self,
        items: &[autopilot::core::mavlink::common::MISSION_ITEM_INT_DATA],
    ) -> autopilot::core::mavlink::common::MavMissionResult {
        use autopilot::core::mavlink::common::{MISSION_COUNT_DATA, MavMessage};
        let count = u16::try_from(items.len()).expect("fits a u16");
        let mut replies = self.send(&MavMessage::MISSION_COUNT(MISSION_COUNT_DATA {
            count,
            target_system: 1,
            target_component: 1,
            ..Default::default()
        }));
        for _ in 0..=items.len() {
            match replies.first() {
                Some(MavMessage::MISSION_REQUEST_INT(r)) => {
                    replies = self.send(&MavMessage::MISSION_ITEM_INT(items[usize::from(r.seq)].clone()));
                }
                Some(MavMessage::MISSION_ACK(a)) => return a.mavtype,
                other => panic!("unexpected mission reply {other:?}"),
            }
        }
        panic!("no MISSION_ACK after {} items", items.len());
    }

    /// Uploads `items`, arms and switches to AUTO MISSION, as a ground station starts a mission.
    ///
    /// # Panics
    /// When the upload, the arming or the mode change is not accepted.
    pub fn start_mission(&mut self, items: &[autopilot::core::mavlink::common::MISSION_ITEM_INT_DATA]) {
        use autopilot::core::mavlink::common::MavMissionResult;
        assert_eq!(self.upload(items), MavMissionResult::MAV_MISSION_ACCEPTED);
        assert_eq!(
            self.command(MavCmd::MAV_CMD_COMPONENT_ARM_DISARM, [1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0]),
            MavResult::MAV_RESULT_ACCEPTED
        );
        assert_eq!(
            self.command(MavCmd::MAV_CMD_DO_SET_MODE, [1.0, 4.0, 4.0, 0.0, 0.0, 0.0, 0.0]),
            MavResult::MAV_RESULT_ACCEPTED
        );
    }
}
