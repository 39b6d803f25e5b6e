//! The parameter system: every tunable of the vehicle declared once ([`table::PARAMS`]), the current
//! values ([`ParamStore`]), their mapping onto a [`VehicleConfig`], a text format to persist them and the
//! generated `docs/params.md` ([`markdown`]).
//!
//! In: names and values from a ground station (PARAM_SET) or from the text the runtime saved, and a
//! [`VehicleConfig`] to start from. Out: range-checked values, the config they describe
//! ([`ParamStore::apply`]), the text to save ([`ParamStore::to_text`]) and the docs. Units are each
//! parameter's `unit` (SI; gains in 1/s, rates in Hz). Pure: the runtime reads and writes the files.
//!
//! Every value is held as an f32: a boolean is 0 or 1 (min 0, max 1), an integer a whole value. On MAVLink
//! a value travels as its kind's [`ParamKind::mav_param_type`], as PX4 sends it: a real as REAL32, an
//! integer or a boolean as INT32 in PX4's bytewise encoding (the encoding is
//! `crate::core::mavlink::params`'). A parameter's index is its position in the table (PARAM_VALUE's
//! `param_index`). The
//! config holds f64: `from_config` rounds to f32, and `apply` writes a field only when the parameter
//! differs from that rounding, so `apply(from_config(c))` leaves any config `c` as it is (5.2 stays the
//! f64 5.2) while a value that was set arrives exactly (`from_config(apply(s)) == s`).
//!
//! The declarations, the store, its range checks and texts work over any table of [`ParamDef`]s, so that
//! another component declares its parameters the same way and serves them with the same PARAM service
//! (`crate::core::mavlink::params`): the SITL plant's SIM_ parameters do. A definition is generic over
//! its docs group `G` and what its value is bound to `B`; the vehicle's table ([`PARAMS`]) is the
//! instance `ParamDef<ParamGroup, Binding>` (the defaults, so `ParamDef` and `ParamStore` alone name it),
//! and only that instance maps onto a [`VehicleConfig`] and has docs.

use std::fmt;

use ::mavlink::dialects::common::MavParamType;
use thiserror::Error;

use crate::core::config::VehicleConfig;

pub mod table;

pub use table::PARAMS;

/// The table's sections (one table each in `docs/params.md`).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ParamGroup {
    Aco,
    Loop,
    Airframe,
    Pid,
    Mrac,
    Commander,
    Navigator,
    Telemetry,
    Radio,
    /// The parameters of the controllers registered beside the built-in ones, each its own.
    Controllers,
}

impl ParamGroup {
    /// Every group, in the order of the docs.
    pub const ALL: [Self; 10] = [
        Self::Aco,
        Self::Loop,
        Self::Airframe,
        Self::Pid,
        Self::Mrac,
        Self::Commander,
        Self::Navigator,
        Self::Radio,
        Self::Telemetry,
        Self::Controllers,
    ];

    /// The section title.
    #[must_use]
    pub fn title(self) -> &'static str {
        match self {
            Self::Aco => "ACO controller",
            Self::Loop => "Loop rates",
            Self::Airframe => "Nominal airframe",
            Self::Pid => "PID baseline",
            Self::Mrac => "MRAC (CA) baseline",
            Self::Commander => "Commander",
            Self::Navigator => "Navigator",
            Self::Telemetry => "Telemetry",
            Self::Radio => "Radio and manual control",
            Self::Controllers => "Other controllers",
        }
    }

    /// One sentence on what the group sets.
    #[must_use]
    pub fn summary(self) -> &'static str {
        match self {
            Self::Aco => {
                "The paper's adaptive controller (`control::aco`, spec A.1-A.4): cascade gains and limits, \
                 the LMS adaptation rates, filters and weight bounds. A change in flight keeps the identified \
                 weights."
            }
            Self::Loop => {
                "The controllers' loop rates (`control::LoopRates`). The inner loop runs once per plant \
                 sample, so these take effect at the next start."
            }
            Self::Airframe => {
                "The nominal model the controllers are designed on (`control::Airframe`); one value sets it \
                 for ACO, CA and PID alike."
            }
            Self::Pid => "Gains of the PID baseline (`control::pid`). A change in flight keeps the integrators.",
            Self::Mrac => {
                "Adaptation of the CA baseline (`control::mrac`). A change in flight keeps the adapted gains."
            }
            Self::Commander => "Arming, takeoff and landing (`commander::CommanderConfig`), under PX4's names.",
            Self::Navigator => "The automatic modes (`navigator::NavigatorConfig`), under PX4's names.",
            Self::Telemetry => "The autopilot's own telemetry.",
            Self::Radio => {
                "The pilot's input (`manual::ManualConfig`): the radio's channel map and calibration, the \
                 source of the sticks, their loss and its failsafe, the arming gestures and the mode switch, \
                 under PX4's names."
            }
            Self::Controllers => {
                "The controllers registered beside ACO, CA and PID (`control::registry`), each declaring its \
                 own (`ControllerType::params`); they follow the core's table, in the registry's order."
            }
        }
    }
}

/// How a value is read.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum ParamKind {
    /// Any finite value in range.
    Real,
    /// A whole value in range.
    Integer,
    /// 0 or 1.
    Boolean,
}

impl ParamKind {
    /// The MAVLink `param_type` a value of this kind travels as (PARAM_VALUE; what a PARAM_SET should
    /// send): REAL32 for a real, INT32 for an integer or a boolean, as PX4 declares them.
    #[must_use]
    pub const fn mav_param_type(self) -> MavParamType {
        match self {
            Self::Real => MavParamType::MAV_PARAM_TYPE_REAL32,
            Self::Integer | Self::Boolean => MavParamType::MAV_PARAM_TYPE_INT32,
        }
    }
}

/// A MAVLink parameter type's short name, as ground stations write it (`INT32`, `REAL32`).
#[must_use]
pub const fn param_type_name(param_type: MavParamType) -> &'static str {
    match param_type {
        MavParamType::MAV_PARAM_TYPE_UINT8 => "UINT8",
        MavParamType::MAV_PARAM_TYPE_INT8 => "INT8",
        MavParamType::MAV_PARAM_TYPE_UINT16 => "UINT16",
        MavParamType::MAV_PARAM_TYPE_INT16 => "INT16",
        MavParamType::MAV_PARAM_TYPE_UINT32 => "UINT32",
        MavParamType::MAV_PARAM_TYPE_INT32 => "INT32",
        MavParamType::MAV_PARAM_TYPE_UINT64 => "UINT64",
        MavParamType::MAV_PARAM_TYPE_INT64 => "INT64",
        MavParamType::MAV_PARAM_TYPE_REAL32 => "REAL32",
        MavParamType::MAV_PARAM_TYPE_REAL64 => "REAL64",
    }
}

/// Where a parameter of the vehicle's table lives in the [`VehicleConfig`].
#[derive(Debug, Clone, Copy)]
pub enum Binding {
    /// Read from and written to config fields (f64; whole numbers and 0/1 converted by the table).
    Config { get: fn(&VehicleConfig) -> f64, set: fn(&mut VehicleConfig, f64) },
    /// Held by the store only; `from_config` gives the default.
    StoreOnly,
}

/// One parameter's declaration. `G` is the docs section it is listed under and `B` what its value is
/// bound to: the vehicle's table uses the defaults, a table without docs whose owner applies every value
/// itself (the SITL plant's) uses `ParamDef<(), ()>`.
#[derive(Debug, Clone, Copy)]
pub struct ParamDef<G = ParamGroup, B = Binding> {
    /// PX4-style name: upper case, digits and `_`, at most 16 characters.
    pub name: &'static str,
    pub group: G,
    pub kind: ParamKind,
    pub default: f32,
    pub min: f32,
    pub max: f32,
    /// Unit of the value ("" for dimensionless).
    pub unit: &'static str,
    /// The value takes effect only at the next start.
    pub restart: bool,
    pub description: &'static str,
    pub binding: B,
}

impl<G, B> ParamDef<G, B> {
    /// Whether `value` is acceptable: finite, in `[min, max]`, whole for integers, 0 or 1 for booleans.
    ///
    /// # Errors
    /// The [`ParamError`] saying why not.
    pub fn check(&self, value: f32) -> Result<(), ParamError> {
        let name = self.name;
        if !value.is_finite() {
            return Err(ParamError::NotFinite { name, value });
        }
        if self.kind == ParamKind::Boolean && value != 0.0 && value != 1.0 {
            return Err(ParamError::NotBoolean { name, value });
        }
        if !(self.min..=self.max).contains(&value) {
            return Err(ParamError::OutOfRange { name, value, min: self.min, max: self.max });
        }
        if self.kind == ParamKind::Integer && value.fract() != 0.0 {
            return Err(ParamError::NotWhole { name, value });
        }
        Ok(())
    }
}

impl<G> ParamDef<G, Binding> {
    /// True when the parameter has no config field (see [`ParamStore::from_config`]).
    #[must_use]
    pub fn store_only(&self) -> bool {
        matches!(self.binding, Binding::StoreOnly)
    }
}

/// The declaration at `index`, if any.
#[must_use]
pub fn def(index: usize) -> Option<&'static ParamDef> {
    PARAMS.get(index)
}

/// A value formatted to read back bit-exactly as an f32: the shortest decimal that does, in exponent form
/// outside `[1e-4, 1e7)` so that huge and tiny values stay short.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Value(pub f32);

impl fmt::Display for Value {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let x = self.0;
        let a = x.abs();
        if x.is_finite() && a != 0.0 && !(1e-4..1e7).contains(&a) { write!(f, "{x:e}") } else { write!(f, "{x}") }
    }
}

/// Why a value was refused. The texts fit a STATUSTEXT (50 characters) for the table's names.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ParamError {
    #[error("unknown parameter {name}")]
    Unknown { name: String },
    #[error("no parameter at index {index}")]
    UnknownIndex { index: usize },
    #[error("{name}: {} is not finite", Value(*.value))]
    NotFinite { name: &'static str, value: f32 },
    #[error("{name}: {} not in {}..{}", Value(*.value), Value(*.min), Value(*.max))]
    OutOfRange { name: &'static str, value: f32, min: f32, max: f32 },
    #[error("{name}: {} is not a whole number", Value(*.value))]
    NotWhole { name: &'static str, value: f32 },
    #[error("{name}: {} must be 0 or 1", Value(*.value))]
    NotBoolean { name: &'static str, value: f32 },
    /// A PARAM_SET whose `param_type` cannot carry a value of the parameter's type (an integer type for a
    /// REAL32 parameter, a 64-bit type for any).
    #[error("{name}: sent as {}, it is {}", param_type_name(*.sent), param_type_name(*.expected))]
    WrongType { name: &'static str, sent: MavParamType, expected: MavParamType },
    /// A PARAM_SET of an integer type whose four bytes are not a value of that type (a byte past the
    /// type's width is not 0).
    #[error("{name}: {bits:#010x} not a bytewise {}", param_type_name(*.sent))]
    NotBytewise { name: &'static str, sent: MavParamType, bits: u32 },
    /// The table's owner could not apply a value the check allows (a plant that refused it).
    #[error("{name}: {reason}")]
    Refused { name: &'static str, reason: String },
}

/// Why a saved parameter text was refused (nothing of it is taken then).
#[derive(Debug, Clone, PartialEq, Error)]
pub enum ParamFileError {
    #[error("line {line}: expected NAME<TAB>VALUE, found `{text}`")]
    Malformed { line: usize, text: String },
    #[error("line {line}: {name}: `{text}` is not a number")]
    BadNumber { line: usize, name: String, text: String },
    #[error("line {line}: {source}")]
    Invalid { line: usize, source: ParamError },
}

/// The first line of [`ParamStore::to_text`].
const TEXT_HEADER: &str =
    "# Parameters that differ from their defaults, one NAME<TAB>VALUE a line (written by the autopilot).";

/// The current value of every parameter of one table, index = table order. The vehicle's store (plain
/// `ParamStore`, over [`PARAMS`]) also maps onto a [`VehicleConfig`].
pub struct ParamStore<G: 'static = ParamGroup, B: 'static = Binding> {
    table: &'static [ParamDef<G, B>],
    values: Vec<f32>,
}

impl<G, B> Clone for ParamStore<G, B> {
    fn clone(&self) -> Self {
        Self { table: self.table, values: self.values.clone() }
    }
}

/// Equal when over the same table with the same values.
impl<G, B> PartialEq for ParamStore<G, B> {
    fn eq(&self, other: &Self) -> bool {
        std::ptr::eq(self.table, other.table) && self.values == other.values
    }
}

/// The values (the table is static and long).
impl<G, B> fmt::Debug for ParamStore<G, B> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.debug_struct("ParamStore").field("values", &self.values).finish_non_exhaustive()
    }
}

impl Default for ParamStore {
    fn default() -> Self {
        Self::defaults()
    }
}

impl ParamStore {
    /// Every parameter of the vehicle at its default.
    #[must_use]
    pub fn defaults() -> Self {
        Self::with_defaults(*PARAMS)
    }

    /// The values `config` holds (rounded to f32; store-only parameters at their defaults). Values are
    /// taken as they are, even out of range: `set` is the gate for new values. Where one parameter sets
    /// several fields (the airframe of the three controllers, PID_VEL_I_NE), the first is read.
    #[must_use]
    pub fn from_config(config: &VehicleConfig) -> Self {
        Self::from_fn(*PARAMS, |_, d| match d.binding {
            Binding::Config { get, .. } => get(config) as f32,
            Binding::StoreOnly => d.default,
        })
    }

    /// Write every parameter onto its config field(s), skipping those whose field already rounds to the
    /// parameter's value (bitwise), so a config keeps its f64 precision where nothing changed. The
    /// config's own validation still applies when it is used (e.g. LOOP_POS_HZ must divide
    /// LOOP_INNER_HZ).
    pub fn apply(&self, config: &mut VehicleConfig) {
        for (d, value) in self.iter() {
            if let Binding::Config { get, set } = d.binding
                && (get(config) as f32).to_bits() != value.to_bits()
            {
                set(config, f64::from(value));
            }
        }
    }

    /// ACO_WEIGHTS_HZ: the rate of the adaptive-weight stream (Hz; 0 = off).
    #[must_use]
    pub fn aco_weights_hz(&self) -> f32 {
        self.get("ACO_WEIGHTS_HZ").unwrap_or(0.0)
    }

    /// SDLOG_MODE: whether the shell writes a ULog for each armed flight and motor test (-1 never, 0 arm to
    /// disarm).
    #[must_use]
    pub fn sdlog_mode(&self) -> i32 {
        self.get("SDLOG_MODE").map_or(0, |v| v as i32)
    }

    /// Whether a ground station may inject failures (SYS_FAILURE_EN 1).
    #[must_use]
    pub fn failure_injection_enabled(&self) -> bool {
        self.get("SYS_FAILURE_EN").is_some_and(|v| v == 1.0)
    }

    /// Whether motor tests are allowed (COM_MOT_TEST_EN 1).
    #[must_use]
    pub fn motor_test_enabled(&self) -> bool {
        self.get("COM_MOT_TEST_EN").is_some_and(|v| v == 1.0)
    }
}

impl<G, B> ParamStore<G, B> {
    /// Every parameter of `table` at its default.
    #[must_use]
    pub fn with_defaults(table: &'static [ParamDef<G, B>]) -> Self {
        Self { table, values: table.iter().map(|d| d.default).collect() }
    }

    /// The values `value(index, def)` gives `table`'s parameters, taken as they are, even out of range
    /// (a state read from elsewhere; `set` is the gate for new values).
    #[must_use]
    pub fn from_fn(table: &'static [ParamDef<G, B>], mut value: impl FnMut(usize, &ParamDef<G, B>) -> f32) -> Self {
        Self { table, values: table.iter().enumerate().map(|(i, d)| value(i, d)).collect() }
    }

    /// The declaration at `index`, if any.
    #[must_use]
    pub fn def(&self, index: usize) -> Option<&'static ParamDef<G, B>> {
        self.table.get(index)
    }

    /// The number of parameters (MAVLink's `param_count`).
    #[must_use]
    pub fn len(&self) -> usize {
        self.values.len()
    }

    /// True only for an empty table.
    #[must_use]
    pub fn is_empty(&self) -> bool {
        self.values.is_empty()
    }

    /// The index of `name` (exact, case-sensitive), if it is a parameter.
    #[must_use]
    pub fn index_of(&self, name: &str) -> Option<usize> {
        self.table.iter().position(|d| d.name == name)
    }

    /// The value of `name`.
    #[must_use]
    pub fn get(&self, name: &str) -> Option<f32> {
        self.index_of(name).and_then(|i| self.get_index(i))
    }

    /// The value at `index`.
    #[must_use]
    pub fn get_index(&self, index: usize) -> Option<f32> {
        self.values.get(index).copied()
    }

    /// Set `name` to `value` after [`ParamDef::check`]; on an error nothing changes.
    ///
    /// # Errors
    /// [`ParamError::Unknown`] for a name not in the table, else the check's error.
    pub fn set(&mut self, name: &str, value: f32) -> Result<(), ParamError> {
        let index = self.index_of(name).ok_or_else(|| ParamError::Unknown { name: name.to_owned() })?;
        self.set_index(index, value)
    }

    /// Set the parameter at `index` to `value` after [`ParamDef::check`]; on an error nothing changes.
    ///
    /// # Errors
    /// [`ParamError::UnknownIndex`] past the table, else the check's error.
    pub fn set_index(&mut self, index: usize, value: f32) -> Result<(), ParamError> {
        let d = self.def(index).ok_or(ParamError::UnknownIndex { index })?;
        d.check(value)?;
        if let Some(slot) = self.values.get_mut(index) {
            *slot = value;
        }
        Ok(())
    }

    /// Every declaration with its current value, in index order.
    pub fn iter(&self) -> impl Iterator<Item = (&'static ParamDef<G, B>, f32)> + '_ {
        self.table.iter().zip(self.values.iter().copied())
    }

    /// The persistence text: a `#` comment, then `NAME<TAB>VALUE` for every parameter whose value differs
    /// (bitwise) from its default, in index order, values printed to parse back bit-exactly.
    #[must_use]
    pub fn to_text(&self) -> String {
        let mut out = String::from(TEXT_HEADER);
        out.push('\n');
        for (d, value) in self.iter().filter(|(d, v)| v.to_bits() != d.default.to_bits()) {
            out.push_str(d.name);
            out.push('\t');
            out.push_str(&Value(value).to_string());
            out.push('\n');
        }
        out
    }

    /// Read a persistence text over `base`: blank lines and `#` comments (whole-line or trailing) are
    /// skipped, every other line is `NAME VALUE` (a tab or spaces between), checked as by [`set`]; names
    /// not in the table are skipped with a warning, a name given twice takes the last value (warned).
    /// Parameters the text does not name keep `base`'s values.
    ///
    /// # Errors
    /// [`ParamFileError`] with the 1-based line number for a malformed line, a value that is not a
    /// number or one [`set`] refuses; nothing of the text is taken then.
    ///
    /// [`set`]: ParamStore::set
    pub fn from_text(text: &str, base: Self) -> Result<(Self, Vec<String>), ParamFileError> {
        let (read, first_error) = Self::read_text(text, base);
        match first_error {
            Some(e) => Err(e),
            None => Ok((read.store, read.warnings)),
        }
    }

    /// Reads a parameter file over `base`: a malformed line, a non-number or a refused value is a warning
    /// (the parameter keeps `base`'s value) and the first of them is returned beside the result.
    fn read_text(text: &str, base: Self) -> (LenientLoad<G, B>, Option<ParamFileError>) {
        let mut first_error = None;
        let mut store = base;
        let mut warnings = Vec::new();
        let mut taken = Vec::new();
        let mut first_line: Vec<Option<usize>> = vec![None; store.len()];
        for (i, raw) in text.lines().enumerate() {
            let line = i + 1;
            let content = raw.find('#').map_or(raw, |hash| &raw[..hash]).trim();
            if content.is_empty() {
                continue;
            }
            let mut fields = content.split_whitespace();
            let parsed = match (fields.next(), fields.next(), fields.next()) {
                (Some(name), Some(value_text), None) => match store.index_of(name) {
                    None => {
                        warnings.push(format!("line {line}: unknown parameter {name} skipped"));
                        continue;
                    }
                    Some(index) => value_text
                        .parse::<f32>()
                        .map_err(|_| ParamFileError::BadNumber {
                            line,
                            name: name.to_owned(),
                            text: value_text.to_owned(),
                        })
                        .and_then(|value| {
                            store.set_index(index, value).map_err(|source| ParamFileError::Invalid { line, source })
                        })
                        .map(|()| (index, name)),
                },
                _ => Err(ParamFileError::Malformed { line, text: raw.trim().to_owned() }),
            };
            match parsed {
                Ok((index, name)) => {
                    taken.push((line, index));
                    if let Some(first) = first_line.get_mut(index).and_then(|slot| slot.replace(line)) {
                        warnings.push(format!("line {line}: {name} also on line {first}; the last value is taken"));
                    }
                }
                Err(e) => {
                    warnings.push(format!("{e}: the default is kept"));
                    first_error.get_or_insert(e);
                }
            }
        }
        (LenientLoad { store, taken, warnings }, first_error)
    }
}

/// A parameter file read leniently ([`ParamStore::from_text_lenient`]): the store, and for each line that
/// was skipped or value that was dropped, a warning naming the line and the parameter.
#[derive(Debug, Clone)]
pub struct LenientLoad<G: 'static = ParamGroup, B: 'static = Binding> {
    pub store: ParamStore<G, B>,
    /// (line, parameter index) of every value taken, in file order.
    pub taken: Vec<(usize, usize)>,
    pub warnings: Vec<String>,
}

impl<G, B> ParamStore<G, B> {
    /// [`Self::from_text`] for a file a person may have edited, or an older version wrote: a line that
    /// cannot be read, an unknown name, a value that is not a number or out of range is skipped with a
    /// warning (the parameter keeps `base`'s value), never an error.
    #[must_use]
    pub fn from_text_lenient(text: &str, base: Self) -> LenientLoad<G, B> {
        Self::read_text(text, base).0
    }
}

/// `docs/params.md`: a title, how it is made, then one table per [`ParamGroup`] (name, MAVLink type,
/// default, min, max, unit, restart, description).
#[must_use]
pub fn markdown() -> String {
    let mut out = String::from("# Parameters\n\n");
    out.push_str(
        "Generated from the parameter table in `autopilot/src/core/params`; do not edit by hand. Regenerate \
         with\n`cargo run -p autopilot --example params_doc` (the unit test `docs_params_md_is_current` fails \
         while this\nfile is stale).\n\n",
    );
    out.push_str(&format!(
        "{} parameters. Type is the MAVLink `param_type` a value travels as, as PX4 sends it: REAL32 (f32) \
         for a real,\nINT32 for an integer or a boolean (0 or 1) in PX4's bytewise encoding: the int32's four \
         bytes stand as they are\nin the float field `param_value` (AUTOPILOT_VERSION declares \
         PARAM_ENCODE_BYTEWISE). A PARAM_SET of an INT32\nparameter may also send REAL32 with a whole value. \
         A parameter marked *yes* under Restart takes effect at the\nnext start; the others apply while \
         running.\n",
        PARAMS.len()
    ));
    for group in ParamGroup::ALL.into_iter().filter(|g| PARAMS.iter().any(|d| d.group == *g)) {
        out.push_str(&format!("\n## {}\n\n{}\n\n", group.title(), group.summary()));
        out.push_str("| Name | Type | Default | Min | Max | Unit | Restart | Description |\n");
        out.push_str("|---|---|---:|---:|---:|---|---|---|\n");
        for d in PARAMS.iter().filter(|d| d.group == group) {
            out.push_str(&format!(
                "| `{}` | {} | {} | {} | {} | {} | {} | {} |\n",
                d.name,
                param_type_name(d.kind.mav_param_type()),
                Value(d.default),
                Value(d.min),
                Value(d.max),
                d.unit,
                if d.restart { "yes" } else { "" },
                d.description,
            ));
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// The checked-in docs, read at compile time (the core does no file I/O).
    const DOCS_PARAMS_MD: &str = include_str!("../../../../docs/params.md");

    /// A value other than the default, in range (whole for integers, 0/1 for booleans).
    fn other_value(d: &ParamDef) -> f32 {
        if d.default != d.max { d.max } else { d.min }
    }

    #[test]
    fn docs_params_md_is_current() {
        assert!(
            DOCS_PARAMS_MD == markdown(),
            "docs/params.md is stale: regenerate it with `cargo run -p autopilot --example params_doc`"
        );
    }

    #[test]
    fn given_the_table_when_checked_then_names_ranges_defaults_and_texts_are_well_formed() {
        let mut names = std::collections::HashSet::new();
        for d in *PARAMS {
            assert!(names.insert(d.name), "{} declared twice", d.name);
            assert!(!d.name.is_empty() && d.name.len() <= 16, "{}: at most 16 characters", d.name);
            assert!(d.name.starts_with(|c: char| c.is_ascii_uppercase()), "{}", d.name);
            assert!(d.name.chars().all(|c| c.is_ascii_uppercase() || c.is_ascii_digit() || c == '_'), "{}", d.name);
            assert!(d.min.is_finite() && d.max.is_finite() && d.min < d.max, "{}: range", d.name);
            assert_eq!(d.check(d.default), Ok(()), "{}: default must pass its own check", d.name);
            assert_eq!(d.check(other_value(d)), Ok(()), "{}", d.name);
            if d.kind == ParamKind::Boolean {
                assert_eq!((d.min, d.max), (0.0, 1.0), "{}", d.name);
            }
            if d.kind != ParamKind::Real {
                assert!(d.min.fract() == 0.0 && d.max.fract() == 0.0, "{}: whole bounds", d.name);
                // Inside ±2^23: every value in range is exact as an f32 and as an i32, and a float sent
                // where a bytewise int32 belongs reads as an int32 outside the range (a positive normal f32
                // is 2^23 or more, a negative one below -2^23), so a mix-up is refused, never misread.
                assert!((-8_388_608.0..8_388_608.0).contains(&d.min), "{}: min within ±2^23", d.name);
                assert!((-8_388_608.0..8_388_608.0).contains(&d.max), "{}: max within ±2^23", d.name);
            }
            assert_eq!(
                d.kind.mav_param_type(),
                if d.kind == ParamKind::Real {
                    MavParamType::MAV_PARAM_TYPE_REAL32
                } else {
                    MavParamType::MAV_PARAM_TYPE_INT32
                },
                "{}",
                d.name
            );
            for text in [d.description, d.unit] {
                assert!(!text.contains('|') && !text.contains('\n'), "{}: `{text}` breaks the docs table", d.name);
            }
            assert!(d.description.ends_with('.'), "{}: description is a sentence", d.name);
        }
        // MAVSDK refuses to work without these two.
        for name in ["MIS_TAKEOFF_ALT", "RTL_RETURN_ALT"] {
            assert!(ParamStore::defaults().get(name).is_some(), "{name}");
        }
        assert!(PARAMS.iter().any(|d| d.name.len() == 16), "the 16-character case is exercised");
    }

    #[test]
    fn given_default_vehicle_config_when_read_then_exactly_the_table_defaults() {
        let from_config = ParamStore::from_config(&VehicleConfig::default());
        let mismatches: Vec<String> = from_config
            .iter()
            .filter(|(d, v)| v.to_bits() != d.default.to_bits())
            .map(|(d, v)| format!("{}: config {v} vs table {}", d.name, d.default))
            .collect();
        assert!(mismatches.is_empty(), "fix the table:\n{}", mismatches.join("\n"));
        assert_eq!(from_config, ParamStore::defaults());
        let mut config = VehicleConfig::default();
        ParamStore::defaults().apply(&mut config);
        assert_eq!(config, VehicleConfig::default(), "applying the defaults keeps the f64 values (5.2 stays 5.2)");
        assert_eq!(config.control.aco.airframe.mass_kg, 5.2);
        assert_eq!(ParamStore::defaults().aco_weights_hz(), 2.0);
    }

    #[test]
    fn given_each_parameter_changed_when_applied_and_read_back_then_exact_and_only_its_own_field() {
        for (i, d) in PARAMS.iter().enumerate() {
            let mut store = ParamStore::defaults();
            store.set_index(i, other_value(d)).expect("in range");
            let mut config = VehicleConfig::default();
            store.apply(&mut config);
            if d.store_only() {
                assert_eq!(config, VehicleConfig::default(), "{}", d.name);
                continue;
            }
            assert_ne!(config, VehicleConfig::default(), "{} maps onto nothing", d.name);
            // Exactly this value comes back, and no other parameter moved (no two share a field).
            assert_eq!(ParamStore::from_config(&config), store, "{}", d.name);
        }
        // Every parameter at once, at f32 values that are not round in decimal.
        let mut store = ParamStore::defaults();
        for (i, d) in PARAMS.iter().enumerate() {
            let v = if d.kind == ParamKind::Real { d.min + (d.max - d.min) / 3.0 } else { other_value(d) };
            store.set_index(i, v).expect("in range");
        }
        let mut config = VehicleConfig::default();
        store.apply(&mut config);
        let mut back = ParamStore::from_config(&config);
        // The store-only values (ACO_WEIGHTS_HZ, SDLOG_MODE) have no config field to come back from.
        for (i, d) in PARAMS.iter().enumerate() {
            if d.store_only() {
                back.set_index(i, store.get_index(i).expect("a value")).expect("store-only value");
            }
        }
        assert_eq!(back, store);
        let mut again = config.clone();
        ParamStore::from_config(&config).apply(&mut again);
        assert_eq!(again, config, "config -> store -> config is exact for f32-representable values");
    }

    #[test]
    fn given_the_airframe_when_set_then_all_three_controllers_get_it() {
        let mut store = ParamStore::defaults();
        store.set("AF_MASS", 6.5).expect("in range");
        store.set("AF_IZZ", 0.25).expect("in range");
        let mut config = VehicleConfig::default();
        store.apply(&mut config);
        let c = &config.control;
        assert_eq!([c.aco.airframe, c.mrac.airframe], [c.pid.airframe; 2]);
        assert_eq!((c.pid.airframe.mass_kg, c.pid.airframe.inertia_kgm2[2]), (6.5, 0.25));
        store.set("PID_VEL_I_NE", 0.75).expect("in range");
        store.apply(&mut config);
        assert_eq!(config.control.pid.kvi_vel_per_s2, [0.75, 0.75, 2.0]);
        assert_eq!(config.control.rates, crate::core::control::LoopRates::default());
    }

    #[test]
    fn given_bad_values_when_set_then_refused_with_short_reasons_and_nothing_changes() {
        let mut store = ParamStore::defaults();
        let cases: [(&str, f32, &str); 8] = [
            ("MPC_XY_CRUISE", 99.0, "MPC_XY_CRUISE: 99 not in 0.1..5"),
            ("MPC_XY_CRUISE", f32::NAN, "MPC_XY_CRUISE: NaN is not finite"),
            ("RTL_RETURN_ALT", f32::INFINITY, "RTL_RETURN_ALT: inf is not finite"),
            ("COM_DISARM_PRFLT", -3.5, "COM_DISARM_PRFLT: -3.5 not in -1..60"),
            ("LOOP_INNER_HZ", 250.5, "LOOP_INNER_HZ: 250.5 is not a whole number"),
            ("ACO_ADAPT_EN", 0.5, "ACO_ADAPT_EN: 0.5 must be 0 or 1"),
            ("AF_MASS", 3.0e30, "AF_MASS: 3e30 not in 0.1..100"),
            ("NO_SUCH_PARAM", 1.0, "unknown parameter NO_SUCH_PARAM"),
        ];
        for (name, value, text) in cases {
            let err = store.set(name, value).expect_err(name);
            assert_eq!(err.to_string(), text);
            assert!(err.to_string().len() <= 50, "{err}");
            assert_eq!(store, ParamStore::defaults(), "{name}: nothing changes");
        }
        assert_eq!(store.set_index(store.len(), 1.0), Err(ParamError::UnknownIndex { index: store.len() }));
        // Every range error of the table fits a STATUSTEXT, even for awkward values, and so do the type
        // refusals with the longest type names.
        for d in *PARAMS {
            let e = d.check(-(d.max.abs() + 1.0) * 1.000_001_2).expect_err(d.name).to_string();
            assert!(e.len() <= 50, "{e}");
            let (long, wide) = (MavParamType::MAV_PARAM_TYPE_UINT64, MavParamType::MAV_PARAM_TYPE_UINT16);
            let wrong = ParamError::WrongType { name: d.name, sent: long, expected: d.kind.mav_param_type() };
            let bytes = ParamError::NotBytewise { name: d.name, sent: wide, bits: u32::MAX };
            for e in [wrong.to_string(), bytes.to_string()] {
                assert!(e.len() <= 50, "{e}");
            }
        }
        let wrong = ParamError::WrongType {
            name: "MPC_XY_CRUISE",
            sent: MavParamType::MAV_PARAM_TYPE_INT32,
            expected: MavParamType::MAV_PARAM_TYPE_REAL32,
        };
        assert_eq!(wrong.to_string(), "MPC_XY_CRUISE: sent as INT32, it is REAL32");
        let bytes = ParamError::NotBytewise {
            name: "NAV_DLL_ACT",
            sent: MavParamType::MAV_PARAM_TYPE_UINT8,
            bits: 0x4000_0000,
        };
        assert_eq!(bytes.to_string(), "NAV_DLL_ACT: 0x40000000 not a bytewise UINT8");
        assert_eq!(store.set("MPC_XY_CRUISE", 5.0), Ok(()), "the bound itself is in range");
        assert_eq!(store.set("MPC_XY_CRUISE", 5.0), Ok(()), "setting the current value is fine");
        assert_eq!(store.get("MPC_XY_CRUISE"), Some(5.0));
    }

    #[test]
    fn given_changed_values_when_written_and_read_back_then_bit_exact_and_only_changes_listed() {
        let mut store = ParamStore::defaults();
        store.set("MPC_XY_CRUISE", 0.1 + f32::EPSILON).expect("in range");
        store.set("AF_IXX", 0.000_123_456_79).expect("in range");
        store.set("ACO_ADAPT_EN", 0.0).expect("in range");
        store.set("LOOP_INNER_HZ", 1000.0).expect("in range");
        store.set("COM_DISARM_LAND", -1.0).expect("in range");
        store.set("ACO_WEIGHTS_HZ", 0.0).expect("in range");
        store.set("ACO_POS_P", 0.6667).expect("the default, not listed");
        let text = store.to_text();
        assert_eq!(text.lines().filter(|l| !l.starts_with('#')).count(), 6, "{text}");
        assert!(text.contains("LOOP_INNER_HZ\t1000\n") && text.contains("ACO_ADAPT_EN\t0\n"), "{text}");
        let (back, warnings) = ParamStore::from_text(&text, ParamStore::defaults()).expect("parses");
        assert!(warnings.is_empty(), "{warnings:?}");
        assert_eq!(back, store);
        assert_eq!(ParamStore::defaults().to_text(), format!("{TEXT_HEADER}\n"));
    }

    #[test]
    fn given_comments_blank_lines_unknown_and_repeated_names_when_read_then_skipped_or_warned() {
        let text = "# saved\n\nMPC_XY_CRUISE 2.5   # trailing comment\n  OLD_PARAM\t3\nMPC_XY_CRUISE\t3\r\n";
        let base = ParamStore::defaults();
        let (store, warnings) = ParamStore::from_text(text, base).expect("parses");
        assert_eq!(store.get("MPC_XY_CRUISE"), Some(3.0));
        assert_eq!(
            warnings,
            [
                "line 4: unknown parameter OLD_PARAM skipped",
                "line 5: MPC_XY_CRUISE also on line 3; the last value is taken"
            ]
        );
        // Parameters the text does not name keep the base's values.
        let mut base = ParamStore::defaults();
        base.set("AF_MASS", 7.0).expect("in range");
        let (store, _) = ParamStore::from_text("MPC_XY_CRUISE\t2\n", base).expect("parses");
        assert_eq!((store.get("AF_MASS"), store.get("MPC_XY_CRUISE")), (Some(7.0), Some(2.0)));
    }

    #[test]
    fn given_a_bad_line_when_read_then_error_with_its_line_number_and_nothing_taken() {
        let good = "MPC_XY_CRUISE\t2\n";
        let cases = [
            ("MPC_XY_CRUISE\n", "line 2: expected NAME<TAB>VALUE, found `MPC_XY_CRUISE`"),
            ("MPC_XY_CRUISE 2 3\n", "line 2: expected NAME<TAB>VALUE, found `MPC_XY_CRUISE 2 3`"),
            ("MPC_XY_CRUISE\tfast\n", "line 2: MPC_XY_CRUISE: `fast` is not a number"),
            ("MPC_XY_CRUISE\t99\n", "line 2: MPC_XY_CRUISE: 99 not in 0.1..5"),
            ("RTL_RETURN_ALT\tNaN\n", "line 2: RTL_RETURN_ALT: NaN is not finite"),
        ];
        for (bad, text) in cases {
            let err = ParamStore::from_text(&format!("{good}{bad}"), ParamStore::defaults()).expect_err(bad);
            assert_eq!(err.to_string(), text);
        }
        assert!(matches!(
            ParamStore::from_text("LOOP_POS_HZ\t50.5", ParamStore::defaults()),
            Err(ParamFileError::Invalid { line: 1, source: ParamError::NotWhole { .. } })
        ));
    }

    #[test]
    fn given_the_markdown_when_generated_then_every_parameter_in_its_groups_table() {
        let md = markdown();
        assert!(md.starts_with("# Parameters\n") && md.contains("autopilot/src/core/params"));
        assert!(md.contains("cargo run -p autopilot --example params_doc"));
        for group in ParamGroup::ALL {
            let present = PARAMS.iter().any(|d| d.group == group);
            assert_eq!(md.contains(&format!("## {}\n", group.title())), present, "{group:?}");
            // Only the guests' group may be empty (no controller with parameters registered).
            assert!(present || group == ParamGroup::Controllers, "{group:?} is empty");
        }
        for d in *PARAMS {
            assert_eq!(md.matches(&format!("| `{}` |", d.name)).count(), 1, "{}", d.name);
        }
        assert!(md.contains("| `LOOP_INNER_HZ` | INT32 | 500 | 50 | 2000 | Hz | yes |"));
        assert!(md.contains("| `NAV_DLL_ACT` | INT32 | 0 | 0 | 5 |"));
        assert!(md.contains("| `ACO_ADAPT_EN` | INT32 | 1 | 0 | 1 | 0/1 |"));
        assert!(md.contains("| `COM_DL_LOSS_T` | REAL32 | 10 | 5 | 300 | s |"));
    }

    proptest! {
        #[test]
        fn given_any_finite_f32_when_formatted_then_parses_back_bit_exactly(bits in any::<u32>()) {
            let x = f32::from_bits(bits);
            prop_assume!(x.is_finite());
            let text = Value(x).to_string();
            let back: f32 = text.parse().expect("a number");
            prop_assert_eq!(back.to_bits(), x.to_bits(), "{}", text);
            prop_assert!(text.len() <= 16, "{}", text);
        }

        #[test]
        fn given_any_in_range_value_when_saved_and_loaded_then_bit_exact(index in 0..PARAMS.len(), t in 0.0f32..=1.0) {
            let d = &PARAMS[index];
            let mut v = d.min + t * (d.max - d.min);
            if d.kind != ParamKind::Real {
                v = v.round();
            }
            let v = v.clamp(d.min, d.max);
            let mut store = ParamStore::defaults();
            store.set_index(index, v).expect("in range");
            let (back, warnings) = ParamStore::from_text(&store.to_text(), ParamStore::defaults()).expect("parses");
            prop_assert!(warnings.is_empty());
            prop_assert_eq!(back, store);
        }
    }
}
