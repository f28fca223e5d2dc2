//! Per-triangle deformation gradients (Sumner & Popovic 2004, Eq. (1)-(3)) and the
//! gradient operator of a rest triangle (gradient form of Botsch et al. 2006).
//!
//! Matrices are row-major `[[f64; 3]; 3]`; `m[r][c]` is row `r`, column `c`.

pub use crate::geometry::mat3::{
    add, cross, dot, edge_frame, inverse, length, mat_mul, mat_vec, scale, sub, to_f64, transpose, HatGradients, Mat3, Vec3,
    IDENTITY,
};

pub const ZERO: Mat3 = [[0.0; 3]; 3];

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

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &Mat3, b: &Mat3, tol: f64) -> bool {
        (0..3).all(|r| (0..3).all(|c| (a[r][c] - b[r][c]).abs() <= tol))
    }

    #[test]
    fn gradients_reproduce_linear_fields() {
        let p = [[0.1, 0.2, 0.3], [1.3, 0.1, -0.2], [0.4, 1.1, 0.5]];
        let op = HatGradients::new(p).unwrap();
        // Gradients of the hat functions sum to zero (constants have no gradient).
        let sum = add(add(op.gradients[0], op.gradients[1]), op.gradients[2]);
        assert!(length(sum) < 1e-12);
        // The field f(x) = a . x sampled at the corners has gradient = tangential part of a.
        let a = [0.7, -1.9, 2.3];
        let mut grad = [0.0; 3];
        for (&g, &q) in op.gradients.iter().zip(&p) {
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
        assert!(HatGradients::new([[0.0; 3], [1.0, 0.0, 0.0], [2.0, 0.0, 0.0]]).is_none());
    }
}
