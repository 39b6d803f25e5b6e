//! The parameter table's telemetry sections: the ACO weights' telemetry rate and the onboard ULog's mode,
//! both kept in the store only.

use crate::core::params::{Binding, ParamDef, ParamGroup, ParamKind};

/// Telemetry: kept in the store only (no config field).
pub(super) const TELEMETRY: &[ParamDef] = &[ParamDef {
    name: "ACO_WEIGHTS_HZ",
    group: ParamGroup::Telemetry,
    kind: ParamKind::Real,
    default: 2.0,
    min: 0.0,
    max: 50.0,
    unit: "Hz",
    restart: false,
    description: "Rate of the stream of the controller's adaptive weights (0: off).",
    binding: Binding::StoreOnly,
}];

/// The onboard ULog: kept in the store only, read by the shell at each arming.
pub(super) const ULOG: &[ParamDef] = &[ParamDef {
    name: "SDLOG_MODE",
    group: ParamGroup::Telemetry,
    kind: ParamKind::Integer,
    default: 0.0,
    min: -1.0,
    max: 0.0,
    unit: "",
    restart: false,
    description: "When the onboard ULog flight log is written: -1 never, 0 from arming until disarming, and while a motor test spins a motor (PX4's default; PX4's other modes are not offered). Read at each arming.",
    binding: Binding::StoreOnly,
}];
