//! Bilateral symmetry of the wrap (beyond method, section 5): a symmetric template wrapped onto a
//! symmetric character gives Left/Right keys that mirror each other, and self-symmetric keys
//! that stay symmetric.
//!
//! Three parts, each needed (docs/design_wrap.md, has the numbers):
//! - **The template's mirror map** is Analyze Rig's ([`MirrorMap`], method, section 0: each
//!   vertex's nearest vertex to its image across a coordinate plane, within 1e-3 of the
//!   diagonal), on the first axis that covers the skin ([`template_mirror`]).
//! - **The character's mirror plane** is the template's plane carried by the alignment, then
//!   refined on the character's own surface ([`refine_plane`]: each skin vertex's image is
//!   matched with the closest surface point, and the plane refitted to those pairs, an ICP on
//!   the reflection). The character is any topology, so its mirror map is a surface map: each
//!   vertex's image as a point on its surface ([`SurfaceMirror`]), which is the vertex map when
//!   the character's topology is symmetric. A character is symmetric when both maps cover at
//!   least [`MIN_COVERAGE`] of the skin; otherwise nothing here applies and the report says why.
//! - **Fit and carry averaged with their mirror**: the fit is projected onto the symmetric
//!   positions after every solve ([`symmetrize`]), the point pairs gain their mirror images;
//!   each carried shape is averaged with the mirror of its partner's carry (a self-symmetric
//!   shape with its own mirror, [`average_with_mirror`], [`MIRROR_AVERAGE_ROUNDS`] times)
//!   before the carry's collision pass.
//!   The fit alone is not enough: the character's triangles are not mirrored, so each side's
//!   carry samples the wrapped template differently.

use rayon::prelude::*;

use crate::geometry::closest_point::SurfacePoint;
use crate::geometry::mat3::{add, dot, length, scale, sub, Vec3};
use crate::geometry::mirror::MirrorMap;

use super::nricp::TargetSurface;

/// The template's vertex mirror tolerance, of its bbox diagonal (Analyze Rig's, method, section 0).
pub const TEMPLATE_TOLERANCE: f64 = 1e-3;
/// A character vertex whose mirror image lies within this fraction of the diagonal of the
/// character's surface is matched (the surface map's tolerance: on Character_YoungWoman, a
/// symmetric head decimated to 45%, 99% of the vertices' images lie within 1.1e-3).
pub const SURFACE_TOLERANCE: f64 = 2e-3;
/// Template and character are symmetric when their maps cover at least this fraction of the
/// skin's vertices.
pub const MIN_COVERAGE: f64 = 0.9;
/// The mirror test (method, section 0)'s tolerance, `|M D_i - D_j| / max(|D_i|, |D_j|)`, for the shapes'
/// pairs on the wrapped template.
pub const PAIR_TOLERANCE: f64 = 0.25;
/// Times each carried shape is averaged with its partner's mirror ([`average_with_mirror`]).
/// The surface mirror interpolates across triangles that are not mirrored, so mirroring twice
/// is not the identity and one average leaves `(d - M M d) / 2`, largest where the motion
/// changes within a triangle (a rolled lip's margin); each average shrinks what is left.
/// Measured (`scripts/bench_wrap.py`, largest worst-vertex miss / keys' error; once, twice,
/// three times): 25k 18.0% / 1.396e-3, 10.0% / 1.409e-3, 5.5% / 1.384e-3; 10k 9.7%, 7.0%, 5.4%
/// (error 1.467-1.469e-3); sample 21.2% / 1.742e-3, 10.2% / 1.751e-3, 9.4% / 1.763e-3. Three
/// times tipped the decimated identity's mouthPucker from proposed pairs (plain carry 1.5 cm
/// beyond the template's) into a twelve-solve pass twice as far from the truth (keys from
/// proposed pairs +7.0%, +8.0%, +10.1% over hand pairs; `blender_tests/test_wrap_pairs.py`).
pub const MIRROR_AVERAGE_ROUNDS: usize = 2;
/// Rounds of the plane's refinement at most: a turned plane slides its matches along the
/// surface and comes back a little each round (the 25k bench character: 0.5 degrees off
/// after 10 rounds, 87% covered; within 0.2 degrees, 100%, from a nearer start).
const REFINE_ROUNDS: usize = 40;

/// A plane a mesh is mirrored across, in the character's space.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct MirrorPlane {
    pub point: Vec3,
    /// Unit.
    pub normal: Vec3,
}

impl MirrorPlane {
    pub fn reflect(&self, p: Vec3) -> Vec3 {
        add(self.reflect_vector(sub(p, self.point)), self.point)
    }

    /// The reflection's linear part, for deltas and normals.
    pub fn reflect_vector(&self, v: Vec3) -> Vec3 {
        sub(v, scale(self.normal, 2.0 * dot(v, self.normal)))
    }

    /// The plane across which each `(p, q)` are best mirror images in least squares: the
    /// normal along the principal direction of the differences `p - q`, through the mean of
    /// the midpoints. `None` without a pair apart.
    pub fn fitted(pairs: &[(Vec3, Vec3)]) -> Option<Self> {
        let differences: Vec<Vec3> = pairs.iter().map(|(p, q)| sub(*p, *q)).collect();
        let mut scatter = [[0.0; 3]; 3];
        for d in &differences {
            for r in 0..3 {
                for c in 0..3 {
                    scatter[r][c] += d[r] * d[c];
                }
            }
        }
        let mut normal = *differences.iter().max_by(|a, b| length(**a).total_cmp(&length(**b)))?;
        for _ in 0..64 {
            let next = crate::geometry::mat3::mat_vec(&scatter, normal);
            let norm = length(next);
            if norm == 0.0 {
                return None;
            }
            normal = scale(next, 1.0 / norm);
        }
        let count = pairs.len() as f64;
        let point = pairs.iter().fold([0.0; 3], |acc, (p, q)| add(acc, scale(add(*p, *q), 0.5 / count)));
        Some(Self { point, normal })
    }

    /// The plane of a mesh whose vertex `v` mirrors to `partner[v]` (vertices `used` only).
    pub fn of_partners(points: &[Vec3], partner: &[Option<u32>], used: &[bool]) -> Option<Self> {
        let pairs: Vec<(Vec3, Vec3)> = (0..points.len())
            .filter_map(|v| partner[v].filter(|&m| used[v] && used[m as usize]).map(|m| (points[v], points[m as usize])))
            .collect();
        Self::fitted(&pairs)
    }
}

/// The template's mirror map and the share of its skin it covers.
pub struct TemplateMirror {
    pub axis: usize,
    pub partner: Vec<Option<u32>>,
    pub coverage: f64,
}

/// Analyze Rig's mirror map on the first axis (X, Y, Z) covering [`MIN_COVERAGE`] of the
/// skin (`is_skin`), else the best covering one.
pub fn template_mirror(points: &[[f32; 3]], is_skin: &[bool]) -> TemplateMirror {
    let skin = is_skin.iter().filter(|&&s| s).count().max(1) as f64;
    let mut best: Option<TemplateMirror> = None;
    for axis in 0..3 {
        let map = MirrorMap::new(points, axis, TEMPLATE_TOLERANCE);
        let covered = (0..points.len()).filter(|&v| is_skin[v] && map.partner[v].is_some_and(|m| is_skin[m as usize])).count();
        let found = TemplateMirror { axis, partner: map.partner, coverage: covered as f64 / skin };
        if found.coverage >= MIN_COVERAGE {
            return found;
        }
        if best.as_ref().is_none_or(|b| found.coverage > b.coverage) {
            best = Some(found);
        }
    }
    best.expect("three axes tried")
}

/// `plane` refined on a surface (`surface`) by matching each of `points` with the closest
/// surface point to its image and refitting the plane to those pairs; a match farther than 5%
/// of `diagonal` at first, half that each round (down to twice [`SURFACE_TOLERANCE`]), or on
/// the surface's open boundary (an image past a cut-off neck) is left out. With the share of
/// `points` whose image lies within [`SURFACE_TOLERANCE`] of the surface.
pub fn refine_plane(plane: MirrorPlane, points: &[Vec3], surface: &TargetSurface, diagonal: f64) -> (MirrorPlane, f64) {
    let mut plane = plane;
    let images = |plane: &MirrorPlane, reach: f64| -> Vec<Option<SurfacePoint>> {
        points.par_iter().map(|p| surface.bvh.closest_point(&plane.reflect(*p), reach * diagonal)).collect()
    };
    for round in 0..REFINE_ROUNDS {
        let reach = (0.05 * 0.5f64.powi(round as i32)).max(2.0 * SURFACE_TOLERANCE);
        let pairs: Vec<(Vec3, Vec3)> = points
            .iter()
            .zip(images(&plane, reach))
            .filter_map(|(p, hit)| hit.filter(|h| !surface.on_boundary(h)).map(|h| (*p, h.point)))
            .collect();
        let Some(next) = MirrorPlane::fitted(&pairs) else { break };
        let moved = (1.0 - dot(next.normal, plane.normal).abs()) + (dot(sub(next.point, plane.point), next.normal) / diagonal).abs();
        plane = next;
        if round >= 4 && moved < 1e-9 {
            break;
        }
    }
    let tolerance = (SURFACE_TOLERANCE * diagonal).powi(2);
    let covered = images(&plane, 0.05).iter().filter(|hit| hit.is_some_and(|h| h.distance_squared <= tolerance)).count();
    (plane, covered as f64 / points.len().max(1) as f64)
}

/// Each vertex's mirror image on the mesh's own surface (`None` beyond [`SURFACE_TOLERANCE`]).
pub struct SurfaceMirror<'a> {
    pub plane: MirrorPlane,
    pub images: Vec<Option<SurfacePoint>>,
    pub triangles: &'a [[u32; 3]],
}

impl SurfaceMirror<'_> {
    /// The field mirrored at vertex `v`: the reflected field at `v`'s image.
    pub fn mirrored(&self, field: &[Vec3], v: usize) -> Option<Vec3> {
        let hit = self.images[v]?;
        let t = self.triangles[hit.triangle as usize];
        Some(self.plane.reflect_vector((0..3).fold([0.0; 3], |acc, i| add(acc, scale(field[t[i] as usize], hit.barycentric[i])))))
    }

    /// Whether the image of `v` lies on vertices static in a shape (`is_static`).
    fn image_static(&self, is_static: &[bool], v: usize) -> bool {
        let Some(hit) = self.images[v] else { return true };
        let t = self.triangles[hit.triangle as usize];
        (0..3).all(|i| hit.barycentric[i] <= 1e-9 || is_static[t[i] as usize])
    }
}

/// Each connected piece's mirror piece across `plane`: of the pieces within a factor of 2 of its
/// vertex count, the one whose centroid lies nearest its reflected centroid (itself for the
/// skin and for a piece the plane cuts, as the teeth; the left eye's is the right eye). A
/// vertex's image is looked for on its piece's mirror only: by closest point alone a few
/// vertices (2 on the 10k bench character) found it on a neighbouring piece that stays still
/// where theirs moves, so the jaw shapes read a 100% worst-vertex miss and their average with
/// the mirror halved those vertices' motion.
pub fn mirror_pieces(points: &[Vec3], piece: &[u32], n_pieces: usize, plane: &MirrorPlane) -> Vec<u32> {
    let mut sum = vec![[0.0; 3]; n_pieces];
    let mut count = vec![0usize; n_pieces];
    for (p, &k) in points.iter().zip(piece) {
        sum[k as usize] = add(sum[k as usize], *p);
        count[k as usize] += 1;
    }
    let centroid: Vec<Vec3> = sum.iter().zip(&count).map(|(s, &n)| scale(*s, 1.0 / n.max(1) as f64)).collect();
    (0..n_pieces)
        .map(|k| {
            let image = plane.reflect(centroid[k]);
            let alike = |q: &usize| 2 * count[*q].min(count[k]) >= count[*q].max(count[k]);
            (0..n_pieces)
                .filter(alike)
                .min_by(|&a, &b| length(sub(centroid[a], image)).total_cmp(&length(sub(centroid[b], image))))
                .unwrap_or(k) as u32
        })
        .collect()
}

/// The positions averaged with their mirror, `x_v <- (x_v + R x_{m(v)}) / 2` for every vertex
/// `used` whose partner is `used` (a vertex on the plane is its own partner: projected onto it).
pub fn symmetrize(positions: &mut [Vec3], partner: &[Option<u32>], used: &[bool], plane: &MirrorPlane) {
    let before = positions.to_vec();
    for (v, p) in positions.iter_mut().enumerate() {
        if let Some(m) = partner[v].filter(|&m| used[v] && used[m as usize]) {
            *p = scale(add(before[v], plane.reflect(before[m as usize])), 0.5);
        }
    }
}

/// The shapes' mirror partners on a mesh with the vertex map `partner` across `plane`
/// (`deltas`: K x N, shape-major): `(i, j)`, `i < j`, for a pair passing the method's (section 0) mirror test
/// (greedy by smallest error, and smaller than each one's own mirror error), `(k, k)` for a
/// self-symmetric shape.
pub fn shape_partners(deltas: &[[f32; 3]], n: usize, partner: &[Option<u32>], plane: &MirrorPlane) -> Vec<(usize, usize)> {
    let k = if n == 0 { 0 } else { deltas.len() / n };
    let field = |s: usize| -> Vec<Vec3> { deltas[s * n..(s + 1) * n].iter().map(crate::geometry::mat3::to_f64).collect() };
    let fields: Vec<Vec<Vec3>> = (0..k).map(field).collect();
    let matched: Vec<usize> = (0..n).filter(|&v| partner[v].is_some()).collect();
    let norms: Vec<f64> = fields.iter().map(|f| matched.iter().map(|&v| dot(f[v], f[v])).sum::<f64>().sqrt()).collect();
    let error = |i: usize, j: usize| -> f64 {
        let largest = norms[i].max(norms[j]);
        if largest == 0.0 || (norms[i] - norms[j]).abs() > PAIR_TOLERANCE * largest {
            return f64::INFINITY;
        }
        let squared: f64 = matched
            .iter()
            .map(|&v| {
                let d = sub(plane.reflect_vector(fields[i][partner[v].unwrap() as usize]), fields[j][v]);
                dot(d, d)
            })
            .sum();
        squared.sqrt() / largest
    };
    let own: Vec<f64> = (0..k).into_par_iter().map(|i| error(i, i)).collect();
    let mut candidates: Vec<(f64, usize, usize)> = (0..k)
        .into_par_iter()
        .flat_map_iter(|i| ((i + 1)..k).map(move |j| (i, j)))
        .map(|(i, j)| (error(i, j), i, j))
        .filter(|&(e, i, j)| e < PAIR_TOLERANCE && e < own[i] && e < own[j])
        .collect();
    candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut taken = vec![false; k];
    let mut pairs = Vec::new();
    for (_, i, j) in candidates {
        if !taken[i] && !taken[j] {
            (taken[i], taken[j]) = (true, true);
            pairs.push((i, j));
        }
    }
    pairs.extend((0..k).filter(|&s| !taken[s] && own[s] < PAIR_TOLERANCE).map(|s| (s, s)));
    pairs.sort_unstable();
    pairs
}

/// The worst vertex's miss between the mirror of shape `a` and shape `b`, `max_v |M a - b|`,
/// relative to the larger of the two shapes' largest motions (0 when both are still).
pub fn worst_miss(a: &[Vec3], b: &[Vec3], mirrored: impl Fn(&[Vec3], usize) -> Option<Vec3>) -> f64 {
    let largest = a.iter().chain(b).map(|d| length(*d)).fold(0.0, f64::max);
    if largest == 0.0 {
        return 0.0;
    }
    (0..b.len()).filter_map(|v| mirrored(a, v).map(|m| length(sub(m, b[v])))).fold(0.0, f64::max) / largest
}

/// Each shape of the pairs `(i, j)` averaged with the mirror of the other's (a self-symmetric
/// `(k, k)` with its own), `d_i <- (d_i + M d_j) / 2`, at the vertices with an image; a vertex
/// static in `i` whose image is static in `j` stays static and zero.
pub fn average_with_mirror(deltas: &mut [Vec<Vec3>], is_static: &mut [Vec<bool>], pairs: &[(usize, usize)], mirror: &SurfaceMirror) {
    for &(i, j) in pairs {
        let (old_i, old_j) = (deltas[i].clone(), deltas[j].clone());
        let (static_i, static_j) = (is_static[i].clone(), is_static[j].clone());
        for (target, own, other, own_static, other_static) in
            [(i, &old_i, &old_j, &static_i, &static_j), (j, &old_j, &old_i, &static_j, &static_i)]
        {
            for v in 0..own.len() {
                let Some(image) = mirror.mirrored(other, v) else { continue };
                let still = own_static[v] && mirror.image_static(other_static, v);
                is_static[target][v] = still;
                deltas[target][v] = if still { [0.0; 3] } else { scale(add(own[v], image), 0.5) };
            }
            if i == j {
                break;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_piece_mirrors_onto_the_piece_of_its_size_nearest_its_reflected_centroid() {
        // Pieces: 0 the skin (on the plane), 1 / 2 the left / right eye, 3 the teeth (on the
        // plane, beside the skin), 4 a speck nearer the left eye's image than the right eye is,
        // too small to be its mirror.
        let plane = MirrorPlane { point: [0.0; 3], normal: [1.0, 0.0, 0.0] };
        let blob = |centre: Vec3, n: usize| -> Vec<Vec3> { (0..n).map(|i| add(centre, [0.01 * (i % 3) as f64, 0.01 * i as f64, 0.0])).collect() };
        let groups = [blob([0.0, 0.0, 0.0], 40), blob([-1.0, 1.0, 0.0], 10), blob([1.05, 1.0, 0.0], 11), blob([0.0, -0.5, 0.2], 8), blob([1.0, 1.0, 0.0], 2)];
        let (mut points, mut piece) = (Vec::new(), Vec::new());
        for (k, group) in groups.iter().enumerate() {
            points.extend(group);
            piece.extend(std::iter::repeat_n(k as u32, group.len()));
        }
        assert_eq!(mirror_pieces(&points, &piece, groups.len(), &plane), vec![0, 2, 1, 3, 4]);
    }

    #[test]
    fn a_plane_fitted_to_mirrored_points_is_their_plane() {
        let plane = MirrorPlane { point: [1.0, -2.0, 0.5], normal: { let n: Vec3 = [0.3, 0.9, -0.2]; scale(n, 1.0 / length(n)) } };
        let points: Vec<Vec3> = (0..50).map(|i| { let t = i as f64; [t.sin() * 3.0, (1.3 * t).cos() * 2.0, 0.1 * t] }).collect();
        let pairs: Vec<(Vec3, Vec3)> = points.iter().map(|p| (*p, plane.reflect(*p))).collect();
        let fitted = MirrorPlane::fitted(&pairs).unwrap();
        assert!(dot(fitted.normal, plane.normal).abs() > 1.0 - 1e-12, "{fitted:?}");
        assert!(dot(sub(fitted.point, plane.point), plane.normal).abs() < 1e-12, "{fitted:?}");
        for p in &points {
            assert!(length(sub(fitted.reflect(fitted.reflect(*p)), *p)) < 1e-12);
            assert!(length(sub(fitted.reflect(*p), plane.reflect(*p))) < 1e-9);
        }
    }
}
