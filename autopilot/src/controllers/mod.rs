//! controllers written only against the public controller interface (guests)
//!
//! Each module here is one controller that uses nothing of `crate::core::control` but its `pub` items
//! (the [`Controller`](crate::core::control::Controller) and
//! [`ControllerType`](crate::core::control::ControllerType) traits, the shared helpers and the channel
//! distributor) and declares its parameters with `crate::core::params`. It is registered with one line in
//! the registry's `BUILT_IN` list. `docs/controllers.md` walks through `se3` as the worked example.

pub mod se3;
