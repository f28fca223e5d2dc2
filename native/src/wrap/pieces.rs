//! The template's pieces other than the skin (eyes, teeth, tongue, lashes) placed on the
//! character: first moved with the fitted skin around them, then, where the character has a
//! piece of the same size in the same place, fitted onto it by a similarity (iterative closest
//! points in both directions, Besl & McKay 1992, each step solved by Umeyama 1991).
//!
//! Why fit them: a piece that only follows the skin inherits the skin fit's slide along the
//! surface (on a decimated MakeHuman identity the eyes and teeth landed 0.3% to 2.3% of the
//! diagonal from where they belong, scaled 5-19% wrong), and a piece's shapes (eyes looking,
//! jaw and tongue) move it rigidly, so every misplacement shows in its keys.

use crate::error::ShapesmithResult;
use crate::geometry::bvh::TriangleBvh;
use crate::geometry::mat3::{add, cross, length, scale, sub, Vec3};
use crate::geometry::neighbours::PointTree;
use crate::geometry::topology::connected_components;

use super::align::{similarity_from_pairs, Similarity};

/// A piece's area-weighted centre and root-mean-square radius (area weights, so that a
/// decimated copy with uneven vertex density has the same moments).
#[derive(Clone, Copy, Debug)]
pub(super) struct Moments {
    pub centre: Vec3,
    pub radius: f64,
}

fn moments(points: &[Vec3], triangles: &[[u32; 3]]) -> Option<Moments> {
    let mut area = 0.0;
    let mut centre = [0.0; 3];
    let samples: Vec<(Vec3, f64)> = triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| points[v as usize]);
            let weight = 0.5 * length(cross(sub(b, a), sub(c, a)));
            (add(add(a, b), c).map(|x| x / 3.0), weight)
        })
        .collect();
    for &(p, w) in &samples {
        area += w;
        centre = add(centre, p.map(|x| x * w));
    }
    if area <= 0.0 {
        return None;
    }
    let centre = centre.map(|x| x / area);
    let radius = (samples.iter().map(|&(p, w)| w * length(sub(p, centre)).powi(2)).sum::<f64>() / area).sqrt();
    (radius > 0.0).then_some(Moments { centre, radius })
}

/// The vertices and triangles of each piece whose label is not `skip`.
pub(super) fn pieces(n: usize, triangles: &[[u32; 3]], skip: impl Fn(usize) -> bool) -> Vec<(Vec<usize>, Vec<[u32; 3]>)> {
    let (label, count) = connected_components(n, triangles);
    let mut out = vec![(Vec::new(), Vec::new()); count];
    for v in 0..n {
        out[label[v] as usize].0.push(v);
    }
    for t in triangles {
        out[label[t[0] as usize] as usize].1.push(*t);
    }
    out.into_iter().filter(|(members, triangles)| !members.is_empty() && !triangles.is_empty() && !skip(members[0])).collect()
}

/// Moves every non-skin piece by the similarity that maps the skin vertices around it (within
/// twice its radius of its centre, widened until there are enough) from aligned to fitted.
pub fn carry_pieces(aligned: &[Vec3], fitted: &mut [Vec3], triangles: &[[u32; 3]], is_skin: &[bool]) -> ShapesmithResult<()> {
    let skin: Vec<u32> = (0..aligned.len() as u32).filter(|&v| is_skin[v as usize]).collect();
    let skin_points: Vec<[f32; 3]> = skin.iter().map(|&v| aligned[v as usize].map(|x| x as f32)).collect();
    let tree = PointTree::new(&skin_points);
    for (piece, _) in pieces(aligned.len(), triangles, |v| is_skin[v]) {
        let centre = piece.iter().fold([0.0; 3], |acc, &v| add(acc, aligned[v].map(|x| x / piece.len() as f64)));
        let radius = piece.iter().map(|&v| length(sub(aligned[v], centre))).fold(0.0, f64::max);
        let mut reach = 2.0 * radius.max(1e-9);
        let mut around = tree.within(centre, reach);
        while around.len() < 12 && around.len() < skin.len() {
            reach *= 2.0;
            around = tree.within(centre, reach);
        }
        let from: Vec<Vec3> = around.iter().map(|&(i, _)| aligned[skin[i] as usize]).collect();
        let to: Vec<Vec3> = around.iter().map(|&(i, _)| fitted[skin[i] as usize]).collect();
        let motion = similarity_from_pairs(&from, &to).or_else(|_| {
            // Skin around the piece on one line: translate by its mean motion.
            let n = from.len().max(1) as f64;
            let shift = from.iter().zip(&to).fold([0.0; 3], |acc, (a, b)| add(acc, sub(*b, *a).map(|x| x / n)));
            Ok::<_, crate::error::ShapesmithError>(Similarity { translation: shift, ..Similarity::IDENTITY })
        })?;
        for &v in &piece {
            fitted[v] = motion.apply(aligned[v]);
        }
    }
    Ok(())
}

/// A template piece matches a character piece when their centres lie within this fraction of
/// the template piece's radius ...
const MATCH_DISTANCE: f64 = 0.5;
/// ... and their radii differ by less than this factor: an eye and the lashes over it, or the
/// upper and lower teeth, are told apart by place and size.
const MATCH_SIZE: f64 = 1.5;
/// Similarity ICP iterations at most, and the relative change of the pairs' mean distance
/// that ends them.
const ICP_ITERATIONS: usize = 30;
const ICP_TOLERANCE: f64 = 1e-4;
/// A fit is kept when the two surfaces end within this fraction of the piece's radius of
/// each other on average (both directions); else the piece stays with the skin.
const ACCEPTED_DISTANCE: f64 = 0.1;

/// Pairs of (template piece, character piece) indices into the `pieces` lists that match in
/// place (centres within `max_offset` template radii) and size, one to one, the closest first.
pub(super) fn match_pieces(template_moments: &[Option<Moments>], character_moments: &[Option<Moments>], max_offset: f64) -> Vec<(usize, usize)> {
    let mut candidates = Vec::new();
    for (i, a) in template_moments.iter().enumerate() {
        for (j, b) in character_moments.iter().enumerate() {
            let (Some(a), Some(b)) = (a, b) else { continue };
            let offset = length(sub(a.centre, b.centre)) / a.radius;
            let size = (b.radius / a.radius).ln().abs();
            if offset < max_offset && size < MATCH_SIZE.ln() {
                candidates.push((offset + size, i, j));
            }
        }
    }
    candidates.sort_by(|x, y| x.0.total_cmp(&y.0));
    let (mut template_taken, mut character_taken) = (vec![false; template_moments.len()], vec![false; character_moments.len()]);
    let mut matched = Vec::new();
    for (_, i, j) in candidates {
        if !template_taken[i] && !character_taken[j] {
            template_taken[i] = true;
            character_taken[j] = true;
            matched.push((i, j));
        }
    }
    matched
}

/// A template piece (eye, tooth row, tongue, lashes) and what became of it: the character
/// piece it matched, if any, and whether it was fitted there (else it follows the skin).
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct PieceMatch {
    /// The piece's lowest vertex and its vertex count (the add-on names the object holding it).
    pub template_vertex: u32,
    pub template_vertices: usize,
    /// The matched character piece's lowest vertex and vertex count, `None` without a match.
    pub character_vertex: Option<u32>,
    pub character_vertices: usize,
    /// After the skin fit: the centres' distance in template piece radii, the character
    /// piece's radius over the template piece's.
    pub offset: f64,
    pub size_ratio: f64,
    pub fitted: bool,
}

/// Fits each non-skin template piece (at `fitted`, already carried with the skin) onto the
/// non-skin character piece it matches (one to one, the closest in place and size first);
/// returns one row per template piece (welded vertex numbering). A piece is matched from where
/// the skin carried it or from where the alignment put it (`aligned`), whichever lies nearer
/// a character piece of its size, and fitted from there: where the character's skin differs
/// around a piece (an eye socket cut open at the lids, as avatars have them), the skin fit
/// there says little about where the piece belongs.
pub fn fit_pieces(
    aligned: &[Vec3],
    fitted: &mut [Vec3],
    triangles: &[[u32; 3]],
    is_skin: &[bool],
    character: &[Vec3],
    character_triangles: &[[u32; 3]],
    is_character_skin: &[bool],
) -> Vec<PieceMatch> {
    let template_pieces = pieces(fitted.len(), triangles, |v| is_skin[v]);
    let character_pieces = pieces(character.len(), character_triangles, |v| is_character_skin[v]);
    let carried_moments: Vec<Option<Moments>> = template_pieces.iter().map(|(_, t)| moments(fitted, t)).collect();
    let aligned_moments: Vec<Option<Moments>> = template_pieces.iter().map(|(_, t)| moments(aligned, t)).collect();
    let character_moments: Vec<Option<Moments>> = character_pieces.iter().map(|(_, t)| moments(character, t)).collect();
    // Per piece, the placement nearer its best character piece.
    let nearest = |m: &Option<Moments>| -> f64 {
        m.map_or(f64::INFINITY, |a| {
            character_moments.iter().flatten().filter(|b| (b.radius / a.radius).ln().abs() < MATCH_SIZE.ln()).map(|b| length(sub(a.centre, b.centre)) / a.radius).fold(f64::INFINITY, f64::min)
        })
    };
    let from_aligned: Vec<bool> = carried_moments.iter().zip(&aligned_moments).map(|(c, a)| nearest(a) < nearest(c)).collect();
    for ((members, _), &use_aligned) in template_pieces.iter().zip(&from_aligned) {
        if use_aligned {
            members.iter().for_each(|&v| fitted[v] = aligned[v]);
        }
    }
    let template_moments: Vec<Option<Moments>> =
        carried_moments.iter().zip(&aligned_moments).zip(&from_aligned).map(|((c, a), &use_aligned)| if use_aligned { *a } else { *c }).collect();
    let mut rows: Vec<PieceMatch> = template_pieces
        .iter()
        .map(|(members, _)| PieceMatch {
            template_vertex: members[0] as u32,
            template_vertices: members.len(),
            character_vertex: None,
            character_vertices: 0,
            offset: 0.0,
            size_ratio: 0.0,
            fitted: false,
        })
        .collect();
    for (i, j) in match_pieces(&template_moments, &character_moments, MATCH_DISTANCE) {
        let (members, piece_triangles) = &template_pieces[i];
        let (character_members, character_piece_triangles) = &character_pieces[j];
        let (Some(a), Some(b)) = (template_moments[i], character_moments[j]) else { continue };
        rows[i].character_vertex = Some(character_members[0] as u32);
        rows[i].character_vertices = character_members.len();
        rows[i].offset = length(sub(a.centre, b.centre)) / a.radius;
        rows[i].size_ratio = b.radius / a.radius;
        if let Some(motion) = similarity_icp(fitted, piece_triangles, members, character, character_piece_triangles, character_members, a.radius) {
            let start: Vec<Vec3> = members.iter().map(|&v| fitted[v]).collect();
            for (&v, p) in members.iter().zip(start) {
                fitted[v] = motion.apply(p);
            }
            rows[i].fitted = true;
        }
    }
    rows
}

/// Which part each template triangle and each character vertex and triangle belong to, for
/// the carry's binding: 0 the skin (largest piece), `k > 0` the `k`-th pair of matching
/// pieces (as [`fit_pieces`] pairs them, on the wrapped template), [`ANY_PART`] a character
/// piece without a match. The upper teeth then never bind to the lower teeth they touch.
pub struct Parts {
    pub template_triangle: Vec<u32>,
    pub character_vertex: Vec<u32>,
    pub character_triangle: Vec<u32>,
    /// The matched pieces, in part order (part `k + 1` is `matched[k]`).
    pub matched: Vec<MatchedPiece>,
}

/// A template piece and the character piece it matches (vertex lists, sorted).
pub struct MatchedPiece {
    pub template_members: Vec<usize>,
    pub template_triangles: Vec<[u32; 3]>,
    pub character_members: Vec<usize>,
}

/// A character piece with no template piece of its place and size binds to any triangle.
pub const ANY_PART: u32 = u32::MAX;

pub fn parts(template: &[Vec3], triangles: &[[u32; 3]], character: &[Vec3], character_triangles: &[[u32; 3]]) -> Parts {
    let is_skin = super::skin_flags(template.len(), triangles);
    let is_character_skin = super::skin_flags(character.len(), character_triangles);
    let template_pieces = pieces(template.len(), triangles, |v| is_skin[v]);
    let character_pieces = pieces(character.len(), character_triangles, |v| is_character_skin[v]);
    let template_moments: Vec<Option<Moments>> = template_pieces.iter().map(|(_, t)| moments(template, t)).collect();
    let character_moments: Vec<Option<Moments>> = character_pieces.iter().map(|(_, t)| moments(character, t)).collect();
    let mut template_vertex = vec![ANY_PART; template.len()];
    let mut character_vertex: Vec<u32> = is_character_skin.iter().map(|&s| if s { 0 } else { ANY_PART }).collect();
    (0..template.len()).filter(|&v| is_skin[v]).for_each(|v| template_vertex[v] = 0);
    let mut matched = Vec::new();
    for (k, (i, j)) in match_pieces(&template_moments, &character_moments, MATCH_DISTANCE).into_iter().enumerate() {
        template_pieces[i].0.iter().for_each(|&v| template_vertex[v] = k as u32 + 1);
        character_pieces[j].0.iter().for_each(|&v| character_vertex[v] = k as u32 + 1);
        let (template_members, template_triangles) = template_pieces[i].clone();
        matched.push(MatchedPiece { template_members, template_triangles, character_members: character_pieces[j].0.clone() });
    }
    Parts {
        template_triangle: triangles.iter().map(|t| template_vertex[t[0] as usize]).collect(),
        character_triangle: character_triangles.iter().map(|t| character_vertex[t[0] as usize]).collect(),
        character_vertex,
        matched,
    }
}

/// A matched piece's keys, where the piece moves rigidly in the shape (within
/// [`RIGID_MOTION`]), as the template piece's own motion mapped by the similarity `S`
/// that placed it (rest -> wrapped, recovered from the two by Umeyama: the wrap's alignment,
/// the skin around it and the piece's own fit composed). Per shape, `M` the similarity best
/// taking the template piece from rest to posed (exact for an eyeball turning or the teeth
/// following the jaw) and `r` what is left of its motion (a tongue's bend), each character
/// vertex `c` of the matched piece moves to
/// $$ c + d_c = S\big(M(y) + r(\hat y)\big), \qquad y = S^{-1}(c), $$
/// `\hat y` the closest point to `y` on the template piece at rest (`r` interpolated there).
/// A piece's motion so stays a rotation about its own centre, which the carry's gradients,
/// sampled across the piece and integrated with the screening's pull to the barycentric copy,
/// only approximate.
pub(super) struct PieceMapping {
    template_members: Vec<usize>,
    /// The template piece at rest, in member order, and its triangles in member numbering.
    rest: Vec<Vec3>,
    local_triangles: Vec<[u32; 3]>,
    character_members: Vec<usize>,
    placed: Similarity,
    /// `y` per character member, and its closest point on the template piece at rest.
    preimages: Vec<Vec3>,
    bound: Vec<crate::geometry::closest_point::SurfacePoint>,
}

/// A piece's motion in a shape is rigid when no vertex moves farther than this fraction of
/// its largest motion from where the shape's best similarity of the piece takes it.
const RIGID_MOTION: f64 = 0.01;

/// The mappings of the matched pieces whose wrapped piece is a similarity image of the
/// template's (within 1e-4 of its radius: else the piece was reshaped, and is carried).
pub(super) fn piece_mappings(matched: &[MatchedPiece], neutral: &[Vec3], wrapped: &[Vec3], character: &[Vec3]) -> Vec<PieceMapping> {
    matched
        .iter()
        .filter_map(|piece| {
            let rest: Vec<Vec3> = piece.template_members.iter().map(|&v| neutral[v]).collect();
            let placed_points: Vec<Vec3> = piece.template_members.iter().map(|&v| wrapped[v]).collect();
            let placed = similarity_from_pairs(&rest, &placed_points).ok()?;
            let radius = moments(wrapped, &piece.template_triangles)?.radius;
            let misfit = rest.iter().zip(&placed_points).map(|(p, q)| length(sub(placed.apply(*p), *q))).fold(0.0, f64::max);
            if misfit > 1e-4 * radius {
                return None;
            }
            let preimages: Vec<Vec3> = piece.character_members.iter().map(|&c| placed.apply_inverse(character[c])).collect();
            let local = |v: u32| piece.template_members.binary_search(&(v as usize)).map(|i| i as u32);
            let local_triangles = piece.template_triangles.iter().map(|t| Ok([local(t[0])?, local(t[1])?, local(t[2])?])).collect::<Result<Vec<_>, usize>>().ok()?;
            let surface = TriangleBvh::build(&rest, &local_triangles);
            let bound = preimages.iter().map(|y| surface.closest_point(y, f64::INFINITY)).collect::<Option<Vec<_>>>()?;
            Some(PieceMapping {
                template_members: piece.template_members.clone(),
                rest,
                local_triangles,
                character_members: piece.character_members.clone(),
                placed,
                preimages,
                bound,
            })
        })
        .collect()
}

impl PieceMapping {
    /// Writes the piece's mapped motion for one template shape (`own`: the template's own
    /// deltas, template vertex order; `still`: below this a template vertex is static) into
    /// the character's `deltas`, and marks the piece's vertices fixed (`fixed`: the collision
    /// pass moves the skin around a piece, not the piece). A piece static in the shape gets
    /// exactly zero; one that bends keeps its carried deltas.
    pub(super) fn write(&self, own: &[[f32; 3]], still: f64, deltas: &mut [Vec3], fixed: &mut [bool]) {
        let motion_of: Vec<Vec3> = self.template_members.iter().map(|&v| [0, 1, 2].map(|a| own[v][a] as f64)).collect();
        let largest = motion_of.iter().map(|d| length(*d)).fold(0.0, f64::max);
        if largest < still {
            self.character_members.iter().for_each(|&c| (deltas[c], fixed[c]) = ([0.0; 3], true));
            return;
        }
        let posed: Vec<Vec3> = self.rest.iter().zip(&motion_of).map(|(p, d)| add(*p, *d)).collect();
        let Ok(motion) = similarity_from_pairs(&self.rest, &posed) else { return };
        // What the similarity leaves of each template vertex's motion, in member order.
        let left: Vec<Vec3> = self.rest.iter().zip(&posed).map(|(p, q)| sub(*q, motion.apply(*p))).collect();
        // A piece that bends in the shape (a tongue stretching out, lashes riding a closing
        // lid) is carried with the skin's gradients: its own similarity, fitted to a thin or
        // blob-like piece, says little about the directions its bend should take there.
        if left.iter().any(|r| length(*r) > RIGID_MOTION * largest) {
            return;
        }
        self.character_members.iter().for_each(|&c| fixed[c] = true);
        for ((&c, y), hit) in self.character_members.iter().zip(&self.preimages).zip(&self.bound) {
            let t = self.local_triangles[hit.triangle as usize];
            let residual = (0..3).fold([0.0; 3], |acc, k| add(acc, scale(left[t[k] as usize], hit.barycentric[k])));
            let image = self.placed.apply(add(motion.apply(*y), residual));
            deltas[c] = sub(image, self.placed.apply(*y));
        }
    }
}

/// The similarity taking the template piece (`points` restricted to `members`) onto the
/// character piece, by closest points both ways (template vertices to the character's
/// surface, character vertices to the moved template's surface); `None` when the surfaces do
/// not meet (see [`ACCEPTED_DISTANCE`]).
fn similarity_icp(
    points: &[Vec3],
    triangles: &[[u32; 3]],
    members: &[usize],
    character: &[Vec3],
    character_triangles: &[[u32; 3]],
    character_members: &[usize],
    radius: f64,
) -> Option<Similarity> {
    let target = TriangleBvh::build(character, character_triangles);
    let mut motion = Similarity::IDENTITY;
    let mut moved = points.to_vec();
    let mut previous = f64::INFINITY;
    let mut mean = f64::INFINITY;
    for _ in 0..ICP_ITERATIONS {
        members.iter().for_each(|&v| moved[v] = motion.apply(points[v]));
        let source_surface = TriangleBvh::build(&moved, triangles);
        let mut from = Vec::with_capacity(members.len() + character_members.len());
        let mut to = Vec::with_capacity(from.capacity());
        let mut total = 0.0;
        for &v in members {
            let hit = target.closest_point(&moved[v], f64::INFINITY)?;
            total += hit.distance_squared.sqrt();
            from.push(points[v]);
            to.push(hit.point);
        }
        for &c in character_members {
            let hit = source_surface.closest_point(&character[c], f64::INFINITY)?;
            total += hit.distance_squared.sqrt();
            // The hit's barycentric point on the piece before this fit, so that the pair
            // constrains the same similarity as the template's own vertices.
            let corners = triangles[hit.triangle as usize];
            from.push((0..3).fold([0.0; 3], |acc, k| add(acc, points[corners[k] as usize].map(|x| x * hit.barycentric[k]))));
            to.push(character[c]);
        }
        mean = total / from.len() as f64;
        motion = similarity_from_pairs(&from, &to).ok()?;
        if (previous - mean).abs() <= ICP_TOLERANCE * radius {
            break;
        }
        previous = mean;
    }
    (mean <= ACCEPTED_DISTANCE * radius).then_some(motion)
}
