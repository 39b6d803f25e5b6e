//! Return to launch: climb to `rtl_return_alt_m` above home (if lower), fly level to above home (or to
//! the rally point the navigator chose as the return began, `Planner::return_ned_m`), land there. In, per step: the [`Planner`] and the [`NavInput`]. Out: the reference's motion; the planner's
//! `landing` status while descending. Each phase is a jerk-limited leg that starts from the reference's
//! motion, so the return is smooth from wherever it is entered (a mission, a hold, offboard).

use nalgebra::Vector3;

use super::leg::{Leg, Motion3};
use super::planner::Flight;
use super::{Climb, NavInput, Planner};

/// Return-to-launch progress.
#[derive(Debug, Clone)]
pub(crate) enum Rtl {
    /// A vertical leg up to the return altitude.
    Climb(Leg),
    Return(Leg),
    Descend(Flight),
}

impl Rtl {
    /// The landing, once descending.
    pub fn into_flight(self) -> Option<Flight> {
        match self {
            Self::Descend(flight) => Some(flight),
            _ => None,
        }
    }
}

/// Where the return goes (a rally point, or home), or the ground below the vehicle without either.
fn home(p: &Planner, input: &NavInput) -> Vector3<f64> {
    p.return_ned_m.or(input.home_ned_m).unwrap_or(Vector3::new(input.pos_ned_m.x, input.pos_ned_m.y, 0.0))
}

fn return_leg(p: &Planner, input: &NavInput, from: Vector3<f64>) -> Rtl {
    let h = home(p, input);
    let to = Vector3::new(h.x, h.y, from.z);
    if (to - from).xy().norm() < p.config.acceptance_radius_m {
        return Rtl::Descend(Flight::land(p, input, to.xy()));
    }
    Rtl::Return(p.line(input, to, Climb::Move, None))
}

/// One step of the return (`rtl` None: it starts now).
pub(crate) fn step(rtl: &mut Option<Rtl>, p: &mut Planner, input: &NavInput) -> Motion3 {
    let phase = rtl.take().unwrap_or_else(|| {
        let here = p.start(input).pos_ned_m;
        let return_d = (home(p, input).z - p.config.rtl_return_alt_m).min(here.z);
        if here.z > return_d + input.takeoff_acceptance_m {
            Rtl::Climb(p.line(input, Vector3::new(here.x, here.y, return_d), Climb::Move, None))
        } else {
            return_leg(p, input, here)
        }
    });
    let (next, m) = match phase {
        Rtl::Climb(mut leg) => {
            let m = p.fly(&mut leg, input);
            let to = leg.end();
            if leg.at_end() && (input.pos_ned_m.z - to.z).abs() <= input.takeoff_acceptance_m {
                (return_leg(p, input, to), m)
            } else {
                (Rtl::Climb(leg), m)
            }
        }
        Rtl::Return(mut leg) => {
            let m = p.fly(&mut leg, input);
            if leg.at_end() && (input.pos_ned_m - leg.end()).xy().norm() <= p.config.acceptance_radius_m {
                (Rtl::Descend(Flight::land(p, input, leg.end().xy())), m)
            } else {
                (Rtl::Return(leg), m)
            }
        }
        Rtl::Descend(mut flight) => {
            let m = flight.fly(p, input);
            (Rtl::Descend(flight), m)
        }
    };
    *rtl = Some(next);
    m
}
