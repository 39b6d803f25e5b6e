//! The plans the vehicle flies and where their points are: the geofence and the rally points as uploaded
//! and the checks against them ([`geofence`]), the store of the mission, fence and rally points
//! ([`Plan`]), the resolver of every commanded target ([`resolve`]) and the guard that checks targets
//! against home and the geofence ([`SetpointGuard`]).

pub mod geofence;
mod guard;
mod resolve;
mod store;

pub use guard::{MAX_SETPOINT_FROM_HOME_M, SetpointGuard};
pub use resolve::{Frame, Unresolved, resolve};
pub use store::Plan;
