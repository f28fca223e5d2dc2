//! Tests of the contact solve ([`super::contact`]) on small procedural heads: two-layer lips,
//! skin over separate static teeth, a floating piece over skin, two strips whose edges cross
//! with no vertex inside, a warped target, and a sheet with many pieces crossing it at rest.
//! "No new intersection" is decided by a brute-force test of every pair of triangles, not by
//! the solve's own sweeps.

use super::tests::{head, lip_closing, lips, max_error, plain, Mesh};
use super::*;
use crate::geometry::penetration::{intersection_length, AddedCurve};
use crate::geometry::topology::grid_triangles;
use crate::NoProgress;

/// `neutral + delta`.
pub(super) fn posed(neutral: &[[f32; 3]], delta: &[[f32; 3]]) -> Vec<[f32; 3]> {
    neutral.iter().zip(delta).map(|(p, d)| [p[0] + d[0], p[1] + d[1], p[2] + d[2]]).collect()
}


/// Per cross-section and across position of the folded strip (walls excluded), the upper
/// layer's height above the lower layer's.
fn lip_gaps(points: &[[f32; 3]]) -> Vec<f32> {
    let rows = 22; // folded_strip: 11 lower then 11 upper profile points per cross-section
    (0..points.len() / rows)
        .flat_map(|i| (1..10).map(move |s| points[i * rows + 21 - s][2] - points[i * rows + s][2]))
        .collect()
}

/// Every pair of triangles sharing no vertex that crosses at `points`, `(a, b, length)` with
/// `a < b`, by testing all pairs.
pub(super) fn crossing_lengths(points: &[[f32; 3]], tris: &[[u32; 3]]) -> Vec<(u32, u32, f64)> {
    let corners = |t: &[u32; 3]| t.map(|v| points[v as usize].map(f64::from));
    let mut found = Vec::new();
    for a in 0..tris.len() {
        for b in a + 1..tris.len() {
            if tris[a].iter().any(|v| tris[b].contains(v)) {
                continue;
            }
            if let Some(length) = intersection_length(corners(&tris[a]), corners(&tris[b])) {
                found.push((a as u32, b as u32, length));
            }
        }
    }
    found
}

/// [`crossing_lengths`]' pairs.
fn crossing_pairs(points: &[[f32; 3]], tris: &[[u32; 3]]) -> std::collections::BTreeSet<(usize, usize)> {
    crossing_lengths(points, tris).into_iter().map(|(a, b, _)| (a as usize, b as usize)).collect()
}

/// The pairs crossing in `target + delta` that do not cross in `target`, by brute force.
fn added_crossings(target: &[[f32; 3]], delta: &[[f32; 3]], tris: &[[u32; 3]]) -> Vec<(usize, usize)> {
    let rest = crossing_pairs(target, tris);
    crossing_pairs(&posed(target, delta), tris).into_iter().filter(|p| !rest.contains(p)).collect()
}

/// [`added_crossings`] less the pairs that slid on from a rest crossing: each triangle is, or
/// shares a corner with, one of a pair crossing at rest (skin resting through the teeth slides
/// over them onto the next triangles; method, section 3), by brute force.
fn added_beyond_slid(target: &[[f32; 3]], delta: &[[f32; 3]], tris: &[[u32; 3]]) -> Vec<(usize, usize)> {
    let rest = crossing_pairs(target, tris);
    let near = |a: usize, x: usize| tris[a].iter().any(|v| tris[x].contains(v));
    let slid = |a: usize, b: usize| rest.iter().any(|&(x, y)| (near(a, x) && near(b, y)) || (near(a, y) && near(b, x)));
    added_crossings(target, delta, tris).into_iter().filter(|&(a, b)| !slid(a, b)).collect()
}

fn with_contact() -> TransferParams {
    TransferParams { contact: Some(ContactParams::default()), ..plain() }
}

#[test]
fn thick_lips_that_virtual_edges_alone_leave_crossed_end_pressed_and_apart() {
    let (source, tris) = lips(0.08);
    // The template closes 90% of its 0.08 gap; the target's lips are thicker (gap 0.04). Both
    // gaps are within tau_d at rest, so the lips' springs are the rest's (a gap the key
    // closes from beyond tau_d would add its own and keep these lips apart unaided).
    let closing = lip_closing(&source, 0.08, 0.036);
    let (target, _) = lips(0.04);
    let names = vec!["mouthClose".to_string()];
    let edges = Some(VirtualEdgeParams { tau_d: 0.05, ..Default::default() });
    let with = |contact: Option<ContactParams>| {
        let params = TransferParams { virtual_edges: edges, edge_weight: 1.0, contact, ..Default::default() };
        let dt = DeformationTransfer::new(&source, &target, &tris, &params).unwrap();
        assert!(!dt.virtual_edges().is_empty());
        dt.transfer(&closing, &names, &NoProgress).unwrap()
    };
    let springs_only = with(None);
    assert!(!added_crossings(&target, &springs_only.deltas, &tris).is_empty(), "virtual edges alone should still cross here");
    let solved = with(Some(ContactParams::default()));
    assert_eq!(added_crossings(&target, &solved.deltas, &tris), vec![]);
    let outcome = solved.contact.as_ref().unwrap()[0];
    assert!(outcome.added_pairs > 0 && outcome.remaining_pairs == 0 && outcome.applied && outcome.converged, "{outcome:?}");
    assert_eq!(solved.before_contact[0].as_deref(), Some(&springs_only.deltas[..]));
    // The layers meet: nowhere crossed, and where they close most the gap is within the
    // contact distance (a quarter of the 0.1 edges).
    let gaps = lip_gaps(&posed(&target, &solved.deltas));
    let closest = gaps.iter().copied().fold(f32::INFINITY, f32::min);
    assert!(closest > 0.0 && closest < 0.025, "closest gap {closest}");
}

#[test]
fn skin_pressed_onto_static_teeth_stays_outside_and_other_shapes_are_untouched() {
    // The template's teeth top is at -0.2, below the pressed skin (-0.15); the target's
    // teeth reach up to -0.08, so the transferred press goes through them.
    let (source, tris) = skin_over_teeth(-0.2);
    let (target, _) = skin_over_teeth(-0.08);
    let deltas = press_and_bump(&source);
    let names = vec!["mouthPress".to_string(), "cheekBump".to_string()];
    let n = target.len();
    assert!(crossing_pairs(&posed(&source, &deltas[..n]), &tris).is_empty());
    let without = DeformationTransfer::new(&source, &target, &tris, &plain()).unwrap().transfer(&deltas, &names, &NoProgress).unwrap();
    assert!(!added_crossings(&target, &without.deltas[..n], &tris).is_empty(), "plain transfer should go through");
    let with = DeformationTransfer::new(&source, &target, &tris, &with_contact()).unwrap().transfer(&deltas, &names, &NoProgress).unwrap();
    assert_eq!(added_crossings(&target, &with.deltas[..n], &tris), vec![]);
    let pressed = posed(&target, &with.deltas[..n]);
    // No skin vertex above the teeth is below their top; the teeth did not move.
    for p in &pressed[..15 * 15] {
        if (0.3..=0.7).contains(&p[0]) && (0.3..=0.7).contains(&p[1]) {
            assert!(p[2] > -0.08, "skin vertex inside the teeth: {p:?}");
        }
    }
    assert!(with.deltas[15 * 15..n].iter().all(|d| *d == [0.0; 3]));
    // The skin still presses down onto the teeth (within the contact distance of their top).
    let lowest = pressed[..15 * 15].iter().map(|p| p[2]).fold(f32::INFINITY, f32::min);
    assert!(lowest < -0.06, "the press should still reach the teeth: {lowest}");
    // The bump adds no intersection: bit for bit as without contact, and reported as such.
    assert_eq!(with.deltas[n..], without.deltas[n..]);
    let outcomes = with.contact.unwrap();
    assert!(outcomes[0].applied && outcomes[0].remaining_pairs == 0);
    let nothing = Some(AddedCurve::default());
    assert_eq!(ContactOutcome { penetration: None, plain_penetration: None, ..outcomes[1] }, ContactOutcome { added: nothing, plain_added: nothing, ..Default::default() });
    assert!(with.before_contact[1].is_none());
}

#[test]
fn a_floating_piece_the_transfer_pushes_through_a_static_one_is_held_out_of_it() {
    // A skin sheet (static in the shape) and an upright plate above it (lashes) that the shape
    // moves down by 0.08 as a whole, so the solve places it by the template's motion. The
    // template's plate starts 0.2 above the skin and stays clear; the target's starts 0.04
    // above and goes 0.04 through.
    let w = 11u32;
    let plate = |height: f32| -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let mut pts: Vec<[f32; 3]> = (0..w * w).map(|v| [(v % w) as f32 / (w - 1) as f32, (v / w) as f32 / (w - 1) as f32, 0.0]).collect();
        let mut tris = grid_triangles(w, w, 0);
        let start = pts.len() as u32;
        pts.extend((0..9).map(|v| [0.42 + 0.1 * (v % 3) as f32, 0.53, height + 0.1 * (v / 3) as f32]));
        tris.extend(grid_triangles(3, 3, start));
        (pts, tris)
    };
    let (source, tris) = plate(0.2);
    let (target, _) = plate(0.04);
    let n = source.len();
    let skin = (w * w) as usize;
    let deltas: Vec<[f32; 3]> = (0..n).map(|v| if v < skin { [0.0; 3] } else { [0.0, 0.0, -0.08] }).collect();
    let names = vec!["lashesDown".to_string()];
    let without = DeformationTransfer::new(&source, &target, &tris, &plain()).unwrap().transfer(&deltas, &names, &NoProgress).unwrap();
    assert!(!added_crossings(&target, &without.deltas, &tris).is_empty(), "the plain solve should go through");
    let with = DeformationTransfer::new(&source, &target, &tris, &with_contact()).unwrap().transfer(&deltas, &names, &NoProgress).unwrap();
    assert_eq!(added_crossings(&target, &with.deltas, &tris), vec![]);
    assert!(with.contact.unwrap()[0].applied);
    // The skin stays put; the plate still moves down, and rests above the skin.
    assert!(with.deltas[..skin].iter().all(|d| *d == [0.0; 3]));
    let lowest = posed(&target, &with.deltas)[skin..].iter().map(|p| p[2]).fold(f32::INFINITY, f32::min);
    assert!(lowest > 0.0 && lowest < 0.03, "the plate's lowest point {lowest}");
}

#[test]
fn strips_whose_edges_cross_with_no_vertex_inside_are_kept_apart() {
    // A static horizontal strip along x and a floating upright strip along y above it; the
    // shape moves the upright strip 0.2 down, across the horizontal one: no vertex of either
    // ever lies over the other's surface (the upright one's corners are beyond the other's
    // width, the other's beyond its plane), only their edges cross.
    let flat: Vec<[f32; 3]> = (0..8).map(|v| [-0.45 + 0.3 * (v % 4) as f32, -0.08 + 0.16 * (v / 4) as f32, 0.0]).collect();
    let upright = |h: f32| -> Vec<[f32; 3]> { (0..8).map(|v| [0.0, -0.45 + 0.3 * (v % 4) as f32, h + 0.3 * (v / 4) as f32]).collect() };
    let mut tris = grid_triangles(4, 2, 0);
    tris.extend(grid_triangles(4, 2, 8));
    let (source, target) = ([flat.clone(), upright(0.4)].concat(), [flat, upright(0.05)].concat());
    let deltas: Vec<[f32; 3]> = (0..16).map(|v| if v < 8 { [0.0; 3] } else { [0.0, 0.0, -0.2] }).collect();
    for (v, p) in posed(&target, &deltas).iter().enumerate() {
        let over = if v < 8 { p[0].abs() < 1e-3 } else { p[1].abs() < 0.08 };
        assert!(!over, "a vertex over the other strip: {p:?}");
    }
    let names = vec!["drop".to_string()];
    let without = DeformationTransfer::new(&source, &target, &tris, &plain()).unwrap().transfer(&deltas, &names, &NoProgress).unwrap();
    assert!(!added_crossings(&target, &without.deltas, &tris).is_empty(), "the plain solve should cross");
    let with = DeformationTransfer::new(&source, &target, &tris, &with_contact()).unwrap().transfer(&deltas, &names, &NoProgress).unwrap();
    assert_eq!(added_crossings(&target, &with.deltas, &tris), vec![]);
    let lowest = posed(&target, &with.deltas)[8..].iter().map(|p| p[2]).fold(f32::INFINITY, f32::min);
    assert!(lowest > 0.0 && lowest < 0.05, "the upright strip's lowest point {lowest}");
}

#[test]
fn self_transfer_stays_exact_even_where_the_template_crosses_itself() {
    // The template's lips close past each other (0.06 each way across a 0.1 gap): the
    // artist's own crossing is kept, so the template onto itself is still exact.
    let (pts, tris) = lips(0.1);
    let closing = lip_closing(&pts, 0.1, 0.06);
    assert!(!crossing_pairs(&posed(&pts, &closing), &tris).is_empty());
    let names = vec!["mouthClose".to_string()];
    let diagonal = crate::rig::bbox_diagonal(&pts);
    for edges in [None, Some(VirtualEdgeParams { tau_d: 0.1, ..Default::default() })] {
        let params = TransferParams { virtual_edges: edges, contact: Some(ContactParams::default()), ..Default::default() };
        let out = DeformationTransfer::new(&pts, &pts, &tris, &params).unwrap().transfer(&closing, &names, &NoProgress).unwrap();
        assert!(max_error(&out.deltas, &closing) < 1e-6 * diagonal, "{}", max_error(&out.deltas, &closing));
        assert!(!out.contact.unwrap()[0].applied);
    }
}

#[test]
fn bad_contact_distances_are_refused() {
    let (pts, tris, _) = head();
    for distance in [-0.1, 0.0, f64::NAN, MAX_CONTACT_DISTANCE + 0.5] {
        let params = TransferParams { contact: Some(ContactParams { distance }), ..plain() };
        let err = DeformationTransfer::new(&pts, &pts, &tris, &params).unwrap_err().to_string();
        assert!(err.contains("contact distance"), "{err}");
    }
}

#[test]
fn contact_keeps_a_warped_target_within_two_percent_of_plain_transfers_error() {
    // The target is the template's lips under a known smooth map W that halves their
    // thickness, so the true shape is W(V0 + D): lips closing to 0.002 apart without crossing.
    // Deformation transfer copies the template's absolute closing (0.048 a side) onto the
    // thinner gap and crosses; the contact solve must not take the result more than 2%
    // further from the truth than plain transfer.
    let squash = |p: &[f32; 3]| [p[0], 1.1 * p[1] + 0.05 * p[0] * p[0], 0.5 * p[2]];
    let (source, tris) = lips(0.1);
    let closing = lip_closing(&source, 0.1, 0.048);
    let target: Vec<[f32; 3]> = source.iter().map(squash).collect();
    let truth: Vec<[f32; 3]> = source
        .iter()
        .zip(&closing)
        .zip(&target)
        .map(|((p, d), t)| {
            let w = squash(&[p[0] + d[0], p[1] + d[1], p[2] + d[2]]);
            [w[0] - t[0], w[1] - t[1], w[2] - t[2]]
        })
        .collect();
    assert_eq!(added_crossings(&target, &truth, &tris), vec![]);
    let names = vec!["mouthClose".to_string()];
    let run = |params: TransferParams| DeformationTransfer::new(&source, &target, &tris, &params).unwrap().transfer(&closing, &names, &NoProgress).unwrap();
    // Mean error over the vertices that move in the truth.
    let error = |deltas: &[[f32; 3]]| {
        let active: Vec<usize> = (0..truth.len()).filter(|&v| truth[v] != [0.0; 3]).collect();
        active.iter().map(|&v| max_error(&deltas[v..v + 1], &truth[v..v + 1])).sum::<f64>() / active.len() as f64
    };
    let without = run(plain());
    assert!(!added_crossings(&target, &without.deltas, &tris).is_empty(), "plain transfer should cross here");
    let with = run(with_contact());
    assert_eq!(added_crossings(&target, &with.deltas, &tris), vec![]);
    let (before, after) = (error(&without.deltas), error(&with.deltas));
    assert!(after <= 1.02 * before, "ground-truth error grew from {before:.3e} to {after:.3e}");
}

#[test]
fn skin_resting_through_a_static_piece_slides_through_it_and_adds_no_other_crossing() {
    let (source, target, tris, deltas) = skin_rising_over_teeth();
    let n = source.len();
    let names = vec!["lipRise".to_string(), "cheekBump".to_string()];
    assert!(!crossing_pairs(&source, &tris).is_empty() && !crossing_pairs(&target, &tris).is_empty());
    assert_eq!(added_crossings(&source, &deltas[..n], &tris), vec![], "the template's rise stays inside its tall teeth");
    let without = DeformationTransfer::new(&source, &target, &tris, &plain()).unwrap().transfer(&deltas, &names, &NoProgress).unwrap();
    assert!(!added_crossings(&target, &without.deltas[..n], &tris).is_empty(), "plain transfer should poke through the top");
    let with = DeformationTransfer::new(&source, &target, &tris, &with_contact()).unwrap().transfer(&deltas, &names, &NoProgress).unwrap();
    assert_eq!(added_beyond_slid(&target, &with.deltas[..n], &tris), vec![]);
    // The skin over the teeth's top stays below it, and the teeth did not move.
    for p in &posed(&target, &with.deltas[..n])[..15 * 15] {
        if (0.32..=0.68).contains(&p[0]) && (0.32..=0.68).contains(&p[1]) {
            assert!(p[2] < 0.02, "skin vertex above the teeth's top: {p:?}");
        }
    }
    assert!(with.deltas[15 * 15..n].iter().all(|d| *d == [0.0; 3]));
    assert_eq!(with.deltas[n..], without.deltas[n..]);
    assert!(with.contact.unwrap()[0].applied);
}

/// A flat skin sheet over a box of teeth (a separate piece), the teeth's top at `top`.
pub(super) fn skin_over_teeth(top: f32) -> Mesh {
    let w = 15usize;
    let mut pts: Vec<[f32; 3]> = Vec::new();
    for y in 0..w {
        for x in 0..w {
            pts.push([x as f32 / (w - 1) as f32, y as f32 / (w - 1) as f32, 0.0]);
        }
    }
    let mut tris = grid_triangles(w as u32, w as u32, 0);
    let start = pts.len() as u32;
    for c in 0..8u32 {
        let z = if c >> 2 == 1 { top } else { -0.5 };
        pts.push([0.3 + 0.4 * (c & 1) as f32, 0.3 + 0.4 * ((c >> 1) & 1) as f32, z]);
    }
    for quad in [[0u32, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]] {
        tris.push([start + quad[0], start + quad[1], start + quad[2]]);
        tris.push([start + quad[0], start + quad[2], start + quad[3]]);
    }
    (pts, tris)
}

/// The skin plane cutting through the teeth at rest (both meshes cross from the start: the
/// MakeHuman lids and lips rest inside their eyeballs and teeth), and a small rise of the skin
/// over the teeth (first shape; the second is [`press_and_bump`]'s bump) that stays inside the
/// template's tall teeth but pokes through the target's top, 0.02 above the skin: only the
/// target's shape adds curve. Template, target, triangles, deltas.
pub(super) fn skin_rising_over_teeth() -> (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<[u32; 3]>, Vec<[f32; 3]>) {
    let (source, tris) = skin_over_teeth(0.2);
    let (target, _) = skin_over_teeth(0.02);
    let mut deltas = press_and_bump(&source);
    for (v, p) in source.iter().enumerate().take(15 * 15) {
        let rise = (-((p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2)) / 0.01).exp();
        deltas[v] = if rise > 1e-3 { [0.0, 0.0, 0.03 * rise] } else { [0.0; 3] };
    }
    (source, target, tris, deltas)
}

/// Shape 0 presses the middle of the skin down by 0.15 (the teeth stay); shape 1 raises a
/// bump in a corner, far from the teeth.
pub(super) fn press_and_bump(pts: &[[f32; 3]]) -> Vec<[f32; 3]> {
    let skin = 15 * 15;
    let mut deltas = vec![[0.0f32; 3]; 2 * pts.len()];
    for (v, p) in pts.iter().enumerate().take(skin) {
        let press = (-((p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2)) / 0.03).exp();
        if press > 1e-3 {
            deltas[v] = [0.0, 0.0, -0.15 * press];
        }
        let bump = (-((p[0] - 0.1).powi(2) + (p[1] - 0.1).powi(2)) / 0.005).exp();
        if bump > 1e-3 {
            deltas[pts.len() + v] = [0.0, 0.0, 0.05 * bump];
        }
    }
    deltas
}

/// A wavy skin sheet (piece 0) with 36 small boxes poking through it at rest (eyeballs and
/// teeth through the lids and lips) and 12 thin slanted blades through it (lashes): 49
/// pieces crossing the skin in hundreds of triangle pairs. Four shapes with smooth falloffs
/// and no cut-off, so that many vertices move by less than the static threshold: a smile on
/// the skin, a jaw (the lower boxes and the skin over them), a look (four boxes turn in
/// place), a puff.
fn many_pieces_crossing_at_rest() -> (Vec<[f32; 3]>, Vec<[u32; 3]>, Vec<[f32; 3]>, Vec<String>) {
    let w = 24usize;
    let height = |x: f32, y: f32| 0.04 * (3.0 * x).sin() * (2.0 * y).cos();
    let mut pts: Vec<[f32; 3]> = (0..w * w)
        .map(|v| {
            let (x, y) = ((v % w) as f32 / (w - 1) as f32, (v / w) as f32 / (w - 1) as f32);
            [x, y, height(x, y)]
        })
        .collect();
    let mut tris = grid_triangles(w as u32, w as u32, 0);
    let skin = pts.len();
    let mut boxes = Vec::new();
    for (i, j) in (0..6).flat_map(|i| (0..6).map(move |j| (i, j))) {
        let centre = [0.12 + 0.152 * i as f32, 0.12 + 0.152 * j as f32];
        let start = pts.len() as u32;
        let z = height(centre[0], centre[1]);
        for c in 0..8u32 {
            let corner = |bit: u32, size: f32| if c & bit == 0 { -size } else { size };
            pts.push([centre[0] + corner(1, 0.037), centre[1] + corner(2, 0.031), z + corner(4, 0.023)]);
        }
        for quad in [[0u32, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]] {
            tris.push([start + quad[0], start + quad[1], start + quad[2]]);
            tris.push([start + quad[0], start + quad[2], start + quad[3]]);
        }
        boxes.push((start as usize..pts.len(), centre));
    }
    for k in 0..12 {
        let (x, y) = (0.2 + 0.055 * k as f32, 0.9);
        let start = pts.len() as u32;
        let z = height(x, y);
        pts.extend([[x, y - 0.02, z - 0.02], [x + 0.03, y - 0.02, z - 0.015], [x + 0.01, y + 0.03, z + 0.03]]);
        tris.push([start, start + 1, start + 2]);
    }
    let n = pts.len();
    let mut deltas = vec![[0.0f32; 3]; 4 * n];
    let falloff = |p: [f32; 3], c: [f32; 2], spread: f32| (-((p[0] - c[0]).powi(2) + (p[1] - c[1]).powi(2)) / spread).exp();
    for v in 0..skin {
        let p = pts[v];
        let smile = falloff(p, [0.5, 0.35], 0.02);
        deltas[v] = [0.02 * smile, 0.015 * smile, 0.03 * smile];
        let jaw = 1.0 / (1.0 + (40.0 * (p[1] - 0.3)).exp());
        deltas[n + v] = [0.0, -0.03 * jaw, 0.006 * jaw];
        let puff = falloff(p, [0.8, 0.75], 0.01);
        deltas[3 * n + v] = [0.005 * puff, 0.0, 0.025 * puff];
    }
    for (range, centre) in &boxes {
        let jaw = 1.0 / (1.0 + (40.0 * (centre[1] - 0.3)).exp());
        let look = falloff([centre[0], centre[1], 0.0], [0.3, 0.7], 0.01) > 0.3;
        for v in range.clone() {
            deltas[n + v] = [0.0, -0.03 * jaw, 0.006 * jaw];
            if look {
                let (x, y) = (pts[v][0] - centre[0], pts[v][1] - centre[1]);
                let (s, c) = 0.25f32.sin_cos();
                deltas[2 * n + v] = [c * x - s * y - x, s * x + c * y - y, 0.0];
            }
        }
    }
    (pts, tris, deltas, ["smile", "jawOpen", "eyeLookIn", "cheekPuff"].map(String::from).to_vec())
}

#[test]
fn self_transfer_of_a_head_of_many_pieces_crossing_at_rest_comes_back_as_it_is() {
    let (pts, tris, deltas, names) = many_pieces_crossing_at_rest();
    let rest = measure_penetration(&pts, &tris);
    assert!(rest.pairs > 300 && rest.between_pieces == rest.length, "{rest:?}");
    assert!(crate::geometry::topology::connected_components(pts.len(), &tris).1 >= 49);
    let transfer = TransferParams { contact: Some(ContactParams::default()), ..Default::default() };
    let params = TransferShapesParams { transfer, measure_penetration: true, ..Default::default() };
    let (out, report) = transfer_shapes(&pts, &deltas, &pts, &tris, &names, None, None, &params, &NoProgress).unwrap();
    let diagonal = crate::rig::bbox_diagonal(&pts);
    let n = pts.len();
    for (k, row) in report.penetration.iter().enumerate() {
        let rows = k * n..(k + 1) * n;
        let error = max_error(&out[rows.clone()], &deltas[rows]);
        assert!(error < 1e-6 * diagonal, "{}: {:.2e} of the diagonal", row.name, error / diagonal);
        assert!(row.contact.is_some_and(|c| !c.applied), "{}: {:?}", row.name, row.contact);
    }
}

/// The report's judge tests the template's shape only near the pairs it is asked about; it
/// must judge those pairs as the whole sweep's exemptions do, bit for bit: the naive copy of
/// each template shape onto thinner lips and onto skin rising over teeth.
#[test]
fn the_judge_near_the_asked_pairs_agrees_with_the_whole_sweep() {
    let (thick, lip_tris) = lips(0.08);
    let closing = lip_closing(&thick, 0.08, 0.036);
    let (source, target, tris, deltas) = skin_rising_over_teeth();
    let mut judged = 0;
    for (source, target, tris, deltas) in [(&thick, &lips(0.04).0, &lip_tris, &closing), (&source, &target, &tris, &deltas)] {
        let n = source.len();
        let dt = DeformationTransfer::new(source, target, tris, &with_contact()).unwrap();
        let judge = dt.crossing_judge().expect("contact on");
        let rest = measure_penetration(source, tris);
        for delta in deltas.chunks(n) {
            let copy: Vec<[f64; 3]> = dt.target_neutral.iter().zip(delta).map(|(p, d)| [0, 1, 2].map(|a| p[a] + f64::from(d[a]))).collect();
            let swept = crate::geometry::penetration::crossings(&copy, tris, &crate::geometry::bvh::TriangleBvh::build(&copy, tris), None);
            let moving = dt.moving_vertices(delta);
            let added = AddedCurve::from_penetrations(&measure_penetration(&posed(source, delta), tris), &rest);
            let whole = judge.added_curve(&swept, &judge.exemptions(&dt, delta, &moving));
            let near = judge.added_curve(&swept, &judge.exemptions_near(&dt, delta, &moving, added, &judge.asked(&swept)));
            assert_eq!(near, whole);
            judged += usize::from(whole.total() > 0.0);
        }
    }
    assert!(judged >= 2, "the copies should add crossings beyond the exemptions on both meshes");
}
