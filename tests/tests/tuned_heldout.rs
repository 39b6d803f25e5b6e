//! The committed tunings, flown again: each `docs/tuning/CTRL/` holds what `sitl tune sitl/tunes/CTRL.toml`
//! found, and its held-out report (`heldout.json`) is what docs/results.md's tuned tables print. This test
//! flies the same gain sets (the spec's start point and, where the tuning found safe gains, the committed
//! `controller.toml`) on the spec's held-out set and requires the committed report byte for byte. A change
//! to a controller, the plant or a metric that moves a held-out number fails here until
//! `scripts/reproduce` is rerun and its new numbers committed.

use sitl::tune::{GainSet, Tune};
use tests::repo::root;

fn reflown(ctrl: &str) -> Option<(String, String)> {
    let root = root();
    let dir = root.join("docs/tuning").join(ctrl);
    let committed = std::fs::read_to_string(dir.join("heldout.json")).ok()?;
    let spec = Tune::load(&root.join(format!("sitl/tunes/{ctrl}.toml"))).unwrap_or_else(|e| panic!("{ctrl}: {e}"));
    let start = spec.controller_block(&spec.start()).unwrap_or_else(|e| panic!("{ctrl}: {e}"));
    let mut gain_sets = vec![GainSet::from_toml(&start, &format!("{} (start)", spec.controller)).expect("start")];
    if let Ok(text) = std::fs::read_to_string(dir.join("controller.toml")) {
        gain_sets.push(GainSet::from_toml(&text, &format!("{} (tuned)", spec.controller)).expect("tuned gains"));
    }
    let pool = rayon::ThreadPoolBuilder::new().num_threads(2).build().expect("a pool");
    let results = spec.evaluate_heldout(&gain_sets, &pool);
    let flown = serde_json::to_string_pretty(&results).expect("serialisable") + "\n";
    Some((committed, flown))
}

#[test]
fn every_committed_tuning_flies_its_held_out_report_again_exactly() {
    let mut checked = Vec::new();
    for ctrl in ["aco", "ca", "pid", "se3"] {
        let Some((committed, flown)) = reflown(ctrl) else { continue };
        if committed != flown {
            let diff =
                committed.lines().zip(flown.lines()).enumerate().find(|(_, (a, b))| a != b).map_or_else(
                    || "the lengths differ".to_owned(),
                    |(i, (a, b))| format!("line {}: {a} -> {b}", i + 1),
                );
            panic!(
                "docs/tuning/{ctrl}/heldout.json no longer matches its gains flown again ({diff}): rerun \
                 scripts/reproduce and commit what it writes"
            );
        }
        checked.push(ctrl);
    }
    assert_eq!(checked, ["aco", "ca", "pid", "se3"], "every tuning has a held-out report");
}
