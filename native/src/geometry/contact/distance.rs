//! Unsigned distances between the primitives IPC puts barriers on (Li et al. 2020, section 4):
//! a point and a triangle, two edges. The closest points decide the *distance type* (which
//! features are closest: a vertex, an edge's line, the triangle's plane); within one type the
//! squared distance is one smooth formula ([`squared`]), which the barrier differentiates.

use super::dual::{cross, dot, sub, Real};

/// Which features of a pair are closest. Points are numbered as the pair gives them: for a
/// point-triangle pair `[p, t0, t1, t2]`, for an edge-edge pair `[a0, a1, b0, b1]`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DistanceType {
    /// Two points `i`, `j`.
    PointPoint(usize, usize),
    /// Point `i` and the line through points `j`, `k`.
    PointLine(usize, usize, usize),
    /// Point 0 and the plane of points 1, 2, 3 (point-triangle only).
    PointPlane,
    /// The lines through points 0, 1 and 2, 3 (edge-edge only).
    LineLine,
}

/// The squared distance of the features `kind` names, as one formula (exact derivatives
/// through [`super::dual::Dual`]).
pub fn squared<T: Real>(kind: DistanceType, x: &[[T; 3]; 4]) -> T {
    match kind {
        DistanceType::PointPoint(i, j) => {
            let d = sub(x[i], x[j]);
            dot(d, d)
        }
        DistanceType::PointLine(i, j, k) => {
            let e = sub(x[k], x[j]);
            let c = cross(e, sub(x[i], x[j]));
            dot(c, c) / dot(e, e)
        }
        DistanceType::PointPlane => {
            let n = cross(sub(x[2], x[1]), sub(x[3], x[1]));
            let h = dot(sub(x[0], x[1]), n);
            h * h / dot(n, n)
        }
        DistanceType::LineLine => {
            let n = cross(sub(x[1], x[0]), sub(x[3], x[2]));
            let h = dot(sub(x[2], x[0]), n);
            h * h / dot(n, n)
        }
    }
}

/// The distance type of point `x[0]` and triangle `x[1..4]`: the region of the triangle its
/// closest point lies in (Ericson, Real-Time Collision Detection, 5.1.5).
pub fn point_triangle_type(x: &[[f64; 3]; 4]) -> DistanceType {
    let (p, a, b, c) = (x[0], x[1], x[2], x[3]);
    let (ab, ac, ap) = (sub(b, a), sub(c, a), sub(p, a));
    let (d1, d2) = (dot(ab, ap), dot(ac, ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return DistanceType::PointPoint(0, 1);
    }
    let bp = sub(p, b);
    let (d3, d4) = (dot(ab, bp), dot(ac, bp));
    if d3 >= 0.0 && d4 <= d3 {
        return DistanceType::PointPoint(0, 2);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        return DistanceType::PointLine(0, 1, 2);
    }
    let cp = sub(p, c);
    let (d5, d6) = (dot(ab, cp), dot(ac, cp));
    if d6 >= 0.0 && d5 <= d6 {
        return DistanceType::PointPoint(0, 3);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        return DistanceType::PointLine(0, 1, 3);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        return DistanceType::PointLine(0, 2, 3);
    }
    DistanceType::PointPlane
}

/// The distance type of segments `x[0]x[1]` and `x[2]x[3]`: whether each closest point is an
/// end or inside its segment (Ericson 5.1.9; parallel segments take an end of the first).
pub fn edge_edge_type(x: &[[f64; 3]; 4]) -> DistanceType {
    let (d1, d2) = (sub(x[1], x[0]), sub(x[3], x[2]));
    let r = sub(x[0], x[2]);
    let (a, e, f) = (dot(d1, d1), dot(d2, d2), dot(d2, r));
    let (c, b) = (dot(d1, r), dot(d1, d2));
    let denom = a * e - b * b;
    // Parallel (or nearly): the lines' distance formula is undefined; an end decides.
    let mut s = if denom > 1e-12 * a * e { ((b * f - c * e) / denom).clamp(0.0, 1.0) } else { 0.0 };
    let mut t = (b * s + f) / e;
    if t < 0.0 {
        t = 0.0;
        s = (-c / a).clamp(0.0, 1.0);
    } else if t > 1.0 {
        t = 1.0;
        s = ((b - c) / a).clamp(0.0, 1.0);
    }
    let end = |u: f64| u <= 0.0 || u >= 1.0;
    let pick = |u: f64, first: usize| if u <= 0.0 { first } else { first + 1 };
    match (end(s), end(t)) {
        (false, false) => DistanceType::LineLine,
        (true, false) => DistanceType::PointLine(pick(s, 0), 2, 3),
        (false, true) => DistanceType::PointLine(pick(t, 2), 0, 1),
        (true, true) => DistanceType::PointPoint(pick(s, 0), pick(t, 2)),
    }
}

/// Squared distance of point `x[0]` and triangle `x[1..4]`.
pub fn point_triangle_squared(x: &[[f64; 3]; 4]) -> f64 {
    squared(point_triangle_type(x), x)
}

/// Squared distance of segments `x[0]x[1]` and `x[2]x[3]`.
pub fn edge_edge_squared(x: &[[f64; 3]; 4]) -> f64 {
    squared(edge_edge_type(x), x)
}

#[cfg(test)]
pub(crate) mod tests_support {
    /// A small deterministic generator (no dependency on the solver's own sampling).
    pub(crate) struct Lcg(pub u64);
    impl Lcg {
        pub fn next(&mut self) -> f64 {
            self.0 = self.0.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            ((self.0 >> 11) as f64) / ((1u64 << 53) as f64)
        }
        pub fn point(&mut self) -> [f64; 3] {
            [self.next() * 2.0 - 1.0, self.next() * 2.0 - 1.0, self.next() * 2.0 - 1.0]
        }
    }
}

#[cfg(test)]
mod tests {
    use super::tests_support::Lcg;
    use super::*;

    fn lerp(a: [f64; 3], b: [f64; 3], t: f64) -> [f64; 3] {
        std::array::from_fn(|i| a[i] + t * (b[i] - a[i]))
    }

    fn dist2(a: [f64; 3], b: [f64; 3]) -> f64 {
        let d = sub(a, b);
        dot(d, d)
    }

    #[test]
    fn point_triangle_distance_is_the_least_over_a_dense_sampling_of_the_triangle() {
        let mut rng = Lcg(7);
        for _ in 0..300 {
            let x = [rng.point(), rng.point(), rng.point(), rng.point()];
            let d = point_triangle_squared(&x);
            let mut brute = f64::INFINITY;
            let steps = 120;
            for i in 0..=steps {
                for j in 0..=steps - i {
                    let (u, v) = (i as f64 / steps as f64, j as f64 / steps as f64);
                    let q: [f64; 3] = std::array::from_fn(|a| x[1][a] + u * (x[2][a] - x[1][a]) + v * (x[3][a] - x[1][a]));
                    brute = brute.min(dist2(x[0], q));
                }
            }
            // Never above the sampled least (it is the exact least), and no more than the
            // sampling's resolution below it.
            assert!(d <= brute + 1e-12, "{d} > {brute}");
            assert!(brute.sqrt() - d.sqrt() < 0.03, "{} vs {}", d.sqrt(), brute.sqrt());
        }
    }

    #[test]
    fn edge_edge_distance_is_the_least_over_a_dense_sampling_of_both_segments() {
        let mut rng = Lcg(11);
        for trial in 0..300 {
            let mut x = [rng.point(), rng.point(), rng.point(), rng.point()];
            if trial % 10 == 0 {
                // Parallel segments.
                let shift = rng.point();
                x[2] = lerp(x[0], x[1], -0.3);
                x[2] = std::array::from_fn(|a| x[2][a] + 0.2 * shift[a]);
                x[3] = std::array::from_fn(|a| x[2][a] + 0.7 * (x[1][a] - x[0][a]));
            }
            let d = edge_edge_squared(&x);
            let mut brute = f64::INFINITY;
            let steps = 400;
            for i in 0..=steps {
                let p = lerp(x[0], x[1], i as f64 / steps as f64);
                for j in 0..=steps {
                    brute = brute.min(dist2(p, lerp(x[2], x[3], j as f64 / steps as f64)));
                }
            }
            assert!(d <= brute + 1e-12, "trial {trial}: {d} > {brute}");
            assert!(brute.sqrt() - d.sqrt() < 0.01, "trial {trial}: {} vs {}", d.sqrt(), brute.sqrt());
        }
    }
}
