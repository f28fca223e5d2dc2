//! One frame's solve: Levenberg-Marquardt on the pose and the weights together (method, section 6),
//! each step a box-constrained quadratic program. The pose block has no bounds, so it is
//! eliminated (Schur complement) and the weights' program, `0 <= w <= 1`, goes to the shared
//! bounded solver; the pose step then follows from the weights.
//!
//! Objective of frame t, residuals in units of the tracker's noise `sigma`:
//! `E(pose, w) = sum_l rho(|P(s R (V0_l + D_l w) + t) - y_l|^2 / sigma^2) + lambda |w - w_{t-1}|^2`,
//! `rho` Huber's loss (quadratic up to `huber` sigmas, linear beyond; iteratively reweighted).

use crate::bounded::{cholesky_solve, solve_bounded, Gram};
use crate::geometry::mat3::{dot, mat_vec, scale, Vec3};

use super::camera::Camera;
use super::pose::Pose;

/// The landmarks' rows of the rig, precomputed once: `V0_l` and `D_{k,l}` for the solved
/// shapes only (`L x K x 3`), in f64.
pub struct LandmarkBasis {
    pub neutral: Vec<Vec3>,
    /// `deltas[(l * K + c)]` is shape `shapes[c]`'s displacement of landmark `l`.
    pub deltas: Vec<Vec3>,
    /// The rig's shape index of each solved weight.
    pub shapes: Vec<usize>,
}

impl LandmarkBasis {
    pub fn n_shapes(&self) -> usize {
        self.shapes.len()
    }

    /// `V0_l + sum_c w_c D_{c,l}`.
    pub fn position(&self, l: usize, weights: &[f64]) -> Vec3 {
        let k = self.n_shapes();
        let mut p = self.neutral[l];
        for (d, w) in self.deltas[l * k..(l + 1) * k].iter().zip(weights) {
            if *w != 0.0 {
                for a in 0..3 {
                    p[a] += w * d[a];
                }
            }
        }
        p
    }
}

/// What a landmark's measurement is: a 3D position, or a pixel seen through a camera.
#[derive(Clone, Copy)]
pub enum Projection<'a> {
    Points,
    Camera(&'a Camera),
}

impl Projection<'_> {
    fn rows(&self) -> usize {
        match self {
            Projection::Points => 3,
            Projection::Camera(_) => 2,
        }
    }
}

/// A tracked landmark on one frame: its index and its measured position (pixels in `[0..2]`).
#[derive(Clone, Copy, Debug)]
pub struct Measurement {
    pub landmark: usize,
    pub value: [f64; 3],
}

#[derive(Clone, Debug)]
pub struct State {
    pub pose: Pose,
    /// The solved shapes' weights, in [`LandmarkBasis::shapes`] order.
    pub weights: Vec<f64>,
}

pub struct FrameSolver<'a> {
    pub basis: &'a LandmarkBasis,
    pub projection: Projection<'a>,
    pub sigma: f64,
    pub huber: Option<f64>,
    pub smoothing: f64,
    pub solve_scale: bool,
    pub iterations: usize,
}

pub struct Fit {
    pub state: State,
    /// RMS over the measurements of the distance between measured and solved positions, in
    /// the measurements' units (object units or pixels).
    pub residual: f64,
    pub iterations: usize,
}

/// Residuals (scaled by `1 / sigma`) of every measurement, and with `jacobian` their rows
/// `d r / d(theta, t, [log s], w)`.
struct Linearisation {
    residuals: Vec<f64>,
    jacobian: Vec<f64>,
}

impl FrameSolver<'_> {
    fn pose_size(&self) -> usize {
        if self.solve_scale {
            7
        } else {
            6
        }
    }

    /// `None` when a landmark falls behind the camera.
    fn linearise(&self, measurements: &[Measurement], state: &State, jacobian: bool) -> Option<Linearisation> {
        let (m, p, k) = (self.projection.rows(), self.pose_size(), self.basis.n_shapes());
        let n = p + k;
        let mut residuals = Vec::with_capacity(m * measurements.len());
        let mut rows = if jacobian { vec![0.0; m * measurements.len() * n] } else { Vec::new() };
        let pose = &state.pose;
        let inv_sigma = 1.0 / self.sigma;
        for (i, measurement) in measurements.iter().enumerate() {
            let local = self.basis.position(measurement.landmark, &state.weights);
            let turned = scale(mat_vec(&pose.rotation, local), pose.scale);
            let x = [turned[0] + pose.translation[0], turned[1] + pose.translation[1], turned[2] + pose.translation[2]];
            // G = d(measurement) / dx, m x 3.
            let mut g = [[0.0; 3]; 3];
            match self.projection {
                Projection::Points => {
                    for a in 0..3 {
                        residuals.push((x[a] - measurement.value[a]) * inv_sigma);
                        g[a][a] = inv_sigma;
                    }
                }
                Projection::Camera(camera) => {
                    let (pixel, d) = camera.project(x)?;
                    for a in 0..2 {
                        residuals.push((pixel[a] - measurement.value[a]) * inv_sigma);
                        g[a] = d[a].map(|v| v * inv_sigma);
                    }
                }
            }
            if !jacobian {
                continue;
            }
            // dx/dtheta = -[a]_x with a = s R X; dx/dt = I; dx/dlog s = a; dx/dw_c = s R D_c.
            let skew = [[0.0, turned[2], -turned[1]], [-turned[2], 0.0, turned[0]], [turned[1], -turned[0], 0.0]];
            let deltas = &self.basis.deltas[measurement.landmark * k..(measurement.landmark + 1) * k];
            let sr: [[f64; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| pose.scale * pose.rotation[r][c]));
            for r in 0..m {
                let row = &mut rows[(i * m + r) * n..(i * m + r + 1) * n];
                let gr = g[r];
                for c in 0..3 {
                    row[c] = (0..3).map(|j| gr[j] * skew[j][c]).sum();
                    row[3 + c] = gr[c];
                }
                if self.solve_scale {
                    row[6] = dot(gr, turned);
                }
                let gsr: Vec3 = std::array::from_fn(|c| (0..3).map(|j| gr[j] * sr[j][c]).sum());
                for (out, d) in row[p..].iter_mut().zip(deltas) {
                    *out = dot(gsr, *d);
                }
            }
        }
        Some(Linearisation { residuals, jacobian: rows })
    }

    /// Huber's `rho` of each measurement's squared residual, and its reweighting factor.
    fn robust(&self, squared: f64) -> (f64, f64) {
        match self.huber {
            Some(limit) if squared > limit * limit => {
                let e = squared.sqrt();
                (2.0 * limit * e - limit * limit, limit / e)
            }
            _ => (squared, 1.0),
        }
    }

    fn cost(&self, residuals: &[f64], weights: &[f64], previous: Option<&[f64]>) -> f64 {
        let m = self.projection.rows();
        let data: f64 = residuals.chunks(m).map(|r| self.robust(r.iter().map(|v| v * v).sum()).0).sum();
        let smooth = previous.map_or(0.0, |prev| weights.iter().zip(prev).map(|(a, b)| (a - b) * (a - b)).sum::<f64>());
        data + self.smoothing * smooth
    }

    /// The objective `E` at `state` (infinite when a landmark falls behind the camera).
    pub fn cost_at(&self, measurements: &[Measurement], state: &State, previous: Option<&[f64]>) -> f64 {
        self.linearise(measurements, state, false).map_or(f64::INFINITY, |lin| self.cost(&lin.residuals, &state.weights, previous))
    }

    /// Solves the frame from `start`; `previous` is the last frame's weights (the smoothing's
    /// anchor), `free_weights` false holds the weights and fits the pose alone.
    pub fn solve(&self, measurements: &[Measurement], start: State, previous: Option<&[f64]>, free_weights: bool) -> Fit {
        let (m, p, k) = (self.projection.rows(), self.pose_size(), self.basis.n_shapes());
        let n = p + k;
        let mut state = start;
        let Some(mut current) = self.linearise(measurements, &state, true) else {
            return self.finish(measurements, state, 0);
        };
        let mut cost = self.cost(&current.residuals, &state.weights, previous);
        let mut damping = 1e-4;
        let mut iterations = 0;
        // Residuals a millionth of the noise: nothing left to explain.
        let negligible = 1e-12 * current.residuals.len() as f64;
        while iterations < self.iterations && cost > negligible {
            iterations += 1;
            // Normal equations of the reweighted linearisation: H = J^T A J, b = J^T A r.
            let mut h = vec![0.0; n * n];
            let mut b = vec![0.0; n];
            for (i, residual) in current.residuals.chunks(m).enumerate() {
                let (_, factor) = self.robust(residual.iter().map(|v| v * v).sum());
                for r in 0..m {
                    let row = &current.jacobian[(i * m + r) * n..(i * m + r + 1) * n];
                    let value = residual[r];
                    for a in 0..n {
                        let ra = factor * row[a];
                        if ra == 0.0 {
                            continue;
                        }
                        b[a] += ra * value;
                        for c in a..n {
                            h[a * n + c] += ra * row[c];
                        }
                    }
                }
            }
            for a in 0..n {
                for c in 0..a {
                    h[a * n + c] = h[c * n + a];
                }
            }
            let largest = (0..n).map(|a| h[a * n + a]).fold(0.0, f64::max).max(f64::MIN_POSITIVE);
            let mut accepted = false;
            for _ in 0..8 {
                let candidate = self.step(&h, &b, &state, previous, damping, largest, free_weights);
                if let Some(next) = self.linearise(measurements, &candidate, true) {
                    let next_cost = self.cost(&next.residuals, &candidate.weights, previous);
                    if next_cost < cost {
                        let gain = cost - next_cost;
                        state = candidate;
                        current = next;
                        cost = next_cost;
                        damping = (damping / 3.0).max(1e-12);
                        // Converged when a step gains less than this share of the objective.
                        accepted = gain > 1e-9 * cost;
                        break;
                    }
                }
                damping *= 4.0;
            }
            if !accepted {
                break;
            }
        }
        self.finish(measurements, state, iterations)
    }

    /// The damped step's answer: pose step and new weights from
    /// `min 1/2 |r + J_p dp + J_w (w' - w)|^2 + lambda/2 |w' - w_prev|^2 + mu/2 (|dp|_D^2 + |w' - w|_D^2)`,
    /// `0 <= w' <= 1`, with `D` the diagonal of `J^T J` (Marquardt's scaling).
    #[allow(clippy::too_many_arguments)]
    fn step(&self, h: &[f64], b: &[f64], state: &State, previous: Option<&[f64]>, damping: f64, largest: f64, free_weights: bool) -> State {
        let (p, k) = (self.pose_size(), self.basis.n_shapes());
        let n = p + k;
        let floor = 1e-12 * largest;
        let damped = |a: usize| h[a * n + a] + damping * h[a * n + a].max(floor);
        let mut hpp: Vec<f64> = (0..p * p).map(|ij| h[(ij / p) * n + ij % p]).collect();
        for a in 0..p {
            hpp[a * p + a] = damped(a);
        }
        // Pose-block inverse, column by column (p <= 7).
        let inverse: Vec<Vec<f64>> = (0..p)
            .map(|c| cholesky_solve(hpp.clone(), (0..p).map(|r| if r == c { 1.0 } else { 0.0 }).collect(), p, floor))
            .collect();
        let apply_inverse = |v: &[f64]| -> Vec<f64> { (0..p).map(|r| (0..p).map(|c| inverse[c][r] * v[c]).sum()).collect() };
        // The linear term in the pose step: g_p = -J_p^T (r - J_w w) = -(b_p - H_pw w).
        let w0 = &state.weights;
        let gp: Vec<f64> = (0..p).map(|a| -(b[a] - (0..k).map(|c| h[a * n + p + c] * w0[c]).sum::<f64>())).collect();
        let weights = if free_weights && k > 0 {
            // Reduced program in w': H' = H_ww + (lambda + mu D) - H_wp H_pp^-1 H_pw,
            // g' = -(b_w - H_ww w) + lambda w_prev + mu D w - H_wp H_pp^-1 g_p.
            let columns: Vec<Vec<f64>> = (0..k).map(|c| apply_inverse(&(0..p).map(|a| h[a * n + p + c]).collect::<Vec<_>>())).collect();
            let pose_term = apply_inverse(&gp);
            let mut values = vec![0.0; k * k];
            let mut g = vec![0.0; k];
            for i in 0..k {
                let hi = p + i;
                for j in 0..k {
                    let coupling: f64 = (0..p).map(|a| h[a * n + hi] * columns[j][a]).sum();
                    values[i * k + j] = h[hi * n + p + j] - coupling;
                }
                let mu = damping * h[hi * n + hi].max(floor);
                values[i * k + i] += self.smoothing * previous.is_some() as u8 as f64 + mu;
                let hw0: f64 = (0..k).map(|j| h[hi * n + p + j] * w0[j]).sum();
                g[i] = -(b[hi] - hw0) + mu * w0[i] + previous.map_or(0.0, |prev| self.smoothing * prev[i])
                    - (0..p).map(|a| h[a * n + hi] * pose_term[a]).sum::<f64>();
            }
            solve_bounded(&Gram { size: k, values }, &g, &vec![0.0; k], &vec![1.0; k])
        } else {
            w0.clone()
        };
        // dp = H_pp^-1 (g_p - H_pw w').
        let rhs: Vec<f64> = (0..p).map(|a| gp[a] - (0..k).map(|c| h[a * n + p + c] * weights[c]).sum::<f64>()).collect();
        let dp = apply_inverse(&rhs);
        let log_scale = if self.solve_scale { dp[6] } else { 0.0 };
        State { pose: state.pose.stepped([dp[0], dp[1], dp[2]], [dp[3], dp[4], dp[5]], log_scale), weights }
    }

    fn finish(&self, measurements: &[Measurement], state: State, iterations: usize) -> Fit {
        let m = self.projection.rows();
        let residual = match self.linearise(measurements, &state, false) {
            Some(lin) if !measurements.is_empty() => {
                let sum: f64 = lin.residuals.chunks(m).map(|r| r.iter().map(|v| v * v).sum::<f64>()).sum();
                self.sigma * (sum / measurements.len() as f64).sqrt()
            }
            _ => f64::INFINITY,
        };
        Fit { state, residual, iterations }
    }
}
