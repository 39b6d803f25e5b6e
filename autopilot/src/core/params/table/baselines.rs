//! The parameter table's baseline sections: the PID cascade, the MRAC ("CA") and the competent CA's options.

use crate::core::params::{Binding, ParamDef, ParamGroup, ParamKind};

/// PID baseline.
pub(super) const PID: &[ParamDef] = &[
    real!(Pid, "PID_POS_P", 0.6667, [0.05, 5.0], "1/s", "Position gain Kp.", control.pid.kp_pos_per_s),
    real!(Pid, "PID_VEL_P", 2.16, [0.1, 20.0], "1/s", "Velocity gain Kv.", control.pid.kv_vel_per_s),
    ParamDef {
        name: "PID_VEL_I_NE",
        group: ParamGroup::Pid,
        kind: ParamKind::Real,
        default: 0.4,
        min: 0.0,
        max: 20.0,
        unit: "1/s²",
        restart: false,
        description: "Velocity integral gain Kvi, north and east (both).",
        binding: Binding::Config {
            get: |c| c.control.pid.kvi_vel_per_s2[0],
            set: |c, v| {
                c.control.pid.kvi_vel_per_s2[0] = v;
                c.control.pid.kvi_vel_per_s2[1] = v;
            },
        },
    },
    real!(
        Pid,
        "PID_VEL_I_D",
        2.0,
        [0.0, 20.0],
        "1/s²",
        "Velocity integral gain Kvi, down.",
        control.pid.kvi_vel_per_s2[2]
    ),
    real!(Pid, "PID_ROLL_P", 2.778, [0.1, 20.0], "1/s", "Roll attitude gain Kη.", control.pid.k_att_per_s[0]),
    real!(Pid, "PID_PITCH_P", 2.778, [0.1, 20.0], "1/s", "Pitch attitude gain Kη.", control.pid.k_att_per_s[1]),
    real!(Pid, "PID_YAW_P", 1.389, [0.1, 20.0], "1/s", "Yaw attitude gain Kη.", control.pid.k_att_per_s[2]),
    real!(Pid, "PID_ROLLRATE_P", 9.0, [0.5, 50.0], "1/s", "Roll rate gain Kω.", control.pid.k_rate_per_s[0]),
    real!(Pid, "PID_PITCHRATE_P", 9.0, [0.5, 50.0], "1/s", "Pitch rate gain Kω.", control.pid.k_rate_per_s[1]),
    real!(Pid, "PID_YAWRATE_P", 4.5, [0.5, 50.0], "1/s", "Yaw rate gain Kω.", control.pid.k_rate_per_s[2]),
    real!(
        Pid,
        "PID_ROLLRATE_I",
        12.0,
        [0.0, 100.0],
        "1/s²",
        "Roll rate integral gain Kri.",
        control.pid.kri_rate_per_s2[0]
    ),
    real!(
        Pid,
        "PID_PITCHRATE_I",
        12.0,
        [0.0, 100.0],
        "1/s²",
        "Pitch rate integral gain Kri.",
        control.pid.kri_rate_per_s2[1]
    ),
    real!(
        Pid,
        "PID_YAWRATE_I",
        2.25,
        [0.0, 100.0],
        "1/s²",
        "Yaw rate integral gain Kri.",
        control.pid.kri_rate_per_s2[2]
    ),
];

/// MRAC ("CA") baseline.
pub(super) const MRAC: &[ParamDef] = &[
    real!(
        Mrac,
        "MRAC_GAM_K_ATT",
        1000.0,
        [0.0, 10000.0],
        "",
        "Gain adaptation rate Γk of the attitude channels.",
        control.mrac.gamma_k_att
    ),
    real!(
        Mrac,
        "MRAC_GAM_TH_ATT",
        1000.0,
        [0.0, 10000.0],
        "",
        "Offset adaptation rate Γθ of the attitude channels.",
        control.mrac.gamma_theta_att
    ),
    real!(
        Mrac,
        "MRAC_GAM_K_POS",
        0.3,
        [0.0, 100.0],
        "",
        "Gain adaptation rate Γk of the position channels.",
        control.mrac.gamma_k_pos
    ),
    real!(
        Mrac,
        "MRAC_GAM_TH_POS",
        1.0,
        [0.0, 100.0],
        "",
        "Offset adaptation rate Γθ of the position channels (CA-fast: 3).",
        control.mrac.gamma_theta_pos
    ),
    flag!(
        Mrac,
        "MRAC_FREEZE_SAT",
        1.0,
        "Stop adapting a channel while its actuator saturates (0: CA-raw).",
        control.mrac.freeze_on_saturation
    ),
];

/// The competent CA (docs/controller.md §4.3); all off by default, the paper's CA.
pub(super) const COMPETENT_CA: &[ParamDef] = &[
    flag!(
        Mrac,
        "MRAC_FF",
        0.0,
        "Feed the reference's velocity, acceleration and jerk through the position reference models (0: the paper's CA).",
        control.mrac.feed_forward
    ),
    real!(
        Mrac,
        "MRAC_WI_ATT",
        0.0,
        [0.0, 50.0],
        "rad/s",
        "Pole of the attitude channels' integral of the model-following error (0: none, the paper's CA).",
        control.mrac.wi_att_radps
    ),
    real!(
        Mrac,
        "MRAC_WI_POS",
        0.0,
        [0.0, 20.0],
        "rad/s",
        "Pole of the position channels' integral of the model-following error (0: none, the paper's CA).",
        control.mrac.wi_pos_radps
    ),
    real!(
        Mrac,
        "MRAC_EMOD",
        0.0,
        [0.0, 10.0],
        "",
        "e-modification σ: adaptive parameters leak toward their initial values at Γσ times the error signal s in size (0: none).",
        control.mrac.e_mod_sigma
    ),
    flag!(
        Mrac,
        "MRAC_HEDGE",
        0.0,
        "Hedge each reference model by the demand the actuators could not give (0: the paper's CA).",
        control.mrac.hedging
    ),
];
