//! Conditioned layouts (method, section 2, "Conditioned layouts"; beyond paper 003): after the
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
//! `tr(S^{-1} B (P W P) B^T)` and the D-gain `log det(S / sigma^2)`. A unit's gain needs only
//! its r x r forms `S` and `T = B (P W P) B^T`. They are computed once from two matrix
//! products `R P`, `R (P W P)` over the stacked rows `R` of the pool, then carried through
//! each step's rank-r update `P' = P - U U^T` (r = 3 rows per landmark): `S -= (B U)(B U)^T`
//! and the matching expansion of `P' W P'` for `T`, a few length-K dot products per row
//! instead of two products over all pool rows. Near ties and long falls of the gains are
//! decided by the products from scratch ([`greedy`]), so the choices are exactly those of
//! evaluating every unit from scratch at every step (no lazy approximation: the A-gain is
//! not submodular, so a stale gain is no bound on the current one).

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use rayon::prelude::*;
use serde::Serialize;

use crate::geometry::neighbours::PointTree;

/// The prior precision of a weight: `1 / Var(U[0, 1]) = 12`.
pub const PRIOR_PRECISION: f64 = 12.0;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, serde::Deserialize)]
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
    let mut l = vec![0.0; n * n];
    cholesky_into(|i, j| m[(i, j)], n, &mut l);
    Mat::from_fn(n, n, |i, j| l[i * n + j])
}

/// [`cholesky`] of the n x n matrix `m(i, j)` into `l` (row-major, zeroed), without
/// allocating: each unit's gain at each step takes one.
fn cholesky_into(m: impl Fn(usize, usize) -> f64, n: usize, l: &mut [f64]) {
    for j in 0..n {
        let d = (m(j, j) - (0..j).map(|c| l[j * n + c] * l[j * n + c]).sum::<f64>()).max(f64::MIN_POSITIVE).sqrt();
        l[j * n + j] = d;
        for i in j + 1..n {
            l[i * n + j] = (m(i, j) - (0..j).map(|c| l[i * n + c] * l[j * n + c]).sum::<f64>()) / d;
        }
    }
}

/// Inverse of a small symmetric positive definite matrix by Cholesky.
fn spd_inverse(m: &Mat<f64>) -> Mat<f64> {
    let n = m.nrows();
    let mut l = vec![0.0; n * n];
    cholesky_into(|i, j| m[(i, j)], n, &mut l);
    let (mut inverse, mut x) = (vec![0.0; n * n], vec![0.0; n]);
    inverse_from_cholesky(&l, n, &mut x, &mut inverse);
    Mat::from_fn(n, n, |i, j| inverse[i * n + j])
}

/// `(L L^T)^{-1}` (row-major, into `inverse`) from the factor `l`, column by column: solve
/// `L L^T x = e_c` (`x`: n of scratch).
fn inverse_from_cholesky(l: &[f64], n: usize, x: &mut [f64], inverse: &mut [f64]) {
    for c in 0..n {
        for i in 0..n {
            let rhs = if i == c { 1.0 } else { 0.0 } - (0..i).map(|j| l[i * n + j] * x[j]).sum::<f64>();
            x[i] = rhs / l[i * n + i];
        }
        for i in (0..n).rev() {
            let rhs = x[i] - (i + 1..n).map(|j| l[j * n + i] * x[j]).sum::<f64>();
            x[i] = rhs / l[i * n + i];
        }
        for i in 0..n {
            inverse[i * n + c] = x[i];
        }
    }
}

/// Every unit's small matrices `S_u = sigma^2 I + B_u P B_u^T` and (criterion A)
/// `T_u = B_u (P W P) B_u^T`, r_u x r_u row-major at `at[u]`: all a unit's gain needs.
struct UnitForms {
    at: Vec<usize>,
    s: Vec<f64>,
    t: Vec<f64>,
}

impl UnitForms {
    /// From scratch for the current `P`, for the allowed units: the two products `R P`,
    /// `R (P W P)` over the stacked rows `R` of the pool (column-major), as every step computed
    /// them before the rank-r updates, so that gains from these forms are that computation's.
    fn exact(problem: &DesignProblem, stacked: MatRef<'_, f64>, offsets: &[usize], p: MatRef<'_, f64>, criterion: Criterion, allowed: &[bool]) -> Self {
        let k = problem.k;
        let rows = stacked.nrows();
        let mut rp = Mat::<f64>::zeros(rows, k);
        matmul(rp.as_mut(), Accum::Replace, stacked, p, 1.0, Par::rayon(0));
        let rq = (criterion == Criterion::A).then(|| {
            let w = MatRef::from_row_major_slice(&problem.weight, k, k);
            let pwp = p * w * p;
            let mut rq = Mat::<f64>::zeros(rows, k);
            matmul(rq.as_mut(), Accum::Replace, stacked, pwp.as_ref(), 1.0, Par::rayon(0));
            rq
        });
        let sigma2 = problem.noise_variance;
        let mut at = vec![0];
        for u in 0..problem.units.len() {
            let r = offsets[u + 1] - offsets[u];
            at.push(at[u] + r * r);
        }
        let size = *at.last().unwrap();
        let (mut s, mut t) = (vec![0.0; size], vec![0.0; if rq.is_some() { size } else { 0 }]);
        let form = |left: &Mat<f64>, u: usize, out: &mut [f64], diagonal: f64| {
            if !allowed[u] {
                return;
            }
            let (start, r) = (offsets[u], offsets[u + 1] - offsets[u]);
            for i in 0..r {
                for j in 0..r {
                    let inner = (0..k).map(|c| left[(start + i, c)] * stacked[(start + j, c)]).sum::<f64>();
                    out[i * r + j] = inner + if i == j { diagonal } else { 0.0 };
                }
            }
        };
        split_at(&mut s, &at).into_par_iter().enumerate().for_each(|(u, out)| form(&rp, u, out, sigma2));
        if let Some(rq) = &rq {
            split_at(&mut t, &at).into_par_iter().enumerate().for_each(|(u, out)| form(rq, u, out, 0.0));
        }
        Self { at, s, t }
    }

    /// The forms after `P' = P - U U^T`: `S_u -= a a^T` and
    /// `T_u += -c a^T - a c^T + a M a^T` with `a = B_u U`, `c = B_u V`, `V = P W U`,
    /// `M = U^T W U` (expanding `P' W P'`). `rows` holds the pool's rows row-major; `ut`,
    /// `vt` are `U^T`, `V^T` (r x K row-major). About `4 r_u r K` operations per unit against
    /// the `2 r_u K^2` of recomputing its rows of `R P` and `R (P W P)`.
    fn update(&mut self, rows: &[f64], offsets: &[usize], k: usize, ut: &[f64], vt: Option<(&[f64], &[f64])>, allowed: &[bool]) {
        let r = ut.len() / k;
        let t_parts: Vec<&mut [f64]> = if vt.is_some() { split_at(&mut self.t, &self.at) } else { (1..self.at.len()).map(|_| Default::default()).collect() };
        split_at(&mut self.s, &self.at).into_par_iter().zip(t_parts).enumerate().for_each(|(u, (s, t))| {
            if !allowed[u] {
                return;
            }
            let (start, ru) = (offsets[u], offsets[u + 1] - offsets[u]);
            let dot = |row: usize, other: &[f64], j: usize| -> f64 { rows[row * k..(row + 1) * k].iter().zip(&other[j * k..(j + 1) * k]).map(|(x, y)| x * y).sum() };
            let a: Vec<f64> = (0..ru * r).map(|ij| dot(start + ij / r, ut, ij % r)).collect();
            for i in 0..ru {
                for j in 0..ru {
                    s[i * ru + j] -= (0..r).map(|l| a[i * r + l] * a[j * r + l]).sum::<f64>();
                }
            }
            let Some((vt, m)) = vt else { return };
            let c: Vec<f64> = (0..ru * r).map(|ij| dot(start + ij / r, vt, ij % r)).collect();
            for i in 0..ru {
                for j in 0..ru {
                    let mut change = 0.0;
                    for l in 0..r {
                        change -= c[i * r + l] * a[j * r + l] + a[i * r + l] * c[j * r + l];
                        change += a[i * r + l] * (0..r).map(|q| m[l * r + q] * a[j * r + q]).sum::<f64>();
                    }
                    t[i * ru + j] += change;
                }
            }
        });
    }

    /// Unit `u`'s gain: A-gain `tr(S^{-1} T)` or D-gain `log det(S / sigma^2)` (module docs);
    /// on the stack for units of up to two landmarks.
    fn gain(&self, u: usize, criterion: Criterion, sigma2: f64) -> f64 {
        const STACK: usize = 36;
        let (from, to) = (self.at[u], self.at[u + 1]);
        let r = ((to - from) as f64).sqrt().round() as usize;
        let s = &self.s[from..to];
        let (mut l_stack, mut inverse_stack, mut x_stack) = ([0.0; STACK], [0.0; STACK], [0.0; STACK]);
        let mut heap = Vec::new();
        let (l, inverse, x): (&mut [f64], &mut [f64], &mut [f64]) = if r * r <= STACK {
            (&mut l_stack[..r * r], &mut inverse_stack[..r * r], &mut x_stack[..r])
        } else {
            heap.resize(2 * r * r + r, 0.0);
            let (l, rest) = heap.split_at_mut(r * r);
            let (inverse, x) = rest.split_at_mut(r * r);
            (l, inverse, x)
        };
        cholesky_into(|i, j| s[i * r + j], r, l);
        match criterion {
            Criterion::D => (0..r).map(|j| 2.0 * l[j * r + j].ln()).sum::<f64>() - r as f64 * sigma2.ln(),
            Criterion::A => {
                inverse_from_cholesky(l, r, x, inverse);
                (0..r).flat_map(|i| (0..r).map(move |j| (i, j))).map(|(i, j)| inverse[i * r + j] * self.t[from + j * r + i]).sum()
            }
        }
    }
}

/// `data` cut into the consecutive pieces `at[u]..at[u + 1]`.
fn split_at<'d>(mut data: &'d mut [f64], at: &[usize]) -> Vec<&'d mut [f64]> {
    at.windows(2)
        .map(|w| {
            let (piece, rest) = std::mem::take(&mut data).split_at_mut(w[1] - w[0]);
            data = rest;
            piece
        })
        .collect()
}

/// The factors of adding the rows `b` (r x K) to `P`: `U^T = L^{-1} (B P)` with
/// `L L^T = sigma^2 I + B P B^T`, so that `P' = P - U U^T` (the Woodbury update of
/// [`Posterior::add`]); for criterion A also `V^T = U^T W P` and `M = U^T W U`.
fn update_factors(problem: &DesignProblem, posterior: &Posterior, b: &[f64], criterion: Criterion) -> (Vec<f64>, Option<(Vec<f64>, Vec<f64>)>) {
    let k = problem.k;
    let r = b.len() / k;
    let p = &posterior.p;
    let bp: Vec<f64> = (0..r * k).map(|ic| (0..k).map(|j| b[ic / k * k + j] * p[(j, ic % k)]).sum()).collect();
    let s = Mat::<f64>::from_fn(r, r, |i, j| {
        (0..k).map(|c| bp[i * k + c] * b[j * k + c]).sum::<f64>() + if i == j { problem.noise_variance } else { 0.0 }
    });
    let l = cholesky(&s);
    let mut ut = vec![0.0; r * k];
    for i in 0..r {
        for c in 0..k {
            ut[i * k + c] = (bp[i * k + c] - (0..i).map(|j| l[(i, j)] * ut[j * k + c]).sum::<f64>()) / l[(i, i)];
        }
    }
    let weighted = (criterion == Criterion::A).then(|| {
        let w = &problem.weight;
        let uw: Vec<f64> = (0..r * k).map(|ic| (0..k).map(|j| ut[ic / k * k + j] * w[j * k + ic % k]).sum()).collect();
        let vt: Vec<f64> = (0..r * k).map(|ic| (0..k).map(|j| uw[ic / k * k + j] * p[(j, ic % k)]).sum()).collect();
        let m: Vec<f64> = (0..r * r).map(|ij| (0..k).map(|c| uw[ij / r * k + c] * ut[ij % r * k + c]).sum()).collect();
        (vt, m)
    });
    (ut, weighted)
}

/// A near tie between the two best gains, relative to the best: below it a step takes the
/// gains from scratch. The rank-r updated forms differ from scratch by rounding that grows
/// with the steps since the last refresh and with how far the gains fell since (about
/// `1e-16 x steps x fall`; the tests measure it); ties closer than this are decided by the
/// from-scratch gains, so the choice is always the one they make.
const NEAR_TIE: f64 = 1e-8;
/// Refresh the forms from scratch once the best gain fell this far below the best at the
/// last refresh, so that rounding stays far below [`NEAR_TIE`] of the gains compared.
const FALL: f64 = 1e-3;

/// Greedy design from the posterior of the `initial` rows: each step adds the allowed unit
/// with the largest gain (lowest index on a tie) and records the predicted RMS error
/// `sqrt(tr(W P))` after it. `blocked_by(u)` lists the units choosing `u` rules out (the
/// radius rule; `u` itself is always ruled out); `continue_after(landmarks added,
/// predicted)` says whether to go on (a unit of 6 rows adds two landmarks). Stops when no
/// unit is allowed or the caller says so.
///
/// The gains come from each unit's small forms `S_u`, `T_u` ([`UnitForms`]), computed once
/// from the products over the whole pool and then carried through each step's rank-r
/// update of `P`; a step whose two best gains are within [`NEAR_TIE`], or whose best gain
/// fell by [`FALL`] since the forms were last computed from scratch, computes them from
/// scratch again. So every choice is the one the products of every step would make (the
/// tests compare with them), at a few row-by-r products per unit a step instead of two
/// full products over all pool rows.
pub fn greedy(
    problem: &DesignProblem,
    initial: &Posterior,
    allowed: &[bool],
    blocked_by: impl Fn(usize) -> Vec<usize>,
    criterion: Criterion,
    mut continue_after: impl FnMut(usize, f64) -> bool,
) -> Vec<Step> {
    let k = problem.k;
    let (offsets, data) = stack(problem);
    // Row-major too, for the updates.
    let row_major: Vec<f64> = problem.units.concat();
    let stacked = MatRef::from_column_major_slice(&data, *offsets.last().unwrap(), k);
    let sigma2 = problem.noise_variance;
    let mut allowed = allowed.to_vec();
    let mut posterior = initial.clone();
    let mut steps = Vec::new();
    let mut added = 0;
    let mut forms: Option<UnitForms> = None;
    let mut scale = 0.0f64;
    loop {
        if !allowed.iter().any(|&a| a) {
            break;
        }
        let mut fresh = forms.is_none();
        let current = forms.get_or_insert_with(|| UnitForms::exact(problem, stacked, &offsets, posterior.p.as_ref(), criterion, &allowed));
        let mut gain = all_gains(current, criterion, sigma2, &allowed);
        let (best, second) = two_best(&gain, &allowed);
        let Some(mut best) = best else { break };
        let near_tie = second.is_some_and(|s| gain[best] - gain[s] <= NEAR_TIE * gain[best].abs());
        if !fresh && (near_tie || gain[best].abs() < FALL * scale) {
            *current = UnitForms::exact(problem, stacked, &offsets, posterior.p.as_ref(), criterion, &allowed);
            gain = all_gains(current, criterion, sigma2, &allowed);
            best = two_best(&gain, &allowed).0.unwrap_or(best);
            fresh = true;
        }
        if fresh {
            scale = gain[best].abs();
        }
        let unit = &problem.units[best];
        let (ut, weighted) = update_factors(problem, &posterior, unit, criterion);
        posterior.add(unit, sigma2);
        allowed[best] = false;
        for u in blocked_by(best) {
            allowed[u] = false;
        }
        current.update(&row_major, &offsets, k, &ut, weighted.as_ref().map(|(vt, m)| (&vt[..], &m[..])), &allowed);
        added += unit.len() / (3 * k);
        let predicted = posterior.expected_squared_error(&problem.weight).max(0.0).sqrt();
        steps.push(Step { unit: best, predicted });
        if !continue_after(added, predicted) {
            break;
        }
    }
    steps
}

/// Where each unit's rows start in the stacked rows of the pool (and the end), and those
/// rows column-major (the layout the products over the pool run on).
fn stack(problem: &DesignProblem) -> (Vec<usize>, Vec<f64>) {
    let k = problem.k;
    let mut offsets = vec![0];
    for unit in &problem.units {
        offsets.push(offsets.last().unwrap() + unit.len() / k);
    }
    let rows = *offsets.last().unwrap();
    let mut data = vec![0.0; rows * k];
    for (u, unit) in problem.units.iter().enumerate() {
        for (i, row) in unit.chunks(k).enumerate() {
            for (c, &x) in row.iter().enumerate() {
                data[c * rows + offsets[u] + i] = x;
            }
        }
    }
    (offsets, data)
}

/// Every allowed unit's gain from its forms (in parallel; the same numbers as in series);
/// `-inf` for the others, which no step may choose.
fn all_gains(forms: &UnitForms, criterion: Criterion, sigma2: f64, allowed: &[bool]) -> Vec<f64> {
    (0..allowed.len()).into_par_iter().map(|u| if allowed[u] { forms.gain(u, criterion, sigma2) } else { f64::NEG_INFINITY }).collect()
}

/// The allowed unit with the largest gain (lowest index on a tie), and the next best.
fn two_best(gain: &[f64], allowed: &[bool]) -> (Option<usize>, Option<usize>) {
    let (mut best, mut second): (Option<usize>, Option<usize>) = (None, None);
    for u in (0..gain.len()).filter(|&u| allowed[u]) {
        match best {
            Some(b) if gain[b] >= gain[u] => {
                if second.is_none_or(|s| gain[u] > gain[s]) {
                    second = Some(u);
                }
            }
            _ => {
                second = best;
                best = Some(u);
            }
        }
    }
    (best, second)
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
