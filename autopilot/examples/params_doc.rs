//! Regenerate `docs/params.md` from the parameter table (`autopilot/src/core/params`): run
//! `cargo run -p autopilot --example params_doc` after changing a parameter. In: nothing. Out: the file
//! (written only when it changed) and a line on stdout saying which.

use std::path::Path;

use anyhow::Context;

fn main() -> anyhow::Result<()> {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../docs/params.md");
    let markdown = autopilot::core::params::markdown();
    if std::fs::read_to_string(&path).is_ok_and(|current| current == markdown) {
        println!("{} is current", path.display());
        return Ok(());
    }
    std::fs::write(&path, &markdown).with_context(|| format!("cannot write {}", path.display()))?;
    println!("wrote {}", path.display());
    Ok(())
}
