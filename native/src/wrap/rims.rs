//! Rims: the template skin's holes (eye openings, a mouth opening) landed on the character's
//! matching holes, with their corners on the corners.
//!
//! Why: closest points on the character's open boundary are rejected (there the template runs
//! past the character's edge, as at a longer neck), so a template vertex on an eye opening's
//! rim had no data term: the stiffness alone placed it, each rim vertex slid along the lid by
//! its own amount, and the closed lid of a blink showed it (a jagged lid edge on a decimated
//! MakeHuman identity). Here each template rim vertex gets a fixed target on the character's
//! matching loop (Amberg et al. 2007 drop correspondences on the target's border, Section
//! 3.2, rightly for a cut neck; an eye opening is a feature both heads share, so its rim is
//! matched instead; the chord-length parametrisation of a boundary loop is the one Floater
//! 1997 maps a boundary with):
//! - A **hole** is a boundary loop of the skin small against the mesh (its radius under
//!   [`HOLE_SIZE`] of the skin's bbox diagonal; the neck cut of a head is about 0.15, an eye
//!   opening 0.03), so the neck cut, which the character may end elsewhere, is left free.
//! - Template and character holes are **paired by place and size** after the alignment, one to
//!   one, the closest first (`pieces::match_pieces`, the pieces' rule, with a looser place:
//!   [`HOLE_OFFSET`]).
//! - Each loop is **split at its corners**, the extreme points along the character loop's
//!   longest axis (an eye's canthi, a mouth's commissures), into two arcs, and a template rim
//!   vertex at arc-length fraction `f` of its arc targets fraction `f` of the matching arc.
//!   Arc length keeps the rim from bunching where the character's loop bends (a closest point
//!   on the loop would gather several template vertices there and leave the rest of the rim
//!   free), and the corners land on the corners. The arcs are matched in the orientation that
//!   puts the targets nearest the template's rim.

use crate::geometry::mat3::{add, dot, length, scale, sub, Vec3};
use crate::geometry::topology::boundary_edges;

use super::align::symmetric_eigen;
use super::pieces::{match_pieces, Moments};

/// A boundary loop is a hole (eye or mouth opening) when its radius is under this fraction of
/// the skin's bbox diagonal.
pub const HOLE_SIZE: f64 = 0.1;

/// Holes pair when their centres lie within this many template hole radii after the
/// alignment (which is rigid: the eyes of two identities sit up to one radius apart; the other
/// eye lies about ten radii away).
pub const HOLE_OFFSET: f64 = 2.0;

/// A template rim vertex and where it belongs on the character's matching rim.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RimTarget {
    pub vertex: u32,
    pub target: Vec3,
}

/// Each boundary loop of the mesh (edges of one triangle), as its vertices in walking order.
/// A vertex where two loops touch is walked once per outgoing boundary edge.
pub fn boundary_loops(triangles: &[[u32; 3]]) -> Vec<Vec<u32>> {
    let boundary = boundary_edges(triangles);
    let mut next = std::collections::BTreeMap::<u32, Vec<u32>>::new();
    for t in triangles {
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            if boundary.contains(&(a.min(b), a.max(b))) {
                next.entry(a).or_default().push(b);
            }
        }
    }
    let mut loops = Vec::new();
    while let Some((&start, _)) = next.iter().find(|(_, out)| !out.is_empty()) {
        let mut walk = vec![start];
        let mut at = start;
        while let Some(to) = next.get_mut(&at).and_then(|out| out.pop()) {
            if to == start {
                break;
            }
            walk.push(to);
            at = to;
        }
        if walk.len() >= 3 {
            loops.push(walk);
        }
    }
    loops
}

/// A loop's points, its cumulative arc length at each vertex and its whole length.
struct Curve {
    points: Vec<Vec3>,
    arc: Vec<f64>,
    length: f64,
}

impl Curve {
    fn new(points: Vec<Vec3>) -> Self {
        let mut arc = Vec::with_capacity(points.len());
        let mut total = 0.0;
        for (i, p) in points.iter().enumerate() {
            if i > 0 {
                total += length(sub(*p, points[i - 1]));
            }
            arc.push(total);
        }
        total += length(sub(points[0], points[points.len() - 1]));
        Self { points, arc, length: total }
    }

    /// Centre and root-mean-square radius of the loop's edges' midpoints weighted by their
    /// lengths (so that uneven vertex spacing does not move them).
    fn moments(&self) -> Option<Moments> {
        let n = self.points.len();
        let segments: Vec<(Vec3, f64)> =
            (0..n).map(|i| (self.points[i], self.points[(i + 1) % n])).map(|(a, b)| (scale(add(a, b), 0.5), length(sub(b, a)))).collect();
        if self.length <= 0.0 {
            return None;
        }
        let centre = scale(segments.iter().fold([0.0; 3], |acc, &(m, w)| add(acc, scale(m, w))), 1.0 / self.length);
        let radius = (segments.iter().map(|&(m, w)| w * length(sub(m, centre)).powi(2)).sum::<f64>() / self.length).sqrt();
        (radius > 0.0).then_some(Moments { centre, radius })
    }

    /// The point at arc length `s` from vertex 0 (walking order, wrapped around).
    fn at(&self, s: f64) -> Vec3 {
        let s = s.rem_euclid(self.length);
        let i = self.arc.partition_point(|&a| a <= s) - 1;
        let j = (i + 1) % self.points.len();
        let end = if j == 0 { self.length } else { self.arc[j] };
        let t = if end > self.arc[i] { (s - self.arc[i]) / (end - self.arc[i]) } else { 0.0 };
        add(self.points[i], scale(sub(self.points[j], self.points[i]), t))
    }

    /// The vertices extreme along `axis` (the corners), lowest first.
    fn corners(&self, axis: Vec3) -> (usize, usize) {
        let along = |i: &usize| dot(self.points[*i], axis);
        let low = (0..self.points.len()).min_by(|a, b| along(a).total_cmp(&along(b))).unwrap_or(0);
        let high = (0..self.points.len()).max_by(|a, b| along(a).total_cmp(&along(b))).unwrap_or(0);
        (low, high)
    }

    /// Where a vertex lies between the corners: (on the forward arc from `low` to `high`,
    /// fraction of that arc from `low`).
    fn arc_fraction(&self, vertex: usize, (low, high): (usize, usize)) -> (bool, f64) {
        let forward = (self.arc[high] - self.arc[low]).rem_euclid(self.length);
        let from_low = (self.arc[vertex] - self.arc[low]).rem_euclid(self.length);
        if from_low <= forward {
            (true, if forward > 0.0 { from_low / forward } else { 0.0 })
        } else {
            (false, (self.length - from_low) / (self.length - forward))
        }
    }

    /// The point at `fraction` of the forward (or backward) arc from `low` to `high`.
    fn on_arc(&self, forward_arc: bool, fraction: f64, (low, high): (usize, usize)) -> Vec3 {
        let forward = (self.arc[high] - self.arc[low]).rem_euclid(self.length);
        if forward_arc {
            self.at(self.arc[low] + fraction * forward)
        } else {
            self.at(self.arc[low] - fraction * (self.length - forward))
        }
    }
}

/// The holes among a skin's boundary loops, as curves at `points`.
fn holes(points: &[Vec3], triangles: &[[u32; 3]], vertices: &[u32]) -> Vec<(Vec<u32>, Curve)> {
    let (mut low, mut high) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
    for &v in vertices {
        for k in 0..3 {
            low[k] = low[k].min(points[v as usize][k]);
            high[k] = high[k].max(points[v as usize][k]);
        }
    }
    let diagonal = length(sub(high, low));
    boundary_loops(triangles)
        .into_iter()
        .map(|walk| {
            let curve = Curve::new(walk.iter().map(|&v| points[v as usize]).collect());
            (walk, curve)
        })
        .filter(|(_, curve)| curve.moments().is_some_and(|m| m.radius < HOLE_SIZE * diagonal))
        .collect()
}

/// The holes among a skin's boundary loops: each as its vertices in walking order and its
/// centre and radius.
pub(super) fn hole_loops(points: &[Vec3], triangles: &[[u32; 3]], vertices: &[u32]) -> Vec<(Vec<u32>, Moments)> {
    holes(points, triangles, vertices).into_iter().filter_map(|(walk, curve)| curve.moments().map(|m| (walk, m))).collect()
}

/// The longest axis of a curve's points (unit).
fn longest_axis(curve: &Curve) -> Option<Vec3> {
    let centre = curve.moments()?.centre;
    let mut covariance = [[0.0; 3]; 3];
    for p in &curve.points {
        let d = sub(*p, centre);
        for r in 0..3 {
            for c in 0..3 {
                covariance[r][c] += d[r] * d[c];
            }
        }
    }
    let (_, vectors) = symmetric_eigen(&covariance).ok()?;
    Some([vectors[0][2], vectors[1][2], vectors[2][2]])
}

/// A template hole paired with a character hole: a vertex of each rim and the rims' vertex
/// counts (the report says which openings landed where).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct HoleMatch {
    pub template_vertex: u32,
    pub template_rim: usize,
    pub character_vertex: u32,
    pub character_rim: usize,
    /// The character's hole is a lid hole (`lids`): the template's lids landed on its rim
    /// about the template eyeball holding `template_vertex`, `template_rim` its vertex count.
    pub lids: bool,
}

/// Targets on the character's holes for the rim vertices of the template's matching holes.
/// `template` at its aligned positions with `skin_triangles`/`skin` its skin, `character` with
/// `character_triangles`/`character_skin` the character's. Returns the targets and the holes
/// paired.
pub fn rim_targets(
    template: &[Vec3],
    skin_triangles: &[[u32; 3]],
    skin: &[u32],
    character: &[Vec3],
    character_triangles: &[[u32; 3]],
    character_skin: &[u32],
) -> (Vec<RimTarget>, Vec<HoleMatch>) {
    let template_holes = holes(template, skin_triangles, skin);
    let character_holes = holes(character, character_triangles, character_skin);
    let pairs = match_pieces(
        &template_holes.iter().map(|(_, c)| c.moments()).collect::<Vec<_>>(),
        &character_holes.iter().map(|(_, c)| c.moments()).collect::<Vec<_>>(),
        HOLE_OFFSET,
    );
    let mut targets = Vec::new();
    let mut paired = Vec::new();
    for (i, j) in pairs {
        let ((walk, template_curve), (character_walk, character_curve)) = (&template_holes[i], &character_holes[j]);
        let Some(axis) = longest_axis(character_curve) else { continue };
        let (template_corners, character_corners) = (template_curve.corners(axis), character_curve.corners(axis));
        let fractions: Vec<(bool, f64)> = (0..walk.len()).map(|k| template_curve.arc_fraction(k, template_corners)).collect();
        // Both orientations of the character's arcs; keep the one nearer the template's rim.
        let candidates: Vec<Vec<Vec3>> = [true, false]
            .iter()
            .map(|&same| fractions.iter().map(|&(forward, f)| character_curve.on_arc(forward == same, f, character_corners)).collect())
            .collect();
        let spread = |points: &Vec<Vec3>| points.iter().zip(&template_curve.points).map(|(a, b)| length(sub(*a, *b)).powi(2)).sum::<f64>();
        let best = if spread(&candidates[0]) <= spread(&candidates[1]) { &candidates[0] } else { &candidates[1] };
        targets.extend(walk.iter().zip(best).map(|(&vertex, &target)| RimTarget { vertex, target }));
        paired.push(HoleMatch {
            template_vertex: walk[0],
            template_rim: walk.len(),
            character_vertex: character_walk[0],
            character_rim: character_walk.len(),
            lids: false,
        });
    }
    (targets, paired)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A flat disc of `rings` rings around a hole of `n` rim vertices on an ellipse (radii
    /// `a`, `b`), rotated by `phase` along the rim, with an outer boundary of radius 10 (not a
    /// hole against the mesh's size): (points, triangles, the rim's vertex indices).
    fn holed_disc(n: usize, a: f64, b: f64, phase: f64, rings: usize) -> (Vec<Vec3>, Vec<[u32; 3]>, Vec<u32>) {
        let mut points = Vec::new();
        for r in 0..=rings {
            let grow = r as f64 / rings as f64;
            for k in 0..n {
                let angle = phase + std::f64::consts::TAU * k as f64 / n as f64;
                let (ra, rb) = (a + grow * (10.0 - a), b + grow * (10.0 - b));
                points.push([ra * angle.cos(), rb * angle.sin(), 0.0]);
            }
        }
        let mut triangles = Vec::new();
        for r in 0..rings {
            for k in 0..n {
                let (i, j) = ((r * n + k) as u32, (r * n + (k + 1) % n) as u32);
                let (oi, oj) = (i + n as u32, j + n as u32);
                triangles.push([i, oi, j]);
                triangles.push([j, oi, oj]);
            }
        }
        (points, triangles, (0..n as u32).collect())
    }

    #[test]
    fn loops_of_a_holed_disc_are_its_rim_and_its_edge_in_order() {
        let (points, triangles, rim) = holed_disc(12, 1.0, 0.5, 0.0, 3);
        let loops = boundary_loops(&triangles);
        assert_eq!(loops.len(), 2);
        let inner = loops.iter().find(|l| l.contains(&0)).expect("the rim is a loop");
        let mut sorted = inner.clone();
        sorted.sort();
        assert_eq!(sorted, rim);
        // Consecutive vertices of the walk are neighbours on the rim.
        for (k, &v) in inner.iter().enumerate() {
            let w = inner[(k + 1) % inner.len()];
            assert!(length(sub(points[v as usize], points[w as usize])) < 0.6, "{v} -> {w}");
        }
    }

    /// A template rim of 12 vertices onto a character rim of 17 (another vertex count, turned
    /// along the rim, a little larger): every target lies on the character's ellipse, the
    /// corners land on the corners, and the targets keep the template's spacing (no bunching):
    /// each target is where the same arc fraction of the same half of the ellipse is.
    #[test]
    fn rim_targets_follow_arc_length_from_corner_to_corner() {
        let (template, template_triangles, _) = holed_disc(12, 1.0, 0.5, 0.0, 3);
        let (character, character_triangles, _) = holed_disc(17, 1.2, 0.55, 0.3, 3);
        let skin: Vec<u32> = (0..template.len() as u32).collect();
        let character_skin: Vec<u32> = (0..character.len() as u32).collect();
        let (targets, paired) = rim_targets(&template, &template_triangles, &skin, &character, &character_triangles, &character_skin);
        assert_eq!(paired.len(), 1);
        assert_eq!(targets.len(), 12);
        let on_polygon = |p: Vec3| {
            // On one of the character rim's chords.
            (0..17).any(|k| {
                let (a, b) = (character[k], character[(k + 1) % 17]);
                let ab = sub(b, a);
                let t = (dot(sub(p, a), ab) / dot(ab, ab)).clamp(0.0, 1.0);
                length(sub(add(a, scale(ab, t)), p)) < 1e-9
            })
        };
        for t in &targets {
            assert!(on_polygon(t.target), "{:?} is off the character's rim", t.target);
        }
        // The template's corners (vertices 0 and 6, at x = +-1) go to the character rim's
        // extreme points in x.
        let extreme = |sign: f64| character[..17].iter().copied().max_by(|a, b| (sign * a[0]).total_cmp(&(sign * b[0]))).unwrap();
        let target_of = |v: u32| targets.iter().find(|t| t.vertex == v).unwrap().target;
        assert!(length(sub(target_of(0), extreme(1.0))) < 1e-9);
        assert!(length(sub(target_of(6), extreme(-1.0))) < 1e-9);
        // Between corners the targets are evenly spread (the template's vertices are evenly
        // spread in angle, so nearly in arc length): no two neighbours' targets much closer
        // than the rest.
        let gaps: Vec<f64> = (0..12).map(|k| length(sub(target_of(k), target_of((k + 1) % 12)))).collect();
        let (shortest, longest) = gaps.iter().fold((f64::INFINITY, 0.0f64), |(lo, hi), &g| (lo.min(g), hi.max(g)));
        assert!(longest < 2.5 * shortest, "{gaps:?}");
    }

    #[test]
    fn a_hole_without_a_match_gives_no_targets() {
        let (template, template_triangles, _) = holed_disc(12, 1.0, 0.5, 0.0, 3);
        // The character's hole is 2.5 times as large: not the same hole.
        let (character, character_triangles, _) = holed_disc(12, 2.5, 1.25, 0.0, 3);
        let all = |n: usize| (0..n as u32).collect::<Vec<u32>>();
        let (targets, paired) = rim_targets(&template, &template_triangles, &all(template.len()), &character, &character_triangles, &all(character.len()));
        assert_eq!((targets.len(), paired.len()), (0, 0));
    }
}
