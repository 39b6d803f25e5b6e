"""The quick start's PD law (docs/python.md), written operation for operation like its Rust twin
``example_pd`` (python/src/example_pd.rs), so both fly bit-identical runs.

Position PD -> acceleration (NED) -> collective and small-angle tilt; attitude PD -> moments on the
nominal model -> rotor lifts (inverse of the paper's Eq 27) -> PWM (Eq 10).
"""

from __future__ import annotations

# The nominal model (autopilot's Airframe::default).
MASS_KG = 5.2
GRAVITY_MPS2 = 9.81
INERTIA_KGM2 = (0.08, 0.08, 0.12)
ARM_M = 0.24
YAW_MOMENT_M = 0.02703
# The rotors' lift at 1000 and 2000 µs (the exact inverse of Eq 10).
ROTOR_LIFT_MIN_N = 11.277060877149857
ROTOR_LIFT_MAX_N = 14.476943047337304


def pwm_from_lift_us(lift_n: float) -> float:
    """Eq 10 on a lift clipped to the rotors' range: 1105 - 260 F + 22.23 F²."""
    f = min(max(lift_n, ROTOR_LIFT_MIN_N), ROTOR_LIFT_MAX_N)
    return 1105.0 - 260.0 * f + 22.23 * f * f


def clip(x: float, limit: float) -> float:
    return min(max(x, -limit), limit)


class PdHover:
    """A PD hover law: ``PdHover()(input, reference) -> four PWM (µs)``."""

    def __init__(
        self,
        kp_pos_per_s2: float = 2.0,
        kd_vel_per_s: float = 2.6,
        kp_att_per_s2: float = 25.0,
        kd_rate_per_s: float = 8.0,
        tilt_max_rad: float = 0.35,
    ) -> None:
        self.kp_pos_per_s2 = kp_pos_per_s2
        self.kd_vel_per_s = kd_vel_per_s
        self.kp_att_per_s2 = kp_att_per_s2
        self.kd_rate_per_s = kd_rate_per_s
        self.tilt_max_rad = tilt_max_rad

    def __call__(self, inp, ref) -> list[float]:
        p, v = inp.pos_ned_m.tolist(), inp.vel_ned_mps.tolist()
        rp, rv, ra = ref.pos_ned_m.tolist(), ref.vel_ned_mps.tolist(), ref.acc_ned_mps2.tolist()
        kp, kd = self.kp_pos_per_s2, self.kd_vel_per_s
        a_n, a_e, a_d = (kp * (rp[i] - p[i]) + kd * (rv[i] - v[i]) + ra[i] for i in range(3))
        g = GRAVITY_MPS2
        thrust_n = MASS_KG * (g - a_d)
        roll_sp = clip(a_e / g, self.tilt_max_rad)
        pitch_sp = clip(-a_n / g, self.tilt_max_rad)
        e, w = inp.euler_rad.tolist(), inp.rate_frd_radps.tolist()
        ka, kr = self.kp_att_per_s2, self.kd_rate_per_s
        alpha_x = ka * (roll_sp - e[0]) - kr * w[0]
        alpha_y = ka * (pitch_sp - e[1]) - kr * w[1]
        alpha_z = ka * (ref.yaw_rad - e[2]) - kr * w[2]
        ix, iy, iz = INERTIA_KGM2
        mx, my, mz = ix * alpha_x, iy * alpha_y, iz * alpha_z
        c, arm, lam = thrust_n / 4.0, ARM_M, YAW_MOMENT_M
        return [
            pwm_from_lift_us(c - mx / (2.0 * arm) - mz / (4.0 * lam)),
            pwm_from_lift_us(c - my / (2.0 * arm) + mz / (4.0 * lam)),
            pwm_from_lift_us(c + my / (2.0 * arm) + mz / (4.0 * lam)),
            pwm_from_lift_us(c + mx / (2.0 * arm) - mz / (4.0 * lam)),
        ]
