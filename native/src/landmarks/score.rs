//! How a layout is judged (method, section 2, "Reconstruction"): measure the landmarks of known
//! poses with tracker noise, solve the blendshape weights by bounded least squares over the
//! landmark rows, rebuild the dense mesh and compare it with the truth.

use std::sync::atomic::{AtomicUsize, Ordering};

use rand::seq::index::sample;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rayon::prelude::*;
use serde::Serialize;

use crate::bounded::{solve_bounded, Gram};
use super::design::{error_weight, predicted_error};
use crate::error::ShapesmithResult;
use crate::geometry::weld::WeldedRig;
use crate::invalid;
use crate::progress::{NoProgress, Progress};
use crate::rig::RigView;

/// Score Layout's settings ([`crate::settings`]); the extra poses are data, `#[serde(skip)]`.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct ScoreParams {
    /// Standard deviation of the measurement noise per coordinate, as a fraction of the
    /// bounding-box diagonal (the method: 0.2%).
    pub noise: f64,
    pub seed: u64,
    /// Further test poses, K weights each (e.g. the packed expressions as 0/1 rows).
    #[serde(skip)]
    pub extra_poses: Vec<Vec<f64>>,
    /// Random sparse mixes: 3 to 6 shapes, weights uniform in [0, 1].
    pub random_mixes: usize,
}

impl Default for ScoreParams {
    fn default() -> Self {
        Self { noise: 0.002, seed: 0, extra_poses: Vec::new(), random_mixes: 50 }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct LayoutScore {
    /// Mean over poses of the mean vertex error, relative to the bounding-box diagonal.
    pub mean: f64,
    /// Largest vertex error over every pose, relative to the diagonal.
    pub max: f64,
    pub poses: usize,
    /// Distinct landmark vertices used.
    pub landmarks: usize,
    /// The design model's prediction of the error (RMS, fraction of the diagonal; see
    /// [`super::design`]) for the same noise; `None` without noise.
    pub predicted: Option<f64>,
}

/// Scores the layout `vertices`. Test poses: each non-inert shape alone at weight 1, then
/// `extra_poses`, then `random_mixes` sparse mixes. Each pose's landmarks are measured with
/// Gaussian noise (`noise x` diagonal per coordinate; pose p draws from ChaCha stream p of
/// `seed`), the weights solved by `min ||D_F w - (x_F - V0_F)||^2, 0 <= w <= 1`, and the
/// dense mesh `V0 + D w` compared with the pose's truth.
///
/// Scored on the welded surface ([`WeldedRig`]), each landmark at its vertex's welded point:
/// a seam's copies are one point of the mesh compared.
pub fn score_layout(rig: &RigView, vertices: &[u32], params: &ScoreParams) -> ShapesmithResult<LayoutScore> {
    score_layout_reporting(rig, vertices, params, &NoProgress)
}

/// [`score_layout`] reporting the share of test poses scored to `progress`; a stop request
/// ends it with [`crate::error::ShapesmithError::Cancelled`]. There are K + 50 poses, each
/// rebuilt densely from all K weights: on a 77k-vertex head with 150 keys, seconds.
pub fn score_layout_reporting(
    rig: &RigView,
    vertices: &[u32],
    params: &ScoreParams,
    progress: &dyn Progress,
) -> ShapesmithResult<LayoutScore> {
    if vertices.iter().any(|&v| v as usize >= rig.n_vertices()) {
        return score_welded(rig, vertices, params, progress);
    }
    let welded = WeldedRig::new(rig);
    let points: Vec<u32> = vertices.iter().map(|&v| welded.weld.welded_of[v as usize]).collect();
    score_welded(&welded.view(), &points, params, progress)
}

fn score_welded(rig: &RigView, vertices: &[u32], params: &ScoreParams, progress: &dyn Progress) -> ShapesmithResult<LayoutScore> {
    rig.validate()?;
    if vertices.is_empty() {
        return Err(invalid!("the layout has no landmark vertices: give at least one vertex index"));
    }
    if let Some(&bad) = vertices.iter().find(|&&v| v as usize >= rig.n_vertices()) {
        return Err(invalid!("landmark vertex {bad} does not exist: the mesh has {} vertices", rig.n_vertices()));
    }
    if !(params.noise.is_finite() && params.noise >= 0.0) {
        return Err(invalid!("noise must be a finite fraction >= 0 of the bounding-box diagonal, got {}", params.noise));
    }
    let k_count = rig.n_shapes();
    for (p, pose) in params.extra_poses.iter().enumerate() {
        if pose.len() != k_count {
            return Err(invalid!("extra pose {p} has {} weights but the rig has {k_count} shapes", pose.len()));
        }
        if let Some(k) = pose.iter().position(|w| !w.is_finite()) {
            return Err(invalid!("extra pose {p}: the weight of '{}' is not finite", rig.names[k]));
        }
    }
    let inert = rig.inert_shapes();
    let live: Vec<usize> = (0..k_count).filter(|k| !inert.contains(k)).collect();
    if live.is_empty() {
        return Err(invalid!("every shape key is inert (moves nothing): there is nothing to reconstruct"));
    }
    let mut landmarks = vertices.to_vec();
    landmarks.sort_unstable();
    landmarks.dedup();

    let poses = test_poses(k_count, &live, params);
    let (gram, rows) = landmark_system(rig, &live, &landmarks);
    let diagonal = rig.bbox_diagonal();
    let sigma = params.noise * diagonal;
    let (lower, upper) = (vec![0.0; live.len()], vec![1.0; live.len()]);
    let scored = AtomicUsize::new(0);
    let errors: Vec<(f64, f64)> = poses
        .par_iter()
        .enumerate()
        .map(|(p, weights)| {
            let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
            rng.set_stream(p as u64);
            // Measured landmark offsets from the neutral: truth plus noise.
            let measured: Vec<f64> = (0..rows.len())
                .map(|r| live.iter().map(|&k| rows[r][k] * weights[k]).sum::<f64>() + sigma * gaussian(&mut rng))
                .collect();
            let g: Vec<f64> = (0..live.len()).map(|c| (0..rows.len()).map(|r| rows[r][live[c]] * measured[r]).sum()).collect();
            let solved = solve_bounded(&gram, &g, &lower, &upper);
            let mut difference = weights.clone();
            for (c, &k) in live.iter().enumerate() {
                difference[k] -= solved[c];
            }
            let error = dense_error(rig, &difference);
            progress.checkpoint((scored.fetch_add(1, Ordering::Relaxed) + 1) as f64 / poses.len() as f64)?;
            Ok(error)
        })
        .collect::<ShapesmithResult<_>>()?;
    let mean = errors.iter().map(|e| e.0).sum::<f64>() / errors.len() as f64 / diagonal;
    let max = errors.iter().map(|e| e.1).fold(0.0, f64::max) / diagonal;
    let predicted = (sigma > 0.0).then(|| {
        let deltas: Vec<&[[f32; 3]]> = live.iter().map(|&k| rig.delta(k)).collect();
        predicted_error(&deltas, &error_weight(&deltas), &landmarks, sigma * sigma) / diagonal
    });
    Ok(LayoutScore { mean, max, poses: poses.len(), landmarks: landmarks.len(), predicted })
}

/// Singles, the caller's poses, then seeded sparse mixes (stream `u64::MAX` of `seed`).
fn test_poses(k_count: usize, live: &[usize], params: &ScoreParams) -> Vec<Vec<f64>> {
    let mut poses: Vec<Vec<f64>> = live
        .iter()
        .map(|&k| {
            let mut w = vec![0.0; k_count];
            w[k] = 1.0;
            w
        })
        .collect();
    poses.extend(params.extra_poses.iter().cloned());
    let mut rng = ChaCha8Rng::seed_from_u64(params.seed);
    rng.set_stream(u64::MAX);
    for _ in 0..params.random_mixes {
        let size = rng.random_range(3..=6).min(live.len());
        let mut w = vec![0.0; k_count];
        for c in sample(&mut rng, live.len(), size) {
            w[live[c]] = rng.random::<f64>();
        }
        poses.push(w);
    }
    poses
}

/// The landmark rows of `D` (3 per landmark, K wide, zero for inert shapes) and their Gram
/// matrix `D_F^T D_F` over the live shapes, shared by every pose.
fn landmark_system(rig: &RigView, live: &[usize], landmarks: &[u32]) -> (Gram, Vec<Vec<f64>>) {
    let rows: Vec<Vec<f64>> = landmarks
        .iter()
        .flat_map(|&v| (0..3).map(move |axis| (v, axis)))
        .map(|(v, axis)| {
            let mut row = vec![0.0; rig.n_shapes()];
            for &k in live {
                row[k] = rig.delta(k)[v as usize][axis] as f64;
            }
            row
        })
        .collect();
    let size = live.len();
    let values = (0..size * size)
        .map(|ij| rows.iter().map(|row| row[live[ij / size]] * row[live[ij % size]]).sum())
        .collect();
    (Gram { size, values }, rows)
}

/// Mean and max over vertices of `|sum_k difference_k D_k[n]|`.
fn dense_error(rig: &RigView, difference: &[f64]) -> (f64, f64) {
    let mut offset = vec![[0.0f64; 3]; rig.n_vertices()];
    for (k, &d) in difference.iter().enumerate().filter(|p| *p.1 != 0.0) {
        for (o, delta) in offset.iter_mut().zip(rig.delta(k)) {
            for a in 0..3 {
                o[a] += d * delta[a] as f64;
            }
        }
    }
    let lengths = offset.iter().map(|o| (o[0] * o[0] + o[1] * o[1] + o[2] * o[2]).sqrt());
    let (sum, max) = lengths.fold((0.0, 0.0f64), |(s, m), e| (s + e, m.max(e)));
    (sum / rig.n_vertices() as f64, max)
}

/// A standard normal draw (Box-Muller).
fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    let u: f64 = 1.0 - rng.random::<f64>();
    let v: f64 = rng.random();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 6 x 6 grid; shape k bumps a different patch of radius 1.5 (k = 0..3), so each shape
    /// has vertices only it moves.
    type Fixture = (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<[u32; 3]>, Vec<String>);

    fn patch_rig() -> Fixture {
        let side = 6u32;
        let points: Vec<[f32; 3]> = (0..side * side).map(|i| [(i % side) as f32, (i / side) as f32, 0.0]).collect();
        let triangles = crate::geometry::topology::grid_triangles(side, side, 0);
        let centres = [[1.0, 1.0], [4.0, 1.0], [1.0, 4.0], [4.0, 4.0]];
        let mut deltas = Vec::new();
        for (k, c) in centres.iter().enumerate() {
            for p in &points {
                let d2 = (p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2);
                let height = (1.0 - d2 / 2.25).max(0.0);
                deltas.push([0.1 * k as f32 * height, 0.0, height]);
            }
        }
        let names = (0..4).map(|k| format!("bump{k}")).collect();
        (points, deltas, triangles, names)
    }

    fn vertex_at(x: u32, y: u32) -> u32 {
        y * 6 + x
    }

    #[test]
    fn exact_without_noise_when_every_shape_has_a_landmark() {
        let (points, deltas, triangles, names) = patch_rig();
        let rig = RigView::new(&points, &deltas, &triangles, &names).unwrap();
        let layout = [vertex_at(1, 1), vertex_at(4, 1), vertex_at(1, 4), vertex_at(4, 4)];
        let params = ScoreParams { noise: 0.0, extra_poses: vec![vec![1.0, 0.0, 1.0, 0.5]], ..ScoreParams::default() };
        let score = score_layout(&rig, &layout, &params).unwrap();
        assert_eq!(score.poses, 4 + 1 + 50);
        assert_eq!(score.landmarks, 4);
        assert!(score.max < 1e-6, "{score:?}");
        // Without the landmark of bump3, its motion cannot be recovered.
        let fewer = score_layout(&rig, &layout[..3], &params).unwrap();
        assert!(fewer.mean > 100.0 * score.mean + 1e-4, "{fewer:?}");
        // With noise the error is positive, grows with the noise, and is reproducible.
        let noisy = |noise| score_layout(&rig, &layout, &ScoreParams { noise, ..params.clone() }).unwrap();
        assert!(noisy(0.002).mean > 1e-6 && noisy(0.01).mean > noisy(0.002).mean);
        assert_eq!(noisy(0.002), noisy(0.002));
    }

    #[test]
    fn rejects_bad_layouts_and_poses() {
        let (points, deltas, triangles, names) = patch_rig();
        let rig = RigView::new(&points, &deltas, &triangles, &names).unwrap();
        let p = ScoreParams::default();
        assert!(score_layout(&rig, &[], &p).unwrap_err().to_string().contains("no landmark"));
        assert!(score_layout(&rig, &[3, 99], &p).unwrap_err().to_string().contains("vertex 99"));
        let wrong = ScoreParams { extra_poses: vec![vec![1.0; 3]], ..p.clone() };
        assert!(score_layout(&rig, &[3], &wrong).unwrap_err().to_string().contains("extra pose 0 has 3"));
        let nan = ScoreParams { extra_poses: vec![vec![0.0, f64::NAN, 0.0, 0.0]], ..p };
        assert!(score_layout(&rig, &[3], &nan).unwrap_err().to_string().contains("bump1"));
    }

    /// Records every fraction reported; answers `false` from the `stop_after`-th on.
    struct Recorder {
        seen: std::sync::Mutex<Vec<f64>>,
        stop_after: usize,
    }

    impl Progress for Recorder {
        fn report(&self, fraction: f64) -> bool {
            let mut seen = self.seen.lock().unwrap();
            seen.push(fraction);
            seen.len() < self.stop_after
        }
    }

    #[test]
    fn reports_each_pose_scored_and_stops_when_asked() {
        let (points, deltas, triangles, names) = patch_rig();
        let rig = RigView::new(&points, &deltas, &triangles, &names).unwrap();
        let layout = [vertex_at(1, 1), vertex_at(4, 1), vertex_at(1, 4)];
        let params = ScoreParams::default();
        let all = Recorder { seen: Default::default(), stop_after: usize::MAX };
        let reported = score_layout_reporting(&rig, &layout, &params, &all).unwrap();
        assert_eq!(reported, score_layout(&rig, &layout, &params).unwrap());
        let mut seen = all.seen.into_inner().unwrap();
        seen.sort_by(f64::total_cmp);
        let poses = reported.poses as f64;
        assert_eq!(seen, (1..=reported.poses).map(|p| p as f64 / poses).collect::<Vec<_>>());
        let early = Recorder { seen: Default::default(), stop_after: 5 };
        let stopped = score_layout_reporting(&rig, &layout, &params, &early);
        assert_eq!(stopped.unwrap_err(), crate::error::ShapesmithError::Cancelled);
    }
}
