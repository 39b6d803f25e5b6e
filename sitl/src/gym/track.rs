//! An env's track reference: the prefiltered progress along a path shared by every env that flies it
//! (the figure-8's ~50 KB of arc-length tables once, not once per env), computed exactly as
//! `scenario::reference::TrackGen` computes its position and velocity, and a second progress
//! [`LOOKAHEAD_S`](super::LOOKAHEAD_S) ahead for the observation.

use std::sync::Arc;

use autopilot::core::navigator::spline::ProgressFilter;
use nalgebra::Vector3;

use crate::scenario::reference::{TrackPath, TrackSpec};

/// `TrackGen`'s prefilter step (s): the reference is the same function of time whatever calls it.
const PREFILTER_STEP_S: f64 = 1e-4;

/// A prefilter integrated in whole steps up to the time asked.
#[derive(Debug, Clone)]
struct Progress {
    filter: ProgressFilter,
    steps: u64,
}

/// The track reference of one episode.
#[derive(Debug, Clone)]
pub(super) struct Track {
    path: Arc<TrackPath>,
    start_s: f64,
    speed_mps: f64,
    total_m: f64,
    pos_d_m: f64,
    segments: usize,
    now: Progress,
    ahead: Progress,
}

impl Track {
    /// The path of `spec`, to share between the envs that fly it.
    pub fn path(spec: &TrackSpec) -> Arc<TrackPath> {
        Arc::new(TrackPath::new(spec.path, &spec.waypoints_ne_m))
    }

    /// `spec` flown along `path` (built from `spec` by [`Track::path`]).
    pub fn new(spec: &TrackSpec, path: Arc<TrackPath>) -> Self {
        let progress = Progress { filter: ProgressFilter::at_rest(spec.prefilter_wn_radps, 0.0), steps: 0 };
        Self {
            total_m: path.length_m() * f64::from(spec.laps),
            path,
            start_s: spec.start_s,
            speed_mps: spec.speed_mps,
            pos_d_m: spec.pos_d_m,
            segments: spec.waypoints_ne_m.len() - 1,
            now: progress.clone(),
            ahead: progress,
        }
    }

    /// When the unfiltered progress reaches the end (s).
    pub fn end_s(&self) -> f64 {
        self.start_s + self.total_m / self.speed_mps
    }

    fn advance(progress: &mut Progress, t_s: f64, start_s: f64, speed_mps: f64, total_m: f64) {
        let target_steps = (t_s / PREFILTER_STEP_S + 1e-6).floor().max(0.0) as u64;
        while progress.steps < target_steps {
            let t = progress.steps as f64 * PREFILTER_STEP_S;
            let raw = ((t - start_s) * speed_mps).clamp(0.0, total_m);
            progress.filter.step(raw, PREFILTER_STEP_S);
            progress.steps += 1;
        }
    }

    /// The reference position and velocity (NED) at `t_s`, and the position at `ahead_s` (both
    /// non-decreasing from call to call).
    pub fn at(&mut self, t_s: f64, ahead_s: f64) -> (Vector3<f64>, Vector3<f64>, Vector3<f64>) {
        let (start, speed, total) = (self.start_s, self.speed_mps, self.total_m);
        Self::advance(&mut self.now, t_s, start, speed, total);
        Self::advance(&mut self.ahead, ahead_s, start, speed, total);
        let (p, dp_ds, _) = self.path.eval(self.now.filter.s_m);
        let v = dp_ds * self.now.filter.s_dot_mps;
        let (q, _, _) = self.path.eval(self.ahead.filter.s_m);
        let d = self.pos_d_m;
        (Vector3::new(p.x, p.y, d), Vector3::new(v.x, v.y, 0.0), Vector3::new(q.x, q.y, d))
    }

    /// Bytes of the path (shared by every env flying it).
    pub fn path_bytes(&self) -> usize {
        // The spline's arc-length samples (400 per segment) and its 5 mm polyline, roughly.
        self.segments * 400 * 8 + (self.path.length_m() / 0.005) as usize * 16
    }

    /// Whether the path is shared with other envs.
    pub fn shared(&self) -> bool {
        Arc::strong_count(&self.path) > 1
    }
}
