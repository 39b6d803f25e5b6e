//! The gain vector under tuning: each gain's field, axes, bounds and scale (unit coordinates to values,
//! rounded to f32), its parsing and the parameters that carry it; gain values set into a controller
//! configuration, written as a `[controller]` block or a parameter file, and gain sets read back from one.

use autopilot::core::config::VehicleConfig;
use autopilot::core::control::{ControllerConfig, ControllerKind, LoopRates, registry};
use autopilot::core::params::{Binding, PARAMS, ParamStore};
use serde_json::Value;

use super::spec::{GainFile, Scale, Tune, TuneError, invalid};
use crate::scenario::Scenario;

/// One gain under tuning.
#[derive(Debug, Clone, PartialEq)]
pub struct Gain {
    /// As written: `aco.kp_pos_per_s`, or with its axes `pid.k_rate_per_s[0,1]`.
    pub label: String,
    /// The `[controller]` path: `["aco", "kp_pos_per_s"]`.
    pub path: Vec<String>,
    /// The elements of an array field that take the value (`None`: a number field).
    pub axes: Option<Vec<usize>>,
    pub bounds: [f64; 2],
    pub scale: Scale,
    /// The start of the search: the spec's `start`, else the autopilot's default.
    pub start: f64,
    /// The autopilot parameters that carry this gain (empty: none does).
    pub params: Vec<&'static str>,
}

impl Gain {
    /// The gain at unit coordinate `x` in `[0, 1]`, rounded to f32.
    #[must_use]
    pub fn value_at(&self, x: f64) -> f64 {
        let [lo, hi] = self.bounds;
        let v = match self.scale {
            Scale::Linear => lo + x * (hi - lo),
            Scale::Log => (lo.ln() + x * (hi.ln() - lo.ln())).exp(),
        };
        f64::from(v.clamp(lo, hi) as f32)
    }

    /// The unit coordinate of value `v` (the inverse of [`Gain::value_at`] before rounding).
    #[must_use]
    pub fn unit_of(&self, v: f64) -> f64 {
        let [lo, hi] = self.bounds;
        match self.scale {
            Scale::Linear => (v - lo) / (hi - lo),
            Scale::Log => (v.ln() - lo.ln()) / (hi.ln() - lo.ln()),
        }
    }
}

/// The controller's `[controller]` table name.
#[must_use]
pub fn table_name(kind: ControllerKind) -> &'static str {
    kind.table()
}

/// `config` with `kind`'s table filled in with its defaults where it has none (a controller outside the
/// built-in three keeps its table in [`ControllerConfig::tables`], empty until something is set), so that
/// every field of the controller can be found, checked and tuned by path.
#[must_use]
pub fn with_table_defaults(config: &ControllerConfig, kind: ControllerKind) -> ControllerConfig {
    let mut out = config.clone();
    if let Some(table) = out.tables.get_mut(kind.table()) {
        for (key, value) in kind.ty().default_table() {
            table.entry(key).or_insert(value);
        }
    } else {
        // A typed section (the built-in controllers') is always written out; a table only when set.
        let written = serde_json::to_value(&out).ok().is_some_and(|v| v.get(kind.table()).is_some());
        if !written {
            out.tables.insert(kind.table().to_owned(), kind.ty().default_table());
        }
    }
    out
}

/// The value at `path` of a JSON tree.
fn at<'a>(root: &'a Value, path: &[String]) -> Option<&'a Value> {
    path.iter().try_fold(root, |v, key| v.get(key))
}

fn at_mut<'a>(root: &'a mut Value, path: &[String]) -> Option<&'a mut Value> {
    path.iter().try_fold(root, |v, key| v.get_mut(key))
}

/// Sets a gain's value in a configuration's JSON tree.
fn set_gain(root: &mut Value, gain: &Gain, value: f64) -> Result<(), String> {
    let field = at_mut(root, &gain.path).ok_or_else(|| format!("{}: no such field", gain.label))?;
    match (&gain.axes, field) {
        (None, field @ Value::Number(_)) => *field = Value::from(value),
        (Some(axes), Value::Array(items)) => {
            for &a in axes {
                let item = items.get_mut(a).ok_or_else(|| format!("{}: no axis {a}", gain.label))?;
                *item = Value::from(value);
            }
        }
        _ => return Err(format!("{}: not a number field", gain.label)),
    }
    Ok(())
}

/// `config` with `values` (one per gain) set.
///
/// # Errors
/// A gain whose field is missing (not for a validated spec).
pub fn with_gains(config: &ControllerConfig, gains: &[Gain], values: &[f64]) -> Result<ControllerConfig, String> {
    let mut tree = serde_json::to_value(config).map_err(|e| e.to_string())?;
    for (gain, &v) in gains.iter().zip(values) {
        set_gain(&mut tree, gain, v)?;
    }
    serde_json::from_value(tree).map_err(|e| e.to_string())
}

impl Tune {
    /// The start point's gains.
    #[must_use]
    pub fn start(&self) -> Vec<f64> {
        self.gains.iter().map(|g| g.start).collect()
    }

    /// The gains of a unit point; the start point's own coordinates give the start values exactly.
    #[must_use]
    pub fn gains_at(&self, x: &[f64]) -> Vec<f64> {
        self.gains
            .iter()
            .zip(x)
            .map(|(g, &xi)| if xi.to_bits() == g.unit_of(g.start).to_bits() { g.start } else { g.value_at(xi) })
            .collect()
    }

    /// The `[controller]` block of gain values: the controller's table with every tuned field (an array
    /// field whole, its untuned axes at the autopilot's defaults), as TOML.
    ///
    /// # Errors
    /// Values that do not make a configuration (not for values from [`Tune::run`]).
    pub fn controller_block(&self, values: &[f64]) -> Result<String, String> {
        let config = with_gains(&self.base, &self.gains, values)?;
        let tree = serde_json::to_value(&config).map_err(|e| e.to_string())?;
        // The spec's [base] first, so the block flies the controller that was tuned.
        let mut table = match serde_json::from_value::<toml::Value>(self.base_overrides.clone()) {
            Ok(toml::Value::Table(t)) => t,
            Ok(_) | Err(_) => toml::map::Map::new(),
        };
        for gain in &self.gains {
            let Some(value) = at(&tree, &gain.path) else { continue };
            let value: toml::Value = serde_json::from_value(value.clone()).map_err(|e| e.to_string())?;
            let mut node = &mut table;
            for key in &gain.path[..gain.path.len() - 1] {
                let entry = node.entry(key.clone()).or_insert_with(|| toml::Value::Table(toml::map::Map::new()));
                let toml::Value::Table(inner) = entry else { return Err(format!("{}: not a table", gain.label)) };
                node = inner;
            }
            node.insert(gain.path[gain.path.len() - 1].clone(), value);
        }
        let mut root = toml::map::Map::new();
        root.insert("controller".into(), toml::Value::Table(table));
        toml::to_string(&toml::Value::Table(root)).map_err(|e| e.to_string())
    }

    /// The autopilot parameter file of gain values: `NAME<TAB>VALUE` for every parameter that differs from
    /// its default (the autopilot's `params.txt` format), after a comment naming any gain no parameter
    /// carries.
    ///
    /// # Errors
    /// As [`Tune::controller_block`].
    pub fn param_file(&self, values: &[f64], header: &str) -> Result<String, String> {
        let control = with_gains(&self.base, &self.gains, values)?;
        let vehicle = VehicleConfig { controller: self.controller, control, ..VehicleConfig::default() };
        let store = ParamStore::from_config(&vehicle);
        let mut out = String::new();
        for line in header.lines() {
            out.push_str("# ");
            out.push_str(line);
            out.push('\n');
        }
        let missing: Vec<&str> = self.gains.iter().filter(|g| g.params.is_empty()).map(|g| g.label.as_str()).collect();
        if !missing.is_empty() {
            out.push_str(&format!(
                "# No parameter carries {}: set them in the [controller] block (controller.toml).\n",
                missing.join(", ")
            ));
        }
        out.push_str(&store.to_text());
        Ok(out)
    }
}

pub(super) fn parse_gain(
    g: &GainFile,
    controller: ControllerKind,
    rates: LoopRates,
    base: &ControllerConfig,
) -> Result<Gain, TuneError> {
    let table = table_name(controller);
    let label = match &g.axes {
        Some(axes) => {
            format!("{}[{}]", g.name, axes.iter().map(ToString::to_string).collect::<Vec<_>>().join(","))
        }
        None => g.name.clone(),
    };
    let path: Vec<String> = g.name.split('.').map(str::to_owned).collect();
    if path.first().map(String::as_str) != Some(table) {
        return invalid(format!(
            "gain `{}`: a {controller} gain is under `{table}.` (as in the scenario's [controller.{table}])",
            g.name
        ));
    }
    let defaults = serde_json::to_value(base).map_err(|e| TuneError::Invalid(e.to_string()))?;
    let default = match (at(&defaults, &path), &g.axes) {
        (Some(Value::Number(n)), None) => n.as_f64(),
        (Some(Value::Array(items)), Some(axes)) => {
            if axes.is_empty() {
                return invalid(format!("gain `{label}`: axes must name at least one element"));
            }
            if let Some(a) = axes.iter().find(|&&a| a >= items.len()) {
                return invalid(format!("gain `{label}`: axis {a} is out of 0..{}", items.len()));
            }
            items[axes[0]].as_f64()
        }
        (Some(Value::Array(items)), None) => {
            return invalid(format!(
                "gain `{}` is an array of {}: say which elements take the value, e.g. axes = [0, 1]",
                g.name,
                items.len()
            ));
        }
        (Some(Value::Number(_)), Some(_)) => {
            return invalid(format!("gain `{}` is a number, not an array: drop `axes`", g.name));
        }
        (Some(_), _) => None,
        (None, _) => {
            let fields = at(&defaults, &path[..1]).and_then(Value::as_object).map(|o| {
                o.iter().filter(|(_, v)| v.is_number() || v.is_array()).map(|(k, _)| k.as_str()).collect::<Vec<_>>()
            });
            return invalid(format!(
                "unknown gain `{}` (the {table} fields: {})",
                g.name,
                fields.unwrap_or_default().join(", ")
            ));
        }
    };
    let Some(default) = default else {
        return invalid(format!("gain `{}` is not a number field", g.name));
    };
    let [lo, hi] = g.bounds;
    if !(lo.is_finite() && hi.is_finite() && lo < hi) {
        return invalid(format!("gain `{label}`: bounds {:?} must be finite and ascending", g.bounds));
    }
    if g.scale == Scale::Log && lo <= 0.0 {
        return invalid(format!("gain `{label}`: a log scale needs bounds > 0, got {:?}", g.bounds));
    }
    let start = g.start.unwrap_or(default);
    if !(lo..=hi).contains(&start) {
        return invalid(format!(
            "gain `{label}`: the start {start}{} is outside its bounds {:?}",
            if g.start.is_some() { "" } else { " (the autopilot's default, or the spec's [base])" },
            g.bounds
        ));
    }
    let mut gain = Gain {
        label: label.clone(),
        path,
        axes: g.axes.clone(),
        bounds: g.bounds,
        scale: g.scale,
        start,
        params: vec![],
    };
    // Every value the search can take must make a configuration the controller accepts.
    for v in [lo, hi, start] {
        let mut config = with_gains(base, std::slice::from_ref(&gain), &[v]).map_err(TuneError::Invalid)?;
        config.rates = rates;
        if let Err(e) = config.validate() {
            return invalid(format!("gain `{label}` = {v} (within its bounds) makes no controller: {e}"));
        }
    }
    gain.params = carrying_params(&gain)?;
    Ok(gain)
}

/// The parameters that carry a gain: those whose value moves when the gain does; each must take every
/// value within the gain's bounds.
fn carrying_params(gain: &Gain) -> Result<Vec<&'static str>, TuneError> {
    let base = VehicleConfig::default();
    let [lo, hi] = gain.bounds;
    // A value other than the start, within the bounds, to see which parameters move with the gain.
    let probe = if gain.start < hi { 0.5 * (gain.start + hi) } else { 0.5 * (lo + gain.start) };
    let start = match gain.path.first().and_then(|t| registry::by_table(t)) {
        Some(kind) => with_table_defaults(&base.control, kind),
        None => base.control.clone(),
    };
    let control = with_gains(&start, std::slice::from_ref(gain), &[probe]).map_err(TuneError::Invalid)?;
    let moved = VehicleConfig { control, ..base.clone() };
    let mut names = Vec::new();
    for d in *PARAMS {
        let Binding::Config { get, .. } = d.binding else { continue };
        if get(&base).to_bits() == get(&moved).to_bits() {
            continue;
        }
        if (lo as f32) < d.min || (hi as f32) > d.max {
            return invalid(format!(
                "gain `{}`: bounds {:?} leave the range of its parameter {} [{}, {}]",
                gain.label, gain.bounds, d.name, d.min, d.max
            ));
        }
        names.push(d.name);
    }
    Ok(names)
}

/// One set of gains to fly: the controller and its configuration overrides (a JSON tree merged over each
/// scenario's `[controller]`).
#[derive(Debug, Clone, PartialEq)]
pub struct GainSet {
    pub label: String,
    pub controller: ControllerKind,
    /// The `[controller]` overrides as a JSON object (`{"aco": {"kp_pos_per_s": 0.8}}`).
    pub overrides: Value,
}

impl GainSet {
    /// The gains of a tuned candidate as overrides, over the spec's `[base]`.
    pub(super) fn from_config(
        controller: ControllerKind,
        config: &ControllerConfig,
        gains: &[Gain],
        base: &Value,
    ) -> Result<Self, String> {
        let tree = serde_json::to_value(config).map_err(|e| e.to_string())?;
        let mut overrides = base.clone();
        for gain in gains {
            let value = at(&tree, &gain.path).cloned().ok_or_else(|| format!("{}: no such field", gain.label))?;
            let mut node = &mut overrides;
            for key in &gain.path[..gain.path.len() - 1] {
                node = node
                    .as_object_mut()
                    .ok_or("not a table")?
                    .entry(key.clone())
                    .or_insert_with(|| Value::Object(serde_json::Map::new()));
            }
            node.as_object_mut().ok_or("not a table")?.insert(gain.path[gain.path.len() - 1].clone(), value);
        }
        Ok(Self { label: String::new(), controller, overrides })
    }

    /// The autopilot's defaults of `controller`.
    #[must_use]
    pub fn defaults(controller: ControllerKind) -> Self {
        Self { label: format!("{controller} (defaults)"), controller, overrides: Value::Object(serde_json::Map::new()) }
    }

    /// A gain file: a `[controller]` block with exactly one controller's table (`aco`, `mrac` for CA, or
    /// `pid`), whose keys must all be fields of that controller's configuration.
    ///
    /// # Errors
    /// An unreadable or malformed file, none or several controller tables, or an unknown key (named).
    pub fn from_toml(text: &str, label: &str) -> Result<Self, TuneError> {
        let err = |message: String| TuneError::GainFile { path: label.to_owned(), message };
        let value: toml::Value = toml::from_str(text).map_err(|e| err(e.to_string()))?;
        let json: Value = serde_json::to_value(&value).map_err(|e| err(e.to_string()))?;
        let root = json.as_object().ok_or_else(|| err("not a table".into()))?;
        if let Some(key) = root.keys().find(|k| *k != "controller") {
            return Err(err(format!("unknown key `{key}`: a gain file holds one [controller] block")));
        }
        let block =
            root.get("controller").and_then(Value::as_object).ok_or_else(|| err("no [controller] block".into()))?;
        let all = registry::all();
        let kinds: Vec<ControllerKind> = all.iter().copied().filter(|k| block.contains_key(table_name(*k))).collect();
        let [controller] = kinds[..] else {
            let tables: Vec<String> = all.iter().map(|k| format!("[controller.{}] ({k})", k.table())).collect();
            return Err(err(format!("the [controller] block must hold exactly one of {}", tables.join(", "))));
        };
        let defaults = serde_json::to_value(with_table_defaults(&ControllerConfig::default(), controller))
            .map_err(|e| err(e.to_string()))?;
        check_known(&Value::Object(block.clone()), &defaults, "controller").map_err(err)?;
        let config = merge(&defaults, &Value::Object(block.clone()));
        let config: ControllerConfig = serde_json::from_value(config).map_err(|e| err(e.to_string()))?;
        config.validate().map_err(|e| err(e.to_string()))?;
        Ok(Self { label: label.to_owned(), controller, overrides: Value::Object(block.clone()) })
    }

    /// The configuration of a scenario's run: its `[controller]` with these overrides and `rates`.
    ///
    /// # Errors
    /// Overrides that make no configuration the controller accepts.
    pub fn config(&self, scenario: &Scenario, rates: LoopRates) -> Result<ControllerConfig, String> {
        let base = serde_json::to_value(&scenario.controller).map_err(|e| e.to_string())?;
        let mut config: ControllerConfig =
            serde_json::from_value(merge(&base, &self.overrides)).map_err(|e| e.to_string())?;
        config.rates = rates;
        config.validate().map_err(|e| e.to_string())?;
        Ok(config)
    }
}

/// Every key of `value` must be in `known` (recursively into tables), else the error names its path.
pub(super) fn check_known(value: &Value, known: &Value, path: &str) -> Result<(), String> {
    if let (Some(v), Some(k)) = (value.as_object(), known.as_object()) {
        for (key, inner) in v {
            let Some(known_inner) = k.get(key) else {
                return Err(format!("unknown key `{path}.{key}`"));
            };
            check_known(inner, known_inner, &format!("{path}.{key}"))?;
        }
    }
    Ok(())
}

/// `over` merged into `base`: tables key by key, anything else replaced.
pub(super) fn merge(base: &Value, over: &Value) -> Value {
    match (base, over) {
        (Value::Object(b), Value::Object(o)) => {
            let mut out = b.clone();
            for (k, v) in o {
                let merged = out.get(k).map_or_else(|| v.clone(), |bv| merge(bv, v));
                out.insert(k.clone(), merged);
            }
            Value::Object(out)
        }
        (_, o) => o.clone(),
    }
}
