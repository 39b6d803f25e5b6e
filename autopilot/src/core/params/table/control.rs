//! The parameter table's sections shared by the three controllers: the loop rates and the nominal airframe.

use crate::core::params::{Binding, ParamDef, ParamGroup, ParamKind};

/// Loop rates.
pub(super) const LOOP_RATES: &[ParamDef] = &[
    whole!(
        Loop,
        "LOOP_INNER_HZ",
        500.0,
        [50.0, 2000.0],
        "Hz",
        restart = true,
        "Rate of the inner loops (rate, attitude, LMS); one tick per plant sample, so it is the plant's sample rate (autopilot --rate sets both loop rates).",
        control.rates.inner_hz
    ),
    whole!(
        Loop,
        "LOOP_POS_HZ",
        100.0,
        [10.0, 500.0],
        "Hz",
        restart = true,
        "Rate of the position loop; must divide LOOP_INNER_HZ.",
        control.rates.position_hz
    ),
];

/// Nominal airframe, shared by the three controllers.
pub(super) const AIRFRAME: &[ParamDef] = &[
    airframe!("AF_MASS", 5.2, [0.1, 100.0], "kg", "Nominal mass m̄.", mass_kg),
    airframe!("AF_IXX", 0.08, [0.0001, 10.0], "kg·m²", "Nominal inertia Īx about the FRD x axis.", inertia_kgm2[0]),
    airframe!("AF_IYY", 0.08, [0.0001, 10.0], "kg·m²", "Nominal inertia Īy about the FRD y axis.", inertia_kgm2[1]),
    airframe!("AF_IZZ", 0.12, [0.0001, 10.0], "kg·m²", "Nominal inertia Īz about the FRD z axis.", inertia_kgm2[2]),
    airframe!("AF_ARM", 0.24, [0.02, 5.0], "m", "Arm length l, rotor to centre.", arm_m),
    airframe!(
        "AF_YAW_MOM",
        0.02703,
        [0.0001, 1.0],
        "m",
        "Yaw-moment coefficient λ: rotor yaw torque per newton of lift.",
        yaw_moment_m
    ),
    airframe!("AF_ROTOR_TAU", 0.04, [0.001, 1.0], "s", "Rotor first-order lag τ̄ (the ACO's rotor model).", rotor_tau_s),
];
