//! The ports of SITL instance N on one machine, after PX4's multi-vehicle convention: every instance sends
//! its telemetry to UDP 14550, where QGroundControl listens and tells the vehicles apart by system id
//! (N + 1), and each has its own API / offboard port (MAVSDK, scripts) at 14540 + N. The ports an instance
//! binds are its own: plant 4560 + N, autopilot 18570 + N, TCP 5760 + N, the plant's SIM_ parameters
//! 19550 + N. With `--hawkeye` the plant also sends its truth to PX4's Hawkeye viewer on 19410 + N (a port
//! the viewer binds, as QGroundControl binds 14550; the plant only sends to it).
//!
//! One departure from PX4: PX4's API port 14540 + N is 14550 itself at N = 10, so instance 10's API
//! traffic would land on QGroundControl's port. Here the API ports skip 14550: 14540 + N for N < 10, and
//! 14541 + N from N = 10 on (14551 .. 14795). With instances 0 ..= [`MAX_INSTANCE`] (254: the system id
//! N + 1 is a byte) the six ranges never meet, and none reaches 65535 (a test checks every pair).
//!
//! The Hawkeye port is PX4's as it is: 19410 + N meets the SIM_ parameter ports from N = 140 on (19410 +
//! 140 = 19550, instance 0's), so it is clear of every other port only up to [`HAWKEYE_MAX_INSTANCE`]
//! (Hawkeye itself draws at most 16 vehicles); `sitl` refuses `--hawkeye` above it.

/// The largest instance: its system id N + 1 = 255 is the largest a MAVLink system id can be.
pub const MAX_INSTANCE: u16 = 254;

/// Where QGroundControl listens; every instance sends its telemetry here.
pub const QGC_PORT: u16 = 14550;
/// The API / offboard port of instance 0 (MAVSDK's `udpin://0.0.0.0:14540`).
pub const API_PORT_BASE: u16 = 14540;
/// The plant protocol port of instance 0 (the plant listens, the autopilot connects).
pub const PLANT_PORT_BASE: u16 = 4560;
/// The autopilot's own UDP port of instance 0 (PX4 SITL's local GCS port).
pub const AUTOPILOT_PORT_BASE: u16 = 18570;
/// The autopilot's TCP server of instance 0.
pub const TCP_PORT_BASE: u16 = 5760;
/// The plant's SIM_ parameter port of instance 0.
pub const SIM_PARAM_PORT_BASE: u16 = 19550;
/// Where PX4's Hawkeye viewer listens for instance 0's HIL_STATE_QUATERNION (the plant sends, with
/// `--hawkeye`).
pub const HAWKEYE_PORT_BASE: u16 = 19410;
/// The largest instance whose Hawkeye port (19410 + N) meets no port of any instance: from 140 on it is
/// another instance's SIM_ parameter port.
pub const HAWKEYE_MAX_INSTANCE: u16 = SIM_PARAM_PORT_BASE - HAWKEYE_PORT_BASE - 1;

/// Why an instance has no ports.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("instance {0} is out of range: instances are 0..={MAX_INSTANCE} (system id N+1 is at most 255)")]
pub struct InstanceOutOfRange(pub u16);

/// The ports of one instance.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct InstancePorts {
    pub instance: u16,
    /// The MAVLink system id, N + 1.
    pub system_id: u8,
    pub plant_udp: u16,
    pub autopilot_udp: u16,
    pub tcp: u16,
    pub sim_params_udp: u16,
    /// Where the telemetry goes for QGroundControl: 14550, shared by every instance.
    pub qgc_udp: u16,
    /// Where the telemetry goes for MAVSDK and scripts: this instance's own.
    pub api_udp: u16,
    /// Where the plant sends its truth for PX4's Hawkeye viewer (`--hawkeye`): 19410 + N, sent to, never
    /// bound; clear of every other port only up to [`HAWKEYE_MAX_INSTANCE`].
    pub hawkeye_udp: u16,
}

impl InstancePorts {
    /// Instance 0's ports.
    pub const FIRST: Self = Self {
        instance: 0,
        system_id: 1,
        plant_udp: PLANT_PORT_BASE,
        autopilot_udp: AUTOPILOT_PORT_BASE,
        tcp: TCP_PORT_BASE,
        sim_params_udp: SIM_PARAM_PORT_BASE,
        qgc_udp: QGC_PORT,
        api_udp: API_PORT_BASE,
        hawkeye_udp: HAWKEYE_PORT_BASE,
    };

    /// The ports of instance `instance`.
    ///
    /// # Errors
    /// [`InstanceOutOfRange`] above [`MAX_INSTANCE`].
    pub fn of(instance: u16) -> Result<Self, InstanceOutOfRange> {
        if instance > MAX_INSTANCE {
            return Err(InstanceOutOfRange(instance));
        }
        let api_offset = if instance < QGC_PORT - API_PORT_BASE { instance } else { instance + 1 };
        Ok(Self {
            instance,
            system_id: u8::try_from(instance + 1).map_err(|_| InstanceOutOfRange(instance))?,
            plant_udp: PLANT_PORT_BASE + instance,
            autopilot_udp: AUTOPILOT_PORT_BASE + instance,
            tcp: TCP_PORT_BASE + instance,
            sim_params_udp: SIM_PARAM_PORT_BASE + instance,
            qgc_udp: QGC_PORT,
            api_udp: API_PORT_BASE + api_offset,
            hawkeye_udp: HAWKEYE_PORT_BASE + instance,
        })
    }

    /// The ports this instance binds (the plant's and the autopilot's), named.
    #[must_use]
    pub fn bound(&self) -> [(&'static str, u16); 4] {
        [
            ("plant", self.plant_udp),
            ("autopilot", self.autopilot_udp),
            ("tcp", self.tcp),
            ("sim_params", self.sim_params_udp),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn instance_0_and_1_have_px4s_ports() {
        let p = InstancePorts::of(0).expect("in range");
        assert_eq!(p, InstancePorts::FIRST);
        assert_eq!((p.system_id, p.plant_udp, p.autopilot_udp, p.tcp), (1, 4560, 18570, 5760));
        assert_eq!((p.qgc_udp, p.api_udp, p.sim_params_udp, p.hawkeye_udp), (14550, 14540, 19550, 19410));
        let p = InstancePorts::of(1).expect("in range");
        assert_eq!((p.system_id, p.qgc_udp, p.api_udp, p.tcp), (2, 14550, 14541, 5761));
    }

    #[test]
    fn the_api_ports_skip_qgroundcontrols_port() {
        assert_eq!(InstancePorts::of(9).expect("in range").api_udp, 14549);
        assert_eq!(InstancePorts::of(10).expect("in range").api_udp, 14551);
        assert_eq!(InstancePorts::of(MAX_INSTANCE).expect("in range").api_udp, 14795);
    }

    #[test]
    fn no_two_instances_up_to_the_largest_share_a_port_by_accident() {
        // Every port of every instance 0..=254, bound or sent to: only 14550 is shared, and by design.
        let mut owner = std::collections::HashMap::new();
        for n in 0..=MAX_INSTANCE {
            let p = InstancePorts::of(n).expect("in range");
            let mut ports: Vec<(&str, u16)> = p.bound().to_vec();
            ports.push(("api", p.api_udp));
            for (what, port) in ports {
                assert_ne!(port, QGC_PORT, "instance {n}'s {what} port is QGroundControl's");
                if let Some((m, other)) = owner.insert(port, (n, what)) {
                    panic!("port {port}: instance {n}'s {what} and instance {m}'s {other}");
                }
            }
        }
        assert_eq!(owner.len(), 5 * (usize::from(MAX_INSTANCE) + 1));
    }

    #[test]
    fn hawkeye_ports_meet_no_other_port_up_to_their_largest_instance_and_px4s_from_140_on() {
        // Every port of every instance, bound or sent to.
        let mut others = std::collections::HashMap::new();
        for n in 0..=MAX_INSTANCE {
            let p = InstancePorts::of(n).expect("in range");
            for (what, port) in p.bound().into_iter().chain([("api", p.api_udp), ("qgc", p.qgc_udp)]) {
                others.insert(port, (n, what));
            }
        }
        assert_eq!(HAWKEYE_MAX_INSTANCE, 139);
        for n in 0..=HAWKEYE_MAX_INSTANCE {
            let port = InstancePorts::of(n).expect("in range").hawkeye_udp;
            assert_eq!(port, 19410 + n);
            assert!(!others.contains_key(&port), "instance {n}'s Hawkeye port {port} is {:?}'s", others.get(&port));
        }
        let first_clash = InstancePorts::of(HAWKEYE_MAX_INSTANCE + 1).expect("in range").hawkeye_udp;
        assert_eq!(others.get(&first_clash), Some(&(0, "sim_params")), "PX4's 19410 + N, as it is");
    }

    #[test]
    fn beyond_the_largest_instance_is_an_error_not_a_wrapped_port() {
        assert_eq!(InstancePorts::of(MAX_INSTANCE + 1), Err(InstanceOutOfRange(255)));
        assert_eq!(InstancePorts::of(u16::MAX), Err(InstanceOutOfRange(u16::MAX)));
    }
}
