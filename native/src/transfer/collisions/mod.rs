//! Collision-aware pass (SPEC section 3, after Ichim et al. 2016's collision handling): a
//! solved shape that adds more intersection curve to the target's neutral than the template's
//! own shape adds to the template's has the vertices that went through another surface held on
//! the side they were on at rest (plus a margin) and is re-solved around them; the round with
//! least excess over the template is kept.
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
//! **Which pairs.** Pairs of the part in excess that cross in the result, not at the target's
//! rest (or at rest with over 5% more curve), not near a pair the template's shape adds (found
//! once per shape, then a lookup among the two one-rings), and of pieces whose own curve grew
//! ([`contacts::pieces_grown`]). When those hold no vertex, all pairs of the part are tried.
//!
//! **Which vertices, and where to.** A vertex the template's own shape takes across the same
//! obstacle follows the artist and is never held. Against a piece static in the shape (teeth,
//! an eyeball, lashes) a corner on the other side of its surface than at rest (read at its
//! closest point, `TriangleBvh::closest_point_where`) targets that point plus the margin along
//! the normal; one that moved at most half an edge goes back to rest. Against a moving surface
//! (lip through lip) the push is `t_u = x_u + (s m_u - h) n` across the other triangle's plane
//! (`s` the rest side, `h` the signed distance now), half of it when that triangle moves too. A
//! flood over mesh neighbours reaches the vertices beyond the crossing curve. The margin `m_u`
//! is `margin` x the mean edge length at `u`, at least `min_margin` x the diagonal. A floating
//! piece (lashes riding on a lid) is held like the skin: its solve places it by the source
//! piece's motion, not by the skin it rides on.
//!
//! **Local re-solve.** The energy gains `w_u |d_u - (t_u - B0_u)|^2`, `w_u = stiffness x A_uu`:
//! a scalar weight on the diagonal, so x, y and z stay separate systems. Only the free vertices
//! within 3 edge lengths (or 3x the push) of a hold are unknowns, the rest stays as solved
//! (`NormalMatrix::solve_local`). Targets and region accumulate over the rounds.
//!
//! **Folds.** A triangle the plain solve turns over while the template keeps it upright, with a
//! corner a virtual-edge spring pulls at, was folded by the springs; its pairs are not held and
//! the springs near them are released in the re-solve (`solve_local`'s `released`).
//!
//! **Attempts** (`ATTEMPTS`). A shape still worse is tried again from its plain solve with
//! other holds: twice the margin, ten times the stiffness, the whole lip contact strip, skin
//! back to rest against static pieces the template adds no curve to, following the template's
//! contacts, the skin resting across a static piece kept where it rests (kept only when it
//! clears the shape), every vertex that went through held on its rest side, the template's
//! contacts not followed (a template whose neutral's lips cross presses its shapes' lips
//! through each other, which the target need not copy), the whole contact strip held with the
//! pairs next to the template's own contacts acted on too, its vertices that cross as the
//! template's still following it (a target pressing its lips along a longer contact than the
//! template's adds its excess right beside the template's contacts, which the other attempts
//! leave alone), and last, beside where the template's neutral itself crosses inside a piece
//! (lips resting through each other, where a rest side says nothing), each corner of a pair held
//! a quarter of the way back along its own motion each round (kept only when it clears the
//! shape; `ALONG_PATH_ROUNDS` times the rounds of the others). The
//! next runs only while the shape is still worse; the plain solve's sweep and the template's
//! contacts are found once (`PlainRound`); the later attempts run two side by side and are taken
//! in order, so the result is that of a serial run.
//!
//! **Chains.** Where the along-path attempt does not clear the shape it often brings the lips
//! within their allowance inside while the skin still goes through the teeth (between pieces),
//! which it does not act on; every attempt from the plain solve instead presses the lips
//! further into each other round after round (a rest-side push across the other lip's plane
//! where the lips are pressed together crosses them elsewhere). So its best state is continued
//! from (`Held`: the deltas, the holds, region and released springs that gave them, and their
//! crossing pairs, swept once): each of `CHAINED` (skin back to rest against static pieces,
//! following the template's contacts, skin resting across a static piece kept at rest) starts
//! there with those holds and is taken when it lowers the chain's excess; the chain is kept
//! only when it clears the shape. A template whose neutral crosses nowhere inside (the warp
//! ground truth) never gets here: the along-path attempt holds nothing there.
//!
//! **Backing off.** A shape neither the attempts nor the chain clear is tried once more from
//! its plain solve: each skin corner of a pair against a static piece (the teeth) held an
//! eighth of the way back along its own motion each round, kept only when it clears the shape.
//! The crossing-lips template's mouthLeft/Right on the dense heads leave skin that rests across
//! the teeth sliding onto new teeth triangles with no corner changing side, which every
//! rest-side hold misses; held back along the way it came, it ends crossing as at rest. Only a
//! shape that would otherwise stay worse gets here, so every other shape comes out as before.
//!
//! **Re-sweeps.** A round changes its region's rows only, so its hierarchy is refitted there
//! (`TriangleBvh::refit_listed`) and only triangles with a corner written elsewhere are swept
//! again (`crossings_of`); every number equals a full sweep's to the bit (tested in `geometry/`).
//!
//! # Deviations (numbers and the alternatives that lost: docs/design_transfer.md)
//! - Only the part in excess is acted on, and only pieces whose curve grew: pushing skin off
//!   the teeth does nothing for lids sliding into the eyeballs and presses the lips together.
//! - Against static pieces a corner that barely moved goes back to rest rather than to the
//!   surface: the MakeHuman lids and lips rest inside their eyeballs and teeth.
//! - Springs are released where they fold the lips, instead of holding across a turned-over
//!   triangle whose plane the side test reads the wrong way round.
//! - No single setting clears every shape: each attempt is the one kept on some shape of the
//!   ten heads measured with `native/examples/collision_counts.rs`.

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
use crate::geometry::penetration::{crossings, crossings_of, shape_penetration, Penetration, REST_GROWTH};

/// Knobs of the collision pass, defaults from SPEC section 3.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
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
        let shared = PlainRound::new(self, guard, shape, factor, out.clone());
        let plain = &shared.plain;
        let rounds = guard.params.max_iterations;
        let (mut outcome, mut excess, _) = self.collision_rounds(guard, shape, &shared, out, &ATTEMPTS[0], None, None, rounds)?;
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
        // The along-path attempt's best state when it does not clear the shape: the lips it
        // brought back inside their allowance, the chain's start (below).
        let mut along: Option<(Option<f64>, Held)> = None;
        let run = |(index, attempt): (usize, &Attempt)| {
            let mut again = plain.clone();
            let dropped = (index == 1).then_some(&first_cleared);
            let tried = self.collision_rounds(guard, shape, &shared, &mut again, attempt, dropped, None, attempt.rounds(rounds));
            if index == 0 && matches!(tried, Ok((_, Some(e), _)) if worse(Some(e)).is_none()) {
                first_cleared.store(true, Ordering::Relaxed);
            }
            tried.map(|(next, next_excess, held)| (next, next_excess, again, held))
        };
        for pair in ATTEMPTS[1..].chunks(2) {
            if worse(excess).is_none() {
                break;
            }
            let later: Vec<_> = pair.par_iter().enumerate().map(run).collect();
            for (tried, attempt) in later.into_iter().zip(pair) {
                // Only a shape still worse than the template (its excess known) tries again.
                let Some(least) = worse(excess) else { break };
                let (next, next_excess, again, held) = tried?;
                solves += next.solves;
                // The embedded attempt's holds are taken only when they clear the shape.
                let taken = !(attempt.embedded || attempt.along_path) || worse(next_excess).is_none();
                if taken && next_excess.is_some_and(|e| e < least) {
                    *out = again;
                    outcome = CollisionOutcome { new_pairs: outcome.new_pairs, ..next };
                    excess = next_excess;
                } else if attempt.along_path {
                    along = held.map(|h| (next_excess, h));
                }
            }
        }
        if worse(excess).is_none() {
            return Ok(CollisionOutcome { solves, ..outcome });
        }
        // Chained attempts (module docs' "Chains"): from the along-path attempt's best state,
        // each of `CHAINED` continues from the chain's state with the holds that gave it, and is
        // taken when it lowers the chain's excess; the chain is kept only when it clears the
        // shape.
        if let Some((mut chain_excess, start)) = along {
            let mut state = Some(start);
            let mut chained = None;
            for attempt in CHAINED {
                let Some(start) = state.as_ref().filter(|_| worse(chain_excess).is_some()) else { break };
                let mut again = start.deltas.clone();
                let (next, next_excess, held) = self.collision_rounds(guard, shape, &shared, &mut again, attempt, None, Some(start), attempt.rounds(rounds))?;
                solves += next.solves;
                if next_excess.is_some_and(|e| chain_excess.is_none_or(|c| e < c)) {
                    chain_excess = next_excess;
                    state = held.or(state);
                    chained = Some((again, next));
                }
            }
            if let Some((again, next)) = chained.filter(|_| worse(chain_excess).is_none()) {
                *out = again;
                return Ok(CollisionOutcome { new_pairs: outcome.new_pairs, solves, ..next });
            }
        }
        // Last (module docs' "Backing off"): from the plain solve, the skin going through a
        // static piece held back along its own motion an eighth of the way each round, kept
        // only when it clears the shape.
        let mut again = plain.clone();
        let (next, next_excess, _) = self.collision_rounds(guard, shape, &shared, &mut again, &BACK_OFF_PIECES, None, None, BACK_OFF_PIECES.rounds(rounds))?;
        solves += next.solves;
        if next_excess.is_some() && worse(next_excess).is_none() {
            *out = again;
            outcome = CollisionOutcome { new_pairs: outcome.new_pairs, ..next };
        }
        Ok(CollisionOutcome { solves, ..outcome })
    }

    /// One attempt of the pass: up to `rounds` rounds of judging, holding and re-solving, from
    /// the plain solve in `out`, or from `start` (its deltas in `out`) with its holds (a chain's
    /// step); leaves the best round in `out` and returns its excess over the template (`None`
    /// when the template's numbers were never needed: nothing new crosses, or the plain solve
    /// meets the criterion) and, for the along-path attempt and a chain's steps, the state of
    /// that round when it is a re-solve. Once `dropped` is set (the caller will not take this
    /// attempt) it stops before its next round.
    #[allow(clippy::too_many_arguments)]
    fn collision_rounds(
        &self,
        guard: &CollisionGuard,
        shape: &ShapeSystem<'_>,
        shared: &PlainRound,
        out: &mut Vec<Vec3>,
        attempt: &Attempt,
        dropped: Option<&AtomicBool>,
        start: Option<&Held>,
        rounds: usize,
    ) -> ShapesmithResult<(CollisionOutcome, Option<f64>, Option<Held>)> {
        let PlainRound { moved, free, static_piece, swept_rest, swept_rest_pairs, .. } = shared;
        let mut outcome = CollisionOutcome::default();
        let piece_of = |t: u32| self.triangle_piece(t);
        let rest_pairs = || guard.rest_pairs.iter().zip(&guard.rest_lengths).map(|(&(a, b), &l)| (a, b, l));
        let tolerance = JUDGE_TOLERANCE * guard.diagonal;
        let meets = |added: &AddedCurve, template: &Option<AddedCurve>| template.is_some_and(|t| added.excess(&t) <= tolerance);
        let mut allowed = shape.allowed;
        let mut targets = start.map_or_else(Targets::new, |s| s.targets.clone());
        let mut region = start.map_or_else(|| vec![false; out.len()], |s| s.region.clone());
        // Where the virtual-edge springs are released: around the pairs the springs folded.
        let mut release = start.map_or_else(|| vec![false; out.len()], |s| s.release.clone());
        let mut crossing: Vec<(u32, u32, f64)> = Vec::new();
        // The vertices whose written position the last re-solve changed.
        let mut changed_vertices: Vec<usize> = Vec::new();
        let mut template: Option<&TemplateContacts> = None;
        // The hierarchy refitted to the last re-sweep's positions, refitted in place where the
        // next re-solve moves triangles.
        let mut sweep_bvh: Option<TriangleBvh> = None;
        let plain = out.clone();
        // The round with the least excess over the template so far (the least added curve
        // while the template's is not known).
        let mut best: Option<BestRound> = None;
        let mut first: Option<AddedCurve> = None;
        // Whether any vertices were sought: only then can another attempt differ.
        let mut held = false;
        // The result's positions (working frame), and where it is written (the target's
        // frame, f32): swept there, so the report takes these numbers as they are. A re-solve
        // changes its region's rows only, and only those are computed again.
        let mut positions: Vec<Vec3> = self.target_neutral.iter().zip(out.iter()).map(|(p, d)| add(*p, *d)).collect();
        let mut written = self.written_positions(guard, out);
        // The plain solve, swept once per shape: every attempt but a chain's steps starts from it.
        let (plain_crossing, plain_bvh) = shared.crossing.get_or_init(|| {
            let bvh = guard.bvh.refitted(&written, &self.triangles);
            (crossings(&written, &self.triangles, &bvh, Some(moved)), bvh)
        });
        // A chain's step re-sweeps from its start's positions.
        if start.is_some() {
            sweep_bvh = Some(guard.bvh.refitted(&written, &self.triangles));
        }
        for round in 0..=rounds {
            if dropped.is_some_and(|d| d.load(Ordering::Relaxed)) {
                break;
            }
            crossing = if round == 0 {
                start.map_or_else(|| plain_crossing.clone(), |s| s.crossing.clone())
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
            let improved = best.as_ref().is_none_or(|b| score(&added) < b.score);
            if improved {
                // The holds that gave it, for the chain to continue from (module docs' "Chains").
                let holds = (round > 0 && (attempt.along_path || start.is_some())).then(|| (targets.clone(), region.clone(), release.clone()));
                let kept = if round == 0 { Vec::new() } else { out.clone() };
                best = Some(BestRound { score: score(&added), deltas: kept, left: 0, crossing: crossing.clone(), holds });
            }
            // New pairs, and rest pairs whose curve grew: skin resting against an eyeball or
            // the teeth adds curve by sliding deeper along pairs that already cross.
            // Both lists are sorted: one walk along the rest pairs instead of a search each.
            let mut at_rest = 0;
            let candidates: Vec<(u32, u32)> = crossing
                .iter()
                .filter(|&&(a, b, l)| {
                    while at_rest < guard.rest_pairs.len() && guard.rest_pairs[at_rest] < (a, b) {
                        at_rest += 1;
                    }
                    guard.rest_pairs.get(at_rest) != Some(&(a, b)) || l > guard.rest_lengths[at_rest] * (1.0 + REST_GROWTH)
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
                    if let Some(b) = best.as_mut() {
                        b.score = first.map_or(0.0, |f| f.excess(&contacts.allowed));
                    }
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
            // Only the part (inside one piece, between pieces) adding more than the template's
            // is acted on: pushing the other part's pairs moves vertices for nothing and can
            // add curve where the shape met the criterion.
            // Of those, only the pairs of two pieces (or of one piece with itself) whose own curve
            // grew: skin sliding out of the teeth it rests in while its lids slide into the
            // eyeballs adds between pieces, yet pushing it off the teeth does nothing for the
            // eyeballs and presses the lips into each other (OldMan's mouthClose).
            let grown = pieces_grown(crossing.iter().copied(), swept_rest_pairs.iter().copied(), piece_of, 0.5 * tolerance);
            let grew = |&(a, b): &(u32, u32)| grown.contains(&piece_key(piece_of(a), piece_of(b)));
            // And of those, the pairs the attempt acts on beside the template's own contacts
            // ([`TemplateContacts::acts_on`]).
            let away = |&(a, b): &(u32, u32)| match &template {
                Some(contacts) => contacts.acts_on(guard, attempt, (a, b), (piece_of(a), piece_of(b))),
                None => true,
            };
            let in_part: Vec<(u32, u32)> = candidates.iter().copied().filter(in_excess).collect();
            let acted: Vec<(u32, u32)> = in_part.iter().copied().filter(grew).collect();
            let away_acted: Vec<(u32, u32)> = acted.iter().copied().filter(away).collect();
            // When every pair of the part in excess lies near one of the template's own
            // contacts, yet the part adds more than the template's, the template's contact is
            // smaller than the target's there (skin sliding along the teeth): the pairs are
            // acted on after all.
            let near_only = away_acted.is_empty() && !in_part.iter().any(|p| !grew(p) && away(p));
            let new_pairs = if near_only { acted.clone() } else { away_acted };
            if round == 0 {
                outcome.new_pairs = new_pairs.len();
            }
            if let Some(b) = best.as_mut().filter(|_| improved) {
                b.left = new_pairs.len();
            }
            if new_pairs.is_empty() || round == rounds {
                break;
            }
            // The template's contacts are known once a round gets here (judged above).
            let Some(contacts) = template else { break };
            held = true;
            // Pairs with a triangle the springs folded over (module docs' "Folds"): their
            // springs are released around them instead of their corners held.
            let folds = shared.folds.get_or_init(|| {
                let springs = shared.springs.get_or_init(|| self.springs(shape.delta));
                self.spring_folds(springs, &shared.plain, &contacts.positions)
            });
            let folded = |t: u32| folds[t as usize];
            let (fold_pairs, new_pairs): (Vec<_>, Vec<_>) = new_pairs.into_iter().partition(|&(a, b)| folded(a) || folded(b));
            let fold_seeds: Vec<(usize, f64)> = fold_pairs
                .iter()
                .flat_map(|&(a, b)| self.triangles[a as usize].into_iter().chain(self.triangles[b as usize]))
                .map(|v| (v as usize, 0.0))
                // A floating piece's springs are not released: with no hold in it, its
                // translation would be free in the re-solve.
                .filter(|&(v, _)| free[v] && !shape.pinned[self.piece[v] as usize])
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
                let pairs: Vec<(u32, u32)> = acted.into_iter().filter(|&(a, b)| !folded(a) && !folded(b)).collect();
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
                outcome.solves += rounds - round;
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
        let excess = if held { allowed.and(best.as_ref().map(|b| b.score)) } else { None };
        let penetration = |pairs: &[(u32, u32, f64)]| {
            let rest: Vec<(u32, u32, f64)> = rest_pairs().collect();
            shape_penetration(pairs, &rest, moved, &guard.triangle_piece)
        };
        // The plain solve's, once per shape (every attempt starts from it).
        let plain_penetration = *shared.penetration.get_or_init(|| penetration(plain_crossing));
        outcome.plain_penetration = Some(plain_penetration);
        let mut reached = None;
        if let Some(BestRound { deltas, left, crossing, holds, .. }) = best {
            outcome.penetration = Some(if deltas.is_empty() && start.is_none() { plain_penetration } else { penetration(&crossing) });
            outcome.remaining_pairs = left;
            outcome.applied = !deltas.is_empty() || start.is_some();
            if let Some((targets, region, release)) = holds {
                reached = Some(Held { deltas: deltas.clone(), targets, region, release, crossing });
            }
            *out = if deltas.is_empty() { plain } else { deltas };
        }
        Ok((outcome, excess, reached))
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
    /// The plain solve's deltas.
    plain: Vec<Vec3>,
    moved: Vec<bool>,
    free: Vec<bool>,
    /// Per piece: none of its vertices moves, so it is an obstacle exactly where the target's
    /// neutral has it.
    static_piece: Vec<bool>,
    /// The rest curve the sweeps see again: all of it but the rest pairs whose triangles both
    /// stay put (those cross exactly as at rest and are not swept), and those pairs.
    swept_rest: AddedCurve,
    swept_rest_pairs: Vec<(u32, u32, f64)>,
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
    fn new(dt: &DeformationTransfer, guard: &CollisionGuard, shape: &ShapeSystem<'_>, factor: &RestrictedFactor, plain: Vec<Vec3>) -> Self {
        let moved: Vec<bool> = dt.triangles.iter().map(|t| t.iter().any(|&v| shape.moving[v as usize])).collect();
        // A floating piece (lashes riding on a lid, teeth on the jaw) is placed by the source
        // piece's motion, not by the skin it rides on, so it crosses what the template's does
        // not: its vertices are held and re-solved like the skin's (each piece in a region
        // holds a target, which fixes its translation).
        let free = (0..dt.piece.len()).map(|v| factor.is_kept(v) || shape.pinned[dt.piece[v] as usize]).collect();
        let mut static_piece = vec![true; shape.pinned.len()];
        for (v, &m) in shape.moving.iter().enumerate() {
            if m {
                static_piece[dt.piece[v] as usize] = false;
            }
        }
        let rest_pairs = guard.rest_pairs.iter().zip(&guard.rest_lengths).map(|(&(a, b), &l)| (a, b, l));
        let swept_rest_pairs: Vec<(u32, u32, f64)> = rest_pairs.filter(|&(a, b, _)| moved[a as usize] || moved[b as usize]).collect();
        let swept_rest = AddedCurve::of(swept_rest_pairs.iter().copied(), |t| dt.triangle_piece(t), AddedCurve::default());
        Self { plain, moved, free, static_piece, swept_rest, swept_rest_pairs, crossing: OnceLock::new(), penetration: OnceLock::new(), template: OnceLock::new(), springs: OnceLock::new(), folds: OnceLock::new() }
    }
}

/// The best round of one attempt so far: its score (excess over the template, or added curve
/// while the template's is not known), its deltas (empty: the attempt's start), the new pairs
/// left in them, their crossing pairs, and the holds, region and released springs that gave
/// them (kept for the along-path attempt and a chain's steps, which a chain continues from).
struct BestRound {
    score: f64,
    deltas: Vec<Vec3>,
    left: usize,
    crossing: Vec<(u32, u32, f64)>,
    holds: Option<(Targets, Vec<bool>, Vec<bool>)>,
}

/// A re-solved state of one shape a later attempt continues from: its deltas, the holds,
/// region and released springs that gave it, and its crossing pairs (swept where written).
#[derive(Clone)]
struct Held {
    deltas: Vec<Vec3>,
    targets: Targets,
    region: Vec<bool>,
    release: Vec<bool>,
    crossing: Vec<(u32, u32, f64)>,
}

/// One way of holding the vertices that went through (see the module's "Attempts"): the
/// targets' weights are `stiffness` x [`CollisionParams::stiffness`], the margin `margin` x
/// [`CollisionGuard::margin`]; with `strip`, a lip vertex on its rest side of the other lip
/// but nearer than the margin is held at the margin too (the whole contact strip, not only
/// the vertices that went through); with `embedded`, a corner of a new pair's triangle that
/// crosses the same static piece at the target's rest goes back to rest, and the attempt is
/// kept only when it clears the shape; with `clear`, the template's own contacts are not
/// followed: every vertex of a pair in excess that went through is held on its rest side; with
/// `contacts`, the pairs near the template's own contacts are acted on too (its vertices
/// crossing as the template's are still left alone); with `along_path`, the corners of pairs
/// inside a piece beside where the template's neutral crosses are held back along their own
/// motion (`along_path_holds`), and the attempt is kept only when it clears the shape.
pub(super) struct Attempt {
    stiffness: f64,
    margin: f64,
    pub(super) strip: bool,
    pub(super) rest: bool,
    pub(super) follow: bool,
    pub(super) embedded: bool,
    pub(super) clear: bool,
    pub(super) contacts: bool,
    pub(super) along_path: bool,
    pub(super) between: bool,
}

impl Attempt {
    /// The rounds the attempt takes at most, `max_iterations` those of the first.
    fn rounds(&self, max_iterations: usize) -> usize {
        if self.along_path { ALONG_PATH_ROUNDS * max_iterations } else { max_iterations }
    }
}

/// The attempts, in order; the next is tried (from the plain solve) only while the shape is
/// still worse than the template. Measured on the heads of `examples/collision_counts.rs`,
/// each later attempt clears shapes the earlier ones leave (module docs).
const ATTEMPTS: [Attempt; 10] = [
    Attempt { stiffness: 1.0, margin: 1.0, strip: false, rest: false, follow: false, embedded: false, clear: false, contacts: false, along_path: false, between: false },
    Attempt { stiffness: 1.0, margin: 2.0, strip: false, rest: false, follow: false, embedded: false, clear: false, contacts: false, along_path: false, between: false },
    Attempt { stiffness: 10.0, margin: 1.0, strip: false, rest: false, follow: false, embedded: false, clear: false, contacts: false, along_path: false, between: false },
    Attempt { stiffness: 1.0, margin: 1.0, strip: true, rest: false, follow: false, embedded: false, clear: false, contacts: false, along_path: false, between: false },
    Attempt { stiffness: 1.0, margin: 1.0, strip: false, rest: true, follow: false, embedded: false, clear: false, contacts: false, along_path: false, between: false },
    Attempt { stiffness: 1.0, margin: 1.0, strip: false, rest: false, follow: true, embedded: false, clear: false, contacts: false, along_path: false, between: false },
    Attempt { stiffness: 1.0, margin: 1.0, strip: false, rest: false, follow: true, embedded: true, clear: false, contacts: false, along_path: false, between: false },
    Attempt { stiffness: 1.0, margin: 1.0, strip: false, rest: false, follow: false, embedded: false, clear: true, contacts: false, along_path: false, between: false },
    Attempt { stiffness: 1.0, margin: 1.0, strip: true, rest: false, follow: false, embedded: false, clear: false, contacts: true, along_path: false, between: false },
    Attempt { stiffness: 1.0, margin: 1.0, strip: false, rest: false, follow: false, embedded: false, clear: false, contacts: false, along_path: true, between: false },
];

/// The last attempt, when neither [`ATTEMPTS`] nor the chain clears the shape (module docs'
/// "Backing off").
const BACK_OFF_PIECES: Attempt =
    Attempt { stiffness: 1.0, margin: 1.0, strip: false, rest: false, follow: false, embedded: false, clear: false, contacts: false, along_path: true, between: true };

/// The attempts chained after [`ATTEMPTS`] (module docs' "Chains"): skin back to rest against
/// static pieces, following the template's contacts, and with the skin resting across a static
/// piece kept where it rests.
const CHAINED: [&Attempt; 3] = [&ATTEMPTS[4], &ATTEMPTS[5], &ATTEMPTS[6]];

/// Rounds of the along-path attempt, in multiples of [`CollisionParams::max_iterations`]: each
/// round moves its corners a quarter of the way back, so lips pressed far through each other
/// need more of them (the crossing-lips template's mouth shapes on the dense heads come within
/// their allowance inside after 8 to 13).
const ALONG_PATH_ROUNDS: usize = 4;

/// Excess over the template's curve (in bbox diagonals) below which a shape meets the
/// criterion: a tenth of the report's tolerance, so that float noise in the sums of a shape
/// that moves crossing triangles without changing their crossing does not start the pass.
const JUDGE_TOLERANCE: f64 = 1e-4;
