//! Sparse symmetric positive definite systems for the tools' least-squares solves: a lower
//! triangle in compressed columns assembled from triplets, a fill-reducing order (AMD)
//! computed once, and sparse Cholesky factors (faer) of the whole matrix or of a principal
//! submatrix (Dirichlet elimination), `Par::Seq` inside so that callers can put rayon across
//! right-hand sides or shapes.

use faer::dyn_stack::{MemBuffer, MemStack, StackReq};
use faer::perm::PermRef;
use faer::reborrow::IntoConst;
use faer::sparse::linalg::cholesky::simplicial::{
    factorize_simplicial_numeric_llt_scratch, EliminationTreeRef, factorize_simplicial_numeric_llt_with_row_idx, prefactorize_symbolic_cholesky,
    prefactorize_symbolic_cholesky_scratch,
};
use faer::sparse::linalg::cholesky::supernodal::{
    factorize_supernodal_numeric_llt, factorize_supernodal_numeric_llt_scratch, factorize_supernodal_symbolic_cholesky,
    factorize_supernodal_symbolic_cholesky_scratch, SupernodalLltRef, SymbolicSupernodalCholesky,
};
use faer::sparse::linalg::cholesky::{factorize_symbolic_cholesky, SymmetricOrdering};
use faer::sparse::linalg::SupernodalThreshold;
use faer::sparse::utils::permute_self_adjoint_to_unsorted;
use faer::sparse::{SparseColMatRef, SymbolicSparseColMatRef};
use faer::{Conj, Mat, Par, Side};

use crate::error::{ShapesmithError, ShapesmithResult};

/// The lower triangle of a symmetric matrix in compressed columns with sorted rows.
#[derive(Clone, Debug)]
pub struct SymmetricMatrix {
    n: usize,
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<f64>,
}

impl SymmetricMatrix {
    /// Sums the entries `(row, column, value)`; each off-diagonal pair is given once, in
    /// either triangle.
    pub fn from_triplets(n: usize, mut entries: Vec<(usize, usize, f64)>) -> Self {
        for e in entries.iter_mut() {
            if e.0 < e.1 {
                *e = (e.1, e.0, e.2);
            }
        }
        entries.sort_unstable_by_key(|&(r, c, _)| (c, r));
        let mut col_ptr = vec![0usize; n + 1];
        let mut row_idx = Vec::with_capacity(entries.len());
        let mut values: Vec<f64> = Vec::with_capacity(entries.len());
        let mut last = None;
        for (r, c, v) in entries {
            if last == Some((r, c)) {
                if let Some(x) = values.last_mut() {
                    *x += v;
                }
                continue;
            }
            last = Some((r, c));
            row_idx.push(r);
            values.push(v);
            col_ptr[c + 1] += 1;
        }
        for c in 0..n {
            col_ptr[c + 1] += col_ptr[c];
        }
        Self { n, col_ptr, row_idx, values }
    }

    pub fn size(&self) -> usize {
        self.n
    }

    /// `A x` for one column (residual checks).
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

    /// Every row of the whole matrix (both triangles), entries in increasing column: a row's
    /// products with a vector summed in this order give [`Self::apply`]'s entry to the bit
    /// (the same products, added in the same order), for the rows one needs only.
    pub fn rows(&self) -> MatrixRows {
        let mut offsets = vec![0usize; self.n + 1];
        for c in 0..self.n {
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                offsets[self.row_idx[k] + 1] += 1;
                if self.row_idx[k] != c {
                    offsets[c + 1] += 1;
                }
            }
        }
        for v in 0..self.n {
            offsets[v + 1] += offsets[v];
        }
        // Filled column by column: row r gets column c's entry at c's turn, and column c's
        // own row gets its entries below the diagonal in increasing row, after its diagonal.
        let mut fill = offsets.clone();
        let mut entries = vec![(0usize, 0.0); offsets[self.n]];
        for c in 0..self.n {
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                let r = self.row_idx[k];
                entries[fill[r]] = (c, self.values[k]);
                fill[r] += 1;
                if r != c {
                    entries[fill[c]] = (r, self.values[k]);
                    fill[c] += 1;
                }
            }
        }
        MatrixRows { offsets, entries }
    }

    /// A fill-reducing elimination order (AMD) of all unknowns: compute it once and hand it
    /// to every factorisation of this pattern or of its principal submatrices.
    pub fn fill_reducing_order(&self) -> ShapesmithResult<Vec<usize>> {
        let structure = SymbolicSparseColMatRef::new_checked(self.n, self.n, &self.col_ptr, None, &self.row_idx);
        let symbolic = factorize_symbolic_cholesky(structure, Side::Lower, SymmetricOrdering::Amd, Default::default())
            .map_err(|e| ShapesmithError::Solver(format!("a sparse system could not be ordered: {e:?}")))?;
        Ok(match symbolic.perm() {
            Some(perm) => perm.arrays().0.to_vec(),
            None => (0..self.n).collect(),
        })
    }

    /// The Cholesky factor of the whole matrix in the elimination order `order`.
    pub fn factor(&self, order: &[usize]) -> ShapesmithResult<Cholesky> {
        let mut inverse = vec![0usize; self.n];
        for (slot, &v) in order.iter().enumerate() {
            inverse[v] = slot;
        }
        Cholesky::factor(self.n, &self.col_ptr, &self.row_idx, &self.values, PermRef::new_checked(order, &inverse, self.n))
    }

    /// The Cholesky factor of the principal submatrix on the unknowns with
    /// `position[v] != u32::MAX`, renumbered to `position[v]` (increasing in `v`), eliminated in
    /// `order` restricted to them. The other unknowns are Dirichlet at zero.
    pub fn factor_restricted(&self, position: &[u32], n_kept: usize, order: &[usize]) -> ShapesmithResult<Cholesky> {
        self.factor_restricted_plus_diagonal(position, n_kept, order, &[])
    }

    /// [`Self::factor_restricted`] of the submatrix plus the springs `(a, b, w)`, each adding
    /// `w (e_a - e_b)(e_a - e_b)^T` over all unknowns and then restricted (an eliminated end
    /// leaves the kept end's diagonal `w` alone). Unlike [`Self::factor_subset_plus`] the
    /// springs may join unknowns the matrix does not couple: the pattern grows by them, in
    /// the same order restricted. With no spring this is [`Self::factor_restricted`] to the bit.
    pub fn factor_restricted_plus_springs(
        &self,
        position: &[u32],
        n_kept: usize,
        order: &[usize],
        springs: &[(usize, usize, f64)],
    ) -> ShapesmithResult<Cholesky> {
        let (mut submatrix, forward) = self.restricted_in_order(position, n_kept, order);
        if !springs.is_empty() {
            let mut entries: Vec<(usize, usize, f64)> = Vec::with_capacity(submatrix.values.len() + 3 * springs.len());
            for c in 0..n_kept {
                for k in submatrix.col_ptr[c]..submatrix.col_ptr[c + 1] {
                    entries.push((submatrix.row_idx[k], c, submatrix.values[k]));
                }
            }
            for &(a, b, w) in springs {
                let (pa, pb) = (position[a], position[b]);
                for p in [pa, pb].into_iter().filter(|&p| p != u32::MAX) {
                    entries.push((p as usize, p as usize, w));
                }
                if pa != u32::MAX && pb != u32::MAX {
                    entries.push((pa as usize, pb as usize, -w));
                }
            }
            let grown = Self::from_triplets(n_kept, entries);
            submatrix = Submatrix { col_ptr: grown.col_ptr, row_idx: grown.row_idx, values: grown.values };
        }
        factor_plus_diagonal(position, submatrix, forward, &[])
    }

    /// [`Self::factor_restricted`] of the submatrix plus `diag(extra)`, `extra` holding
    /// `(unknown, value)` pairs of kept unknowns (soft point constraints on them).
    pub fn factor_restricted_plus_diagonal(
        &self,
        position: &[u32],
        n_kept: usize,
        order: &[usize],
        extra: &[(usize, f64)],
    ) -> ShapesmithResult<Cholesky> {
        let (submatrix, forward) = self.restricted_in_order(position, n_kept, order);
        factor_plus_diagonal(position, submatrix, forward, extra)
    }

    /// The principal submatrix on the unknowns with `position[v] != u32::MAX` (renumbered)
    /// and `order` restricted to them, in their new numbers.
    fn restricted_in_order(&self, position: &[u32], n_kept: usize, order: &[usize]) -> (Submatrix, Vec<usize>) {
        let kept = (0..self.n).filter(|&c| position[c] != u32::MAX);
        let forward = order.iter().map(|&v| position[v]).filter(|&p| p != u32::MAX).map(|p| p as usize).collect();
        (self.restricted(position, n_kept, kept), forward)
    }

    /// [`Self::factor_restricted_plus_diagonal`] for a few unknowns, in time proportional to
    /// their columns instead of the whole matrix's: `kept` lists them increasing
    /// (`position[kept[s]] == s`, `u32::MAX` elsewhere) and `rank` is the inverse of the
    /// elimination order (`rank[order[s]] == s`). Same submatrix, same order restricted, so
    /// the same factor to the bit.
    pub fn factor_subset_plus_diagonal(&self, kept: &[usize], position: &[u32], rank: &[usize], extra: &[(usize, f64)]) -> ShapesmithResult<Cholesky> {
        self.factor_subset_plus(kept, position, rank, extra, &[])
    }

    /// [`Self::factor_subset_plus_diagonal`] with `off_diagonal` `(r, c, value)` (by
    /// original unknown, both kept, `r != c`) also added to the stored entry `A_rc` (and
    /// `A_cr`): the springs the collision pass releases. An entry that is not stored is an
    /// error.
    pub fn factor_subset_plus(
        &self,
        kept: &[usize],
        position: &[u32],
        rank: &[usize],
        extra: &[(usize, f64)],
        off_diagonal: &[(usize, usize, f64)],
    ) -> ShapesmithResult<Cholesky> {
        let mut submatrix = self.restricted(position, kept.len(), kept.iter().copied());
        for &(r, c, value) in off_diagonal {
            // The lower triangle's entry: in the column of the smaller of the two.
            let (a, b) = (position[r] as usize, position[c] as usize);
            let (lo, hi) = (a.min(b), a.max(b));
            let Some(k) = (submatrix.col_ptr[lo]..submatrix.col_ptr[lo + 1]).find(|&k| submatrix.row_idx[k] == hi) else {
                return Err(ShapesmithError::Solver(format!("no stored entry ({r}, {c}) to change")));
            };
            submatrix.values[k] += value;
        }
        // The whole order restricted to the kept unknowns: them, sorted by rank.
        let mut forward: Vec<usize> = (0..kept.len()).collect();
        forward.sort_unstable_by_key(|&p| rank[kept[p]]);
        factor_plus_diagonal(position, submatrix, forward, extra)
    }

    /// The principal submatrix on the unknowns `kept` (increasing), renumbered by `position`;
    /// the lower triangle stays lower and rows stay sorted because `position` increases.
    fn restricted(&self, position: &[u32], n_kept: usize, kept: impl Iterator<Item = usize>) -> Submatrix {
        let mut col_ptr = Vec::with_capacity(n_kept + 1);
        let mut row_idx = Vec::new();
        let mut values = Vec::new();
        col_ptr.push(0);
        for c in kept {
            for k in self.col_ptr[c]..self.col_ptr[c + 1] {
                let r = position[self.row_idx[k]];
                if r != u32::MAX {
                    row_idx.push(r as usize);
                    values.push(self.values[k]);
                }
            }
            col_ptr.push(row_idx.len());
        }
        Submatrix { col_ptr, row_idx, values }
    }

    /// The diagonal entry `A_vv` (zero when it is not stored).
    pub fn diagonal(&self, v: usize) -> f64 {
        let k = self.col_ptr[v];
        if k < self.col_ptr[v + 1] && self.row_idx[k] == v {
            self.values[k]
        } else {
            0.0
        }
    }
}

/// A principal submatrix's lower triangle in compressed columns.
struct Submatrix {
    col_ptr: Vec<usize>,
    row_idx: Vec<usize>,
    values: Vec<f64>,
}

/// The Cholesky factor of `submatrix + diag(extra)` (`extra` by original unknown, renumbered
/// through `position`) eliminated in the order `forward` (new slot -> submatrix unknown).
fn factor_plus_diagonal(position: &[u32], submatrix: Submatrix, forward: Vec<usize>, extra: &[(usize, f64)]) -> ShapesmithResult<Cholesky> {
    let Submatrix { col_ptr, row_idx, mut values } = submatrix;
    let n_kept = forward.len();
    for &(v, w) in extra {
        // Rows are sorted: a stored diagonal is the column's first entry.
        let c = position[v] as usize;
        if col_ptr[c] == col_ptr[c + 1] || row_idx[col_ptr[c]] != c {
            return Err(ShapesmithError::Solver(format!("unknown {v} has no diagonal entry to add a constraint to")));
        }
        values[col_ptr[c]] += w;
    }
    let mut inverse = vec![0usize; n_kept];
    for (slot, &p) in forward.iter().enumerate() {
        inverse[p] = slot;
    }
    Cholesky::factor(n_kept, &col_ptr, &row_idx, &values, PermRef::new_checked(&forward, &inverse, n_kept))
}

/// The rows of a [`SymmetricMatrix`] ([`SymmetricMatrix::rows`]).
#[derive(Clone, Debug)]
pub struct MatrixRows {
    offsets: Vec<usize>,
    entries: Vec<(usize, f64)>,
}

impl MatrixRows {
    /// Row `v`'s stored entries `(column, value)`, in increasing column.
    pub fn row(&self, v: usize) -> &[(usize, f64)] {
        &self.entries[self.offsets[v]..self.offsets[v + 1]]
    }
}

/// The error of a factorisation that failed at step `what`.
fn factorisation_failed(what: &str, e: &dyn std::fmt::Debug) -> ShapesmithError {
    ShapesmithError::Solver(format!("a sparse system could not be factorised ({what}: {e:?})"))
}

/// A sparse `L L^T` factor, sequential inside.
pub struct Cholesky(Factor);

/// faer's `L L^T` factor, in the form faer itself would choose for the matrix.
enum Factor {
    /// A simplicial factor computed in one pass (`forward`: elimination slot -> unknown; `L`
    /// in compressed columns, rows sorted, the diagonal first).
    Simplicial { forward: Vec<usize>, col_ptr: Vec<usize>, row_idx: Vec<usize>, values: Vec<f64> },
    /// A supernodal factor by faer's supernodal kernels (`forward` as above).
    Supernodal { forward: Vec<usize>, symbolic: SymbolicSupernodalCholesky<usize>, values: Vec<f64> },
}

/// faer 0.24's `CHOLESKY_SUPERNODAL_RATIO_FACTOR` (private): above `40 *` the default
/// threshold of flops per factor entry, faer factorises supernodally.
const SUPERNODAL_RATIO_FACTOR: f64 = 40.0;

impl Cholesky {
    /// When faer would pick its simplicial factor (meshes' systems, with few flops per factor
    /// entry), the factor is computed by the same faer kernels in one pass instead of faer's general path,
    /// which permutes the matrix twice (symbolic and numeric) and computes every row's
    /// elimination reach twice (once for the pattern of `L`, once for its values): here the
    /// permuted upper triangle is built once, the elimination tree and column counts are
    /// computed on it, and `factorize_simplicial_numeric_llt_with_row_idx` fills the rows and
    /// values of `L` together. Same permuted matrix (same row order, hence the same reach
    /// order and sums), same arithmetic: the same factor to the bit. Measured with callgrind
    /// on `time_transfer Target_Boy 1`: the factorisations' instructions 411 M -> 296 M, the
    /// whole run 3209 M -> 3005 M (with [`Self::solve_points`]'s own triangular solves) at
    /// the same checksum bits. Otherwise (supernodal) see [`Self::factor_supernodal`].
    fn factor(n: usize, col_ptr: &[usize], row_idx: &[usize], values: &[f64], order: PermRef<'_, usize>) -> ShapesmithResult<Self> {
        let structure = SymbolicSparseColMatRef::new_checked(n, n, col_ptr, None, row_idx);
        let matrix = SparseColMatRef::new(structure, values);
        let nnz = row_idx.len();
        let scratch = StackReq::any_of(&[
            StackReq::new::<usize>(n + 1),
            prefactorize_symbolic_cholesky_scratch::<usize>(n, nnz),
            factorize_simplicial_numeric_llt_scratch::<usize, f64>(n),
        ]);
        let mut buffer = MemBuffer::try_new(scratch).map_err(|e| factorisation_failed("memory", &e))?;
        let stack = MemStack::new(&mut buffer);
        let (mut upper_col_ptr, mut upper_row_idx, mut upper_values) = (vec![0usize; n + 1], vec![0usize; nnz], vec![0.0; nnz]);
        let permuted =
            permute_self_adjoint_to_unsorted(&mut upper_values, &mut upper_col_ptr, &mut upper_row_idx, matrix, order, Side::Lower, Side::Upper, stack);
        let upper = permuted.into_const();
        let mut etree = vec![0isize; n];
        let mut col_counts = vec![0usize; n];
        let tree = prefactorize_symbolic_cholesky(&mut etree, &mut col_counts, upper.symbolic(), stack);
        // faer's choice between simplicial and supernodal, computed as it computes it.
        let factor_nnz: usize = col_counts.iter().sum();
        let (divisions, updates) = col_counts.iter().fold((0u128, 0u128), |(d, u), &c| (d + c as u128, u + c as u128 * (c as u128 + 1) / 2));
        if (divisions as f64 + updates as f64) / factor_nnz as f64 > SupernodalThreshold::AUTO.0 * SUPERNODAL_RATIO_FACTOR {
            return Self::factor_supernodal(matrix, order, upper.symbolic(), tree, &col_counts);
        }
        let mut factor_col_ptr = Vec::with_capacity(n + 1);
        factor_col_ptr.push(0usize);
        for &c in &col_counts {
            factor_col_ptr.push(factor_col_ptr[factor_col_ptr.len() - 1] + c);
        }
        let (mut factor_row_idx, mut factor_values) = (vec![0usize; factor_nnz], vec![0.0; factor_nnz]);
        factorize_simplicial_numeric_llt_with_row_idx(&mut factor_values, &mut factor_row_idx, &factor_col_ptr, tree, upper, Default::default(), stack)
            .map_err(|e| factorisation_failed("not positive definite", &e))?;
        let forward = order.arrays().0.to_vec();
        Ok(Self(Factor::Simplicial { forward, col_ptr: factor_col_ptr, row_idx: factor_row_idx, values: factor_values }))
    }

    /// faer's general path (`factorize_symbolic_cholesky` then `factorize_numeric_llt`) from
    /// its parts: the supernodal structure from the permuted upper triangle, elimination tree
    /// and column counts [`Self::factor`] has computed, where the general path permutes the
    /// matrix and computes the tree and counts again; then the matrix permuted to its lower
    /// triangle as the general path's numeric step permutes it, and the same supernodal
    /// kernel with the same (default) parameters: the same factor to the bit.
    fn factor_supernodal(
        matrix: SparseColMatRef<'_, usize, f64>,
        order: PermRef<'_, usize>,
        upper: SymbolicSparseColMatRef<'_, usize>,
        tree: EliminationTreeRef<'_, usize>,
        col_counts: &[usize],
    ) -> ShapesmithResult<Self> {
        let (n, nnz) = (matrix.nrows(), matrix.row_idx().len());
        let mut buffer = MemBuffer::try_new(StackReq::any_of(&[factorize_supernodal_symbolic_cholesky_scratch::<usize>(n), StackReq::new::<usize>(n + 1)]))
            .map_err(|e| factorisation_failed("memory", &e))?;
        let symbolic = factorize_supernodal_symbolic_cholesky(upper, tree, col_counts, MemStack::new(&mut buffer), Default::default())
            .map_err(|e| factorisation_failed("symbolic", &e))?;
        let (mut lower_col_ptr, mut lower_row_idx, mut lower_values) = (vec![0usize; n + 1], vec![0usize; nnz], vec![0.0; nnz]);
        let lower = permute_self_adjoint_to_unsorted(
            &mut lower_values,
            &mut lower_col_ptr,
            &mut lower_row_idx,
            matrix,
            order,
            Side::Lower,
            Side::Lower,
            MemStack::new(&mut buffer),
        )
        .into_const();
        let mut factor_values = vec![0.0; symbolic.len_val()];
        let scratch = factorize_supernodal_numeric_llt_scratch::<usize, f64>(&symbolic, Par::Seq, Default::default());
        let mut buffer = MemBuffer::try_new(scratch).map_err(|e| factorisation_failed("memory", &e))?;
        factorize_supernodal_numeric_llt(&mut factor_values, lower, Default::default(), &symbolic, Par::Seq, MemStack::new(&mut buffer), Default::default())
            .map_err(|e| factorisation_failed("not positive definite", &e))?;
        Ok(Self(Factor::Supernodal { forward: order.arrays().0.to_vec(), symbolic, values: factor_values }))
    }

    /// Solves for three columns given per unknown. The simplicial factor's solve is faer's
    /// (`triangular_solve::solve_lower_triangular{,_transpose}_in_place`) written out with the
    /// same operations in the same order (forward: scale by `1 / L_jj`, then subtract down
    /// the column; backward: the column's products summed from its last row up, starting at
    /// zero, subtracted, then scaled by `1 / L_jj`), on the three coordinates stored side by
    /// side and permuted while copying in and out: the same bits, without faer re-checking
    /// the factor's pattern on every solve and without the column-major copies (callgrind,
    /// `time_transfer Target_Boy 1`: the solves 55 M -> 48 M instructions; through faer's
    /// triangular solves with the pattern checked per solve they took 68 M).
    pub fn solve_points(&self, rhs: &[[f64; 3]]) -> Vec<[f64; 3]> {
        match &self.0 {
            Factor::Simplicial { forward, col_ptr, row_idx, values } => {
                let mut x: Vec<[f64; 3]> = forward.iter().map(|&v| rhs[v]).collect();
                for j in 0..forward.len() {
                    let (first, end) = (col_ptr[j], col_ptr[j + 1]);
                    let scale = 1.0 / values[first];
                    let xj = x[j].map(|c| c * scale);
                    x[j] = xj;
                    for (&i, &l) in row_idx[first + 1..end].iter().zip(&values[first + 1..end]) {
                        for c in 0..3 {
                            x[i][c] -= l * xj[c];
                        }
                    }
                }
                for j in (0..forward.len()).rev() {
                    let (first, end) = (col_ptr[j], col_ptr[j + 1]);
                    let mut sum = [0.0; 3];
                    for (&i, &l) in row_idx[first + 1..end].iter().zip(&values[first + 1..end]).rev() {
                        for c in 0..3 {
                            sum[c] += l * x[i][c];
                        }
                    }
                    let scale = 1.0 / values[first];
                    x[j] = [(x[j][0] - sum[0]) * scale, (x[j][1] - sum[1]) * scale, (x[j][2] - sum[2]) * scale];
                }
                let mut out = vec![[0.0; 3]; forward.len()];
                for (&v, xs) in forward.iter().zip(x) {
                    out[v] = xs;
                }
                out
            }
            // faer's `LltRef::solve_in_place_with_conj`: the right-hand side permuted into a
            // column-major copy, the supernodal solve, permuted back.
            Factor::Supernodal { forward, symbolic, values } => {
                let mut b = Mat::<f64>::from_fn(rhs.len(), 3, |s, c| rhs[forward[s]][c]);
                let mut buffer = MemBuffer::new(symbolic.solve_in_place_scratch::<f64>(3, Par::Seq));
                SupernodalLltRef::new(symbolic, values).solve_in_place_with_conj(Conj::No, b.as_mut(), Par::Seq, MemStack::new(&mut buffer));
                let mut out = vec![[0.0; 3]; rhs.len()];
                for (s, &v) in forward.iter().enumerate() {
                    out[v] = [b[(s, 0)], b[(s, 1)], b[(s, 2)]];
                }
                out
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A random symmetric pattern: each row's products summed in the rows' order equal
    /// `apply`'s entries to the bit.
    #[test]
    fn rows_reproduce_apply_to_the_bit() {
        let n = 40;
        let mut entries = Vec::new();
        for i in 0..n {
            entries.push((i, i, 4.0 + (i as f64 * 0.37).sin()));
            for j in [(i * 7 + 3) % n, (i * 11 + 5) % n] {
                if j != i {
                    entries.push((i, j, -0.1 - (i as f64 * j as f64 * 0.013).cos().abs()));
                }
            }
        }
        let a = SymmetricMatrix::from_triplets(n, entries);
        let x: Vec<f64> = (0..n).map(|v| (v as f64 * 1.3).sin() * 1e3 + 1.0 / (v as f64 + 0.7)).collect();
        let rows = a.rows();
        let by_rows: Vec<f64> = (0..n).map(|v| rows.row(v).iter().fold(0.0, |s, &(c, w)| s + w * x[c])).collect();
        assert!((0..n).all(|v| rows.row(v).windows(2).all(|p| p[0].0 < p[1].0)));
        assert!((0..n).all(|v| rows.row(v).len() >= 3), "each row should hold its diagonal and neighbours");
        assert_eq!(by_rows.iter().map(|y| y.to_bits()).collect::<Vec<_>>(), a.apply(&x).iter().map(|y| y.to_bits()).collect::<Vec<_>>());
    }

    /// The factor built from the kept columns only is the one built by scanning the whole
    /// matrix: same solution to the bit, with and without added diagonal entries.
    #[test]
    fn subset_factor_is_the_restricted_factor_to_the_bit() {
        let n = 60;
        let mut entries = Vec::new();
        for i in 0..n {
            entries.push((i, i, 5.0 + (i as f64 * 0.21).cos()));
            for j in [(i * 13 + 7) % n, (i + 1) % n] {
                if j != i {
                    entries.push((i, j, -0.3 - (i as f64 * 0.7 + j as f64).sin().abs()));
                }
            }
        }
        let a = SymmetricMatrix::from_triplets(n, entries);
        let order = a.fill_reducing_order().unwrap();
        let mut rank = vec![0; n];
        for (slot, &v) in order.iter().enumerate() {
            rank[v] = slot;
        }
        let kept: Vec<usize> = (0..n).filter(|v| v % 3 != 0 && v % 7 != 2).collect();
        let mut position = vec![u32::MAX; n];
        for (slot, &v) in kept.iter().enumerate() {
            position[v] = slot as u32;
        }
        let rhs: Vec<[f64; 3]> = (0..kept.len()).map(|s| [(s as f64).sin(), 1.0 / (s as f64 + 1.0), -(s as f64)]).collect();
        let bits = |x: Vec<[f64; 3]>| x.iter().flatten().map(|v| v.to_bits()).collect::<Vec<_>>();
        for extra in [vec![], vec![(kept[2], 3.5), (kept[9], 0.25), (kept[2], 1.0)]] {
            let whole = a.factor_restricted_plus_diagonal(&position, kept.len(), &order, &extra).unwrap().solve_points(&rhs);
            let subset = a.factor_subset_plus_diagonal(&kept, &position, &rank, &extra).unwrap().solve_points(&rhs);
            assert_eq!(bits(whole), bits(subset));
        }
        // A wrong answer would show: the added diagonal changes the solution.
        let plain = a.factor_subset_plus_diagonal(&kept, &position, &rank, &[]).unwrap().solve_points(&rhs);
        let held = a.factor_subset_plus_diagonal(&kept, &position, &rank, &[(kept[2], 3.5)]).unwrap().solve_points(&rhs);
        assert_ne!(bits(plain), bits(held));
    }

    /// A path graph Laplacian plus a diagonal: whole and restricted solves have zero residual.
    #[test]
    fn whole_and_restricted_solves_have_zero_residual() {
        let n = 30;
        let mut entries = Vec::new();
        for i in 0..n - 1 {
            entries.extend([(i, i, 1.0), (i + 1, i + 1, 1.0), (i, i + 1, -1.0)]);
        }
        entries.extend((0..n).map(|i| (i, i, 0.1 * (i % 3) as f64 + 0.01)));
        let a = SymmetricMatrix::from_triplets(n, entries);
        let order = a.fill_reducing_order().unwrap();
        let rhs: Vec<[f64; 3]> = (0..n).map(|i| [(i as f64).sin(), 1.0, -(i as f64)]).collect();
        let x = a.factor(&order).unwrap().solve_points(&rhs);
        for c in 0..3 {
            let ax = a.apply(&x.iter().map(|p| p[c]).collect::<Vec<_>>());
            assert!((0..n).all(|i| (ax[i] - rhs[i][c]).abs() < 1e-9));
        }
        // Keep the odd unknowns; the even ones are zero.
        let position: Vec<u32> = (0..n as u32).map(|v| if v % 2 == 1 { v / 2 } else { u32::MAX }).collect();
        let kept_rhs: Vec<[f64; 3]> = (0..n).filter(|v| v % 2 == 1).map(|v| rhs[v]).collect();
        let y = a.factor_restricted(&position, n / 2, &order).unwrap().solve_points(&kept_rhs);
        let mut full = vec![0.0; n];
        for v in (1..n).step_by(2) {
            full[v] = y[v / 2][0];
        }
        let ay = a.apply(&full);
        assert!((1..n).step_by(2).all(|v| (ay[v] - rhs[v][0]).abs() < 1e-9));
    }
}
