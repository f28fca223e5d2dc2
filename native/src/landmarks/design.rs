//! Conditioned layouts (SPEC section 2, "Conditioned layouts"; beyond paper 003): after the
//! proven-optimal cover, landmarks are added greedily by an experimental-design criterion on
//! the landmark rows of `D`, so that the weights can be told apart under tracker noise.
//!
//! # The model behind the criterion
//! A tracker measures landmark offsets `y = D_F w + e`, `e ~ N(0, sigma^2 I)` (3 rows per
//! landmark, `sigma` = the score's noise). The bounded least squares of [`super::score`]
//! keeps `0 <= w <= 1`; here that bound enters as a prior of the same spread, `w_k` of
//! variance `1/12` (uniform on [0, 1]). The posterior covariance of the weights is then
//! `P = (D_F^T D_F / sigma^2 + 12 I)^{-1}` and the expected squared error of the rebuilt mesh,
//! per vertex, is `tr(W P)` with `W = D^T D / N` (all 3N rows). So
//! `predicted error = sqrt(tr(W P)) / diagonal`: the RMS vertex error the reconstruction is
//! expected to make, on the score's scale (the score reports the mean, not the RMS, and clips
//! at the bounds, so it sits below the prediction; they rise and fall together, which the
//! tests assert).
//!
//! # Criteria
//! - [`Criterion::A`] (default): minimise `tr(W P)`, i.e. the predicted error itself (a
//!   weighted A-optimal design, also called V- or I-optimal). Not submodular in general; the
//!   greedy bound `1 - exp(-gamma)` holds with the submodularity ratio `gamma` (Das & Kempe
//!   2011), which the tests compute by brute force and assert.
//! - [`Criterion::D`]: maximise `log det P^{-1}`, monotone submodular: greedy is within
//!   `1 - 1/e` of the best subset (Nemhauser, Wolsey & Fisher 1978), asserted too.
//!
//! Both gains come from the Woodbury identity: adding a unit with rows `B` (r x K),
//! `S = sigma^2 I_r + B P B^T`, `P' = P - P B^T S^{-1} B P`; the A-gain is
//! `tr(S^{-1} B (P W P) B^T)` and the D-gain `log det(S / sigma^2)`. Every step evaluates all
//! units with two matrix products `R P`, `R (P W P)` over the stacked rows `R` of the pool,
//! then updates `P` by the rank-r formula (exact greedy, no lazy approximation).

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use rayon::prelude::*;
use serde::Serialize;

use crate::geometry::neighbours::PointTree;

/// The prior precision of a weight: `1 / Var(U[0, 1]) = 12`.
pub const PRIOR_PRECISION: f64 = 12.0;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Criterion {
    /// Weighted A-optimal: the predicted reconstruction error.
    A,
    /// D-optimal: the log-determinant of the information.
    D,
}

/// A design problem over K live shapes: the pool's units (one vertex, or a vertex and its
/// mirror partner, whose rows enter together), the weight `W = D^T D / N`, the noise.
pub struct DesignProblem {
    pub k: usize,
    /// Rows per unit: 3 per vertex, each K long (row-major).
    pub units: Vec<Vec<f64>>,
    /// `W`, K x K row-major.
    pub weight: Vec<f64>,
    pub noise_variance: f64,
}

/// One greedy step: the unit chosen and the predicted error after it (in the units of `W`'s
/// square root, i.e. mesh units; divide by the diagonal to compare with the score).
#[derive(Clone, Debug, PartialEq)]
pub struct Step {
    pub unit: usize,
    pub predicted: f64,
}

/// The posterior covariance `P`, K x K.
#[derive(Clone, Debug)]
pub struct Posterior {
    k: usize,
    p: Mat<f64>,
}

impl Posterior {
    /// `P = (B^T B / sigma^2 + 12 I)^{-1}` for the given rows (each K long).
    pub fn new(k: usize, rows: &[&[f64]], noise_variance: f64) -> Self {
        let mut information = Mat::<f64>::from_fn(k, k, |i, j| if i == j { PRIOR_PRECISION } else { 0.0 });
        for row in rows {
            for i in 0..k {
                for j in 0..k {
                    information[(i, j)] += row[i] * row[j] / noise_variance;
                }
            }
        }
        Self { k, p: spd_inverse(&information) }
    }

    /// `tr(W P)`, the predicted mean squared vertex error.
    pub fn expected_squared_error(&self, weight: &[f64]) -> f64 {
        (0..self.k).flat_map(|i| (0..self.k).map(move |j| (i, j))).map(|(i, j)| weight[i * self.k + j] * self.p[(j, i)]).sum()
    }

    /// Adds the rows `b` (r x K, row-major) by the Woodbury identity.
    fn add(&mut self, b: &[f64], noise_variance: f64) {
        let k = self.k;
        let r = b.len() / k;
        let bp = Mat::<f64>::from_fn(r, k, |i, c| (0..k).map(|j| b[i * k + j] * self.p[(j, c)]).sum());
        let s = Mat::<f64>::from_fn(r, r, |i, j| {
            (0..k).map(|c| bp[(i, c)] * b[j * k + c]).sum::<f64>() + if i == j { noise_variance } else { 0.0 }
        });
        let s_inv = spd_inverse(&s);
        let correction = bp.transpose() * &s_inv * &bp;
        self.p -= &correction;
        // Keep P exactly symmetric against rounding.
        for i in 0..k {
            for j in 0..i {
                let mean = 0.5 * (self.p[(i, j)] + self.p[(j, i)]);
                self.p[(i, j)] = mean;
                self.p[(j, i)] = mean;
            }
        }
    }
}

/// The Cholesky factor `L` (lower, `L L^T = m`) of a small symmetric positive definite
/// matrix; a pivot that rounding drives to zero is floored, not a failure.
fn cholesky(m: &Mat<f64>) -> Mat<f64> {
    let n = m.nrows();
    let mut l = Mat::<f64>::zeros(n, n);
    for j in 0..n {
        let d = (m[(j, j)] - (0..j).map(|c| l[(j, c)] * l[(j, c)]).sum::<f64>()).max(f64::MIN_POSITIVE).sqrt();
        l[(j, j)] = d;
        for i in j + 1..n {
            l[(i, j)] = (m[(i, j)] - (0..j).map(|c| l[(i, c)] * l[(j, c)]).sum::<f64>()) / d;
        }
    }
    l
}

/// Inverse of a small symmetric positive definite matrix by Cholesky.
fn spd_inverse(m: &Mat<f64>) -> Mat<f64> {
    let n = m.nrows();
    let l = cholesky(m);
    // Columns of L^{-T} L^{-1}: solve L L^T x = e_c.
    let mut inverse = Mat::<f64>::zeros(n, n);
    for c in 0..n {
        let mut x = vec![0.0; n];
        for i in 0..n {
            let rhs = if i == c { 1.0 } else { 0.0 } - (0..i).map(|j| l[(i, j)] * x[j]).sum::<f64>();
            x[i] = rhs / l[(i, i)];
        }
        for i in (0..n).rev() {
            let rhs = x[i] - (i + 1..n).map(|j| l[(j, i)] * x[j]).sum::<f64>();
            x[i] = rhs / l[(i, i)];
        }
        for i in 0..n {
            inverse[(i, c)] = x[i];
        }
    }
    inverse
}

/// The gains of every allowed unit for the current `P`: A-gain `tr(S^{-1} B P W P B^T)` or
/// D-gain `log det(S / sigma^2)`, with `S = sigma^2 I + B P B^T` (module docs); `-inf` for
/// the others, which no step may choose.
fn gains(
    problem: &DesignProblem,
    stacked: MatRef<'_, f64>,
    offsets: &[usize],
    posterior: &Posterior,
    criterion: Criterion,
    allowed: &[bool],
) -> Vec<f64> {
    let k = problem.k;
    let p = posterior.p.as_ref();
    let rows = stacked.nrows();
    let mut rp = Mat::<f64>::zeros(rows, k);
    matmul(rp.as_mut(), Accum::Replace, stacked, p, 1.0, Par::rayon(0));
    let rq = match criterion {
        Criterion::D => None,
        Criterion::A => {
            let w = MatRef::from_row_major_slice(&problem.weight, k, k);
            let pwp = p * w * p;
            let mut rq = Mat::<f64>::zeros(rows, k);
            matmul(rq.as_mut(), Accum::Replace, stacked, pwp.as_ref(), 1.0, Par::rayon(0));
            Some(rq)
        }
    };
    let sigma2 = problem.noise_variance;
    // Each unit's gain on its own: in parallel, in order, the same numbers as in series.
    (0..problem.units.len())
        .into_par_iter()
        .map(|u| {
            if !allowed[u] {
                return f64::NEG_INFINITY;
            }
            let (start, end) = (offsets[u], offsets[u + 1]);
            let r = end - start;
            let inner = |left: &Mat<f64>, i: usize, j: usize| (0..k).map(|c| left[(start + i, c)] * stacked[(start + j, c)]).sum::<f64>();
            let s = Mat::<f64>::from_fn(r, r, |i, j| inner(&rp, i, j) + if i == j { sigma2 } else { 0.0 });
            match &rq {
                None => log_det_spd(&s) - r as f64 * sigma2.ln(),
                Some(rq) => {
                    let t = Mat::<f64>::from_fn(r, r, |i, j| inner(rq, i, j));
                    let s_inv = spd_inverse(&s);
                    (0..r).flat_map(|i| (0..r).map(move |j| (i, j))).map(|(i, j)| s_inv[(i, j)] * t[(j, i)]).sum()
                }
            }
        })
        .collect()
}

fn log_det_spd(m: &Mat<f64>) -> f64 {
    let l = cholesky(m);
    (0..m.nrows()).map(|j| 2.0 * l[(j, j)].ln()).sum()
}

/// Greedy design from the posterior of the `initial` rows: each step adds the allowed unit
/// with the largest gain (lowest index on a tie) and records the predicted RMS error
/// `sqrt(tr(W P))` after it. `blocked_by(u)` lists the units choosing `u` rules out (the
/// radius rule; `u` itself is always ruled out); `continue_after(landmarks added,
/// predicted)` says whether to go on (a unit of 6 rows adds two landmarks). Stops when no
/// unit is allowed or the caller says so.
pub fn greedy(
    problem: &DesignProblem,
    initial: &Posterior,
    allowed: &[bool],
    blocked_by: impl Fn(usize) -> Vec<usize>,
    criterion: Criterion,
    mut continue_after: impl FnMut(usize, f64) -> bool,
) -> Vec<Step> {
    let k = problem.k;
    let mut offsets = vec![0];
    for unit in &problem.units {
        offsets.push(offsets.last().unwrap() + unit.len() / k);
    }
    let rows = *offsets.last().unwrap();
    // Column-major stacked rows of every unit.
    let mut data = vec![0.0; rows * k];
    for (u, unit) in problem.units.iter().enumerate() {
        for (i, row) in unit.chunks(k).enumerate() {
            for (c, &x) in row.iter().enumerate() {
                data[c * rows + offsets[u] + i] = x;
            }
        }
    }
    let stacked = MatRef::from_column_major_slice(&data, rows, k);
    let mut allowed = allowed.to_vec();
    let mut posterior = initial.clone();
    let mut steps = Vec::new();
    let mut added = 0;
    loop {
        if !allowed.iter().any(|&a| a) {
            break;
        }
        let gain = gains(problem, stacked, &offsets, &posterior, criterion, &allowed);
        let best = (0..gain.len()).filter(|&u| allowed[u]).fold(None, |best: Option<usize>, u| match best {
            Some(b) if gain[b] >= gain[u] => Some(b),
            _ => Some(u),
        });
        let Some(best) = best else { break };
        posterior.add(&problem.units[best], problem.noise_variance);
        allowed[best] = false;
        for u in blocked_by(best) {
            allowed[u] = false;
        }
        added += problem.units[best].len() / (3 * k);
        let predicted = posterior.expected_squared_error(&problem.weight).max(0.0).sqrt();
        steps.push(Step { unit: best, predicted });
        if !continue_after(added, predicted) {
            break;
        }
    }
    steps
}

/// `W = D^T D / N` over the live shapes (K x K, row-major), from column-major blocks of the
/// deltas so that the product runs as one matrix multiply.
pub fn error_weight(deltas: &[&[[f32; 3]]]) -> Vec<f64> {
    let k = deltas.len();
    let n = deltas.first().map_or(0, |d| d.len());
    let mut weight = Mat::<f64>::zeros(k, k);
    const BLOCK: usize = 4096;
    let mut block = vec![0.0; 3 * BLOCK * k];
    for start in (0..n).step_by(BLOCK) {
        let count = BLOCK.min(n - start);
        let rows = 3 * count;
        for (c, delta) in deltas.iter().enumerate() {
            for (i, d) in delta[start..start + count].iter().enumerate() {
                for a in 0..3 {
                    block[c * rows + 3 * i + a] = d[a] as f64;
                }
            }
        }
        let b = MatRef::from_column_major_slice(&block[..rows * k], rows, k);
        matmul(weight.as_mut(), Accum::Add, b.transpose(), b, 1.0, Par::rayon(0));
    }
    let scale = 1.0 / n.max(1) as f64;
    (0..k * k).map(|ij| weight[(ij / k, ij % k)] * scale).collect()
}

/// The 3 rows (K long each, row-major) of landmark `vertex` over the shapes `deltas`.
pub fn vertex_rows(deltas: &[&[[f32; 3]]], vertex: usize) -> Vec<f64> {
    (0..3).flat_map(|a| deltas.iter().map(move |d| d[vertex][a] as f64)).collect()
}

/// The predicted RMS vertex error (mesh units) of reconstructing from `vertices`.
pub fn predicted_error(deltas: &[&[[f32; 3]]], weight: &[f64], vertices: &[u32], noise_variance: f64) -> f64 {
    let rows: Vec<Vec<f64>> = vertices.iter().map(|&v| vertex_rows(deltas, v as usize)).collect();
    let k = deltas.len();
    let slices: Vec<&[f64]> = rows.iter().flat_map(|r| r.chunks(k)).collect();
    Posterior::new(k, &slices, noise_variance).expected_squared_error(weight).max(0.0).sqrt()
}

/// What the design stage needs from the layout run.
pub struct DesignInput<'a> {
    /// The live shapes' deltas (K of them, N rows each).
    pub deltas: Vec<&'a [[f32; 3]]>,
    pub neutral: &'a [[f32; 3]],
    /// Pool vertices: the kept side of a mirror pair (or any vertex without one), each with
    /// its partner when the layout is symmetric.
    pub pool: Vec<Vec<u32>>,
    /// The cover's landmarks (partners included).
    pub cover: Vec<u32>,
    /// Exclusion radius in mesh units (the multi-cover's).
    pub radius: f64,
    pub diagonal: f64,
}

#[derive(Clone, Debug)]
pub struct DesignSettings {
    pub landmarks: Option<usize>,
    /// Fraction of the diagonal.
    pub target_error: Option<f64>,
    pub criterion: Criterion,
    /// Per coordinate, fraction of the diagonal.
    pub noise: f64,
    /// The curve runs at least to this many landmarks in all.
    pub curve_to: usize,
}

/// One point of the predicted-error curve: the layout's size and its predicted error
/// (fraction of the diagonal) once `vertices` were added.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct CurvePoint {
    pub landmarks: usize,
    pub predicted_error: f64,
    pub vertices: Vec<u32>,
}

#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(rename_all = "snake_case")]
pub enum DesignStop {
    /// The requested count was reached.
    Count,
    /// The predicted error reached the target.
    Target,
    /// No allowed vertex was left in the pool (visibility and radius rules).
    PoolExhausted,
}

#[derive(Clone, Debug)]
pub struct DesignOutcome {
    /// The vertices added, in greedy order (a mirror pair adds two at one step).
    pub added: Vec<Vec<u32>>,
    /// The cover first, then every greedy step up to the curve's end (beyond `added`).
    pub curve: Vec<CurvePoint>,
    pub stop: DesignStop,
}

/// The predicted RMS error of the cover, then greedy additions from the pool (module docs),
/// never within `radius` of a landmark already placed. The greedy sequence runs to
/// `max(landmarks, curve_to)` in all, or on until the target is reached, so that the curve
/// shows where more landmarks stop paying; the layout takes its prefix up to `landmarks`
/// (one fewer when the next step is a mirror pair) or to the first step that reaches the
/// target, whichever comes first.
pub fn extend_layout(input: &DesignInput, settings: &DesignSettings) -> DesignOutcome {
    let k = input.deltas.len();
    let sigma = settings.noise * input.diagonal;
    let noise_variance = sigma * sigma;
    let weight = error_weight(&input.deltas);
    let cover_rows: Vec<Vec<f64>> = input.cover.iter().map(|&v| vertex_rows(&input.deltas, v as usize)).collect();
    let slices: Vec<&[f64]> = cover_rows.iter().flat_map(|r| r.chunks(k)).collect();
    let initial = Posterior::new(k, &slices, noise_variance);
    let cover_error = initial.expected_squared_error(&weight).max(0.0).sqrt() / input.diagonal;
    let mut curve = vec![CurvePoint { landmarks: input.cover.len(), predicted_error: cover_error, vertices: Vec::new() }];

    let tree = PointTree::new(input.neutral);
    let mut unit_of = vec![usize::MAX; input.neutral.len()];
    for (u, unit) in input.pool.iter().enumerate() {
        for &v in unit {
            unit_of[v as usize] = u;
        }
    }
    let near = |vertices: &[u32]| -> Vec<usize> {
        let mut units: Vec<usize> = vertices
            .iter()
            .flat_map(|&v| tree.within(input.neutral[v as usize].map(f64::from), input.radius))
            .map(|(n, _)| unit_of[n])
            .filter(|&u| u != usize::MAX)
            .collect();
        units.sort_unstable();
        units.dedup();
        units
    };
    let mut allowed = vec![true; input.pool.len()];
    for u in near(&input.cover) {
        allowed[u] = false;
    }
    let problem = DesignProblem {
        k,
        units: input.pool.iter().map(|unit| unit.iter().flat_map(|&v| vertex_rows(&input.deltas, v as usize)).collect()).collect(),
        weight,
        noise_variance,
    };
    let horizon = settings.landmarks.unwrap_or(0).max(settings.curve_to);
    // Compared as reported (fractions of the diagonal), so that a target read off the curve
    // stops exactly at its point.
    let target = settings.target_error;
    let steps = greedy(&problem, &initial, &allowed, |u| near(&input.pool[u]), settings.criterion, |added, predicted| {
        input.cover.len() + added < horizon || target.is_some_and(|t| predicted / input.diagonal > t)
    });

    let mut added = Vec::new();
    let mut stop = DesignStop::PoolExhausted;
    let mut total = input.cover.len();
    if target.is_some_and(|t| cover_error <= t) {
        stop = DesignStop::Target;
    } else if settings.landmarks.is_some_and(|m| total >= m) {
        stop = DesignStop::Count;
    }
    for step in &steps {
        let vertices = input.pool[step.unit].clone();
        total += vertices.len();
        curve.push(CurvePoint { landmarks: total, predicted_error: step.predicted / input.diagonal, vertices: vertices.clone() });
        if stop != DesignStop::PoolExhausted {
            continue;
        }
        if settings.landmarks.is_some_and(|m| total > m) {
            stop = DesignStop::Count;
            continue;
        }
        added.push(vertices);
        if target.is_some_and(|t| step.predicted / input.diagonal <= t) {
            stop = DesignStop::Target;
        } else if settings.landmarks.is_some_and(|m| total >= m) {
            stop = DesignStop::Count;
        }
    }
    DesignOutcome { added, curve, stop }
}

#[cfg(test)]
#[path = "design_tests.rs"]
mod tests;
