//! The parameters of `se3` (`SE3_*`, group "Other controllers") and the gains `sitl tune` searches. Each
//! parameter reads and writes one field of the `se3` table through `ControllerConfig::section` and
//! `set_section`, so a PARAM_SET reaches a flying `se3` by the same reconfigure as the built-in ones.

use super::{Se3Config, TABLE, defaults};
use crate::core::control::registry::{GainScale, TunableGain};
use crate::core::params::{Binding, ParamDef, ParamGroup, ParamKind};

/// One real parameter bound to `field` of the `se3` table (`$($path)+` after `s.`).
macro_rules! se3_param {
    ($name:literal, $default:expr, [$min:literal, $max:literal], $unit:literal, $description:literal, $($path:tt)+) => {
        ParamDef {
            name: $name,
            group: ParamGroup::Controllers,
            kind: ParamKind::Real,
            default: $default as f32,
            min: $min,
            max: $max,
            unit: $unit,
            restart: false,
            description: $description,
            binding: Binding::Config {
                get: |c| c.control.section::<Se3Config>(TABLE).unwrap_or_default().$($path)+,
                set: |c, v| {
                    let mut s = c.control.section::<Se3Config>(TABLE).unwrap_or_default();
                    s.$($path)+ = v;
                    // A typed section always serialises to a table.
                    c.control.set_section(TABLE, &s).ok();
                },
            },
        }
    };
}

/// The `SE3_*` parameters, appended after the core's table in the registry's order.
pub(super) static PARAMS: &[ParamDef] = &[
    se3_param!("SE3_KX", defaults::KX_PER_S2, [0.1, 100.0], "1/s²", "SE(3) position gain kx per unit mass.", kx_per_s2),
    se3_param!("SE3_KV", defaults::KV_PER_S, [0.1, 50.0], "1/s", "SE(3) velocity gain kv per unit mass.", kv_per_s),
    se3_param!(
        "SE3_KI_POS",
        defaults::KI_POS_PER_S3,
        [0.0, 50.0],
        "1/s³",
        "SE(3) position integral gain (0: off).",
        ki_pos_per_s3
    ),
    se3_param!(
        "SE3_I_POS_MAX",
        defaults::POS_INT_MAX_MPS2,
        [0.0, 10.0],
        "m/s²",
        "SE(3) bound on each position integral term.",
        pos_int_max_mps2
    ),
    se3_param!(
        "SE3_I_POS_ZONE",
        defaults::POS_INT_ZONE_M,
        [0.0, 10.0],
        "m",
        "SE(3) position error within which the position integral runs.",
        pos_int_zone_m
    ),
    se3_param!(
        "SE3_KR",
        defaults::KR_PER_S2,
        [1.0, 1000.0],
        "1/s²",
        "SE(3) roll and pitch attitude gain kR per unit inertia.",
        kr_per_s2
    ),
    se3_param!(
        "SE3_KW",
        defaults::KW_PER_S,
        [0.5, 100.0],
        "1/s",
        "SE(3) roll and pitch rate gain kΩ per unit inertia.",
        kw_per_s
    ),
    se3_param!(
        "SE3_KR_YAW",
        defaults::KR_YAW_PER_S2,
        [0.5, 500.0],
        "1/s²",
        "SE(3) yaw attitude gain kR per unit inertia.",
        kr_yaw_per_s2
    ),
    se3_param!(
        "SE3_KW_YAW",
        defaults::KW_YAW_PER_S,
        [0.2, 100.0],
        "1/s",
        "SE(3) yaw rate gain kΩ per unit inertia.",
        kw_yaw_per_s
    ),
    se3_param!(
        "SE3_KI_ATT",
        defaults::KI_ATT_PER_S3,
        [0.0, 500.0],
        "1/s³",
        "SE(3) attitude integral gain (0: off).",
        ki_att_per_s3
    ),
    se3_param!(
        "SE3_I_ATT_MAX",
        defaults::ATT_INT_MAX_RADPS2,
        [0.0, 50.0],
        "rad/s²",
        "SE(3) bound on each attitude integral term.",
        att_int_max_radps2
    ),
    se3_param!(
        "SE3_I_ATT_ZONE",
        defaults::ATT_INT_ZONE_RAD,
        [0.0, 3.0],
        "rad",
        "SE(3) attitude error within which the attitude integral runs.",
        att_int_zone_rad
    ),
    se3_param!(
        "SE3_TILT_MAX",
        defaults::TILT_MAX_RAD,
        [0.05, 1.5],
        "rad",
        "SE(3) largest tilt of the thrust vector.",
        limits.tilt_max_rad
    ),
];

/// The gains `sitl tune` searches for `se3` when a spec names none.
pub(super) static GAINS: &[TunableGain] = &[
    TunableGain { name: "se3.kx_per_s2", axes: &[], bounds: [0.5, 30.0], scale: GainScale::Log },
    TunableGain { name: "se3.kv_per_s", axes: &[], bounds: [0.5, 15.0], scale: GainScale::Log },
    TunableGain { name: "se3.ki_pos_per_s3", axes: &[], bounds: [0.05, 20.0], scale: GainScale::Log },
    TunableGain { name: "se3.kr_per_s2", axes: &[], bounds: [10.0, 400.0], scale: GainScale::Log },
    TunableGain { name: "se3.kw_per_s", axes: &[], bounds: [3.0, 40.0], scale: GainScale::Log },
    TunableGain { name: "se3.ki_att_per_s3", axes: &[], bounds: [0.5, 200.0], scale: GainScale::Log },
];
