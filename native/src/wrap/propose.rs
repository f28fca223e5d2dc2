//! Point pairs proposed, not clicked: the same named features (eye and mouth corners, nose tip,
//! chin) found on the template and on the character, so that Wrap works on a new character
//! with no click. Lid and lip centres, brows and the nose wings are not proposed: found the
//! same way they made the carried keys worse (docs/design_wrap.md, "Proposed pairs").
//!
//! How (geometry only on the character; the template's rig only tells where its face is):
//! 1. **The template's frame.** Front and up from the rig ([`find_front`]: where its shapes
//!    move and which way those regions face), the left-right axis from its symmetry plane
//!    ([`symmetry_plane`] refines the plane the mirror map found). Its eyes and mouth are
//!    first looked for around the motion of the shapes named for them (`blink`, `eye`, `lid`;
//!    `mouth`, `lip`), split by the symmetry plane into left and right.
//! 2. **The character's frame.** A similarity of the template's skin onto the character's
//!    skin by trimmed iterative closest points both ways (Besl & McKay 1992, each step
//!    Umeyama 1991), started with the template's symmetry plane on the character's (found
//!    like the template's, from the planes normal to its principal axes) and turned about
//!    its normal in steps, both ways round, the one ending closest kept; the template's front
//!    and up taken through it. Trimmed (the farthest [`TRIM`] of the pairs dropped) because
//!    the two necks end in different places.
//! 3. **The same rule on both meshes.** An *opening* (eye, mouth) is where the skin seen from
//!    the front ends: the *margin*, skin vertices facing the front that a ray towards it leaves
//!    free, whose neighbour is hidden (by the lid, the lips, the eyeball; or turned away, as
//!    the inner side of a parted lip) or which lie on an open boundary (a lid or lip hole).
//!    Around each opening's seed (on the character: where the aligned template's opening is)
//!    the margin's connected run nearest the seed among the wide ones is the opening, its
//!    lateral extremes the corners. The nose tip is the most frontal skin on the symmetry
//!    plane between the upper lip and the eyes; the chin the most frontal point of the
//!    midline profile under the hollow below the lower lip, found by where the profile's
//!    front outline bridges that hollow.
//! 4. A feature found on both meshes is a pair (template vertex, character vertex); one
//!    missing on either (a closed scan without openings) is left out and named.

use rayon::prelude::*;

use crate::error::ShapesmithResult;
use crate::geometry::bvh::TriangleBvh;
use crate::geometry::front::{find_front, outward_normals, region_centroid};
use crate::geometry::mat3::{add, cross, dot, length, mat_vec, scale, sub, to_f64, unit, Vec3};
use crate::geometry::topology::{boundary_edges, connected_components, Adjacency};
use crate::geometry::weld::{Weld, WeldedRig};
use crate::invalid;
use crate::progress::Progress;
use crate::rig::{bbox_diagonal, RigView};

use super::align::{similarity_from_pairs, symmetric_eigen, Similarity};
use super::skin_flags;

/// The farthest share of closest-point pairs dropped at each alignment step (necks cut at
/// different heights, a character with shoulders).
pub const TRIM: f64 = 0.25;
/// Points sampled over each skin by area for its moments, symmetry plane and alignment.
const SAMPLES: usize = 1500;
/// Alignment iterations per starting turn, then for the best one. A turn near the truth
/// converges slowly from 15 degrees off: after 4 steps a coarse avatar with its lids open
/// (1.4k vertices) ranked it 10th, behind the face turned down; after 8, second.
const SCREEN_ITERATIONS: usize = 8;
/// The turns about the character's symmetry-plane normal tried as starts, in degrees.
const TURN_STEP_DEGREES: f64 = 15.0;
const REFINE_ITERATIONS: usize = 30;
/// The screened starts refined further, the closest first (a margin over the second place
/// the truth took on that avatar).
const REFINED_STARTS: usize = 8;
/// Search radii around an opening's seed, fractions of the skin's bbox diagonal (an eye is
/// about 0.08 of a head's diagonal wide, a mouth 0.13).
const EYE_RADIUS: f64 = 0.1;
const MOUTH_RADIUS: f64 = 0.12;
/// A skin vertex faces the front when its normal's front component is over this.
const FACING: f64 = 0.1;
/// A piece is round (an eyeball) when its vertices' distances from its centre have a standard
/// deviation under this fraction of their mean (a sphere's: 0).
const ROUND_PIECE: f64 = 0.15;
/// A margin run is an opening's candidate when it is at least this fraction as wide as the
/// widest run around the seed (a closed mouth's lips against a fold's run 15% wider).
const WIDE_RUN: f64 = 0.5;
/// Half-width of the band about the symmetry plane the nose tip is looked for in.
const PLANE_BAND: f64 = 0.02;

/// Names of the template's shapes whose motion marks its eyes and its mouth.
const EYE_NAMES: [&str; 3] = ["blink", "eye", "lid"];
const MOUTH_NAMES: [&str; 2] = ["mouth", "lip"];

/// One proposed pair: the same feature on both meshes, as vertices (input numbering) and
/// their rest positions.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ProposedPair {
    pub name: String,
    pub template_vertex: u32,
    pub character_vertex: u32,
    pub template: [f32; 3],
    pub character: [f32; 3],
}

/// The proposal: the pairs, and the frames and alignment they were found in.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Proposal {
    pub pairs: Vec<ProposedPair>,
    /// Features found on one mesh only (or on neither), left out.
    pub missing: Vec<String>,
    /// The template's skin onto the character's (step 2) and where it ended: the mean trimmed
    /// distance, a fraction of the character's diagonal.
    pub similarity: Similarity,
    pub alignment_distance: f64,
    pub template_front: Vec3,
    pub template_up: Vec3,
    pub character_front: Vec3,
    pub character_up: Vec3,
    pub warnings: Vec<String>,
}

/// Proposes point pairs between the template (`rig`: its rest shape, keys and triangles, in
/// its own space) and the character (any topology, units and axes). Errors when the template
/// has no moving shape (its front is unknown) or either mesh has no faces.
pub fn propose_pairs(
    rig: &RigView,
    character: &[[f32; 3]],
    character_triangles: &[[u32; 3]],
    progress: &dyn Progress,
) -> ShapesmithResult<Proposal> {
    rig.validate()?;
    crate::rig::validate_points(character, "character")?;
    crate::rig::validate_triangle_indices(character.len(), character_triangles)?;
    if rig.triangles.is_empty() || character_triangles.is_empty() {
        return Err(invalid!("the template and the character both need faces"));
    }
    let welded_rig = WeldedRig::new(rig);
    let template_view = welded_rig.view();
    let template_front = find_front(&template_view, 0)?;
    let character_weld = Weld::new(character, character_triangles);
    let character_points: Vec<Vec3> = character_weld.gather(character).iter().map(to_f64).collect();
    let template_points: Vec<Vec3> = template_view.neutral.iter().map(to_f64).collect();
    let template_mesh = Mesh::new(template_points, &welded_rig.weld.triangles);
    let character_mesh = Mesh::new(character_points, &character_weld.triangles);
    progress.checkpoint(0.1)?;

    // 1. The template's frame and seeds.
    let lateral = unit(cross(template_front.up, template_front.front)).ok_or_else(|| invalid!("the template's front and up are parallel"))?;
    let start = template_front.lateral_axis.map_or(template_mesh.skin_centre(), |_| {
        let mut o = template_mesh.skin_centre();
        o = sub(o, scale(lateral, dot(o, lateral)));
        o
    });
    let (lateral, origin) = symmetry_plane(&template_mesh, lateral, start);
    let template_frame = Frame::new(origin, lateral, template_front.up, template_front.front);
    let seeds = rig_seeds(&template_view, &template_frame);
    let template_features = find_features(&template_mesh, &template_frame, &seeds);
    progress.checkpoint(0.3)?;

    // 2. The character's frame.
    let (similarity, alignment_distance) = align_skins(&template_mesh, &template_frame, &character_mesh, progress)?;
    let turn = |v: Vec3| unit(sub(similarity.apply(v), similarity.apply([0.0; 3]))).unwrap_or(v);
    let (character_lateral, character_origin) =
        symmetry_plane(&character_mesh, turn(template_frame.lateral), similarity.apply(template_frame.origin));
    let character_frame = Frame::new(character_origin, character_lateral, turn(template_frame.up), turn(template_frame.front));
    let moved = |p: Option<Vec3>| p.map(|p| similarity.apply(p));
    let character_seeds = Seeds {
        eyes: [moved(template_features.eye_centre(0, &template_mesh)), moved(template_features.eye_centre(1, &template_mesh))],
        mouth: moved(template_features.mouth_centre(&template_mesh)),
    };
    let character_features = find_features(&character_mesh, &character_frame, &character_seeds);
    progress.checkpoint(0.95)?;

    // 3. Pairs by name.
    let mut pairs = Vec::new();
    let mut missing = Vec::new();
    for (name, found) in template_features.named() {
        let other = character_features.named().into_iter().find(|(n, _)| *n == name).and_then(|(_, v)| v);
        match (found, other) {
            (Some(t), Some(c)) => {
                let (template_vertex, character_vertex) = (welded_rig.weld.vertex(t), character_weld.vertex(c));
                pairs.push(ProposedPair {
                    name: name.to_string(),
                    template_vertex,
                    character_vertex,
                    template: rig.neutral[template_vertex as usize],
                    character: character[character_vertex as usize],
                });
            }
            _ => missing.push(name.to_string()),
        }
    }
    let mut warnings = Vec::new();
    if !missing.is_empty() {
        warnings.push(format!("not found on both heads, so not proposed: {}", missing.join(", ")));
    }
    if alignment_distance > 0.02 {
        warnings.push(format!(
            "the template's skin ends {:.1}% of the diagonal from the character's after the alignment: check the proposed pairs",
            100.0 * alignment_distance
        ));
    }
    Ok(Proposal {
        pairs,
        missing,
        similarity,
        alignment_distance,
        template_front: template_frame.front,
        template_up: template_frame.up,
        character_front: character_frame.front,
        character_up: character_frame.up,
        warnings,
    })
}

/// A welded mesh with its skin (largest piece), neighbours, open boundary, normals and what
/// hides the skin from the front.
struct Mesh {
    points: Vec<Vec3>,
    is_skin: Vec<bool>,
    skin: Vec<u32>,
    skin_triangles: Vec<[u32; 3]>,
    on_boundary: Vec<bool>,
    adjacency: Adjacency,
    /// The skin and the round pieces (eyeballs): what hides skin from the front.
    occluders: TriangleBvh,
    /// Unit area-weighted vertex normals of the skin, outward.
    normals: Vec<Vec3>,
    diagonal: f64,
}

impl Mesh {
    fn new(points: Vec<Vec3>, triangles: &[[u32; 3]]) -> Self {
        let is_skin = skin_flags(points.len(), triangles);
        let skin: Vec<u32> = (0..points.len() as u32).filter(|&v| is_skin[v as usize]).collect();
        let skin_triangles: Vec<[u32; 3]> = triangles.iter().filter(|t| is_skin[t[0] as usize]).copied().collect();
        let mut on_boundary = vec![false; points.len()];
        for (a, b) in boundary_edges(&skin_triangles) {
            on_boundary[a as usize] = true;
            on_boundary[b as usize] = true;
        }
        let skin_f32: Vec<[f32; 3]> = skin.iter().map(|&v| points[v as usize].map(|x| x as f32)).collect();
        Self {
            adjacency: Adjacency::from_triangles(points.len(), &skin_triangles),
            occluders: TriangleBvh::build(&points, &occluders(&points, triangles, &is_skin)),
            normals: outward_normals(&points, &skin_triangles),
            diagonal: bbox_diagonal(&skin_f32),
            points,
            is_skin,
            skin,
            skin_triangles,
            on_boundary,
        }
    }

    fn skin_centre(&self) -> Vec3 {
        scale(self.skin.iter().fold([0.0; 3], |acc, &v| add(acc, self.points[v as usize])), 1.0 / self.skin.len().max(1) as f64)
    }

    /// About `count` points spread over the skin by area, whatever its vertices' layout: the
    /// k-th at cumulative area `(k + 1/2) / count` of the whole (triangles in order), inside
    /// its triangle at the k-th point of the R2 sequence (Roberts 2018: fractional parts of
    /// `1/2 + k a`, `a` = (1/g, 1/g^2) for the plastic number g), folded into the triangle.
    fn samples(&self, count: usize) -> Vec<Vec3> {
        let area = |t: &[u32; 3]| {
            let [a, b, c] = t.map(|v| self.points[v as usize]);
            0.5 * length(cross(sub(b, a), sub(c, a)))
        };
        let mut cumulative = Vec::with_capacity(self.skin_triangles.len());
        let mut total = 0.0;
        for t in &self.skin_triangles {
            total += area(t);
            cumulative.push(total);
        }
        if !(total > 0.0) {
            return self.skin.iter().map(|&v| self.points[v as usize]).collect();
        }
        const R2: [f64; 2] = [0.754_877_666_246_692_7, 0.569_840_290_998_053_2];
        (0..count)
            .map(|k| {
                let at = (k as f64 + 0.5) / count as f64 * total;
                let t = cumulative.partition_point(|&c| c < at).min(cumulative.len() - 1);
                let [a, b, c] = self.skin_triangles[t].map(|v| self.points[v as usize]);
                let [mut u, mut w] = R2.map(|r| (0.5 + r * k as f64).fract());
                if u + w > 1.0 {
                    (u, w) = (1.0 - u, 1.0 - w);
                }
                add(a, add(scale(sub(b, a), u), scale(sub(c, a), w)))
            })
            .collect()
    }

    /// Skin vertices a ray towards `front` leaves free (no triangle of the skin or of a round
    /// piece ahead),
    /// and facing it (its normal within [`FACING`] of perpendicular or nearer: the inner side of
    /// a lip or lid, rolled away, is not seen even through a parted mouth).
    fn visible(&self, front: Vec3) -> Vec<bool> {
        let offset = 1e-5 * self.diagonal;
        (0..self.points.len())
            .map(|v| {
                self.is_skin[v]
                    && dot(self.normals[v], front) > FACING
                    && !self.occluders.any_hit(&add(self.points[v], scale(front, offset)), &front, f64::INFINITY)
            })
            .collect()
    }

    /// The margin: visible skin vertices next to a hidden skin vertex or on the open boundary.
    fn margin(&self, front: Vec3) -> Vec<bool> {
        let visible = self.visible(front);
        (0..self.points.len())
            .map(|v| {
                visible[v]
                    && (self.on_boundary[v] || self.adjacency.neighbours(v).iter().any(|&w| self.is_skin[w as usize] && !visible[w as usize]))
            })
            .collect()
    }
}

/// The triangles of the skin and of every round piece (an eyeball: its vertices' distances
/// from its centre vary by under [`ROUND_PIECE`] of their mean): lashes hang in front of the
/// lids without being where a lid ends, and teeth sit behind skin that hides or faces away.
fn occluders(points: &[Vec3], triangles: &[[u32; 3]], is_skin: &[bool]) -> Vec<[u32; 3]> {
    let (label, count) = connected_components(points.len(), triangles);
    let mut members: Vec<Vec<Vec3>> = vec![Vec::new(); count];
    for (v, &l) in label.iter().enumerate() {
        members[l as usize].push(points[v]);
    }
    let round: Vec<bool> = members
        .iter()
        .map(|piece| {
            let n = piece.len().max(1) as f64;
            let centre = scale(piece.iter().fold([0.0; 3], |acc, p| add(acc, *p)), 1.0 / n);
            let distances: Vec<f64> = piece.iter().map(|p| length(sub(*p, centre))).collect();
            let mean = distances.iter().sum::<f64>() / n;
            let spread = (distances.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / n).sqrt();
            piece.len() >= 8 && spread < ROUND_PIECE * mean
        })
        .collect();
    triangles.iter().filter(|t| is_skin[t[0] as usize] || round[label[t[0] as usize] as usize]).copied().collect()
}

/// An orthonormal frame: `x` to the left (`up x front`), `y` up, `z` to the front.
#[derive(Clone, Copy, Debug)]
struct Frame {
    origin: Vec3,
    lateral: Vec3,
    up: Vec3,
    front: Vec3,
}

impl Frame {
    /// From the symmetry plane's normal `lateral` and rough `up` and `front`: the front made
    /// perpendicular to the plane, up = front x lateral, both flipped with the normal when that
    /// up points down (so that `x` points to the left whichever way the normal pointed).
    fn new(origin: Vec3, lateral: Vec3, up: Vec3, front: Vec3) -> Self {
        let front = unit(sub(front, scale(lateral, dot(front, lateral)))).unwrap_or(front);
        let (mut lateral, mut plane_up) = (lateral, cross(front, lateral));
        if dot(plane_up, up) < 0.0 {
            lateral = scale(lateral, -1.0);
            plane_up = scale(plane_up, -1.0);
        }
        Self { origin, lateral, up: plane_up, front }
    }

    fn local(&self, p: Vec3) -> Vec3 {
        let d = sub(p, self.origin);
        [dot(d, self.lateral), dot(d, self.up), dot(d, self.front)]
    }
}

/// The mirror plane of a mesh's skin near (`normal`, through `origin`): each sample
/// reflected, its closest skin point found, and the plane re-fitted as the one that best
/// swaps each pair (normal: the principal direction of the pairs' differences; origin: the
/// mean of their midpoints), ten times.
fn symmetry_plane(mesh: &Mesh, normal: Vec3, origin: Vec3) -> (Vec3, Vec3) {
    let surface = TriangleBvh::build(&mesh.points, &mesh.skin_triangles);
    let samples = mesh.samples(SAMPLES);
    let (mut normal, mut origin) = (normal, origin);
    for _ in 0..10 {
        let mut spread = [[0.0; 3]; 3];
        let (mut middle, mut count) = ([0.0; 3], 0.0);
        for &p in &samples {
            let reflected = sub(p, scale(normal, 2.0 * dot(sub(p, origin), normal)));
            let Some(hit) = surface.closest_point(&reflected, 0.05 * mesh.diagonal) else { continue };
            let d = sub(p, hit.point);
            for r in 0..3 {
                for c in 0..3 {
                    spread[r][c] += d[r] * d[c];
                }
            }
            middle = add(middle, scale(add(p, hit.point), 0.5));
            count += 1.0;
        }
        let Ok((_, vectors)) = symmetric_eigen(&spread) else { break };
        let found = [vectors[0][2], vectors[1][2], vectors[2][2]];
        if count < 10.0 || !found.iter().all(|x| x.is_finite()) {
            break;
        }
        normal = if dot(found, normal) < 0.0 { scale(found, -1.0) } else { found };
        origin = scale(middle, 1.0 / count);
    }
    (normal, origin)
}

/// Where the template's eyes and mouth are, from its rig: the motion-weighted centre of the
/// shapes named for each, the eyes' split by the symmetry plane.
struct Seeds {
    /// Left (`x > 0`), right.
    eyes: [Option<Vec3>; 2],
    mouth: Option<Vec3>,
}

fn rig_seeds(rig: &RigView, frame: &Frame) -> Seeds {
    // One side of the plane for each eye, both for the mouth.
    let centroid = |words: &[&str], side: Option<f64>| {
        region_centroid(rig, words, |p| !side.is_some_and(|s| s * frame.local(p)[0] <= 0.0))
    };
    Seeds { eyes: [centroid(&EYE_NAMES, Some(1.0)), centroid(&EYE_NAMES, Some(-1.0))], mouth: centroid(&MOUTH_NAMES, None) }
}

/// An opening's corners (welded vertices): inner then outer for an eye, right then left for
/// the mouth.
#[derive(Clone, Copy, Debug, Default)]
struct Opening {
    corners: [u32; 2],
}

#[derive(Debug, Default)]
struct Features {
    eyes: [Option<Opening>; 2],
    mouth: Option<Opening>,
    nose_tip: Option<u32>,
    chin: Option<u32>,
}

const SIDES: [&str; 2] = ["left", "right"];

impl Features {
    fn eye_centre(&self, side: usize, mesh: &Mesh) -> Option<Vec3> {
        self.eyes[side].map(|e| scale(add(mesh.points[e.corners[0] as usize], mesh.points[e.corners[1] as usize]), 0.5))
    }

    fn mouth_centre(&self, mesh: &Mesh) -> Option<Vec3> {
        self.mouth.map(|m| scale(add(mesh.points[m.corners[0] as usize], mesh.points[m.corners[1] as usize]), 0.5))
    }

    /// Every feature by name, found or not, in one order for both meshes.
    fn named(&self) -> Vec<(String, Option<u32>)> {
        let mut out = Vec::new();
        for (s, side) in SIDES.iter().enumerate() {
            out.push((format!("eye corner inner {side}"), self.eyes[s].map(|e| e.corners[0])));
            out.push((format!("eye corner outer {side}"), self.eyes[s].map(|e| e.corners[1])));
        }
        out.push(("mouth corner left".into(), self.mouth.map(|m| m.corners[1])));
        out.push(("mouth corner right".into(), self.mouth.map(|m| m.corners[0])));
        out.push(("nose tip".into(), self.nose_tip));
        out.push(("chin".into(), self.chin));
        out
    }
}

/// The features of one mesh in its frame, its openings looked for around `seeds`.
fn find_features(mesh: &Mesh, frame: &Frame, seeds: &Seeds) -> Features {
    let margin = mesh.margin(frame.front);
    let local: Vec<Vec3> = mesh.points.iter().map(|&p| frame.local(p)).collect();
    let mut features = Features::default();
    for s in 0..2 {
        let sign = if s == 0 { 1.0 } else { -1.0 };
        features.eyes[s] = seeds.eyes[s].and_then(|seed| {
            let near: Vec<u32> = candidates(mesh, &margin, seed, EYE_RADIUS).into_iter().filter(|&v| sign * local[v as usize][0] > 0.0).collect();
            // Inner corner first: the one nearer the symmetry plane.
            opening(mesh, &local, &near, frame.local(seed)).map(|o| if sign > 0.0 { o } else { Opening { corners: [o.corners[1], o.corners[0]] } })
        });
    }
    features.mouth = seeds.mouth.and_then(|seed| opening(mesh, &local, &candidates(mesh, &margin, seed, MOUTH_RADIUS), frame.local(seed)));
    let (Some(mouth), Some(left), Some(right)) = (features.mouth, features.eyes[0], features.eyes[1]) else { return features };
    let y = |v: u32| local[v as usize][1];
    let mouth_y = 0.5 * (y(mouth.corners[0]) + y(mouth.corners[1]));
    let eye_y = 0.25 * (y(left.corners[0]) + y(left.corners[1]) + y(right.corners[0]) + y(right.corners[1]));
    let width = local[mouth.corners[1] as usize][0] - local[mouth.corners[0] as usize][0];
    let band = PLANE_BAND * mesh.diagonal;
    let best = |keep: &dyn Fn(Vec3) -> bool, score: &dyn Fn(Vec3) -> f64| -> Option<u32> {
        mesh.skin.iter().copied().filter(|&v| keep(local[v as usize])).max_by(|&a, &b| score(local[a as usize]).total_cmp(&score(local[b as usize])))
    };
    // Above the upper lip (a fifth of the mouth's width over its corners) and below the eyes.
    let lip = mouth_y + 0.2 * width;
    features.nose_tip = best(&|p| p[0].abs() < band && p[1] > lip && p[1] < eye_y, &|p| p[2]);
    features.chin = chin(mesh, &local, mouth_y, 1.8 * width, 0.05 * width);
    features
}

/// The chin: on the skin's midline section (its cut by the symmetry plane, the front-most
/// point at each height; see [`midline_section`]) down from the mouth's corners (height
/// `start`) for `reach` in `bin`s of height, the front outline's bridge over the hollow under
/// the lower lip ([`lip_chin_bridge`]) lands on the chin's lower half: the chin is the point
/// between the hollow and that landing farthest in front of the line joining them (the top of
/// the chin's bulge, or of its curve where a decimation flattened the bulge); the skin vertex
/// nearest it. The bridge is a property of the curve, not of its vertices: the chin's own
/// bulge past the hollow (a local maximum of depth) is often under a hundredth of the mouth's
/// width high, and a decimation that flattened it left no chin.
fn chin(mesh: &Mesh, local: &[Vec3], start: f64, reach: f64, bin: f64) -> Option<u32> {
    let points: Vec<[f64; 2]> = midline_section(mesh, local, start, reach, bin).into_iter().flatten().collect();
    let (hollow, lands) = lip_chin_bridge(&points)?;
    let (p, q) = (points[hollow], points[lands]);
    let ahead = |r: [f64; 2]| (q[1] - p[1]) * (r[0] - p[0]) - (q[0] - p[0]) * (r[1] - p[1]);
    let [y, z] = points[hollow..=lands].iter().copied().max_by(|a, b| ahead(*a).total_cmp(&ahead(*b)))?;
    let at = [0.0, y, z];
    mesh.skin.iter().copied().min_by(|&a, &b| length(sub(local[a as usize], at)).total_cmp(&length(sub(local[b as usize], at))))
}

/// Of a profile (`[height, depth]` points, downwards), its front outline (the side of its
/// convex hull facing +depth: Andrew's monotone chain) and, of the outline's edges that skip
/// points (bridges), front-facing (rising less than 45 degrees from the vertical: not the
/// underside of the chin) and not ending at the profile's last point (the neck below the
/// chin), the one with the deepest point behind it (its distance from the edge's line):
/// returns that deepest point and the edge's lower end. Turning the profile turns its outline
/// with it, so the bridge does not hang on the frame's tilt, nor on where the section's
/// vertices fall.
fn lip_chin_bridge(points: &[[f64; 2]]) -> Option<(usize, usize)> {
    let mut outline: Vec<usize> = Vec::with_capacity(points.len());
    for i in 0..points.len() {
        while let [.., a, b] = outline[..] {
            let (p, q, r) = (points[a], points[b], points[i]);
            // q stays when it lies in front of the line from p to r (heights decrease).
            if (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0]) > 0.0 {
                break;
            }
            outline.pop();
        }
        outline.push(i);
    }
    // The point between a and b farthest behind the line through them, and that distance.
    let deepest = |a: usize, b: usize| {
        let (p, q) = (points[a], points[b]);
        let (dy, dz) = (q[0] - p[0], q[1] - p[1]);
        let norm = dy.hypot(dz);
        (a + 1..b).map(|i| ((dz * (points[i][0] - p[0]) - dy * (points[i][1] - p[1])).abs() / norm, i)).max_by(|x, y| x.0.total_cmp(&y.0))
    };
    let last = points.len().checked_sub(1)?;
    outline
        .windows(2)
        .filter(|w| w[1] > w[0] + 1 && w[1] < last && (points[w[1]][1] - points[w[0]][1]).abs() < (points[w[1]][0] - points[w[0]][0]).abs())
        .filter_map(|w| deepest(w[0], w[1]).map(|(depth, i)| (depth, i, w[1])))
        .filter(|(depth, _, _)| *depth > 0.0)
        .max_by(|x, y| x.0.total_cmp(&y.0))
        .map(|(_, hollow, lands)| (hollow, lands))
}

/// The skin's cut by the plane `x = 0` of `local`, from height `start` down for `reach`: per
/// `bin` of height, the front-most point (`[y, z]`) of the cut's segments spanning the bin's
/// middle, `None` where none does.
fn midline_section(mesh: &Mesh, local: &[Vec3], start: f64, reach: f64, bin: f64) -> Vec<Option<[f64; 2]>> {
    let count = (reach / bin).ceil() as usize;
    let mut front: Vec<Option<[f64; 2]>> = vec![None; count];
    for t in &mesh.skin_triangles {
        // Where the triangle's edges cross x = 0.
        let mut ends = Vec::with_capacity(2);
        for (a, b) in [(t[0], t[1]), (t[1], t[2]), (t[2], t[0])] {
            let (p, q) = (local[a as usize], local[b as usize]);
            if (p[0] < 0.0) != (q[0] < 0.0) {
                let f = p[0] / (p[0] - q[0]);
                ends.push([p[1] + f * (q[1] - p[1]), p[2] + f * (q[2] - p[2])]);
            }
        }
        let [a, b] = ends[..] else { continue };
        let (low, high) = if a[0] < b[0] { (a, b) } else { (b, a) };
        let first = ((start - high[0]) / bin - 0.5).ceil().max(0.0) as usize;
        for i in first..count {
            let y = start - (i as f64 + 0.5) * bin;
            if y < low[0] {
                break;
            }
            let f = if high[0] > low[0] { (y - low[0]) / (high[0] - low[0]) } else { 0.5 };
            let z = low[1] + f * (high[1] - low[1]);
            if front[i].is_none_or(|p| p[1] < z) {
                front[i] = Some([y, z]);
            }
        }
    }
    front
}

/// Margin vertices within `radius` (of the diagonal) of `seed`.
fn candidates(mesh: &Mesh, margin: &[bool], seed: Vec3, radius: f64) -> Vec<u32> {
    let reach = radius * mesh.diagonal;
    mesh.skin.iter().copied().filter(|&v| margin[v as usize] && length(sub(mesh.points[v as usize], seed)) < reach).collect()
}

/// The opening among `near` margin vertices: of their connected runs (through paths of one or
/// two skin edges) at least [`WIDE_RUN`] as wide laterally as the widest, the one whose centre
/// lies nearest `seed` (in `frame`); its lateral extremes are the corners (lowest `x` first).
/// The widest alone can be a fold: the hollow under the lower lip, hidden from the front by
/// the lip above it, runs wider than a closed mouth on an avatar whose lids are open holes.
fn opening(mesh: &Mesh, local: &[Vec3], near: &[u32], seed: Vec3) -> Option<Opening> {
    if near.len() < 3 {
        return None;
    }
    let index: std::collections::HashMap<u32, u32> = near.iter().enumerate().map(|(i, &v)| (v, i as u32)).collect();
    // Joined through two-edge paths: on a coarse mesh the upper and lower margins of an eye
    // may meet at the corners only through a vertex that is on neither.
    let mut edges: Vec<[u32; 3]> = Vec::new();
    for (i, &v) in near.iter().enumerate() {
        for &w in mesh.adjacency.neighbours(v as usize) {
            let two_ring = std::iter::once(w).chain(mesh.adjacency.neighbours(w as usize).iter().copied());
            edges.extend(two_ring.filter_map(|u| index.get(&u).map(|&j| [i as u32, j, j])));
        }
    }
    let (label, count) = connected_components(near.len(), &edges);
    let mut runs: Vec<Vec<u32>> = vec![Vec::new(); count];
    for (&v, &l) in near.iter().zip(&label) {
        runs[l as usize].push(v);
    }
    let x = |v: &u32| local[*v as usize][0];
    // Each run's lateral extremes, lowest `x` first.
    let ends = |run: &[u32]| Some((*run.iter().min_by(|a, b| x(a).total_cmp(&x(b)))?, *run.iter().max_by(|a, b| x(a).total_cmp(&x(b)))?));
    let width = |run: &[u32]| ends(run).map_or(0.0, |(low, high)| x(&high) - x(&low));
    let widest = runs.iter().map(|r| width(r)).fold(0.0, f64::max);
    let from_seed = |run: &[u32]| {
        let sum = run.iter().fold([0.0; 3], |sum, &v| add(sum, local[v as usize]));
        length(sub(scale(sum, 1.0 / run.len() as f64), seed))
    };
    let chosen = runs.iter().filter(|r| width(r) >= WIDE_RUN * widest).min_by(|a, b| from_seed(a).total_cmp(&from_seed(b)))?;
    let (low, high) = ends(chosen)?;
    (x(&high) > x(&low)).then_some(Opening { corners: [low, high] })
}

/// The similarity taking the template's skin (its symmetry plane `template_frame`) onto the
/// character's, and the mean trimmed distance it ends at (fraction of the character's
/// diagonal): the character's symmetry plane first (of the planes normal to its principal
/// axes, refined, the one its skin mirrors best onto itself), then every turn of the
/// template's frame about that plane's normal in [`TURN_STEP_DEGREES`] steps, both ways
/// round, each followed by a few ICP steps; the [`REFINED_STARTS`] closest refined further,
/// the closest after that kept.
fn align_skins(template: &Mesh, template_frame: &Frame, character: &Mesh, progress: &dyn Progress) -> ShapesmithResult<(Similarity, f64)> {
    let (character_centre, character_size, character_axes) = moments(character)?;
    let (_, template_size, _) = moments(template)?;
    if !(template_size > 0.0 && character_size > 0.0) {
        return Err(invalid!("the template or the character has all its skin at one point"));
    }
    let (normal, origin) = character_axes
        .iter()
        .map(|&axis| symmetry_plane(character, axis, character_centre))
        .min_by(|a, b| mirror_distance(character, a.0, a.1).total_cmp(&mirror_distance(character, b.0, b.1)))
        .ok_or_else(|| invalid!("the character's symmetry plane could not be found"))?;
    let template_samples = template.samples(SAMPLES);
    let character_samples = character.samples(SAMPLES);
    let target = TriangleBvh::build(&character.points, &character.skin_triangles);
    let template_skin = TriangleBvh::build(&template.points, &template.skin_triangles);
    let s = character_size / template_size;
    let helper = if normal[0].abs() < 0.9 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
    let (f, u, l) = (template_frame.front, template_frame.up, template_frame.lateral);
    let steps = (360.0 / TURN_STEP_DEGREES).round() as usize;
    let mut starts = Vec::with_capacity(2 * steps);
    for sign in [1.0, -1.0] {
        let lateral = scale(normal, sign);
        let b1 = unit(cross(lateral, helper)).unwrap_or(helper);
        let b2 = cross(lateral, b1);
        for step in 0..steps {
            let angle = (step as f64 * TURN_STEP_DEGREES).to_radians();
            let up = add(scale(b1, angle.cos()), scale(b2, angle.sin()));
            let front = cross(lateral, up);
            // R = [up front lateral] [u f l]^T: the template's frame onto this one.
            let rotation: [[f64; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| up[r] * u[c] + front[r] * f[c] + lateral[r] * l[c]));
            starts.push(Similarity { rotation, scale: s, translation: sub(origin, scale(mat_vec(&rotation, template_frame.origin), s)) });
        }
    }
    // The starts are independent: screened side by side, a batch per checkpoint.
    let icp = |start: Similarity, iterations: usize| trimmed_icp(&template_skin, &template_samples, &character_samples, &target, start, iterations);
    let mut screened: Vec<(Similarity, f64)> = Vec::with_capacity(starts.len());
    let batch = 2 * rayon::current_num_threads();
    for chunk in starts.chunks(batch) {
        screened.extend(chunk.par_iter().map(|&start| icp(start, SCREEN_ITERATIONS)).collect::<Vec<_>>());
        progress.checkpoint(0.3 + 0.4 * screened.len() as f64 / starts.len() as f64)?;
    }
    // The few closest screened starts refined: a few steps rank the turns only roughly.
    screened.sort_by(|a, b| a.1.total_cmp(&b.1));
    let refined: Vec<(Similarity, f64)> =
        screened.into_par_iter().take(REFINED_STARTS).map(|(start, _)| icp(start, REFINE_ITERATIONS)).collect();
    // The first of the closest, as a serial run would keep it.
    let best = refined.into_iter().reduce(|best, next| if next.1 < best.1 { next } else { best });
    progress.checkpoint(0.8)?;
    let (motion, distance) = best.ok_or_else(|| invalid!("the template's skin could not be aligned with the character's"))?;
    Ok((motion, distance / character.diagonal))
}

/// Centre, root-mean-square radius and principal axes (unit) of a mesh's skin (its samples).
fn moments(mesh: &Mesh) -> ShapesmithResult<(Vec3, f64, [Vec3; 3])> {
    let points = mesh.samples(SAMPLES);
    let centre = scale(points.iter().fold([0.0; 3], |acc, p| add(acc, *p)), 1.0 / points.len().max(1) as f64);
    let mut covariance = [[0.0; 3]; 3];
    for p in &points {
        let d = sub(*p, centre);
        for r in 0..3 {
            for c in 0..3 {
                covariance[r][c] += d[r] * d[c] / points.len() as f64;
            }
        }
    }
    let (values, vectors) = symmetric_eigen(&covariance)?;
    Ok((centre, values.iter().sum::<f64>().sqrt(), [0, 1, 2].map(|k| [vectors[0][k], vectors[1][k], vectors[2][k]])))
}

/// Mean distance of the skin's samples, mirrored across the plane, to the skin.
fn mirror_distance(mesh: &Mesh, normal: Vec3, origin: Vec3) -> f64 {
    let surface = TriangleBvh::build(&mesh.points, &mesh.skin_triangles);
    let samples = mesh.samples(SAMPLES);
    let total: f64 = samples
        .iter()
        .map(|&p| {
            let reflected = sub(p, scale(normal, 2.0 * dot(sub(p, origin), normal)));
            surface.closest_point(&reflected, f64::INFINITY).map_or(f64::INFINITY, |h| h.distance_squared.sqrt())
        })
        .sum();
    total / samples.len().max(1) as f64
}

/// Similarity ICP with closest points both ways (template samples onto the character's skin,
/// character samples onto the moved template's skin), the farthest [`TRIM`] dropped each
/// step; returns the motion and its last mean kept distance. The moved template's closest
/// point to `q` is the motion of the rest skin's (`template_skin`) closest point to
/// `motion^-1(q)`, at `s` times the distance: one hierarchy serves every step and start.
fn trimmed_icp(
    template_skin: &TriangleBvh,
    template_samples: &[Vec3],
    character_samples: &[Vec3],
    target: &TriangleBvh,
    start: Similarity,
    iterations: usize,
) -> (Similarity, f64) {
    let mut motion = start;
    let mut mean = f64::INFINITY;
    for _ in 0..iterations {
        let mut pairs: Vec<(f64, Vec3, Vec3)> = Vec::with_capacity(template_samples.len() + character_samples.len());
        for &p in template_samples {
            if let Some(hit) = target.closest_point(&motion.apply(p), f64::INFINITY) {
                pairs.push((hit.distance_squared, p, hit.point));
            }
        }
        for &q in character_samples {
            if let Some(hit) = template_skin.closest_point(&motion.apply_inverse(q), f64::INFINITY) {
                pairs.push((hit.distance_squared * motion.scale * motion.scale, hit.point, q));
            }
        }
        pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
        pairs.truncate(((1.0 - TRIM) * pairs.len() as f64).ceil() as usize);
        if pairs.len() < 4 {
            break;
        }
        mean = pairs.iter().map(|p| p.0.sqrt()).sum::<f64>() / pairs.len() as f64;
        let (from, to): (Vec<Vec3>, Vec<Vec3>) = pairs.iter().map(|&(_, p, q)| (p, q)).unzip();
        match similarity_from_pairs(&from, &to) {
            Ok(next) => motion = next,
            Err(_) => break,
        }
    }
    (motion, mean)
}

#[cfg(test)]
#[path = "propose_tests.rs"]
mod tests;
