//! Per-triangle deformation gradients (Sumner & Popovic 2004, Eq. (1)-(3)) and the
//! gradient operator of a rest triangle (gradient form of Botsch et al. 2006).
//!
//! Matrices are row-major `[[f64; 3]; 3]`; `m[r][c]` is row `r`, column `c`.

pub type Vec3 = [f64; 3];
pub type Mat3 = [[f64; 3]; 3];

pub const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];
pub const ZERO: Mat3 = [[0.0; 3]; 3];

pub fn to_f64(p: &[f32; 3]) -> Vec3 {
    p.map(f64::from)
}

pub fn sub(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub fn add(a: Vec3, b: Vec3) -> Vec3 {
    [a[0] + b[0], a[1] + b[1], a[2] + b[2]]
}

pub fn scale(a: Vec3, s: f64) -> Vec3 {
    [a[0] * s, a[1] * s, a[2] * s]
}

pub fn dot(a: Vec3, b: Vec3) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

pub fn cross(a: Vec3, b: Vec3) -> Vec3 {
    [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
}

pub fn length(a: Vec3) -> f64 {
    dot(a, a).sqrt()
}

pub fn mat_vec(m: &Mat3, v: Vec3) -> Vec3 {
    [dot(m[0], v), dot(m[1], v), dot(m[2], v)]
}

pub fn mat_mul(a: &Mat3, b: &Mat3) -> Mat3 {
    let mut out = ZERO;
    for r in 0..3 {
        for c in 0..3 {
            out[r][c] = a[r][0] * b[0][c] + a[r][1] * b[1][c] + a[r][2] * b[2][c];
        }
    }
    out
}

pub fn transpose(m: &Mat3) -> Mat3 {
    let mut out = ZERO;
    for r in 0..3 {
        for c in 0..3 {
            out[r][c] = m[c][r];
        }
    }
    out
}

/// `a + s * b`, entry-wise.
pub fn mat_add_scaled(a: &Mat3, b: &Mat3, s: f64) -> Mat3 {
    let mut out = *a;
    for r in 0..3 {
        for c in 0..3 {
            out[r][c] += s * b[r][c];
        }
    }
    out
}

pub fn frobenius(m: &Mat3) -> f64 {
    m.iter().flatten().map(|x| x * x).sum::<f64>().sqrt()
}

/// Inverse by the adjugate; `None` when the determinant vanishes.
pub fn inverse(m: &Mat3) -> Option<Mat3> {
    let c0 = cross(m_col(m, 1), m_col(m, 2));
    let c1 = cross(m_col(m, 2), m_col(m, 0));
    let c2 = cross(m_col(m, 0), m_col(m, 1));
    let det = dot(m_col(m, 0), c0);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    // Rows of the inverse are the cofactor vectors over the determinant.
    Some([scale(c0, 1.0 / det), scale(c1, 1.0 / det), scale(c2, 1.0 / det)])
}

fn m_col(m: &Mat3, c: usize) -> Vec3 {
    [m[0][c], m[1][c], m[2][c]]
}

/// The edge matrix `V = [v2 - v1, v3 - v1, v4 - v1]` of Sumner & Popovic (Eq. (3)), with
/// the fourth vertex `v4 = v1 + n / sqrt(|n|)`, `n = (v2 - v1) x (v3 - v1)`: the scaled
/// normal grows like an edge, so a uniformly scaled triangle has gradient `s I`.
pub fn edge_frame(p: [Vec3; 3]) -> Mat3 {
    let e1 = sub(p[1], p[0]);
    let e2 = sub(p[2], p[0]);
    let n = cross(e1, e2);
    let len = length(n);
    let n = if len > 0.0 { scale(n, 1.0 / len.sqrt()) } else { n };
    // Columns e1, e2, n.
    [[e1[0], e2[0], n[0]], [e1[1], e2[1], n[1]], [e1[2], e2[2], n[2]]]
}

/// The corners of triangle `tri` as f64 points of `points + offsets` (offsets optional).
pub fn corners(points: &[Vec3], offsets: Option<&[Vec3]>, tri: &[u32; 3]) -> [Vec3; 3] {
    tri.map(|v| {
        let p = points[v as usize];
        match offsets {
            Some(d) => add(p, d[v as usize]),
            None => p,
        }
    })
}

/// The delta gradient `S - I` of a deformed triangle, with `S = V~ V^{-1}` (Sumner & Popovic
/// Eq. (1)); `rest_inverse` is `V^{-1}` of the rest triangle.
pub fn delta_gradient(rest_inverse: &Mat3, deformed: [Vec3; 3]) -> Mat3 {
    mat_add_scaled(&mat_mul(&edge_frame(deformed), rest_inverse), &IDENTITY, -1.0)
}

/// The rest triangle's gradient operator in gradient form: the area and the gradients of the
/// three hat functions, `grad phi_i = n_hat x (p_{i+2} - p_{i+1}) / (2 area)`. For a
/// per-vertex field `d`, `G_t d = sum_i d_i grad_phi_i^T` is its (tangential) Jacobian.
#[derive(Clone, Copy, Debug)]
pub struct TriangleOperator {
    pub area: f64,
    pub hat_gradients: [Vec3; 3],
}

impl TriangleOperator {
    /// `None` for a triangle of zero area.
    pub fn new(p: [Vec3; 3]) -> Option<Self> {
        let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
        let twice_area = length(n);
        if twice_area == 0.0 || !twice_area.is_finite() {
            return None;
        }
        let unit = scale(n, 1.0 / twice_area);
        let hat = |i: usize| scale(cross(unit, sub(p[(i + 2) % 3], p[(i + 1) % 3])), 1.0 / twice_area);
        Some(Self { area: 0.5 * twice_area, hat_gradients: [hat(0), hat(1), hat(2)] })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &Mat3, b: &Mat3, tol: f64) -> bool {
        (0..3).all(|r| (0..3).all(|c| (a[r][c] - b[r][c]).abs() <= tol))
    }

    #[test]
    fn hat_gradients_reproduce_linear_fields() {
        let p = [[0.1, 0.2, 0.3], [1.3, 0.1, -0.2], [0.4, 1.1, 0.5]];
        let op = TriangleOperator::new(p).unwrap();
        // Gradients of the hat functions sum to zero (constants have no gradient).
        let sum = add(add(op.hat_gradients[0], op.hat_gradients[1]), op.hat_gradients[2]);
        assert!(length(sum) < 1e-12);
        // The field f(x) = a . x sampled at the corners has gradient = tangential part of a.
        let a = [0.7, -1.9, 2.3];
        let mut grad = [0.0; 3];
        for (&g, &q) in op.hat_gradients.iter().zip(&p) {
            grad = add(grad, scale(g, dot(a, q)));
        }
        let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
        let n = scale(n, 1.0 / length(n));
        let tangential = sub(a, scale(n, dot(a, n)));
        assert!(length(sub(grad, tangential)) < 1e-12, "{grad:?} vs {tangential:?}");
        assert!((op.area - 0.5 * length(cross(sub(p[1], p[0]), sub(p[2], p[0])))).abs() < 1e-15);
    }

    #[test]
    fn gradient_of_a_linear_map_is_that_map() {
        let p = [[0.0, 0.0, 0.0], [1.0, 0.2, 0.0], [0.3, 0.9, 0.1]];
        let rest_inverse = inverse(&edge_frame(p)).unwrap();
        // A rotation times a uniform scale maps the scaled normal exactly.
        let (c, s) = (0.6f64, 0.8f64);
        let m: Mat3 = [[2.0 * c, -2.0 * s, 0.0], [2.0 * s, 2.0 * c, 0.0], [0.0, 0.0, 2.0]];
        let deformed = p.map(|q| add(mat_vec(&m, q), [5.0, -1.0, 2.0]));
        let h = delta_gradient(&rest_inverse, deformed);
        assert!(close(&h, &mat_add_scaled(&m, &IDENTITY, -1.0), 1e-12), "{h:?}");
        let inv = inverse(&m).unwrap();
        assert!(close(&mat_mul(&m, &inv), &IDENTITY, 1e-12));
        assert!(inverse(&ZERO).is_none());
        assert!(TriangleOperator::new([[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]).is_none());
    }
}
