//! Tests of the pass's holds (`holds.rs`) on small synthetic lips and teeth.

use super::super::{Attempt, CollisionGuard, CollisionParams, ATTEMPTS, BACK_OFF_PIECES};
use super::TemplateContacts;
use crate::geometry::bvh::TriangleBvh;
use crate::geometry::penetration::crossings;
use crate::transfer::gradients::{add, to_f64, Vec3};
use crate::transfer::collision_tests::skin_over_teeth;
use crate::transfer::tests::{lip_closing, lips};
use crate::transfer::virtual_edges::VirtualEdgeParams;
use crate::transfer::{DeformationTransfer, TransferParams};

/// `neutral + delta` as positions.
fn posed(neutral: &[Vec3], delta: Vec<[f32; 3]>) -> Vec<Vec3> {
    neutral.iter().zip(&delta).map(|(p, d)| add(*p, to_f64(d))).collect()
}

/// Template lips 0.1 apart, the target's 0.04 closed by `amount` each: the transfer, its
/// guard, the target's positions and their crossing pairs (some).
fn closed_target_lips(amount: f32) -> (Vec<[f32; 3]>, DeformationTransfer, CollisionGuard, Vec<Vec3>, Vec<(u32, u32)>) {
    let (source, tris) = lips(0.1);
    let (target, _) = lips(0.04);
    let dt = DeformationTransfer::new(&source, &target, &tris, &TransferParams::default()).unwrap();
    let guard = CollisionGuard::new(&dt.source_neutral, &dt.target_neutral, &target, &tris, CollisionParams::default());
    let positions = posed(&dt.target_neutral, lip_closing(&target, 0.04, amount));
    let bvh = TriangleBvh::build(&positions, &tris);
    let pairs: Vec<(u32, u32)> = crossings(&positions, &tris, &bvh, None).into_iter().map(|(a, b, _)| (a, b)).collect();
    assert!(!pairs.is_empty());
    (source, dt, guard, positions, pairs)
}

/// `lip_closing`'s bump at `p`, 1 in the middle of the lips: along^2 x across^2.
fn bump(p: &[f32; 3]) -> f32 {
    let along = (std::f32::consts::PI * p[0] / 1.5).sin().max(0.0);
    let across = (std::f32::consts::PI * (p[1] + 0.5)).sin().max(0.0);
    along.powi(2) * across.powi(2)
}

#[test]
fn a_fold_is_the_springs_only_where_a_spring_pulls_and_the_template_stays_upright() {
    // The two-layer lips with virtual edges between the layers. A plain solve that turns
    // over a triangle with a spring at a corner is a spring fold (its springs are released,
    // its corners not held); not when the template's shape turns it over too, nor a
    // triangle no spring pulls at.
    let (source, tris) = lips(0.1);
    let (target, _) = lips(0.04);
    let params = TransferParams { virtual_edges: Some(VirtualEdgeParams { tau_d: 0.05, ..Default::default() }), edge_weight: 1.0, ..Default::default() };
    let dt = DeformationTransfer::new(&source, &target, &tris, &params).unwrap();
    let springs = dt.springs(&vec![[0.0; 3]; source.len()]);
    assert!(!springs.is_empty());
    let pulled = |v: u32| springs.iter().any(|&(i, j, _, _)| i == v as usize || j == v as usize);
    let with = tris.iter().position(|t| t.iter().any(|&v| pulled(v))).unwrap();
    let without = tris.iter().position(|t| t.iter().all(|&v| !pulled(v))).expect("a triangle no spring pulls at");
    // Each turned over by taking its first corner across the opposite edge.
    let turn = |points: &[Vec3], t: usize, out: &mut Vec<Vec3>| {
        let [a, b, c] = tris[t].map(|v| v as usize);
        out[a] = add(out[a], [0, 1, 2].map(|k| points[b][k] + points[c][k] - 2.0 * points[a][k]));
    };
    let mut plain = vec![[0.0; 3]; source.len()];
    turn(&dt.target_neutral, with, &mut plain);
    turn(&dt.target_neutral, without, &mut plain);
    let upright = dt.source_neutral.clone();
    let folds = dt.spring_folds(&springs, &plain, &upright);
    assert!(folds[with] && !folds[without]);
    let mut turned = upright.clone();
    turn(&dt.source_neutral, with, &mut turned);
    assert!(!dt.spring_folds(&springs, &plain, &turned)[with]);
    // Nothing turned over, nothing folded.
    assert!(!dt.spring_folds(&springs, &vec![[0.0; 3]; source.len()], &upright).iter().any(|&f| f));
}

#[test]
fn vertices_the_templates_own_shape_takes_through_the_other_lip_are_not_held() {
    // The target's lips closed by 0.045 each cross wherever the bump f (lip_closing's
    // along^2 x across^2) exceeds 0.44.
    let (source, dt, guard, positions, pairs) = closed_target_lips(0.045);
    let free = vec![true; positions.len()];
    let held = |amount: f32| {
        let moved = vec![true; dt.triangles.len()];
        let template = dt.template_contacts(&guard, &lip_closing(&source, 0.1, amount), &moved);
        dt.offending_vertices(&guard, &positions, &pairs, &free, &[false], &ATTEMPTS[0], &template)
    };
    let bump = |v: usize| bump(&source[v]);
    // A template closing 90% of its gap crosses nowhere: the crossing target vertices are
    // held, the middle of the lips among them.
    let open = held(0.045);
    assert!(open.keys().any(|&v| bump(v) > 0.95), "{open:?}");
    // A template pressing its lips 0.02 into each other crosses where f > 0.83: the target
    // follows it there and is held only around it.
    let pressed = held(0.06);
    assert!(!pressed.is_empty() && pressed.keys().all(|v| open.contains_key(v)));
    assert!(pressed.keys().all(|&v| bump(v) < 0.95), "{pressed:?}");
}

#[test]
fn the_clear_attempt_holds_the_vertices_the_template_takes_through_the_other_lip_too() {
    // The template presses its lips 0.02 into each other (a template whose neutral's lips
    // cross presses its shapes' lips through each other): the first attempt follows it and
    // leaves the middle of the target's crossed lips alone; the clear attempt holds every
    // vertex that went through, as for a template that crosses nowhere, to the same point.
    let (source, dt, guard, positions, pairs) = closed_target_lips(0.045);
    let free = vec![true; positions.len()];
    let moved = vec![true; dt.triangles.len()];
    let held = |amount: f32, attempt: &Attempt| {
        let template = dt.template_contacts(&guard, &lip_closing(&source, 0.1, amount), &moved);
        dt.offending_vertices(&guard, &positions, &pairs, &free, &[false], attempt, &template)
    };
    let clear = ATTEMPTS.iter().find(|a| a.clear).expect("a clear attempt");
    assert!(!clear.follow && !clear.strip && !clear.rest && !clear.embedded);
    let (followed, cleared, uncrossed) = (held(0.06, &ATTEMPTS[0]), held(0.06, clear), held(0.045, &ATTEMPTS[0]));
    assert!(cleared.len() > followed.len(), "{} held against {}", cleared.len(), followed.len());
    assert_eq!(cleared.len(), uncrossed.len());
    for (v, target) in &uncrossed {
        let at = cleared.get(v).unwrap_or_else(|| panic!("vertex {v} is not held"));
        assert!((0..3).all(|a| (at[a] - target[a]).abs() < 1e-12), "vertex {v}: {at:?} against {target:?}");
    }
}

#[test]
fn the_contacts_attempt_acts_beside_the_templates_own_contacts_and_still_follows_them() {
    // The template presses its lips 0.02 into each other where the bump exceeds 0.83; the
    // target's, closed by 0.045 each across 0.04, cross wider (bump over 0.44). The first
    // attempt leaves the target's pairs within two one-rings of the template's contacts
    // alone; the contacts attempt acts on them too, so it holds more, yet none of the
    // vertices the template itself takes through the other lip.
    let (source, dt, guard, positions, pairs) = closed_target_lips(0.045);
    let moved = vec![true; dt.triangles.len()];
    let acted = |contacts: &TemplateContacts, attempt: &Attempt| -> Vec<(u32, u32)> {
        let pieces = |a: u32, b: u32| (dt.triangle_piece(a), dt.triangle_piece(b));
        pairs.iter().copied().filter(|&(a, b)| contacts.acts_on(&guard, attempt, (a, b), pieces(a, b))).collect()
    };
    let pressed = dt.template_contacts(&guard, &lip_closing(&source, 0.1, 0.06), &moved);
    let beside_contacts = ATTEMPTS.iter().find(|a| a.contacts).expect("a contacts attempt");
    assert!(beside_contacts.strip && !beside_contacts.follow && !beside_contacts.clear && !beside_contacts.along_path);
    let (first, beside) = (acted(&pressed, &ATTEMPTS[0]), acted(&pressed, beside_contacts));
    assert_eq!(beside, pairs);
    assert!(!first.is_empty() && first.len() < pairs.len(), "{} of {}", first.len(), pairs.len());
    assert!(pairs.iter().filter(|p| !first.contains(p)).all(|&(a, b)| pressed.near(&guard, a, b)));
    // A template that keeps its lips apart has no contacts: every attempt acts on every pair.
    let apart = dt.template_contacts(&guard, &lip_closing(&source, 0.1, 0.045), &moved);
    assert!(ATTEMPTS.iter().all(|attempt| acted(&apart, attempt) == pairs));
    let free = vec![true; positions.len()];
    let held = |pairs: &[(u32, u32)], attempt: &Attempt| dt.offending_vertices(&guard, &positions, pairs, &free, &[false], attempt, &pressed);
    let (held_first, held_last) = (held(&first, &ATTEMPTS[0]), held(&beside, beside_contacts));
    assert!(held_first.keys().all(|v| held_last.contains_key(v)) && held_last.len() > held_first.len());
    assert!(held_last.keys().all(|&v| bump(&source[v]) < 0.95), "{held_last:?}");
}

#[test]
fn the_along_path_attempt_holds_lips_back_along_their_motion_only_where_the_templates_rest_crossed() {
    // The target's lips (0.04 apart) closed by 0.045 each cross in the middle. Under a
    // template whose neutral's lips rest pressed 0.02 into each other there, every corner of
    // a crossing pair is held a quarter of the way back to its rest; under a template whose
    // lips rest apart, the attempt holds nothing (the rest sides are read there).
    let (source, tris) = lips(0.1);
    let (target, _) = lips(0.04);
    let crossed: Vec<[f32; 3]> = source.iter().zip(lip_closing(&source, 0.1, 0.06)).map(|(p, d)| [p[0], p[1], p[2] + d[2]]).collect();
    let dt = DeformationTransfer::new(&crossed, &target, &tris, &TransferParams::default()).unwrap();
    let guard = CollisionGuard::new(&dt.source_neutral, &dt.target_neutral, &target, &tris, CollisionParams::default());
    assert!(!guard.template_rest_pairs.is_empty());
    let positions = posed(&dt.target_neutral, lip_closing(&target, 0.04, 0.045));
    let bvh = TriangleBvh::build(&positions, &tris);
    let pairs: Vec<(u32, u32)> = crossings(&positions, &tris, &bvh, None).into_iter().map(|(a, b, _)| (a, b)).collect();
    let free = vec![true; positions.len()];
    let held = dt.along_path_holds(&guard, &positions, &pairs, &free);
    assert!(!held.is_empty());
    let corners: Vec<usize> = pairs.iter().flat_map(|&(a, b)| tris[a as usize].into_iter().chain(tris[b as usize])).map(|v| v as usize).collect();
    for (&u, at) in &held {
        assert!(corners.contains(&u), "vertex {u} is not a corner of a crossing pair");
        let expected = [0, 1, 2].map(|k| positions[u][k] + 0.25 * (dt.target_neutral[u][k] - positions[u][k]));
        assert!((0..3).all(|k| (at[k] - expected[k]).abs() < 1e-12), "vertex {u}: {at:?} against {expected:?}");
    }
    let (_, clean, clean_guard, _, _) = closed_target_lips(0.045);
    assert!(clean_guard.template_rest_pairs.is_empty());
    assert!(clean.along_path_holds(&clean_guard, &positions, &pairs, &free).is_empty());
}

#[test]
fn the_strip_attempt_also_holds_lip_vertices_nearer_than_the_margin() {
    // The target's lips (0.04 apart) closed by 0.02 each where the bump is full: they
    // touch in the middle and cross nowhere else, so near the crossing some vertices are
    // on their own side but nearer the other lip than the margin (a quarter of the 0.1
    // edges).
    let (_, dt, guard, positions, pairs) = closed_target_lips(0.024);
    let free = vec![true; positions.len()];
    // The template's shape leaves its lips apart: nothing is filtered.
    let template = dt.template_contacts(&guard, &vec![[0.0; 3]; positions.len()], &vec![true; dt.triangles.len()]);
    let held = |strip: bool| {
        let attempt = Attempt { stiffness: 1.0, margin: 1.0, strip, rest: false, follow: false, embedded: false, clear: false, contacts: false, along_path: false, between: false };
        dt.offending_vertices(&guard, &positions, &pairs, &free, &[false], &attempt, &template)
    };
    let (through, strip) = (held(false), held(true));
    assert!(!through.is_empty() && through.keys().all(|v| strip.contains_key(v)));
    // Each layer's vertex and the one facing it on the other layer (folded_strip: 22
    // profile points a cross-section, the upper layer's in reverse).
    let gap = |v: usize| {
        let (i, r) = (v / 22, v % 22);
        let (lower, upper) = if r < 11 { (v, i * 22 + 21 - r) } else { (i * 22 + 21 - r, v) };
        positions[upper][2] - positions[lower][2]
    };
    let near: Vec<usize> = strip.keys().copied().filter(|v| !through.contains_key(v)).collect();
    assert!(!near.is_empty(), "the strip holds more than the vertices that went through");
    for v in near {
        // On its own side, within the margin, and held away from the other lip.
        assert!(gap(v) > 0.0 && gap(v) < 0.05, "vertex {v}: gap {}", gap(v));
        let away = if v % 22 < 11 { positions[v][2] - strip[&v][2] } else { strip[&v][2] - positions[v][2] };
        assert!(away > 0.0, "vertex {v} is held towards the other lip");
    }
}

#[test]
fn the_follow_attempt_holds_lip_vertices_where_the_templates_own_shape_has_them() {
    // The template presses its lips 0.02 through each other in the middle (0.06 each
    // across its 0.1 gap); the target's, closed by 0.045 each across 0.04, go 0.05
    // through. The first attempt leaves the middle alone (the template crosses there);
    // the follow attempt holds it where the template has it against the other lip's
    // triangle, half way (both lips move): still through, but less deep.
    let (source, dt, guard, positions, pairs) = closed_target_lips(0.045);
    let free = vec![true; positions.len()];
    let moved = vec![true; dt.triangles.len()];
    let template = dt.template_contacts(&guard, &lip_closing(&source, 0.1, 0.06), &moved);
    let held = |attempt: &Attempt| dt.offending_vertices(&guard, &positions, &pairs, &free, &[false], attempt, &template);
    let (first, follow) = (held(&ATTEMPTS[0]), held(&ATTEMPTS[5]));
    assert!(ATTEMPTS[5].follow);
    // The vertex facing `v` on the other layer (folded_strip: 22 profile points a
    // cross-section, the upper layer's in reverse), and `v`'s signed gap to it at `z`.
    let facing = |v: usize| v / 22 * 22 + 21 - v % 22;
    let gap = |v: usize, z: f64| if v % 22 < 11 { positions[facing(v)][2] - z } else { z - positions[facing(v)][2] };
    let middle: Vec<usize> = follow.keys().copied().filter(|&v| gap(v, positions[v][2]) < -0.049).collect();
    assert!(!middle.is_empty(), "{follow:?}");
    for v in middle {
        assert!(!first.contains_key(&v), "vertex {v} is held by the first attempt");
        let (now, then) = (gap(v, positions[v][2]), gap(v, follow[&v][2]));
        assert!(now < then && then < -0.02 && then > -0.045, "vertex {v}: gap {now} held at {then}");
    }
}

/// The skin over teeth of `collision_tests` (template teeth top at 0.2, the target's at
/// 0.02) with the skin moved by `skin_delta` of each of its rest points: the transfer, its
/// guard, the posed target and the crossing pairs that were not there at rest.
struct PosedSkinOverTeeth {
    tris: Vec<[u32; 3]>,
    dt: DeformationTransfer,
    guard: CollisionGuard,
    delta: Vec<[f32; 3]>,
    positions: Vec<Vec3>,
    rest: Vec<(u32, u32)>,
    pairs: Vec<(u32, u32)>,
    free: Vec<bool>,
    skin: u32,
    teeth: u32,
}

/// The skin's vertices are the first 15 x 15 of `skin_over_teeth`'s.
const SKIN_VERTICES: usize = 15 * 15;

/// The skin moved by `skin_delta`, the teeth kept.
fn skin_moved(source: &[[f32; 3]], skin_delta: impl Fn(&[f32; 3]) -> [f32; 3]) -> Vec<[f32; 3]> {
    source.iter().enumerate().map(|(v, p)| if v < SKIN_VERTICES { skin_delta(p) } else { [0.0; 3] }).collect()
}

fn posed_skin_over_teeth(skin_delta: impl Fn(&[f32; 3]) -> [f32; 3]) -> PosedSkinOverTeeth {
    let (source, tris) = skin_over_teeth(0.2);
    let (target, _) = skin_over_teeth(0.02);
    let dt = DeformationTransfer::new(&source, &target, &tris, &TransferParams::default()).unwrap();
    let guard = CollisionGuard::new(&dt.source_neutral, &dt.target_neutral, &target, &tris, CollisionParams::default());
    let delta = skin_moved(&source, skin_delta);
    let positions = posed(&dt.target_neutral, delta.clone());
    let sweep = |p: &[Vec3]| -> Vec<(u32, u32)> {
        crossings(p, &tris, &TriangleBvh::build(p, &tris), None).into_iter().map(|(a, b, _)| (a, b)).collect()
    };
    let rest = sweep(&dt.target_neutral);
    let pairs: Vec<(u32, u32)> = sweep(&positions).into_iter().filter(|p| !rest.contains(p)).collect();
    assert!(!pairs.is_empty());
    let (skin, teeth) = (dt.piece[0], dt.piece[source.len() - 1]);
    let free: Vec<bool> = dt.piece.iter().map(|&piece| piece == skin).collect();
    PosedSkinOverTeeth { tris, dt, guard, delta, positions, rest, pairs, free, skin, teeth }
}

impl PosedSkinOverTeeth {
    /// Only the teeth static.
    fn teeth_static(&self) -> Vec<bool> {
        let mut static_piece = vec![false; 2];
        static_piece[self.teeth as usize] = true;
        static_piece
    }

    /// The skin corners of the new pairs (skin triangles come first, so they are a pair's
    /// first), sorted, once each.
    fn skin_corners(&self) -> Vec<usize> {
        let mut corners: Vec<usize> = self.pairs.iter().flat_map(|&(a, _)| self.tris[a as usize].map(|v| v as usize)).collect();
        corners.sort_unstable();
        corners.dedup();
        corners
    }

    fn at_rest(&self, u: usize, at: &Vec3) -> bool {
        (0..3).all(|a| (at[a] - self.dt.target_neutral[u][a]).abs() < 1e-9)
    }
}

/// A slide of 0.06 along y: more than half an edge, less than one.
fn slide(_: &[f32; 3]) -> [f32; 3] {
    [0.0, 0.06, 0.0]
}

#[test]
fn the_rest_attempt_sends_skin_through_a_piece_the_template_adds_nothing_to_back_to_rest() {
    // The skin plane rests inside the teeth (it cuts their walls). A rise of `height` in
    // the middle, 0.1 around (no closer to the walls than an edge, so the curve along them
    // stays as at rest), of 0.06: it stays inside the template's teeth (top at 0.2) and
    // pokes through the target's (0.02). Only the middle vertex moves more than half an
    // edge (0.07): its neighbours go back to rest in every attempt.
    let bump = |p: &[f32; 3]| (1.0 - ((p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2)) / 0.01).max(0.0).powi(2);
    let rise = |height: f32| move |p: &[f32; 3]| [0.0, 0.0, height * bump(p)];
    let fixture = posed_skin_over_teeth(rise(0.06));
    let PosedSkinOverTeeth { dt, guard, positions, pairs, free, skin, teeth, .. } = &fixture;
    let (source, _) = skin_over_teeth(0.2);
    let static_piece = fixture.teeth_static();
    let moved = vec![true; fixture.tris.len()];
    let held = |height: f32, attempt: &Attempt| {
        let contacts = dt.template_contacts(guard, &skin_moved(&source, rise(height)), &moved);
        let targets = dt.offending_vertices(guard, positions, pairs, free, &static_piece, attempt, &contacts);
        (contacts.adds_none(*skin, *teeth), targets)
    };
    let at_rest = |targets: &super::super::Targets| targets.iter().all(|(&u, t)| fixture.at_rest(u, t));
    // The template's rise adds no curve against its teeth: the first attempt pushes the
    // middle to the target's teeth top (a margin inside, the side it rests on); the rest
    // attempt sends it back to rest, where it crosses the teeth exactly as in the neutral.
    let (adds_none, first) = held(0.06, &ATTEMPTS[0]);
    let (_, back) = held(0.06, &ATTEMPTS[4]);
    assert!(adds_none && ATTEMPTS[4].rest);
    assert!(first.len() == back.len() && !at_rest(&first), "{first:?}");
    assert!(!back.is_empty() && at_rest(&back), "{back:?}");
    // A template rising 0.3, through its own teeth's top, adds curve against them: the rest
    // attempt holds as the first one does.
    let (adds_none, through) = held(0.3, &ATTEMPTS[0]);
    assert!(!adds_none);
    assert_eq!(held(0.3, &ATTEMPTS[4]).1, through);
}

#[test]
fn the_embedded_attempt_puts_skin_resting_across_a_static_piece_back_at_rest() {
    // The skin plane cuts the teeth's walls at rest. Sliding it takes the triangles
    // straddling the wall x = 0.3 across the wall's diagonal: new pairs whose corners all
    // stay on the side of the teeth they rest on, so the follow attempt holds none of them.
    // The embedded attempt puts the corners of a triangle that crosses the teeth at rest
    // back at rest, and every corner that kept its side.
    let fixture = posed_skin_over_teeth(slide);
    let PosedSkinOverTeeth { tris, dt, guard, delta, positions, rest, pairs, free, .. } = &fixture;
    let static_piece = fixture.teeth_static();
    let contacts = dt.template_contacts(guard, delta, &vec![true; tris.len()]);
    let held = |attempt: &Attempt| dt.offending_vertices(guard, positions, pairs, free, &static_piece, attempt, &contacts);
    let (follow, embedded) = (held(&ATTEMPTS[5]), held(&ATTEMPTS[6]));
    assert!(ATTEMPTS[6].embedded && !ATTEMPTS[5].embedded);
    let held_at_rest = |u: usize| {
        let at = embedded.get(&u).unwrap_or_else(|| panic!("vertex {u} is not held"));
        assert!(fixture.at_rest(u, at), "vertex {u} held at {at:?}");
    };
    // The skin corners of the new pairs whose skin triangle crosses the teeth at rest.
    let resting: Vec<usize> = pairs
        .iter()
        .filter(|&&(a, _)| rest.iter().any(|&(r, _)| r == a))
        .flat_map(|&(a, _)| tris[a as usize].map(|v| v as usize))
        .collect();
    assert!(!resting.is_empty(), "{pairs:?}");
    resting.iter().for_each(|&u| held_at_rest(u));
    assert!(resting.iter().any(|u| !follow.contains_key(u)), "{follow:?}");
    // Every other skin corner of a new pair on the side of the teeth (inside the box's
    // walls or outside) it rests on goes back to rest too: the teeth's edge went through
    // its triangle, not the corner through the teeth.
    let inside = |p: &Vec3| (0.3..=0.7).contains(&p[0]) && (0.3..=0.7).contains(&p[1]);
    let kept_side: Vec<usize> = fixture
        .skin_corners()
        .into_iter()
        .filter(|&u| inside(&dt.target_neutral[u]) == inside(&positions[u]) && !resting.contains(&u))
        .collect();
    assert!(!kept_side.is_empty());
    kept_side.iter().for_each(|&u| held_at_rest(u));
}

#[test]
fn the_last_attempt_holds_skin_through_a_static_piece_an_eighth_back_along_its_motion() {
    // The same slide: no corner changes side. Each skin corner of a new pair is held an
    // eighth of the way back to rest, 0.0525 along y; nothing of the teeth (not free) and
    // nothing at all when the teeth move too.
    let fixture = posed_skin_over_teeth(slide);
    let PosedSkinOverTeeth { tris, dt, guard, delta, positions, pairs, free, .. } = &fixture;
    let contacts = dt.template_contacts(guard, delta, &vec![true; tris.len()]);
    let held = |static_piece: &[bool]| dt.offending_vertices(guard, positions, pairs, free, static_piece, &BACK_OFF_PIECES, &contacts);
    assert!(held(&[false; 2]).is_empty());
    let targets = held(&fixture.teeth_static());
    assert_eq!(targets.keys().copied().collect::<Vec<_>>(), fixture.skin_corners());
    for (&u, at) in &targets {
        let back = [dt.target_neutral[u][0], dt.target_neutral[u][1] + 0.0525, dt.target_neutral[u][2]];
        assert!((0..3).all(|a| (at[a] - back[a]).abs() < 1e-6), "vertex {u} held at {at:?}, not {back:?}");
    }
}
