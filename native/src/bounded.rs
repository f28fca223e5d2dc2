//! Bounded least squares on the normal equations: minimise `1/2 w^T H w - g^T w` subject to
//! `lower <= w <= upper`, with `H = A^T A` (K x K, K about 50). A primal active-set method in
//! the manner of Stark & Parker's BVLS: free one violating bound at a time, solve the free
//! block by Cholesky, step back to feasibility when the solution leaves the box.
//! Shared by the landmark score (weights from noisy landmarks) and the performance solve
//! (each Gauss-Newton step's weights).

/// A dense symmetric K x K matrix, row-major.
#[derive(Clone, Debug)]
pub struct Gram {
    pub size: usize,
    pub values: Vec<f64>,
}

impl Gram {
    pub fn at(&self, i: usize, j: usize) -> f64 {
        self.values[i * self.size + j]
    }
}

/// Relative ridge added to `H` (times its largest diagonal entry) so that a shape no landmark
/// sees (a zero column of `A`), or two shapes the landmarks cannot tell apart, get a unique
/// answer: the one nearer zero. Small enough to leave a well-posed answer at 1e-9.
pub const RIDGE: f64 = 1e-10;

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum State {
    Lower,
    Upper,
    Free,
}

/// Solves the box-constrained quadratic program; the answer satisfies the KKT conditions to
/// a tolerance relative to the data. Never fails: a rank-deficient `H` is ridged, and the
/// iteration count is capped (every iterate is feasible).
pub fn solve_bounded(h: &Gram, g: &[f64], lower: &[f64], upper: &[f64]) -> Vec<f64> {
    let k = h.size;
    let scale = (0..k).map(|i| h.at(i, i)).fold(0.0, f64::max);
    let ridge = RIDGE * scale.max(f64::MIN_POSITIVE);
    let hr = |i: usize, j: usize| h.at(i, j) + if i == j { ridge } else { 0.0 };
    let tolerance = 1e-12 * (scale + g.iter().fold(0.0f64, |m, x| m.max(x.abs())));
    let mut w = lower.to_vec();
    let mut state = vec![State::Lower; k];
    for i in 0..k {
        if lower[i] == upper[i] {
            state[i] = State::Upper;
        }
    }
    let gradient = |w: &[f64], i: usize| (0..k).map(|j| hr(i, j) * w[j]).sum::<f64>() - g[i];
    for _ in 0..(10 * k + 20) {
        // The bound with the most negative multiplier leaves its bound.
        let violator = (0..k)
            .filter_map(|i| {
                let d = gradient(&w, i);
                match state[i] {
                    State::Lower if d < -tolerance && lower[i] < upper[i] => Some((i, -d)),
                    State::Upper if d > tolerance && lower[i] < upper[i] => Some((i, d)),
                    _ => None,
                }
            })
            .max_by(|a, b| a.1.total_cmp(&b.1));
        let Some((entering, _)) = violator else { break };
        state[entering] = State::Free;
        // Solve the free block; walk towards it, fixing variables that reach a bound.
        for _ in 0..=k {
            let free: Vec<usize> = (0..k).filter(|&i| state[i] == State::Free).collect();
            if free.is_empty() {
                break;
            }
            let block: Vec<f64> = free.iter().flat_map(|&i| free.iter().map(move |&j| (i, j))).map(|(i, j)| hr(i, j)).collect();
            let rhs: Vec<f64> = free
                .iter()
                .map(|&i| g[i] - (0..k).filter(|&j| state[j] != State::Free).map(|j| hr(i, j) * w[j]).sum::<f64>())
                .collect();
            let target = cholesky_solve(block, rhs, free.len(), ridge);
            let mut step = 1.0f64;
            let mut blocking = None;
            for (z, &i) in target.iter().zip(&free) {
                let (bound, side) = if *z > upper[i] {
                    (upper[i], State::Upper)
                } else if *z < lower[i] {
                    (lower[i], State::Lower)
                } else {
                    continue;
                };
                let fraction = ((bound - w[i]) / (z - w[i])).clamp(0.0, 1.0);
                if fraction < step || blocking.is_none() {
                    step = fraction;
                    blocking = Some((i, bound, side));
                }
            }
            for (z, &i) in target.iter().zip(&free) {
                w[i] = (w[i] + step * (z - w[i])).clamp(lower[i], upper[i]);
            }
            let Some((hit, bound, side)) = blocking else { break };
            // Fix the blocking variable, and any other that landed on a bound.
            w[hit] = bound;
            state[hit] = side;
            for &i in &free {
                if w[i] <= lower[i] {
                    state[i] = State::Lower;
                } else if w[i] >= upper[i] {
                    state[i] = State::Upper;
                }
            }
        }
    }
    w
}

/// Solves `M x = b` for a symmetric positive (semi)definite `M` (row-major, n x n) by
/// Cholesky, with pivots floored at `floor` so that a numerically singular block still gives
/// a finite answer.
pub fn cholesky_solve(mut m: Vec<f64>, mut b: Vec<f64>, n: usize, floor: f64) -> Vec<f64> {
    for j in 0..n {
        let mut pivot = m[j * n + j] - (0..j).map(|p| m[j * n + p] * m[j * n + p]).sum::<f64>();
        pivot = pivot.max(floor).sqrt();
        m[j * n + j] = pivot;
        for i in j + 1..n {
            let s = m[i * n + j] - (0..j).map(|p| m[i * n + p] * m[j * n + p]).sum::<f64>();
            m[i * n + j] = s / pivot;
        }
    }
    for i in 0..n {
        b[i] = (b[i] - (0..i).map(|p| m[i * n + p] * b[p]).sum::<f64>()) / m[i * n + i];
    }
    for i in (0..n).rev() {
        b[i] = (b[i] - (i + 1..n).map(|p| m[p * n + i] * b[p]).sum::<f64>()) / m[i * n + i];
    }
    b
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn objective(h: &Gram, g: &[f64], w: &[f64]) -> f64 {
        let k = h.size;
        let quadratic: f64 = (0..k).flat_map(|i| (0..k).map(move |j| (i, j))).map(|(i, j)| w[i] * h.at(i, j) * w[j]).sum();
        0.5 * quadratic - g.iter().zip(w).map(|(a, b)| a * b).sum::<f64>()
    }

    fn random_problem(rng: &mut impl Rng, k: usize, rows: usize) -> (Gram, Vec<f64>) {
        let a: Vec<f64> = (0..rows * k).map(|_| rng.random_range(-1.0..1.0)).collect();
        let b: Vec<f64> = (0..rows).map(|_| rng.random_range(-1.5..1.5)).collect();
        let values = (0..k * k).map(|ij| (0..rows).map(|r| a[r * k + ij / k] * a[r * k + ij % k]).sum()).collect();
        let g = (0..k).map(|i| (0..rows).map(|r| a[r * k + i] * b[r]).sum()).collect();
        (Gram { size: k, values }, g)
    }

    /// Every assignment of each variable to {lower, upper, free}: solve the free block, keep
    /// the best feasible point.
    fn brute_force(h: &Gram, g: &[f64], lower: &[f64], upper: &[f64]) -> f64 {
        let k = h.size;
        let mut best = f64::INFINITY;
        for code in 0..3usize.pow(k as u32) {
            let digits: Vec<usize> = (0..k).map(|i| code / 3usize.pow(i as u32) % 3).collect();
            let mut w: Vec<f64> = (0..k).map(|i| if digits[i] == 1 { upper[i] } else { lower[i] }).collect();
            let free: Vec<usize> = (0..k).filter(|&i| digits[i] == 2).collect();
            let block = free.iter().flat_map(|&i| free.iter().map(move |&j| h.at(i, j))).collect();
            let rhs = free.iter().map(|&i| g[i] - (0..k).filter(|j| digits[*j] != 2).map(|j| h.at(i, j) * w[j]).sum::<f64>()).collect();
            for (value, &i) in cholesky_solve(block, rhs, free.len(), 0.0).into_iter().zip(&free) {
                w[i] = value;
            }
            if (0..k).all(|i| w[i] >= lower[i] - 1e-12 && w[i] <= upper[i] + 1e-12) {
                best = best.min(objective(h, g, &w));
            }
        }
        best
    }

    #[test]
    fn matches_brute_force_on_small_problems() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(21);
        for trial in 0..200 {
            let k = rng.random_range(1..6);
            let rows = k + rng.random_range(0..4);
            let (h, g) = random_problem(&mut rng, k, rows);
            let (lower, upper) = (vec![0.0; k], vec![1.0; k]);
            let w = solve_bounded(&h, &g, &lower, &upper);
            assert!(w.iter().all(|&x| (0.0..=1.0).contains(&x)), "trial {trial}: {w:?}");
            let want = brute_force(&h, &g, &lower, &upper);
            let got = objective(&h, &g, &w);
            assert!((got - want).abs() < 1e-8 * (1.0 + want.abs()), "trial {trial}: {got} vs {want}");
        }
    }

    /// Rank-deficient problems (fewer rows than unknowns) with K = 12: the KKT conditions hold.
    #[test]
    fn satisfies_kkt_when_rank_deficient() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        for trial in 0..50 {
            let k = 12;
            let rows = rng.random_range(3..15);
            let (h, g) = random_problem(&mut rng, k, rows);
            let w = solve_bounded(&h, &g, &vec![0.0; k], &vec![1.0; k]);
            let scale = (0..k).map(|i| h.at(i, i)).fold(0.0, f64::max);
            for i in 0..k {
                let d = (0..k).map(|j| h.at(i, j) * w[j]).sum::<f64>() - g[i];
                let tolerance = 1e-7 * (1.0 + scale);
                let ok = if w[i] <= 0.0 { d >= -tolerance } else if w[i] >= 1.0 { d <= tolerance } else { d.abs() <= tolerance };
                assert!(ok, "trial {trial}, variable {i}: w = {}, gradient {d}", w[i]);
            }
        }
    }

    #[test]
    fn unconstrained_optimum_inside_the_box_is_returned() {
        // H = diag(2, 4), g = (1, 1): w = (0.5, 0.25).
        let h = Gram { size: 2, values: vec![2.0, 0.0, 0.0, 4.0] };
        let w = solve_bounded(&h, &[1.0, 1.0], &[0.0, 0.0], &[1.0, 1.0]);
        assert!((w[0] - 0.5).abs() < 1e-9 && (w[1] - 0.25).abs() < 1e-9, "{w:?}");
        // g = (4, -1): clamps to (1, 0).
        assert_eq!(solve_bounded(&h, &[4.0, -1.0], &[0.0, 0.0], &[1.0, 1.0]), vec![1.0, 0.0]);
    }
}
