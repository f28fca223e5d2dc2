//! Known answers: a small synthetic rig animated with random smooth weights and a rigid head
//! motion, its landmarks measured exactly, with noise, partly lost, and through a camera.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::pose::rotation_from_vector;
use super::*;
use crate::geometry::mat3::{add, Mat3};
use crate::progress::NoProgress;

const SHAPES: usize = 8;
const LANDMARKS: usize = 40;
const RIGID: usize = 6;
const FRAMES: usize = 24;

struct Fixture {
    neutral: Vec<[f32; 3]>,
    deltas: Vec<[f32; 3]>,
    names: Vec<String>,
    /// True weights and poses per frame.
    weights: Vec<Vec<f64>>,
    poses: Vec<Pose>,
}

/// 40 vertices on an ellipsoid about 0.25 units across (a head); the first 6 move in no
/// shape; each shape moves 12 random others by up to 0.02.
fn fixture(seed: u64, head_scale: f64) -> Fixture {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let neutral: Vec<[f32; 3]> = (0..LANDMARKS)
        .map(|i| {
            let (a, b) = (i as f64 * 2.4, (i as f64 * 0.37).sin() * 1.2);
            [(0.09 * a.cos() * b.cos()) as f32, (0.11 * a.sin() * b.cos()) as f32, (0.12 * b.sin()) as f32]
        })
        .collect();
    let mut deltas = vec![[0.0f32; 3]; SHAPES * LANDMARKS];
    for k in 0..SHAPES {
        for _ in 0..12 {
            let v = rng.random_range(RIGID..LANDMARKS);
            deltas[k * LANDMARKS + v] = std::array::from_fn(|_| rng.random_range(-0.02f32..0.02));
        }
    }
    let names = (0..SHAPES).map(|k| format!("shape{k}")).collect();
    let phases: Vec<(f64, f64)> = (0..SHAPES).map(|_| (rng.random_range(0.0..6.3), rng.random_range(0.1..0.3))).collect();
    // Clamped sines: smooth, and resting on both bounds for stretches.
    let weights = (0..FRAMES)
        .map(|t| phases.iter().map(|(phase, speed)| (0.5 + 0.7 * (phase + speed * t as f64).sin()).clamp(0.0, 1.0)).collect())
        .collect();
    let poses = (0..FRAMES)
        .map(|t| {
            let t = t as f64;
            Pose {
                rotation: rotation_from_vector([0.2 * (0.1 * t).sin(), 0.3 * (0.07 * t).cos() - 0.2, 0.1 * (0.13 * t).sin()]),
                translation: [0.05 * (0.1 * t).sin(), 0.02 * t * 0.1, -0.03 * (0.05 * t).cos()],
                scale: head_scale,
            }
        })
        .collect();
    Fixture { neutral, deltas, names, weights, poses }
}

impl Fixture {
    fn rig(&self) -> RigView<'_> {
        RigView::new(&self.neutral, &self.deltas, &[], &self.names).unwrap()
    }

    fn landmarks(&self) -> Vec<u32> {
        (0..LANDMARKS as u32).collect()
    }

    /// The true world positions, frame-major.
    fn points(&self) -> Vec<[f64; 3]> {
        (0..FRAMES)
            .flat_map(|t| {
                (0..LANDMARKS).map(move |l| {
                    let mut local = self.neutral[l].map(f64::from);
                    for k in 0..SHAPES {
                        let d = self.deltas[k * LANDMARKS + l];
                        for a in 0..3 {
                            local[a] += self.weights[t][k] * d[a] as f64;
                        }
                    }
                    self.poses[t].apply(local)
                })
            })
            .collect()
    }
}

fn weight_error(solved: &Performance, truth: &Fixture) -> (f64, f64) {
    let mut sum = 0.0;
    let mut max = 0.0f64;
    for (frame, want) in solved.frames.iter().zip(&truth.weights) {
        for (a, b) in frame.weights.iter().zip(want) {
            sum += (a - b) * (a - b);
            max = max.max((a - b).abs());
        }
    }
    ((sum / (FRAMES * SHAPES) as f64).sqrt(), max)
}

fn rotation_error(a: &Mat3, b: &Mat3) -> f64 {
    (0..3).flat_map(|r| (0..3).map(move |c| (a[r][c] - b[r][c]).abs())).fold(0.0, f64::max)
}

fn exact() -> PerformanceParams {
    PerformanceParams { smoothing: 0.0, huber: None, ..PerformanceParams::default() }
}

#[test]
fn recovers_weights_and_pose_exactly_without_noise() {
    let truth = fixture(1, 1.0);
    let points = truth.points();
    let solved = solve_performance(&truth.rig(), &truth.landmarks(), &Tracks::Points(&points), &exact(), &NoProgress).unwrap();
    let unmoved: Vec<usize> = (0..LANDMARKS).filter(|&l| (0..SHAPES).all(|k| truth.deltas[k * LANDMARKS + l] == [0.0; 3])).collect();
    assert!(unmoved.starts_with(&(0..RIGID).collect::<Vec<_>>()));
    assert_eq!(solved.rigid, unmoved);
    let (rms, max) = weight_error(&solved, &truth);
    assert!(max < 1e-6, "weights off by {max} (rms {rms})");
    for (frame, pose) in solved.frames.iter().zip(&truth.poses) {
        assert!(rotation_error(&frame.pose.rotation, &pose.rotation) < 1e-7);
        assert!(crate::geometry::mat3::length(sub(frame.pose.translation, pose.translation)) < 1e-7);
        assert!(frame.residual.unwrap() < 1e-7 && !frame.kept && frame.observed == LANDMARKS);
    }
    // The default robust loss and smoothing change nothing where the data fit exactly.
    let robust = solve_performance(&truth.rig(), &truth.landmarks(), &Tracks::Points(&points), &PerformanceParams::default(), &NoProgress).unwrap();
    assert!(weight_error(&robust, &truth).1 < 1e-4);
}

#[test]
fn solves_the_head_scale_when_asked_and_keeps_the_given_one_otherwise() {
    let truth = fixture(2, 1.25);
    let points = truth.points();
    let tracks = Tracks::Points(&points);
    let params = PerformanceParams { solve_scale: true, ..exact() };
    let solved = solve_performance(&truth.rig(), &truth.landmarks(), &tracks, &params, &NoProgress).unwrap();
    assert!(weight_error(&solved, &truth).1 < 1e-6);
    assert!(solved.frames.iter().all(|f| (f.pose.scale - 1.25).abs() < 1e-8));
    let start = Pose { scale: 1.25, ..Pose::default() };
    let fixed = solve_performance(&truth.rig(), &truth.landmarks(), &tracks, &PerformanceParams { start, ..exact() }, &NoProgress).unwrap();
    assert!(weight_error(&fixed, &truth).1 < 1e-6);
    assert!(fixed.frames.iter().all(|f| f.pose.scale == 1.25));
}

#[test]
fn noise_gives_a_bounded_error_that_smoothing_lowers() {
    let truth = fixture(3, 1.0);
    let diagonal = truth.rig().bbox_diagonal();
    let mut rng = ChaCha8Rng::seed_from_u64(9);
    let sigma = 1e-3 * diagonal;
    let noisy: Vec<[f64; 3]> = truth
        .points()
        .iter()
        .map(|p| {
            let n: [f64; 3] = std::array::from_fn(|_| sigma * gaussian(&mut rng));
            add(*p, n)
        })
        .collect();
    let tracks = Tracks::Points(&noisy);
    let alone = solve_performance(&truth.rig(), &truth.landmarks(), &tracks, &PerformanceParams { smoothing: 0.0, ..Default::default() }, &NoProgress).unwrap();
    let smoothed = solve_performance(&truth.rig(), &truth.landmarks(), &tracks, &PerformanceParams { smoothing: 10.0, ..Default::default() }, &NoProgress).unwrap();
    let (rms_alone, max_alone) = weight_error(&alone, &truth);
    let (rms_smooth, _) = weight_error(&smoothed, &truth);
    // A landmark displacement of ~0.01 against noise 2.6e-4: weights to a few hundredths.
    assert!(rms_alone < 0.03 && max_alone < 0.15, "rms {rms_alone}, max {max_alone}");
    assert!(rms_smooth < rms_alone, "smoothing {rms_smooth} vs {rms_alone}");
    // The residual is the noise's size: sqrt(3) sigma less what the fit absorbs.
    for frame in &alone.frames {
        let r = frame.residual.unwrap();
        assert!(r > 0.5 * sigma && r < 2.5 * sigma, "residual {r} against sigma {sigma}");
    }
}

#[test]
fn lost_landmarks_are_skipped_and_an_empty_frame_keeps_its_neighbour() {
    let truth = fixture(4, 1.0);
    let mut points = truth.points();
    let mut rng = ChaCha8Rng::seed_from_u64(5);
    // Every frame loses 8 random landmarks (one coordinate is enough); frame 7 loses all,
    // and so does frame 0 (kept from frame 1).
    for t in 0..FRAMES {
        for _ in 0..8 {
            let l = rng.random_range(0..LANDMARKS);
            points[t * LANDMARKS + l][rng.random_range(0..3)] = f64::NAN;
        }
    }
    for t in [0, 7] {
        for l in 0..LANDMARKS {
            points[t * LANDMARKS + l] = [f64::NAN; 3];
        }
    }
    let solved = solve_performance(&truth.rig(), &truth.landmarks(), &Tracks::Points(&points), &exact(), &NoProgress).unwrap();
    assert_eq!(solved.kept, vec![0, 7]);
    for (t, frame) in solved.frames.iter().enumerate() {
        let lost = (0..LANDMARKS).filter(|&l| points[t * LANDMARKS + l].iter().any(|v| v.is_nan())).count();
        assert_eq!(frame.observed, LANDMARKS - lost);
        if t == 0 || t == 7 {
            assert!(frame.kept && frame.residual.is_none());
            let neighbour = &solved.frames[if t == 0 { 1 } else { 6 }];
            assert_eq!(frame.weights, neighbour.weights);
            assert_eq!(frame.pose, neighbour.pose);
        } else {
            let error = frame.weights.iter().zip(&truth.weights[t]).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max);
            assert!(error < 1e-6, "frame {t}: {error}");
        }
    }
}

#[test]
fn recovers_from_2d_tracks_through_a_distorting_camera() {
    let truth = fixture(6, 1.0);
    // A camera 0.8 units in front of the head (along +Y), looking back at it.
    let look = [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]];
    let camera = Camera {
        focal: [1800.0, 1800.0],
        principal: [960.0, 540.0],
        distortion: [-0.15, 0.05, -0.01],
        rotation: look,
        translation: mat_vec(&look, [0.0, -0.8, 0.0]).map(|v| -v),
    };
    let pixels: Vec<[f64; 2]> = truth.points().iter().map(|p| camera.project(*p).unwrap().0).collect();
    let tracks = Tracks::Pixels(&pixels, camera);
    let solved = solve_performance(&truth.rig(), &truth.landmarks(), &tracks, &exact(), &NoProgress).unwrap();
    let (rms, max) = weight_error(&solved, &truth);
    assert!(max < 1e-5, "weights off by {max} (rms {rms})");
    for (frame, pose) in solved.frames.iter().zip(&truth.poses) {
        assert!(rotation_error(&frame.pose.rotation, &pose.rotation) < 1e-5);
        assert!(frame.residual.unwrap() < 1e-5);
    }
    // Scale cannot be solved from one camera.
    let scaled = PerformanceParams { solve_scale: true, ..exact() };
    let error = solve_performance(&truth.rig(), &truth.landmarks(), &tracks, &scaled, &NoProgress).unwrap_err();
    assert!(error.to_string().contains("scale"), "{error}");
}

#[test]
fn rejects_unusable_tracks() {
    let truth = fixture(7, 1.0);
    let rig = truth.rig();
    let landmarks = truth.landmarks();
    let short = vec![[0.0; 3]; LANDMARKS + 1];
    let error = solve_performance(&rig, &landmarks, &Tracks::Points(&short), &exact(), &NoProgress).unwrap_err();
    assert!(error.to_string().contains("whole number of frames"), "{error}");
    let lost = vec![[f64::NAN; 3]; LANDMARKS * 3];
    let error = solve_performance(&rig, &landmarks, &Tracks::Points(&lost), &exact(), &NoProgress).unwrap_err();
    assert!(error.to_string().contains("no landmark is tracked"), "{error}");
    let error = solve_performance(&rig, &[0, 99], &Tracks::Points(&short[..4]), &exact(), &NoProgress).unwrap_err();
    assert!(error.to_string().contains("vertex 99"), "{error}");
    let negative = PerformanceParams { smoothing: -1.0, ..exact() };
    let points = truth.points();
    assert!(solve_performance(&rig, &landmarks, &Tracks::Points(&points), &negative, &NoProgress).is_err());
}

fn gaussian(rng: &mut ChaCha8Rng) -> f64 {
    let u: f64 = 1.0 - rng.random::<f64>();
    let v: f64 = rng.random();
    (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
}
