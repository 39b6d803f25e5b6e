//! Test fixtures shared by the scenario, sweep and tune tests: one short gust hover, so each test that
//! needs a gust scenario flies the same one (with its own gust amplitude and release time).

use super::Scenario;

/// A 6 s hover at 1.5 m on the mismatch plant with the paper's state noise and a gust of `amplitude_mps`
/// from 1 s (0.5 s rise) released at `release_s` (0.5 s fall), as scenario TOML named `short-gust`: short
/// enough that a sweep or a tuning of a few runs takes well under a second.
pub(crate) fn short_gust_toml(amplitude_mps: f64, release_s: f64) -> String {
    format!(
        r#"
name = "short-gust"
duration_s = 6.0
plant = "mismatch"
state_noise = "paper"
metrics = ["gust"]
[initial]
pos_ned_m = [0.0, 0.0, -1.5]
[reference]
kind = "position"
steps = [{{ t_s = 0.0, pos_ned_m = [0.0, 0.0, -1.5] }}]
[wind.gust]
amplitude_mps = {amplitude_mps:?}
onset_s = 1.0
rise_s = 0.5
release_s = {release_s:?}
fall_s = 0.5
"#
    )
}

/// [`short_gust_toml`] loaded.
pub(crate) fn short_gust(amplitude_mps: f64, release_s: f64) -> Scenario {
    Scenario::from_toml("short-gust", &short_gust_toml(amplitude_mps, release_s)).expect("the fixture loads")
}

#[test]
fn the_short_gust_fixture_is_a_6_s_gust_hover_with_the_given_gust() {
    let s = short_gust(4.0, 2.5);
    let gust = s.wind.gust.expect("a gust");
    assert_eq!((s.duration_s, gust.amplitude_mps, gust.onset_s, gust.release_s), (6.0, Some(4.0), 1.0, 2.5));
}
