//! State estimation: the building blocks of the fused estimator. In: IMU samples (specific force m/s²,
//! rates rad/s, FRD) and scalar observations at the sensor rates (`eskf`), WGS-84 fixes (deg, m AMSL) at the
//! GPS rate (`geo`), the estimated NED position (m) and velocity (m/s) per IMU sample (`history`). Out: the
//! error-state Kalman filter's state and covariance, NED positions about an origin, and delayed states.

pub mod eskf;
pub mod geo;
pub mod history;

pub use geo::GeoOrigin;
