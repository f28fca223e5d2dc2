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
//! The collision pass re-solves a shape only near the vertices it holds
//! ([`NormalMatrix::solve_local`]): the deltas outside a small region are kept as solved
//! (Dirichlet), so a re-solve factorises a few hundred unknowns, not the shape's system.

use super::gradients::{add, dot, scale, sub, HatGradients, Vec3};
use crate::error::ShapesmithResult;
use crate::sparse::{Cholesky, MatrixRows, SymmetricMatrix};

/// The symmetric normal matrix and a fill-reducing order of all vertices.
#[derive(Clone, Debug)]
pub struct NormalMatrix {
    matrix: SymmetricMatrix,
    /// The matrix's rows, for the local re-solve's coupling to the vertices held outside.
    rows: MatrixRows,
    /// A fill-reducing elimination order of all vertices (AMD), restricted per solve.
    order: Vec<usize>,
    /// Each vertex's slot in `order`: a local re-solve sorts its few vertices by it instead
    /// of scanning the whole order.
    rank: Vec<usize>,
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
        let mut rank = vec![0; n];
        for (slot, &v) in order.iter().enumerate() {
            rank[v] = slot;
        }
        Ok(Self { rows: matrix.rows(), matrix, order, rank })
    }

    /// `A x` for a vector stored per vertex (residual checks in tests).
    #[cfg(test)]
    pub fn apply(&self, x: &[f64]) -> Vec<f64> {
        self.matrix.apply(x)
    }

    /// `A_vv`.
    pub fn diagonal(&self, v: usize) -> f64 {
        self.matrix.diagonal(v)
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
    /// restricted.
    pub fn factor_restricted(&self, position: &[u32], n_kept: usize) -> ShapesmithResult<RestrictedFactor> {
        let factor = if n_kept == 0 { None } else { Some(self.matrix.factor_restricted(position, n_kept, &self.order)?) };
        Ok(RestrictedFactor { position: position.to_vec(), n_kept, factor })
    }

    /// Minimises the shape's energy plus `sum_u w_u |d_u - c_u|^2` over the deltas of the
    /// vertices in `region` only, the others held at `current` (Dirichlet):
    /// `(A_RR + W) d_R = rhs_R - A_R,out d_out + W c`. `constraints` holds `(u, w_u, c_u)`
    /// with `u` in `region`; `rhs` is the shape's right-hand side per vertex. The springs
    /// `released` `(i, j, w, t)` (adding `w (e_i - e_j)(e_i - e_j)^T` to `A` and `+t`, `-t` to
    /// `rhs` at `i`, `j`) are taken out of the rows of their ends in the region: they no longer
    /// pull the region. Returns `current` with the region's rows replaced.
    pub fn solve_local(
        &self,
        region: &[usize],
        constraints: &[(usize, f64, Vec3)],
        released: &[(usize, usize, f64, Vec3)],
        rhs: &[Vec3],
        current: &[Vec3],
    ) -> ShapesmithResult<Vec<Vec3>> {
        let n = current.len();
        let mut position = vec![u32::MAX; n];
        let mut sorted = region.to_vec();
        sorted.sort_unstable();
        sorted.dedup();
        for (slot, &v) in sorted.iter().enumerate() {
            position[v] = slot as u32;
        }
        // A_R,out d_out on the region's rows only: each row's products with the vertices
        // outside, in increasing column (the product of the whole matrix with the region's
        // entries zeroed, to the bit: the zeros it adds change no sum).
        let coupling = |v: usize| {
            let mut sum = [0.0; 3];
            for &(u, a) in self.rows.row(v) {
                if position[u] == u32::MAX {
                    for axis in 0..3 {
                        sum[axis] += a * current[u][axis];
                    }
                }
            }
            sum
        };
        let mut extra: Vec<(usize, f64)> = constraints.iter().map(|&(u, w, _)| (u, w)).collect();
        let mut off_diagonal = Vec::new();
        let mut local: Vec<Vec3> = sorted.iter().map(|&v| sub(rhs[v], coupling(v))).collect();
        for &(i, j, w, t) in released {
            let inside = |v: usize| position[v] != u32::MAX;
            for (a, b, sign) in [(i, j, 1.0), (j, i, -1.0)] {
                if !inside(a) {
                    continue;
                }
                // Row a loses w d_a - w d_b = sign t: its diagonal, its rhs, and its coupling
                // to b (inside: the off-diagonal entry; outside: -w current_b).
                extra.push((a, -w));
                let slot = position[a] as usize;
                local[slot] = sub(local[slot], scale(t, sign));
                if !inside(b) {
                    local[slot] = sub(local[slot], scale(current[b], w));
                } else if a < b {
                    off_diagonal.push((a, b, w));
                }
            }
        }
        // The region's columns only: a re-solve costs its few hundred unknowns, not the mesh.
        let factor = self.matrix.factor_subset_plus(&sorted, &position, &self.rank, &extra, &off_diagonal)?;
        for &(u, w, target) in constraints {
            let slot = position[u] as usize;
            local[slot] = add(local[slot], scale(target, w));
        }
        let solved = factor.solve_points(&local);
        let mut out = current.to_vec();
        for (&v, d) in sorted.iter().zip(solved) {
            out[v] = d;
        }
        Ok(out)
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
    /// Whether vertex `v` is an unknown of this system (not eliminated).
    pub fn is_kept(&self, v: usize) -> bool {
        self.position[v] != u32::MAX
    }

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

    #[test]
    fn local_solve_over_every_unknown_is_the_constrained_full_solve_and_keeps_the_rest() {
        let (pts, tris) = grid(7, 6);
        let ops: Vec<HatGradients> = tris.iter().map(|t| HatGradients::new(t.map(|v| pts[v as usize])).unwrap()).collect();
        let a = NormalMatrix::assemble(pts.len(), &tris, &ops, &[(3, 40)], 2.0).unwrap();
        let n = pts.len();
        // Vertices 0..7 are Dirichlet at zero (the shape's static row); the rest are free.
        let free: Vec<usize> = (7..n).collect();
        let rhs: Vec<Vec3> = (0..n).map(|v| [(v as f64 * 0.3).sin(), 0.2, (v as f64) * 0.01]).collect();
        let current = vec![[0.0; 3]; n];
        let constraints = vec![(20usize, 5.0 * a.diagonal(20), [0.1, -0.2, 0.3]), (33, 2.0 * a.diagonal(33), [0.0, 0.5, 0.0])];
        let local = a.solve_local(&free, &constraints, &[], &rhs, &current).unwrap();
        // (A_FF + W) d_F = rhs_F + W c, checked through A's product on the whole vector.
        for c in 0..3 {
            let col: Vec<f64> = local.iter().map(|x| x[c]).collect();
            let ad = a.apply(&col);
            for &v in &free {
                let mut expect = rhs[v][c];
                let mut lhs = ad[v];
                for &(u, w, target) in &constraints {
                    if u == v {
                        lhs += w * col[v];
                        expect += w * target[c];
                    }
                }
                assert!((lhs - expect).abs() < 1e-9, "vertex {v}: {lhs} vs {expect}");
            }
        }
        // On a smaller region with the same constraints the optimum is the same (the whole
        // solution is optimal on any part with the rest held); a new target moves only the
        // region, and moves vertex 20 towards it.
        let region: Vec<usize> = vec![19, 20, 21, 26, 27, 28];
        let same = a.solve_local(&region, &constraints[..1], &[], &rhs, &local).unwrap();
        assert!(region.iter().all(|&v| (0..3).all(|c| (same[v][c] - local[v][c]).abs() < 1e-9)));
        let pulled = [(20usize, constraints[0].1, [1.0, 1.0, 1.0])];
        let again = a.solve_local(&region, &pulled, &[], &rhs, &local).unwrap();
        for v in 0..n {
            if !region.contains(&v) {
                assert_eq!(again[v], local[v]);
            }
        }
        assert!((0..3).all(|c| again[20][c] > local[20][c]));
    }

    #[test]
    fn releasing_springs_in_a_local_solve_is_solving_without_them() {
        // Springs 20-40 (both ends in the region), 27-3 (one end in it, one outside) and 9-12
        // (neither: kept). Released, the region's solve is the one of the matrix assembled
        // without the first two and their right-hand sides, the rest held at `current`.
        let (pts, tris) = grid(7, 6);
        let ops: Vec<HatGradients> = tris.iter().map(|t| HatGradients::new(t.map(|v| pts[v as usize])).unwrap()).collect();
        let n = pts.len();
        let springs = [(20u32, 40u32), (27, 3), (9, 12)];
        let w = 2.5;
        let with = NormalMatrix::assemble(n, &tris, &ops, &springs, w).unwrap();
        let without = NormalMatrix::assemble(n, &tris, &ops, &springs[2..], w).unwrap();
        let base: Vec<Vec3> = (0..n).map(|v| [(v as f64 * 0.3).sin(), 0.2, (v as f64) * 0.01]).collect();
        let pulls = [[0.3, -0.1, 0.2], [-0.2, 0.4, 0.1], [0.05, 0.0, -0.3]];
        let mut rhs = base.clone();
        let mut kept_rhs = base;
        for (k, &(i, j)) in springs.iter().enumerate() {
            let (i, j) = (i as usize, j as usize);
            rhs[i] = add(rhs[i], pulls[k]);
            rhs[j] = sub(rhs[j], pulls[k]);
            if k == 2 {
                kept_rhs[i] = add(kept_rhs[i], pulls[k]);
                kept_rhs[j] = sub(kept_rhs[j], pulls[k]);
            }
        }
        let current: Vec<Vec3> = (0..n).map(|v| [0.01 * v as f64, -0.02, (v as f64 * 0.7).cos()]).collect();
        let region: Vec<usize> = vec![19, 20, 21, 26, 27, 28, 33, 34, 40, 41];
        let constraints = [(26usize, 3.0 * with.diagonal(26), [0.2, 0.1, -0.1])];
        let released: Vec<(usize, usize, f64, Vec3)> =
            springs[..2].iter().zip(pulls).map(|(&(i, j), t)| (i as usize, j as usize, w, t)).collect();
        let got = with.solve_local(&region, &constraints, &released, &rhs, &current).unwrap();
        let expected = without.solve_local(&region, &constraints, &[], &kept_rhs, &current).unwrap();
        for v in 0..n {
            assert!((0..3).all(|c| (got[v][c] - expected[v][c]).abs() < 1e-9), "vertex {v}: {:?} vs {:?}", got[v], expected[v]);
        }
        // Not released, the springs pull the region elsewhere.
        let pulled = with.solve_local(&region, &constraints, &[], &rhs, &current).unwrap();
        assert!(region.iter().any(|&v| (0..3).any(|c| (pulled[v][c] - expected[v][c]).abs() > 1e-3)));
    }
}
