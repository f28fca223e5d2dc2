//! Driving the rig from a performance (method, section 6; the use the layouts of Zell & McDonnell
//! 2022, `zell2022landmarks`, exist for): per frame, the head's rigid pose and the shape
//! weights `0 <= w <= 1` that best explain tracked landmarks, from 3D trajectories or from 2D
//! tracks through a calibrated camera. The landmark tool's noise model (Gaussian tracker
//! noise, bounded least squares over the landmark rows of `D`) with the pose as further
//! unknowns.
//!
//! | method, section 6 | Here |
//! |---|---|
//! | `R_t, c_t` | [`Pose::rotation`], [`Pose::translation`] ([`Pose::scale`] optional) |
//! | `w_t` | [`SolvedFrame::weights`] |
//! | `P` | identity ([`Tracks::Points`]) or [`Camera::project`] ([`Tracks::Pixels`]) |
//! | `rho` | Huber's loss, [`PerformanceParams::huber`] |
//! | `lambda` | [`PerformanceParams::smoothing`] |
//!
//! # Deviations
//! - Residuals are measured in units of the tracker's noise (`noise_points` of the rig's
//!   diagonal, or `noise_pixels`), so that `lambda` means the same on every rig: a weight
//!   change of 1 between frames costs as much as `lambda` squared noise-sized residuals.
//! - The first frame's pose comes from the landmarks no shape moves (Kabsch with the rig's
//!   scale; all landmarks at zero weights when fewer than 3 are rigid); for 2D tracks the
//!   caller's starting rotation is kept and the head moved along the tracks' mean ray to the
//!   depth that matches their spread (no PnP), then the pose is fitted alone before the
//!   weights join. Later frames start from the previous frame (and, for 3D, from a Kabsch fit
//!   on every landmark at the previous weights when that explains the frame better).
//! - Shapes no landmark moves are held at 0 and reported as `unseen`; inert shapes likewise.

pub mod camera;
mod frame;
pub mod pose;
#[cfg(test)]
mod tests;

use serde::Serialize;

use crate::error::ShapesmithResult;
use crate::geometry::mat3::{dot, mat_vec, scale, sub, transpose, Vec3};
use crate::invalid;
use crate::progress::Progress;
use crate::rig::{RigView, INERT_FRACTION};
pub use camera::Camera;
use frame::{FrameSolver, LandmarkBasis, Measurement, Projection, State};
pub use pose::Pose;

/// Solve Performance's settings ([`crate::settings`]); the start pose is the head's
/// placement, data, `#[serde(skip)]`.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PerformanceParams {
    /// `lambda`: the penalty on `|w_t - w_{t-1}|^2` against residuals in noise units; 0 solves
    /// every frame on its own.
    pub smoothing: f64,
    /// The 3D tracker's noise per coordinate, as a fraction of the rig's bounding-box diagonal.
    pub noise_points: f64,
    /// The 2D tracker's noise per coordinate, in pixels.
    pub noise_pixels: f64,
    /// Huber's threshold in noise units (a landmark further off counts linearly); `None` is
    /// plain least squares.
    pub huber: Option<f64>,
    /// Solve a uniform scale per frame (3D only: one camera cannot tell size from distance).
    pub solve_scale: bool,
    /// Levenberg-Marquardt iterations per frame, at most.
    pub iterations: usize,
    /// A landmark is rigid (used for the first pose) when no shape moves it by more than this
    /// fraction of the largest landmark displacement of the rig.
    pub rigid_fraction: f64,
    /// The head's pose to start from: its scale is kept unless `solve_scale`, and with 2D
    /// tracks its rotation is the first frame's first guess.
    #[serde(skip)]
    pub start: Pose,
}

impl Default for PerformanceParams {
    fn default() -> Self {
        Self {
            smoothing: 1.0,
            noise_points: 1e-3,
            noise_pixels: 1.0,
            huber: Some(3.0),
            solve_scale: false,
            iterations: 30,
            rigid_fraction: 0.05,
            start: Pose::default(),
        }
    }
}

/// The tracked landmarks, frame-major (`T x L`); a non-finite coordinate marks a landmark lost
/// on that frame.
#[derive(Clone, Copy, Debug)]
pub enum Tracks<'a> {
    /// Positions in the space the head's pose maps the rig into.
    Points(&'a [[f64; 3]]),
    /// Pixels from the image's bottom-left corner, seen through the camera.
    Pixels(&'a [[f64; 2]], Camera),
}

impl Tracks<'_> {
    fn len(&self) -> usize {
        match self {
            Tracks::Points(values) => values.len(),
            Tracks::Pixels(values, _) => values.len(),
        }
    }

    fn measurement(&self, index: usize, landmark: usize) -> Option<Measurement> {
        let value = match self {
            Tracks::Points(values) => values[index],
            Tracks::Pixels(values, _) => [values[index][0], values[index][1], 0.0],
        };
        value.iter().all(|v| v.is_finite()).then_some(Measurement { landmark, value })
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct SolvedFrame {
    pub pose: Pose,
    /// One weight per shape of the rig (0 for unseen and inert shapes).
    pub weights: Vec<f64>,
    /// RMS distance between the tracked and the solved landmarks, in the tracks' units (object
    /// units or pixels); `None` on a kept frame.
    pub residual: Option<f64>,
    /// Landmarks tracked on this frame.
    pub observed: usize,
    /// No landmark was tracked: the frame repeats its nearest solved neighbour.
    pub kept: bool,
    pub iterations: usize,
}

#[derive(Clone, Debug, Serialize)]
pub struct Performance {
    pub frames: Vec<SolvedFrame>,
    /// Indices (into the caller's landmarks) of the landmarks no shape moves.
    pub rigid: Vec<usize>,
    /// Shapes no landmark moves: held at 0.
    pub unseen: Vec<usize>,
    pub inert: Vec<usize>,
    /// Frames without any tracked landmark.
    pub kept: Vec<usize>,
}

/// Solves every frame in order (method, section 6), warm-started from the previous one.
/// `landmarks` are the rig's vertices the tracks follow, in the tracks' column order.
pub fn solve_performance(
    rig: &RigView,
    landmarks: &[u32],
    tracks: &Tracks,
    params: &PerformanceParams,
    progress: &dyn Progress,
) -> ShapesmithResult<Performance> {
    rig.validate()?;
    validate(rig, landmarks, tracks, params)?;
    let count = landmarks.len();
    let frames = tracks.len() / count;
    let inert = rig.inert_shapes();
    let floor = INERT_FRACTION * rig.bbox_diagonal();
    let moves = |k: usize| landmarks.iter().map(|&v| crate::rig::norm(&rig.delta(k)[v as usize])).fold(0.0, f64::max);
    let unseen: Vec<usize> = (0..rig.n_shapes()).filter(|k| !inert.contains(k) && moves(*k) <= floor).collect();
    let shapes: Vec<usize> = (0..rig.n_shapes()).filter(|k| !inert.contains(k) && !unseen.contains(k)).collect();
    let basis = LandmarkBasis {
        neutral: landmarks.iter().map(|&v| rig.neutral[v as usize].map(f64::from)).collect(),
        deltas: landmarks.iter().flat_map(|&v| shapes.iter().map(move |&k| rig.delta(k)[v as usize].map(f64::from))).collect(),
        shapes: shapes.clone(),
    };
    let largest = (0..rig.n_shapes()).map(moves).fold(0.0, f64::max);
    let rigid: Vec<usize> = (0..count)
        .filter(|&l| shapes.iter().all(|&k| crate::rig::norm(&rig.delta(k)[landmarks[l] as usize]) <= params.rigid_fraction * largest))
        .collect();
    let (projection, sigma) = match tracks {
        Tracks::Points(_) => (Projection::Points, params.noise_points * rig.bbox_diagonal() * params.start.scale),
        Tracks::Pixels(_, camera) => (Projection::Camera(camera), params.noise_pixels),
    };
    let solver = FrameSolver {
        basis: &basis,
        projection,
        sigma,
        huber: params.huber,
        smoothing: params.smoothing,
        solve_scale: params.solve_scale,
        iterations: params.iterations,
    };
    let mut solved: Vec<Option<(State, f64, usize, usize)>> = Vec::with_capacity(frames);
    let mut previous: Option<State> = None;
    for t in 0..frames {
        if t % 4 == 0 {
            progress.checkpoint(t as f64 / frames as f64)?;
        }
        let measurements: Vec<Measurement> = (0..count).filter_map(|l| tracks.measurement(t * count + l, l)).collect();
        if measurements.is_empty() {
            solved.push(None);
            continue;
        }
        let fit = match &previous {
            None => {
                let start = first_guess(&basis, &measurements, tracks, &rigid, params);
                let placed = solver.solve(&measurements, start, None, false);
                solver.solve(&measurements, placed.state, None, true)
            }
            Some(last) => {
                let mut start = last.clone();
                if let Tracks::Points(_) = tracks {
                    let source: Vec<Vec3> = measurements.iter().map(|m| scale(basis.position(m.landmark, &last.weights), last.pose.scale)).collect();
                    let target: Vec<Vec3> = measurements.iter().map(|m| m.value).collect();
                    if let Some(fitted) = pose::fit_pose(&source, &target, &vec![1.0; source.len()], false) {
                        let candidate = State { pose: Pose { scale: last.pose.scale, ..fitted }, weights: last.weights.clone() };
                        let anchor = Some(last.weights.as_slice());
                        if solver.cost_at(&measurements, &candidate, anchor) < solver.cost_at(&measurements, &start, anchor) {
                            start = candidate;
                        }
                    }
                }
                solver.solve(&measurements, start, Some(&last.weights), true)
            }
        };
        previous = Some(fit.state.clone());
        solved.push(Some((fit.state, fit.residual, measurements.len(), fit.iterations)));
    }
    progress.checkpoint(1.0)?;
    if solved.iter().all(Option::is_none) {
        return Err(invalid!("no landmark is tracked on any of the {frames} frames: check the tracks' names and values"));
    }
    let expand = |weights: &[f64]| {
        let mut all = vec![0.0; rig.n_shapes()];
        for (c, &k) in shapes.iter().enumerate() {
            all[k] = weights[c];
        }
        all
    };
    let mut out: Vec<SolvedFrame> = Vec::with_capacity(frames);
    let kept: Vec<usize> = (0..frames).filter(|&t| solved[t].is_none()).collect();
    for t in 0..frames {
        let (state, residual, observed, iterations, was_kept) = match &solved[t] {
            Some((state, residual, observed, iterations)) => (state, Some(*residual), *observed, *iterations, false),
            None => {
                // The nearest solved frame before, else after.
                let source = (0..t).rev().chain(t + 1..frames).find(|&u| solved[u].is_some()).expect("some frame is solved");
                let (state, ..) = solved[source].as_ref().expect("solved");
                (state, None, 0, 0, true)
            }
        };
        out.push(SolvedFrame { pose: state.pose, weights: expand(&state.weights), residual, observed, kept: was_kept, iterations });
    }
    Ok(Performance { frames: out, rigid, unseen, inert, kept })
}

fn validate(rig: &RigView, landmarks: &[u32], tracks: &Tracks, params: &PerformanceParams) -> ShapesmithResult<()> {
    if landmarks.is_empty() {
        return Err(invalid!("no landmarks given: the tracks must follow at least one vertex of the rig"));
    }
    if let Some(&bad) = landmarks.iter().find(|&&v| v as usize >= rig.n_vertices()) {
        return Err(invalid!("landmark vertex {bad} does not exist: the mesh has {} vertices", rig.n_vertices()));
    }
    if tracks.len() == 0 || !tracks.len().is_multiple_of(landmarks.len()) {
        return Err(invalid!(
            "the tracks hold {} values, not a whole number of frames of {} landmarks",
            tracks.len(),
            landmarks.len()
        ));
    }
    let positive = |value: f64, what: &str| {
        if value > 0.0 && value.is_finite() {
            Ok(())
        } else {
            Err(invalid!("{what} must be a positive number, got {value}"))
        }
    };
    positive(params.noise_points, "the 3D noise")?;
    positive(params.noise_pixels, "the 2D noise")?;
    positive(params.start.scale, "the head's scale")?;
    if let Some(limit) = params.huber {
        positive(limit, "the Huber threshold")?;
    }
    if !(params.smoothing >= 0.0 && params.smoothing.is_finite()) {
        return Err(invalid!("the smoothing must be a finite number >= 0, got {}", params.smoothing));
    }
    if params.iterations == 0 {
        return Err(invalid!("the solve needs at least one iteration per frame"));
    }
    let start = &params.start;
    if start.rotation.iter().flatten().chain(&start.translation).any(|v| !v.is_finite()) {
        return Err(invalid!("the head's starting pose is not finite"));
    }
    if let Tracks::Pixels(_, camera) = tracks {
        camera.validate()?;
        if params.solve_scale {
            return Err(invalid!("the head's scale cannot be solved from one camera (it trades against distance): turn scale off"));
        }
    }
    Ok(())
}

/// The first solved frame's starting state (see the module's deviations): weights 0.
fn first_guess(basis: &LandmarkBasis, measurements: &[Measurement], tracks: &Tracks, rigid: &[usize], params: &PerformanceParams) -> State {
    let weights = vec![0.0; basis.n_shapes()];
    let s = params.start.scale;
    let pose = match tracks {
        Tracks::Points(_) => {
            let rigid_seen: Vec<&Measurement> = measurements.iter().filter(|m| rigid.contains(&m.landmark)).collect();
            let chosen: Vec<&Measurement> = if rigid_seen.len() >= 3 { rigid_seen } else { measurements.iter().collect() };
            let source: Vec<Vec3> = chosen.iter().map(|m| scale(basis.neutral[m.landmark], s)).collect();
            let target: Vec<Vec3> = chosen.iter().map(|m| m.value).collect();
            match pose::fit_pose(&source, &target, &vec![1.0; source.len()], params.solve_scale) {
                Some(fitted) => Pose { scale: s * fitted.scale, ..fitted },
                None => params.start,
            }
        }
        Tracks::Pixels(_, camera) => place_along_rays(basis, measurements, camera, &params.start),
    };
    State { pose, weights }
}

/// Keeps the starting rotation and scale, and moves the head so that its landmarks' centroid
/// lies on the tracks' mean ray at the depth where the rig's spread matches the tracks'.
fn place_along_rays(basis: &LandmarkBasis, measurements: &[Measurement], camera: &Camera, start: &Pose) -> Pose {
    let n = measurements.len() as f64;
    let rays: Vec<[f64; 2]> = measurements.iter().map(|m| camera.normalised([m.value[0], m.value[1]])).collect();
    let ray_centre = rays.iter().fold([0.0; 2], |acc, r| [acc[0] + r[0] / n, acc[1] + r[1] / n]);
    let ray_spread = (rays.iter().map(|r| (r[0] - ray_centre[0]).powi(2) + (r[1] - ray_centre[1]).powi(2)).sum::<f64>() / n).sqrt();
    // The rig's landmarks turned into the camera's axes (no translation).
    let turned: Vec<Vec3> = measurements
        .iter()
        .map(|m| mat_vec(&camera.rotation, scale(mat_vec(&start.rotation, basis.neutral[m.landmark]), start.scale)))
        .collect();
    let centre = turned.iter().fold([0.0; 3], |acc, p| [acc[0] + p[0] / n, acc[1] + p[1] / n, acc[2] + p[2] / n]);
    let spread = (turned.iter().map(|p| (p[0] - centre[0]).powi(2) + (p[1] - centre[1]).powi(2)).sum::<f64>() / n).sqrt();
    if !(ray_spread > 0.0 && spread > 0.0) {
        return *start;
    }
    let depth = spread / ray_spread;
    // The centroid's place in the camera's frame, then in the world.
    let wanted = [ray_centre[0] * depth, ray_centre[1] * depth, -depth];
    let world_centre = mat_vec(&transpose(&camera.rotation), sub(wanted, camera.translation));
    let model_centre = mat_vec(&transpose(&camera.rotation), centre);
    let translation = sub(world_centre, model_centre);
    debug_assert!(dot(translation, translation).is_finite());
    Pose { translation, ..*start }
}
