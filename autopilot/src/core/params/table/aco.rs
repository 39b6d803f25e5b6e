//! The parameter table's ACO sections: the cascade's gains and limits (spec A.4 steps 4-7) and the LMS
//! identification's rates, filters and bounds (spec A.1, Eqs 11-18).

use crate::core::params::{Binding, ParamDef, ParamGroup, ParamKind};

/// ACO controller: the cascade (spec A.4 steps 4-7).
pub(super) const CASCADE: &[ParamDef] = &[
    real!(
        Aco,
        "ACO_POS_P",
        0.6667,
        [0.05, 5.0],
        "1/s",
        "Position gain Kp: velocity command per metre of position error.",
        control.aco.kp_pos_per_s
    ),
    real!(
        Aco,
        "ACO_VEL_P",
        2.16,
        [0.1, 20.0],
        "1/s",
        "Velocity gain Kv: acceleration demand per m/s of velocity error.",
        control.aco.kv_vel_per_s
    ),
    real!(
        Aco,
        "ACO_ROLL_P",
        2.778,
        [0.1, 20.0],
        "1/s",
        "Roll attitude gain Kη (Eqs 22-24).",
        control.aco.k_att_per_s[0]
    ),
    real!(
        Aco,
        "ACO_PITCH_P",
        2.778,
        [0.1, 20.0],
        "1/s",
        "Pitch attitude gain Kη (Eqs 22-24).",
        control.aco.k_att_per_s[1]
    ),
    real!(Aco, "ACO_YAW_P", 1.389, [0.1, 20.0], "1/s", "Yaw attitude gain Kη (Eqs 22-24).", control.aco.k_att_per_s[2]),
    real!(
        Aco,
        "ACO_ROLLRATE_P",
        9.0,
        [0.5, 50.0],
        "1/s",
        "Roll rate gain Kω (Eq 9 inverted).",
        control.aco.k_rate_per_s[0]
    ),
    real!(
        Aco,
        "ACO_PITCHRATE_P",
        9.0,
        [0.5, 50.0],
        "1/s",
        "Pitch rate gain Kω (Eq 9 inverted).",
        control.aco.k_rate_per_s[1]
    ),
    real!(
        Aco,
        "ACO_YAWRATE_P",
        4.5,
        [0.5, 50.0],
        "1/s",
        "Yaw rate gain Kω (Eq 9 inverted).",
        control.aco.k_rate_per_s[2]
    ),
    real!(
        Aco,
        "ACO_ROLL_RMAX",
        3.5,
        [0.1, 10.0],
        "rad/s",
        "Limit on the desired roll rate.",
        control.aco.rate_limit_radps[0]
    ),
    real!(
        Aco,
        "ACO_PITCH_RMAX",
        3.5,
        [0.1, 10.0],
        "rad/s",
        "Limit on the desired pitch rate.",
        control.aco.rate_limit_radps[1]
    ),
    real!(
        Aco,
        "ACO_YAW_RMAX",
        1.5,
        [0.1, 10.0],
        "rad/s",
        "Limit on the desired yaw rate.",
        control.aco.rate_limit_radps[2]
    ),
    real!(
        Aco,
        "ACO_VEL_MAX_NE",
        3.0,
        [0.1, 20.0],
        "m/s",
        "Limit on the velocity command, north and east (per axis).",
        control.aco.vel_limit_ne_mps
    ),
    real!(
        Aco,
        "ACO_VEL_MAX_D",
        2.0,
        [0.1, 10.0],
        "m/s",
        "Limit on the vertical velocity command.",
        control.aco.vel_limit_d_mps
    ),
    real!(
        Aco,
        "ACO_ACC_MAX_NE",
        5.0,
        [0.1, 20.0],
        "m/s²",
        "Limit on the horizontal norm of the desired acceleration.",
        control.aco.acc_limit_ne_mps2
    ),
    real!(
        Aco,
        "ACO_ACC_MAX_D",
        4.0,
        [0.1, 15.0],
        "m/s²",
        "Limit on the vertical desired acceleration.",
        control.aco.acc_limit_d_mps2
    ),
];

/// ACO controller: the LMS identification (spec A.1, Eqs 11-18).
pub(super) const LMS: &[ParamDef] = &[
    real!(
        Aco,
        "ACO_GAM_W_T",
        10.0,
        [0.0, 100.0],
        "1/s",
        "Adaptation rate of the translation gain weights w_i (gamma = 2 mu f_s).",
        control.aco.gamma_w_t_per_s
    ),
    real!(
        Aco,
        "ACO_GAM_B_T",
        5.0,
        [0.0, 100.0],
        "1/s",
        "Adaptation rate of the translation bias weights b_i.",
        control.aco.gamma_b_t_per_s
    ),
    real!(
        Aco,
        "ACO_GAM_C_R",
        20.0,
        [0.0, 100.0],
        "1/s",
        "Adaptation rate of the rotation gain weights c_j.",
        control.aco.gamma_c_r_per_s
    ),
    real!(
        Aco,
        "ACO_GAM_D_R",
        5.0,
        [0.0, 100.0],
        "1/s",
        "Adaptation rate of the rotation bias weights d_j.",
        control.aco.gamma_d_r_per_s
    ),
    real!(
        Aco,
        "ACO_LPF_T_HZ",
        8.0,
        [0.5, 40.0],
        "Hz",
        "Cutoff of the 2nd-order low-pass on both sides of the translation LMS.",
        control.aco.lpf_translation_hz
    ),
    real!(
        Aco,
        "ACO_LPF_R_HZ",
        15.0,
        [0.5, 40.0],
        "Hz",
        "Cutoff of the 2nd-order low-pass on both sides of the rotation LMS.",
        control.aco.lpf_rotation_hz
    ),
    real!(
        Aco,
        "ACO_W_T_MIN",
        0.5,
        [0.05, 1.0],
        "g",
        "Lower bound of the translation gain weights w_i, in units of g.",
        control.aco.w_t_bounds_g[0]
    ),
    real!(
        Aco,
        "ACO_W_T_MAX",
        2.0,
        [1.0, 10.0],
        "g",
        "Upper bound of the translation gain weights w_i, in units of g.",
        control.aco.w_t_bounds_g[1]
    ),
    real!(
        Aco,
        "ACO_B_T_MAX",
        4.0,
        [0.0, 20.0],
        "m/s²",
        "Bound on the magnitude of the translation bias weights b_i.",
        control.aco.b_t_max_mps2
    ),
    real!(
        Aco,
        "ACO_C_R_MIN",
        0.5,
        [0.05, 1.0],
        "alpha_ref",
        "Lower bound of the rotation gain weights c_j, in units of ACO_ALPHA_REF.",
        control.aco.c_r_bounds_alpha_ref[0]
    ),
    real!(
        Aco,
        "ACO_C_R_MAX",
        2.0,
        [1.0, 10.0],
        "alpha_ref",
        "Upper bound of the rotation gain weights c_j, in units of ACO_ALPHA_REF.",
        control.aco.c_r_bounds_alpha_ref[1]
    ),
    real!(
        Aco,
        "ACO_D_R_MAX",
        8.0,
        [0.0, 50.0],
        "rad/s²",
        "Bound on the magnitude of the rotation bias weights d_j.",
        control.aco.d_r_max_radps2
    ),
    real!(
        Aco,
        "ACO_ALPHA_REF",
        10.0,
        [0.1, 1000.0],
        "rad/s²",
        "Normalisation of the rotation regressor (the nominal c_j); a change rescales the c_j.",
        control.aco.alpha_ref_radps2
    ),
    flag!(
        Aco,
        "ACO_ADAPT_EN",
        1.0,
        "LMS adaptation on; 0 freezes every weight where it is.",
        control.aco.adaptation_enabled
    ),
    flag!(
        Aco,
        "ACO_POS_I_EN",
        0.0,
        "Zoned position integral on (spec A.4, optional on hardware).",
        control.aco.pos_integral_enabled
    ),
    real!(
        Aco,
        "ACO_POS_I",
        0.1,
        [0.0, 5.0],
        "1/s",
        "Position integral gain Ki: v_c = Kp (e_p + Ki ∫e_p dt) + v_ref.",
        control.aco.ki_pos_per_s
    ),
    real!(
        Aco,
        "ACO_POS_I_ZONE",
        0.25,
        [0.01, 10.0],
        "m",
        "The position integral accumulates on an axis only while its error is below this.",
        control.aco.pos_integral_zone_m
    ),
];
