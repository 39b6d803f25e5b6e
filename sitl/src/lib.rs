//! The SITL side: the paper's quadrotor plant (`plant`), pure and deterministic, and the paper's
//! experiments run against it, one at a time (`scenario`) or swept over plants, winds and seeds (`sweep`).

pub mod gym;
pub mod launch;
pub mod link;
pub mod pacer;
pub mod plant;
pub mod progress;
pub mod scenario;
#[cfg(unix)]
pub mod serial_line;
pub mod sim_params;
pub mod sweep;
pub mod tune;
pub mod view;
