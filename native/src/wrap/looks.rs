//! Where riggers look first, per carried key: the eyes close on a blink, the mouth opens on
//! jawOpen as far as the template's does and mouthClose closes it again, the lid line and the
//! lip contour stay as smooth as the template's, no triangle turns over, and the key is as
//! smooth as a plain copy of the wrapped template's (the measures are [`super::measures`]).
//!
//! The places are found once on the template, from its own rest and keys, and read on the
//! character through the wrap: each template vertex on a margin, where the fit put it, bound
//! to the character's skin facing its way (as the carry binds, so that a point on one lip
//! never lands on the other), and posed by the character's key there (barycentric).
//! - **An eye's margins**: the lids rest on the eyeball (a round piece, as the lid landmarks
//!   find it: `lids`), so seen from the front along the face's front through the eyeball's
//!   centre the lid margin is, in each of [`SECTORS`] directions around that axis, the skin
//!   vertex in front of the centre nearest the axis that the eyeball does not hide: outside
//!   the eyeball's sphere (a point in front of the centre and inside the sphere lies behind
//!   the eyeball's front as seen along the axis). Whole lids fold back into a socket behind
//!   the eyeball, and the socket's skin lies nearer the axis than the margin: read there, the
//!   gap runs from the margin to a hidden point the fit shapes freely (nothing on the
//!   character's surface sees it), and a blink that closes reads open. The half above the
//!   centre is the upper margin, below the lower; the eye's middle is the margin's vertex
//!   straight above and straight below the centre. The eyeball is the one nearest the skin
//!   the blink moves.
//! - **The lips' seam**: the lips touch at rest and jawOpen parts them, so a skin vertex is on
//!   the seam when its nearest skin vertex within an edge of it at rest is moved apart by
//!   jawOpen to more than [`SEAM_OPENING`] times their rest distance (a vertex and its own
//!   neighbours on one lip move together). The lip jawOpen moves more is the moving margin;
//!   the mouth's middle is the seam's pair nearest the symmetry plane, the most frontal.
//! - **The face's size**: from the mouth's middle to the midpoint of the eyes' middles, the
//!   length the mouth's opening is compared in (a cartoon's mouth is as open for its face).

use rayon::prelude::*;
use serde::Serialize;

use crate::error::ShapesmithResult;
use crate::geometry::bvh::TriangleBvh;
use crate::geometry::front::find_front;
use crate::geometry::mat3::{add, cross, dot, length, scale, sub, to_f64, vertex_normals, Vec3};
use crate::geometry::neighbours::PointTree;
use crate::geometry::topology::Adjacency;
use crate::invalid;
use crate::rig::{validate_points, validate_triangle_indices, RigView};

use super::carry::{bind, bind_facing_normals};
use super::lids::eyeballs;
use super::measures::{key_roughness, line_turning, opening_gap, turned_over, turned_over_share};
use super::skin_flags;

/// Directions around an eye's axis the lid margin is sampled in.
pub const SECTORS: usize = 32;
/// A seam vertex's partner is moved apart by jawOpen to more than this many times their rest
/// distance (twice: a tear, where a smooth stretch of skin stays well under it).
pub const SEAM_OPENING: f64 = 2.0;
/// An eye closes when its blink leaves at most this fraction of the rest opening.
pub const CLOSED_GAP: f64 = 0.05;
/// A character point binds to skin facing within this angle of the template point's normal.
const FACING_DEGREES: f64 = 60.0;

/// One opening's two margins as template vertices: the one its key moves more, then the
/// other, each ordered across the face, and the middle pair (moving, resting).
#[derive(Clone, Debug, Serialize)]
pub struct Margins {
    pub moving: Vec<u32>,
    pub resting: Vec<u32>,
    pub middle: [u32; 2],
}

/// The openings found on the template: the eyes (left-named key first) and the mouth.
#[derive(Clone, Debug, Default, Serialize)]
pub struct Openings {
    pub eyes: Vec<(String, Margins)>,
    pub mouth: Option<Margins>,
    /// From the mouth's middle to the midpoint of the eyes' middles, at rest.
    pub face_size: Option<f64>,
}

/// What the measures read on one key (`None`: not measured for this key, or the place was not
/// found on the template). Gaps and openings are fractions; turnings are radians.
#[derive(Clone, Debug, Default, Serialize)]
pub struct ShapeLooks {
    pub name: String,
    /// Character triangles turned over by the key ([`turned_over`]), and the share of the
    /// skin the key moves they cover ([`turned_over_share`]); the template's own key's share
    /// on the template (a closing lid folds some on any mesh).
    pub turned_over: usize,
    pub turned_over_share: f64,
    pub template_turned_over_share: f64,
    /// [`key_roughness`] of the carried key, of the wrapped template's key copied to the
    /// character's vertices (barycentric at the closest point: a plain copy), and of the
    /// truth when one is given.
    pub roughness: f64,
    pub copy_roughness: f64,
    pub truth_roughness: Option<f64>,
    /// A blink: the gap left at the eye's middle, / the rest opening; and the template's.
    pub eye_gap: Option<f64>,
    pub template_eye_gap: Option<f64>,
    pub eyes_close: Option<bool>,
    /// A blink: the upper margin's turning, closed; and the template's.
    pub lid_turning: Option<f64>,
    pub template_lid_turning: Option<f64>,
    /// jawOpen: the opening at the mouth's middle / the face's size; and the template's.
    pub mouth_opening: Option<f64>,
    pub template_mouth_opening: Option<f64>,
    /// jawOpen: both lip margins' turning, open; and the template's.
    pub lip_turning: Option<f64>,
    pub template_lip_turning: Option<f64>,
    /// mouthClose: the share of jawOpen's opening that jawOpen + mouthClose closes; and the
    /// template's.
    pub mouth_closing: Option<f64>,
    pub template_mouth_closing: Option<f64>,
}

/// The measures of every key, and the openings they were read at.
#[derive(Clone, Debug, Serialize)]
pub struct Looks {
    pub openings: Openings,
    pub shapes: Vec<ShapeLooks>,
}

fn key_index(names: &[String], name: &str) -> Option<usize> {
    names.iter().position(|n| n.eq_ignore_ascii_case(name))
}

fn delta(deltas: &[[f32; 3]], n: usize, k: usize) -> Vec<Vec3> {
    deltas[k * n..(k + 1) * n].iter().map(to_f64).collect()
}

/// The template's openings (module docs). `rig` is the template's rest and own keys.
pub fn find_openings(rig: &RigView) -> ShapesmithResult<Openings> {
    let n = rig.n_vertices();
    let points: Vec<Vec3> = rig.neutral.iter().map(to_f64).collect();
    let is_skin = skin_flags(n, rig.triangles);
    // The lateral axis tried first is X (Blender's); find_front tries the others too.
    let front = find_front(rig, 0)?;
    let (f, up) = (front.front, front.up);
    let across = cross(up, f);
    let balls = eyeballs(&points, rig.triangles, &is_skin);
    let mut openings = Openings::default();
    for name in ["eyeBlinkLeft", "eyeBlinkRight"] {
        let Some(k) = key_index(rig.names, name) else { continue };
        let blink = delta(rig.deltas, n, k);
        let (mut centre, mut weight) = ([0.0; 3], 0.0);
        for v in (0..n).filter(|&v| is_skin[v]) {
            centre = add(centre, scale(points[v], length(blink[v])));
            weight += length(blink[v]);
        }
        if weight == 0.0 {
            continue;
        }
        let centre = scale(centre, 1.0 / weight);
        let Some(ball) = balls.iter().min_by(|a, b| length(sub(a.centre, centre)).total_cmp(&length(sub(b.centre, centre)))) else { continue };
        if let Some(margins) = eye_margins(&points, &is_skin, (ball.centre, ball.radius), f, up, across, &blink) {
            openings.eyes.push((rig.names[k].clone(), margins));
        }
    }
    if let Some(k) = key_index(rig.names, "jawOpen") {
        openings.mouth = lip_seam(&points, rig.triangles, &is_skin, &delta(rig.deltas, n, k), f, across);
    }
    if let (Some(mouth), false) = (&openings.mouth, openings.eyes.is_empty()) {
        let middle = |m: &Margins| scale(add(points[m.middle[0] as usize], points[m.middle[1] as usize]), 0.5);
        let eyes = scale(openings.eyes.iter().fold([0.0; 3], |acc, (_, m)| add(acc, middle(m))), 1.0 / openings.eyes.len() as f64);
        openings.face_size = Some(length(sub(eyes, middle(mouth)))).filter(|&s| s > 0.0);
    }
    Ok(openings)
}

/// An eye's margins around the axis through the eyeball's centre along the front `f`
/// (`eyeball`: its centre and radius; skin inside its sphere is hidden behind it).
fn eye_margins(points: &[Vec3], is_skin: &[bool], eyeball: (Vec3, f64), f: Vec3, up: Vec3, across: Vec3, blink: &[Vec3]) -> Option<Margins> {
    let (centre, radius) = eyeball;
    let width = std::f64::consts::TAU / SECTORS as f64;
    let mut nearest: Vec<Option<(f64, u32)>> = vec![None; SECTORS];
    for v in (0..points.len()).filter(|&v| is_skin[v]) {
        let r = sub(points[v], centre);
        if dot(r, f) <= 0.0 || length(r) < radius {
            continue;
        }
        let (x, y) = (dot(r, across), dot(r, up));
        let sector = (((y.atan2(x) + std::f64::consts::PI) / width).round() as usize) % SECTORS;
        let radius = x.hypot(y);
        if nearest[sector].is_none_or(|(best, _)| radius < best) {
            nearest[sector] = Some((radius, v as u32));
        }
    }
    // Sector s is centred on the angle s * width - pi: straight up is 3/4 of the way round.
    let (top, bottom) = (nearest[3 * SECTORS / 4]?.1, nearest[SECTORS / 4]?.1);
    let mut ring: Vec<u32> = nearest.iter().flatten().map(|&(_, v)| v).collect();
    ring.dedup();
    let side = |above: bool| {
        let mut line: Vec<u32> = ring.iter().copied().filter(|&v| (dot(sub(points[v as usize], centre), up) > 0.0) == above).collect();
        line.sort_by(|&a, &b| dot(points[a as usize], across).total_cmp(&dot(points[b as usize], across)));
        line.dedup();
        line
    };
    let (upper, lower) = (side(true), side(false));
    let motion = |line: &[u32]| line.iter().map(|&v| length(blink[v as usize])).sum::<f64>() / line.len().max(1) as f64;
    if upper.len() < 3 || lower.len() < 3 {
        return None;
    }
    Some(if motion(&upper) >= motion(&lower) {
        Margins { moving: upper, resting: lower, middle: [top, bottom] }
    } else {
        Margins { moving: lower, resting: upper, middle: [bottom, top] }
    })
}

/// The lips' seam that jawOpen (`open`) parts (module docs).
fn lip_seam(points: &[Vec3], triangles: &[[u32; 3]], is_skin: &[bool], open: &[Vec3], f: Vec3, across: Vec3) -> Option<Margins> {
    let skin: Vec<u32> = (0..points.len() as u32).filter(|&v| is_skin[v as usize]).collect();
    let rest: Vec<[f32; 3]> = skin.iter().map(|&v| points[v as usize].map(|x| x as f32)).collect();
    let tree = PointTree::new(&rest);
    let edges = Adjacency::from_triangles(points.len(), triangles).mean_edge_lengths(points);
    let posed = |v: usize| add(points[v], open[v]);
    let mut pairs: Vec<(u32, u32)> = Vec::new();
    for &v in &skin {
        let v = v as usize;
        let partner = tree
            .within(points[v], edges[v])
            .into_iter()
            .map(|(i, d)| (skin[i] as usize, d))
            .filter(|&(w, d)| w != v && d > 0.0)
            .min_by(|a, b| a.1.total_cmp(&b.1));
        if let Some((w, d)) = partner {
            if length(sub(posed(v), posed(w))) > SEAM_OPENING * d {
                pairs.push((v as u32, w as u32));
            }
        }
    }
    let (mut moving, mut resting) = (Vec::new(), Vec::new());
    for &(v, w) in &pairs {
        if length(open[v as usize]) > length(open[w as usize]) { moving.push(v) } else { resting.push(v) }
    }
    let across_of = |v: &u32| dot(points[*v as usize], across);
    for line in [&mut moving, &mut resting] {
        line.sort_by(|a, b| across_of(a).total_cmp(&across_of(b)));
    }
    if moving.len() < 3 || resting.len() < 3 {
        return None;
    }
    // The symmetry plane: midway between the seam's extremes across the face.
    let all: Vec<f64> = pairs.iter().map(|(v, _)| across_of(v)).collect();
    let mid = 0.5 * (all.iter().copied().fold(f64::INFINITY, f64::min) + all.iter().copied().fold(f64::NEG_INFINITY, f64::max));
    let &(v, w) = pairs.iter().min_by(|a, b| {
        let key = |p: &(u32, u32)| ((0.5 * (across_of(&p.0) + across_of(&p.1)) - mid).abs(), -dot(points[p.0 as usize], f));
        let (ka, kb) = (key(a), key(b));
        ka.0.total_cmp(&kb.0).then(ka.1.total_cmp(&kb.1))
    })?;
    let middle = if length(open[v as usize]) > length(open[w as usize]) { [v, w] } else { [w, v] };
    Some(Margins { moving, resting, middle })
}

/// Where each template margin vertex is read: on the template itself, or at its bound point
/// on the character.
enum Reader<'a> {
    Template { rest: &'a [Vec3] },
    Character { rest: &'a [Vec3], bound: std::collections::HashMap<u32, ([u32; 3], [f64; 3])> },
}

impl Reader<'_> {
    fn at(&self, v: u32, key: &[Vec3]) -> Vec3 {
        match self {
            Reader::Template { rest } => add(rest[v as usize], key[v as usize]),
            Reader::Character { rest, bound, .. } => {
                let (corners, weights) = bound[&v];
                corners.iter().zip(weights).fold([0.0; 3], |acc, (&c, w)| add(acc, scale(add(rest[c as usize], key[c as usize]), w)))
            }
        }
    }

    fn line(&self, line: &[u32], key: &[Vec3]) -> Vec<Vec3> {
        line.iter().map(|&v| self.at(v, key)).collect()
    }
}

/// The opening measures of the keys named in `names` (`keys[k]`: per-vertex deltas of the
/// mesh `reader` reads): per key (eye gap, lid turning, mouth opening, lip turning, mouth
/// closing), as [`ShapeLooks`]' fields.
type Measured = [Option<f64>; 5];

fn measure_openings(openings: &Openings, names: &[String], keys: &[Vec<Vec3>], reader: &Reader, zero: &[Vec3]) -> Vec<Measured> {
    let jaw = key_index(names, "jawOpen");
    let mouth_gap = |m: &Margins, key: &[Vec3]| length(sub(reader.at(m.middle[0], key), reader.at(m.middle[1], key)));
    let face = openings.face_size.map(|_| {
        // The face's size on this mesh: the rest places of the same points.
        let middle = |m: &Margins| scale(add(reader.at(m.middle[0], zero), reader.at(m.middle[1], zero)), 0.5);
        let eyes = scale(openings.eyes.iter().fold([0.0; 3], |acc, (_, m)| add(acc, middle(m))), 1.0 / openings.eyes.len() as f64);
        openings.mouth.as_ref().map_or(0.0, |m| length(sub(eyes, middle(m))))
    });
    names
        .iter()
        .enumerate()
        .map(|(k, name)| {
            let key = &keys[k];
            let mut row: Measured = [None; 5];
            if let Some((_, eye)) = openings.eyes.iter().find(|(n, _)| n.eq_ignore_ascii_case(name)) {
                let [m, r] = eye.middle;
                row[0] = opening_gap(reader.at(m, zero), reader.at(r, zero), reader.at(m, key), reader.at(r, key));
                row[1] = Some(line_turning(&reader.line(&eye.moving, key)));
            }
            if let Some(mouth) = &openings.mouth {
                if Some(k) == jaw {
                    row[2] = face.filter(|&s| s > 0.0).map(|s| mouth_gap(mouth, key) / s);
                    row[3] = Some(line_turning(&reader.line(&mouth.moving, key)) + line_turning(&reader.line(&mouth.resting, key)));
                }
                if let (true, Some(j)) = (name.eq_ignore_ascii_case("mouthClose"), jaw) {
                    let both: Vec<Vec3> = keys[j].iter().zip(key).map(|(&a, &b)| add(a, b)).collect();
                    let open = mouth_gap(mouth, &keys[j]);
                    row[4] = (open > 0.0).then(|| 1.0 - mouth_gap(mouth, &both) / open);
                }
            }
            row
        })
        .collect()
}

/// The measures of the carried keys (`keys`, K x Nc, shape-major, in the order of
/// `template.names`) on the character, against the template's own keys (`template`: its rest
/// and keys, whose vertex order `wrapped` shares: where the fit put each template vertex),
/// the wrapped template's keys (`wrapped_keys`, what the carry carried: its plain copy's
/// roughness) and, when given, the truth on the character (`truth`).
#[allow(clippy::too_many_arguments)]
pub fn look_at_keys(
    template: &RigView,
    wrapped: &[[f32; 3]],
    wrapped_keys: &[[f32; 3]],
    character: &[[f32; 3]],
    character_triangles: &[[u32; 3]],
    keys: &[[f32; 3]],
    truth: Option<&[[f32; 3]]>,
) -> ShapesmithResult<Looks> {
    let (nt, nc, k) = (template.n_vertices(), character.len(), template.n_shapes());
    validate_points(wrapped, "wrapped_neutral")?;
    validate_points(character, "character_neutral")?;
    validate_triangle_indices(nc, character_triangles)?;
    validate_triangle_indices(nt, template.triangles)?;
    if wrapped.len() != nt || wrapped_keys.len() != k * nt {
        return Err(invalid!("the wrapped template has {} vertices and {} key rows; the template {nt} vertices and {k} keys", wrapped.len(), wrapped_keys.len()));
    }
    if keys.len() != k * nc || truth.is_some_and(|t| t.len() != k * nc) {
        return Err(invalid!("the character's keys must be {k} keys of {nc} vertices"));
    }
    if character_triangles.is_empty() || template.triangles.is_empty() {
        return Err(invalid!("the template and the character need faces"));
    }
    let openings = find_openings(template)?;
    let template_rest: Vec<Vec3> = template.neutral.iter().map(to_f64).collect();
    let template_keys: Vec<Vec<Vec3>> = (0..k).map(|s| delta(template.deltas, nt, s)).collect();
    let own = measure_openings(&openings, template.names, &template_keys, &Reader::Template { rest: &template_rest }, &vec![[0.0; 3]; nt]);

    // The margin vertices bound to the character's skin, facing the wrapped template's way.
    let wrapped_rest: Vec<Vec3> = wrapped.iter().map(to_f64).collect();
    let rest: Vec<Vec3> = character.iter().map(to_f64).collect();
    let is_skin = skin_flags(nc, character_triangles);
    let skin_triangles: Vec<[u32; 3]> = character_triangles.iter().filter(|t| is_skin[t[0] as usize]).copied().collect();
    let mut margin: Vec<u32> = openings.eyes.iter().map(|(_, m)| m).chain(&openings.mouth).flat_map(|m| m.moving.iter().chain(&m.resting).chain(&m.middle)).copied().collect();
    margin.sort_unstable();
    margin.dedup();
    let normals = vertex_normals(&wrapped_rest, template.triangles);
    let queries: Vec<Vec3> = margin.iter().map(|&v| wrapped_rest[v as usize]).collect();
    let query_normals: Vec<Vec3> = margin.iter().map(|&v| normals[v as usize]).collect();
    let bound = if margin.is_empty() || skin_triangles.is_empty() {
        Default::default()
    } else {
        let bvh = TriangleBvh::build(&rest, &skin_triangles);
        let hits = bind_facing_normals(&queries, &query_normals, &rest, &skin_triangles, &bvh, FACING_DEGREES.to_radians().cos());
        margin.iter().zip(hits).map(|(&v, hit)| (v, (skin_triangles[hit.triangle as usize], hit.barycentric))).collect()
    };
    let reader = Reader::Character { rest: &rest, bound };
    let carried: Vec<Vec<Vec3>> = (0..k).map(|s| delta(keys, nc, s)).collect();
    let measured = measure_openings(&openings, template.names, &carried, &reader, &vec![[0.0; 3]; nc]);

    // The plain copy: each character vertex takes the wrapped keys at its closest point.
    let wrapped_bvh = TriangleBvh::build(&wrapped_rest, template.triangles);
    let copy_at = bind(&rest, &wrapped_bvh);
    let adjacency = Adjacency::from_triangles(nc, character_triangles);
    let shapes = (0..k)
        .into_par_iter()
        .map(|s| {
            let wrapped_key = delta(wrapped_keys, nt, s);
            let copy: Vec<Vec3> = copy_at
                .iter()
                .map(|hit| {
                    let corners = template.triangles[hit.triangle as usize];
                    corners.iter().zip(hit.barycentric).fold([0.0; 3], |acc, (&c, w)| add(acc, scale(wrapped_key[c as usize], w)))
                })
                .collect();
            let posed: Vec<Vec3> = rest.iter().zip(&carried[s]).map(|(&p, &d)| add(p, d)).collect();
            let [eye_gap, lid_turning, mouth_opening, lip_turning, mouth_closing] = measured[s];
            let [template_eye_gap, template_lid_turning, template_mouth_opening, template_lip_turning, template_mouth_closing] = own[s];
            ShapeLooks {
                name: template.names[s].clone(),
                turned_over: turned_over(&rest, &posed, character_triangles),
                turned_over_share: turned_over_share(&rest, &carried[s], character_triangles),
                template_turned_over_share: turned_over_share(&template_rest, &template_keys[s], template.triangles),
                roughness: key_roughness(&carried[s], &adjacency),
                copy_roughness: key_roughness(&copy, &adjacency),
                truth_roughness: truth.map(|t| key_roughness(&delta(t, nc, s), &adjacency)),
                eye_gap,
                template_eye_gap,
                eyes_close: eye_gap.map(|g| g <= CLOSED_GAP),
                lid_turning,
                template_lid_turning,
                mouth_opening,
                template_mouth_opening,
                lip_turning,
                template_lip_turning,
                mouth_closing,
                template_mouth_closing,
            }
        })
        .collect();
    Ok(Looks { openings, shapes })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// An eye as whole lids make it (front +z, up +y, eyeball of radius 1 at the origin): a lid
    /// margin ring of `n` vertices resting on the eyeball (1.05 radii from its centre, 0.5 from
    /// the axis), and the lids' fold back into the socket, a ring nearer the axis inside the
    /// eyeball's sphere (0.3 from the axis, 0.2 in front of the centre). The blink moves the
    /// upper lid, margin and fold alike, down by 1.2 times the opening (as the template's
    /// blinks, it presses past the lower lid).
    fn socketed_eye(n: usize) -> (Vec<Vec3>, Vec<Vec3>, std::ops::Range<usize>) {
        let ring = |radius: f64, depth: f64| (0..n).map(move |i| {
            let a = std::f64::consts::TAU * i as f64 / n as f64;
            [radius * a.cos(), radius * a.sin(), depth]
        });
        let margin_depth = (1.05f64 * 1.05 - 0.25).sqrt();
        let points: Vec<Vec3> = ring(0.5, margin_depth).chain(ring(0.3, 0.2)).collect();
        let blink = points.iter().map(|p| if p[1] > 0.0 { [0.0, -1.2, 0.0] } else { [0.0; 3] }).collect();
        (points, blink, 0..n)
    }

    #[test]
    fn a_lid_margin_is_the_skin_the_eyeball_does_not_hide_and_a_closing_blink_reads_closed() {
        let (points, blink, margin) = socketed_eye(32);
        let is_skin = vec![true; points.len()];
        let (f, up, across) = ([0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]);
        let eye = eye_margins(&points, &is_skin, ([0.0; 3], 1.0), f, up, across, &blink).expect("the margins are found");
        // Every margin vertex is on the visible ring, none in the socket behind the eyeball;
        // the middle is the ring's top (moving) and bottom (resting).
        assert!(eye.moving.iter().chain(&eye.resting).all(|&v| margin.contains(&(v as usize))), "{eye:?}");
        assert_eq!(eye.middle, [8, 24]);
        // The blink brings the upper margin down past the lower one: closed, as the template's.
        let openings = Openings { eyes: vec![("eyeBlinkLeft".into(), eye)], mouth: None, face_size: None };
        let names = ["eyeBlinkLeft".to_string()];
        let reader = Reader::Template { rest: &points };
        let zero = vec![[0.0; 3]; points.len()];
        let gap = measure_openings(&openings, &names, &[blink.clone()], &reader, &zero)[0][0];
        assert_eq!(gap, Some(0.0));
        // Half a blink (0.6 of the opening) leaves 0.4 of it.
        let half: Vec<Vec3> = blink.iter().map(|d| scale(*d, 0.5)).collect();
        let gap = measure_openings(&openings, &names, &[half], &reader, &zero)[0][0].unwrap();
        assert!((gap - 0.4).abs() < 1e-9, "{gap}");
    }
}
