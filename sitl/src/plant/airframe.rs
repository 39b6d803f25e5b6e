//! Airframe parameters of the plant (spec (b) "Parameters"; Eq 7 inertia and disturbance torque, Eq 27 arm
//! l and yaw ratio λ): in, a preset name plus per-value overrides from a TOML `[airframe]` table; out, a
//! validated [`Airframe`] in SI units, read by every integrator substep. Mutable at run time through
//! `Plant::airframe_mut` (fault injection: `rotor_health`, `disturbance_torque_frd_nm`, ...).

use nalgebra::Vector3;
use serde::Deserialize;

use super::PlantError;
use super::payload::Payload;

/// The preset names [`Airframe::preset`] accepts.
pub const PRESET_NAMES: &str = "nominal, mismatch";

/// The physical parameters of the simulated quadrotor. All SI; body axes FRD.
///
/// Deserialises from an [`AirframeConfig`] table (`preset = "mismatch"`, then any field as an override), so
/// a deserialised `Airframe` has always been validated.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(try_from = "AirframeConfig")]
pub struct Airframe {
    /// Vehicle mass m (kg).
    pub mass_kg: f64,
    /// Principal moments of inertia diag(Ixx, Iyy, Izz) about the FRD axes (kg·m²), Eq 7.
    pub inertia_kgm2: Vector3<f64>,
    /// Arm length l, centre to each rotor (m), Eq 27.
    pub arm_m: f64,
    /// Yaw-moment ratio λ, reaction torque per newton of lift (m), Eq 27.
    pub yaw_moment_m: f64,
    /// First-order rotor lag τ_m (s): dF/dt = (k_F·h·F10(PWM) - F)/τ_m.
    pub motor_tau_s: f64,
    /// Thrust scale k_F multiplying every rotor's Eq 10 lift (1 = nominal).
    pub thrust_scale: f64,
    /// Per-rotor health factor in [0, 1] multiplying that rotor's lift (index i is paper rotor i+1);
    /// 0 = failed rotor, 1 = healthy.
    pub rotor_health: [f64; 4],
    /// Constant disturbance torque τ_dist in FRD (N·m), Eq 7.
    pub disturbance_torque_frd_nm: Vector3<f64>,
    /// Drag area Cd·A (m²) of the quadratic airframe drag (0 = no drag).
    pub drag_cda_m2: f64,
    /// Air density ρ (kg/m³) used by the drag term.
    pub air_density_kgpm3: f64,
    /// Gravitational acceleration g (m/s²), along +D.
    pub gravity_mps2: f64,
    /// An added point mass and its offset (SIM_PAYLOAD_KG, SIM_CG_OFS_X/Y; [`Payload`]); none by default
    /// and in every preset. Not a TOML key: it is set in flight (or by a scenario's `[[event]]`).
    pub payload: Payload,
}

impl Airframe {
    /// The paper's model airframe (spec (b) table, "nominal"): the plant the controller was designed for.
    #[must_use]
    pub fn nominal() -> Self {
        Self {
            mass_kg: 5.2,
            inertia_kgm2: Vector3::new(0.08, 0.08, 0.12),
            arm_m: 0.24,
            yaw_moment_m: 0.02703,
            motor_tau_s: 0.04,
            thrust_scale: 1.0,
            rotor_health: [1.0; 4],
            disturbance_torque_frd_nm: Vector3::zeros(),
            drag_cda_m2: 0.10,
            air_density_kgpm3: 1.225,
            gravity_mps2: 9.81,
            payload: Payload::default(),
        }
    }

    /// The robustness runs' true plant (spec (b) table, "mismatch"): m 5.4 kg, I × 1.3, λ × 1.2,
    /// τ_m 0.05 s, k_F 0.99, τ_dist (0.06, -0.06, 0) N·m.
    #[must_use]
    pub fn mismatch() -> Self {
        let nominal = Self::nominal();
        Self {
            mass_kg: 5.4,
            inertia_kgm2: nominal.inertia_kgm2 * 1.3,
            yaw_moment_m: nominal.yaw_moment_m * 1.2,
            motor_tau_s: 0.05,
            thrust_scale: 0.99,
            disturbance_torque_frd_nm: Vector3::new(0.06, -0.06, 0.0),
            ..nominal
        }
    }

    /// The preset called `name` (one of [`PRESET_NAMES`], exact spelling).
    ///
    /// # Errors
    /// [`PlantError::UnknownPreset`] for any other name.
    pub fn preset(name: &str) -> Result<Self, PlantError> {
        match name {
            "nominal" => Ok(Self::nominal()),
            "mismatch" => Ok(Self::mismatch()),
            _ => Err(PlantError::UnknownPreset { name: name.to_owned(), known: PRESET_NAMES }),
        }
    }

    /// The mass the rotors carry (kg): the airframe's m plus any payload (exactly m without one).
    #[must_use]
    pub fn total_mass_kg(&self) -> f64 {
        self.mass_kg + self.payload.mass_kg
    }

    /// Weight (m + m_p)·g (N).
    #[must_use]
    pub fn weight_n(&self) -> f64 {
        self.total_mass_kg() * self.gravity_mps2
    }

    /// The per-rotor lift that holds hover, (m + m_p)·g/4 (N).
    #[must_use]
    pub fn hover_lift_n(&self) -> f64 {
        self.weight_n() / 4.0
    }

    /// The PWM that makes a healthy rotor of this airframe produce `hover_lift_n` in steady state:
    /// Eq 10 evaluated at m·g/(4·k_F). Not clamped; outside 1000-2000 µs the airframe cannot hover.
    #[must_use]
    pub fn hover_pwm_us(&self) -> f64 {
        super::rotor::pwm_from_lift_us(self.hover_lift_n() / self.thrust_scale)
    }

    /// Check that every value is physical.
    ///
    /// # Errors
    /// [`PlantError::InvalidValue`] naming the first offending field: a non-finite value, mass, inertia,
    /// arm, λ, τ_m, k_F or ρ not > 0, principal inertias violating the triangle inequality, rotor health
    /// outside [0, 1], negative drag area or gravity.
    pub fn validate(&self) -> Result<(), PlantError> {
        positive("airframe.mass_kg", self.mass_kg)?;
        for (i, name) in
            ["airframe.inertia_kgm2[0]", "airframe.inertia_kgm2[1]", "airframe.inertia_kgm2[2]"].into_iter().enumerate()
        {
            positive(name, self.inertia_kgm2[i])?;
        }
        let [ix, iy, iz] = [self.inertia_kgm2.x, self.inertia_kgm2.y, self.inertia_kgm2.z];
        if ix + iy < iz || iy + iz < ix || iz + ix < iy {
            return Err(PlantError::InvalidValue {
                name: "airframe.inertia_kgm2",
                value: format!("{:?}", [ix, iy, iz]),
                reason: "principal inertias of a rigid body satisfy the triangle inequality \
                         (Ixx + Iyy >= Izz, ...)",
            });
        }
        positive("airframe.arm_m", self.arm_m)?;
        positive("airframe.yaw_moment_m", self.yaw_moment_m)?;
        positive("airframe.motor_tau_s", self.motor_tau_s)?;
        positive("airframe.thrust_scale", self.thrust_scale)?;
        for (i, &h) in self.rotor_health.iter().enumerate() {
            if !(0.0..=1.0).contains(&h) {
                return Err(PlantError::InvalidValue {
                    name: [
                        "airframe.rotor_health[0]",
                        "airframe.rotor_health[1]",
                        "airframe.rotor_health[2]",
                        "airframe.rotor_health[3]",
                    ][i],
                    value: h.to_string(),
                    reason: "must be within [0, 1] (0 = failed, 1 = healthy)",
                });
            }
        }
        for (i, name) in [
            "airframe.disturbance_torque_frd_nm[0]",
            "airframe.disturbance_torque_frd_nm[1]",
            "airframe.disturbance_torque_frd_nm[2]",
        ]
        .into_iter()
        .enumerate()
        {
            finite(name, self.disturbance_torque_frd_nm[i])?;
        }
        non_negative("airframe.drag_cda_m2", self.drag_cda_m2)?;
        positive("airframe.air_density_kgpm3", self.air_density_kgpm3)?;
        non_negative("airframe.gravity_mps2", self.gravity_mps2)?;
        non_negative("airframe.payload.mass_kg", self.payload.mass_kg)?;
        for (i, name) in
            ["airframe.payload.offset_frd_m[0]", "airframe.payload.offset_frd_m[1]", "airframe.payload.offset_frd_m[2]"]
                .into_iter()
                .enumerate()
        {
            finite(name, self.payload.offset_frd_m[i])?;
        }
        Ok(())
    }
}

impl Default for Airframe {
    fn default() -> Self {
        Self::nominal()
    }
}

/// The TOML form of an airframe: a preset and optional overrides of any of its values, e.g.
///
/// ```toml
/// [airframe]
/// preset = "mismatch"
/// mass_kg = 5.3
/// rotor_health = [1.0, 1.0, 0.8, 1.0]
/// ```
///
/// Unknown keys are rejected, so a misspelt override is an error rather than silently ignored.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AirframeConfig {
    /// Preset to start from (see [`PRESET_NAMES`]); default "nominal".
    pub preset: String,
    pub mass_kg: Option<f64>,
    pub inertia_kgm2: Option<[f64; 3]>,
    pub arm_m: Option<f64>,
    pub yaw_moment_m: Option<f64>,
    pub motor_tau_s: Option<f64>,
    pub thrust_scale: Option<f64>,
    pub rotor_health: Option<[f64; 4]>,
    pub disturbance_torque_frd_nm: Option<[f64; 3]>,
    pub drag_cda_m2: Option<f64>,
    pub air_density_kgpm3: Option<f64>,
    pub gravity_mps2: Option<f64>,
}

impl Default for AirframeConfig {
    fn default() -> Self {
        Self {
            preset: "nominal".to_owned(),
            mass_kg: None,
            inertia_kgm2: None,
            arm_m: None,
            yaw_moment_m: None,
            motor_tau_s: None,
            thrust_scale: None,
            rotor_health: None,
            disturbance_torque_frd_nm: None,
            drag_cda_m2: None,
            air_density_kgpm3: None,
            gravity_mps2: None,
        }
    }
}

impl AirframeConfig {
    /// The values set over the preset, in declaration order: (key, value; one number for a scalar, each
    /// element for an array).
    #[must_use]
    pub fn overrides(&self) -> Vec<(&'static str, Vec<f64>)> {
        let scalar = |name, v: Option<f64>| v.map(|v| (name, vec![v]));
        let array = |name, v: Option<&[f64]>| v.map(|v| (name, v.to_vec()));
        [
            scalar("mass_kg", self.mass_kg),
            array("inertia_kgm2", self.inertia_kgm2.as_ref().map(|v| &v[..])),
            scalar("arm_m", self.arm_m),
            scalar("yaw_moment_m", self.yaw_moment_m),
            scalar("motor_tau_s", self.motor_tau_s),
            scalar("thrust_scale", self.thrust_scale),
            array("rotor_health", self.rotor_health.as_ref().map(|v| &v[..])),
            array("disturbance_torque_frd_nm", self.disturbance_torque_frd_nm.as_ref().map(|v| &v[..])),
            scalar("drag_cda_m2", self.drag_cda_m2),
            scalar("air_density_kgpm3", self.air_density_kgpm3),
            scalar("gravity_mps2", self.gravity_mps2),
        ]
        .into_iter()
        .flatten()
        .collect()
    }

    /// The preset with the overrides applied, validated.
    ///
    /// # Errors
    /// [`PlantError::UnknownPreset`] or [`PlantError::InvalidValue`] (see [`Airframe::validate`]).
    pub fn resolve(&self) -> Result<Airframe, PlantError> {
        let mut a = Airframe::preset(&self.preset)?;
        if let Some(v) = self.mass_kg {
            a.mass_kg = v;
        }
        if let Some(v) = self.inertia_kgm2 {
            a.inertia_kgm2 = Vector3::from(v);
        }
        if let Some(v) = self.arm_m {
            a.arm_m = v;
        }
        if let Some(v) = self.yaw_moment_m {
            a.yaw_moment_m = v;
        }
        if let Some(v) = self.motor_tau_s {
            a.motor_tau_s = v;
        }
        if let Some(v) = self.thrust_scale {
            a.thrust_scale = v;
        }
        if let Some(v) = self.rotor_health {
            a.rotor_health = v;
        }
        if let Some(v) = self.disturbance_torque_frd_nm {
            a.disturbance_torque_frd_nm = Vector3::from(v);
        }
        if let Some(v) = self.drag_cda_m2 {
            a.drag_cda_m2 = v;
        }
        if let Some(v) = self.air_density_kgpm3 {
            a.air_density_kgpm3 = v;
        }
        if let Some(v) = self.gravity_mps2 {
            a.gravity_mps2 = v;
        }
        a.validate()?;
        Ok(a)
    }
}

impl TryFrom<AirframeConfig> for Airframe {
    type Error = PlantError;

    fn try_from(config: AirframeConfig) -> Result<Self, Self::Error> {
        config.resolve()
    }
}

pub(crate) fn finite(name: &'static str, value: f64) -> Result<(), PlantError> {
    if value.is_finite() {
        Ok(())
    } else {
        Err(PlantError::InvalidValue { name, value: value.to_string(), reason: "must be finite" })
    }
}

pub(crate) fn positive(name: &'static str, value: f64) -> Result<(), PlantError> {
    finite(name, value)?;
    if value > 0.0 {
        Ok(())
    } else {
        Err(PlantError::InvalidValue { name, value: value.to_string(), reason: "must be > 0" })
    }
}

pub(crate) fn non_negative(name: &'static str, value: f64) -> Result<(), PlantError> {
    finite(name, value)?;
    if value >= 0.0 {
        Ok(())
    } else {
        Err(PlantError::InvalidValue { name, value: value.to_string(), reason: "must be >= 0" })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn given_presets_when_resolved_then_they_carry_the_spec_table_values() {
        let n = Airframe::preset("nominal").unwrap();
        assert_eq!(n.mass_kg, 5.2);
        assert_eq!(n.inertia_kgm2, Vector3::new(0.08, 0.08, 0.12));
        assert_eq!(n.yaw_moment_m, 0.02703);
        assert_eq!(n.motor_tau_s, 0.04);
        assert_eq!(n.thrust_scale, 1.0);
        assert_eq!(n.arm_m, 0.24);
        assert_eq!(n.drag_cda_m2, 0.10);
        assert_eq!(n.air_density_kgpm3, 1.225);
        assert_eq!(n.gravity_mps2, 9.81);
        let m = Airframe::preset("mismatch").unwrap();
        assert_eq!(m.mass_kg, 5.4);
        assert!((m.inertia_kgm2 - Vector3::new(0.104, 0.104, 0.156)).norm() < 1e-15);
        assert!((m.yaw_moment_m - 0.032436).abs() < 1e-15);
        assert_eq!(m.motor_tau_s, 0.05);
        assert_eq!(m.thrust_scale, 0.99);
        assert_eq!(m.disturbance_torque_frd_nm, Vector3::new(0.06, -0.06, 0.0));
        assert_eq!(m.arm_m, 0.24);
        n.validate().unwrap();
        m.validate().unwrap();
    }

    #[test]
    fn given_an_unknown_preset_when_resolved_then_the_error_names_it_and_the_known_ones() {
        let err = Airframe::preset("heavy").unwrap_err();
        let msg = err.to_string();
        assert!(msg.contains("\"heavy\"") && msg.contains("nominal, mismatch"), "{msg}");
        let toml_err = toml::from_str::<Airframe>("preset = \"Nominal\"").unwrap_err();
        assert!(toml_err.to_string().contains("unknown airframe preset"), "{toml_err}");
    }

    #[test]
    fn given_non_physical_values_when_resolved_then_each_is_refused_with_its_name() {
        let cases: [(&str, &str); 9] = [
            ("mass_kg = 0.0", "airframe.mass_kg"),
            ("mass_kg = -5.0", "airframe.mass_kg"),
            ("mass_kg = nan", "airframe.mass_kg"),
            ("inertia_kgm2 = [0.08, 0.08, inf]", "airframe.inertia_kgm2[2]"),
            ("inertia_kgm2 = [0.01, 0.01, 0.12]", "triangle inequality"),
            ("rotor_health = [1.0, 1.2, 1.0, 1.0]", "airframe.rotor_health[1]"),
            ("rotor_health = [1.0, 1.0, -0.1, 1.0]", "airframe.rotor_health[2]"),
            ("motor_tau_s = 0.0", "airframe.motor_tau_s"),
            ("drag_cda_m2 = -0.1", "airframe.drag_cda_m2"),
        ];
        for (text, expected) in cases {
            let err = toml::from_str::<Airframe>(text).unwrap_err().to_string();
            assert!(err.contains(expected), "{text}: {err}");
        }
        let mut a = Airframe::nominal();
        a.gravity_mps2 = f64::NEG_INFINITY;
        assert!(a.validate().unwrap_err().to_string().contains("gravity"));
    }

    #[test]
    fn given_a_toml_table_with_overrides_when_parsed_then_the_preset_is_overridden_only_there() {
        let a: Airframe =
            toml::from_str("preset = \"mismatch\"\nmass_kg = 5.3\nrotor_health = [1.0, 1.0, 0.5, 1.0]\n").unwrap();
        let expected = Airframe { mass_kg: 5.3, rotor_health: [1.0, 1.0, 0.5, 1.0], ..Airframe::mismatch() };
        assert_eq!(a, expected);
        let defaulted: Airframe = toml::from_str("").unwrap();
        assert_eq!(defaulted, Airframe::nominal());
        let typo = toml::from_str::<Airframe>("mass = 5.3").unwrap_err().to_string();
        assert!(typo.contains("unknown field"), "{typo}");
    }

    #[test]
    fn given_nominal_airframe_when_asking_hover_pwm_then_it_is_the_spec_value() {
        let pwm = Airframe::nominal().hover_pwm_us();
        assert!((pwm - 1404.7).abs() < 0.2, "{pwm}");
    }
}
