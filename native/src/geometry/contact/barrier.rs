//! The contact potential of IPC (Li, Ferguson, Schneider, Langlois, Zorin, Panozzo, Jiang,
//! Kaufman 2020): per pair closer than `d_hat`, `kappa m(x) b(d^2)` with the log barrier
//! `b(s) = -(s - s_hat)^2 ln(s / s_hat)` for `s < s_hat = d_hat^2` (zero beyond: C2 at
//! `s_hat`), on squared distances as ipc-toolkit writes it, and for edge-edge pairs the
//! mollifier `m(x)` of section 4.3, which smooths the barrier where two edges turn parallel
//! and the distance type changes. Its Hessian, projected to the nearest positive
//! semi-definite matrix ([`project_psd`]), is the pair's block of projected Newton.

use super::distance::{edge_edge_type, point_triangle_type, squared};
use super::dual::{cross, dot, sub, variables, Dual, N};

/// `b(s)` and its first two derivatives in `s`, for `0 < s < s_hat` (zero beyond).
pub fn barrier(s: f64, s_hat: f64) -> (f64, f64, f64) {
    if s >= s_hat {
        return (0.0, 0.0, 0.0);
    }
    let (r, l) = (s - s_hat, (s / s_hat).ln());
    (-r * r * l, -2.0 * r * l - r * r / s, -2.0 * l - 4.0 * r / s + r * r / (s * s))
}

/// The edge-edge mollifier `m(x) = -x^2 / e^2 + 2 x / e` for `x < e`, else 1, of
/// `x = |(a1 - a0) x (b1 - b0)|^2`, `e = 1e-3 |a1 - a0|^2 |b1 - b0|^2` at rest (IPC 4.3).
pub fn mollifier(x: Dual, threshold: f64) -> Dual {
    if x.v >= threshold {
        return Dual::constant(1.0);
    }
    let e = threshold;
    x.chain(-x.v * x.v / (e * e) + 2.0 * x.v / e, -2.0 * x.v / (e * e) + 2.0 / e, -2.0 / (e * e))
}

/// `e` of [`mollifier`] for edges whose rest vectors are `a`, `b`.
pub fn mollifier_threshold(a: [f64; 3], b: [f64; 3]) -> f64 {
    1e-3 * dot(a, a) * dot(b, b)
}

/// Which primitives a pair holds: a point and a triangle, or two edges (with the edges'
/// mollifier threshold).
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum PairKind {
    PointTriangle,
    EdgeEdge { mollifier: f64 },
}

/// The pair's squared distance (by its distance type).
pub fn pair_squared(kind: PairKind, x: &[[f64; 3]; 4]) -> f64 {
    match kind {
        PairKind::PointTriangle => squared(point_triangle_type(x), x),
        PairKind::EdgeEdge { .. } => squared(edge_edge_type(x), x),
    }
}

/// `m(x) b(d^2)` of one pair (without `kappa`), zero when the pair is `d_hat` or more apart.
pub fn pair_energy(kind: PairKind, x: &[[f64; 3]; 4], s_hat: f64) -> f64 {
    let s = pair_squared(kind, x);
    let b = barrier(s, s_hat).0;
    match kind {
        PairKind::EdgeEdge { mollifier: e } if b != 0.0 => {
            let c = cross(sub(x[1], x[0]), sub(x[3], x[2]));
            let m = dot(c, c);
            if m < e {
                b * (-m * m / (e * e) + 2.0 * m / e)
            } else {
                b
            }
        }
        _ => b,
    }
}

/// `m(x) b(d^2)` with its gradient and Hessian in the pair's 12 coordinates.
pub fn pair_derivatives(kind: PairKind, x: &[[f64; 3]; 4], s_hat: f64) -> Dual {
    // Most candidates of a broad phase are beyond `d_hat`: tested in plain numbers first.
    if pair_squared(kind, x) >= s_hat {
        return Dual::constant(0.0);
    }
    let vars = variables(x);
    let kind_of = match kind {
        PairKind::PointTriangle => point_triangle_type(x),
        PairKind::EdgeEdge { .. } => edge_edge_type(x),
    };
    let s = squared(kind_of, &vars);
    if s.v >= s_hat {
        return Dual::constant(0.0);
    }
    let (b, db, ddb) = barrier(s.v, s_hat);
    let energy = s.chain(b, db, ddb);
    match kind {
        PairKind::EdgeEdge { mollifier: e } => {
            let c = cross(sub(vars[1], vars[0]), sub(vars[3], vars[2]));
            let m = mollifier(dot(c, c), e);
            if m.v == 1.0 && m.g.iter().all(|&g| g == 0.0) {
                energy
            } else {
                energy * m
            }
        }
        PairKind::PointTriangle => energy,
    }
}

/// The symmetric matrix `h` with its negative eigenvalues set to zero: `V max(L, 0) V^T` from
/// its eigendecomposition `h = V L V^T` ([`symmetric_eigen`]).
pub fn project_psd<const M: usize>(h: &[[f64; M]; M]) -> [[f64; M]; M] {
    let (values, vectors) = symmetric_eigen(h);
    let mut out = [[0.0; M]; M];
    for (k, &lambda) in values.iter().enumerate() {
        if lambda <= 0.0 {
            continue;
        }
        for i in 0..M {
            let vi = lambda * vectors[i][k];
            for j in 0..M {
                out[i][j] += vi * vectors[j][k];
            }
        }
    }
    out
}

/// Eigenvalues `d` and eigenvectors (the columns of `V`) of the symmetric matrix `h`:
/// Householder reduction to tridiagonal form, then the implicit QL iteration (Wilkinson and
/// Reinsch's `tred2` and `tql2`, as the public-domain JAMA library writes them): about
/// `10 M^3` operations, where cyclic Jacobi rotations took about `6 M^3` a sweep and six to
/// eight sweeps (the projection was a sixth of the contact solve's time on the bench heads).
fn symmetric_eigen<const M: usize>(h: &[[f64; M]; M]) -> ([f64; M], [[f64; M]; M]) {
    let (mut v, mut d, mut e) = (*h, [0.0; M], [0.0; M]);
    if M == 0 {
        return (d, v);
    }
    let n = M;
    // tred2: `v` becomes the orthogonal reduction, `d` the diagonal, `e` the off-diagonal.
    d.copy_from_slice(&v[n - 1]);
    for i in (1..n).rev() {
        let scale: f64 = d[..i].iter().map(|x| x.abs()).sum();
        let mut h = 0.0;
        if scale == 0.0 {
            e[i] = d[i - 1];
            for j in 0..i {
                d[j] = v[i - 1][j];
                v[i][j] = 0.0;
                v[j][i] = 0.0;
            }
        } else {
            for dk in d[..i].iter_mut() {
                *dk /= scale;
                h += *dk * *dk;
            }
            let f = d[i - 1];
            let g = if f > 0.0 { -h.sqrt() } else { h.sqrt() };
            e[i] = scale * g;
            h -= f * g;
            d[i - 1] = f - g;
            e[..i].iter_mut().for_each(|x| *x = 0.0);
            for j in 0..i {
                let f = d[j];
                v[j][i] = f;
                let mut g = e[j] + v[j][j] * f;
                for k in j + 1..i {
                    g += v[k][j] * d[k];
                    e[k] += v[k][j] * f;
                }
                e[j] = g;
            }
            let mut f = 0.0;
            for j in 0..i {
                e[j] /= h;
                f += e[j] * d[j];
            }
            let hh = f / (h + h);
            for j in 0..i {
                e[j] -= hh * d[j];
            }
            for j in 0..i {
                let (f, g) = (d[j], e[j]);
                for k in j..i {
                    v[k][j] -= f * e[k] + g * d[k];
                }
                d[j] = v[i - 1][j];
                v[i][j] = 0.0;
            }
        }
        d[i] = h;
    }
    for i in 0..n - 1 {
        v[n - 1][i] = v[i][i];
        v[i][i] = 1.0;
        let h = d[i + 1];
        if h != 0.0 {
            for k in 0..=i {
                d[k] = v[k][i + 1] / h;
            }
            for j in 0..=i {
                let g: f64 = (0..=i).map(|k| v[k][i + 1] * v[k][j]).sum();
                for k in 0..=i {
                    v[k][j] -= g * d[k];
                }
            }
        }
        for row in v[..=i].iter_mut() {
            row[i + 1] = 0.0;
        }
    }
    for j in 0..n {
        d[j] = v[n - 1][j];
        v[n - 1][j] = 0.0;
    }
    v[n - 1][n - 1] = 1.0;
    e[0] = 0.0;
    // tql2: the tridiagonal matrix diagonalised by implicit QL steps with Wilkinson shifts.
    for i in 1..n {
        e[i - 1] = e[i];
    }
    e[n - 1] = 0.0;
    let (mut f, mut largest) = (0.0f64, 0.0f64);
    for l in 0..n {
        largest = largest.max(d[l].abs() + e[l].abs());
        let m = (l..n).find(|&m| e[m].abs() <= f64::EPSILON * largest).unwrap_or(n - 1);
        // Each QL step shrinks `e[l]` quadratically; thirty are a bound never met in practice.
        for _ in 0..30 {
            if m <= l || e[l].abs() <= f64::EPSILON * largest {
                break;
            }
            let g = d[l];
            let mut p = (d[l + 1] - g) / (2.0 * e[l]);
            let r = if p < 0.0 { -p.hypot(1.0) } else { p.hypot(1.0) };
            d[l] = e[l] / (p + r);
            d[l + 1] = e[l] * (p + r);
            let dl1 = d[l + 1];
            let shift = g - d[l];
            for x in d[l + 2..].iter_mut() {
                *x -= shift;
            }
            f += shift;
            p = d[m];
            let (mut c, mut c2, mut c3) = (1.0f64, 1.0f64, 1.0f64);
            let el1 = e[l + 1];
            let (mut s, mut s2) = (0.0f64, 0.0f64);
            for i in (l..m).rev() {
                c3 = c2;
                c2 = c;
                s2 = s;
                let g = c * e[i];
                let h = c * p;
                let r = p.hypot(e[i]);
                e[i + 1] = s * r;
                s = e[i] / r;
                c = p / r;
                p = c * d[i] - s * g;
                d[i + 1] = h + s * (c * g + s * d[i]);
                for row in v.iter_mut() {
                    let h = row[i + 1];
                    row[i + 1] = s * row[i] + c * h;
                    row[i] = c * row[i] - s * h;
                }
            }
            p = -s * s2 * c3 * el1 * e[l] / dl1;
            e[l] = s * p;
            d[l] = c * p;
        }
        d[l] += f;
        e[l] = 0.0;
    }
    (d, v)
}

/// `W (x) I_3` applied to the rows of `h` (`W` the 4 x 4 Hadamard matrix over 2, symmetric
/// and its own inverse), its first block row the mean of the four points.
fn hadamard_rows(h: &[[f64; N]; N]) -> [[f64; N]; N] {
    const W: [[f64; 4]; 4] = [[1.0, 1.0, 1.0, 1.0], [1.0, 1.0, -1.0, -1.0], [1.0, -1.0, 1.0, -1.0], [1.0, -1.0, -1.0, 1.0]];
    std::array::from_fn(|i| std::array::from_fn(|j| (0..4).map(|b| 0.5 * W[i / 3][b] * h[3 * b + i % 3][j]).sum()))
}

/// [`project_psd`] of a pair's Hessian, whose energy does not change when the four points
/// move together (it depends on their differences alone): `h t = 0` for the three
/// translations `t`. In the orthonormal basis `T = W (x) I_3` ([`hadamard_rows`]) whose first
/// three vectors are the translations, `T h T = diag(0, h_9)`; the projection of `h` is
/// `T diag(0, P(h_9)) T`, the eigenvalue problem 9 x 9 instead of 12 x 12 (the
/// eigenproblem's cost grows as the cube: 0.42 of it).
pub fn project_pair_psd(h: &[[f64; N]; N]) -> [[f64; N]; N] {
    let rotated = hadamard_rows(&transpose(&hadamard_rows(h)));
    let inner: [[f64; 9]; 9] = std::array::from_fn(|i| std::array::from_fn(|j| rotated[i + 3][j + 3]));
    let projected = project_psd(&inner);
    let padded: [[f64; N]; N] = std::array::from_fn(|i| std::array::from_fn(|j| if i < 3 || j < 3 { 0.0 } else { projected[i - 3][j - 3] }));
    hadamard_rows(&transpose(&hadamard_rows(&padded)))
}

fn transpose(h: &[[f64; N]; N]) -> [[f64; N]; N] {
    std::array::from_fn(|i| std::array::from_fn(|j| h[j][i]))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::contact::distance::tests_support::Lcg;

    fn perturbed(x: &[[f64; 3]; 4], i: usize, h: f64) -> [[f64; 3]; 4] {
        let mut y = *x;
        y[i / 3][i % 3] += h;
        y
    }

    #[test]
    fn barrier_derivatives_match_finite_differences() {
        let s_hat = 0.7;
        for &s in &[0.01, 0.1, 0.3, 0.5, 0.69] {
            let (_, d, dd) = barrier(s, s_hat);
            let h = 1e-6;
            let fd = (barrier(s + h, s_hat).0 - barrier(s - h, s_hat).0) / (2.0 * h);
            let fdd = (barrier(s + h, s_hat).1 - barrier(s - h, s_hat).1) / (2.0 * h);
            assert!((d - fd).abs() <= 1e-6 * (1.0 + d.abs()), "{s}: {d} vs {fd}");
            assert!((dd - fdd).abs() <= 1e-5 * (1.0 + dd.abs()), "{s}: {dd} vs {fdd}");
        }
        // C2 at s_hat: value and derivatives vanish from below.
        let (b, d, _) = barrier(s_hat * (1.0 - 1e-9), s_hat);
        assert!(b.abs() < 1e-15 && d.abs() < 1e-8);
        assert!(barrier(1e-12, s_hat).0 > barrier(1e-6, s_hat).0);
    }

    #[test]
    fn pair_gradient_and_hessian_match_finite_differences_of_the_energy() {
        let mut rng = Lcg(3);
        let mut checked = 0;
        for trial in 0..400 {
            let base = [rng.point(), rng.point(), rng.point(), rng.point()];
            let scale = 0.4;
            let x: [[f64; 3]; 4] = std::array::from_fn(|p| base[p].map(|c| c * scale));
            let kind = if trial % 2 == 0 {
                PairKind::PointTriangle
            } else {
                let (a, b) = (sub(x[1], x[0]), sub(x[3], x[2]));
                // Half the edge pairs near parallel, where the mollifier is active.
                PairKind::EdgeEdge { mollifier: if trial % 4 == 1 { 10.0 * dot(cross(a, b), cross(a, b)) } else { mollifier_threshold(a, b) } }
            };
            let s = pair_squared(kind, &x);
            let s_hat = 1.5 * s;
            let d = pair_derivatives(kind, &x, s_hat);
            assert!((d.v - pair_energy(kind, &x, s_hat)).abs() <= 1e-12 * (1.0 + d.v.abs()));
            let h = 1e-6 * s.sqrt().max(1e-3);
            // Skip pairs whose distance type changes within the stencil (a kink of the
            // distance, not of the formula).
            let types_same = (0..N).all(|i| {
                let (p, m) = (perturbed(&x, i, h), perturbed(&x, i, -h));
                match kind {
                    PairKind::PointTriangle => point_triangle_type(&p) == point_triangle_type(&x) && point_triangle_type(&m) == point_triangle_type(&x),
                    PairKind::EdgeEdge { .. } => edge_edge_type(&p) == edge_edge_type(&x) && edge_edge_type(&m) == edge_edge_type(&x),
                }
            });
            if !types_same {
                continue;
            }
            checked += 1;
            let size = d.g.iter().map(|g| g.abs()).fold(0.0, f64::max).max(1e-12);
            for i in 0..N {
                let fd = (pair_energy(kind, &perturbed(&x, i, h), s_hat) - pair_energy(kind, &perturbed(&x, i, -h), s_hat)) / (2.0 * h);
                assert!((d.g[i] - fd).abs() <= 1e-4 * size, "trial {trial} coordinate {i}: {} vs {fd}", d.g[i]);
                let gp = pair_derivatives(kind, &perturbed(&x, i, h), s_hat);
                let gm = pair_derivatives(kind, &perturbed(&x, i, -h), s_hat);
                let hsize = d.h.iter().flatten().map(|x| x.abs()).fold(0.0, f64::max).max(1e-12);
                for j in 0..N {
                    let fd = (gp.g[j] - gm.g[j]) / (2.0 * h);
                    assert!((d.h[j][i] - fd).abs() <= 1e-4 * hsize, "trial {trial} entry ({j}, {i}): {} vs {fd}", d.h[j][i]);
                }
            }
        }
        assert!(checked > 300, "only {checked} pairs checked");
    }

    #[test]
    fn psd_projection_keeps_positive_parts_and_drops_negative_ones() {
        let mut rng = Lcg(5);
        let mut q = [[0.0; N]; N];
        for row in q.iter_mut() {
            for x in row.iter_mut() {
                *x = rng.next() - 0.5;
            }
        }
        // A symmetric matrix with both signs, and its projection.
        let mut h = [[0.0; N]; N];
        for i in 0..N {
            for j in 0..N {
                h[i][j] = (0..N).map(|k| q[i][k] * q[j][k] * if k % 3 == 0 { -1.0 } else { 1.0 }).sum();
            }
        }
        let p = project_psd(&h);
        // `h = P + Q` with `P` PSD, `Q` negative semi-definite and `P Q = 0` characterises the
        // projection.
        let quad = |m: &[[f64; N]; N], v: &[f64; N]| -> f64 { (0..N).map(|i| (0..N).map(|j| v[i] * m[i][j] * v[j]).sum::<f64>()).sum() };
        let rest: [[f64; N]; N] = std::array::from_fn(|i| std::array::from_fn(|j| h[i][j] - p[i][j]));
        for _ in 0..50 {
            let v: [f64; N] = std::array::from_fn(|_| rng.next() - 0.5);
            assert!(quad(&p, &v) >= -1e-12);
            assert!(quad(&rest, &v) <= 1e-12);
        }
        let size = h.iter().flatten().map(|x| x.abs()).fold(0.0, f64::max);
        assert!((0..N).all(|i| (0..N).all(|j| (0..N).map(|k| p[i][k] * rest[k][j]).sum::<f64>().abs() <= 1e-10 * size * size)));
        // A PSD matrix is kept.
        let psd: [[f64; N]; N] = std::array::from_fn(|i| std::array::from_fn(|j| (0..N).map(|k| q[i][k] * q[j][k]).sum()));
        let kept = project_psd(&psd);
        assert!((0..N).all(|i| (0..N).all(|j| (kept[i][j] - psd[i][j]).abs() < 1e-10)));
    }

    #[test]
    fn the_pair_projection_equals_the_full_one_on_pair_hessians() {
        let mut rng = Lcg(11);
        let mut compared = 0;
        for trial in 0..200 {
            let x: [[f64; 3]; 4] = std::array::from_fn(|_| rng.point().map(|c| c * 0.4));
            let kind = if trial % 2 == 0 { PairKind::PointTriangle } else { PairKind::EdgeEdge { mollifier: mollifier_threshold(sub(x[1], x[0]), sub(x[3], x[2])) } };
            let d = pair_derivatives(kind, &x, 1.5 * pair_squared(kind, &x));
            let size = d.h.iter().flatten().map(|x| x.abs()).fold(0.0, f64::max);
            if size == 0.0 {
                continue;
            }
            let (full, reduced) = (project_psd(&d.h), project_pair_psd(&d.h));
            assert!((0..N).all(|i| (0..N).all(|j| (full[i][j] - reduced[i][j]).abs() <= 1e-10 * size)), "trial {trial}");
            // And it does project: some of these Hessians have negative eigenvalues.
            compared += usize::from((0..N).any(|i| (0..N).any(|j| (full[i][j] - d.h[i][j]).abs() > 1e-6 * size)));
        }
        assert!(compared > 50, "only {compared} indefinite Hessians");
    }
}
