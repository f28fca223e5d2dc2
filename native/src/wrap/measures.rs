//! What a rigger looks at first in a set of keys, as numbers: whether an opening (an eye, the
//! mouth) closes or opens, whether a triangle turns over, whether a margin line (a lid line, a
//! lip contour) stays smooth, and whether a key is smooth. Pure functions on arrays; the
//! places they are measured at (the lid margins, the lips' seam) are found in [`super::looks`].

use crate::geometry::mat3::{cross, dot, length, sub, unit, Vec3};
use crate::geometry::topology::Adjacency;

/// A vertex moves in a key when its motion is over this fraction of the key's largest.
pub const MOVING_FRACTION: f64 = 0.01;

/// The gap left between two margins at an opening's middle, as a fraction of the rest
/// opening: `max(0, (u - l) . n) / |u0 - l0|`, with `u`, `l` the posed points on the two
/// margins (the upper lid and the lower lid at the eye's middle), `u0`, `l0` the same points
/// at rest and `n` the unit direction from `l0` to `u0`. A margin carried past the other
/// (the upper lid pressed below the lower lid's edge) reads as closed, 0; one that stays put
/// reads 1. `None` when the rest opening is empty (the margins touch at rest).
pub fn opening_gap(upper_rest: Vec3, lower_rest: Vec3, upper: Vec3, lower: Vec3) -> Option<f64> {
    let rest = sub(upper_rest, lower_rest);
    let width = length(rest);
    let n = unit(rest)?;
    Some(dot(sub(upper, lower), n).max(0.0) / width)
}

/// The triangles whose normal turns by more than a right angle from the rest to the posed
/// mesh (`dot(n_rest, n_posed) < 0`): a face turned inside out, a fold a rigger sees as a
/// crease or a dark patch. Degenerate triangles (no normal at rest or posed) are not counted.
pub fn turned_over(rest: &[Vec3], posed: &[Vec3], triangles: &[[u32; 3]]) -> usize {
    let normal = |p: &[Vec3], t: &[u32; 3]| {
        let [a, b, c] = t.map(|v| p[v as usize]);
        cross(sub(b, a), sub(c, a))
    };
    triangles
        .iter()
        .filter(|t| {
            let (r, p) = (normal(rest, t), normal(posed, t));
            length(r) > 0.0 && length(p) > 0.0 && dot(r, p) < 0.0
        })
        .count()
}

/// The share of the skin a key moves that it turns over: the rest area of the
/// [`turned_over`] triangles over the rest area of the triangles with a corner moving over
/// [`MOVING_FRACTION`] of the key's largest motion. A closing lid folds into the socket on any
/// mesh (the bundled template's own blinks turn 58 triangles over), so a count alone cannot
/// tell a carried key from its template; an area share can, whatever either mesh's
/// resolution. 0 for a key that does not move.
pub fn turned_over_share(rest: &[Vec3], deltas: &[Vec3], triangles: &[[u32; 3]]) -> f64 {
    let largest = deltas.iter().map(|&d| length(d)).fold(0.0, f64::max);
    let area = |t: &[u32; 3]| {
        let [a, b, c] = t.map(|v| rest[v as usize]);
        0.5 * length(cross(sub(b, a), sub(c, a)))
    };
    let moving: Vec<&[u32; 3]> = triangles.iter().filter(|t| t.iter().any(|&v| length(deltas[v as usize]) > MOVING_FRACTION * largest)).collect();
    let moved_area: f64 = moving.iter().map(|t| area(t)).sum();
    if largest == 0.0 || moved_area == 0.0 {
        return 0.0;
    }
    let posed: Vec<Vec3> = rest.iter().zip(deltas).map(|(&p, &d)| crate::geometry::mat3::add(p, d)).collect();
    // A fold from +0.0: an empty f64 sum is -0.0, which would print as a negative share.
    let turned = moving.iter().filter(|t| turned_over(rest, &posed, std::slice::from_ref(**t)) == 1).map(|t| area(t)).fold(0.0, |sum, a| sum + a);
    turned / moved_area
}

/// A line's roughness: the summed second differences of its arc-length parametrisation,
/// `sum_i |t_{i+1} - t_i|` over its unit segment directions `t_i` (each term `2 sin(theta/2)`
/// for the turn `theta` at a point, so the sum is the line's total turning, about `∫|κ| ds`
/// for a smooth line whatever its sampling). A lid line that zig-zags turns back and forth at
/// every point and sums far more than the smooth arc through the same ends. Zero-length
/// segments are skipped; fewer than three distinct points give 0.
pub fn line_turning(points: &[Vec3]) -> f64 {
    let directions: Vec<Vec3> = points.windows(2).filter_map(|w| unit(sub(w[1], w[0]))).collect();
    directions.windows(2).map(|w| length(sub(w[1], w[0]))).sum()
}

/// A key's roughness: the mean norm of the uniform Laplacian of its deltas,
/// `|(1/|N(v)|) sum_{w in N(v)} d_w - d_v|`, over its moving vertices (motion over
/// [`MOVING_FRACTION`] of its largest), divided by its largest motion. Noise from vertex to
/// vertex (a crumpled lid, stair steps) raises it; a smooth motion keeps it near the mesh's
/// own curvature of the field. Comparable between keys on one mesh (the carried key and the
/// same-topology truth sampled at the same vertices), not between meshes of other resolution.
/// 0 for a key that does not move.
pub fn key_roughness(deltas: &[Vec3], adjacency: &Adjacency) -> f64 {
    let largest = deltas.iter().map(|&d| length(d)).fold(0.0, f64::max);
    if largest == 0.0 {
        return 0.0;
    }
    let (mut sum, mut count) = (0.0, 0usize);
    for (v, &d) in deltas.iter().enumerate() {
        let neighbours = adjacency.neighbours(v);
        if length(d) <= MOVING_FRACTION * largest || neighbours.is_empty() {
            continue;
        }
        let mut mean = [0.0; 3];
        for &w in neighbours {
            mean = crate::geometry::mat3::add(mean, deltas[w as usize]);
        }
        mean = crate::geometry::mat3::scale(mean, 1.0 / neighbours.len() as f64);
        sum += length(sub(mean, d));
        count += 1;
    }
    if count == 0 {
        0.0
    } else {
        sum / count as f64 / largest
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::topology::grid_triangles;

    #[test]
    fn a_closed_lid_leaves_no_gap_and_an_open_one_all_of_it() {
        let (upper, lower) = ([0.0, 0.0, 1.0], [0.0, 0.0, 0.0]);
        assert_eq!(opening_gap(upper, lower, [0.0, 0.1, 0.0], lower), Some(0.0));
        // Pressed past the lower lid: still closed.
        assert_eq!(opening_gap(upper, lower, [0.0, 0.0, -0.2], lower), Some(0.0));
        assert_eq!(opening_gap(upper, lower, upper, lower), Some(1.0));
        let half = opening_gap(upper, lower, [0.3, 0.0, 0.55], [0.0, 0.0, 0.05]).unwrap();
        assert!((half - 0.5).abs() < 1e-12, "{half}");
        assert_eq!(opening_gap(lower, lower, upper, lower), None);
    }

    #[test]
    fn a_flipped_triangle_is_counted_and_a_moved_one_is_not() {
        let rest = [[0.0, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [1.0, 1.0, 0.0]];
        let triangles = [[0, 1, 2], [1, 3, 2]];
        let moved: Vec<Vec3> = rest.iter().map(|p| [p[0] + 3.0, p[1], p[2] + 1.0]).collect();
        assert_eq!(turned_over(&rest, &moved, &triangles), 0);
        // The far corner pulled across the shared edge: the second triangle turns over.
        let mut folded = rest.to_vec();
        folded[3] = [-0.5, -0.5, 0.0];
        assert_eq!(turned_over(&rest, &folded, &triangles), 1);
        // A whole mirror image turns every triangle over.
        let mirrored: Vec<Vec3> = rest.iter().map(|p| [-p[0], p[1], p[2]]).collect();
        assert_eq!(turned_over(&rest, &mirrored, &triangles), 2);
        // The share: with the first corner also moved (in its plane) both triangles move, and
        // the folded one is half their area.
        let mut deltas: Vec<Vec3> = rest.iter().zip(&folded).map(|(&r, &f)| sub(f, r)).collect();
        deltas[0] = [-0.1, 0.0, 0.0];
        assert!((turned_over_share(&rest, &deltas, &triangles) - 0.5).abs() < 1e-12);
        assert_eq!(turned_over_share(&rest, &vec![[0.0; 3]; 4], &triangles), 0.0);
        let shifted: Vec<Vec3> = rest.iter().map(|_| [0.0, 0.0, 1.0]).collect();
        assert!(turned_over_share(&rest, &shifted, &triangles).is_sign_positive());
    }

    #[test]
    fn a_zig_zag_line_is_rougher_than_the_smooth_arc_through_it() {
        let arc: Vec<Vec3> = (0..=20).map(|i| {
            let a = std::f64::consts::PI * i as f64 / 20.0;
            [a.cos(), a.sin(), 0.0]
        }).collect();
        let smooth = line_turning(&arc);
        // A half circle in 20 chords turns 19 times by pi / 20: about pi, however it is sampled.
        let expected = 19.0 * 2.0 * (std::f64::consts::PI / 40.0).sin();
        assert!((smooth - expected).abs() < 1e-9, "{smooth} vs {expected}");
        let zig: Vec<Vec3> = arc.iter().enumerate().map(|(i, p)| {
            let r = if i % 2 == 0 { 1.0 } else { 0.95 };
            [r * p[0], r * p[1], 0.0]
        }).collect();
        assert!(line_turning(&zig) > 3.0 * smooth, "{} vs {smooth}", line_turning(&zig));
        assert_eq!(line_turning(&arc[..2]), 0.0);
        let straight: Vec<Vec3> = (0..5).map(|i| [i as f64, 0.0, 0.0]).collect();
        assert!(line_turning(&straight).abs() < 1e-12);
    }

    #[test]
    fn noise_makes_a_key_rough_and_a_smooth_field_is_not() {
        let (w, h) = (12u32, 12u32);
        let triangles = grid_triangles(w, h, 0);
        let n = (w * h) as usize;
        let adjacency = Adjacency::from_triangles(n, &triangles);
        // A linear field: the uniform Laplacian vanishes inside, only the border reads.
        let linear: Vec<Vec3> = (0..n).map(|v| [0.0, 0.0, (v as u32 % w) as f64]).collect();
        let noisy: Vec<Vec3> = linear.iter().enumerate().map(|(v, d)| [0.0, 0.0, d[2] + if v % 2 == 0 { 0.5 } else { -0.5 }]).collect();
        let (smooth, rough) = (key_roughness(&linear, &adjacency), key_roughness(&noisy, &adjacency));
        assert!(rough > 3.0 * smooth, "{rough} vs {smooth}");
        // Scale-free: the same key twice as large is as rough.
        let doubled: Vec<Vec3> = noisy.iter().map(|d| d.map(|x| 2.0 * x)).collect();
        assert!((key_roughness(&doubled, &adjacency) - rough).abs() < 1e-12);
        assert_eq!(key_roughness(&vec![[0.0; 3]; n], &adjacency), 0.0);
    }
}
