//! Example-based personalisation (Li, Weise & Pauly 2010, "Example-based facial rigging",
//! section 4): refit the transferred shapes so that the blendshape model reproduces training
//! expressions of the target, regularised in the gradient domain towards deformation transfer.
//!
//! Per triangle t, with `S_kt` the transferred gradients (stored as `S - I`), `A_jt` the
//! example gradients and `alpha` the J x K weights, the personalised gradients minimise
//! (EBFR Eq. (3)-(5), gradient form)
//!
//! `sum_j |sum_k alpha_jk M_kt - A_jt|_F^2 + beta sum_k w_kt |M_kt - S_kt|_F^2`,
//! `w_kt = ((1 + |S_kt|_F) / (kappa + |S_kt|_F))^theta`, here divided by its value at the
//! shape's largest strain so that `beta` is the weight where the shape deforms most.
//!
//! The normal equations `(alpha^T alpha + D) M = alpha^T A + D S`, `D = beta diag(w)`, have
//! the closed form `M = S + D^{-1} alpha^T Y` with `(I_J + alpha D^{-1} alpha^T) Y = A - alpha S`
//! (push-through identity): one J x J solve per triangle instead of K x K. Shapes in no
//! example keep `M = S` exactly; with no example the result is plain transfer. Each shape is
//! then one Poisson solve with its plain-transfer static set.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;

use rayon::prelude::*;

use super::deformation::DeformationTransfer;
use super::gradients::{corners, delta_gradient, dot, edge_frame, frobenius, inverse, mat_add_scaled, sub, Mat3, Vec3, ZERO};
use crate::error::ShapesmithResult;
use crate::invalid;
use crate::progress::Progress;
use crate::rig::validate_points;

/// Knobs of [`DeformationTransfer::personalise`]; defaults from SPEC section 3 and EBFR.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct PersonaliseParams {
    /// `beta`, the weight of the pull towards the deformation-transferred gradients.
    pub beta_reg: f64,
    /// `kappa` of EBFR's adaptive weight: how much more a shape is held where it barely moves.
    pub kappa: f64,
    /// `theta` of EBFR's adaptive weight.
    pub theta: f64,
    /// Refit the example weights (bounded to [0, 1]) in alternation with the shapes.
    pub refine_weights: bool,
    /// Number of weight refits when `refine_weights` is set.
    pub refine_iterations: usize,
}

impl Default for PersonaliseParams {
    fn default() -> Self {
        Self { beta_reg: 0.1, kappa: 0.1, theta: 2.0, refine_weights: false, refine_iterations: 3 }
    }
}

/// Personalised shapes.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Personalisation {
    /// K x N target deltas, shape-major.
    pub deltas: Vec<[f32; 3]>,
    /// J x K weights the shapes were fitted with (refined, or as given).
    pub weights: Vec<f64>,
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
        let example_gradients = self.example_gradients(&example_deltas)?;
        let inert: Vec<bool> = (0..n_shapes).map(|k| self.is_inert(&source_deltas[k * n..(k + 1) * n])).collect();

        let mut alpha = weights.to_vec();
        let rounds = if params.refine_weights { 1 + params.refine_iterations } else { 1 };
        let done = AtomicUsize::new(0);
        let total = (rounds * n_shapes).max(1) as f64;
        let mut shapes: Vec<Vec<Vec3>> = Vec::new();
        for round in 0..rounds {
            if round > 0 {
                alpha = refit_weights(&shapes, &example_deltas, &alpha);
            }
            let active: Vec<usize> =
                (0..n_shapes).filter(|&k| !inert[k] && (0..n_examples).any(|j| alpha[j * n_shapes + k] != 0.0)).collect();
            let ctx = Fit { source_deltas, alpha: &alpha, n_shapes, active: &active, params };
            let corrections = self.corrections(&ctx, &example_gradients);
            shapes = (0..n_shapes)
                .into_par_iter()
                .map(|k| {
                    let delta = &source_deltas[k * n..(k + 1) * n];
                    let out = if inert[k] {
                        vec![[0.0; 3]; n]
                    } else {
                        let mut gradients = self.shape_gradients(delta);
                        if active.contains(&k) {
                            let peak = peak_strain(&gradients);
                            for (t, g) in gradients.iter_mut().enumerate() {
                                let inverse_weight = 1.0 / (params.beta_reg * adaptive_weight(g, peak, params));
                                let mut sum = ZERO;
                                for j in 0..n_examples {
                                    sum = mat_add_scaled(&sum, &corrections[t * n_examples + j], alpha[j * n_shapes + k]);
                                }
                                *g = mat_add_scaled(g, &sum, inverse_weight);
                            }
                        }
                        self.solve_shape(delta, |t| gradients[t])?
                    };
                    let finished = done.fetch_add(1, Ordering::Relaxed) + 1;
                    progress.checkpoint(finished as f64 / total)?;
                    Ok(out)
                })
                .collect::<ShapesmithResult<Vec<_>>>()?;
        }
        Ok(Personalisation {
            deltas: shapes.iter().flat_map(|d| self.to_target_frame(d)).collect(),
            weights: alpha,
            inert: self.inert_names(source_deltas, names),
            seconds: start.elapsed().as_secs_f64(),
        })
    }

    /// `A_jt = E_jt E_0t^{-1} - I` on the target triangles (working frame), J x T.
    fn example_gradients(&self, example_deltas: &[Vec<Vec3>]) -> ShapesmithResult<Vec<Vec<Mat3>>> {
        let rest_inverse = self
            .triangles
            .iter()
            .enumerate()
            .map(|(t, tri)| {
                inverse(&edge_frame(corners(&self.target_neutral, None, tri)))
                    .ok_or_else(|| invalid!("target: triangle {t} is degenerate"))
            })
            .collect::<ShapesmithResult<Vec<_>>>()?;
        Ok(example_deltas
            .par_iter()
            .map(|e| {
                self.triangles
                    .iter()
                    .zip(&rest_inverse)
                    .map(|(tri, inv)| delta_gradient(inv, corners(&self.target_neutral, Some(e), tri)))
                    .collect()
            })
            .collect())
    }

    /// `Y_t` (J entries per triangle, triangle-major) with
    /// `(I_J + alpha D_t^{-1} alpha^T) Y_t = A_t - alpha S_t` over the active shapes.
    fn corrections(&self, fit: &Fit<'_>, example_gradients: &[Vec<Mat3>]) -> Vec<Mat3> {
        let n = self.n_vertices();
        let n_examples = example_gradients.len();
        let (k_all, alpha) = (fit.n_shapes, fit.alpha);
        let peaks: Vec<f64> = fit
            .active
            .par_iter()
            .map(|&k| peak_strain(&self.shape_gradients(&fit.source_deltas[k * n..(k + 1) * n])))
            .collect();
        (0..self.triangles.len())
            .into_par_iter()
            .flat_map_iter(|t| {
                let mut system = vec![0.0; n_examples * n_examples];
                for j in 0..n_examples {
                    system[j * n_examples + j] = 1.0;
                }
                let mut residual: Vec<Mat3> = (0..n_examples).map(|j| example_gradients[j][t]).collect();
                for (&k, &peak) in fit.active.iter().zip(&peaks) {
                    let s = self.triangle_gradient(t, &fit.source_deltas[k * n..(k + 1) * n]);
                    let inverse_weight = 1.0 / (fit.params.beta_reg * adaptive_weight(&s, peak, fit.params));
                    for a in 0..n_examples {
                        let wa = alpha[a * k_all + k];
                        if wa == 0.0 {
                            continue;
                        }
                        residual[a] = mat_add_scaled(&residual[a], &s, -wa);
                        for b in 0..n_examples {
                            system[a * n_examples + b] += wa * alpha[b * k_all + k] * inverse_weight;
                        }
                    }
                }
                solve_spd(&mut system, n_examples, &mut residual);
                residual
            })
            .collect()
    }
}

/// What one personalisation round fits with.
struct Fit<'a> {
    source_deltas: &'a [[f32; 3]],
    alpha: &'a [f64],
    n_shapes: usize,
    active: &'a [usize],
    params: &'a PersonaliseParams,
}

/// EBFR's adaptive regulariser weight `((1 + |S|) / (kappa + |S|))^theta`, divided by its
/// value at the shape's largest strain `peak`: 1 where the template shape deforms most (there
/// `beta` alone weighs the transfer against the examples) and up to `(1 / kappa)^theta`
/// where it does not deform, so an example cannot pull a shape into a region it does not move.
fn adaptive_weight(s: &Mat3, peak: f64, params: &PersonaliseParams) -> f64 {
    let raw = |norm: f64| ((1.0 + norm) / (params.kappa + norm)).powf(params.theta);
    raw(frobenius(s)) / raw(peak)
}

/// The largest `|S_kt|_F` of a shape over its triangles.
fn peak_strain(gradients: &[Mat3]) -> f64 {
    gradients.iter().map(frobenius).fold(0.0, f64::max)
}

/// Solves `M X = B` in place for symmetric positive definite `M` (dense, `j x j`, Cholesky).
/// `M = I + PSD` here, so the pivots are at least 1.
fn solve_spd(m: &mut [f64], j: usize, rhs: &mut [Mat3]) {
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
    // Forward (L y = b) then backward (L^T x = y) substitution, entry-wise on 3x3 blocks.
    for r in 0..j {
        for k in 0..r {
            rhs[r] = mat_add_scaled(&rhs[r], &rhs[k], -m[r * j + k]);
        }
        rhs[r] = rhs[r].map(|row| row.map(|x| x / m[r * j + r]));
    }
    for r in (0..j).rev() {
        for k in r + 1..j {
            rhs[r] = mat_add_scaled(&rhs[r], &rhs[k], -m[k * j + r]);
        }
        rhs[r] = rhs[r].map(|row| row.map(|x| x / m[r * j + r]));
    }
}

/// Per example, the weights in [0, 1] minimising `|sum_k alpha_k d_k - e_j|^2` over all
/// vertices (projected coordinate descent from the current weights; shapes that do not move
/// keep weight 0).
fn refit_weights(shapes: &[Vec<Vec3>], examples: &[Vec<Vec3>], alpha: &[f64]) -> Vec<f64> {
    let k_all = shapes.len();
    let inner = |a: &[Vec3], b: &[Vec3]| a.iter().zip(b).map(|(x, y)| dot(*x, *y)).sum::<f64>();
    let gram: Vec<Vec<f64>> = (0..k_all)
        .into_par_iter()
        .map(|k| (0..k_all).map(|l| inner(&shapes[k], &shapes[l])).collect())
        .collect();
    let mut refined = alpha.to_vec();
    for (j, example) in examples.iter().enumerate() {
        let target: Vec<f64> = shapes.par_iter().map(|d| inner(d, example)).collect();
        let w = &mut refined[j * k_all..(j + 1) * k_all];
        for k in 0..k_all {
            w[k] = if gram[k][k] > 0.0 { w[k].clamp(0.0, 1.0) } else { 0.0 };
        }
        for _sweep in 0..500 {
            let mut change: f64 = 0.0;
            for k in 0..k_all {
                if gram[k][k] <= 0.0 {
                    continue;
                }
                let gradient: f64 = (0..k_all).map(|l| gram[k][l] * w[l]).sum::<f64>() - target[k];
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
    if !(params.kappa.is_finite() && params.kappa > 0.0 && params.theta.is_finite() && params.theta >= 0.0) {
        return Err(invalid!("kappa must be positive and theta >= 0, got kappa = {}, theta = {}", params.kappa, params.theta));
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
        let w = refit_weights(&shapes, &[mix, beyond], &[1.0, 1.0, 1.0, 0.0, 0.0, 0.5]);
        assert!((w[0] - 0.3).abs() < 1e-6 && (w[1] - 0.8).abs() < 1e-6 && w[2] == 0.0, "{w:?}");
        // Wants (2, -1): clamped to the box.
        assert!((w[3] - 1.0).abs() < 1e-12 && w[4].abs() < 1e-12 && w[5] == 0.0, "{w:?}");
    }
}
