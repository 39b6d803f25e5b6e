//! The controller registry: every controller by name, in one list. In: a name from a command line, a
//! scenario, sweep or tuning file, or the vehicle's configuration. Out: a [`ControllerKind`], the handle
//! that builds the controller and describes it (its configuration table, parameters, tunable gains).
//!
//! A controller is one type behind one trait, [`ControllerType`]. The built-in ones are listed in
//! [`BUILT_IN`]; a program (or a test) adds its own at run time with [`register`]. Nothing else in the
//! autopilot or the simulator names a controller: every tool takes any registered name.

use std::fmt;
use std::hash::{Hash, Hasher};
use std::str::FromStr;
use std::sync::RwLock;

use serde::{Deserialize, Deserializer, Serialize, Serializer};
use thiserror::Error;

use super::{ConfigError, Controller, ControllerConfig};
use crate::core::params::ParamDef;

/// How a tunable gain is searched between its bounds (a tuning spec's `scale`, linear by default).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum GainScale {
    /// Evenly in the value.
    #[default]
    Linear,
    /// Evenly in the logarithm (the bounds must be > 0): for gains spanning decades.
    Log,
}

/// One gain a controller offers to `sitl tune`: where it lives in the controller's table, the range a
/// search may take it over, and how that range is searched.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TunableGain {
    /// `table.field` as in the `[controller]` block, e.g. `pid.k_rate_per_s`.
    pub name: &'static str,
    /// The elements of an array field that take the value together (empty: a number field).
    pub axes: &'static [usize],
    pub bounds: [f64; 2],
    pub scale: GainScale,
}

/// A kind of controller: its name and how it is configured and built. Implement it for a unit struct,
/// put a `static` of it in [`BUILT_IN`] (or [`register`] it at run time) and every tool can fly it.
pub trait ControllerType: Sync + Send + 'static {
    /// The name on the command line and in files: lower case, digits and `_`.
    fn name(&self) -> &'static str;
    /// Other names it answers to (`mrac` for `ca`).
    fn aliases(&self) -> &'static [&'static str] {
        &[]
    }
    /// Its table in a `[controller]` block and in `[vehicle.control]` (by default its name).
    fn table(&self) -> &'static str {
        self.name()
    }
    /// One line for listings: what it is and where it comes from.
    fn summary(&self) -> &'static str;
    /// Its table's defaults, as TOML: what a missing table or key means.
    fn default_table(&self) -> toml::Table;
    /// Check its table of `config` (the loop rates are checked by the caller).
    ///
    /// # Errors
    /// A [`ConfigError`] naming the field.
    fn validate(&self, config: &ControllerConfig) -> Result<(), ConfigError>;
    /// Build one, from its table of `config` at `config.rates` (validated by the caller).
    ///
    /// # Errors
    /// A [`ConfigError`] naming the field.
    fn build(&self, config: &ControllerConfig) -> Result<Box<dyn Controller>, ConfigError>;
    /// Its parameters, appended to the vehicle's table after the core's (their indices follow the order
    /// of the registry). The built-in controllers' parameters are in the core's table at the indices
    /// ground stations have cached, so theirs is empty.
    fn params(&self) -> &'static [ParamDef] {
        &[]
    }
    /// Whether it flies the rate level ([`Reference::rate_frd_radps`](super::Reference::rate_frd_radps)):
    /// Acro, offboard body rates and a policy's rate actions need it, and are refused for a controller
    /// without it.
    fn flies_rates(&self) -> bool {
        false
    }
    /// The gains `sitl tune` searches when a tuning spec names none.
    fn gains(&self) -> &'static [TunableGain] {
        &[]
    }
}

/// A registered controller: a handle on its [`ControllerType`]. Compared, hashed, shown and written by
/// name; read from a name through the registry ([`find`]).
#[derive(Clone, Copy)]
pub struct ControllerKind(&'static dyn ControllerType);

impl ControllerKind {
    /// The handle of a controller type (not registered by this: see [`register`]).
    #[must_use]
    pub const fn of(ty: &'static dyn ControllerType) -> Self {
        Self(ty)
    }

    /// The paper's ACO.
    pub const ACO: Self = Self(&super::builtin::ACO);
    /// The paper's "common adaptive" baseline (MRAC).
    pub const CA: Self = Self(&super::builtin::CA);
    /// The PX4-style PID cascade.
    pub const PID: Self = Self(&super::builtin::PID);
    /// The three controllers the paper compares, in its order (the default of a scenario).
    pub const PAPER: [Self; 3] = [Self::ACO, Self::CA, Self::PID];

    /// The name used on the command line and in files.
    #[must_use]
    pub fn as_str(self) -> &'static str {
        self.0.name()
    }

    /// Its type: table, defaults, parameters, gains.
    #[must_use]
    pub fn ty(self) -> &'static dyn ControllerType {
        self.0
    }

    /// Its table in a `[controller]` block.
    #[must_use]
    pub fn table(self) -> &'static str {
        self.0.table()
    }

    /// Whether it flies the rate level ([`ControllerType::flies_rates`]).
    #[must_use]
    pub fn flies_rates(self) -> bool {
        self.0.flies_rates()
    }
}

impl PartialEq for ControllerKind {
    fn eq(&self, other: &Self) -> bool {
        self.as_str() == other.as_str()
    }
}

impl Eq for ControllerKind {}

impl Hash for ControllerKind {
    fn hash<H: Hasher>(&self, state: &mut H) {
        self.as_str().hash(state);
    }
}

impl PartialOrd for ControllerKind {
    fn partial_cmp(&self, other: &Self) -> Option<std::cmp::Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for ControllerKind {
    fn cmp(&self, other: &Self) -> std::cmp::Ordering {
        self.as_str().cmp(other.as_str())
    }
}

impl fmt::Debug for ControllerKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "ControllerKind({})", self.as_str())
    }
}

impl fmt::Display for ControllerKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.as_str())
    }
}

impl Serialize for ControllerKind {
    fn serialize<S: Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.as_str())
    }
}

impl<'de> Deserialize<'de> for ControllerKind {
    fn deserialize<D: Deserializer<'de>>(deserializer: D) -> Result<Self, D::Error> {
        let name = String::deserialize(deserializer)?;
        name.parse().map_err(serde::de::Error::custom)
    }
}

/// A name no registered controller answers to; the message lists the ones that do.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
#[error("unknown controller `{name}` (registered: {registered})")]
pub struct ParseControllerKindError {
    pub name: String,
    pub registered: String,
}

impl FromStr for ControllerKind {
    type Err = ParseControllerKindError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        find(s)
    }
}

/// Why a controller cannot be registered.
#[derive(Debug, Clone, PartialEq, Eq, Error)]
pub enum RegistryError {
    #[error("controller name `{0}` is registered twice")]
    Duplicate(String),
    #[error("controller name `{0}` is not lower case letters, digits and `_` (nor `rates`)")]
    BadName(String),
}

/// The controllers built into the autopilot, in the order listings show them. One line per controller.
#[rustfmt::skip]
pub static BUILT_IN: &[&dyn ControllerType] = &[
    &super::builtin::ACO,
    &super::builtin::CA,
    &super::builtin::PID,
    &crate::controllers::se3::SE3,
];

/// Controllers registered at run time, after the built-in ones.
static REGISTERED: RwLock<Vec<&'static dyn ControllerType>> = RwLock::new(Vec::new());

fn registered() -> Vec<&'static dyn ControllerType> {
    REGISTERED.read().unwrap_or_else(std::sync::PoisonError::into_inner).clone()
}

/// Every name and alias a type answers to.
fn names_of(ty: &dyn ControllerType) -> impl Iterator<Item = &'static str> + use<> {
    let (name, aliases) = (ty.name(), ty.aliases());
    std::iter::once(name).chain(aliases.iter().copied())
}

fn valid_name(name: &str) -> bool {
    !name.is_empty() && name.chars().all(|c| c.is_ascii_lowercase() || c.is_ascii_digit() || c == '_')
}

/// The first name, alias or table of `types` that is malformed or taken twice.
fn check_list(types: &[&'static dyn ControllerType]) -> Result<(), RegistryError> {
    let (mut seen, mut tables): (Vec<&str>, Vec<&str>) = (Vec::new(), Vec::new());
    for ty in types {
        for name in names_of(*ty).chain(std::iter::once(ty.table())) {
            if !valid_name(name) || name == "rates" {
                return Err(RegistryError::BadName(name.to_owned()));
            }
        }
        for name in names_of(*ty) {
            if seen.contains(&name) {
                return Err(RegistryError::Duplicate(name.to_owned()));
            }
            seen.push(name);
        }
        if tables.contains(&ty.table()) {
            return Err(RegistryError::Duplicate(ty.table().to_owned()));
        }
        tables.push(ty.table());
    }
    Ok(())
}

/// Checks the whole list (built-in and registered): every name well formed and none taken twice. The
/// programs call it at start-up and refuse to start on an error.
///
/// # Errors
/// The first [`RegistryError`].
pub fn check() -> Result<(), RegistryError> {
    let mut all: Vec<&'static dyn ControllerType> = BUILT_IN.to_vec();
    all.extend(registered());
    check_list(&all)
}

/// Adds a controller after the built-in ones; its name and aliases must be new.
///
/// # Errors
/// [`RegistryError::Duplicate`] when a name or alias is taken, [`RegistryError::BadName`] when one is
/// malformed; nothing is registered then.
pub fn register(ty: &'static dyn ControllerType) -> Result<ControllerKind, RegistryError> {
    let mut list = REGISTERED.write().unwrap_or_else(std::sync::PoisonError::into_inner);
    let mut all: Vec<&'static dyn ControllerType> = BUILT_IN.to_vec();
    all.extend(list.iter().copied());
    all.push(ty);
    check_list(&all)?;
    list.push(ty);
    Ok(ControllerKind(ty))
}

/// Every registered controller: the built-in ones, then those registered at run time.
#[must_use]
pub fn all() -> Vec<ControllerKind> {
    BUILT_IN.iter().copied().chain(registered()).map(ControllerKind).collect()
}

/// The registered names, comma-separated (for messages).
#[must_use]
pub fn names() -> String {
    all().iter().map(|k| k.as_str()).collect::<Vec<_>>().join(", ")
}

/// The controller answering to `name` (case and surrounding blanks ignored; aliases too).
///
/// # Errors
/// [`ParseControllerKindError`], listing the registered names.
pub fn find(name: &str) -> Result<ControllerKind, ParseControllerKindError> {
    let wanted = name.trim().to_ascii_lowercase();
    all()
        .into_iter()
        .find(|k| names_of(k.ty()).any(|n| n == wanted))
        .ok_or_else(|| ParseControllerKindError { name: name.to_owned(), registered: names() })
}

/// The controller whose table is `table`, if one is registered.
#[must_use]
pub fn by_table(table: &str) -> Option<ControllerKind> {
    all().into_iter().find(|k| k.table() == table)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn given_kind_names_when_parsed_and_displayed_then_round_trip() {
        for k in all() {
            assert_eq!(k.to_string().parse::<ControllerKind>(), Ok(k));
        }
        assert_eq!("ACO".parse::<ControllerKind>(), Ok(ControllerKind::ACO));
        assert_eq!(" mrac ".parse::<ControllerKind>(), Ok(ControllerKind::CA));
        let err = "lqr".parse::<ControllerKind>().expect_err("no lqr");
        assert_eq!(err.to_string(), format!("unknown controller `lqr` (registered: {})", names()));
        assert!(err.to_string().contains("aco, ca, pid"), "{err}");
    }

    #[test]
    fn given_the_built_in_list_when_checked_then_no_name_is_taken_twice() {
        assert_eq!(check(), Ok(()));
        assert_eq!(
            check_list(&[&super::super::builtin::ACO, &super::super::builtin::ACO]),
            Err(RegistryError::Duplicate("aco".into()))
        );
        assert_eq!(
            register(&super::super::builtin::PID).map(|k| k.to_string()),
            Err(RegistryError::Duplicate("pid".into()))
        );
        assert_eq!(serde_json::to_string(&ControllerKind::CA).expect("kind"), "\"ca\"");
        assert_eq!(serde_json::from_str::<ControllerKind>("\"pid\"").expect("kind"), ControllerKind::PID);
        assert!(serde_json::from_str::<ControllerKind>("\"lqr\"").is_err());
    }
}
