//! End-to-end tests of [`place_landmarks`] on small procedural "faces": a height field
//! symmetric across x = 0 with bump-shaped blendshapes.

use super::*;
use crate::progress::NoProgress;
use crate::ShapesmithError;

const HALF: i32 = 6;
const ROWS: i32 = 12;

/// Grid vertices at integer (x, y), x in -HALF..=HALF, y in 0..ROWS, on a gentle dome.
fn grid() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let width = 2 * HALF + 1;
    let points = (0..ROWS)
        .flat_map(|y| (-HALF..=HALF).map(move |x| (x, y)))
        .map(|(x, y)| [x as f32, y as f32, 3.0 - 0.03 * (x * x + (y - 6) * (y - 6)) as f32])
        .collect();
    (points, crate::geometry::topology::grid_triangles(width as u32, ROWS as u32, 0))
}

fn index(x: i32, y: i32) -> usize {
    (y * (2 * HALF + 1) + x + HALF) as usize
}

/// `(name, centre x, centre y, radius, height)` of a bump-shaped blendshape.
type Bump = (&'static str, f32, f32, f32, f32);

/// Neutral, deltas, triangles and names of a procedural rig.
type Fixture = (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<[u32; 3]>, Vec<String>);

/// One shape per bump; a zero height makes an inert shape.
fn face(bumps: &[Bump]) -> Fixture {
    let (points, triangles) = grid();
    let mut deltas = Vec::new();
    for &(_, cx, cy, radius, height) in bumps {
        for p in &points {
            let d2 = (p[0] - cx).powi(2) + (p[1] - cy).powi(2);
            deltas.push([0.0, 0.0, height * (1.0 - d2 / (radius * radius)).max(0.0)]);
        }
    }
    let names = bumps.iter().map(|b| b.0.to_string()).collect();
    (points, deltas, triangles, names)
}

/// Two mirror pairs of different strength, a midline shape, a broad shape and an inert one.
const BUMPS: [Bump; 7] = [
    ("browUpLeft", -3.0, 9.0, 2.0, 0.5),
    ("browUpRight", 3.2, 9.0, 2.0, 0.4),
    ("smileLeft", -3.0, 3.0, 2.5, 0.6),
    ("smileRight", 3.0, 3.0, 2.5, 0.3),
    ("jawOpen", 0.0, 1.0, 3.0, -1.0),
    ("puff", 0.0, 5.0, 6.0, 0.2),
    ("nothing", 0.0, 5.0, 2.0, 0.0),
];

fn run(bumps: &[Bump], params: &LandmarkParams) -> ShapesmithResult<LandmarkLayout> {
    let (points, deltas, triangles, names) = face(bumps);
    let rig = RigView::new(&points, &deltas, &triangles, &names).unwrap();
    place_landmarks(&rig, params, &NoProgress)
}

#[test]
fn every_live_shape_is_covered_by_a_candidate() {
    for epsilon in [0.3, 0.5, 0.8] {
        for max_per_shape in [1, 2] {
            let params = LandmarkParams { epsilon, max_per_shape, rays: 16, ..LandmarkParams::default() };
            let layout = run(&BUMPS, &params).unwrap();
            assert_eq!(layout.inert, vec![6]);
            assert!(layout.uncovered.is_empty() && layout.optimal);
            for k in 0..6 {
                assert!(
                    layout.landmarks.iter().any(|l| l.shapes.contains(&k)),
                    "eps {epsilon}: shape {k} has no landmark in {:?}",
                    layout.landmarks
                );
            }
            for l in &layout.landmarks {
                assert_eq!(l.shapes.first().copied().unwrap_or(l.strongest), l.strongest);
                assert!((0.0..=1.0).contains(&l.visibility));
            }
            assert!(layout.rays_cast > 0 && layout.rounds >= 1);
        }
    }
}

#[test]
fn single_cover_is_as_small_as_possible() {
    // The candidate sets of the two brows and the two smiles are pairwise disjoint, so no
    // cover has fewer than 4 landmarks; at eps 0.3 jawOpen and the broad puff overlap the
    // smiles and can ride along, so 4 is the optimum.
    let params = LandmarkParams { epsilon: 0.3, max_per_shape: 1, gamma: 0.0, rays: 8, ..LandmarkParams::default() };
    let layout = run(&BUMPS, &params).unwrap();
    assert_eq!(layout.landmarks.len(), 4, "{:?}", layout.landmarks);
    // At eps 0.8 every candidate set is a small disc around its bump: one landmark each.
    let params = LandmarkParams { epsilon: 0.8, ..params };
    assert_eq!(run(&BUMPS, &params).unwrap().landmarks.len(), 6);
}

#[test]
fn symmetric_layout_is_mirror_symmetric() {
    let params = LandmarkParams { symmetric: true, rays: 16, ..LandmarkParams::default() };
    let layout = run(&BUMPS, &params).unwrap();
    let (points, _) = grid();
    let chosen: std::collections::BTreeSet<u32> = layout.landmarks.iter().map(|l| l.vertex).collect();
    for &v in &chosen {
        let p = points[v as usize];
        let mirror = index(-p[0] as i32, p[1] as i32) as u32;
        assert!(chosen.contains(&mirror), "vertex {v} at {p:?} lacks its mirror {mirror} in {chosen:?}");
    }
    // An asymmetric rig: only the left smile. Plain layouts take one vertex, symmetric two.
    let lone = [("smileLeft", -3.0, 3.0, 2.5, 0.6)];
    let plain = run(&lone, &LandmarkParams { rays: 8, max_per_shape: 1, ..LandmarkParams::default() }).unwrap();
    assert_eq!(plain.landmarks.iter().map(|l| l.vertex).collect::<Vec<_>>(), vec![index(-3, 3) as u32]);
    let symmetric = run(&lone, &LandmarkParams { rays: 8, max_per_shape: 1, symmetric: true, ..LandmarkParams::default() }).unwrap();
    let mut got: Vec<u32> = symmetric.landmarks.iter().map(|l| l.vertex).collect();
    got.sort();
    assert_eq!(got, vec![index(-3, 3) as u32, index(3, 3) as u32]);
    // The mirrored landmark does not move in the shape: it serves nothing but names it.
    let right = symmetric.landmarks.iter().find(|l| l.vertex == index(3, 3) as u32).unwrap();
    assert!(right.shapes.is_empty() && right.strongest == 0);
}

#[test]
fn backup_rounds_respect_the_radius() {
    let params = LandmarkParams { max_per_shape: 3, share_limit: 0.0, radius: 0.12, rays: 8, ..LandmarkParams::default() };
    let layout = run(&BUMPS, &params).unwrap();
    assert!(layout.rounds >= 2, "share_limit 0 makes every shape ask again");
    let (points, _) = grid();
    let radius = 0.12 * crate::rig::bbox_diagonal(&points);
    for a in &layout.landmarks {
        for b in layout.landmarks.iter().filter(|b| b.round > a.round) {
            let d: f64 = (0..3).map(|i| (a.position[i] - b.position[i]).powi(2)).sum::<f64>().sqrt();
            assert!(d > radius, "round {} landmark {} is {d} from round {} landmark {}", b.round, b.vertex, a.round, a.vertex);
        }
    }
}

#[test]
fn deterministic_across_runs_and_thread_counts() {
    let params = LandmarkParams { rays: 32, symmetric: true, ..LandmarkParams::default() };
    let once = || run(&BUMPS, &params).unwrap().landmarks;
    let serial = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap().install(once);
    let parallel = rayon::ThreadPoolBuilder::new().num_threads(3).build().unwrap().install(once);
    assert_eq!(serial, parallel);
    assert_eq!(once(), once());
}

#[test]
fn cameras_replace_the_hemisphere() {
    // A camera far in front of the dome sees every vertex; one below it sees none.
    let front = LandmarkParams { cameras: Some(vec![[0.0, 6.0, 50.0]]), rays: 0, ..LandmarkParams::default() };
    let layout = run(&BUMPS, &front).unwrap();
    assert!(layout.landmarks.iter().all(|l| l.visibility == 1.0));
    let behind = LandmarkParams { cameras: Some(vec![[0.0, 6.0, -50.0]]), min_visibility: 0.5, ..front.clone() };
    let err = run(&BUMPS, &behind).unwrap_err();
    assert!(err.to_string().contains("min_visibility"), "{err}");
}

#[test]
fn occluded_candidates_leave_shapes_uncovered() {
    // A lid over the left brow in every pose hides browUpLeft's candidates.
    let (mut points, mut deltas, mut triangles, names) = face(&BUMPS);
    let n = points.len() as u32;
    points.extend([[-6.0, 6.5, 4.0], [-0.5, 6.5, 4.0], [-0.5, 11.5, 4.0], [-6.0, 11.5, 4.0]]);
    triangles.extend([[n, n + 1, n + 2], [n, n + 2, n + 3]]);
    let k_count = names.len();
    let old = std::mem::take(&mut deltas);
    for k in 0..k_count {
        deltas.extend_from_slice(&old[k * n as usize..(k + 1) * n as usize]);
        deltas.extend([[0.0; 3]; 4]);
    }
    let rig = RigView::new(&points, &deltas, &triangles, &names).unwrap();
    let params = LandmarkParams { min_visibility: 0.5, rays: 32, ..LandmarkParams::default() };
    let layout = place_landmarks(&rig, &params, &NoProgress).unwrap();
    assert_eq!(layout.uncovered, vec![0]);
    assert!(layout.landmarks.iter().all(|l| !l.shapes.contains(&0) || l.visibility >= 0.5));
}

#[test]
fn landmarks_stay_on_the_allowed_vertices() {
    // The right half of the face is a "part" (teeth, eyes) that may not carry landmarks: every
    // landmark lands on the left half or the midline, the right-only shapes are uncovered, and
    // the shapes both halves move are still covered from the allowed side.
    let allowed: Vec<bool> = face(&BUMPS).0.iter().map(|p| p[0] <= 0.0).collect();
    let params = LandmarkParams { rays: 16, allowed: Some(allowed.clone()), ..LandmarkParams::default() };
    let layout = run(&BUMPS, &params).unwrap();
    assert!(layout.landmarks.iter().all(|l| allowed[l.vertex as usize]), "{:?}", layout.landmarks);
    assert_eq!(layout.uncovered, vec![1, 3]);
    for k in [0, 2, 4, 5] {
        assert!(layout.landmarks.iter().any(|l| l.shapes.contains(&k)), "shape {k} uncovered");
    }
    let design = LandmarkParams { landmarks: Some(20), ..params.clone() };
    assert!(run(&BUMPS, &design).unwrap().landmarks.iter().all(|l| allowed[l.vertex as usize]));
    let message = |allowed: Vec<bool>| {
        run(&BUMPS, &LandmarkParams { allowed: Some(allowed), ..LandmarkParams::default() }).unwrap_err().to_string()
    };
    assert!(message(vec![true; 3]).contains("allowed has 3 entries"));
    assert!(message(vec![false; allowed.len()]).contains("forbids every vertex"));
}

#[test]
fn invalid_input_is_named() {
    let message = |params: LandmarkParams| run(&BUMPS, &params).unwrap_err().to_string();
    assert_eq!(message(LandmarkParams { epsilon: 0.0, ..LandmarkParams::default() }), "epsilon must be in (0, 1], got 0");
    assert!(message(LandmarkParams { epsilon: 1.5, ..LandmarkParams::default() }).contains("epsilon"));
    assert!(message(LandmarkParams { rays: 0, ..LandmarkParams::default() }).contains("rays"));
    assert!(message(LandmarkParams { alpha: -0.1, ..LandmarkParams::default() }).contains("alpha"));
    assert!(message(LandmarkParams { max_per_shape: 0, ..LandmarkParams::default() }).contains("max_per_shape"));
    assert!(message(LandmarkParams { cameras: Some(vec![]), ..LandmarkParams::default() }).contains("cameras"));
    assert!(matches!(run(&[], &LandmarkParams::default()), Err(ShapesmithError::InvalidInput(_))));
    // Every shape inert: an empty layout that names them, not an error.
    let layout = run(&[("a", 0.0, 0.0, 1.0, 0.0), ("b", 1.0, 1.0, 1.0, 0.0)], &LandmarkParams::default()).unwrap();
    assert!(layout.landmarks.is_empty() && layout.inert == vec![0, 1] && layout.rounds == 0);
}

#[test]
fn cancellation_stops_the_job() {
    struct StopAtOnce;
    impl Progress for StopAtOnce {
        fn report(&self, _: f64) -> bool {
            false
        }
    }
    let (points, deltas, triangles, names) = face(&BUMPS);
    let rig = RigView::new(&points, &deltas, &triangles, &names).unwrap();
    assert_eq!(place_landmarks(&rig, &LandmarkParams::default(), &StopAtOnce).unwrap_err(), ShapesmithError::Cancelled);
}

/// A conditioned layout keeps the cover, stops at the requested count, stays mirror-symmetric
/// and keeps its additions out of each other's radius.
#[test]
fn conditioned_layouts_keep_the_cover_and_stay_symmetric() {
    let (points, _) = grid();
    for symmetric in [false, true] {
        let base = LandmarkParams { symmetric, rays: 16, max_per_shape: 1, radius: 0.05, curve_to: 0, ..LandmarkParams::default() };
        let cover = run(&BUMPS, &base).unwrap();
        let cover_vertices: Vec<u32> = cover.landmarks.iter().map(|l| l.vertex).collect();
        assert!(cover.curve.is_empty() && cover.design_stop.is_none() && cover.predicted_error > 0.0);
        let m = cover_vertices.len() + 6;
        let layout = run(&BUMPS, &LandmarkParams { landmarks: Some(m), ..base.clone() }).unwrap();
        let vertices: Vec<u32> = layout.landmarks.iter().map(|l| l.vertex).collect();
        // Every covered shape keeps its landmark: the cover is a subset, unchanged.
        for l in &cover.landmarks {
            assert!(layout.landmarks.contains(l), "cover landmark {l:?} lost");
        }
        assert!(vertices.len() <= m && vertices.len() >= m - 1, "{} for {m}", vertices.len());
        assert_eq!(layout.design_stop, Some(DesignStop::Count));
        assert!(layout.predicted_error < cover.predicted_error, "{} vs {}", layout.predicted_error, cover.predicted_error);
        let added: Vec<&Landmark> = layout.landmarks.iter().filter(|l| l.added.is_some()).collect();
        assert_eq!(added.len(), vertices.len() - cover_vertices.len());
        let radius = 0.05 * crate::rig::bbox_diagonal(&points);
        for a in &added {
            assert!(a.visibility >= base.pool_visibility && a.round == cover.rounds);
            for b in layout.landmarks.iter().filter(|b| b.added.is_none_or(|s| s < a.added.unwrap())) {
                let d: f64 = (0..3).map(|i| (a.position[i] - b.position[i]).powi(2)).sum::<f64>().sqrt();
                assert!(d > radius, "added {} is {d} from {}", a.vertex, b.vertex);
            }
        }
        // The curve starts at the cover and falls with every step.
        assert_eq!(layout.curve[0].landmarks, cover_vertices.len());
        assert!((layout.curve[0].predicted_error - cover.predicted_error).abs() < 1e-12);
        assert!(layout.curve.windows(2).all(|w| w[1].predicted_error <= w[0].predicted_error && w[1].landmarks > w[0].landmarks));
        if symmetric {
            for &v in &vertices {
                let p = points[v as usize];
                let mirror = index(-p[0] as i32, p[1] as i32) as u32;
                assert!(vertices.contains(&mirror), "vertex {v} at {p:?} lacks its mirror");
            }
        }
    }
}

#[test]
fn a_target_error_stops_the_design_where_the_curve_reaches_it() {
    let base = LandmarkParams { rays: 16, max_per_shape: 1, curve_to: 0, ..LandmarkParams::default() };
    let probe = run(&BUMPS, &LandmarkParams { landmarks: Some(20), ..base.clone() }).unwrap();
    // Halfway between the errors after the third and fourth additions.
    let target = 0.5 * (probe.curve[3].predicted_error + probe.curve[4].predicted_error);
    let layout = run(&BUMPS, &LandmarkParams { target_error: Some(target), ..base.clone() }).unwrap();
    assert_eq!(layout.design_stop, Some(DesignStop::Target));
    assert_eq!(layout.landmarks.len(), probe.curve[4].landmarks);
    assert!(layout.predicted_error <= target && layout.curve[3].predicted_error > target);
    // Already below target: the cover alone.
    let easy = run(&BUMPS, &LandmarkParams { target_error: Some(1.0), ..base.clone() }).unwrap();
    assert_eq!(easy.design_stop, Some(DesignStop::Target));
    assert!(easy.landmarks.iter().all(|l| l.added.is_none()));
    // Unreachable: the pool runs out.
    let hard = run(&BUMPS, &LandmarkParams { target_error: Some(1e-12), radius: 0.2, ..base }).unwrap();
    assert_eq!(hard.design_stop, Some(DesignStop::PoolExhausted));
}

#[test]
fn design_input_is_checked() {
    let message = |params: LandmarkParams| run(&BUMPS, &params).unwrap_err().to_string();
    let base = LandmarkParams { rays: 8, ..LandmarkParams::default() };
    assert!(message(LandmarkParams { landmarks: Some(0), ..base.clone() }).contains("landmarks must be at least 1"));
    assert!(message(LandmarkParams { target_error: Some(-0.1), ..base.clone() }).contains("target_error"));
    assert!(message(LandmarkParams { target_error: Some(f64::NAN), ..base.clone() }).contains("target_error"));
    let few = message(LandmarkParams { landmarks: Some(2), ..base });
    assert!(few.contains("the cover alone needs") && few.contains("landmarks = 2"), "{few}");
}

/// The predicted error tracks the measured noisy bounded reconstruction error across random
/// layouts of random rigs.
#[test]
fn predicted_error_correlates_with_measured_error() {
    use rand::{Rng, SeedableRng};
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(4);
    let mut pairs = Vec::new();
    for _ in 0..4 {
        let bumps: Vec<Bump> = (0..8)
            .map(|_| ("b", rng.random_range(-5.0..5.0), rng.random_range(1.0..10.0), rng.random_range(1.5..4.0), rng.random_range(0.2..1.0)))
            .collect();
        let (points, deltas, triangles, names) = face(&bumps);
        let rig = RigView::new(&points, &deltas, &triangles, &names).unwrap();
        let live: Vec<usize> = (0..names.len()).collect();
        let shape_deltas: Vec<&[[f32; 3]]> = live.iter().map(|&k| rig.delta(k)).collect();
        let weight = error_weight(&shape_deltas);
        let sigma = 0.002 * rig.bbox_diagonal();
        for size in [2, 4, 6, 9, 14, 20, 30] {
            let vertices: Vec<u32> = rand::seq::index::sample(&mut rng, points.len(), size).iter().map(|v| v as u32).collect();
            let measured = score_layout(&rig, &vertices, &ScoreParams::default()).unwrap().mean;
            let predicted = predicted_error(&shape_deltas, &weight, &vertices, sigma * sigma) / rig.bbox_diagonal();
            pairs.push((predicted.ln(), measured.ln()));
        }
    }
    let n = pairs.len() as f64;
    let (mx, my) = (pairs.iter().map(|p| p.0).sum::<f64>() / n, pairs.iter().map(|p| p.1).sum::<f64>() / n);
    let cov: f64 = pairs.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let (vx, vy): (f64, f64) = (pairs.iter().map(|p| (p.0 - mx).powi(2)).sum(), pairs.iter().map(|p| (p.1 - my).powi(2)).sum());
    let correlation = cov / (vx * vy).sqrt();
    assert!(correlation > 0.8, "correlation of log errors {correlation}: {pairs:?}");
}
