//! 3-vectors and row-major 3x3 matrices (`m[r][c]`), and the per-triangle frames of
//! deformation gradients (Sumner & Popovic 2004, Eq. (3)). The wrap's alignment, fit and
//! carry use these; transfer re-exports them from `transfer/gradients.rs`.

pub type Vec3 = [f64; 3];
pub type Mat3 = [[f64; 3]; 3];

pub const IDENTITY: Mat3 = [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]];

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
    std::array::from_fn(|r| std::array::from_fn(|c| a[r][0] * b[0][c] + a[r][1] * b[1][c] + a[r][2] * b[2][c]))
}

pub fn transpose(m: &Mat3) -> Mat3 {
    std::array::from_fn(|r| std::array::from_fn(|c| m[c][r]))
}

pub fn determinant(m: &Mat3) -> f64 {
    dot(m[0], cross(m[1], m[2]))
}

/// Inverse by the adjugate; `None` when the determinant vanishes.
pub fn inverse(m: &Mat3) -> Option<Mat3> {
    let det = determinant(m);
    if det == 0.0 || !det.is_finite() {
        return None;
    }
    // Columns of the inverse are the cross products of the rows over the determinant.
    let c = [cross(m[1], m[2]), cross(m[2], m[0]), cross(m[0], m[1])];
    Some(std::array::from_fn(|r| std::array::from_fn(|k| c[k][r] / det)))
}

/// The edge matrix `[v2 - v1, v3 - v1, n / sqrt(|n|)]` (columns) of a triangle, with
/// `n = (v2 - v1) x (v3 - v1)`: Sumner & Popovic's fourth vertex, scaled so that a uniformly
/// scaled triangle has gradient `s I`.
pub fn edge_frame(p: [Vec3; 3]) -> Mat3 {
    let e1 = sub(p[1], p[0]);
    let e2 = sub(p[2], p[0]);
    let n = cross(e1, e2);
    let len = length(n);
    let n = if len > 0.0 { scale(n, 1.0 / len.sqrt()) } else { n };
    [[e1[0], e2[0], n[0]], [e1[1], e2[1], n[1]], [e1[2], e2[2], n[2]]]
}

/// Area-weighted vertex normals (unit length; zero for a vertex in no triangle).
pub fn vertex_normals(points: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let mut normals = vec![[0.0; 3]; points.len()];
    for t in triangles {
        let [a, b, c] = t.map(|v| points[v as usize]);
        let n = cross(sub(b, a), sub(c, a));
        for &v in t {
            normals[v as usize] = add(normals[v as usize], n);
        }
    }
    for n in normals.iter_mut() {
        let len = length(*n);
        if len > 0.0 {
            *n = scale(*n, 1.0 / len);
        }
    }
    normals
}

/// A rest triangle's gradient operator: its area and the gradients of its three hat
/// functions, `grad phi_i = n_hat x (p_{i+2} - p_{i+1}) / (2 area)` (Botsch et al. 2006's
/// gradient form). For a per-vertex field `d`, `sum_i d_i grad_phi_i^T` is its tangential
/// Jacobian on the triangle.
#[derive(Clone, Copy, Debug)]
pub struct HatGradients {
    pub area: f64,
    pub gradients: [Vec3; 3],
}

impl HatGradients {
    /// `None` for a triangle of zero area.
    pub fn new(p: [Vec3; 3]) -> Option<Self> {
        let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
        let twice_area = length(n);
        if twice_area == 0.0 || !twice_area.is_finite() {
            return None;
        }
        let unit = scale(n, 1.0 / twice_area);
        let hat = |i: usize| scale(cross(unit, sub(p[(i + 2) % 3], p[(i + 1) % 3])), 1.0 / twice_area);
        Some(Self { area: 0.5 * twice_area, gradients: [hat(0), hat(1), hat(2)] })
    }
}

/// `v` scaled to length 1, or None when its length is zero or not finite.
pub fn unit(v: Vec3) -> Option<Vec3> {
    let n = length(v);
    (n.is_finite() && n > 1e-300).then(|| scale(v, 1.0 / n))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn inverse_and_frames_of_a_known_map() {
        let m: Mat3 = [[2.0, 0.3, -1.0], [0.1, 1.5, 0.2], [0.4, -0.7, 3.0]];
        let product = mat_mul(&m, &inverse(&m).unwrap());
        assert!((0..3).all(|r| (0..3).all(|c| (product[r][c] - IDENTITY[r][c]).abs() < 1e-12)));
        assert!(inverse(&[[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 1.0, 0.0]]).is_none());
        // A rotation times a uniform scale maps the rest frame onto the deformed frame.
        let (c, s) = (0.6f64, 0.8f64);
        let similarity: Mat3 = [[2.0 * c, -2.0 * s, 0.0], [2.0 * s, 2.0 * c, 0.0], [0.0, 0.0, 2.0]];
        let p = [[0.0, 0.0, 0.0], [1.0, 0.2, 0.0], [0.3, 0.9, 0.1]];
        let moved = p.map(|q| add(mat_vec(&similarity, q), [1.0, 2.0, 3.0]));
        let gradient = mat_mul(&edge_frame(moved), &inverse(&edge_frame(p)).unwrap());
        assert!((0..3).all(|r| (0..3).all(|c| (gradient[r][c] - similarity[r][c]).abs() < 1e-12)));
        assert!((determinant(&transpose(&similarity)) - 8.0).abs() < 1e-12);
    }
}
