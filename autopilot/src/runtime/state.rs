//! The state directory at start and at `--wipe`: what an earlier run left (the parameters, the mission,
//! the geofence and the rally points) loaded leniently (a value it cannot use falls back to its
//! default, a file it cannot read or parse is moved aside), the start-up line that says what was
//! restored, and the files a wipe removes. Saving is [`super::persist`]'s.

use crate::core::mavlink::common::MavCmd;
use crate::core::mission::Mission;
use crate::core::params::ParamStore;
use crate::core::plan::geofence::{FENCE_COMMANDS, Fence, Rally};
use crate::runtime::persist::{self, PersistError, Persister};

/// What an earlier run left in the state directory, and where to save: the parameters (applied over the
/// configuration when the vehicle is built) and the mission.
#[derive(Debug, Default)]
pub struct Persisted {
    pub params: Option<ParamStore>,
    pub mission: Option<Mission>,
    pub fence: Option<Fence>,
    pub rally: Option<Rally>,
    /// Where parameter and mission changes are saved; `None`: not saved.
    pub persister: Option<Persister>,
}

/// The parameter file in the state directory.
pub const PARAMS_FILE: &str = "params.txt";
/// The mission file in the state directory (QGC WPL 110).
pub const MISSION_FILE: &str = "mission.waypoints";
/// The geofence file in the state directory (QGC WPL 110, fence commands).
pub const FENCE_FILE: &str = "fence.waypoints";
/// The rally-point file in the state directory (QGC WPL 110, NAV_RALLY_POINT).
pub const RALLY_FILE: &str = "rally.waypoints";

/// What an earlier run left in `dir` (parameters over `vehicle`'s, the mission), and the saver. A state
/// file never stops the autopilot from starting (as PX4 starts on defaults): a parameter line that cannot
/// be read, or a value out of range or that makes the configuration unusable with the values before it
/// (loop rates that do not divide), falls back to its default with a warning naming the file, the line
/// and the parameter; a file that cannot be read or parsed at all is moved aside (`NAME.corrupt-<time>`)
/// with a warning, and the vehicle starts without it.
///
/// # Errors
/// The state directory's own I/O error (it cannot be created).
pub fn load_state(
    dir: &std::path::Path,
    vehicle: &crate::core::config::VehicleConfig,
) -> Result<Persisted, PersistError> {
    let persister = Persister::start(dir)?;
    let aside = |name: &str, why: &dyn std::fmt::Display| match persist::move_aside(dir, name) {
        Ok(to) => {
            tracing::warn!(file = %dir.join(name).display(), moved_to = %to.display(), "{why}: moved aside, starting without it")
        }
        Err(e) => tracing::warn!(file = %dir.join(name).display(), "{why}; {e}: starting without it"),
    };
    let params = match persist::load(dir, PARAMS_FILE) {
        Ok(Some(text)) => {
            let file = dir.join(PARAMS_FILE);
            let base = ParamStore::from_config(vehicle);
            let loaded = ParamStore::from_text_lenient(&text, base.clone());
            for w in &loaded.warnings {
                tracing::warn!(file = %file.display(), "{w}");
            }
            // Replayed in file order over the defaults: a value that makes the configuration unusable with
            // the ones before it keeps its default.
            let mut store = base.clone();
            for &(line, index) in &loaded.taken {
                let (Some(value), Some(default)) = (loaded.store.get_index(index), base.get_index(index)) else {
                    continue;
                };
                if store.set_index(index, value).is_err() {
                    continue;
                }
                let mut config = vehicle.clone();
                store.apply(&mut config);
                if let Err(e) = config.validate() {
                    let _ = store.set_index(index, default);
                    let name = store.def(index).map_or("?", |d| d.name);
                    tracing::warn!(file = %file.display(), "line {line}: {name} = {value}: {e}: the default {default} is used");
                }
            }
            Some(store)
        }
        Ok(None) => None,
        Err(e) => {
            aside(PARAMS_FILE, &e);
            None
        }
    };
    let items = |text: &str, command_of: fn(u32) -> Option<MavCmd>| {
        crate::core::mission::items_from_wpl(text, command_of).map_err(|e| e.to_string())
    };
    let mission = load_plan(dir, MISSION_FILE, &aside, |text| {
        crate::core::mission::Mission::from_wpl(text).map_err(|e| e.to_string())
    });
    let fence = load_plan(dir, FENCE_FILE, &aside, |text| {
        Fence::new(items(text, |n| FENCE_COMMANDS.into_iter().find(|c| *c as u32 == n))?).map_err(|e| e.to_string())
    });
    let rally = load_plan(dir, RALLY_FILE, &aside, |text| {
        let rally_point = |n| {
            let point = MavCmd::MAV_CMD_NAV_RALLY_POINT;
            (n == point as u32).then_some(point)
        };
        Rally::new(items(text, rally_point)?).map_err(|e| e.to_string())
    });
    let persisted = Persisted { params, mission, fence, rally, persister: Some(persister) };
    tracing::info!("{}", RestoredState::of(&persisted, vehicle).describe(dir));
    Ok(persisted)
}

/// The files of the state directory that `--wipe` removes: everything the vehicle restores at start but
/// the signing key (a wipe must not quietly turn signing off; delete `signing.key` for that).
pub const STATE_FILES: [&str; 4] = [PARAMS_FILE, MISSION_FILE, FENCE_FILE, RALLY_FILE];

/// Removes the state files of `dir` ([`STATE_FILES`]) so the vehicle starts on defaults, as ArduPilot's
/// `-w` does; returns the files that were there.
///
/// # Errors
/// [`PersistError::Write`] naming a file that could not be removed.
pub fn wipe_state(dir: &std::path::Path) -> Result<Vec<std::path::PathBuf>, PersistError> {
    persist::wipe(dir, &STATE_FILES)
}

/// What a start restored from the state directory, for the start-up line that says so.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
struct RestoredState {
    /// Parameters whose restored value differs from the configuration's default.
    changed_params: Vec<&'static str>,
    mission_items: usize,
    fence_items: usize,
    rally_points: usize,
}

impl RestoredState {
    /// What `persisted` holds, parameters compared with `vehicle`'s defaults.
    fn of(persisted: &Persisted, vehicle: &crate::core::config::VehicleConfig) -> Self {
        let defaults = crate::core::params::ParamStore::from_config(vehicle);
        let changed_params = persisted.params.as_ref().map_or_else(Vec::new, |store| {
            store
                .iter()
                .zip(defaults.iter())
                .filter(|((_, value), (_, default))| value.to_bits() != default.to_bits())
                .map(|((def, _), _)| def.name)
                .collect()
        });
        Self {
            changed_params,
            mission_items: persisted.mission.as_ref().map_or(0, crate::core::mission::Mission::len),
            fence_items: persisted.fence.as_ref().map_or(0, |f| f.items().len()),
            rally_points: persisted.rally.as_ref().map_or(0, |r| r.items().len()),
        }
    }

    /// "state restored from DIR: 2 parameters differ from default (A, B), mission of 5 items, ... (`--wipe`
    /// starts clean)", or "no state to restore in DIR (a fresh start)".
    fn describe(&self, dir: &std::path::Path) -> String {
        let mut parts = Vec::new();
        match self.changed_params.as_slice() {
            [] => {}
            names => {
                let shown: Vec<&str> = names.iter().take(8).copied().collect();
                let more = if names.len() > shown.len() {
                    format!(", and {} more", names.len() - shown.len())
                } else {
                    String::new()
                };
                let noun = if names.len() == 1 { "parameter differs" } else { "parameters differ" };
                parts.push(format!("{} {noun} from default ({}{more})", names.len(), shown.join(", ")));
            }
        }
        let plural = |n: usize, one: &str, many: &str| if n == 1 { one.to_owned() } else { format!("{n} {many}") };
        if self.mission_items > 0 {
            parts.push(format!("a mission of {}", plural(self.mission_items, "1 item", "items")));
        }
        if self.fence_items > 0 {
            parts.push(format!("a fence of {}", plural(self.fence_items, "1 item", "items")));
        }
        if self.rally_points > 0 {
            parts.push(plural(self.rally_points, "1 rally point", "rally points"));
        }
        if parts.is_empty() {
            format!("no state to restore in {} (a fresh start: defaults, no mission)", dir.display())
        } else {
            format!("state restored from {}: {} (`--wipe` starts clean)", dir.display(), parts.join(", "))
        }
    }
}

/// A plan file (mission, fence, rally) of the state directory parsed by `parse`: None when absent; when
/// unreadable or unparsable, moved aside by `aside` (and None).
fn load_plan<T>(
    dir: &std::path::Path,
    file: &str,
    aside: &dyn Fn(&str, &dyn std::fmt::Display),
    parse: impl Fn(&str) -> Result<T, String>,
) -> Option<T> {
    match persist::load(dir, file) {
        Ok(Some(text)) => parse(&text).map_err(|e| aside(file, &e)).ok(),
        Ok(None) => None,
        Err(e) => {
            aside(file, &e);
            None
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::core::config::VehicleConfig;
    use crate::core::vehicle::Vehicle;
    use crate::runtime::signing;

    fn temp_dir(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("aco-state-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).expect("temp dir");
        dir
    }

    #[test]
    fn a_hand_edited_params_file_with_a_bricking_rate_and_garbage_starts_the_vehicle_on_those_defaults() {
        // GIVEN a params.txt with a loop rate that does not divide the inner rate, a garbage line, a value
        // that is not a number, an out-of-range value, and one good value.
        let dir = temp_dir("params");
        let text = "LOOP_POS_HZ\t300\nthis is not a parameter line\nMPC_XY_CRUISE\tfast\nMPC_TKO_SPEED\t99\nMPC_XY_CRUISE\t2\n";
        std::fs::write(dir.join(PARAMS_FILE), text).expect("write");
        let vehicle = VehicleConfig::default();
        // WHEN the autopilot loads its state THEN it starts, on the good value and the defaults of the rest.
        let persisted = load_state(&dir, &vehicle).expect("a state file never stops the start");
        let store = persisted.params.expect("the parameters");
        assert_eq!(store.get("MPC_XY_CRUISE"), Some(2.0));
        assert_eq!(store.get("LOOP_POS_HZ"), Some(100.0), "the default: 300 does not divide 500");
        assert_eq!(store.get("MPC_TKO_SPEED"), Some(1.0), "the default: 99 is out of range");
        Vehicle::with_params(vehicle, store).expect("the vehicle starts");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn the_start_says_what_was_restored_and_wipe_starts_clean() {
        // GIVEN a state directory with two changed parameters, a mission and a signing key.
        let dir = temp_dir("restored");
        let vehicle = VehicleConfig::default();
        let mut store = crate::core::params::ParamStore::from_config(&vehicle);
        store.set("MPC_XY_CRUISE", 2.0).expect("in range");
        store.set("NAV_DLL_ACT", 2.0).expect("in range");
        std::fs::write(dir.join(PARAMS_FILE), store.to_text()).expect("write");
        let wpl = "QGC WPL 110\n0\t1\t0\t16\t0\t0\t0\t0\t47.397742\t8.545594\t488.0\t1\n\
                   1\t0\t3\t22\t0\t0\t0\t0\t0\t0\t5\t1\n2\t0\t3\t21\t0\t0\t0\t0\t0\t0\t0\t1\n";
        std::fs::write(dir.join(MISSION_FILE), wpl).expect("write");
        std::fs::write(dir.join(signing::KEY_FILE), "00").expect("write");
        // WHEN it is loaded THEN the start-up line names the changed parameters and counts the mission.
        let persisted = load_state(&dir, &vehicle).expect("starts");
        let restored = RestoredState::of(&persisted, &vehicle);
        let mut changed = restored.changed_params.clone();
        changed.sort_unstable();
        assert_eq!(changed, ["MPC_XY_CRUISE", "NAV_DLL_ACT"]);
        let line = restored.describe(&dir);
        assert!(
            line.starts_with(&format!("state restored from {}: 2 parameters differ from default (", dir.display())),
            "{line}"
        );
        assert!(line.contains("MPC_XY_CRUISE, NAV_DLL_ACT), a mission of 3 items ("), "{line}");
        assert!(line.ends_with("(`--wipe` starts clean)"), "{line}");
        drop(persisted);
        // WHEN the state is wiped THEN the next start restores nothing, and the signing key is kept.
        let removed = wipe_state(&dir).expect("wipe");
        assert_eq!(removed.len(), 2, "{removed:?}");
        let persisted = load_state(&dir, &vehicle).expect("starts");
        let line = RestoredState::of(&persisted, &vehicle).describe(&dir);
        assert_eq!(line, format!("no state to restore in {} (a fresh start: defaults, no mission)", dir.display()));
        assert!(dir.join(signing::KEY_FILE).exists());
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_mission_file_that_cannot_be_parsed_is_moved_aside_and_the_vehicle_starts_without_it() {
        let dir = temp_dir("mission");
        std::fs::write(dir.join(MISSION_FILE), "not a QGC WPL file\n").expect("write");
        let persisted = load_state(&dir, &VehicleConfig::default()).expect("starts");
        assert!(persisted.mission.is_none());
        assert!(!dir.join(MISSION_FILE).exists(), "moved away");
        let aside: Vec<_> = std::fs::read_dir(&dir)
            .expect("dir")
            .flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with(&format!("{MISSION_FILE}.corrupt-")))
            .collect();
        assert_eq!(aside.len(), 1, "kept for a person to look at");
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn a_polygon_fence_uploaded_is_saved_and_after_a_restart_downloads_identical() {
        use crate::core::mavlink::MavHeader;
        use crate::core::mavlink::common::{
            MISSION_COUNT_DATA, MISSION_ITEM_INT_DATA, MISSION_REQUEST_INT_DATA, MISSION_REQUEST_LIST_DATA, MavFrame,
            MavMessage, MavMissionType,
        };
        use crate::core::vehicle::ShellEffect;
        const GCS: MavHeader = MavHeader { system_id: 255, component_id: 190, sequence: 0 };
        const FENCE: MavMissionType = MavMissionType::MAV_MISSION_TYPE_FENCE;
        let vertex = |seq: u16, lat: i32, lon: i32| MISSION_ITEM_INT_DATA {
            param1: 4.0,
            x: lat,
            y: lon,
            seq,
            command: MavCmd::MAV_CMD_NAV_FENCE_POLYGON_VERTEX_INCLUSION,
            target_system: 1,
            target_component: 1,
            frame: MavFrame::MAV_FRAME_GLOBAL,
            mission_type: FENCE,
            ..Default::default()
        };
        let polygon = [
            vertex(0, 473_970_000, 85_450_000),
            vertex(1, 473_980_000, 85_450_000),
            vertex(2, 473_980_000, 85_465_000),
            vertex(3, 473_970_000, 85_465_000),
        ];
        // GIVEN a fence uploaded as QGroundControl uploads it, and saved where the autopilot saves it.
        let dir = temp_dir("fence");
        let mut vehicle = Vehicle::new(VehicleConfig::default()).expect("vehicle");
        let count = MISSION_COUNT_DATA {
            count: 4,
            target_system: 1,
            target_component: 1,
            mission_type: FENCE,
            ..Default::default()
        };
        vehicle.handle_message(0, &GCS, &MavMessage::MISSION_COUNT(count));
        for item in &polygon {
            vehicle.handle_message(0, &GCS, &MavMessage::MISSION_ITEM_INT(item.clone()));
        }
        let saved: Vec<String> = vehicle
            .take_effects()
            .into_iter()
            .filter_map(|e| if let ShellEffect::SaveFence(text) = e { Some(text) } else { None })
            .collect();
        assert_eq!(saved.len(), 1, "saved once, when the upload completed");
        std::fs::write(dir.join(FENCE_FILE), &saved[0]).expect("write");
        // WHEN the autopilot restarts from its state directory.
        let persisted = load_state(&dir, &VehicleConfig::default()).expect("starts");
        let mut restarted = Vehicle::new(VehicleConfig::default()).expect("vehicle");
        restarted.load_fence(persisted.fence.expect("the fence is loaded"));
        // THEN a download gives back the items uploaded.
        let list = MISSION_REQUEST_LIST_DATA { target_system: 1, target_component: 1, mission_type: FENCE };
        let reply = restarted.handle_message(0, &GCS, &MavMessage::MISSION_REQUEST_LIST(list));
        assert!(matches!(reply.as_slice(), [MavMessage::MISSION_COUNT(c)] if c.count == 4 && c.mission_type == FENCE));
        for (seq, sent) in (0..4).zip(&polygon) {
            let request = MISSION_REQUEST_INT_DATA { seq, target_system: 1, target_component: 1, mission_type: FENCE };
            let reply = restarted.handle_message(0, &GCS, &MavMessage::MISSION_REQUEST_INT(request));
            let [MavMessage::MISSION_ITEM_INT(got)] = reply.as_slice() else { panic!("{reply:?}") };
            let expect = MISSION_ITEM_INT_DATA { target_system: 255, target_component: 190, ..sent.clone() };
            assert_eq!(*got, expect);
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
