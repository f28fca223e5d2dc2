//! Example-based personalisation (Li, Weise & Pauly 2010, "Example-based facial rigging",
//! EBFR section 4): refit the transferred shapes so that the blendshape model reproduces
//! training expressions of the target, regularised in the gradient domain towards deformation
//! transfer. Method, section 3; judged on the warp ground truth of method, section 4.
//!
//! Per target triangle t (rest normal n_t, `P_t = I - n_t n_t^T`, hat gradients `grad phi_i`),
//! with `S_kt` the transferred gradients (stored as `S - I`), `A_jt P_t = sum_i e_ji grad_phi_i^T`
//! the example's gradient (exactly linear in the example deltas `e_j`) and `alpha` the J x K
//! weights, the fitted gradients `M_kt` minimise EBFR Eq. (3)-(5) read as a Gaussian MAP fit:
//!
//! - (P1) `sum_j |sum_k alpha_jk M_kt P_t - A_jt P_t|^2 / nu_jt + sum_k |(M_kt - S_kt) P_t|^2 / tau_kt`
//! - (P2) `tau_kt = |S_kt P_t|^2 / beta`: the transfer's error is taken proportional to how much
//!   the shape itself deforms the triangle (the warp's `J S J^-1 - S` is);
//! - (P3) `nu_jt = 3 sigma_j^2 sum_i |grad phi_i|^2`, the expected squared gradient of the
//!   scan noise, floored at `EXACT_DATA` times the triangle's prior spread;
//! - (P4) `sigma_j`: each expression's noise, measured on the vertices none of its members
//!   moves (there the scan should equal the neutral);
//! - (P5) closed form in the variance (push-through) form, one J x J solve per triangle:
//!   `M_k = S_k + tau_k sum_j alpha_jk Y_j`, `(N_t + alpha T_t alpha^T) Y_t = A_t P_t - alpha S_t P_t`.
//!
//! What this does with packed expressions: where one member of an
//! expression moves a triangle and the others barely do, `tau` of that member dwarfs theirs
//! and, the scan being trusted, that member's gradient becomes the scan's (up to `nu`); where
//! members overlap in their weak tails the residual is split in proportion to `tau`, i.e. to
//! each shape's own strain there. With noise, `nu / tau` decides between scan and transfer.
//! Each shape is then one Poisson solve with its plain-transfer static set; shapes in no
//! example keep `M = S` and come out as plain transfer bit for bit, and with no example the
//! result is plain transfer. Two more unknowns are fitted the same way, since a gradient
//! cannot see them: (P7) the translation of each piece that floats in a shape (eyeballs,
//! lashes, teeth, tongue: no static vertex), and (P8) the virtual-edge springs' targets,
//! which plain transfer takes from the template. (P6) weight refinement fits each expression's
//! members' weights in [0, 1] to the *transferred* shapes before the fit.
//!
//! # Deviations (measured by `scripts/bench_personalise.py`, bundled head, 18 packed
//! expressions, virtual edges on; mean error on active vertices / diagonal)
//! - **EBFR's adaptive weight replaced.** `w_k = ((1 + |S|) / (kappa + |S|))^theta` with
//!   `beta = 0.1` (normalised at each shape's peak strain) held every
//!   shape towards the transfer even where the scan shows it alone: 1.51e-3 (additive copy
//!   2.69e-3). The variance model P1-P5 alone: 9.26e-4; with the pieces' translations (P7):
//!   5.26e-4; with the springs' targets (P8): 3.49e-4 (4x head 3.42e-4; without virtual edges
//!   3.41e-4).
//! - **Only the tangential part is fitted** (`X P_t`): it is all the Poisson solve sees, and it
//!   is linear in the example, whereas EBFR's normal column is not.
//! - **`beta` means the transfer's relative error**, `1 / sqrt(beta)` of the strain, by
//!   default 1; it acts only through noise (clean rows are the same for every `beta`). With
//!   0.1% scan noise, packed: 1.22e-3 at `beta` 0.25, 1.32e-3 at 1, 1.65e-3 at 4 (the warp is
//!   a large error for the transfer; real scans may favour it more). Scans are followed where
//!   shapes move strongly, so their noise enters the shapes nearly one to one there (1.32e-3
//!   at 0.1% noise, the scans' own mean noise being 1.6e-3); the scans' residual is not
//!   smoothed against the transfer before the fit.
//! - **Weight refinement against the transferred shapes, once, members only** (EBFR
//!   alternates with the shapes). With the scans trusted, shapes fitted with wrong weights
//!   absorb the error (a shape at 0.8 with weight 1 explains a scan as well as the truth at
//!   0.8), so alternating cannot move the weights; the transfer, wrong in direction more than
//!   in size, can. Members posed at weights in [0.75, 1] and told 1: mean weight error 0.128
//!   -> 0.085, shapes 1.67e-3 -> 1.38e-3 (alternating with the shapes: 1.82e-3 -> 2.08e-3).
//!   Shapes the user left out of an expression stay out.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use super::deformation::DeformationTransfer;
use super::gradients::{add, corners, cross, dot, frobenius, length, mat_add_scaled, scale, sub, HatGradients, Mat3, Vec3, ZERO};
use crate::error::ShapesmithResult;
use crate::invalid;
use crate::progress::Progress;
use crate::rig::validate_points;

/// Knobs of [`DeformationTransfer::personalise`].
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PersonaliseParams {
    /// `beta`, the weight of the pull towards the transferred gradients against the training
    /// expressions: the transfer is taken to be wrong by `1 / sqrt(beta)` of a shape's own
    /// strain (Eq. P2); it matters only as far as the expressions are noisy.
    pub beta_reg: f64,
    /// Refit each expression's weights of its members (bounded to [0, 1]) against the
    /// transferred shapes before the fit.
    pub refine_weights: bool,
}

impl Default for PersonaliseParams {
    fn default() -> Self {
        Self { beta_reg: DEFAULT_BETA, refine_weights: false }
    }
}

/// See [`PersonaliseParams::beta_reg`] and the module's measurements.
pub const DEFAULT_BETA: f64 = 1.0;

/// A training expression is trusted at least this much more than the transfer (Eq. P3's
/// floor on `nu`): keeps the J x J system well conditioned when the expressions are exact.
const EXACT_DATA: f64 = 1e-9;

/// Personalised shapes.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Personalisation {
    /// K x N target deltas, shape-major.
    pub deltas: Vec<[f32; 3]>,
    /// J x K weights the shapes were fitted with (refined, or as given).
    pub weights: Vec<f64>,
    /// Per training expression, the scan noise estimated from its still vertices (standard
    /// deviation per coordinate, in the target's units).
    pub noise: Vec<f64>,
    /// Shapes that do not move in the template (their deltas are zero).
    pub inert: Vec<String>,
    /// Wall-clock seconds.
    pub seconds: f64,
}

impl DeformationTransfer {
    /// Personalises the transfer of `source_deltas` (K x N) with J training expressions
    /// `examples` (J x N target positions) whose blend weights are `weights` (J x K,
    /// row-major; packed expressions are 0/1 rows).
    pub fn personalise(
        &self,
        source_deltas: &[[f32; 3]],
        names: &[String],
        examples: &[[f32; 3]],
        weights: &[f64],
        params: &PersonaliseParams,
        progress: &dyn Progress,
    ) -> ShapesmithResult<Personalisation> {
        let start = Instant::now();
        self.validate_deltas(source_deltas, names)?;
        let (n, n_shapes) = (self.n_vertices(), names.len());
        validate_personalise_params(params)?;
        if !examples.len().is_multiple_of(n) {
            return Err(invalid!("training expressions hold {} vertex rows, not a multiple of the {n} vertices", examples.len()));
        }
        let n_examples = examples.len() / n;
        if weights.len() != n_examples * n_shapes {
            return Err(invalid!(
                "the example weights hold {} numbers but {n_examples} training expressions x {n_shapes} shapes need {}",
                weights.len(),
                n_examples * n_shapes
            ));
        }
        for j in 0..n_examples {
            validate_points(&examples[j * n..(j + 1) * n], &format!("training expression {j}"))?;
        }
        if let Some(i) = weights.iter().position(|w| !w.is_finite()) {
            return Err(invalid!("weight of shape '{}' in training expression {} is not finite", names[i % n_shapes], i / n_shapes));
        }

        let example_deltas: Vec<Vec<Vec3>> = (0..n_examples)
            .map(|j| (0..n).map(|v| sub(self.to_working_frame(&examples[j * n + v]), self.target_neutral[v])).collect())
            .collect();
        let inert: Vec<bool> = (0..n_shapes).map(|k| self.is_inert(&source_deltas[k * n..(k + 1) * n])).collect();
        let operators = self.rest_operators()?;
        let done = AtomicUsize::new(0);
        let total = (if params.refine_weights { 2 * n_shapes } else { n_shapes }).max(1) as f64;
        let tick = || {
            let finished = done.fetch_add(1, Ordering::Relaxed) + 1;
            progress.checkpoint(finished as f64 / total)
        };

        let alpha = if params.refine_weights {
            let transferred = (0..n_shapes)
                .into_par_iter()
                .map(|k| {
                    let delta = &source_deltas[k * n..(k + 1) * n];
                    let out = if inert[k] { vec![[0.0; 3]; n] } else { self.solve_shape(delta, |t| self.triangle_gradient(t, delta))? };
                    tick()?;
                    Ok(out)
                })
                .collect::<ShapesmithResult<Vec<_>>>()?;
            refit_member_weights(&transferred, &example_deltas, weights)
        } else {
            weights.to_vec()
        };
        let active: Vec<usize> =
            (0..n_shapes).filter(|&k| !inert[k] && (0..n_examples).any(|j| alpha[j * n_shapes + k] != 0.0)).collect();
        let moving: Vec<Vec<bool>> = (0..n_shapes)
            .map(|k| if active.contains(&k) { self.moving_vertices(&source_deltas[k * n..(k + 1) * n]) } else { Vec::new() })
            .collect();
        let noise = self.example_noise(&example_deltas, &alpha, n_shapes, &moving);
        let fit = Fit { source_deltas, alpha: &alpha, n_shapes, active: &active, moving: &moving, beta: params.beta_reg };
        let corrections = self.corrections(&fit, &operators, &example_deltas, &noise);
        let edge_changes = self.fit_edge_changes(&fit, &example_deltas, &noise);
        let shapes = (0..n_shapes)
            .into_par_iter()
            .map(|k| {
                let delta = &source_deltas[k * n..(k + 1) * n];
                let out = if inert[k] {
                    vec![[0.0; 3]; n]
                } else {
                    let mut gradients = self.shape_gradients(delta);
                    if !active.contains(&k) {
                        self.solve_shape(delta, |t| gradients[t])?
                    } else {
                        for (t, g) in gradients.iter_mut().enumerate() {
                            let spread = fit.prior_variance(g, &operators[t]);
                            if spread == 0.0 {
                                continue;
                            }
                            let mut sum = ZERO;
                            for j in 0..n_examples {
                                sum = mat_add_scaled(&sum, &corrections[t * n_examples + j], alpha[j * n_shapes + k]);
                            }
                            *g = mat_add_scaled(g, &sum, spread);
                        }
                        self.solve_shape_with_edge_changes(delta, |t| gradients[t], &edge_changes[k])?
                    }
                };
                tick()?;
                Ok(out)
            })
            .collect::<ShapesmithResult<Vec<_>>>()?;
        let mut shapes = shapes;
        self.place_pieces_by_examples(&fit, &example_deltas, &noise, &mut shapes);
        Ok(Personalisation {
            deltas: shapes.iter().flat_map(|d| self.to_target_frame(d)).collect(),
            weights: alpha,
            noise,
            inert: self.inert_names(source_deltas, names),
            seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// The gradient operators of the target's rest triangles (working frame).
    fn rest_operators(&self) -> ShapesmithResult<Vec<HatGradients>> {
        self.triangles
            .iter()
            .enumerate()
            .map(|(t, tri)| {
                HatGradients::new(corners(&self.target_neutral, None, tri)).ok_or_else(|| invalid!("target: triangle {t} is degenerate"))
            })
            .collect()
    }

    /// Eq. P4: per training expression, the noise standard deviation per coordinate, from the
    /// vertices none of its members moves (there the expression should equal the neutral).
    /// Expressions with fewer than [`MIN_STILL`] such vertices take the median of the others.
    fn example_noise(&self, example_deltas: &[Vec<Vec3>], alpha: &[f64], n_shapes: usize, moving: &[Vec<bool>]) -> Vec<f64> {
        let measured: Vec<Option<f64>> = example_deltas
            .par_iter()
            .enumerate()
            .map(|(j, e)| {
                let members: Vec<usize> = (0..n_shapes).filter(|&k| alpha[j * n_shapes + k] != 0.0 && !moving[k].is_empty()).collect();
                let (mut sum, mut count) = (0.0, 0usize);
                for (v, d) in e.iter().enumerate() {
                    if members.iter().all(|&k| !moving[k][v]) {
                        sum += dot(*d, *d);
                        count += 1;
                    }
                }
                (count >= MIN_STILL).then(|| (sum / (3 * count) as f64).sqrt())
            })
            .collect();
        let mut known: Vec<f64> = measured.iter().flatten().copied().collect();
        known.sort_by(f64::total_cmp);
        let fallback = known.get(known.len() / 2).copied().unwrap_or(0.0);
        measured.into_iter().map(|m| m.unwrap_or(fallback)).collect()
    }

    /// Eq. P7: the translation of each piece that floats in a fitted shape (no static vertex:
    /// the gradients cannot place it, plain transfer carries the template's motion over),
    /// fitted to the expressions' mean motion of the piece with the same variance form as the
    /// gradients: per piece, the floating members' mean deltas `mu_k` (prior: as solved) and
    /// the anchored members' (as solved, fixed) explain the examples' means `m_j`,
    /// `mu_k = mu_k0 + tau_k sum_j alpha_jk Y_j`, `(N + alpha T alpha^T) Y = m - alpha mu_0`,
    /// `tau_k = |mu_k0|^2 / beta`, `N_j = 3 sigma_j^2 / |piece|`.
    fn place_pieces_by_examples(&self, fit: &Fit<'_>, example_deltas: &[Vec<Vec3>], noise: &[f64], shapes: &mut [Vec<Vec3>]) {
        let n_examples = example_deltas.len();
        let (k_all, alpha) = (fit.n_shapes, fit.alpha);
        let n_pieces = self.piece.iter().map(|&p| p as usize + 1).max().unwrap_or(0);
        let mut members: Vec<Vec<usize>> = vec![Vec::new(); n_pieces];
        for (v, &p) in self.piece.iter().enumerate() {
            members[p as usize].push(v);
        }
        let mean = |d: &[Vec3], vertices: &[usize]| {
            scale(vertices.iter().fold([0.0; 3], |acc, &v| add(acc, d[v])), 1.0 / vertices.len() as f64)
        };
        let shifts: Vec<(usize, usize, Vec3)> = members
            .par_iter()
            .enumerate()
            .flat_map_iter(|(p, vertices)| {
                let floating: Vec<usize> =
                    fit.active.iter().copied().filter(|&k| vertices.iter().all(|&v| fit.moving[k][v])).collect();
                if floating.is_empty() {
                    return Vec::new();
                }
                let solved: Vec<Vec3> = (0..k_all).map(|k| mean(&shapes[k], vertices)).collect();
                let spread: Vec<f64> = floating.iter().map(|&k| dot(solved[k], solved[k]) / fit.beta).collect();
                let mut system = vec![0.0; n_examples * n_examples];
                let mut residual: Vec<Vec3> = (0..n_examples)
                    .map(|j| {
                        let explained = (0..k_all).fold([0.0; 3], |acc, k| add(acc, scale(solved[k], alpha[j * k_all + k])));
                        sub(mean(&example_deltas[j], vertices), explained)
                    })
                    .collect();
                for (&k, &tau) in floating.iter().zip(&spread) {
                    for a in 0..n_examples {
                        for b in 0..n_examples {
                            system[a * n_examples + b] += alpha[a * k_all + k] * alpha[b * k_all + k] * tau;
                        }
                    }
                }
                for j in 0..n_examples {
                    let diagonal = &mut system[j * n_examples + j];
                    let nu = 3.0 * noise[j] * noise[j] / vertices.len() as f64;
                    *diagonal += if *diagonal > 0.0 { nu.max(EXACT_DATA * *diagonal) } else { 1.0 };
                }
                solve_spd(&mut system, n_examples, &mut residual);
                floating
                    .iter()
                    .zip(&spread)
                    .map(|(&k, &tau)| {
                        let pull = (0..n_examples).fold([0.0; 3], |acc, j| add(acc, scale(residual[j], alpha[j * k_all + k])));
                        (k, p, scale(pull, tau))
                    })
                    .collect()
            })
            .collect();
        for (k, p, shift) in shifts {
            for &v in &members[p] {
                shapes[k][v] = add(shapes[k][v], shift);
            }
        }
    }

    /// Eq. P8: per fitted shape, its virtual-edge springs' targets `c_ke` (the change of the
    /// pair's vector, [`DeformationTransfer::edge_changes`] for the template's shape) fitted
    /// like a triangle's gradient: the examples' pair changes `o_je = e_j,i - e_j,j` are
    /// explained by `sum_k alpha_jk c_ke`, `c_k = c_k0 + tau_k sum_j alpha_jk Y_j`,
    /// `(N + alpha T alpha^T) Y = o - alpha c_0`, `tau_k = |c_k0|^2 / beta`,
    /// `N_j = 6 sigma_j^2` (two noisy vertices). Springs left at the template's target
    /// would pull a fitted shape back towards the template wherever the pair moves.
    fn fit_edge_changes(&self, fit: &Fit<'_>, example_deltas: &[Vec<Vec3>], noise: &[f64]) -> Vec<Vec<Vec3>> {
        let n = self.n_vertices();
        let n_examples = example_deltas.len();
        let (k_all, alpha) = (fit.n_shapes, fit.alpha);
        let mut priors: Vec<Vec<Vec3>> = vec![Vec::new(); k_all];
        for &k in fit.active {
            priors[k] = self.edge_changes(&fit.source_deltas[k * n..(k + 1) * n]);
        }
        let fitted: Vec<Vec<(usize, Vec3)>> = self
            .virtual_edges()
            .par_iter()
            .enumerate()
            .map(|(e, &(i, j))| {
                let (i, j) = (i as usize, j as usize);
                let spread: Vec<f64> = fit.active.iter().map(|&k| dot(priors[k][e], priors[k][e]) / fit.beta).collect();
                let mut system = vec![0.0; n_examples * n_examples];
                let mut residual: Vec<Vec3> = (0..n_examples)
                    .map(|x| {
                        let observed = sub(example_deltas[x][i], example_deltas[x][j]);
                        fit.active.iter().fold(observed, |acc, &k| sub(acc, scale(priors[k][e], alpha[x * k_all + k])))
                    })
                    .collect();
                for (&k, &tau) in fit.active.iter().zip(&spread) {
                    for a in 0..n_examples {
                        for b in 0..n_examples {
                            system[a * n_examples + b] += alpha[a * k_all + k] * alpha[b * k_all + k] * tau;
                        }
                    }
                }
                for x in 0..n_examples {
                    let diagonal = &mut system[x * n_examples + x];
                    let nu = 6.0 * noise[x] * noise[x];
                    *diagonal += if *diagonal > 0.0 { nu.max(EXACT_DATA * *diagonal) } else { 1.0 };
                }
                solve_spd(&mut system, n_examples, &mut residual);
                fit.active
                    .iter()
                    .zip(&spread)
                    .map(|(&k, &tau)| {
                        let pull = (0..n_examples).fold([0.0; 3], |acc, x| add(acc, scale(residual[x], alpha[x * k_all + k])));
                        (k, add(priors[k][e], scale(pull, tau)))
                    })
                    .collect()
            })
            .collect();
        for (e, per_edge) in fitted.into_iter().enumerate() {
            for (k, change) in per_edge {
                priors[k][e] = change;
            }
        }
        priors
    }

    /// Eq. P5: `Y_t` (J entries per triangle, triangle-major) with
    /// `(N_t + alpha T_t alpha^T) Y_t = A_t - alpha S_t` over the active shapes.
    fn corrections(&self, fit: &Fit<'_>, operators: &[HatGradients], example_deltas: &[Vec<Vec3>], noise: &[f64]) -> Vec<Mat3> {
        let n = self.n_vertices();
        let n_examples = example_deltas.len();
        let (k_all, alpha) = (fit.n_shapes, fit.alpha);
        (0..self.triangles.len())
            .into_par_iter()
            .flat_map_iter(|t| {
                let (tri, op) = (&self.triangles[t], &operators[t]);
                let mut system = vec![0.0; n_examples * n_examples];
                let mut residual: Vec<Mat3> =
                    example_deltas.iter().map(|e| linear_gradient(op, tri.map(|v| e[v as usize]))).collect();
                for &k in fit.active {
                    if !tri.iter().any(|&v| fit.moving[k][v as usize]) {
                        continue;
                    }
                    let s = self.triangle_gradient(t, &fit.source_deltas[k * n..(k + 1) * n]);
                    let spread = fit.prior_variance(&s, op);
                    for a in 0..n_examples {
                        let wa = alpha[a * k_all + k];
                        if wa == 0.0 {
                            continue;
                        }
                        residual[a] = mat_add_scaled(&residual[a], &tangential(&s, op), -wa);
                        for b in 0..n_examples {
                            system[a * n_examples + b] += wa * alpha[b * k_all + k] * spread;
                        }
                    }
                }
                let roughness: f64 = op.gradients.iter().map(|g| dot(*g, *g)).sum();
                for j in 0..n_examples {
                    let diagonal = &mut system[j * n_examples + j];
                    let nu = 3.0 * noise[j] * noise[j] * roughness;
                    *diagonal += if *diagonal > 0.0 { nu.max(EXACT_DATA * *diagonal) } else { 1.0 };
                }
                solve_spd(&mut system, n_examples, &mut residual);
                residual
            })
            .collect()
    }
}

/// What one personalisation fits with.
struct Fit<'a> {
    source_deltas: &'a [[f32; 3]],
    alpha: &'a [f64],
    n_shapes: usize,
    active: &'a [usize],
    /// Per shape, its moving vertices (empty for shapes not fitted).
    moving: &'a [Vec<bool>],
    beta: f64,
}

impl Fit<'_> {

    /// Eq. P2: `tau_kt = |S_kt P_t|^2 / beta`, the expected squared error of the transferred
    /// gradient, proportional to how much the shape deforms the triangle; zero on triangles
    /// whose corners the shape does not move.
    fn prior_variance(&self, s: &Mat3, op: &HatGradients) -> f64 {
        frobenius(&tangential(s, op)).powi(2) / self.beta
    }
}

/// Expressions need this many still vertices for their own noise estimate.
const MIN_STILL: usize = 30;

/// `X P_t`: the part of a gradient the Poisson solve sees (its action on the rest triangle's
/// plane), `P_t = I - n n^T`.
fn tangential(x: &Mat3, op: &HatGradients) -> Mat3 {
    let n = cross(op.gradients[0], op.gradients[1]);
    let n = scale(n, 1.0 / length(n));
    let mut out = *x;
    for row in out.iter_mut() {
        let along = dot(*row, n);
        *row = sub(*row, scale(n, along));
    }
    out
}

/// `sum_i d_i grad_phi_i^T`: the gradient of the piecewise-linear field with corner values
/// `d` on the rest triangle (rows are the coordinates), linear in `d`.
fn linear_gradient(op: &HatGradients, d: [Vec3; 3]) -> Mat3 {
    let mut out = ZERO;
    for (di, g) in d.iter().zip(&op.gradients) {
        for r in 0..3 {
            for c in 0..3 {
                out[r][c] += di[r] * g[c];
            }
        }
    }
    out
}

/// A right-hand side of the small dense solves: a 3x3 gradient or a translation.
trait Block: Copy {
    /// `self + s * other`.
    fn add_scaled(&self, other: &Self, s: f64) -> Self;
    /// `s * self`.
    fn scaled(&self, s: f64) -> Self;
}

impl Block for Mat3 {
    fn add_scaled(&self, other: &Self, s: f64) -> Self {
        mat_add_scaled(self, other, s)
    }
    fn scaled(&self, s: f64) -> Self {
        self.map(|row| row.map(|x| x * s))
    }
}

impl Block for Vec3 {
    fn add_scaled(&self, other: &Self, s: f64) -> Self {
        add(*self, scale(*other, s))
    }
    fn scaled(&self, s: f64) -> Self {
        scale(*self, s)
    }
}

/// Solves `M X = B` in place for symmetric positive definite `M` (dense, `j x j`, Cholesky).
/// `M = N + PSD` here with `N` a positive diagonal, so the pivots are positive.
fn solve_spd<B: Block>(m: &mut [f64], j: usize, rhs: &mut [B]) {
    for c in 0..j {
        let mut d = m[c * j + c];
        for k in 0..c {
            d -= m[c * j + k] * m[c * j + k];
        }
        let d = d.max(f64::MIN_POSITIVE).sqrt();
        m[c * j + c] = d;
        for r in c + 1..j {
            let mut x = m[r * j + c];
            for k in 0..c {
                x -= m[r * j + k] * m[c * j + k];
            }
            m[r * j + c] = x / d;
        }
    }
    // Forward (L y = b) then backward (L^T x = y) substitution, block-wise.
    for r in 0..j {
        for k in 0..r {
            rhs[r] = rhs[r].add_scaled(&rhs[k], -m[r * j + k]);
        }
        rhs[r] = rhs[r].scaled(1.0 / m[r * j + r]);
    }
    for r in (0..j).rev() {
        for k in r + 1..j {
            rhs[r] = rhs[r].add_scaled(&rhs[k], -m[k * j + r]);
        }
        rhs[r] = rhs[r].scaled(1.0 / m[r * j + r]);
    }
}

/// Eq. P6: per example, the weights of its members (the shapes given a non-zero weight) in
/// [0, 1] minimising `|sum_k alpha_k d_k - e_j|^2` over all vertices, `d_k` the transferred
/// shapes (projected coordinate descent from the given weights; other shapes keep weight 0).
fn refit_member_weights(shapes: &[Vec<Vec3>], examples: &[Vec<Vec3>], alpha: &[f64]) -> Vec<f64> {
    let k_all = shapes.len();
    let inner = |a: &[Vec3], b: &[Vec3]| a.iter().zip(b).map(|(x, y)| dot(*x, *y)).sum::<f64>();
    let gram: Vec<Vec<f64>> = (0..k_all)
        .into_par_iter()
        .map(|k| (0..k_all).map(|l| inner(&shapes[k], &shapes[l])).collect())
        .collect();
    let mut refined = alpha.to_vec();
    for (j, example) in examples.iter().enumerate() {
        let w = &mut refined[j * k_all..(j + 1) * k_all];
        let members: Vec<usize> = (0..k_all).filter(|&k| w[k] != 0.0 && gram[k][k] > 0.0).collect();
        let target: Vec<f64> = members.par_iter().map(|&k| inner(&shapes[k], example)).collect();
        for (k, weight) in w.iter_mut().enumerate() {
            *weight = if members.contains(&k) { weight.clamp(0.0, 1.0) } else { 0.0 };
        }
        for _sweep in 0..500 {
            let mut change: f64 = 0.0;
            for (&k, &aim) in members.iter().zip(&target) {
                let gradient: f64 = members.iter().map(|&l| gram[k][l] * w[l]).sum::<f64>() - aim;
                let next = (w[k] - gradient / gram[k][k]).clamp(0.0, 1.0);
                change = change.max((next - w[k]).abs());
                w[k] = next;
            }
            if change < 1e-10 {
                break;
            }
        }
    }
    refined
}

fn validate_personalise_params(params: &PersonaliseParams) -> ShapesmithResult<()> {
    if !(params.beta_reg.is_finite() && params.beta_reg > 0.0) {
        return Err(invalid!("beta_reg must be a positive number, got {}", params.beta_reg));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn small_spd_solve_matches_the_product() {
        let j = 3;
        let base = [4.0, 1.0, 0.5, 1.0, 3.0, 0.2, 0.5, 0.2, 2.0];
        let x: Vec<Mat3> = (0..j).map(|i| [[i as f64, 1.0, -2.0], [0.5, 0.0, 3.0 * i as f64], [1.0, 1.0, 1.0]]).collect();
        let mut b: Vec<Mat3> = (0..j)
            .map(|r| (0..j).fold(ZERO, |acc, c| mat_add_scaled(&acc, &x[c], base[r * j + c])))
            .collect();
        let mut m = base.to_vec();
        solve_spd(&mut m, j, &mut b);
        for i in 0..j {
            assert!((0..3).all(|r| (0..3).all(|c| (b[i][r][c] - x[i][r][c]).abs() < 1e-12)));
        }
    }

    #[test]
    fn weight_refit_recovers_a_mix_and_respects_the_box() {
        let d0: Vec<Vec3> = (0..30).map(|v| [v as f64, 0.0, 1.0]).collect();
        let d1: Vec<Vec3> = (0..30).map(|v| [0.0, (v as f64).sin(), 0.5]).collect();
        let still = vec![[0.0; 3]; 30];
        let shapes = vec![d0.clone(), d1.clone(), still];
        let mix: Vec<Vec3> = (0..30).map(|v| [0.3 * d0[v][0], 0.8 * d1[v][1], 0.3 + 0.4]).collect();
        let beyond: Vec<Vec3> = (0..30).map(|v| [2.0 * d0[v][0], -d1[v][1], 2.0 - 0.5]).collect();
        let w = refit_member_weights(&shapes, &[mix.clone(), beyond, mix.clone()], &[1.0, 1.0, 1.0, 0.5, 0.2, 0.5, 1.0, 0.0, 0.0]);
        assert!((w[0] - 0.3).abs() < 1e-6 && (w[1] - 0.8).abs() < 1e-6 && w[2] == 0.0, "{w:?}");
        // Wants (2, -1): clamped to the box.
        assert!((w[3] - 1.0).abs() < 1e-12 && w[4].abs() < 1e-12 && w[5] == 0.0, "{w:?}");
        // A shape not in the expression stays out of it, though it would explain the rest.
        let alone = d0.iter().zip(&mix).map(|(a, b)| dot(*a, *b)).sum::<f64>() / d0.iter().map(|a| dot(*a, *a)).sum::<f64>();
        assert!((w[6] - alone).abs() < 1e-9 && w[7] == 0.0 && w[8] == 0.0, "{w:?} vs {alone}");
    }
}
