//! Lid holes: an avatar's lids cut open, the skin ending at the lid margins with the eyeballs
//! showing through, where the template's lids are whole (the bundled template's only skin
//! holes are its ear canals). No template hole matches such a hole, so its rim is an open
//! boundary whose closest points the fit rejects, and the template's lids slid along the
//! surface: on the sample character with its lids cut open they landed 1.1% of the diagonal
//! from their true places (0.3% with the lids closed) and the carried blink closed the holes
//! 60% of the way.
//!
//! Each rim vertex `c` of a character hole that an eyeball shows through and that no template
//! hole matched becomes a landmark of the fit: the template skin point at the same place about
//! the matching template eyeball, `e_t + (r_t / r_c) (c - e_c)` (`e`, `r`: the eyeballs'
//! centres and radii), bound to the template's skin facing the rim's way (its outer lid, not
//! the lid's inner fold). Lids rest on their eyeballs alike, so the place about the eyeball
//! carries over between identities: as pairs these points gave keys within 2% of the true
//! correspondence's (`docs/design_wrap.md`). The landmarks also join the user's pairs in a
//! second alignment, through which they act (in the fit alone they changed nothing).

use crate::geometry::bvh::TriangleBvh;
use crate::geometry::mat3::{add, length, scale, sub, vertex_normals, Vec3};

use super::carry::bind_facing_normals;
use super::nricp::Landmark;
use super::pieces::pieces;
use super::rims::{hole_loops, HoleMatch};

/// A piece is an eyeball when its vertices' distances from their centroid vary by under this
/// fraction of their mean (a sphere; lashes, teeth and a tongue are not).
const ROUNDNESS: f64 = 0.15;
/// ... and it has at least this many vertices.
const MIN_EYEBALL_VERTICES: usize = 8;
/// An eyeball shows through a hole whose centre lies within this many of its radii of the
/// eyeball's centre (a lid hole's centre lies about one radius in front of it).
const LID_REACH: f64 = 1.5;
/// A template eyeball matches a character eyeball whose centre lies within this many template
/// radii of it after the alignment and whose radius is within this factor of its own.
const EYEBALL_OFFSET: f64 = 2.0;
const EYEBALL_SIZE: f64 = 1.5;
/// A lid landmark binds to template skin facing within this angle of the rim vertex's normal.
const FACING_DEGREES: f64 = 60.0;

/// An eyeball: its vertices' centroid, their mean distance from it, its lowest vertex and its
/// vertex count.
#[derive(Clone, Copy, Debug)]
pub(super) struct Eyeball {
    pub(super) centre: Vec3,
    pub(super) radius: f64,
    vertex: u32,
    vertices: usize,
}

/// The round pieces among the mesh's pieces that are not skin.
pub(super) fn eyeballs(points: &[Vec3], triangles: &[[u32; 3]], is_skin: &[bool]) -> Vec<Eyeball> {
    pieces(points.len(), triangles, |v| is_skin[v])
        .into_iter()
        .filter(|(members, _)| members.len() >= MIN_EYEBALL_VERTICES)
        .filter_map(|(members, _)| {
            let centre = scale(members.iter().fold([0.0; 3], |acc, &v| add(acc, points[v])), 1.0 / members.len() as f64);
            let distances: Vec<f64> = members.iter().map(|&v| length(sub(points[v], centre))).collect();
            let mean = distances.iter().sum::<f64>() / distances.len() as f64;
            let spread = (distances.iter().map(|d| (d - mean).powi(2)).sum::<f64>() / distances.len() as f64).sqrt();
            (mean > 0.0 && spread < ROUNDNESS * mean).then_some(Eyeball { centre, radius: mean, vertex: members[0] as u32, vertices: members.len() })
        })
        .collect()
}

/// The template's and the character's meshes as the lid landmarks need them: all points and
/// triangles, the skin flags, the skin's triangles.
pub(super) struct LidMeshes<'a> {
    pub points: &'a [Vec3],
    pub triangles: &'a [[u32; 3]],
    pub is_skin: &'a [bool],
    pub skin_triangles: &'a [[u32; 3]],
}

/// The fit's landmarks on the character's lid holes (module docs) and a report row per lid
/// hole landed. `template` at its aligned positions; `matched` the holes the rims paired (their
/// character holes are no lid holes).
pub(super) fn lid_landmarks(template: &LidMeshes, character: &LidMeshes, matched: &[HoleMatch]) -> (Vec<Landmark>, Vec<HoleMatch>) {
    let character_skin: Vec<u32> = (0..character.points.len() as u32).filter(|&v| character.is_skin[v as usize]).collect();
    let holes: Vec<(Vec<u32>, _)> = hole_loops(character.points, character.skin_triangles, &character_skin)
        .into_iter()
        .filter(|(walk, _)| !matched.iter().any(|m| walk.contains(&m.character_vertex)))
        .collect();
    if holes.is_empty() {
        return (Vec::new(), Vec::new());
    }
    let (template_eyes, character_eyes) =
        (eyeballs(template.points, template.triangles, template.is_skin), eyeballs(character.points, character.triangles, character.is_skin));
    let normals = vertex_normals(character.points, character.skin_triangles);
    let surface = TriangleBvh::build(template.points, template.skin_triangles);
    let nearest = |eyes: &[Eyeball], p: Vec3| eyes.iter().copied().min_by(|a, b| length(sub(a.centre, p)).total_cmp(&length(sub(b.centre, p))));
    let (mut landmarks, mut rows) = (Vec::new(), Vec::new());
    for (walk, hole) in holes {
        let Some(eye) = nearest(&character_eyes, hole.centre).filter(|e| length(sub(e.centre, hole.centre)) < LID_REACH * e.radius) else { continue };
        let Some(own) = nearest(&template_eyes, eye.centre)
            .filter(|t| length(sub(t.centre, eye.centre)) < EYEBALL_OFFSET * t.radius && (eye.radius / t.radius).ln().abs() < EYEBALL_SIZE.ln())
        else {
            continue;
        };
        let places: Vec<Vec3> = walk.iter().map(|&c| add(own.centre, scale(sub(character.points[c as usize], eye.centre), own.radius / eye.radius))).collect();
        let facing: Vec<Vec3> = walk.iter().map(|&c| normals[c as usize]).collect();
        let hits = bind_facing_normals(&places, &facing, template.points, template.skin_triangles, &surface, FACING_DEGREES.to_radians().cos());
        landmarks.extend(walk.iter().zip(hits).map(|(&c, hit)| Landmark {
            corners: template.skin_triangles[hit.triangle as usize],
            barycentric: hit.barycentric,
            target: character.points[c as usize],
        }));
        rows.push(HoleMatch { template_vertex: own.vertex, template_rim: own.vertices, character_vertex: walk[0], character_rim: walk.len(), lids: true });
    }
    (landmarks, rows)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::mat3::unit;
    use crate::wrap::tests::sphere_mesh;

    /// A sphere of `radius` about `centre` (rings from the pole at +z, the front).
    fn sphere(centre: Vec3, radius: f64, rings: usize, segments: usize, phase: f64) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        sphere_mesh(rings, segments, phase, |theta, phi| add(centre, scale([theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()], radius)))
    }

    /// A head made of a lid shell 1.1 eyeball radii about an eyeball, the shell's triangles
    /// within `hole` radians of the front cut away (0: whole lids), and a large skin triangle
    /// behind (so that the hole is small against the skin): (points, triangles, skin flags,
    /// the skin's triangles).
    struct Head {
        points: Vec<Vec3>,
        triangles: Vec<[u32; 3]>,
        is_skin: Vec<bool>,
        skin_triangles: Vec<[u32; 3]>,
    }

    impl Head {
        fn meshes(&self) -> LidMeshes<'_> {
            LidMeshes { points: &self.points, triangles: &self.triangles, is_skin: &self.is_skin, skin_triangles: &self.skin_triangles }
        }
    }

    fn eye_in_lids(centre: Vec3, radius: f64, hole: f64, rings: usize, phase: f64) -> Head {
        let (mut points, shell) = sphere(centre, 1.1 * radius, rings, 2 * rings, phase);
        let front = |p: Vec3| (sub(p, centre)[2] / (1.1 * radius)).clamp(-1.0, 1.0).acos();
        let mut shell: Vec<[u32; 3]> = shell.into_iter().filter(|t| t.iter().all(|&v| front(points[v as usize]) > hole)).collect();
        let back = points.len() as u32;
        points.extend([[-20.0, -20.0, -10.0], [20.0, -20.0, -10.0], [0.0, 20.0, -10.0]]);
        shell.push([back, back + 1, back + 2]);
        let skin = points.len();
        let (ball, ball_triangles) = sphere(centre, radius, 8, 12, 0.0);
        let offset = points.len() as u32;
        points.extend(ball);
        let mut triangles = shell.clone();
        triangles.extend(ball_triangles.iter().map(|t| t.map(|v| v + offset)));
        let is_skin = (0..points.len()).map(|v| v < skin).collect();
        Head { points, triangles, is_skin, skin_triangles: shell }
    }

    #[test]
    fn a_lid_hole_rim_lands_on_the_template_lids_at_the_same_place_about_the_eyeball() {
        // The template's lids are whole; the character's eyeball is larger, a little off, and
        // shows through a hole in its lids (another tessellation). Each rim vertex's landmark
        // lies on the template's lid shell in the rim vertex's direction from its eyeball.
        let lids = eye_in_lids([0.0; 3], 1.0, 0.0, 20, 0.1);
        let c_centre = [0.1, -0.05, 0.0];
        let avatar = eye_in_lids(c_centre, 1.2, 0.6, 16, 0.0);
        let (template, character) = (lids.meshes(), avatar.meshes());
        let (t_points, t_skin) = (&lids.points, &lids.is_skin);
        let (landmarks, rows) = lid_landmarks(&template, &character, &[]);
        // The rim: the 32 vertices of the first ring kept (theta = 4 pi / 16).
        assert_eq!(rows.len(), 1, "{rows:?}");
        assert!(rows[0].lids && rows[0].character_rim == 32 && rows[0].template_rim == 86, "{rows:?}");
        assert_eq!(landmarks.len(), 32);
        for l in &landmarks {
            let on_template = (0..3).fold([0.0; 3], |acc, k| add(acc, scale(t_points[l.corners[k] as usize], l.barycentric[k])));
            assert!(l.corners.iter().all(|&v| t_skin[v as usize]), "{l:?} is off the template's lids");
            let (own, theirs) = (unit(on_template).unwrap(), unit(sub(l.target, c_centre)).unwrap());
            assert!(crate::geometry::mat3::dot(own, theirs) > 2f64.to_radians().cos(), "{own:?} vs {theirs:?}");
            assert!((length(on_template) - 1.1).abs() < 0.02, "{on_template:?}");
        }
        // A hole the rims already paired, or one no eyeball shows through, lands nothing.
        let paired = HoleMatch { template_vertex: 0, template_rim: 32, character_vertex: rows[0].character_vertex, character_rim: 32, lids: false };
        assert!(lid_landmarks(&template, &character, &[paired]).0.is_empty());
        let no_eye = LidMeshes { triangles: &avatar.skin_triangles, ..avatar.meshes() };
        assert!(lid_landmarks(&template, &no_eye, &[]).0.is_empty());
    }
}
