//! Offboard setpoints, decoded. In: SET_POSITION_TARGET_LOCAL_NED, SET_POSITION_TARGET_GLOBAL_INT and
//! SET_ATTITUDE_TARGET for this system, with the estimator's geodetic origin and home's altitude (for the
//! global frames). Out: an [`OffboardSetpoint`] in local NED (m, m/s, m/s², rad) for the navigator, or a
//! refusal text.
//!
//! `type_mask` bits select the fields (PX4's usage: MAVSDK's 2552 = position + yaw, 2503 = velocity +
//! yaw): a cleared X/Y/Z-ignore bit gives the position, VX/VY/VZ the velocity, AX/AY/AZ the acceleration
//! (FORCE_SET is refused), YAW and YAW_RATE the heading. Frames: LOCAL_NED (1); BODY_NED (8), whose
//! velocity and acceleration are rotated by the current yaw; GLOBAL_INT (5, AMSL) and
//! GLOBAL_RELATIVE_ALT_INT (6, above home). SET_ATTITUDE_TARGET gives an attitude (its quaternion, as ZYX
//! Euler angles) and, unless THROTTLE_IGNORE is set, a normalized collective thrust (0 = every rotor at
//! its 1000 µs lift, 1 = at its 2000 µs lift; hover is about 0.46 on the paper's airframe), as PX4 takes
//! it. With THROTTLE_IGNORE the altitude is held where attitude control began (the paper's attitude-only
//! mode). With ATTITUDE_IGNORE (bit 7) it gives body rates (FRD rad/s; a rate whose BODY_*_RATE_IGNORE
//! bit is set is 0) and the thrust: the rate level, as PX4's offboard rates (MAVSDK's
//! `set_attitude_rate`). With an attitude, rates not ignored are its rate feed-forward.

use ::mavlink::dialects::common::{AttitudeTargetTypemask, MavFrame, MavMessage, PositionTargetTypemask};
use nalgebra::{Quaternion, Rotation3, UnitQuaternion, Vector3};

use super::addressed_to_us;
use super::units::dege7_to_deg;
use crate::core::estimator::GeoOrigin;
use crate::core::mission::NavTarget;
use crate::core::navigator::OffboardSetpoint;
use crate::core::plan::{self, Frame, Unresolved};

/// What the decoder needs to know of the vehicle.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct OffboardContext {
    pub origin: Option<GeoOrigin>,
    pub home_alt_amsl_m: Option<f64>,
    /// Current yaw (rad), for body frames.
    pub yaw_rad: f64,
}

// The *_INT frames and BODY_NED are deprecated in the dialect, but MAVSDK and QGroundControl send them.
/// The offboard setpoint in `msg`, if it is one for system `sysid`: `Some(Ok)` to use, `Some(Err(text))`
/// to refuse (a frame or mask this vehicle cannot fly), `None` when `msg` is not an offboard setpoint for us.
#[allow(deprecated)]
#[must_use]
pub fn decode(sysid: u8, msg: &MavMessage, ctx: &OffboardContext) -> Option<Result<OffboardSetpoint, String>> {
    match msg {
        MavMessage::SET_POSITION_TARGET_LOCAL_NED(m) => {
            if !addressed_to_us(sysid, m.target_system, m.target_component) {
                return None;
            }
            let body = match m.coordinate_frame {
                MavFrame::MAV_FRAME_LOCAL_NED => false,
                MavFrame::MAV_FRAME_BODY_NED => true,
                other => return Some(Err(format!("Offboard: frame {} not supported", other as u32))),
            };
            let pos = Vector3::new(f64::from(m.x), f64::from(m.y), f64::from(m.z));
            Some(position_target(
                m.type_mask,
                Some(pos),
                [m.vx, m.vy, m.vz],
                [m.afx, m.afy, m.afz],
                m.yaw,
                m.yaw_rate,
                body,
                ctx,
            ))
        }
        MavMessage::SET_POSITION_TARGET_GLOBAL_INT(m) => {
            if !addressed_to_us(sysid, m.target_system, m.target_component) {
                return None;
            }
            let relative = match m.coordinate_frame {
                MavFrame::MAV_FRAME_GLOBAL_INT | MavFrame::MAV_FRAME_GLOBAL => false,
                MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT_INT | MavFrame::MAV_FRAME_GLOBAL_RELATIVE_ALT => true,
                other => return Some(Err(format!("Offboard: frame {} not supported", other as u32))),
            };
            let wants_position = !m.type_mask.intersects(
                PositionTargetTypemask::POSITION_TARGET_TYPEMASK_X_IGNORE
                    | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_Y_IGNORE
                    | PositionTargetTypemask::POSITION_TARGET_TYPEMASK_Z_IGNORE,
            );
            let pos = if wants_position {
                let target = NavTarget::Global {
                    lat_deg: dege7_to_deg(m.lat_int),
                    lon_deg: dege7_to_deg(m.lon_int),
                    alt_m: f64::from(m.alt),
                    relative,
                };
                let frame = Frame { origin: ctx.origin, home_alt_amsl_m: ctx.home_alt_amsl_m, ground_d_m: 0.0 };
                // An offboard setpoint has no "current altitude": a NaN altitude resolves to a point that is
                // not finite, refused below with the rest.
                match plan::resolve(&target, &frame, Vector3::repeat(f64::NAN)) {
                    Ok(p) => Some(p),
                    Err(Unresolved::NoOrigin) => return Some(Err("Offboard: no global position yet".into())),
                    Err(Unresolved::NoHomeAltitude) => {
                        return Some(Err("Offboard: no home for a relative altitude".into()));
                    }
                    // A non-finite point is refused where every setpoint is checked.
                    Err(Unresolved::Invalid) => Some(Vector3::repeat(f64::NAN)),
                }
            } else {
                None
            };
            Some(position_target(
                m.type_mask,
                pos,
                [m.vx, m.vy, m.vz],
                [m.afx, m.afy, m.afz],
                m.yaw,
                m.yaw_rate,
                false,
                ctx,
            ))
        }
        MavMessage::SET_ATTITUDE_TARGET(m) => {
            if !addressed_to_us(sysid, m.target_system, 0) {
                return None;
            }
            use AttitudeTargetTypemask as T;
            let rate_bits = [
                (T::ATTITUDE_TARGET_TYPEMASK_BODY_ROLL_RATE_IGNORE, m.body_roll_rate),
                (T::ATTITUDE_TARGET_TYPEMASK_BODY_PITCH_RATE_IGNORE, m.body_pitch_rate),
                (T::ATTITUDE_TARGET_TYPEMASK_BODY_YAW_RATE_IGNORE, m.body_yaw_rate),
            ];
            let rates_given = rate_bits.iter().any(|(bit, _)| !m.type_mask.contains(*bit));
            let rates =
                Vector3::from(rate_bits.map(|(bit, r)| if m.type_mask.contains(bit) { 0.0 } else { f64::from(r) }));
            if !rates.iter().all(|r| r.is_finite()) {
                return Some(Err("Offboard: body rates not finite".into()));
            }
            let euler = if m.type_mask.contains(T::ATTITUDE_TARGET_TYPEMASK_ATTITUDE_IGNORE) {
                if !rates_given {
                    return Some(Err("Offboard: attitude and rates both ignored".into()));
                }
                None
            } else {
                let [w, x, y, z] = m.q.map(f64::from);
                let q = Quaternion::new(w, x, y, z);
                if !(q.norm() > 0.5 && q.coords.iter().all(|c| c.is_finite())) {
                    return Some(Err("Offboard: invalid attitude quaternion".into()));
                }
                let (roll_rad, pitch_rad, yaw_rad) = UnitQuaternion::new_normalize(q).euler_angles();
                Some(Vector3::new(roll_rad, pitch_rad, yaw_rad))
            };
            let thrust_frac = if m.type_mask.contains(AttitudeTargetTypemask::ATTITUDE_TARGET_TYPEMASK_THROTTLE_IGNORE)
            {
                None
            } else {
                let thrust = f64::from(m.thrust);
                if !(0.0..=1.0).contains(&thrust) {
                    return Some(Err(format!("Offboard: thrust {thrust} outside 0-1")));
                }
                Some(thrust)
            };
            Some(Ok(OffboardSetpoint {
                attitude_rad: euler,
                thrust_frac,
                rate_frd_radps: rates_given.then_some(rates),
                ..OffboardSetpoint::default()
            }))
        }
        _ => None,
    }
}

/// The fields of a position target selected by `mask`.
#[allow(clippy::too_many_arguments)]
fn position_target(
    mask: PositionTargetTypemask,
    pos: Option<Vector3<f64>>,
    vel: [f32; 3],
    acc: [f32; 3],
    yaw: f32,
    yaw_rate: f32,
    body: bool,
    ctx: &OffboardContext,
) -> Result<OffboardSetpoint, String> {
    use PositionTargetTypemask as M;
    if mask.contains(M::POSITION_TARGET_TYPEMASK_FORCE_SET) {
        return Err("Offboard: force setpoints not supported".into());
    }
    let all = |bits: M| !mask.intersects(bits);
    let any = |bits: M| !mask.contains(bits);
    let vec3 = |v: [f32; 3]| Vector3::new(f64::from(v[0]), f64::from(v[1]), f64::from(v[2]));
    let to_ned =
        |v: Vector3<f64>| if body { Rotation3::from_axis_angle(&Vector3::z_axis(), ctx.yaw_rad) * v } else { v };
    let pos_bits = M::POSITION_TARGET_TYPEMASK_X_IGNORE
        | M::POSITION_TARGET_TYPEMASK_Y_IGNORE
        | M::POSITION_TARGET_TYPEMASK_Z_IGNORE;
    let vel_bits = M::POSITION_TARGET_TYPEMASK_VX_IGNORE
        | M::POSITION_TARGET_TYPEMASK_VY_IGNORE
        | M::POSITION_TARGET_TYPEMASK_VZ_IGNORE;
    let acc_bits = M::POSITION_TARGET_TYPEMASK_AX_IGNORE
        | M::POSITION_TARGET_TYPEMASK_AY_IGNORE
        | M::POSITION_TARGET_TYPEMASK_AZ_IGNORE;
    if any(pos_bits) && !all(pos_bits) || any(vel_bits) && !all(vel_bits) || any(acc_bits) && !all(acc_bits) {
        return Err("Offboard: set all three axes of a field".into());
    }
    let position = if all(pos_bits) { pos.filter(|p| p.iter().all(|x| x.is_finite())) } else { None };
    if all(pos_bits) && position.is_none() {
        return Err("Offboard: position not finite".into());
    }
    let finite3 = |v: Vector3<f64>| v.iter().all(|x| x.is_finite());
    let velocity = all(vel_bits).then(|| to_ned(vec3(vel))).filter(|v| finite3(*v));
    let acceleration = all(acc_bits).then(|| to_ned(vec3(acc))).filter(|a| finite3(*a));
    if position.is_none() && velocity.is_none() && acceleration.is_none() {
        return Err("Offboard: no position or velocity".into());
    }
    let yaw_rad = any(M::POSITION_TARGET_TYPEMASK_YAW_IGNORE).then_some(f64::from(yaw)).filter(|y| y.is_finite());
    let yaw_rate_radps =
        any(M::POSITION_TARGET_TYPEMASK_YAW_RATE_IGNORE).then_some(f64::from(yaw_rate)).filter(|y| y.is_finite());
    Ok(OffboardSetpoint {
        pos_ned_m: position,
        vel_ned_mps: velocity,
        acc_ned_mps2: acceleration,
        yaw_rad,
        yaw_rate_radps,
        attitude_rad: None,
        thrust_frac: None,
        rate_frd_radps: None,
    })
}

#[cfg(test)]
mod tests {
    use ::mavlink::dialects::common::{SET_ATTITUDE_TARGET_DATA, SET_POSITION_TARGET_LOCAL_NED_DATA};

    use super::*;

    fn local(mask: u16, frame: MavFrame) -> MavMessage {
        MavMessage::SET_POSITION_TARGET_LOCAL_NED(SET_POSITION_TARGET_LOCAL_NED_DATA {
            time_boot_ms: 0,
            x: 1.0,
            y: 2.0,
            z: -3.0,
            vx: 0.5,
            vy: 0.0,
            vz: 0.0,
            afx: 0.0,
            afy: 0.0,
            afz: 0.0,
            yaw: 0.3,
            yaw_rate: 0.1,
            type_mask: PositionTargetTypemask::from_bits_truncate(mask),
            target_system: 1,
            target_component: 1,
            coordinate_frame: frame,
        })
    }

    #[test]
    fn given_mavsdks_masks_when_decoded_then_position_plus_yaw_and_velocity_plus_yaw() {
        let ctx = OffboardContext::default();
        let sp = decode(1, &local(2552, MavFrame::MAV_FRAME_LOCAL_NED), &ctx).expect("ours").expect("valid");
        assert_eq!(sp.pos_ned_m, Some(Vector3::new(1.0, 2.0, -3.0)));
        assert_eq!((sp.vel_ned_mps, sp.acc_ned_mps2, sp.yaw_rate_radps), (None, None, None));
        assert!((sp.yaw_rad.expect("yaw") - 0.3).abs() < 1e-6);
        let sp = decode(1, &local(2503, MavFrame::MAV_FRAME_LOCAL_NED), &ctx).expect("ours").expect("valid");
        assert_eq!((sp.pos_ned_m, sp.vel_ned_mps), (None, Some(Vector3::new(0.5, 0.0, 0.0))));
        assert!(sp.yaw_rad.is_some());
    }

    #[test]
    #[allow(deprecated)]
    fn given_a_body_frame_velocity_then_it_is_rotated_by_the_yaw() {
        let ctx = OffboardContext { yaw_rad: std::f64::consts::FRAC_PI_2, ..OffboardContext::default() };
        let sp = decode(1, &local(2503, MavFrame::MAV_FRAME_BODY_NED), &ctx).expect("ours").expect("valid");
        let v = sp.vel_ned_mps.expect("velocity");
        assert!((v - Vector3::new(0.0, 0.5, 0.0)).norm() < 1e-9, "{v:?}");
    }

    #[test]
    fn given_unusable_targets_then_refused_and_others_ignored() {
        let ctx = OffboardContext::default();
        assert!(decode(1, &local(2552 | 512, MavFrame::MAV_FRAME_LOCAL_NED), &ctx).expect("ours").is_err());
        assert!(decode(1, &local(2552 | 1, MavFrame::MAV_FRAME_LOCAL_NED), &ctx).expect("ours").is_err());
        assert!(decode(1, &local(0xFFF, MavFrame::MAV_FRAME_LOCAL_NED), &ctx).expect("ours").is_err());
        assert!(decode(1, &local(2552, MavFrame::MAV_FRAME_LOCAL_ENU), &ctx).expect("ours").is_err());
        assert_eq!(decode(2, &local(2552, MavFrame::MAV_FRAME_LOCAL_NED), &ctx), None);
    }

    #[test]
    fn given_an_attitude_target_then_its_euler_angles() {
        let q = UnitQuaternion::from_euler_angles(0.1, -0.05, 0.4);
        let msg = MavMessage::SET_ATTITUDE_TARGET(SET_ATTITUDE_TARGET_DATA {
            time_boot_ms: 0,
            q: [q.w as f32, q.i as f32, q.j as f32, q.k as f32],
            body_roll_rate: 0.0,
            body_pitch_rate: 0.0,
            body_yaw_rate: 0.0,
            thrust: 0.5,
            target_system: 1,
            target_component: 1,
            type_mask: AttitudeTargetTypemask::from_bits_truncate(7),
            ..Default::default()
        });
        let sp = decode(1, &msg, &OffboardContext::default()).expect("ours").expect("valid");
        let e = sp.attitude_rad.expect("attitude");
        assert!((e - Vector3::new(0.1, -0.05, 0.4)).norm() < 1e-6, "{e:?}");
        assert_eq!(sp.thrust_frac, Some(0.5), "MAVSDK's set_attitude (mask 7): the thrust is used");
    }

    fn attitude_target(type_mask: u8, thrust: f32) -> MavMessage {
        MavMessage::SET_ATTITUDE_TARGET(SET_ATTITUDE_TARGET_DATA {
            q: [1.0, 0.0, 0.0, 0.0],
            thrust,
            target_system: 1,
            target_component: 1,
            type_mask: AttitudeTargetTypemask::from_bits_truncate(type_mask),
            ..Default::default()
        })
    }

    #[test]
    fn given_an_attitude_target_then_thrust_by_type_mask_and_out_of_range_thrust_refused() {
        let ctx = OffboardContext::default();
        let ours = |msg: MavMessage| decode(1, &msg, &ctx).expect("ours");
        // THROTTLE_IGNORE (64): the altitude is held, whatever the thrust field says.
        assert_eq!(ours(attitude_target(7 | 64, 0.9)).expect("valid").thrust_frac, None);
        assert_eq!(ours(attitude_target(7 | 64, f32::NAN)).expect("valid").thrust_frac, None);
        assert_eq!(ours(attitude_target(7, 0.0)).expect("valid").thrust_frac, Some(0.0));
        assert_eq!(ours(attitude_target(7, 1.0)).expect("valid").thrust_frac, Some(1.0));
        for bad in [-0.1, 1.5, f32::NAN, f32::INFINITY] {
            assert!(ours(attitude_target(7, bad)).is_err(), "thrust {bad} refused");
        }
        // Attitude and every rate ignored: nothing to fly.
        assert!(ours(attitude_target(128 | 7, 0.5)).is_err());
    }

    /// MAVSDK's `set_attitude_rate` (ATTITUDE_IGNORE, 128): body rates (FRD rad/s) with the thrust, no
    /// attitude; an ignored rate is 0. With an attitude and rates not ignored, the rates ride along as its
    /// feed-forward.
    #[test]
    fn given_a_body_rate_target_then_rates_and_thrust_without_attitude() {
        let ctx = OffboardContext::default();
        let rate_target = |mask: u8, rates: [f32; 3]| {
            MavMessage::SET_ATTITUDE_TARGET(SET_ATTITUDE_TARGET_DATA {
                body_roll_rate: rates[0],
                body_pitch_rate: rates[1],
                body_yaw_rate: rates[2],
                ..match attitude_target(mask, 0.46) {
                    MavMessage::SET_ATTITUDE_TARGET(d) => d,
                    _ => unreachable!("an attitude target"),
                }
            })
        };
        let sp = decode(1, &rate_target(128, [0.5, -0.25, 0.1]), &ctx).expect("ours").expect("valid");
        assert_eq!(sp.attitude_rad, None);
        let r = sp.rate_frd_radps.expect("rates");
        assert!((r - Vector3::new(0.5, -0.25, 0.1)).norm() < 1e-6, "{r:?}");
        assert_eq!(sp.thrust_frac.map(|t| (t * 100.0).round()), Some(46.0));
        let sp = decode(1, &rate_target(128 | 4, [0.5, -0.25, 0.1]), &ctx).expect("ours").expect("valid");
        assert_eq!(sp.rate_frd_radps.map(|r| r.z), Some(0.0), "yaw rate ignored: 0");
        let sp = decode(1, &rate_target(0, [0.5, 0.0, 0.0]), &ctx).expect("ours").expect("valid");
        assert!(sp.attitude_rad.is_some() && sp.rate_frd_radps.is_some(), "attitude with its feed-forward");
        assert!(decode(1, &rate_target(128, [f32::NAN, 0.0, 0.0]), &ctx).expect("ours").is_err());
    }
}
