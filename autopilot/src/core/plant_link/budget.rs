//! The plant link's byte budget: the bytes per second each direction of the plant protocol carries at a
//! plant rate, against what a serial line moves at its baud rate (8N1: 10 bits on the wire per byte), and
//! the highest standard plant rate that fits. Pure: both ends of the link (`autopilot --plant serial:`
//! and `sitl serve --serial`) print it at start and refuse a stream that does not fit.
//!
//! Frame sizes are not a table: each is the length of a real MAVLink 2 frame made by this crate's own
//! encoders from a typical sample ([`frame_bytes`]), so the budget follows the codecs (MAVLink 2 drops a
//! payload's trailing zero bytes: `HIL_SENSOR` is 74 bytes, not 77, because its extension `id` is 0 and
//! the high bytes of its `fields_updated` too).
//!
//! Two rules, one per timing of the link (docs/board.md):
//! - **Fits** (the board's rule, and the refusal): each direction on its own (a UART is full duplex) at
//!   most [`FIT_PERCENT`] of the line, the rest left for what the budget does not count (COMMAND_ACKs,
//!   the forwarded injections, a HEARTBEAT while the plant is silent).
//! - **Lockstep** (the SITL plant, which waits for each answer before it steps): a step's bytes both ways
//!   cross the line one after the other, so real time holds only while they take less than one plant
//!   period; [`LinkBudget::lockstep_real_time_factor`] is the most a lockstep run can reach.

use mavlink::MavHeader;
use mavlink::dialects::common::{MavBatteryChargeState, MavMessage};
use nalgebra::{UnitQuaternion, Vector3};

use super::codec::{
    ActuatorCommand, HilBaroFields, HilSensorFields, encode_actuator_controls, encode_battery_status, encode_frame_v2,
    encode_hil_gps, encode_hil_sensor, encode_hil_state_quaternion, encode_odometry, encode_rc_channels,
};
use crate::core::battery::BatterySample;
use crate::core::estimator::{GeoOrigin, GpsSample, TruthSample};
use crate::core::manual::RcFrame;

/// Bits on the wire per byte: a start bit, 8 data bits and a stop bit (8N1).
pub const BITS_PER_BYTE: u32 = 10;

/// A direction fits when it needs at most this share of the line (%).
pub const FIT_PERCENT: f64 = 90.0;

/// The plant rates a refusal may name (Hz), highest first: each a whole number of µs per sample, and
/// each with a position-loop rate at most 100 Hz that divides it ([`position_rate_hz`]).
pub const PLANT_RATES_HZ: [u32; 9] = [1000, 500, 400, 250, 200, 125, 100, 80, 50];

/// A plant rate given on a command line (`--rate`): one of [`PLANT_RATES_HZ`], or why not.
///
/// # Errors
/// A message naming the text and the rates taken.
pub fn parse_plant_rate(text: &str) -> Result<u32, String> {
    let rate_hz: u32 = text.parse().map_err(|_| format!("`{text}` is not a whole number of Hz"))?;
    if PLANT_RATES_HZ.contains(&rate_hz) {
        Ok(rate_hz)
    } else {
        Err(format!("{rate_hz} Hz is not one of {PLANT_RATES_HZ:?}"))
    }
}

/// The sample period of a plant rate (µs; whole for every one of [`PLANT_RATES_HZ`]).
#[must_use]
pub fn period_us(plant_rate_hz: u32) -> u64 {
    1_000_000 / u64::from(plant_rate_hz.max(1))
}

/// The bytes per second a serial line at `baud` carries each way (8N1: [`BITS_PER_BYTE`] a byte).
#[must_use]
pub const fn bytes_per_s_of_baud(baud: u32) -> u64 {
    baud as u64 / BITS_PER_BYTE as u64
}

/// The board's radio receiver frames (`RC_CHANNELS`, every 20 ms of plant time).
pub const RC_RATE_HZ: f64 = 50.0;
/// The board's battery monitor (`BATTERY_STATUS`, every 100 ms of plant time).
pub const BATTERY_RATE_HZ: f64 = 10.0;
/// GPS fixes (`HIL_GPS`), the plant's default.
pub const GPS_RATE_HZ: f64 = 10.0;

/// The position-loop rate that goes with a plant (inner-loop) rate: the largest divisor of it that is
/// at most 100 Hz (500 -> 100, 250 -> 50, 125 -> 25, 80 -> 80).
#[must_use]
pub fn position_rate_hz(plant_rate_hz: u32) -> u32 {
    (1..=plant_rate_hz.clamp(1, 100)).rev().find(|d| plant_rate_hz.is_multiple_of(*d)).unwrap_or(1)
}

/// What the plant sends and at what rates.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantStreams {
    /// Sensor samples per second: one `HIL_SENSOR` each, answered by one `HIL_ACTUATOR_CONTROLS`.
    pub sample_rate_hz: f64,
    /// `HIL_GPS` fixes per second.
    pub gps_rate_hz: f64,
    /// Whether the board forwards a radio receiver (`RC_CHANNELS` at [`RC_RATE_HZ`]).
    pub rc: bool,
    /// Whether the board has a battery monitor (`BATTERY_STATUS` at [`BATTERY_RATE_HZ`]).
    pub battery: bool,
    /// The simulator's ground truth, `HIL_STATE_QUATERNION` with every sample (never from a board).
    pub truth: bool,
    /// The truth again at float precision, `ODOMETRY` with every sample (truth-fed runs only).
    pub odometry: bool,
}

impl PlantStreams {
    /// A board's streams at `sample_rate_hz`: GPS at 10 Hz, a radio, a battery monitor, no truth.
    #[must_use]
    pub fn board(sample_rate_hz: f64) -> Self {
        Self { sample_rate_hz, gps_rate_hz: GPS_RATE_HZ, rc: true, battery: true, truth: false, odometry: false }
    }

    /// The same streams at another sample rate.
    #[must_use]
    pub fn at(self, sample_rate_hz: f64) -> Self {
        Self { sample_rate_hz, ..self }
    }
}

/// One message stream in one direction.
#[derive(Debug, Clone, PartialEq)]
pub struct StreamBytes {
    pub name: &'static str,
    /// One frame on the wire, header and CRC included (bytes).
    pub frame_bytes: u32,
    /// Frames per second.
    pub rate_hz: f64,
}

impl StreamBytes {
    #[must_use]
    pub fn bytes_per_s(&self) -> f64 {
        f64::from(self.frame_bytes) * self.rate_hz
    }
}

/// One direction of the link.
#[derive(Debug, Clone, PartialEq)]
pub struct DirectionBudget {
    pub streams: Vec<StreamBytes>,
    /// What the line carries (bytes/s): baud / [`BITS_PER_BYTE`].
    pub capacity_bytes_per_s: f64,
}

impl DirectionBudget {
    #[must_use]
    pub fn bytes_per_s(&self) -> f64 {
        self.streams.iter().map(StreamBytes::bytes_per_s).sum()
    }

    /// Share of the line (%).
    #[must_use]
    pub fn percent(&self) -> f64 {
        100.0 * self.bytes_per_s() / self.capacity_bytes_per_s
    }

    #[must_use]
    pub fn fits(&self) -> bool {
        self.percent() <= FIT_PERCENT
    }

    /// `HIL_SENSOR 76 B x 500 Hz + ... = 41,480 B/s (360 % of 11,520)`.
    fn describe(&self) -> String {
        let parts: Vec<String> = self
            .streams
            .iter()
            .map(|s| format!("{} {} B x {} Hz", s.name, s.frame_bytes, round_hz(s.rate_hz)))
            .collect();
        format!(
            "{} = {} B/s ({:.0} % of {})",
            parts.join(" + "),
            thousands(self.bytes_per_s()),
            self.percent(),
            thousands(self.capacity_bytes_per_s)
        )
    }
}

/// Both directions of a plant link at one baud rate.
#[derive(Debug, Clone, PartialEq)]
pub struct LinkBudget {
    pub baud: u32,
    pub streams: PlantStreams,
    /// Plant to autopilot.
    pub down: DirectionBudget,
    /// Autopilot to plant.
    pub up: DirectionBudget,
}

impl LinkBudget {
    /// The budget of `streams` on a line at `baud`.
    #[must_use]
    pub fn of(streams: &PlantStreams, baud: u32) -> Self {
        let capacity_bytes_per_s = bytes_per_s_of_baud(baud) as f64;
        let sizes = FrameSizes::get();
        let r = streams.sample_rate_hz;
        let mut down = vec![StreamBytes { name: "HIL_SENSOR", frame_bytes: sizes.hil_sensor, rate_hz: r }];
        if streams.gps_rate_hz > 0.0 {
            down.push(StreamBytes { name: "HIL_GPS", frame_bytes: sizes.hil_gps, rate_hz: streams.gps_rate_hz.min(r) });
        }
        if streams.rc {
            down.push(StreamBytes { name: "RC_CHANNELS", frame_bytes: sizes.rc_channels, rate_hz: RC_RATE_HZ.min(r) });
        }
        if streams.battery {
            down.push(StreamBytes {
                name: "BATTERY_STATUS",
                frame_bytes: sizes.battery_status,
                rate_hz: BATTERY_RATE_HZ.min(r),
            });
        }
        if streams.truth {
            down.push(StreamBytes {
                name: "HIL_STATE_QUATERNION",
                frame_bytes: sizes.hil_state_quaternion,
                rate_hz: r,
            });
        }
        if streams.odometry {
            down.push(StreamBytes { name: "ODOMETRY", frame_bytes: sizes.odometry, rate_hz: r });
        }
        let up =
            vec![StreamBytes { name: "HIL_ACTUATOR_CONTROLS", frame_bytes: sizes.hil_actuator_controls, rate_hz: r }];
        Self {
            baud,
            streams: *streams,
            down: DirectionBudget { streams: down, capacity_bytes_per_s },
            up: DirectionBudget { streams: up, capacity_bytes_per_s },
        }
    }

    /// Both directions fit (see the module documentation).
    #[must_use]
    pub fn fits(&self) -> bool {
        self.down.fits() && self.up.fits()
    }

    /// Wall time a lockstep step's bytes take on the line, both ways one after the other (s).
    #[must_use]
    pub fn lockstep_wire_s(&self) -> f64 {
        let r = self.streams.sample_rate_hz;
        (self.down.bytes_per_s() + self.up.bytes_per_s()) / r / self.down.capacity_bytes_per_s
    }

    /// The fastest a lockstep plant can run on this line, as a multiple of real time (the line alone;
    /// the two processes' own time comes on top).
    #[must_use]
    pub fn lockstep_real_time_factor(&self) -> f64 {
        1.0 / (self.lockstep_wire_s() * self.streams.sample_rate_hz)
    }

    /// The budget as printed at start, one line per direction and one for lockstep.
    #[must_use]
    pub fn lines(&self) -> Vec<String> {
        let verdict = |d: &DirectionBudget| if d.fits() { "fits" } else { "does NOT fit" };
        let r = self.streams.sample_rate_hz;
        vec![
            format!(
                "link budget at {} Hz on {} baud ({} B/s each way, {} bits a byte; fits at most {FIT_PERCENT:.0} %):",
                round_hz(r),
                self.baud,
                thousands(self.down.capacity_bytes_per_s),
                BITS_PER_BYTE
            ),
            format!("  plant -> autopilot: {}: {}", self.down.describe(), verdict(&self.down)),
            format!("  autopilot -> plant: {}: {}", self.up.describe(), verdict(&self.up)),
            format!(
                "  lockstep: {:.2} ms of each {:.2} ms step on the wire both ways, at most {:.2}x real time",
                self.lockstep_wire_s() * 1e3,
                1e3 / r,
                self.lockstep_real_time_factor()
            ),
        ]
    }

    /// `None` when it fits; otherwise the one line that says why not and names the plant rate that fits
    /// (`flag` is how the user sets it, e.g. `--rate`).
    #[must_use]
    pub fn refusal(&self, flag: &str) -> Option<String> {
        if self.fits() {
            return None;
        }
        let (which, d) =
            if self.down.fits() { ("autopilot -> plant", &self.up) } else { ("plant -> autopilot", &self.down) };
        let over = format!(
            "{} Hz does not fit {} baud: {which} needs {} B/s, {:.0} % of the line's {} (at most {FIT_PERCENT:.0} %)",
            round_hz(self.streams.sample_rate_hz),
            self.baud,
            thousands(d.bytes_per_s()),
            d.percent(),
            thousands(d.capacity_bytes_per_s)
        );
        Some(match fitting_rate_hz(&self.streams, self.baud) {
            Some(hz) => format!("{over}; {hz} Hz fits: {flag} {hz}"),
            None => format!("{over}; no plant rate down to {} Hz fits: a faster line is needed", PLANT_RATES_HZ[8]),
        })
    }
}

/// The highest of [`PLANT_RATES_HZ`] at which `streams` fit a line at `baud`.
#[must_use]
pub fn fitting_rate_hz(streams: &PlantStreams, baud: u32) -> Option<u32> {
    PLANT_RATES_HZ.into_iter().find(|&hz| LinkBudget::of(&streams.at(f64::from(hz)), baud).fits())
}

/// Wire bytes of one MAVLink 2 frame of `message` (unsigned).
#[must_use]
pub fn frame_bytes(message: &MavMessage) -> u32 {
    let header = MavHeader { system_id: 1, component_id: 1, sequence: 0 };
    u32::try_from(encode_frame_v2(header, message).len()).unwrap_or(u32::MAX)
}

/// The frame sizes of the plant protocol's messages, from typical samples.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameSizes {
    pub hil_sensor: u32,
    pub hil_gps: u32,
    pub rc_channels: u32,
    pub battery_status: u32,
    pub hil_state_quaternion: u32,
    pub odometry: u32,
    pub hil_actuator_controls: u32,
}

impl FrameSizes {
    /// Encodes a typical message of each kind (a vehicle hovering 10 m up, armed, 8 radio channels, a
    /// 6-cell pack) and measures its frame.
    #[must_use]
    pub fn get() -> Self {
        let time_us = 123_456_789;
        let sensor = HilSensorFields {
            time_us,
            accel_frd_mps2: Vector3::new(0.12, -0.08, -9.79),
            gyro_frd_radps: Vector3::new(0.011, -0.007, 0.003),
            mag_frd_gauss: Some(Vector3::new(0.21, 0.01, 0.43)),
            baro: Some(HilBaroFields { pressure_hpa: 1012.1, pressure_alt_m: 110.3, temperature_degc: 14.9 }),
        };
        let home = GeoOrigin { lat_deg: 54.9, lon_deg: 23.9, alt_amsl_m: 100.0 };
        let gps = GpsSample {
            time_us,
            lat_deg: 54.900_01,
            lon_deg: 23.900_02,
            alt_amsl_m: 110.2,
            vel_ned_mps: Vector3::new(0.05, -0.03, 0.01),
            fix_type: 3,
            satellites: 12,
            eph_m: 0.8,
            epv_m: 1.2,
        };
        let truth = TruthSample {
            time_us,
            pos_ned_m: Vector3::new(1.2, -0.4, -10.0),
            vel_ned_mps: Vector3::new(0.05, -0.03, 0.01),
            q_ned_frd: UnitQuaternion::from_euler_angles(0.01, -0.02, 0.3),
            rate_frd_radps: Vector3::new(0.011, -0.007, 0.003),
            specific_force_frd_mps2: Vector3::new(0.12, -0.08, -9.79),
        };
        let mut rc = RcFrame { count: 8, rssi: u8::MAX, ..RcFrame::default() };
        rc.channels_us[..8].copy_from_slice(&[1500, 1500, 1100, 1500, 1000, 1000, 1000, 1000]);
        let battery = BatterySample {
            voltage_v: 24.6,
            current_a: Some(28.0),
            remaining: Some(0.8),
            consumed_mah: Some(420.0),
            consumed_j: Some(37_000.0),
            cells: 6,
        };
        let actuators =
            ActuatorCommand { time_us, pwm_us: [1552.0, 1548.0, 1550.0, 1551.0], armed: true, motor_test: false };
        Self {
            hil_sensor: frame_bytes(&MavMessage::HIL_SENSOR(encode_hil_sensor(&sensor))),
            hil_gps: frame_bytes(&MavMessage::HIL_GPS(encode_hil_gps(&gps))),
            rc_channels: frame_bytes(&MavMessage::RC_CHANNELS(encode_rc_channels(&rc, 123_456))),
            battery_status: frame_bytes(&MavMessage::BATTERY_STATUS(encode_battery_status(
                &battery,
                MavBatteryChargeState::MAV_BATTERY_CHARGE_STATE_UNDEFINED,
            ))),
            hil_state_quaternion: frame_bytes(&MavMessage::HIL_STATE_QUATERNION(encode_hil_state_quaternion(
                &truth, &home, 0.06,
            ))),
            odometry: frame_bytes(&MavMessage::ODOMETRY(encode_odometry(&truth))),
            hil_actuator_controls: frame_bytes(&MavMessage::HIL_ACTUATOR_CONTROLS(encode_actuator_controls(
                &actuators,
            ))),
        }
    }
}

/// A rate as printed: whole when it is whole.
fn round_hz(rate_hz: f64) -> String {
    if (rate_hz - rate_hz.round()).abs() < 1e-9 {
        format!("{}", rate_hz.round() as i64)
    } else {
        format!("{rate_hz:.1}")
    }
}

/// `41480.0` -> `41,480`.
fn thousands(value: f64) -> String {
    let digits = format!("{}", value.round() as i64);
    let mut out = String::new();
    for (i, c) in digits.chars().enumerate() {
        if i > 0 && (digits.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frame_sizes_are_the_encoders_frames_with_trailing_zeros_dropped() {
        let s = FrameSizes::get();
        // 12 bytes of MAVLink 2 framing (10 header, 2 CRC) around each payload.
        assert_eq!(
            s.hil_sensor,
            12 + 62,
            "HIL_SENSOR: of its 65-byte payload, the zero extension id and the two high bytes of fields_updated \
             (13 flag bits) dropped"
        );
        assert_eq!(s.hil_actuator_controls, 12 + 81, "HIL_ACTUATOR_CONTROLS armed: mode is last and not zero");
        assert_eq!(s.rc_channels, 12 + 42, "RC_CHANNELS: rssi 255 is last");
        assert_eq!(s.hil_gps, 12 + 36, "HIL_GPS: the zero extensions id and yaw dropped");
    }

    #[test]
    fn position_rates_divide_the_plant_rate_and_stay_at_most_100_hz() {
        assert_eq!(position_rate_hz(500), 100);
        assert_eq!(position_rate_hz(250), 50);
        assert_eq!(position_rate_hz(125), 25);
        assert_eq!(position_rate_hz(80), 80);
        for hz in PLANT_RATES_HZ {
            let p = position_rate_hz(hz);
            assert!(p <= 100 && hz.is_multiple_of(p), "{hz} -> {p}");
            assert_eq!(period_us(hz) * u64::from(hz), 1_000_000, "{hz} Hz is a whole number of µs");
        }
    }

    #[test]
    fn a_board_at_500_hz_does_not_fit_115200_baud_and_the_refusal_names_80_hz() {
        let budget = LinkBudget::of(&PlantStreams::board(500.0), 115_200);
        assert!(!budget.fits());
        let line = budget.refusal("--rate").expect("a refusal");
        assert!(line.starts_with("500 Hz does not fit 115200 baud: plant -> autopilot needs"), "{line}");
        assert!(line.ends_with("; 80 Hz fits: --rate 80"), "{line}");
        assert!(!line.contains('\n'));
        assert!(LinkBudget::of(&PlantStreams::board(80.0), 115_200).fits());
        assert!(!LinkBudget::of(&PlantStreams::board(100.0), 115_200).fits());
    }

    #[test]
    fn a_board_at_250_hz_fits_921600_baud_and_one_at_500_hz_with_truth_does_not() {
        let board = LinkBudget::of(&PlantStreams::board(250.0), 921_600);
        assert!(board.fits() && board.refusal("--rate").is_none());
        assert!(board.lockstep_real_time_factor() > 1.5, "{:?}", board.lines());
        let sitl = LinkBudget::of(&PlantStreams { truth: true, ..PlantStreams::board(500.0) }, 921_600);
        assert!(sitl.down.fits() && sitl.up.fits(), "each way alone fits: {:?}", sitl.lines());
        assert!(sitl.lockstep_real_time_factor() < 1.0, "but lockstep cannot hold real time: {:?}", sitl.lines());
    }

    #[test]
    fn the_up_direction_alone_can_refuse() {
        // Without GPS, radio or battery the sensor frame (76 B) is smaller than the answer (93 B).
        let lean = PlantStreams { gps_rate_hz: 0.0, rc: false, battery: false, ..PlantStreams::board(125.0) };
        let budget = LinkBudget::of(&lean, 115_200);
        assert!(budget.down.fits() && !budget.up.fits());
        assert!(budget.refusal("--rate").expect("refused").contains("autopilot -> plant needs 11,625 B/s"));
    }

    #[test]
    fn nothing_fits_a_9600_line_and_the_refusal_says_so() {
        let line = LinkBudget::of(&PlantStreams::board(500.0), 9600).refusal("--rate").expect("refused");
        assert!(line.ends_with("no plant rate down to 50 Hz fits: a faster line is needed"), "{line}");
    }

    #[test]
    fn thousands_groups_digits() {
        assert_eq!(thousands(41_480.4), "41,480");
        assert_eq!(thousands(999.0), "999");
        assert_eq!(thousands(1_152_000.0), "1,152,000");
    }

    #[test]
    fn docs_board_md_holds_the_budgets_and_the_refusal_as_the_code_prints_them() {
        let page = include_str!(concat!(env!("CARGO_MANIFEST_DIR"), "/../docs/board.md"));
        for (rate_hz, baud) in [(250.0, 921_600), (500.0, 921_600), (500.0, 115_200), (80.0, 115_200)] {
            let printed = LinkBudget::of(&PlantStreams::board(rate_hz), baud).lines().join("\n");
            assert!(page.contains(&printed), "docs/board.md lacks, or has another, budget:\n{printed}");
        }
        let refusal = LinkBudget::of(&PlantStreams::board(500.0), 115_200).refusal("--rate").expect("refused");
        assert!(page.contains(&refusal), "docs/board.md lacks the refusal:\n{refusal}");
        let s = FrameSizes::get();
        for (name, bytes) in [
            ("HIL_SENSOR", s.hil_sensor),
            ("HIL_GPS", s.hil_gps),
            ("RC_CHANNELS", s.rc_channels),
            ("BATTERY_STATUS", s.battery_status),
            ("HIL_STATE_QUATERNION` (SITL truth only)", s.hil_state_quaternion),
            ("HIL_ACTUATOR_CONTROLS` (armed)", s.hil_actuator_controls),
        ] {
            let row =
                if name.contains('`') { format!("| `{name} | {bytes} |") } else { format!("| `{name}` | {bytes} |") };
            assert!(page.contains(&row), "docs/board.md's frame table lacks `{row}`");
        }
    }
}
