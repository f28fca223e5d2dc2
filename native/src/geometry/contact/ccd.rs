//! Additive continuous collision detection (Li, Kaufman, Jiang 2021, "Codimensional
//! Incremental Potential Contact", section 5 and its supplement): the largest fraction `t` of
//! a step along which a point-triangle or edge-edge pair stays apart. With the pair's motion
//! made relative (its mean displacement removed), no point of the pair can close the gap
//! faster than `l_p` (the largest displacement of the first primitive plus that of the
//! second), so advancing by `eta d / l_p` never reaches contact; repeating from the new
//! distance gives a step that is always safe and tight up to the factor `eta`, with no root
//! finding and no false negative.

use super::barrier::{pair_squared, PairKind};
use super::dual::dot;

/// `eta`: each advance covers this share of the distance left, so the pair keeps at least
/// `1 - eta` of its distance at the step returned (ipc-toolkit's conservative rescaling).
pub const CONSERVATIVE_RESCALING: f64 = 0.9;

/// Advances at most this many times per pair; a pair that would need more returns the
/// (safe) step reached so far.
const MAX_ADVANCES: usize = 100_000;

/// The largest `t <= t_max` such that the pair moved by `t dx` from `x` has not met, or
/// `t_max` when it stays apart all the way. `x[0]` is the point and `x[1..4]` the triangle
/// (point-triangle), or `x[0]x[1]` and `x[2]x[3]` the edges (edge-edge). The pair must be
/// apart at `x`.
pub fn additive_ccd(kind: PairKind, x: &[[f64; 3]; 4], dx: &[[f64; 3]; 4], t_max: f64) -> f64 {
    let (relative, l_p) = relative_motion(kind, dx);
    if l_p == 0.0 {
        return t_max;
    }
    let mut y = *x;
    let mut d = pair_squared(kind, &y).sqrt();
    let gap = (1.0 - CONSERVATIVE_RESCALING) * d;
    let mut t = 0.0;
    for _ in 0..MAX_ADVANCES {
        let advance = CONSERVATIVE_RESCALING * d / l_p;
        for (p, q) in y.iter_mut().zip(&relative) {
            for a in 0..3 {
                p[a] += advance * q[a];
            }
        }
        d = pair_squared(kind, &y).sqrt();
        if t > 0.0 && d < gap {
            return t;
        }
        t += advance;
        if t > t_max {
            return t_max;
        }
    }
    t
}

/// The pair's step `dx` with its mean removed, and `l_p`: no point of one primitive closes on
/// the other faster than `l_p` along the whole step, so the pair's distance at `x + t dx` is
/// at least its distance at `x` less `t l_p`.
pub fn relative_motion(kind: PairKind, dx: &[[f64; 3]; 4]) -> ([[f64; 3]; 4], f64) {
    let mean: [f64; 3] = std::array::from_fn(|a| dx.iter().map(|p| p[a]).sum::<f64>() / 4.0);
    let relative: [[f64; 3]; 4] = std::array::from_fn(|p| std::array::from_fn(|a| dx[p][a] - mean[a]));
    let norm = |p: usize| dot(relative[p], relative[p]).sqrt();
    let l_p = match kind {
        PairKind::PointTriangle => norm(0) + norm(1).max(norm(2)).max(norm(3)),
        PairKind::EdgeEdge { .. } => norm(0).max(norm(1)) + norm(2).max(norm(3)),
    };
    (relative, l_p)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::contact::distance::tests_support::Lcg;

    fn at(x: &[[f64; 3]; 4], dx: &[[f64; 3]; 4], t: f64) -> [[f64; 3]; 4] {
        std::array::from_fn(|p| std::array::from_fn(|a| x[p][a] + t * dx[p][a]))
    }

    /// Whether segment `p q` passes through triangle `a b c` (signed volumes), independent of
    /// the distance code.
    fn segment_crosses(p: [f64; 3], q: [f64; 3], t: [[f64; 3]; 3]) -> bool {
        let vol = |a: [f64; 3], b: [f64; 3], c: [f64; 3], d: [f64; 3]| {
            let (u, v, w) = (sub3(b, a), sub3(c, a), sub3(d, a));
            u[0] * (v[1] * w[2] - v[2] * w[1]) - u[1] * (v[0] * w[2] - v[2] * w[0]) + u[2] * (v[0] * w[1] - v[1] * w[0])
        };
        let (s1, s2) = (vol(t[0], t[1], t[2], p), vol(t[0], t[1], t[2], q));
        if s1 * s2 > 0.0 {
            return false;
        }
        let (a, b, c) = (vol(p, q, t[0], t[1]), vol(p, q, t[1], t[2]), vol(p, q, t[2], t[0]));
        (a >= 0.0 && b >= 0.0 && c >= 0.0) || (a <= 0.0 && b <= 0.0 && c <= 0.0)
    }

    fn sub3(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
        [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
    }

    #[test]
    fn a_point_through_a_triangle_is_stopped_before_it_and_never_passes() {
        let mut rng = Lcg(21);
        let mut stopped = 0;
        for trial in 0..500 {
            let tri = [rng.point(), rng.point(), rng.point()];
            // A target point inside the triangle, the point starting on one side and moving
            // to the other, the triangle moving a little too.
            let (u, v) = (rng.next() * 0.5, rng.next() * 0.5);
            let inside: [f64; 3] = std::array::from_fn(|a| tri[0][a] + u * (tri[1][a] - tri[0][a]) + v * (tri[2][a] - tri[0][a]));
            let dir = rng.point();
            let p0: [f64; 3] = std::array::from_fn(|a| inside[a] + 0.5 * dir[a]);
            let p1: [f64; 3] = std::array::from_fn(|a| inside[a] - 0.5 * dir[a]);
            let x = [p0, tri[0], tri[1], tri[2]];
            let wobble = 0.05;
            let mut dx = [sub3(p1, p0), rng.point(), rng.point(), rng.point()];
            for d in dx.iter_mut().skip(1) {
                *d = d.map(|c| c * wobble);
            }
            let t = additive_ccd(PairKind::PointTriangle, &x, &dx, 1.0);
            // Brute force along [0, t]: the point never meets the triangle.
            let steps = 2000;
            for i in 1..=steps {
                let (a, b) = (at(&x, &dx, t * (i - 1) as f64 / steps as f64), at(&x, &dx, t * i as f64 / steps as f64));
                // The point's segment between two samples against the triangle at the later one
                // (the triangle moves little): no crossing.
                assert!(!segment_crosses(a[0], b[0], [b[1], b[2], b[3]]), "trial {trial}: crossed before {t}");
            }
            assert!(pair_squared(PairKind::PointTriangle, &at(&x, &dx, t)) > 0.0);
            stopped += usize::from(t < 1.0);
        }
        // Every trajectory passes through the triangle (wobble aside), so nearly all stop.
        assert!(stopped > 450, "{stopped}");
    }

    #[test]
    fn random_motions_never_reach_contact_within_the_step() {
        let mut rng = Lcg(33);
        for trial in 0..400 {
            let kind = if trial % 2 == 0 { PairKind::PointTriangle } else { PairKind::EdgeEdge { mollifier: 0.0 } };
            let x = [rng.point(), rng.point(), rng.point(), rng.point()];
            let dx: [[f64; 3]; 4] = std::array::from_fn(|_| rng.point().map(|c| 2.0 * c));
            let t = additive_ccd(kind, &x, &dx, 1.0);
            let d0 = pair_squared(kind, &x).sqrt();
            let steps = 3000;
            let least = (0..=steps).map(|i| pair_squared(kind, &at(&x, &dx, t * i as f64 / steps as f64)).sqrt()).fold(f64::INFINITY, f64::min);
            assert!(least > 0.0, "trial {trial}");
            // Tight: where it stops short, the pair is within a small multiple of the kept gap
            // of contact somewhere just beyond.
            if t < 1.0 {
                let beyond = (0..=200).map(|i| pair_squared(kind, &at(&x, &dx, (t + (1.0 - t) * i as f64 / 200.0).min(1.0))).sqrt()).fold(f64::INFINITY, f64::min);
                assert!(beyond < d0, "trial {trial}: stopped at {t} with no approach");
            }
        }
    }

    #[test]
    fn an_edge_moved_through_another_stops_before_the_crossing_time() {
        // Edge A fixed, edge B translated straight through A's interior: the volume of the
        // tetrahedron (a0, a1, b0, b1) is linear in t and changes sign once, at the crossing
        // time t*, which the step returned must not reach.
        let mut rng = Lcg(44);
        for trial in 0..500 {
            let (a0, a1) = (rng.point(), rng.point());
            let s = 0.1 + 0.8 * rng.next();
            let on_a: [f64; 3] = std::array::from_fn(|i| a0[i] + s * (a1[i] - a0[i]));
            let dir = rng.point();
            let (u, offset) = (0.1 + 0.8 * rng.next(), rng.point());
            // B passes through on_a at its parameter u when shifted by `offset`.
            let b0: [f64; 3] = std::array::from_fn(|i| on_a[i] - u * dir[i] + offset[i]);
            let b1: [f64; 3] = std::array::from_fn(|i| b0[i] + dir[i]);
            let x = [a0, a1, b0, b1];
            let mv = offset.map(|c| -2.0 * c);
            let dx = [[0.0; 3], [0.0; 3], mv, mv];
            let vol = |y: &[[f64; 3]; 4]| {
                let (p, q, r) = (sub3(y[1], y[0]), sub3(y[2], y[0]), sub3(y[3], y[0]));
                p[0] * (q[1] * r[2] - q[2] * r[1]) - p[1] * (q[0] * r[2] - q[2] * r[0]) + p[2] * (q[0] * r[1] - q[1] * r[0])
            };
            let (v0, v1) = (vol(&x), vol(&at(&x, &dx, 1.0)));
            assert!(v0 * v1 < 0.0, "trial {trial}: the construction must cross");
            let crossing = v0 / (v0 - v1);
            let t = additive_ccd(PairKind::EdgeEdge { mollifier: 0.0 }, &x, &dx, 1.0);
            assert!(t < crossing, "trial {trial}: {t} >= {crossing}");
            assert!(vol(&at(&x, &dx, t)) * v0 > 0.0);
        }
    }
}
