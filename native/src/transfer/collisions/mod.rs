//! Collision-aware pass (SPEC section 3, after Ichim et al. 2016's collision handling): after
//! a shape is solved, a result that adds more intersection curve to the target's neutral than
//! the template's own shape adds to the template's has the vertices that went through another
//! surface held on the side they were on at rest (plus a margin) and is re-solved around
//! them; a few rounds at most, and the round with least excess over the template is kept.
//!
//! **Judge first.** The result is swept (triangles with a moving corner; two unmoved
//! triangles cross exactly as at rest) and its added curve compared with what the template's
//! shape allows (from the report's template numbers when given, else one sweep of the
//! template shape), part by part: inside one piece and between pieces, the more of the curve
//! the template's shape adds to its neutral (a removal allowing none) and its own curve beyond
//! the target neutral's ([`TemplateCurve::allowed`], SPEC 3's criterion). A shape adding no
//! more is returned untouched, bit for bit: the criterion is "no more than the template", so
//! the artist's own contacts (lips pressed together in mouthClose) stay, a template whose
//! neutral crosses where the target's does not is copied as it is, and self-transfer stays
//! exact.
//!
//! **Which pairs.** Pairs of the part in excess only, sharing no vertex, crossing in the
//! result, not at the target's rest (or at rest with over 5% more curve: skin resting in an
//! eyeball or the teeth adds curve by sliding along pairs that already cross), and not near a
//! pair the template's shape adds: some triangle sharing a corner with one crosses some
//! triangle sharing a corner with the other in the template's shape and not at the
//! template's rest (the template's crossing triangles are listed once per shape, then each
//! pair is a lookup). Only vertices the solve is free to move (moving, in a piece anchored by
//! its static vertices) are held. When every pair of the part in excess lies near a template
//! contact (the template's skin slides a little along its teeth, the target's far more), the
//! pairs of that part are acted on regardless of the template's contacts. Of the pairs of the
//! part in excess, only those of two pieces (or one piece with itself) whose own curve grew
//! are acted on ([`contacts::pieces_grown`]): skin sliding out of the teeth it rests in while
//! the lids slide into the eyeballs adds curve between pieces, but pushing it off the teeth
//! does nothing for the eyeballs and presses the lips into each other. When the pairs left
//! hold no vertex, all pairs of the part in excess (of pieces whose curve grew) are tried.
//!
//! **Which vertices, and where to.** A vertex that the template's own shape takes to the other
//! side of the corresponding obstacle (the same triangle's plane, the same static piece's
//! surface, read on the template's neutral and shape; the topology is shared) is never held:
//! there the target follows the artist. Against a piece that is static in the shape (teeth, an
//! eyeball, lashes: an obstacle exactly where the target's neutral has it), a corner of a new
//! pair offends when it is on the other side of that piece's surface than at rest, the side
//! read at its closest point on the piece (`TriangleBvh::closest_point_where`); its target is
//! that closest point plus the margin along the surface normal. A corner that moved at most
//! half an edge goes back to rest instead, where its triangle crosses the piece as in the
//! neutral. Against a surface that moves
//! too (lip through lip), it offends when it is on the other side of the other triangle's
//! plane than at rest; its target is pushed along that plane's normal to the rest side plus
//! the margin, `t_u = x_u + (s m_u - h) n` (`s` the rest side, `h` the signed distance now),
//! half of it when the other triangle can move (its corners get the other half from the pair
//! seen the other way round). Triangle pairs cross only along a curve, so the vertices beyond
//! it are reached by a flood over mesh neighbours with the same tests. The margin `m_u` is
//! `margin` x the mean length of the edges at `u`, at least `min_margin` x the diagonal.
//!
//! **Constraint and local re-solve.** The energy gains `w_u |d_u - (t_u - B0_u)|^2`, `w_u =
//! stiffness x A_uu`: a point target with a scalar weight adds the same number to the
//! diagonal of the x, y and z systems, so the coordinates stay separable (a half-space term
//! would couple them). Only the free vertices within reach of a held vertex (3 edge lengths,
//! or 3x its push) are unknowns; the rest of the shape stays as solved (Dirichlet), so a
//! round factorises a small system (`NormalMatrix::solve_local`) instead of the shape's.
//! Targets and the region accumulate over the rounds. Of the plain solve and the rounds,
//! the one with least excess over the template is kept: it never makes a shape worse.
//!
//! **Folds.** A triangle the plain solve turns over (normal against the target neutral's)
//! while the template's shape keeps it upright, with a corner a virtual-edge spring pulls at,
//! was folded by the springs (the dense heads' jawOpen and mouthClose: without virtual edges
//! they add no curve). There a side test reads the turned-over triangle's plane the wrong way
//! round, and holds push the lips into each other (Deviations). A pair with such a triangle
//! is not held: the springs with an end within reach of its corners (the region's rule) are
//! released in the local re-solve (`NormalMatrix::solve_local`'s `released`: out of the
//! region's rows, which follow the gradients alone), and a round that releases springs anew
//! holds nothing; later rounds hold the other pairs as before. A shape no spring folds is
//! untouched by this.
//!
//! **Attempts.** A shape still worse than the template after the rounds is tried again from
//! its plain solve with other holds (`ATTEMPTS`): twice the margin, then ten times the
//! stiffness, then holding the whole lip contact strip (a vertex on its rest side of the other
//! lip's plane but nearer than the margin is held at the margin too, so the re-solve cannot
//! pull the crossing's neighbours through), then sending skin back to rest against a static
//! piece the template's shape adds no curve to (rest), then following the template's own
//! contacts (follow: holds near them too, a lip vertex placed where the template's shape has it
//! relative to the same triangle), then, last, the follow attempt with the skin that rests
//! across a static piece kept where it rests (embedded: a corner of a new pair against a static
//! piece goes back to rest when its triangle crosses the same piece at the target's rest,
//! whichever side the corner is on, or when the corner is on its rest side of the piece; skin
//! resting in the teeth adds curve by sliding along them with every corner on its rest side,
//! a tooth's edge through its triangles, which no side test sees). The attempt with least
//! excess is kept, and the next is tried only while the shape is still worse; the embedded
//! attempt, which holds skin that the template moves, is kept only when it clears the shape. No single setting clears every shape
//! (Deviations). Every attempt starts from the plain solve, so its sweep and the template
//! shape's contacts are found once per shape (`PlainRound`); the later attempts run two side
//! by side (the few shapes needing them are a dozen rounds each, the last to finish otherwise)
//! and are then taken in order, so the result is the same as one after the other.
//!
//! **Re-sweeps.** A re-solve changes its region's rows only, so a round's positions, written
//! positions and hierarchy are updated there only (`TriangleBvh::refit_listed` from a copy of
//! the plain solve's), and only the triangles with a corner written elsewhere are swept
//! again, one hierarchy query each (`crossings_of`); the other pairs are kept. Every number
//! is the same to the bit as a full sweep's (tested in `geometry/`).
//!
//! # Deviations (measured with `native/examples/collision_counts.rs` on the arrays of
//! `scripts/save_collision_arrays.py`; shapes worse than the template after the
//! pass on Boy / OldMan / YoungWoman, issue 9's criterion)
//!
//! - Session 10 (worse after the pass on Boy / OldMan / YoungWoman / 19k / 25k, warp; `face_*`
//!   0 throughout): from 0 / 0 / 0 / 1 / 2, +4.2% (19k mouthClose +1.12 cm inside; 25k jawOpen
//!   +7.67 cm inside, mouthClose +3.83 inside / +2.39 between). Diagnosis (excess in 1e-3 of
//!   the diagonal): on 25k both shapes' plain transfer without virtual edges adds no curve
//!   (0.0 / 0.0); with them jawOpen adds 213.0 inside, all 370 pairs acted on in the lips,
//!   and the solve turns 337 triangles over that the template's shape keeps upright (it turns
//!   65 others over): the springs fold the lips (mouthClose: 286). 160 of the 370 pairs have a
//!   turned-over triangle, 293 of 1108 pushes went across a turned-over triangle's plane (its
//!   normal reversed, so the side test reads the wrong side), and each round's pairs were the
//!   holds' own (round 1: 405 of 495 pairs new, 492 with a held corner; turned-over
//!   triangles in the region 57 -> 111 -> 168 -> 220): excess 213 -> 291 -> 389 -> 453 ->
//!   812. Tried: no push across a turned-over triangle, 25k jawOpen +6.01 cm, 19k mouthClose
//!   +0.53; releasing every spring in the local region, holds kept: 19k 0, 25k unchanged;
//!   both: jawOpen +2.78, mouthClose +5.57 / 0; releasing with no hold at all: jawOpen and
//!   mouthClose 0 / +0.65 between, 12 other 25k shapes worse (they need holds); fold pairs
//!   read on each round's positions: 25k mouthLeft/Right +0.98 between (folds the holds made);
//!   without the spring-end condition, YoungWoman's eyeSquintLeft/Right (5 triangles turned
//!   over, no spring at them, the same without virtual edges) 0 -> 0.64 (below 1) or 7.9 when
//!   no fold pair may be held. Kept ("Folds"): **0 / 0 / 0 / 0 / 0, +4.2%** (warp digits the
//!   same); 25k jawOpen 213.0 -> 0, mouthClose 106.3 / 66.4 -> 0 / 0, 19k mouthClose 31.1 / 0
//!   -> 0. Shapes whose bits change: those five with spring folds (19k jawOpen, mouthClose; 25k
//!   jawOpen, mouthClose; face_19k jawOpen), every other shape of the ten heads bit for bit.
//!   Cost in shape, vertices moved by over 10% of the shape's largest delta from the
//!   virtual-edge solve, before / after (largest move in mm, of the shape's largest delta):
//!   19k jawOpen 0 / 44 (3.2 / 11.2 of 40.0), face_19k jawOpen 0 / 50 (2.6 / 11.9 of 38.4),
//!   19k mouthClose 1318 / 41 (30.9 / 10.3 of 30.9), 25k jawOpen 0 / 127 (- / 12.8 of 40.6),
//!   mouthClose 0 / 156 (- / 10.8 of 30.2): the lips around a fold follow the gradients
//!   without the springs. Pass seconds on the 25k head (`time_transfer`, before and after
//!   alternately, load 4-6 from other work, two runs of 3): 4.76 / 3.28 / 4.11 and 2.91 / 2.66
//!   / 2.88 against 1.72 / 1.99 / 2.54 and 1.58 / 1.62 / 0.98, best -48% and -63%; local
//!   re-solves 188 -> 135; bits edabb6258832579c -> d66bb356a4a6bde1.
//! - Earlier rounds (from 5 / 5 / 5 down to 0 / 0 / 0 / 1 / 2, what was tried and dropped, with
//!   the numbers): docs/transfer.md, "Earlier rounds of the collision pass".

mod contacts;
mod guard;
mod holds;

use std::sync::atomic::{AtomicBool, Ordering};
use std::collections::BTreeMap;
use std::sync::OnceLock;

use rayon::prelude::*;

pub use crate::geometry::penetration::{AddedCurve, TemplateCurve};
use contacts::{piece_key, pieces_grown, TemplateContacts};
pub(super) use guard::CollisionGuard;
use guard::Neutral;

use super::deformation::DeformationTransfer;
use super::gradients::{add, length, sub, Vec3};
use super::system::RestrictedFactor;
use crate::error::ShapesmithResult;
use crate::geometry::bvh::TriangleBvh;
use crate::geometry::penetration::{crossings, crossings_of, shape_penetration, Penetration};

/// Knobs of the collision pass, defaults from SPEC section 3.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct CollisionParams {
    /// Distance kept from the other surface, as a fraction of the mean length of the edges at
    /// the vertex on the target's neutral (SPEC: 25%).
    pub margin: f64,
    /// The least distance kept, as a fraction of the target neutral's bounding-box diagonal
    /// (a floor where edges are very short; larger floors hold vertices off where the true
    /// shape comes closer: see the module's measurements in `transfer/mod.rs`).
    pub min_margin: f64,
    /// Re-solves per shape at most.
    pub max_iterations: usize,
    /// Weight of a vertex's target point, as a multiple of its diagonal entry in the normal
    /// matrix (so it means the same on coarse and dense meshes).
    pub stiffness: f64,
}

impl Default for CollisionParams {
    fn default() -> Self {
        Self { margin: 0.25, min_margin: 0.001, max_iterations: 4, stiffness: 100.0 }
    }
}

/// What the collision pass did to one shape.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize)]
pub struct CollisionOutcome {
    /// Crossing pairs new after the plain solve (not at the target's rest, not in the
    /// template's shape).
    pub new_pairs: usize,
    /// New pairs left in the result kept (0 when it adds no more curve than the template).
    pub remaining_pairs: usize,
    /// Vertices held by a target point.
    pub constrained_vertices: usize,
    /// Re-solves done.
    pub solves: usize,
    /// Unknowns of the last local re-solve.
    pub region_vertices: usize,
    /// Whether the result is a re-solve; `false` when the plain solve was kept (bit for bit),
    /// because it was no worse than the template or no re-solve added less curve.
    pub applied: bool,
    /// The penetration of the result kept and of the plain solve, from the pass's own sweeps
    /// of the written positions (equal to [`crate::geometry::penetration::measure_penetration`]
    /// of them to the bit): the report reads them instead of sweeping the shapes again.
    #[serde(skip)]
    pub penetration: Option<Penetration>,
    #[serde(skip)]
    pub plain_penetration: Option<Penetration>,
}

/// One shape's solve as the pass sees it.
pub(super) struct ShapeSystem<'a> {
    /// The source shape's deltas (N rows).
    pub delta: &'a [[f32; 3]],
    /// Vertices that move in the shape (free or in a floating piece).
    pub moving: &'a [bool],
    /// Per piece: floats (pinned and translated after the solve).
    pub pinned: &'a [bool],
    pub rhs: &'a [Vec3],
    /// The curve the criterion allows the shape to add to the target's neutral
    /// ([`TemplateCurve::allowed`]), when the template's numbers are known.
    pub allowed: Option<AddedCurve>,
}

/// Where a vertex that went through must go: its target position (working frame).
type Targets = BTreeMap<usize, Vec3>;

impl DeformationTransfer {
    /// The connected piece triangle `t` belongs to (that of any of its corners).
    fn triangle_piece(&self, t: u32) -> u32 {
        self.piece[self.triangles[t as usize][0] as usize]
    }

    /// Runs the pass on the solved deltas `out` (working frame) of one shape; `factor` tells
    /// which vertices the shape's solve was free to move.
    pub(super) fn collision_pass(
        &self,
        guard: &CollisionGuard,
        shape: &ShapeSystem<'_>,
        factor: &RestrictedFactor,
        out: &mut Vec<Vec3>,
    ) -> ShapesmithResult<CollisionOutcome> {
        let plain = out.clone();
        let shared = PlainRound::new(self, guard, shape, factor);
        let (mut outcome, mut excess) = self.collision_rounds(guard, shape, &shared, out, &ATTEMPTS[0], None)?;
        let mut solves = outcome.solves;
        let worse = |excess: Option<f64>| excess.filter(|&e| e > JUDGE_TOLERANCE * guard.diagonal);
        if worse(excess).is_none() {
            return Ok(outcome);
        }
        // The later attempts, each from the plain solve, two side by side: a shape that needs
        // them (a few mouth shapes, each a dozen rounds) is the last to finish otherwise. They
        // are then taken in order as if run one after the other: the next only while the shape is
        // still worse (its excess known), so the result does not depend on the threads. Once
        // the first of a pair clears the shape, the second's result is dropped: it stops at its
        // next round (or does not start, when it waits for the same thread), so the other
        // shapes get the thread.
        let first_cleared = AtomicBool::new(false);
        let run = |(index, attempt): (usize, &Attempt)| {
            let mut again = plain.clone();
            let dropped = (index == 1).then_some(&first_cleared);
            let tried = self.collision_rounds(guard, shape, &shared, &mut again, attempt, dropped);
            if index == 0 && matches!(tried, Ok((_, Some(e))) if worse(Some(e)).is_none()) {
                first_cleared.store(true, Ordering::Relaxed);
            }
            tried.map(|(next, next_excess)| (next, next_excess, again))
        };
        for pair in ATTEMPTS[1..].chunks(2) {
            if worse(excess).is_none() {
                break;
            }
            let later: Vec<_> = pair.par_iter().enumerate().map(run).collect();
            for (tried, attempt) in later.into_iter().zip(pair) {
                // Only a shape still worse than the template (its excess known) tries again.
                let Some(least) = worse(excess) else { break };
                let (next, next_excess, again) = tried?;
                solves += next.solves;
                // The embedded attempt's holds are taken only when they clear the shape.
                let taken = !attempt.embedded || worse(next_excess).is_none();
                if taken && next_excess.is_some_and(|e| e < least) {
                    *out = again;
                    outcome = CollisionOutcome { new_pairs: outcome.new_pairs, ..next };
                    excess = next_excess;
                }
            }
        }
        Ok(CollisionOutcome { solves, ..outcome })
    }

    /// One attempt of the pass: up to `max_iterations` rounds of judging, holding and
    /// re-solving, from the plain solve in `out`; leaves the best round in `out` and returns
    /// its excess over the template (`None` when the template's numbers were never needed:
    /// nothing new crosses, or the plain solve meets the criterion). Once `dropped` is set
    /// (the caller will not take this attempt) it stops before its next round.
    fn collision_rounds(
        &self,
        guard: &CollisionGuard,
        shape: &ShapeSystem<'_>,
        shared: &PlainRound,
        out: &mut Vec<Vec3>,
        attempt: &Attempt,
        dropped: Option<&AtomicBool>,
    ) -> ShapesmithResult<(CollisionOutcome, Option<f64>)> {
        let PlainRound { moved, free, static_piece, swept_rest, .. } = shared;
        let mut outcome = CollisionOutcome::default();
        let piece_of = |t: u32| self.triangle_piece(t);
        let rest_pairs = || guard.rest_pairs.iter().zip(&guard.rest_lengths).map(|(&(a, b), &l)| (a, b, l));
        let tolerance = JUDGE_TOLERANCE * guard.diagonal;
        let meets = |added: &AddedCurve, template: &Option<AddedCurve>| template.is_some_and(|t| added.excess(&t) <= tolerance);
        let mut allowed = shape.allowed;
        let mut targets = Targets::new();
        let mut region = vec![false; out.len()];
        // Where the virtual-edge springs are released: around the pairs the springs folded.
        let mut release = vec![false; out.len()];
        let mut crossing: Vec<(u32, u32, f64)> = Vec::new();
        // The vertices whose written position the last re-solve changed.
        let mut changed_vertices: Vec<usize> = Vec::new();
        let mut template: Option<&TemplateContacts> = None;
        // The hierarchy refitted to the last re-sweep's positions, refitted in place where the
        // next re-solve moves triangles.
        let mut sweep_bvh: Option<TriangleBvh> = None;
        let plain = out.clone();
        // The least excess over the template so far (the least added curve while the
        // template's is not known), the deltas that add it (empty: the plain solve), the
        // new pairs left in them and their crossing pairs.
        let mut best: Option<(f64, Vec<Vec3>, usize, Vec<(u32, u32, f64)>)> = None;
        let mut first: Option<AddedCurve> = None;
        // Whether any vertices were sought: only then can another attempt differ.
        let mut held = false;
        // The result's positions (working frame), and where it is written (the target's
        // frame, f32): swept there, so the report takes these numbers as they are. A re-solve
        // changes its region's rows only, and only those are computed again.
        let mut positions: Vec<Vec3> = self.target_neutral.iter().zip(out.iter()).map(|(p, d)| add(*p, *d)).collect();
        let mut written = self.written_positions(guard, out);
        // The plain solve, swept once per shape: every attempt starts from it.
        let (plain_crossing, plain_bvh) = shared.crossing.get_or_init(|| {
            let bvh = guard.bvh.refitted(&written, &self.triangles);
            (crossings(&written, &self.triangles, &bvh, Some(moved)), bvh)
        });
        for round in 0..=guard.params.max_iterations {
            if dropped.is_some_and(|d| d.load(Ordering::Relaxed)) {
                break;
            }
            crossing = if round == 0 {
                plain_crossing.clone()
            } else {
                // After a re-solve, only triangles with a corner written elsewhere than
                // at the last sweep are tested again (against every triangle); the others
                // cross exactly as then and keep their pairs: the same pairs and lengths,
                // to the bit, as a sweep of every moved triangle.
                let mut changed = vec![false; self.triangles.len()];
                let mut changed_list = Vec::new();
                for &v in &changed_vertices {
                    for &t in guard.triangles_at(v as u32) {
                        if !changed[t as usize] {
                            changed[t as usize] = true;
                            changed_list.push(t);
                        }
                    }
                }
                // The hierarchy of the last sweep (at the first re-solve, the plain
                // solve's, shared by every attempt) refitted where triangles moved.
                let mut bvh = sweep_bvh.take().unwrap_or_else(|| plain_bvh.clone());
                bvh.refit_listed(&guard.refit_links, &written, &self.triangles, &changed_list);
                let mut pairs: Vec<(u32, u32, f64)> =
                    crossing.iter().copied().filter(|&(a, b, _)| !changed[a as usize] && !changed[b as usize]).collect();
                // An unmoved triangle against an unmoved one crosses as at rest: counted apart.
                let swept = crossings_of(&written, &self.triangles, &bvh, &changed_list);
                pairs.extend(swept.into_iter().filter(|&(a, b, _)| moved[a as usize] || moved[b as usize]));
                pairs.sort_unstable_by_key(|&(a, b, _)| (a, b));
                sweep_bvh = Some(bvh);
                pairs
            };
            // The curve this result adds to the target's neutral (SPEC 3's criterion).
            let added = AddedCurve::of(crossing.iter().copied(), piece_of, *swept_rest);
            if first.is_none() {
                first = Some(added);
            }
            let score = |a: &AddedCurve| allowed.map_or(a.inside + a.between, |t| a.excess(&t));
            let improved = best.as_ref().is_none_or(|(b, _, _, _)| score(&added) < *b);
            if improved {
                best = Some((score(&added), if round == 0 { Vec::new() } else { out.clone() }, 0, crossing.clone()));
            }
            // New pairs, and rest pairs whose curve grew: skin resting against an eyeball or
            // the teeth adds curve by sliding deeper along pairs that already cross.
            let candidates: Vec<(u32, u32)> = crossing
                .iter()
                .filter(|&&(a, b, l)| match guard.rest_pairs.binary_search(&(a, b)) {
                    Err(_) => true,
                    Ok(i) => l > guard.rest_lengths[i] * (1.0 + REST_GROWTH),
                })
                .map(|&(a, b, _)| (a, b))
                .collect();
            // Nothing new crosses, or no more curve than the template's own shape adds.
            if candidates.is_empty() || meets(&added, &allowed) {
                break;
            }
            if template.is_none() {
                // The template shape's contacts, swept once per shape.
                let contacts = shared.template.get_or_init(|| self.template_contacts(guard, shape.delta, moved));
                if allowed.is_none() {
                    // Only the plain solve was judged so far (by added curve): judge it by
                    // its excess over the template.
                    allowed = Some(contacts.allowed);
                    best = best.map(|(_, kept, left, pairs)| (first.map_or(0.0, |f| f.excess(&contacts.allowed)), kept, left, pairs));
                }
                template = Some(contacts);
                if meets(&added, &allowed) {
                    break;
                }
            }
            let in_excess = |&(a, b): &(u32, u32)| match allowed {
                Some(t) => {
                    let over_inside = added.inside - t.inside > 0.5 * tolerance;
                    let over_between = added.between - t.between > 0.5 * tolerance;
                    if piece_of(a) == piece_of(b) { over_inside } else { over_between }
                }
                None => true,
            };
            let mut new_pairs: Vec<(u32, u32)> = match &template {
                // The rest attempt also acts near the template's contacts against a piece it
                // adds no curve to: there its contacts only slide along what its neutral has.
                Some(contacts) => candidates
                    .iter()
                    .copied()
                    .filter(|&(a, b)| {
                        let (p, q) = (piece_of(a), piece_of(b));
                        attempt.follow || (attempt.rest && p != q && contacts.adds_none(p, q)) || !contacts.near(guard, a, b)
                    })
                    .collect(),
                None => candidates.clone(),
            };
            if !new_pairs.iter().any(in_excess) {
                // Every pair of the part in excess lies near one of the template's own
                // contacts, yet the part adds more than the template's: the template's contact
                // is smaller than the target's there (skin sliding along the teeth), so the
                // pairs are acted on after all.
                new_pairs = candidates.clone();
            }
            // Only the part (inside one piece, between pieces) adding more than the template's
            // is acted on: pushing the other part's pairs moves vertices for nothing and can
            // add curve where the shape met the criterion.
            // Of those, only the pairs of two pieces (or of one piece with itself) whose own curve
            // grew: skin sliding out of the teeth it rests in while its lids slide into the
            // eyeballs adds between pieces, yet pushing it off the teeth does nothing for the
            // eyeballs and presses the lips into each other (OldMan's mouthClose).
            let swept_rest_pairs = rest_pairs().filter(|&(a, b, _)| moved[a as usize] || moved[b as usize]);
            let grown = pieces_grown(crossing.iter().copied(), swept_rest_pairs, piece_of, 0.5 * tolerance);
            let grew = |&(a, b): &(u32, u32)| grown.contains(&piece_key(piece_of(a), piece_of(b)));
            let acted_on = |pairs: &[(u32, u32)]| -> Vec<(u32, u32)> { pairs.iter().copied().filter(in_excess).filter(grew).collect() };
            let new_pairs = acted_on(&new_pairs);
            if round == 0 {
                outcome.new_pairs = new_pairs.len();
            }
            if let Some((_, _, left, _)) = best.as_mut().filter(|_| improved) {
                *left = new_pairs.len();
            }
            if new_pairs.is_empty() || round == guard.params.max_iterations {
                break;
            }
            // The template's contacts are known once a round gets here (judged above).
            let Some(contacts) = template else { break };
            held = true;
            // Pairs with a triangle the springs folded over (module docs' "Folds"): their
            // springs are released around them instead of their corners held.
            let folds = shared.folds.get_or_init(|| {
                let springs = shared.springs.get_or_init(|| self.springs(shape.delta));
                self.spring_folds(springs, &plain, &contacts.positions)
            });
            let folded = |t: u32| folds[t as usize];
            let (fold_pairs, new_pairs): (Vec<_>, Vec<_>) = new_pairs.into_iter().partition(|&(a, b)| folded(a) || folded(b));
            let fold_seeds: Vec<(usize, f64)> = fold_pairs
                .iter()
                .flat_map(|&(a, b)| self.triangles[a as usize].into_iter().chain(self.triangles[b as usize]))
                .map(|v| (v as usize, 0.0))
                .filter(|&(v, _)| free[v])
                .collect();
            let released_before = release.iter().filter(|&&r| r).count();
            self.grow_region(guard, &fold_seeds, free, &mut release);
            let unfolding = release.iter().filter(|&&r| r).count() != released_before;
            // A round that releases springs where it did not yet holds nothing: a hold next to
            // a fold pushes its vertices across folded triangles' planes, into the other lip.
            let mut found = if unfolding {
                Targets::new()
            } else {
                self.offending_vertices(guard, &positions, &new_pairs, free, static_piece, attempt, contacts)
            };
            if found.is_empty() && fold_pairs.is_empty() {
                // The pairs away from the template's contacts hold no vertex (the template's
                // shape crosses where they are, or they sit on rest pairs): act on all pairs of
                // the part in excess (OldMan's jawForward, skin sliding deeper into the upper
                // teeth than the template's does).
                let pairs: Vec<(u32, u32)> = acted_on(&candidates).into_iter().filter(|&(a, b)| !folded(a) && !folded(b)).collect();
                found = self.offending_vertices(guard, &positions, &pairs, free, static_piece, attempt, contacts);
            }
            if found.is_empty() && fold_seeds.is_empty() {
                break;
            }
            let mut seeds = fold_seeds;
            // Whether every target is one the last re-solve already had, to the bit (and no
            // spring newly released).
            let mut same_targets = outcome.solves > 0 && !unfolding;
            for (u, target) in found {
                let reach = length(sub(target, add(self.target_neutral[u], out[u])));
                seeds.push((u, reach));
                let before = targets.insert(u, target);
                same_targets &= before.is_some_and(|b| b.map(f64::to_bits) == target.map(f64::to_bits));
            }
            self.grow_region(guard, &seeds, free, &mut region);
            let members: Vec<usize> = (0..out.len()).filter(|&v| region[v]).collect();
            // The same targets over the same region (it only grows) as the last re-solve, whose
            // result `out` is: this re-solve would give it again to the bit, and so would every
            // later round (same positions, pairs and holds). They are counted, not run: about a
            // quarter of the rounds on the 25k head.
            if same_targets && members.len() == outcome.region_vertices {
                outcome.solves += guard.params.max_iterations - round;
                break;
            }
            let constraints: Vec<(usize, f64, Vec3)> = targets
                .iter()
                .map(|(&u, &target)| (u, attempt.stiffness * guard.params.stiffness * self.matrix.diagonal(u), sub(target, self.target_neutral[u])))
                .collect();
            let released: Vec<(usize, usize, f64, Vec3)> = match shared.springs.get() {
                Some(springs) if release.iter().any(|&r| r) => {
                    springs.iter().copied().filter(|&(i, j, _, _)| release[i] || release[j]).collect()
                }
                _ => Vec::new(),
            };
            *out = self.matrix.solve_local(&members, &constraints, &released, shape.rhs, out)?;
            let region_deltas: Vec<Vec3> = members.iter().map(|&v| out[v]).collect();
            let mut now_changed = Vec::new();
            for ((&v, d), p) in members.iter().zip(&region_deltas).zip(guard.written_at(self, &members, &region_deltas)) {
                positions[v] = add(self.target_neutral[v], *d);
                if p != written[v] {
                    written[v] = p;
                    now_changed.push(v);
                }
            }
            changed_vertices = now_changed;
            outcome.solves += 1;
            outcome.region_vertices = members.len();
        }
        outcome.constrained_vertices = targets.len();
        // The round that adds least curve wins; when that is the plain solve, the shape comes
        // out exactly as without the pass.
        let excess = if held { allowed.and(best.as_ref().map(|b| b.0)) } else { None };
        let penetration = |pairs: &[(u32, u32, f64)]| {
            let rest: Vec<(u32, u32, f64)> = rest_pairs().collect();
            shape_penetration(pairs, &rest, moved, &guard.triangle_piece)
        };
        // The plain solve's, once per shape (every attempt starts from it).
        let plain_penetration = *shared.penetration.get_or_init(|| penetration(plain_crossing));
        outcome.plain_penetration = Some(plain_penetration);
        if let Some((_, kept, left, pairs)) = best {
            outcome.penetration = Some(if kept.is_empty() { plain_penetration } else { penetration(&pairs) });
            outcome.remaining_pairs = left;
            outcome.applied = !kept.is_empty();
            *out = if kept.is_empty() { plain } else { kept };
        }
        Ok((outcome, excess))
    }

    /// `target neutral + out` where it is written: in the target's own frame, added in f32
    /// (as the report and Blender see the shape), as f64.
    fn written_positions(&self, guard: &CollisionGuard, out: &[Vec3]) -> Vec<Vec3> {
        let all: Vec<usize> = (0..out.len()).collect();
        guard.written_at(self, &all, out)
    }

}

/// What every attempt of one shape's pass shares (each starts from the plain solve): which
/// triangles moved and which vertices the solve is free to move, the pieces that stay put, the
/// rest curve the sweeps see again, and, once the first attempt has found them, the plain
/// solve's crossing pairs and the template shape's contacts, so that a later attempt does not
/// sweep them again.
struct PlainRound {
    moved: Vec<bool>,
    free: Vec<bool>,
    /// Per piece: none of its vertices moves, so it is an obstacle exactly where the target's
    /// neutral has it.
    static_piece: Vec<bool>,
    /// The rest curve the sweeps see again: all of it but the rest pairs whose triangles both
    /// stay put (those cross exactly as at rest and are not swept).
    swept_rest: AddedCurve,
    /// The plain solve's crossing pairs, and the hierarchy refitted to it (each attempt's
    /// first re-sweep refits it only where the re-solve moved triangles).
    crossing: OnceLock<(Vec<(u32, u32, f64)>, TriangleBvh)>,
    /// The plain solve's penetration, from those pairs.
    penetration: OnceLock<Penetration>,
    template: OnceLock<TemplateContacts>,
    /// The shape's virtual-edge springs ([`DeformationTransfer::springs`]) and the triangles
    /// they folded ([`DeformationTransfer::spring_folds`]), found once per shape.
    springs: OnceLock<Vec<(usize, usize, f64, Vec3)>>,
    folds: OnceLock<Vec<bool>>,
}

impl PlainRound {
    fn new(dt: &DeformationTransfer, guard: &CollisionGuard, shape: &ShapeSystem<'_>, factor: &RestrictedFactor) -> Self {
        let moved: Vec<bool> = dt.triangles.iter().map(|t| t.iter().any(|&v| shape.moving[v as usize])).collect();
        let free = (0..dt.piece.len()).map(|v| factor.is_kept(v) && !shape.pinned[dt.piece[v] as usize]).collect();
        let mut static_piece = vec![true; shape.pinned.len()];
        for (v, &m) in shape.moving.iter().enumerate() {
            if m {
                static_piece[dt.piece[v] as usize] = false;
            }
        }
        let rest_pairs = guard.rest_pairs.iter().zip(&guard.rest_lengths).map(|(&(a, b), &l)| (a, b, l));
        let swept_rest = AddedCurve::of(
            rest_pairs.filter(|&(a, b, _)| moved[a as usize] || moved[b as usize]),
            |t| dt.triangle_piece(t),
            AddedCurve::default(),
        );
        Self { moved, free, static_piece, swept_rest, crossing: OnceLock::new(), penetration: OnceLock::new(), template: OnceLock::new(), springs: OnceLock::new(), folds: OnceLock::new() }
    }
}

/// One way of holding the vertices that went through (see the module's "Attempts"): the
/// targets' weights are `stiffness` x [`CollisionParams::stiffness`], the margin `margin` x
/// [`CollisionGuard::margin`]; with `strip`, a lip vertex on its rest side of the other lip
/// but nearer than the margin is held at the margin too (the whole contact strip, not only
/// the vertices that went through); with `embedded`, a corner of a new pair's triangle that
/// crosses the same static piece at the target's rest goes back to rest, and the attempt is
/// kept only when it clears the shape.
pub(super) struct Attempt {
    stiffness: f64,
    margin: f64,
    pub(super) strip: bool,
    pub(super) rest: bool,
    pub(super) follow: bool,
    pub(super) embedded: bool,
}

/// The attempts, in order; the next is tried (from the plain solve) only while the shape is
/// still worse than the template. Measured on the three bundled targets, each later attempt
/// clears shapes the earlier ones leave (module docs).
const ATTEMPTS: [Attempt; 7] = [
    Attempt { stiffness: 1.0, margin: 1.0, strip: false, rest: false, follow: false, embedded: false },
    Attempt { stiffness: 1.0, margin: 2.0, strip: false, rest: false, follow: false, embedded: false },
    Attempt { stiffness: 10.0, margin: 1.0, strip: false, rest: false, follow: false, embedded: false },
    Attempt { stiffness: 1.0, margin: 1.0, strip: true, rest: false, follow: false, embedded: false },
    Attempt { stiffness: 1.0, margin: 1.0, strip: false, rest: true, follow: false, embedded: false },
    Attempt { stiffness: 1.0, margin: 1.0, strip: false, rest: false, follow: true, embedded: false },
    Attempt { stiffness: 1.0, margin: 1.0, strip: false, rest: false, follow: true, embedded: true },
];

/// A rest pair (crossing in the target's neutral) is acted on when its curve grows by more
/// than this fraction in the shape.
const REST_GROWTH: f64 = 0.05;

/// Excess over the template's curve (in bbox diagonals) below which a shape meets the
/// criterion: a tenth of the report's tolerance, so that float noise in the sums of a shape
/// that moves crossing triangles without changing their crossing does not start the pass.
const JUDGE_TOLERANCE: f64 = 1e-4;
