//! The sparse normal system of the transfer energy and its per-shape Dirichlet solve.
//!
//! Normal matrix (per coordinate, unknowns are the deltas `d = x - B0`):
//! `A = sum_t area_t G_t^T G_t + w_ve sum_(i,j) (e_i - e_j)(e_i - e_j)^T`,
//! the cotangent Laplacian of the target rest mesh plus one spring per virtual edge.
//! It depends only on the target neutral: assembled once. Each shape fixes its static
//! vertices at `d = 0` exactly by eliminating them, which leaves the principal submatrix on
//! the shape's moving vertices: symbolic and numeric Cholesky of that smaller matrix,
//! `Par::Seq` inside so that rayon can run shapes side by side. The fill-reducing order
//! (AMD) is computed once on the whole matrix and each submatrix takes its restriction,
//! which costs a fifth of the solve time less than ordering every shape afresh. The matrix,
//! the order and the restricted factorisations are [`crate::sparse`]'s (the wrap's too).
//!
//! The contact solve reads the matrix's rows ([`NormalMatrix::rows`]): its Newton steps
//! add the barrier's Hessian to `A` over a region of each shape.

use super::gradients::{dot, HatGradients};
use crate::error::ShapesmithResult;
use crate::sparse::{Cholesky, MatrixRows, SymmetricMatrix};

/// The symmetric normal matrix and a fill-reducing order of all vertices.
#[derive(Clone, Debug)]
pub struct NormalMatrix {
    matrix: SymmetricMatrix,
    /// The matrix's rows, for the contact solve's Newton steps.
    rows: MatrixRows,
    /// A fill-reducing elimination order of all vertices (AMD), restricted per solve.
    order: Vec<usize>,
}

impl NormalMatrix {
    /// Sums the per-triangle blocks `area_t grad_phi_i . grad_phi_j` and the springs
    /// `w (e_i - e_j)(e_i - e_j)^T`.
    pub fn assemble(
        n: usize,
        triangles: &[[u32; 3]],
        operators: &[HatGradients],
        springs: &[(u32, u32)],
        spring_weight: f64,
    ) -> ShapesmithResult<Self> {
        let mut entries: Vec<(usize, usize, f64)> = Vec::with_capacity(6 * triangles.len() + 3 * springs.len());
        for (tri, op) in triangles.iter().zip(operators) {
            for a in 0..3 {
                for b in 0..3 {
                    let (r, c) = (tri[a] as usize, tri[b] as usize);
                    if r >= c {
                        entries.push((r, c, op.area * dot(op.gradients[a], op.gradients[b])));
                    }
                }
            }
        }
        for &(i, j) in springs {
            let (lo, hi) = ((i.min(j)) as usize, (i.max(j)) as usize);
            entries.push((lo, lo, spring_weight));
            entries.push((hi, hi, spring_weight));
            entries.push((hi, lo, -spring_weight));
        }
        let matrix = SymmetricMatrix::from_triplets(n, entries);
        let order = matrix.fill_reducing_order()?;
        Ok(Self { rows: matrix.rows(), matrix, order })
    }

    /// `A x` for a vector stored per vertex (residual checks in tests).
    #[cfg(test)]
    pub fn apply(&self, x: &[f64]) -> Vec<f64> {
        self.matrix.apply(x)
    }

    /// Solves `A_FF d_F = rhs_F` on the kept vertices for the three coordinates; the other
    /// vertices are Dirichlet at zero. `rhs` is per vertex (all N); the result is per vertex
    /// with zeros at eliminated vertices.
    #[cfg(test)]
    pub fn solve_restricted(&self, position: &[u32], n_kept: usize, rhs: &[[f64; 3]]) -> ShapesmithResult<Vec<[f64; 3]>> {
        Ok(self.factor_restricted_plus_springs(position, n_kept, &[])?.solve(rhs))
    }

    /// Factorises `A_FF`, the principal submatrix on the kept vertices (`position[v] !=
    /// u32::MAX`, numbered `position[v]`, increasing), in the whole matrix's AMD order
    /// restricted, plus the springs `w (e_i - e_j)(e_i - e_j)^T` (`(i, j, w)`) one shape adds:
    /// its key's contacts ([`crate::sparse`] grows the pattern by them). With none, the
    /// factor of `A_FF` as before, to the bit.
    pub fn factor_restricted_plus_springs(&self, position: &[u32], n_kept: usize, springs: &[(usize, usize, f64)]) -> ShapesmithResult<RestrictedFactor> {
        let factor = if n_kept == 0 { None } else { Some(self.matrix.factor_restricted_plus_springs(position, n_kept, &self.order, springs)?) };
        Ok(RestrictedFactor { position: position.to_vec(), n_kept, factor })
    }

    /// The rows of `A` (each vertex's columns and entries).
    pub fn rows(&self) -> &MatrixRows {
        &self.rows
    }
}

/// One shape's factorised system `A_FF` on its kept vertices.
pub struct RestrictedFactor {
    position: Vec<u32>,
    n_kept: usize,
    /// `None` when no vertex is kept.
    factor: Option<Cholesky>,
}

impl RestrictedFactor {
    /// `d_F` with `A_FF d_F = rhs_F`, per vertex (all N), zeros at eliminated vertices.
    pub fn solve(&self, rhs: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let mut out = vec![[0.0; 3]; self.position.len()];
        let Some(factor) = &self.factor else { return out };
        let mut kept = vec![[0.0; 3]; self.n_kept];
        for (v, &p) in self.position.iter().enumerate() {
            if p != u32::MAX {
                kept[p as usize] = rhs[v];
            }
        }
        let solved = factor.solve_points(&kept);
        for (v, &p) in self.position.iter().enumerate() {
            if p != u32::MAX {
                out[v] = solved[p as usize];
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid(w: usize, h: usize) -> (Vec<[f64; 3]>, Vec<[u32; 3]>) {
        let mut pts = Vec::new();
        for y in 0..h {
            for x in 0..w {
                pts.push([x as f64, y as f64 * 1.1, 0.05 * ((x * y) as f64).sin()]);
            }
        }
        (pts, crate::geometry::topology::grid_triangles(w as u32, h as u32, 0))
    }

    #[test]
    fn laplacian_kills_constants_and_restricted_solve_has_zero_residual() {
        let (pts, tris) = grid(6, 5);
        let ops: Vec<HatGradients> = tris
            .iter()
            .map(|t| HatGradients::new(t.map(|v| pts[v as usize])).unwrap())
            .collect();
        let a = NormalMatrix::assemble(pts.len(), &tris, &ops, &[(0, 29)], 0.7).unwrap();
        // Constants are in the null space (springs included).
        let ones = vec![1.0; pts.len()];
        assert!(a.apply(&ones).iter().all(|v| v.abs() < 1e-12));
        // Fix the first row of the grid; solve; check the free rows of A d = b.
        // Vertices 6.. are free, numbered from 0.
        let position: Vec<u32> = (0..pts.len() as u32).map(|v| if v < 6 { u32::MAX } else { v - 6 }).collect();
        let kept = pts.len() as u32 - 6;
        let rhs: Vec<[f64; 3]> = (0..pts.len()).map(|v| [(v as f64).cos(), 1.0, -(v as f64) * 0.1]).collect();
        let d = a.solve_restricted(&position, kept as usize, &rhs).unwrap();
        assert!(d[..6].iter().all(|x| *x == [0.0; 3]));
        for c in 0..3 {
            let col: Vec<f64> = d.iter().map(|x| x[c]).collect();
            let ad = a.apply(&col);
            for v in 6..pts.len() {
                assert!((ad[v] - rhs[v][c]).abs() < 1e-9, "vertex {v}: {} vs {}", ad[v], rhs[v][c]);
            }
        }
    }
}
