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
//! which costs a fifth of the solve time less than ordering every shape afresh.

use faer::dyn_stack::{MemBuffer, MemStack};
use faer::perm::PermRef;
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, LltRef, SymbolicCholesky, SymmetricOrdering};
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, MatMut, Par, Side};

use super::gradients::{dot, HatGradients};
use crate::error::{ShapesmithError, ShapesmithResult};

/// The lower triangle of the symmetric normal matrix in compressed columns, sorted rows.
#[derive(Clone, Debug)]
pub struct NormalMatrix {
    n: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<f64>,
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
                        entries.push((c, r, op.area * dot(op.gradients[a], op.gradients[b])));
                    }
                }
            }
        }
        for &(i, j) in springs {
            let (lo, hi) = ((i.min(j)) as usize, (i.max(j)) as usize);
            entries.push((lo, lo, spring_weight));
            entries.push((hi, hi, spring_weight));
            entries.push((lo, hi, -spring_weight));
        }
        // (column, row) order, duplicates summed.
        entries.sort_unstable_by_key(|&(c, r, _)| (c, r));
        let mut col_ptr = vec![0usize; n + 1];
        let mut row_idx = Vec::with_capacity(entries.len());
        let mut values: Vec<f64> = Vec::with_capacity(entries.len());
        let mut last: Option<(usize, usize)> = None;
        for (c, r, v) in entries {
            if last == Some((c, r)) {
                if let Some(x) = values.last_mut() {
                    *x += v;
                }
                continue;
            }
            last = Some((c, r));
            row_idx.push(r);
            values.push(v);
            col_ptr[c + 1] += 1;
        }
        for c in 0..n {
            col_ptr[c + 1] += col_ptr[c];
        }
        let structure = SymbolicSparseColMatRef::new_checked(n, n, &col_ptr, None, &row_idx);
        let symbolic = factorize_symbolic_cholesky(structure, Side::Lower, SymmetricOrdering::Amd, Default::default())
            .map_err(|e| ShapesmithError::Solver(format!("the transfer system could not be ordered: {e:?}")))?;
        let order = match symbolic.perm() {
            Some(perm) => perm.arrays().0.to_vec(),
            None => (0..n).collect(),
        };
        Ok(Self { n, col_ptr, row_idx, values, order })
    }

    /// `A x` for a vector stored per vertex (residual checks in tests).
    #[cfg(test)]
    pub fn apply(&self, x: &[f64]) -> Vec<f64> {
        let mut y = vec![0.0; self.n];
        for c in 0..self.n {
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                let r = self.row_idx[k];
                y[r] += self.values[k] * x[c];
                if r != c {
                    y[c] += self.values[k] * x[r];
                }
            }
        }
        y
    }

    /// The principal submatrix on the vertices with `position[v] != u32::MAX`, renumbered to
    /// `position[v]`. `position` must be increasing on the kept vertices, so the lower
    /// triangle stays lower and rows stay sorted.
    fn restricted(&self, position: &[u32], n_kept: usize) -> (Vec<usize>, Vec<usize>, Vec<f64>) {
        let mut col_ptr = Vec::with_capacity(n_kept + 1);
        let mut row_idx = Vec::new();
        let mut values = Vec::new();
        col_ptr.push(0);
        for c in 0..self.n {
            if position[c] == u32::MAX {
                continue;
            }
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                let r = position[self.row_idx[k]];
                if r != u32::MAX {
                    row_idx.push(r as usize);
                    values.push(self.values[k]);
                }
            }
            col_ptr.push(row_idx.len());
        }
        (col_ptr, row_idx, values)
    }

    /// Solves `A_FF d_F = rhs_F` on the kept vertices for the three coordinates; the other
    /// vertices are Dirichlet at zero. `rhs` is per vertex (all N); the result is per vertex
    /// with zeros at eliminated vertices.
    #[cfg(test)]
    pub fn solve_restricted(&self, position: &[u32], n_kept: usize, rhs: &[[f64; 3]]) -> ShapesmithResult<Vec<[f64; 3]>> {
        Ok(self.factor_restricted(position, n_kept)?.solve(rhs))
    }

    /// Factorises `A_FF`, the principal submatrix on the kept vertices (`position[v] !=
    /// u32::MAX`, numbered `position[v]`, increasing), in the whole matrix's AMD order
    /// restricted. The factor is kept so that soft constraints can be added to its diagonal
    /// and refactorised numerically on the same pattern ([`RestrictedFactor::add_to_diagonal`]).
    pub fn factor_restricted(&self, position: &[u32], n_kept: usize) -> ShapesmithResult<RestrictedFactor> {
        let (col_ptr, row_idx, values) = self.restricted(position, n_kept);
        let forward: Vec<usize> = self.order.iter().map(|&v| position[v]).filter(|&p| p != u32::MAX).map(|p| p as usize).collect();
        let mut inverse = vec![0usize; n_kept];
        for (slot, &p) in forward.iter().enumerate() {
            inverse[p] = slot;
        }
        let factor = if n_kept == 0 {
            None
        } else {
            Some(Cholesky::factor(n_kept, &col_ptr, &row_idx, &values, PermRef::new_checked(&forward, &inverse, n_kept))?)
        };
        Ok(RestrictedFactor { position: position.to_vec(), n_kept, col_ptr, row_idx, values, factor })
    }
}

/// One shape's factorised system `A_FF` on its kept vertices, plus any diagonal additions.
pub struct RestrictedFactor {
    position: Vec<u32>,
    n_kept: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    /// The restricted matrix as assembled (without diagonal additions).
    values: Vec<f64>,
    /// `None` when no vertex is kept.
    factor: Option<Cholesky>,
}

impl RestrictedFactor {
    /// Whether vertex `v` is an unknown of this system (not eliminated).
    pub fn is_kept(&self, v: usize) -> bool {
        self.position[v] != u32::MAX
    }

    /// The diagonal entry `A_vv` of a kept vertex (the first stored row of its lower column).
    pub fn diagonal(&self, v: usize) -> f64 {
        let c = self.position[v] as usize;
        let k = self.col_ptr[c];
        debug_assert_eq!(self.row_idx[k], c);
        self.values[k]
    }

    /// Refactorises `A_FF + diag(extra)` numerically on the symbolic factor already computed
    /// (the pattern does not change): `extra` holds `(vertex, weight)` of kept vertices and
    /// replaces any earlier additions.
    pub fn add_to_diagonal(&mut self, extra: &[(usize, f64)]) -> ShapesmithResult<()> {
        let Some(factor) = self.factor.as_mut() else { return Ok(()) };
        let mut values = self.values.clone();
        for &(v, w) in extra {
            values[self.col_ptr[self.position[v] as usize]] += w;
        }
        factor.refactor(self.n_kept, &self.col_ptr, &self.row_idx, &values)
    }

    /// `d_F` with `(A_FF + additions) d_F = rhs_F`, per vertex (all N), zeros at eliminated
    /// vertices.
    pub fn solve(&self, rhs: &[[f64; 3]]) -> Vec<[f64; 3]> {
        let mut out = vec![[0.0; 3]; self.position.len()];
        let Some(factor) = &self.factor else { return out };
        let mut b = faer::Mat::<f64>::zeros(self.n_kept, 3);
        for (v, &p) in self.position.iter().enumerate() {
            if p != u32::MAX {
                for a in 0..3 {
                    b[(p as usize, a)] = rhs[v][a];
                }
            }
        }
        factor.solve_in_place(b.as_mut());
        for (v, &p) in self.position.iter().enumerate() {
            if p != u32::MAX {
                out[v] = [b[(p as usize, 0)], b[(p as usize, 1)], b[(p as usize, 2)]];
            }
        }
        out
    }
}

fn solver_error(what: &str, e: &dyn std::fmt::Debug) -> ShapesmithError {
    ShapesmithError::Solver(format!("the transfer system could not be factorised ({what}: {e:?})"))
}

/// A sparse LL^T factor in a given elimination order, sequential inside.
struct Cholesky {
    symbolic: SymbolicCholesky<usize>,
    values: Vec<f64>,
}

impl Cholesky {
    fn factor(n: usize, col_ptr: &[usize], row_idx: &[usize], values: &[f64], order: PermRef<'_, usize>) -> ShapesmithResult<Self> {
        let structure = SymbolicSparseColMatRef::new_checked(n, n, col_ptr, None, row_idx);
        let symbolic = factorize_symbolic_cholesky(structure, Side::Lower, SymmetricOrdering::Custom(order), Default::default())
            .map_err(|e| solver_error("symbolic", &e))?;
        let mut factor = Self { values: vec![0.0; symbolic.len_val()], symbolic };
        factor.refactor(n, col_ptr, row_idx, values)?;
        Ok(factor)
    }

    /// Numeric factorisation of a matrix with the pattern the symbolic factor was made for.
    fn refactor(&mut self, n: usize, col_ptr: &[usize], row_idx: &[usize], values: &[f64]) -> ShapesmithResult<()> {
        let structure = SymbolicSparseColMatRef::new_checked(n, n, col_ptr, None, row_idx);
        let matrix = SparseColMatRef::new(structure, values);
        let scratch = self.symbolic.factorize_numeric_llt_scratch::<f64>(Par::Seq, Default::default());
        let mut buffer = MemBuffer::try_new(scratch).map_err(|e| solver_error("memory", &e))?;
        self.symbolic
            .factorize_numeric_llt(
                &mut self.values,
                matrix,
                Side::Lower,
                Default::default(),
                Par::Seq,
                MemStack::new(&mut buffer),
                Default::default(),
            )
            .map_err(|e| solver_error("not positive definite", &e))?;
        Ok(())
    }

    fn solve_in_place(&self, rhs: MatMut<'_, f64>) {
        let mut buffer = MemBuffer::new(self.symbolic.solve_in_place_scratch::<f64>(rhs.ncols(), Par::Seq));
        LltRef::new(&self.symbolic, &self.values).solve_in_place_with_conj(Conj::No, rhs, Par::Seq, MemStack::new(&mut buffer));
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
        let mut tris = Vec::new();
        for y in 0..h - 1 {
            for x in 0..w - 1 {
                let v = (y * w + x) as u32;
                tris.push([v, v + 1, v + w as u32 + 1]);
                tris.push([v, v + w as u32 + 1, v + w as u32]);
            }
        }
        (pts, tris)
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
