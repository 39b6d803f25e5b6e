//! The view stream: what a live viewer is sent of a flight, as one JSON object per line or datagram
//! ([`ViewFrame`]), and the autopilot's tap ([`ViewTap`]) that sends the vehicle's side of it (the
//! estimate, the setpoints, the motors, the battery, the mode, the controller's telemetry, the plan and
//! every STATUSTEXT) over UDP on vehicle time. `sitl` adds the plant's truth and hands the whole stream to
//! the viewer bridge (`python -m aco_gcs.view`, Rerun); docs/view.md describes each field.
//!
//! The tap never waits: it sends from a nonblocking socket, and a datagram the socket refuses (nobody
//! listening, a full buffer) is counted and lost.

use std::collections::BTreeMap;
use std::net::{Ipv4Addr, Ipv6Addr, SocketAddr, UdpSocket};

use mavlink::dialects::common::MavSeverity;
use nalgebra::{UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use crate::core::control::Controller;
use crate::core::estimator::GeoOrigin;
use crate::core::vehicle::{PlanView, Vehicle};

/// Vehicle time between two [`VehicleFrame`]s (µs): 50 Hz.
pub const VIEW_PERIOD_US: u64 = 20_000;
/// Vehicle time between two looks at the plan (µs); a [`PlanFrame`] goes out when it changed, and at
/// least every [`PLAN_REPEAT_US`].
pub const PLAN_CHECK_US: u64 = 100_000;
/// The longest vehicle time between two [`PlanFrame`]s (µs), so a viewer that joins late sees the plan.
pub const PLAN_REPEAT_US: u64 = 1_000_000;

/// One frame of the view stream. Every frame names its source (`src`: `v<N>` for instance N, or a
/// scenario run's controller) and its time (`t_us`, simulated µs). Positions are NED metres; quaternions
/// are Hamilton `[w, x, y, z]`, body FRD to NED.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum ViewFrame {
    Meta(MetaFrame),
    Truth(TruthFrame),
    Vehicle(VehicleFrame),
    Ahead(AheadFrame),
    Plan(PlanFrame),
    Event(EventFrame),
}

/// What the stream holds: a title, the sources in colour order, the sample rate.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct MetaFrame {
    pub src: String,
    pub t_us: u64,
    pub title: String,
    pub sources: Vec<String>,
    pub rate_hz: f64,
}

/// The plant's true state.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct TruthFrame {
    pub src: String,
    pub t_us: u64,
    pub pos_ned_m: [f64; 3],
    pub q_ned_frd: [f64; 4],
    pub vel_ned_mps: [f64; 3],
    pub euler_rad: [f64; 3],
    pub wind_ned_mps: [f64; 3],
}

/// What the vehicle saw and asked at one step: the estimate (or the state its controller was fed), the
/// position and attitude setpoints, the motors, the battery, the mode and the controller's telemetry.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct VehicleFrame {
    pub src: String,
    pub t_us: u64,
    pub armed: bool,
    pub mode: String,
    pub pos_ned_m: [f64; 3],
    pub vel_ned_mps: [f64; 3],
    pub q_ned_frd: [f64; 4],
    pub euler_rad: [f64; 3],
    pub sp_pos_ned_m: Option<[f64; 3]>,
    pub sp_euler_rad: Option<[f64; 3]>,
    pub pwm_us: [f64; 4],
    pub battery_v: Option<f64>,
    pub battery_pct: Option<f64>,
    pub telemetry: BTreeMap<String, f64>,
    /// The estimator's geodetic origin (lat deg, lon deg, alt m AMSL) of the local frame, once latched:
    /// how a receiver that knows the plant's map places this frame in its own.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub origin: Option<[f64; 3]>,
}

/// The reference's path over the next seconds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AheadFrame {
    pub src: String,
    pub t_us: u64,
    pub points_ned_m: Vec<[f64; 3]>,
}

/// The plan (see [`PlanView`]): home, the mission's points (and the index among them of the item flown
/// now), the geofence's polygons and circles (NE m; circles `[n, e, radius]`), its ceiling as a height
/// (m, up) and the rally points.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct PlanFrame {
    pub src: String,
    pub t_us: u64,
    pub home_ned_m: Option<[f64; 3]>,
    pub mission_ned_m: Vec<[f64; 3]>,
    pub mission_current: Option<usize>,
    pub fence_polygons_ne_m: Vec<Vec<[f64; 2]>>,
    pub fence_circles_ne_m: Vec<[f64; 3]>,
    pub fence_max_alt_m: Option<f64>,
    pub rally_ned_m: Vec<[f64; 3]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub origin: Option<[f64; 3]>,
}

/// A STATUSTEXT of the vehicle (mode changes, failsafes, refusals), at its MAV_SEVERITY (0-7).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct EventFrame {
    pub src: String,
    pub t_us: u64,
    pub severity: u8,
    pub text: String,
}

/// A vector as the stream writes it.
#[must_use]
pub fn arr3(v: &Vector3<f64>) -> [f64; 3] {
    [v.x, v.y, v.z]
}

/// A quaternion as the stream writes it: `[w, x, y, z]`.
#[must_use]
pub fn quat(q: &UnitQuaternion<f64>) -> [f64; 4] {
    [q.w, q.i, q.j, q.k]
}

/// A controller's telemetry as the stream writes it: its named values, the finite ones.
#[must_use]
pub fn telemetry_of(controller: &dyn Controller) -> BTreeMap<String, f64> {
    controller.telemetry().into_iter().filter(|(_, v)| v.is_finite()).map(|(k, v)| (k.into(), v)).collect()
}

/// The stream's first frame: its title and its sources in colour order, at [`VIEW_PERIOD_US`].
#[must_use]
pub fn meta_frame(title: String, sources: Vec<String>) -> ViewFrame {
    ViewFrame::Meta(MetaFrame {
        src: sources.first().cloned().unwrap_or_default(),
        t_us: 0,
        title,
        sources,
        rate_hz: 1e6 / VIEW_PERIOD_US as f64,
    })
}

/// A view sample every [`VIEW_PERIOD_US`]: the autopilot's vehicle frames on vehicle time, `sitl`'s truth
/// frames on plant time. Call [`ViewSampler::due`] after each step; the first step is due.
#[derive(Debug, Clone, Default)]
pub struct ViewSampler {
    next_us: u64,
}

impl ViewSampler {
    /// Whether time `t_us` is due a sample (and then the next one is due at the next multiple of the
    /// period, so a step that does not divide it still gives one sample per period).
    pub fn due(&mut self, t_us: u64) -> bool {
        if t_us < self.next_us {
            return false;
        }
        self.next_us = t_us - t_us % VIEW_PERIOD_US + VIEW_PERIOD_US;
        true
    }
}

fn shifted(p: &mut [f64; 3], d: &Vector3<f64>) {
    for (x, dx) in p.iter_mut().zip(d.iter()) {
        *x += dx;
    }
}

impl ViewFrame {
    /// The frame's source.
    #[must_use]
    pub fn src(&self) -> &str {
        match self {
            Self::Meta(f) => &f.src,
            Self::Truth(f) => &f.src,
            Self::Vehicle(f) => &f.src,
            Self::Ahead(f) => &f.src,
            Self::Plan(f) => &f.src,
            Self::Event(f) => &f.src,
        }
    }

    /// Moves every position of the frame by `offset_ned_m` (from a vehicle's local frame into the
    /// plant's, whose origin differs by where the estimator latched its own).
    pub fn shift_ned(&mut self, offset_ned_m: &Vector3<f64>) {
        let d = offset_ned_m;
        match self {
            Self::Meta(_) | Self::Event(_) => {}
            Self::Truth(f) => shifted(&mut f.pos_ned_m, d),
            Self::Vehicle(f) => {
                shifted(&mut f.pos_ned_m, d);
                if let Some(p) = f.sp_pos_ned_m.as_mut() {
                    shifted(p, d);
                }
            }
            Self::Ahead(f) => f.points_ned_m.iter_mut().for_each(|p| shifted(p, d)),
            Self::Plan(f) => {
                for p in f.home_ned_m.iter_mut().chain(f.mission_ned_m.iter_mut()).chain(f.rally_ned_m.iter_mut()) {
                    shifted(p, d);
                }
                for polygon in &mut f.fence_polygons_ne_m {
                    for v in polygon {
                        v[0] += d.x;
                        v[1] += d.y;
                    }
                }
                for c in &mut f.fence_circles_ne_m {
                    c[0] += d.x;
                    c[1] += d.y;
                }
                if let Some(h) = f.fence_max_alt_m.as_mut() {
                    *h -= d.z;
                }
            }
        }
    }

    /// The frame as one JSON line (without its newline).
    #[must_use]
    pub fn to_json(&self) -> String {
        // Plain data of numbers and strings: serialising it cannot fail.
        serde_json::to_string(self).unwrap_or_default()
    }
}

fn origin_of(origin: Option<GeoOrigin>) -> Option<[f64; 3]> {
    origin.map(|o| [o.lat_deg, o.lon_deg, o.alt_amsl_m])
}

/// The vehicle's side of one view sample at vehicle time `t_us`, from source `src`.
#[must_use]
pub fn vehicle_frame(src: &str, t_us: u64, vehicle: &Vehicle) -> VehicleFrame {
    let snap = vehicle.log_snapshot();
    let e = &snap.estimate;
    let telemetry = telemetry_of(vehicle.controller());
    let battery = snap.battery.sample;
    VehicleFrame {
        src: src.into(),
        t_us,
        armed: snap.armed,
        mode: snap.mode.to_string(),
        pos_ned_m: arr3(&e.pos_ned_m),
        vel_ned_mps: arr3(&e.vel_ned_mps),
        q_ned_frd: quat(&e.q_ned_frd),
        euler_rad: arr3(&e.euler_rad),
        sp_pos_ned_m: snap.reference.map(|r| arr3(&r.pos_ned_m)),
        sp_euler_rad: snap.reference.map(|r| {
            arr3(&r.attitude_rad.unwrap_or_else(|| {
                let sp = snap.attitude_setpoint_rad;
                if sp.iter().all(|v| v.is_finite()) { sp } else { Vector3::new(0.0, 0.0, r.yaw_rad) }
            }))
        }),
        pwm_us: snap.pwm_us,
        battery_v: battery.map(|b| b.voltage_v),
        battery_pct: snap.battery.remaining().map(|r| r * 100.0),
        telemetry,
        origin: origin_of(e.origin),
    }
}

/// The plan's frame at vehicle time `t_us` (see [`PlanView`]).
#[must_use]
pub fn plan_frame(src: &str, t_us: u64, plan: &PlanView, origin: Option<GeoOrigin>) -> PlanFrame {
    PlanFrame {
        src: src.into(),
        t_us,
        home_ned_m: plan.home_ned_m.as_ref().map(arr3),
        mission_ned_m: plan.mission_ned_m.iter().map(|(_, p)| arr3(p)).collect(),
        mission_current: plan.mission_current.and_then(|seq| plan.mission_ned_m.iter().position(|(s, _)| *s >= seq)),
        fence_polygons_ne_m: plan
            .fence_polygons_ne_m
            .iter()
            .map(|(_, vertices)| vertices.iter().map(|v| [v.x, v.y]).collect())
            .collect(),
        // GF_MAX_HOR_DIST is drawn as the circle about home it is.
        fence_circles_ne_m: plan
            .fence_circles_ne_m
            .iter()
            .map(|(_, c, r)| [c.x, c.y, *r])
            .chain(plan.fence_max_hor_m.zip(plan.home_ned_m).map(|(r, h)| [h.x, h.y, r]))
            .collect(),
        fence_max_alt_m: plan.fence_max_d_m.map(|d| -d),
        rally_ned_m: plan.rally_ned_m.iter().map(arr3).collect(),
        origin: origin_of(origin),
    }
}

/// A nonblocking UDP socket on an ephemeral port, for sending to a viewer at `to` (the view stream's
/// receiver, PX4's Hawkeye): bound to the loopback when `to` is on it, else to any address of its family.
///
/// # Errors
/// The bind's or the socket option's error.
pub fn viewer_socket(to: SocketAddr) -> std::io::Result<UdpSocket> {
    let local: SocketAddr = match to {
        SocketAddr::V4(a) if a.ip().is_loopback() => (Ipv4Addr::LOCALHOST, 0).into(),
        SocketAddr::V4(_) => (Ipv4Addr::UNSPECIFIED, 0).into(),
        SocketAddr::V6(a) if a.ip().is_loopback() => (Ipv6Addr::LOCALHOST, 0).into(),
        SocketAddr::V6(_) => (Ipv6Addr::UNSPECIFIED, 0).into(),
    };
    let socket = UdpSocket::bind(local)?;
    socket.set_nonblocking(true)?;
    Ok(socket)
}

/// How many frames the tap sent and lost.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ViewTapStats {
    pub sent: u64,
    pub lost: u64,
}

/// The autopilot's side of the view stream: after each vehicle step, a [`VehicleFrame`] every
/// [`VIEW_PERIOD_US`] of vehicle time and a [`PlanFrame`] when the plan changed; an [`EventFrame`] for
/// every STATUSTEXT. Off unless the autopilot was given `--view-udp`.
#[derive(Debug, Default)]
pub struct ViewTap {
    out: Option<(UdpSocket, SocketAddr)>,
    src: String,
    vehicle_sampler: ViewSampler,
    next_plan_check_us: u64,
    last_plan: Option<(u64, PlanFrame)>,
    stats: ViewTapStats,
}

impl ViewTap {
    /// A tap that sends nothing.
    #[must_use]
    pub fn off() -> Self {
        Self::default()
    }

    /// A tap sending instance `instance`'s frames (source `v<instance>`) to `to`.
    ///
    /// # Errors
    /// The socket cannot be opened.
    pub fn to(to: SocketAddr, instance: u16) -> std::io::Result<Self> {
        Ok(Self { out: Some((viewer_socket(to)?, to)), src: format!("v{instance}"), ..Self::default() })
    }

    /// Frames sent and lost so far.
    #[must_use]
    pub fn stats(&self) -> ViewTapStats {
        self.stats
    }

    fn send(&mut self, frame: &ViewFrame) {
        if let Some((socket, to)) = &self.out {
            match socket.send_to(frame.to_json().as_bytes(), to) {
                Ok(_) => self.stats.sent += 1,
                Err(_) => self.stats.lost += 1,
            }
        }
    }

    /// After the vehicle's step at `now_us`: its frame when one is due, and the plan's when it changed.
    pub fn end_step(&mut self, now_us: u64, vehicle: &Vehicle) {
        if self.out.is_none() {
            return;
        }
        if self.vehicle_sampler.due(now_us) {
            let frame = ViewFrame::Vehicle(vehicle_frame(&self.src, now_us, vehicle));
            self.send(&frame);
        }
        if now_us >= self.next_plan_check_us {
            self.next_plan_check_us = now_us + PLAN_CHECK_US;
            let origin = vehicle.log_snapshot().estimate.origin;
            let plan = plan_frame(&self.src, now_us, &vehicle.plan_view(), origin);
            let due = match &self.last_plan {
                None => true,
                Some((at_us, last)) => {
                    now_us.saturating_sub(*at_us) >= PLAN_REPEAT_US
                        || PlanFrame { t_us: plan.t_us, ..last.clone() } != plan
                }
            };
            if due {
                let frame = ViewFrame::Plan(plan.clone());
                self.send(&frame);
                self.last_plan = Some((now_us, plan));
            }
        }
    }

    /// A STATUSTEXT the vehicle sent at `now_us`.
    pub fn text(&mut self, now_us: u64, severity: MavSeverity, text: &str) {
        if self.out.is_none() {
            return;
        }
        let frame = ViewFrame::Event(EventFrame {
            src: self.src.clone(),
            t_us: now_us,
            severity: severity as u8,
            text: text.into(),
        });
        self.send(&frame);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn vehicle_json() -> &'static str {
        r#"{"kind":"vehicle","src":"v0","t_us":20000,"armed":true,"mode":"Position","pos_ned_m":[1.0,2.0,-3.0],
            "vel_ned_mps":[0.0,0.0,0.0],"q_ned_frd":[1.0,0.0,0.0,0.0],"euler_rad":[0.0,0.0,0.0],
            "sp_pos_ned_m":[1.0,2.0,-4.0],"sp_euler_rad":null,"pwm_us":[1500.0,1500.0,1500.0,1500.0],
            "battery_v":null,"battery_pct":50.0,"telemetry":{"aco.w_t_n":0.5}}"#
    }

    #[test]
    fn given_a_vehicle_line_then_it_parses_and_writes_back_the_same_frame() {
        let frame: ViewFrame = serde_json::from_str(vehicle_json()).unwrap();
        let ViewFrame::Vehicle(v) = &frame else { panic!("not a vehicle frame: {frame:?}") };
        assert_eq!((v.src.as_str(), v.t_us, v.armed, v.origin), ("v0", 20_000, true, None));
        assert_eq!(v.telemetry.get("aco.w_t_n"), Some(&0.5));
        let again: ViewFrame = serde_json::from_str(&frame.to_json()).unwrap();
        assert_eq!(again, frame);
        assert!(frame.to_json().starts_with(r#"{"kind":"vehicle","src":"v0""#), "{}", frame.to_json());
    }

    #[test]
    fn given_an_offset_then_every_position_moves_and_the_ceiling_with_the_down_axis() {
        let mut frame: ViewFrame = serde_json::from_str(vehicle_json()).unwrap();
        frame.shift_ned(&Vector3::new(10.0, -1.0, 0.5));
        let ViewFrame::Vehicle(v) = &frame else { unreachable!() };
        assert_eq!((v.pos_ned_m, v.sp_pos_ned_m), ([11.0, 1.0, -2.5], Some([11.0, 1.0, -3.5])));
        let mut plan = ViewFrame::Plan(PlanFrame {
            src: "v0".into(),
            t_us: 0,
            home_ned_m: Some([0.0; 3]),
            mission_ned_m: vec![[5.0, 5.0, -2.0]],
            mission_current: Some(0),
            fence_polygons_ne_m: vec![vec![[0.0, 0.0], [1.0, 0.0], [1.0, 1.0]]],
            fence_circles_ne_m: vec![[3.0, 4.0, 10.0]],
            fence_max_alt_m: Some(20.0),
            rally_ned_m: vec![[-1.0, -1.0, 0.0]],
            origin: None,
        });
        plan.shift_ned(&Vector3::new(10.0, -1.0, 0.5));
        let ViewFrame::Plan(p) = &plan else { unreachable!() };
        assert_eq!(p.home_ned_m, Some([10.0, -1.0, 0.5]));
        assert_eq!(p.mission_ned_m, vec![[15.0, 4.0, -1.5]]);
        assert_eq!(p.fence_polygons_ne_m[0][1], [11.0, -1.0]);
        assert_eq!(p.fence_circles_ne_m[0], [13.0, 3.0, 10.0]);
        assert_eq!(p.fence_max_alt_m, Some(19.5));
        assert_eq!(p.rally_ned_m, vec![[9.0, -2.0, 0.5]]);
    }

    #[test]
    fn given_an_unknown_kind_or_a_missing_field_then_the_line_is_refused() {
        assert!(serde_json::from_str::<ViewFrame>(r#"{"kind":"teapot","src":"v0","t_us":0}"#).is_err());
        assert!(serde_json::from_str::<ViewFrame>(r#"{"kind":"truth","src":"v0","t_us":0}"#).is_err());
    }

    #[test]
    fn given_2_ms_steps_then_the_sampler_is_due_at_50_hz_and_once_per_period_at_any_step() {
        let mut sampler = ViewSampler::default();
        let due: Vec<u64> = (0..=500u64).map(|k| k * 2_000).filter(|&t| sampler.due(t)).collect();
        assert_eq!(due.len(), 51, "0..=1 s at 50 Hz");
        assert!(due.windows(2).all(|w| w[1] - w[0] == VIEW_PERIOD_US), "{due:?}");
        // A step that does not divide the period still gives one sample per period.
        let mut sampler = ViewSampler::default();
        let due: Vec<u64> = (0..=125u64).map(|k| k * 8_000).filter(|&t| sampler.due(t)).collect();
        assert_eq!(due.len(), 51, "{due:?}");
    }

    #[test]
    fn given_a_tap_to_a_socket_then_vehicle_frames_come_at_50_hz_of_vehicle_time_and_texts_at_once() {
        let rx = UdpSocket::bind("127.0.0.1:0").unwrap();
        rx.set_read_timeout(Some(std::time::Duration::from_secs(5))).unwrap();
        let mut tap = ViewTap::to(rx.local_addr().unwrap(), 3).unwrap();
        let vehicle = Vehicle::new(crate::core::config::VehicleConfig::default()).unwrap();
        for k in 0..=100u64 {
            tap.end_step(k * 2_000, &vehicle);
        }
        tap.text(200_000, MavSeverity::MAV_SEVERITY_WARNING, "Failsafe: GPS lost");
        let mut buf = [0u8; 65_536];
        let mut kinds = Vec::new();
        while kinds.len() < usize::try_from(tap.stats().sent).unwrap() {
            let n = rx.recv(&mut buf).unwrap();
            let frame: ViewFrame = serde_json::from_slice(&buf[..n]).unwrap();
            assert_eq!(frame.src(), "v3");
            kinds.push(match frame {
                ViewFrame::Vehicle(v) => format!("vehicle@{}", v.t_us),
                ViewFrame::Plan(p) => format!("plan@{}", p.t_us),
                ViewFrame::Event(e) => format!("event:{}:{}", e.severity, e.text),
                other => panic!("unexpected {other:?}"),
            });
        }
        let vehicles: Vec<&String> = kinds.iter().filter(|k| k.starts_with("vehicle@")).collect();
        // 0..=200 ms of vehicle time at 50 Hz: 0, 20, ..., 200 ms.
        assert_eq!(vehicles.len(), 11, "{kinds:?}");
        assert_eq!(vehicles[1], "vehicle@20000");
        assert_eq!(kinds.iter().filter(|k| k.starts_with("plan@")).count(), 1, "{kinds:?}");
        assert_eq!(kinds.last().map(String::as_str), Some("event:4:Failsafe: GPS lost"));
        assert_eq!(tap.stats().lost, 0);
    }
}
