//! Collision-aware carry (SPEC section 3's collision-aware solve, on the character's own mesh):
//! a carried shape that adds more intersection curve to the character's neutral than the
//! template's own shape allows (SPEC 3's criterion, [`TemplateCurve::allowed`], per part:
//! inside one piece, between pieces; the template's curve given in the character's units) has the
//! vertices that went through another surface held on their rest side of it, with a margin,
//! and is re-solved around them; a few rounds at most, and the round with least excess is
//! kept. A shape meeting the criterion is returned untouched, bit for bit.
//!
//! Why on the character and not only on the wrapped template: the character's own lips are
//! closer (and coarser) than the wrapped template's, so the wrapped template's motion, copied
//! faithfully, still brings them through each other.
//!
//! **Judge.** The shape is swept on its moved triangles (two unmoved triangles cross exactly
//! as at rest, `geometry::penetration`), and its added curve per part compared with the
//! criterion's allowance ([`AddedCurve::excess_parts`]); worse means an excess over
//! [`CarryParams::collision_tolerance`] x the character's bbox diagonal.
//!
//! **Holds.** For each pair of the part in excess that crosses in the result and not at rest
//! (in the last attempt also one crossing at rest with more curve than then: Deviations), each
//! free (non-static) corner `u` of one triangle is tested against the other: against a piece
//! that is static in the shape (teeth, an eyeball), at its closest point on that piece (the
//! side read along that triangle's normal, at rest and now): on the other side than at rest, or
//! nearer than the margin, `t_u` is that closest point plus the margin along the normal, on the
//! rest side. Against a surface that moves too (lip through lip), along the other triangle's
//! unit normal `n` now: `t_u = x_u + (s m_u - h) n` (`s` the side of the triangle's plane `u`
//! had at rest, `h` its signed height now), half of it when the other triangle moves (its
//! corners get the other half from the pair seen the other way round). `m_u` is
//! `collision_margin` x the mean length of the edges at `u` (at least 1e-3 of the diagonal). A
//! vertex held by several pairs takes its largest push; targets accumulate over the rounds.
//!
//! **Re-solve.** The energy gains `w_u |d_u - (t_u - x_u^0)|^2`, `w_u = stiffness x A_uu`
//! (a scalar weight: the diagonal of the x, y and z systems, so one factor serves the three).
//! Only the free vertices within reach of a held vertex (`REACH` template edges, or three
//! times its push) are unknowns; the rest of the shape stays as the plain carry solved it
//! (Dirichlet), so a round factorises a small principal submatrix plus the diagonal
//! (`SymmetricMatrix::factor_subset_plus_diagonal`) instead of the character's matrix.
//! A round's re-sweep tests again only the triangles with a corner in its region
//! (`crossings_of`; the same pairs and lengths as a full sweep), and the kept round's
//! penetration is handed back ([`CarryPenetration`]) so the add-on does not sweep again.
//!
//! # Deviations (numbers and the alternatives that lost: docs/design_wrap.md)
//! - **Three attempts** ([`ATTEMPTS`]): first a corner that moved at most twice the margin
//!   against a static piece goes back to rest (skin resting on the teeth or an eyeball crosses
//!   it there as the neutral does); while the shape is still worse, a second attempt from the
//!   plain carry holds every such corner at the margin; a third holds every free corner of a
//!   crossing pair halfway back along its own motion, again each round (a lip that turns over
//!   goes through the other lip's plane on the side it rested on, so the side test pushes it
//!   the wrong way; halving its motion never crosses where the rest does not); a fourth acts
//!   also on the pairs crossing at rest whose curve grows by [`REST_GROWTH`] (as the
//!   transfer's pass does) and puts the corners of skin triangles that cross the static piece
//!   at rest back to rest (a lip resting in the teeth that slides deeper into them:
//!   mouthPucker), taken only when it clears the shape. The least excess is kept.
//! - **All rounds run**: a round that does not lower the excess can be followed by one that
//!   clears the shape.
//! - **Left worse**: the rolled lips (the lip turns over, so the side of the other triangle's
//!   plane it had at rest says nothing; no round helps and the plain carry is kept), and small
//!   excesses in squints and brows.

use std::collections::{BTreeMap, HashSet};
use std::sync::OnceLock;

use crate::error::ShapesmithResult;
use crate::geometry::bvh::TriangleBvh;
use crate::geometry::mat3::{add, cross, dot, length, scale, sub, Vec3};
pub use crate::geometry::penetration::{AddedCurve, TemplateCurve};
use crate::geometry::penetration::{crossings, crossings_of, shape_penetration, Penetration, REST_GROWTH};
use crate::geometry::topology::Adjacency;
use crate::sparse::{MatrixRows, SymmetricMatrix};

/// What the collision pass did to one carried shape.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct CarryCollision {
    /// The plain carry's excess over the template (character units, both parts summed).
    pub plain_excess: f64,
    /// The kept result's excess.
    pub excess: f64,
    /// Whether a re-solved round was kept (false: the plain carry, bit for bit).
    pub applied: bool,
    /// Re-solves run, and vertices held in the kept round.
    pub solves: usize,
    pub held_vertices: usize,
}

/// The character's penetration (SPEC section 3's metric) at rest and in each kept shape, as
/// `measure_penetration` gives it (the pass sweeps every shape anyway, so the add-on need
/// not), and per shape SPEC 3's criterion on it: the curve the shape adds to the character's
/// neutral beyond what the template's shape allows, per part ([`TemplateCurve::allowed`],
/// [`AddedCurve::excess_parts`]), as the transfer's report gives it for a same-topology
/// target.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct CarryPenetration {
    pub neutral: Penetration,
    pub shapes: Vec<Penetration>,
    pub excess: Vec<AddedCurve>,
    /// Per shape, what the criterion allowed it to add to the character's neutral.
    pub allowed: Vec<AddedCurve>,
}

impl CarryPenetration {
    /// `shapes` judged against the template's curve, `template_curve` (one per shape, in the
    /// character's units).
    pub(super) fn judged(neutral: Penetration, shapes: Vec<Penetration>, template_curve: &[TemplateCurve]) -> Self {
        let rest = AddedCurve::crossing(&neutral);
        let allowed: Vec<AddedCurve> = template_curve.iter().map(|t| t.allowed(&rest)).collect();
        let excess = shapes.iter().zip(&allowed).map(|(p, a)| AddedCurve::from_penetrations(p, &neutral).excess_parts(a)).collect();
        Self { neutral, shapes, excess, allowed }
    }
}

/// How an attempt holds a crossing vertex (module docs, "Holds" and Deviations).
#[derive(Clone, Copy, Debug, PartialEq)]
enum HoldRule {
    /// At the margin off the other surface, skin that moved at most twice the margin against a
    /// static piece back to rest.
    BackToRest,
    /// At the margin off the other surface.
    Margin,
    /// Halfway back along its own motion, each round: for a lip that turns over, where the
    /// side of the other lip's plane it rested on says nothing.
    AlongPath,
    /// Also the pairs crossing at rest whose curve grew; skin whose triangle crosses the static
    /// piece at the character's rest (a lip resting in the teeth) back to rest, the other
    /// corners as `BackToRest`; taken only when it clears the shape.
    Embedded,
}

/// The attempts, each from the plain carry, while the shape is still worse (each clears
/// shapes the others do not: Deviations).
const ATTEMPTS: [HoldRule; 4] = [HoldRule::BackToRest, HoldRule::Margin, HoldRule::AlongPath, HoldRule::Embedded];

/// Re-solved rounds per attempt at most.
const ROUNDS: usize = 4;

/// The re-solve's region: free vertices within this many mean template edges of a held vertex.
const REACH: f64 = 3.0;

/// A shape's positions, crossing pairs (those with a moved triangle), moved triangles and
/// added curve.
struct Swept {
    posed: Vec<Vec3>,
    pairs: Vec<(u32, u32, f64)>,
    moved: Vec<bool>,
    penetration: Penetration,
    added: AddedCurve,
}

/// The character at rest, measured once for every shape.
pub(super) struct Guard<'a> {
    points: &'a [Vec3],
    character: &'a [[f32; 3]],
    triangles: &'a [[u32; 3]],
    bvh: TriangleBvh,
    /// Crossing pairs at rest, `(a, b, length)` sorted.
    rest_pairs: Vec<(u32, u32, f64)>,
    /// `(triangle, piece)`: the triangle crosses that other piece at rest; made when the
    /// embedded attempt first asks.
    embedded: OnceLock<HashSet<(u32, u32)>>,
    /// Each triangle's unit normal at rest (`None` when degenerate).
    rest_normal: Vec<Option<Vec3>>,
    rest: Penetration,
    /// Connected piece of each triangle and each vertex.
    triangle_piece: Vec<u32>,
    vertex_piece: &'a [u32],
    n_pieces: usize,
    adjacency: Adjacency,
    rows: MatrixRows,
    /// `rank[order[s]] == s`.
    rank: Vec<usize>,
    /// `m_u`, per vertex.
    margin: Vec<f64>,
    stiffness: f64,
    tolerance: f64,
    /// Radius of a held vertex's region (`REACH` template edges).
    reach: f64,
}

impl<'a> Guard<'a> {
    #[allow(clippy::too_many_arguments)]
    pub(super) fn new(
        points: &'a [Vec3],
        character: &'a [[f32; 3]],
        triangles: &'a [[u32; 3]],
        (vertex_piece, n_pieces): (&'a [u32], usize),
        matrix: &SymmetricMatrix,
        order: &[usize],
        params: &super::CarryParams,
        template_edge: f64,
        diagonal: f64,
    ) -> Self {
        let bvh = TriangleBvh::build(points, triangles);
        let rest_pairs = crossings(points, triangles, &bvh, None);
        let rest_normal = triangles.iter().map(|t| unit_normal(t.map(|w| points[w as usize]))).collect();
        let triangle_piece: Vec<u32> = triangles.iter().map(|t| vertex_piece[t[0] as usize]).collect();
        let rest = shape_penetration(&rest_pairs, &[], &vec![true; triangles.len()], &triangle_piece);
        let adjacency = Adjacency::from_triangles(points.len(), triangles);
        let margin = adjacency.mean_edge_lengths(points).iter().map(|mean| (params.collision_margin * mean).max(1e-3 * diagonal)).collect();
        let mut rank = vec![0usize; order.len()];
        order.iter().enumerate().for_each(|(slot, &v)| rank[v] = slot);
        Self {
            points,
            character,
            triangles,
            bvh,
            rest_pairs,
            embedded: OnceLock::new(),
            rest_normal,
            rest,
            triangle_piece,
            vertex_piece,
            n_pieces,
            adjacency,
            rows: matrix.rows(),
            rank,
            margin,
            stiffness: params.collision_stiffness,
            tolerance: params.collision_tolerance * diagonal,
            reach: REACH * template_edge,
        }
    }

    /// The character's own penetration at rest.
    pub(super) fn rest(&self) -> Penetration {
        self.rest
    }

    /// The excess of `deltas` over what the template's shape allows (`template`, both parts
    /// summed) and its penetration, as the pass judges a round; whether that is within the
    /// tolerance (not worse than the template).
    pub(super) fn judge(&self, deltas: &[[f32; 3]], template: &AddedCurve) -> (f64, bool, Penetration) {
        let swept = self.sweep(deltas);
        let excess = swept.added.excess_parts(template).total();
        (excess, excess <= self.tolerance, swept.penetration)
    }

    /// The positions written for `deltas` (f32 sums, as the keys are measured), the crossing
    /// pairs of the moved triangles and the curve added to the rest.
    fn sweep(&self, deltas: &[[f32; 3]]) -> Swept {
        let posed = self.posed(deltas);
        let moved: Vec<bool> = self.triangles.iter().map(|t| t.iter().any(|&v| deltas[v as usize] != [0.0; 3])).collect();
        let pairs = crossings(&posed, self.triangles, &self.bvh.refitted(&posed, self.triangles), Some(&moved));
        self.swept(posed, pairs, moved)
    }

    /// [`Self::sweep`] of a round that changed `plain`'s deltas in `region` only: the triangles
    /// with a corner there are swept again (one hierarchy query each), `plain`'s other pairs
    /// kept; the same pairs and lengths as a full sweep (`crossings_of`).
    fn resweep(&self, plain: &Swept, deltas: &[[f32; 3]], region: &[bool]) -> Swept {
        let posed = self.posed(deltas);
        let touched: Vec<bool> = self.triangles.iter().map(|t| t.iter().any(|&v| region[v as usize])).collect();
        let listed: Vec<u32> = (0..self.triangles.len() as u32).filter(|&t| touched[t as usize]).collect();
        let moved: Vec<bool> = plain.moved.iter().zip(&touched).map(|(&m, &t)| m || t).collect();
        let mut pairs: Vec<(u32, u32, f64)> =
            plain.pairs.iter().copied().filter(|&(a, b, _)| !touched[a as usize] && !touched[b as usize]).collect();
        pairs.extend(crossings_of(&posed, self.triangles, &self.bvh.refitted(&posed, self.triangles), &listed));
        pairs.sort_by_key(|&(a, b, _)| (a, b));
        self.swept(posed, pairs, moved)
    }

    fn posed(&self, deltas: &[[f32; 3]]) -> Vec<Vec3> {
        self.character.iter().zip(deltas).map(|(p, d)| [0, 1, 2].map(|a| (p[a] + d[a]) as f64)).collect()
    }

    fn swept(&self, posed: Vec<Vec3>, pairs: Vec<(u32, u32, f64)>, moved: Vec<bool>) -> Swept {
        let penetration = shape_penetration(&pairs, &self.rest_pairs, &moved, &self.triangle_piece);
        let added = AddedCurve::from_penetrations(&penetration, &self.rest);
        Swept { posed, pairs, moved, penetration, added }
    }

    /// The carried shape `solved` (f64, static vertices zero) held off the surfaces it goes
    /// through beyond what the template's shape allows (`template`, [`TemplateCurve::allowed`]
    /// on the character's neutral), its normal equations'
    /// right-hand side being `rhs` (per vertex) and `matrix` the character's screened matrix.
    pub(super) fn resolve(
        &self,
        solved: &[Vec3],
        rhs: &[Vec3],
        static_vertex: &[bool],
        template: &AddedCurve,
        matrix: &SymmetricMatrix,
    ) -> ShapesmithResult<(Vec<[f32; 3]>, CarryCollision, Penetration)> {
        let plain: Vec<[f32; 3]> = solved.iter().map(|d| d.map(|x| x as f32)).collect();
        let plain_sweep = self.sweep(&plain);
        let plain_excess = plain_sweep.added.excess_parts(template);
        let mut outcome = CarryCollision { plain_excess: plain_excess.total(), excess: plain_excess.total(), ..Default::default() };
        if plain_excess.total() <= self.tolerance {
            return Ok((plain, outcome, plain_sweep.penetration));
        }
        let mut best = plain.clone();
        let mut best_penetration = plain_sweep.penetration;
        for rule in ATTEMPTS {
            if outcome.excess <= self.tolerance {
                break;
            }
            let mut parts = plain_excess;
            let mut targets: BTreeMap<usize, Vec3> = BTreeMap::new();
            let mut current = plain.clone();
            let mut current_sweep = None;
            for _ in 0..ROUNDS {
                let sweep = current_sweep.as_ref().unwrap_or(&plain_sweep);
                if !self.hold(&sweep.posed, &sweep.pairs, &current, static_vertex, parts, rule, &mut targets) {
                    break;
                }
                let (round, region) = self.local_solve(solved, rhs, static_vertex, &targets, matrix)?;
                outcome.solves += 1;
                let round_sweep = self.resweep(&plain_sweep, &round, &region);
                let round_parts = round_sweep.added.excess_parts(template);
                let taken = rule != HoldRule::Embedded || round_parts.total() <= self.tolerance;
                if taken && round_parts.total() < outcome.excess {
                    outcome = CarryCollision { excess: round_parts.total(), applied: true, held_vertices: targets.len(), ..outcome };
                    best = round.clone();
                    best_penetration = round_sweep.penetration;
                }
                if round_parts.total() <= self.tolerance {
                    break;
                }
                (parts, current, current_sweep) = (round_parts, round, Some(round_sweep));
            }
        }
        Ok((best, outcome, best_penetration))
    }

    /// Adds (or moves further) the targets of the free corners of the new crossing pairs of
    /// the parts in excess (module docs, "Holds"); whether any was added or moved.
    #[allow(clippy::too_many_arguments)]
    fn hold(
        &self,
        posed: &[Vec3],
        swept: &[(u32, u32, f64)],
        deltas: &[[f32; 3]],
        static_vertex: &[bool],
        parts: AddedCurve,
        rule: HoldRule,
        targets: &mut BTreeMap<usize, Vec3>,
    ) -> bool {
        let mut piece_moves = vec![false; self.n_pieces];
        for (v, d) in deltas.iter().enumerate() {
            piece_moves[self.vertex_piece[v] as usize] |= *d != [0.0; 3];
        }
        // A pair crossing at rest is left alone; in the embedded attempt, only while its curve
        // does not grow (skin resting in the teeth that slides deeper into them along the
        // pairs it rests on).
        let growth = if rule == HoldRule::Embedded { 1.0 + REST_GROWTH } else { f64::INFINITY };
        let at_rest = |a: u32, b: u32, l: f64| {
            self.rest_pairs.binary_search_by_key(&(a, b), |p| (p.0, p.1)).is_ok_and(|i| l <= self.rest_pairs[i].2 * growth)
        };
        let mut pushes: BTreeMap<usize, Vec3> = BTreeMap::new();
        let embedded = || {
            self.embedded.get_or_init(|| {
                let piece = |t: u32| self.triangle_piece[t as usize];
                self.rest_pairs.iter().filter(|&&(a, b, _)| piece(a) != piece(b)).flat_map(|&(a, b, _)| [(a, piece(b)), (b, piece(a))]).collect()
            })
        };
        for &(a, b, l) in swept {
            let inside = self.triangle_piece[a as usize] == self.triangle_piece[b as usize];
            let part_excess = if inside { parts.inside } else { parts.between };
            if part_excess <= 0.0 || at_rest(a, b, l) {
                continue;
            }
            for (mine, other) in [(a, b), (b, a)] {
                for &u in &self.triangles[mine as usize] {
                    let u = u as usize;
                    if static_vertex[u] {
                        continue;
                    }
                    let other_piece = self.triangle_piece[other as usize];
                    let push = if rule == HoldRule::AlongPath {
                        let back = scale(sub(self.points[u], posed[u]), 0.5);
                        (length(back) > 1e-3 * self.margin[u]).then_some(back)
                    } else if !inside && !piece_moves[other_piece as usize] {
                        if rule == HoldRule::Embedded && embedded().contains(&(mine, other_piece)) {
                            let back = sub(self.points[u], posed[u]);
                            (length(back) > 0.0).then_some(back)
                        } else {
                            self.off_static_piece(posed[u], u, other_piece, rule != HoldRule::Margin)
                        }
                    } else {
                        let other_moves = self.triangles[other as usize].iter().any(|&w| deltas[w as usize] != [0.0; 3]);
                        self.off_plane(posed, u, other as usize).map(|p| if other_moves { scale(p, 0.5) } else { p })
                    };
                    if let Some(push) = push {
                        let entry = pushes.entry(u).or_insert([0.0; 3]);
                        if length(push) > length(*entry) {
                            *entry = push;
                        }
                    }
                }
            }
        }
        let changed = !pushes.is_empty();
        for (u, push) in pushes {
            targets.insert(u, add(posed[u], push));
        }
        changed
    }

    /// The push taking vertex `u` (now at `x`) to its rest side of static piece `piece`, at
    /// its closest point there plus the margin (back to rest when it moved at most twice the
    /// margin); `None` when it is on that side beyond the margin.
    fn off_static_piece(&self, x: Vec3, u: usize, piece: u32, back_to_rest: bool) -> Option<Vec3> {
        let on_piece = |t: u32| self.triangle_piece[t as usize] == piece;
        let side = |p: Vec3| -> Option<(f64, Vec3, Vec3)> {
            let hit = self.bvh.closest_point_where(&p, f64::INFINITY, on_piece)?;
            let n = self.rest_normal[hit.triangle as usize]?;
            Some((dot(sub(p, hit.point), n), n, hit.point))
        };
        let (rest_height, ..) = side(self.points[u])?;
        let (height, n, point) = side(x)?;
        let s = rest_height.signum();
        let m = self.margin[u];
        if height * s >= m {
            return None;
        }
        // Skin resting on the piece (a lid on its eyeball, a lip on the teeth) that moved at
        // most half an edge (twice the margin) goes back to where it rests, which crosses the
        // piece as the neutral does, rather than out to the margin.
        let rest = self.points[u];
        Some(if back_to_rest && length(sub(x, rest)) <= 2.0 * m { sub(rest, x) } else { sub(add(point, scale(n, s * m)), x) })
    }

    /// `(s m_u - h) n`: the push taking vertex `u` to its rest side of triangle `other`'s plane
    /// plus the margin; `None` when it is there already.
    fn off_plane(&self, posed: &[Vec3], u: usize, other: usize) -> Option<Vec3> {
        let tri = self.triangles[other];
        let rest_normal = self.rest_normal[other]?;
        let s = dot(sub(self.points[u], self.points[tri[0] as usize]), rest_normal).signum();
        let n = unit_normal(tri.map(|w| posed[w as usize]))?;
        let h = dot(sub(posed[u], posed[tri[0] as usize]), n);
        let m = self.margin[u];
        (h * s < m).then(|| scale(n, s * m - h))
    }

    /// The shape re-solved on the free vertices around the held ones (the region, returned),
    /// `targets` soft, the rest of it as `solved`.
    fn local_solve(
        &self,
        solved: &[Vec3],
        rhs: &[Vec3],
        static_vertex: &[bool],
        targets: &BTreeMap<usize, Vec3>,
        matrix: &SymmetricMatrix,
    ) -> ShapesmithResult<(Vec<[f32; 3]>, Vec<bool>)> {
        let n = self.points.len();
        // Free vertices within reach of a held vertex (rest distances), by a flood over edges.
        let mut in_region = vec![false; n];
        let mut reached_from = vec![usize::MAX; n];
        for (&u, target) in targets {
            let radius = self.reach.max(3.0 * length(sub(*target, add(self.points[u], solved[u]))));
            let mut stack = vec![u];
            reached_from[u] = u;
            in_region[u] = true;
            while let Some(v) = stack.pop() {
                for &w in self.adjacency.neighbours(v) {
                    let w = w as usize;
                    if static_vertex[w] || reached_from[w] == u || length(sub(self.points[w], self.points[u])) > radius {
                        continue;
                    }
                    reached_from[w] = u;
                    in_region[w] = true;
                    stack.push(w);
                }
            }
        }
        let kept: Vec<usize> = (0..n).filter(|&v| in_region[v]).collect();
        let mut position = vec![u32::MAX; n];
        kept.iter().enumerate().for_each(|(p, &v)| position[v] = p as u32);
        let extra: Vec<(usize, f64)> = targets.keys().map(|&u| (u, self.stiffness * matrix.diagonal(u))).collect();
        let factor = matrix.factor_subset_plus_diagonal(&kept, &position, &self.rank, &extra)?;
        let mut local_rhs: Vec<Vec3> = kept
            .iter()
            .map(|&v| {
                self.rows.row(v).iter().filter(|&&(c, _)| position[c] == u32::MAX).fold(rhs[v], |acc, &(c, a)| sub(acc, scale(solved[c], a)))
            })
            .collect();
        for &(u, w) in &extra {
            let p = position[u] as usize;
            local_rhs[p] = add(local_rhs[p], scale(sub(targets[&u], self.points[u]), w));
        }
        let local = factor.solve_points(&local_rhs);
        let mut deltas: Vec<[f32; 3]> = solved.iter().map(|d| d.map(|x| x as f32)).collect();
        for (p, &v) in kept.iter().enumerate() {
            deltas[v] = local[p].map(|x| x as f32);
        }
        Ok((deltas, in_region))
    }
}

fn unit_normal(t: [Vec3; 3]) -> Option<Vec3> {
    let n = cross(sub(t[1], t[0]), sub(t[2], t[0]));
    let len = length(n);
    (len > 0.0).then(|| scale(n, 1.0 / len))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::penetration::measure_penetration;
    use crate::progress::NoProgress;
    use crate::wrap::{carry_shapes, CarryParams};

    /// Two lip layers of one piece: a strip folded into a U along x (upper layer at `z = gap`
    /// from x = 4 to 0, a half-turn of radius `gap`, the lower layer at `z = -gap` back to x =
    /// 4), `nu` by `ny` quads over y in [0, 2]; normals into the mouth.
    fn lips(gap: f64, nu: usize, ny: usize) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let at = |u: f64, y: f64| -> [f32; 3] {
            let p = if u < 0.4 {
                [4.0 * (1.0 - u / 0.4), y, gap]
            } else if u < 0.6 {
                let angle = std::f64::consts::PI * (u - 0.4) / 0.2;
                [-gap * angle.sin(), y, gap * angle.cos()]
            } else {
                [4.0 * (u - 0.6) / 0.4, y, -gap]
            };
            p.map(|x| x as f32)
        };
        let points: Vec<[f32; 3]> =
            (0..=ny).flat_map(|j| (0..=nu).map(move |i| (i, j))).map(|(i, j)| at(i as f64 / nu as f64, 2.0 * j as f64 / ny as f64)).collect();
        let mut triangles = crate::geometry::topology::grid_triangles(nu as u32 + 1, ny as u32 + 1, 0);
        let corner = |v: u32| points[v as usize].map(f64::from);
        let first = triangles[0];
        if cross(sub(corner(first[1]), corner(first[0])), sub(corner(first[2]), corner(first[0])))[2] > 0.0 {
            triangles.iter_mut().for_each(|t| t.swap(1, 2));
        }
        (points, triangles)
    }

    /// The lips closing by `amount` each around (2.5, 1), static beyond 1.2.
    fn closing(points: &[[f32; 3]], amount: f64) -> Vec<[f32; 3]> {
        points
            .iter()
            .map(|p| {
                let (x, y, z) = (p[0] as f64, p[1] as f64, p[2] as f64);
                let bump = (1.0 - ((x - 2.5).powi(2) + (y - 1.0).powi(2)) / 1.44).max(0.0).powi(3);
                [0.0, 0.0, (-z.signum() * amount * bump) as f32]
            })
            .collect()
    }

    fn posed(points: &[[f32; 3]], deltas: &[[f32; 3]]) -> Vec<[f32; 3]> {
        points.iter().zip(deltas).map(|(p, d)| [0, 1, 2].map(|a| p[a] + d[a])).collect()
    }

    /// The carry of the template's closing onto the character, with the template's added
    /// curve (none) given or not.
    fn carried(amount: f64, collisions: bool) -> (Vec<[f32; 3]>, Vec<[u32; 3]>, crate::wrap::CarryResult) {
        carried_with(amount, collisions, &CarryParams::default())
    }

    fn carried_with(amount: f64, collisions: bool, params: &CarryParams) -> (Vec<[f32; 3]>, Vec<[u32; 3]>, crate::wrap::CarryResult) {
        let (template, template_triangles) = lips(1.0, 20, 8);
        let (character, character_triangles) = lips(0.5, 40, 16);
        let deltas = closing(&template, amount);
        // The template's lips close without touching: it adds no curve.
        assert_eq!(measure_penetration(&posed(&template, &deltas), &template_triangles).pairs, 0);
        let none = [TemplateCurve::default()];
        let result = carry_shapes(
            &template,
            &template_triangles,
            &deltas,
            &character,
            &character_triangles,
            collisions.then_some(&none[..]),
            None,
            None,
            params,
            &NoProgress,
        )
        .unwrap();
        (character, character_triangles, result)
    }

    #[test]
    fn lips_closer_than_the_templates_stay_apart_and_still_close() {
        let (character, triangles, plain) = carried(0.9, false);
        let crossed = measure_penetration(&posed(&character, &plain.deltas), &triangles);
        assert!(crossed.length > 0.5, "the plain carry should push the lips through each other: {crossed:?}");
        let (_, _, held) = carried(0.9, true);
        let outcome = held.collisions[0];
        assert!(outcome.applied && outcome.plain_excess > 0.5, "{outcome:?}");
        let after = measure_penetration(&posed(&character, &held.deltas), &triangles);
        assert_eq!(after.pairs, 0, "{after:?}, {outcome:?}");
        // The pass's own numbers are the full sweep's, and its verdict the criterion's.
        let penetration = held.penetration.as_ref().unwrap();
        assert_eq!((penetration.shapes[0], penetration.neutral), (after, measure_penetration(&character, &triangles)));
        assert_eq!(penetration.excess, vec![AddedCurve::default()]);
        // The lips still close: the gap at the centre (x = 2.5, y = 1), 1.0 at rest, is
        // within a few margins (0.25 x the 0.25 edge, each side). Measured: the plain carry
        // crosses along 3.0 (64 pairs), the pass clears it in 4 re-solves, gap 0.085.
        let centre = |z: f32| character.iter().position(|p| (p[0] - 2.5).abs() < 1e-4 && (p[1] - 1.0).abs() < 1e-4 && p[2] == z).unwrap();
        let (upper, lower) = (centre(0.5), centre(-0.5));
        let gap = (character[upper][2] + held.deltas[upper][2]) - (character[lower][2] + held.deltas[lower][2]);
        assert!(gap > 0.0 && gap < 0.2, "gap {gap}");
    }

    /// A sheet of skin (15 x 15 vertices over the unit square, z = 0) through a box of teeth
    /// (a separate piece over [0.3, 0.7]^2, z from -0.5 to 0.02): the sheet cuts the box's
    /// walls at rest, as lips rest in the teeth.
    fn skin_through_teeth() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let w = 15u32;
        let mut points: Vec<[f32; 3]> = (0..w * w).map(|i| [(i % w) as f32 / (w - 1) as f32, (i / w) as f32 / (w - 1) as f32, 0.0]).collect();
        let mut triangles = crate::geometry::topology::grid_triangles(w, w, 0);
        let start = points.len() as u32;
        for c in 0..8u32 {
            points.push([0.3 + 0.4 * (c & 1) as f32, 0.3 + 0.4 * ((c >> 1) & 1) as f32, if c >> 2 == 1 { 0.02 } else { -0.5 }]);
        }
        for quad in [[0u32, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]] {
            triangles.push([start + quad[0], start + quad[1], start + quad[2]]);
            triangles.push([start + quad[0], start + quad[2], start + quad[3]]);
        }
        (points, triangles)
    }

    #[test]
    fn skin_sliding_deeper_into_the_teeth_it_rests_in_is_held_back() {
        // The sheet inside the box sinks by up to 0.2 (0.06 at the walls): it crosses the
        // walls along the same 48 pairs as at rest, on a longer, curved line. The template
        // adds no curve, so all of the growth is excess; the pass holds the growing rest pairs
        // and puts the skin cutting the walls back at rest, while the middle still sinks
        // (measured: plain excess 0.070, kept 1.2e-6, middle at -0.105).
        let (points, triangles) = skin_through_teeth();
        let deltas: Vec<[f32; 3]> = (0..points.len())
            .map(|v| {
                let p = points[v];
                let r2 = (p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2);
                if v < 225 { [0.0, 0.0, -0.2 * (1.0 - r2 / 0.09).max(0.0).powi(2)] } else { [0.0; 3] }
            })
            .collect();
        let none = [TemplateCurve::default()];
        let result = carry_shapes(&points, &triangles, &deltas, &points, &triangles, Some(&none[..]), None, None, &CarryParams::default(), &NoProgress).unwrap();
        let (rest, kept) = (measure_penetration(&points, &triangles), measure_penetration(&posed(&points, &result.deltas), &triangles));
        assert_eq!(rest.pairs, 48);
        let outcome = result.collisions[0];
        assert!(outcome.applied && outcome.plain_excess > 0.05 && outcome.excess < 1e-4, "{outcome:?}");
        assert!(kept.pairs == rest.pairs && (kept.length - rest.length).abs() < 1e-4, "{kept:?} against {rest:?}");
        let middle = points.iter().position(|p| p[0] == 0.5 && p[1] == 0.5).unwrap();
        // Deeper than the plain carry takes the skin at the walls (0.06).
        assert!(result.deltas[middle][2] < -0.08, "{:?}", result.deltas[middle]);
    }

    #[test]
    fn a_shape_meeting_the_criterion_is_unchanged_bit_for_bit() {
        let (character, triangles, plain) = carried(0.2, false);
        assert_eq!(measure_penetration(&posed(&character, &plain.deltas), &triangles).pairs, 0);
        let (_, _, guarded) = carried(0.2, true);
        assert!(plain.deltas.iter().any(|d| d[2] != 0.0));
        assert_eq!(plain.deltas, guarded.deltas);
        assert!(!guarded.collisions[0].applied && guarded.collisions[0].excess == 0.0);
    }

    #[test]
    fn without_the_pass_the_carried_shapes_are_judged_and_left_as_carried() {
        let (character, triangles, plain) = carried(0.9, false);
        assert!(plain.penetration.is_none() && plain.collisions.is_empty());
        let judged_only = CarryParams { collision_pass: false, ..CarryParams::default() };
        let (_, _, judged) = carried_with(0.9, true, &judged_only);
        assert_eq!(judged.deltas, plain.deltas);
        assert!(judged.collisions.is_empty());
        // The template adds no curve: all the lips' crossing is excess, inside one piece.
        let crossed = measure_penetration(&posed(&character, &plain.deltas), &triangles);
        let penetration = judged.penetration.as_ref().unwrap();
        assert_eq!((penetration.shapes[0], penetration.neutral), (crossed, measure_penetration(&character, &triangles)));
        let excess = penetration.excess[0];
        assert!(excess.between == 0.0 && excess.inside > 0.5, "{excess:?}");
        assert!((excess.inside - (crossed.length - penetration.neutral.length)).abs() < 1e-12, "{excess:?} {crossed:?}");
    }
}
