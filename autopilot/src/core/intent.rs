//! What the commander and the navigator say to each other, and nothing else: the commander decides the
//! mode and passes its [`Intent`] (take off to an altitude, hold, reposition to a point, land, or an
//! automatic mode) to the navigator, which latches the points, owns the yaw and flies; the navigator's
//! [`Progress`] (the mission finished, an automatic landing began or ended) goes back as events the vehicle
//! hands to the commander. Neither reads the other's state: information flows commander -> navigator ->
//! controller, and progress comes back as events.

use nalgebra::Vector3;

/// What the commander asks the navigator to fly (NED m, rad). The navigator latches the points the first
/// step an intent differs from the one before: where a takeoff climbs (here, at `alt_m` above the ground;
/// a new altitude while climbing keeps the point), where a landing descends (here), and the yaw held
/// (the vehicle's as it leaves the ground idle, or a reposition's).
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum Intent {
    /// Motors at minimum (armed on the ground) or off.
    Idle,
    /// Climb to `alt_m` above the ground, here.
    Takeoff { alt_m: f64 },
    /// Hold: where the reference stops, the takeoff's point, or a point flown to (DO_REPOSITION), with
    /// a new yaw (None: keep).
    Hold { at: HoldAt, yaw_rad: Option<f64> },
    /// Descend here at the land speed until landed.
    Land,
    /// The navigator decides (mission, return, offboard).
    Auto(AutoMode),
    /// Fly the pilot's sticks (the navigator's input) in this manual mode.
    Manual(ManualMode),
}

/// How the sticks fly (PX4's manual modes; MANUAL is flown as STABILIZED on a multicopter, as PX4 does).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum ManualMode {
    /// Sticks to attitude and yaw rate, throttle stick to thrust.
    Stabilized,
    /// Sticks to attitude and yaw rate, throttle stick to climb rate; the altitude held at centre.
    Altitude,
    /// Sticks to horizontal velocity and yaw rate, throttle stick to climb rate; the position held when
    /// centred.
    Position,
    /// Sticks to body rates (`MC_ACRO_*`), throttle stick to thrust; nothing levels the attitude.
    Acro,
}

/// Where a [`Intent::Hold`] holds.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum HoldAt {
    /// A jerk-limited stop where the reference is (a pause, Hold entered from another mode).
    Stop,
    /// The point the takeoff climbed to (the hold that ends a takeoff continues its leg).
    TakeoffPoint,
    /// This point (NED m), flown to from where the reference is.
    Point(Vector3<f64>),
}

/// Which automatic behaviour the commander is in.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum AutoMode {
    Mission,
    ReturnToLaunch,
    Offboard,
}

/// What the navigator reports back, when it changes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Progress {
    /// The mission flew its last item without landing (true), or was replaced or restarted (false).
    MissionDone(bool),
    /// An automatic mode (mission, return) began (true) or stopped (false) descending to land.
    Landing(bool),
}
