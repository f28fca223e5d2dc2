//! The rig as the add-on hands it over: a neutral `V0` (N x 3), deltas `D_k = V_k - V0`
//! (K x N x 3), triangles (T x 3) and shape names, all borrowed from the caller's arrays.
//! Method, section 0.

use crate::error::ShapesmithResult;
use crate::invalid;

/// A shape whose largest displacement is below this fraction of the bounding-box diagonal
/// is inert: reported and skipped, never divided by (method, section 0).
pub const INERT_FRACTION: f64 = 1e-6;

/// A triangle whose area is below this fraction of the squared bounding-box diagonal is
/// degenerate: its gradient operator would be singular.
pub const DEGENERATE_AREA_FRACTION: f64 = 1e-12;

#[derive(Clone, Copy, Debug)]
pub struct RigView<'a> {
    pub neutral: &'a [[f32; 3]],
    /// K x N displacements, shape-major: shape k is `deltas[k * N..(k + 1) * N]`.
    pub deltas: &'a [[f32; 3]],
    pub triangles: &'a [[u32; 3]],
    pub names: &'a [String],
}

impl<'a> RigView<'a> {
    /// Borrows the arrays after checking that their sizes agree.
    pub fn new(
        neutral: &'a [[f32; 3]],
        deltas: &'a [[f32; 3]],
        triangles: &'a [[u32; 3]],
        names: &'a [String],
    ) -> ShapesmithResult<Self> {
        let n = neutral.len();
        if n == 0 {
            return Err(invalid!("the mesh has no vertices"));
        }
        if deltas.len() != names.len() * n {
            return Err(invalid!(
                "deltas hold {} vertex rows but {} shape names x {} vertices need {}",
                deltas.len(),
                names.len(),
                n,
                names.len() * n
            ));
        }
        Ok(Self { neutral, deltas, triangles, names })
    }

    pub fn n_vertices(&self) -> usize {
        self.neutral.len()
    }

    pub fn n_shapes(&self) -> usize {
        self.names.len()
    }

    /// The displacement field of shape `k` (N rows).
    pub fn delta(&self, k: usize) -> &'a [[f32; 3]] {
        let n = self.n_vertices();
        &self.deltas[k * n..(k + 1) * n]
    }

    /// Checks what every method needs: finite coordinates, triangle indices in range, no
    /// degenerate triangle. Errors name the first offending vertex, shape or triangle.
    pub fn validate(&self) -> ShapesmithResult<()> {
        validate_points(self.neutral, "neutral")?;
        for k in 0..self.n_shapes() {
            validate_points(self.delta(k), &format!("shape key '{}'", self.names[k]))?;
        }
        validate_triangles(self.neutral, self.triangles)
    }

    pub fn bbox_diagonal(&self) -> f64 {
        bbox_diagonal(self.neutral)
    }

    /// `max_n |D_k[n]|`.
    pub fn max_displacement(&self, k: usize) -> f64 {
        self.delta(k).iter().map(norm).fold(0.0, f64::max)
    }

    /// Shapes whose largest displacement is below [`INERT_FRACTION`] of the diagonal.
    pub fn inert_shapes(&self) -> Vec<usize> {
        let floor = INERT_FRACTION * self.bbox_diagonal();
        (0..self.n_shapes()).filter(|&k| self.max_displacement(k) <= floor).collect()
    }

    /// Binary blendshape `b_k[n] = |D_k[n]| >= mu * max_n |D_k[n]|` (paper 000, eq. 2), as
    /// the sorted vertex indices. Empty for an inert shape.
    pub fn active_vertices(&self, k: usize, mu: f64) -> Vec<u32> {
        let max = self.max_displacement(k);
        if max <= INERT_FRACTION * self.bbox_diagonal() {
            return Vec::new();
        }
        let threshold = mu * max;
        (0..self.n_vertices() as u32)
            .filter(|&n| norm(&self.delta(k)[n as usize]) >= threshold)
            .collect()
    }
}

pub fn norm(v: &[f32; 3]) -> f64 {
    let [x, y, z] = v.map(f64::from);
    (x * x + y * y + z * z).sqrt()
}

pub fn bbox_diagonal(points: &[[f32; 3]]) -> f64 {
    let mut lo = [f64::INFINITY; 3];
    let mut hi = [f64::NEG_INFINITY; 3];
    for p in points {
        for a in 0..3 {
            lo[a] = lo[a].min(p[a] as f64);
            hi[a] = hi[a].max(p[a] as f64);
        }
    }
    if points.is_empty() {
        return 0.0;
    }
    ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2)).sqrt()
}

/// Every coordinate finite; the error names the vertex.
pub fn validate_points(points: &[[f32; 3]], what: &str) -> ShapesmithResult<()> {
    match points.iter().position(|p| p.iter().any(|c| !c.is_finite())) {
        Some(n) => Err(invalid!("{what}: vertex {n} has a non-finite coordinate {:?}", points[n])),
        None => Ok(()),
    }
}

/// Every triangle index below `n_vertices`.
pub fn validate_triangle_indices(n_vertices: usize, triangles: &[[u32; 3]]) -> ShapesmithResult<()> {
    for (t, tri) in triangles.iter().enumerate() {
        if let Some(&bad) = tri.iter().find(|&&v| v as usize >= n_vertices) {
            return Err(invalid!("triangle {t} uses vertex {bad}, but the mesh has {n_vertices} vertices"));
        }
    }
    Ok(())
}

/// Indices in range, three distinct corners, area above [`DEGENERATE_AREA_FRACTION`].
pub fn validate_triangles(points: &[[f32; 3]], triangles: &[[u32; 3]]) -> ShapesmithResult<()> {
    validate_triangle_indices(points.len(), triangles)?;
    let min_area = DEGENERATE_AREA_FRACTION * bbox_diagonal(points).powi(2);
    for (t, tri) in triangles.iter().enumerate() {
        if tri[0] == tri[1] || tri[1] == tri[2] || tri[0] == tri[2] {
            return Err(invalid!("triangle {t} repeats a vertex: {tri:?}"));
        }
        if triangle_area(points, tri) <= min_area {
            return Err(invalid!(
                "triangle {t} (vertices {}, {}, {}) is degenerate: its area is zero",
                tri[0],
                tri[1],
                tri[2]
            ));
        }
    }
    Ok(())
}

/// Indices of triangles whose area is at most [`DEGENERATE_AREA_FRACTION`] of the squared
/// diagonal (indices must already be in range).
pub fn degenerate_triangles(points: &[[f32; 3]], triangles: &[[u32; 3]]) -> Vec<u32> {
    let min_area = DEGENERATE_AREA_FRACTION * bbox_diagonal(points).powi(2);
    (0..triangles.len() as u32)
        .filter(|&t| triangle_area(points, &triangles[t as usize]) <= min_area)
        .collect()
}

pub fn triangle_area(points: &[[f32; 3]], tri: &[u32; 3]) -> f64 {
    let p = tri.map(|v| points[v as usize].map(f64::from));
    let e1 = [p[1][0] - p[0][0], p[1][1] - p[0][1], p[1][2] - p[0][2]];
    let e2 = [p[2][0] - p[0][0], p[2][1] - p[0][1], p[2][2] - p[0][2]];
    let c = [
        e1[1] * e2[2] - e1[2] * e2[1],
        e1[2] * e2[0] - e1[0] * e2[2],
        e1[0] * e2[1] - e1[1] * e2[0],
    ];
    0.5 * (c[0] * c[0] + c[1] * c[1] + c[2] * c[2]).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        (vec![[0., 0., 0.], [1., 0., 0.], [1., 1., 0.], [0., 1., 0.]], vec![[0, 1, 2], [0, 2, 3]])
    }

    #[test]
    fn sizes_must_agree() {
        let (v, t) = quad();
        let names = vec!["a".to_string()];
        let deltas = vec![[0.0; 3]; 3];
        let err = RigView::new(&v, &deltas, &t, &names).unwrap_err();
        assert!(err.to_string().contains("need 4"), "{err}");
    }

    #[test]
    fn validation_names_offenders() {
        let (mut v, t) = quad();
        let names = vec!["smile".to_string()];
        let mut deltas = vec![[0.0; 3]; 4];
        deltas[2][1] = f32::NAN;
        let rig = RigView::new(&v, &deltas, &t, &names).unwrap();
        let msg = rig.validate().unwrap_err().to_string();
        assert!(msg.contains("smile") && msg.contains("vertex 2"), "{msg}");

        v[2] = v[0];
        let msg = validate_triangles(&v, &t).unwrap_err().to_string();
        assert!(msg.contains("triangle 0") && msg.contains("degenerate"), "{msg}");
        let msg = validate_triangles(&v, &[[0, 1, 7]]).unwrap_err().to_string();
        assert!(msg.contains("vertex 7"), "{msg}");
    }

    #[test]
    fn inert_and_active_sets() {
        let (v, t) = quad();
        let names = vec!["still".to_string(), "moves".to_string()];
        let mut deltas = vec![[0.0; 3]; 8];
        deltas[4 + 1] = [0.0, 0.0, 1.0];
        deltas[4 + 2] = [0.0, 0.0, 0.2];
        let rig = RigView::new(&v, &deltas, &t, &names).unwrap();
        assert_eq!(rig.inert_shapes(), vec![0]);
        assert!(rig.active_vertices(0, 0.3).is_empty());
        assert_eq!(rig.active_vertices(1, 0.3), vec![1]);
        assert_eq!(rig.active_vertices(1, 0.1), vec![1, 2]);
    }
}
