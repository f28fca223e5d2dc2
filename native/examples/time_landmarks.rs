//! Times `place_landmarks` (visibility, cover, selection) outside Blender, on the arrays
//! `scripts/bench_transfer.py -- --save-arrays DIR` writes (the 25k head is the one
//! `scripts/bench_landmarks.py -- --speed-only` times):
//!
//!     cargo run --release --example time_landmarks -- DIR/<head> [RUNS] [exhaustive]
//!
//! The bench's call (eps 0.5, one round, M = 34, 64 rays). Prints the best of RUNS (default
//! 3) runs' native seconds per stage, rays cast and reused, rays/s, and a checksum of the
//! layout (vertices and visibilities) so that two builds run one after the other can be
//! compared for both speed and sameness. `exhaustive` traces every ray through every pose.

use std::time::Instant;

use shapesmith_native::landmarks::{place_landmarks, LandmarkParams};
use shapesmith_native::rig::RigView;
use shapesmith_native::NoProgress;

#[path = "common/arrays.rs"]
mod arrays;
use arrays::{points, read};

fn main() {
    let dir = std::env::args().nth(1).expect("usage: time_landmarks DIR [RUNS] [exhaustive]");
    let runs: usize = std::env::args().nth(2).map_or(3, |r| r.parse().expect("RUNS is a count"));
    let reuse = std::env::args().nth(3).as_deref() != Some("exhaustive");
    let neutral = points(&format!("{dir}/source.f32"));
    let deltas = points(&format!("{dir}/deltas.f32"));
    let triangles = read(&format!("{dir}/triangles.u32"));
    let names: Vec<String> = (0..deltas.len() / neutral.len()).map(|k| format!("shape {k}")).collect();
    let rig = RigView::new(&neutral, &deltas, &triangles, &names).expect("rig");
    let params = LandmarkParams { epsilon: 0.5, max_per_shape: 1, landmarks: Some(34), reuse_visibility: reuse, ..Default::default() };
    let mut best: Option<(f64, f64, f64, f64)> = None;
    for _ in 0..runs {
        let started = Instant::now();
        let layout = place_landmarks(&rig, &params, &NoProgress).expect("layout");
        let wall = started.elapsed().as_secs_f64();
        if best.is_none_or(|b| wall < b.0) {
            best = Some((wall, layout.seconds_visibility, layout.seconds_solve, layout.seconds_design));
        }
        let checksum: f64 = layout.landmarks.iter().map(|l| l.vertex as f64 * (1.0 + l.visibility)).sum();
        println!(
            "{wall:.3} s: visibility {:.3} s, solve {:.3} s, design {:.3} s; {} rays cast, {} reused, {:.3e} rays/s; {} vertices traced; {} landmarks, checksum {checksum:.6}",
            layout.seconds_visibility,
            layout.seconds_solve,
            layout.seconds_design,
            layout.rays_cast,
            layout.rays_reused,
            layout.rays_cast as f64 / layout.seconds_visibility,
            layout.visibility_vertices,
            layout.landmarks.len(),
        );
    }
    let (wall, visibility, solve, design) = best.expect("at least one run");
    println!("best of {runs}: {wall:.3} s (visibility {visibility:.3}, solve {solve:.3}, design {design:.3})");
}
