//! Closest points on triangles and on a triangle mesh (through [`super::bvh::TriangleBvh`]):
//! the binding queries of the wrap (a template vertex to the character's surface, a
//! character triangle to the wrapped template's).

use super::bvh::{dot, sub};

/// A point on a mesh's surface: the triangle it lies on (an index into the caller's
/// triangle list), the point, its barycentric coordinates in that triangle's corner order, and
/// the squared distance from the query.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SurfacePoint {
    pub triangle: u32,
    pub point: [f64; 3],
    pub barycentric: [f64; 3],
    pub distance_squared: f64,
}

/// The point of triangle `abc` closest to `p` and its barycentric coordinates, by the
/// Voronoi-region walk of Ericson (Real-Time Collision Detection, 2005, section 5.1.5).
/// A degenerate triangle answers with its closest corner or edge point.
pub fn closest_on_triangle(p: &[f64; 3], a: &[f64; 3], b: &[f64; 3], c: &[f64; 3]) -> ([f64; 3], [f64; 3]) {
    let ab = sub(b, a);
    let ac = sub(c, a);
    let ap = sub(p, a);
    let d1 = dot(&ab, &ap);
    let d2 = dot(&ac, &ap);
    if d1 <= 0.0 && d2 <= 0.0 {
        return (*a, [1.0, 0.0, 0.0]);
    }
    let bp = sub(p, b);
    let d3 = dot(&ab, &bp);
    let d4 = dot(&ac, &bp);
    if d3 >= 0.0 && d4 <= d3 {
        return (*b, [0.0, 1.0, 0.0]);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let v = d1 / (d1 - d3);
        return (along(a, &ab, v), [1.0 - v, v, 0.0]);
    }
    let cp = sub(p, c);
    let d5 = dot(&ab, &cp);
    let d6 = dot(&ac, &cp);
    if d6 >= 0.0 && d5 <= d6 {
        return (*c, [0.0, 0.0, 1.0]);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let w = d2 / (d2 - d6);
        return (along(a, &ac, w), [1.0 - w, 0.0, w]);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (along(b, &sub(c, b), w), [0.0, 1.0 - w, w]);
    }
    let denominator = va + vb + vc;
    if denominator == 0.0 || !denominator.is_finite() {
        // Collinear corners that no region test caught: the nearest corner.
        let corners = [a, b, c];
        let nearest = (0..3).min_by(|&i, &j| distance_squared(p, corners[i]).total_cmp(&distance_squared(p, corners[j]))).unwrap_or(0);
        let mut bary = [0.0; 3];
        bary[nearest] = 1.0;
        return (*corners[nearest], bary);
    }
    let v = vb / denominator;
    let w = vc / denominator;
    let point = std::array::from_fn(|i| a[i] + ab[i] * v + ac[i] * w);
    (point, [1.0 - v - w, v, w])
}

pub fn distance_squared(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    let d = sub(a, b);
    dot(&d, &d)
}

fn along(origin: &[f64; 3], direction: &[f64; 3], t: f64) -> [f64; 3] {
    std::array::from_fn(|i| origin[i] + direction[i] * t)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::bvh::TriangleBvh;
    use rand::{Rng, SeedableRng};

    /// Against a dense sampling of the triangle: nothing sampled is closer than the answer,
    /// and the answer is the barycentric combination it reports.
    #[test]
    fn closest_on_triangle_beats_every_sample() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for _ in 0..200 {
            let [a, b, c, p]: [[f64; 3]; 4] = std::array::from_fn(|_| std::array::from_fn(|_| rng.random_range(-1.0..1.0)));
            let (q, bary) = closest_on_triangle(&p, &a, &b, &c);
            assert!(bary.iter().all(|&x| (-1e-12..=1.0 + 1e-12).contains(&x)) && (bary.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            let rebuilt: [f64; 3] = std::array::from_fn(|i| bary[0] * a[i] + bary[1] * b[i] + bary[2] * c[i]);
            assert!(distance_squared(&rebuilt, &q) < 1e-20);
            let best = distance_squared(&p, &q);
            for i in 0..=40 {
                for j in 0..=(40 - i) {
                    let (u, v) = (i as f64 / 40.0, j as f64 / 40.0);
                    let s: [f64; 3] = std::array::from_fn(|k| a[k] + u * (b[k] - a[k]) + v * (c[k] - a[k]));
                    assert!(distance_squared(&p, &s) >= best - 1e-12);
                }
            }
        }
    }

    /// The hierarchy's closest point is the brute-force closest over all triangles.
    #[test]
    fn mesh_query_matches_brute_force() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(5);
        let points: Vec<[f64; 3]> = (0..450).map(|_| std::array::from_fn(|_| rng.random::<f64>())).collect();
        let triangles: Vec<[u32; 3]> = (0..150).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        let bvh = TriangleBvh::build(&points, &triangles);
        for _ in 0..500 {
            let p: [f64; 3] = std::array::from_fn(|_| rng.random_range(-0.5..1.5));
            let brute = triangles
                .iter()
                .map(|t| {
                    let [a, b, c] = t.map(|v| points[v as usize]);
                    distance_squared(&p, &closest_on_triangle(&p, &a, &b, &c).0)
                })
                .fold(f64::INFINITY, f64::min);
            let hit = bvh.closest_point(&p, f64::INFINITY).expect("an unbounded query always finds a triangle");
            assert!((hit.distance_squared - brute).abs() < 1e-12, "{} vs {brute}", hit.distance_squared);
            let bounded = bvh.closest_point(&p, 0.5 * brute.sqrt());
            assert!(bounded.is_none(), "nothing lies within half the closest distance");
        }
    }
}
