//! Collision and occlusion conflicts checked against definitions recomputed here the long
//! way (every pose in full, every triangle for every vertex), on synthetic faces with known
//! answers and on random two-sheet instances where sheets pass through and hide each other.

use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use super::collisions::find_collisions;
use super::conflicts::ConflictReason;
use super::occlusion::{find_occlusions, hides, DEPTH_EPSILON};
use super::regions::{moving_regions, PosedTriangles, RestHierarchy, MOVING_FRACTION};
use super::tests::{check_packing, Instance};
use super::*;
use crate::geometry::bvh::TriangleBvh;
use crate::geometry::mat3::{cross, dot, length, scale, Vec3};
use crate::geometry::penetration::crossings;
use crate::progress::NoProgress;

/// `V0 + sum of D_k` in f64, every vertex, each shape moving only the vertices that move
/// more than `MOVING_FRACTION` of its largest displacement.
fn posed(rig: &RigView, shapes: &[usize]) -> Vec<Vec3> {
    let max: Vec<f64> = shapes.iter().map(|&k| rig.delta(k).iter().map(crate::rig::norm).fold(0.0, f64::max)).collect();
    let step = |i: usize, v: usize| {
        let d = rig.delta(shapes[i])[v];
        if crate::rig::norm(&d) > MOVING_FRACTION * max[i] { d } else { [0.0; 3] }
    };
    (0..rig.n_vertices())
        .map(|v| std::array::from_fn(|a| rig.neutral[v][a] as f64 + (0..shapes.len()).map(|i| step(i, v)[a] as f64).sum::<f64>()))
        .collect()
}

/// The penetration metric's length over the whole posed mesh, and its part between pieces.
fn curve_length(rig: &RigView, shapes: &[usize]) -> [f64; 2] {
    let points = posed(rig, shapes);
    let (label, _) = crate::geometry::topology::connected_components(rig.n_vertices(), rig.triangles);
    let piece = |t: u32| label[rig.triangles[t as usize][0] as usize];
    let all = crossings(&points, rig.triangles, &TriangleBvh::build(&points, rig.triangles), None);
    [all.iter().map(|c| c.2).sum(), all.iter().filter(|c| piece(c.0) != piece(c.1)).map(|c| c.2).sum()]
}

/// E(A, B) of method, section 1 from four full sweeps: (total, between pieces).
fn added_curve(rig: &RigView, a: usize, b: usize) -> [f64; 2] {
    let [ab, ao, bo, rest] = [curve_length(rig, &[a, b]), curve_length(rig, &[a]), curve_length(rig, &[b]), curve_length(rig, &[])];
    [0, 1].map(|i| ab[i] - ao[i] - bo[i] + rest[i])
}

/// How many of shape `hidden`'s active vertices the camera along `toward` sees in the pose
/// `shapes`, testing every triangle.
fn seen(rig: &RigView, shapes: &[usize], active: &[u32], toward: Vec3) -> usize {
    let z = scale(toward, 1.0 / length(toward));
    let helper = if z[0].abs() < 0.5 { [1.0, 0.0, 0.0] } else { [0.0, 1.0, 0.0] };
    let x = scale(cross(z, helper), 1.0 / length(cross(z, helper)));
    let y = cross(z, x);
    let points: Vec<Vec3> = posed(rig, shapes).iter().map(|&p| [dot(p, x), dot(p, y), dot(p, z)]).collect();
    let epsilon = DEPTH_EPSILON * rig.bbox_diagonal();
    active
        .iter()
        .filter(|&&v| {
            !rig.triangles
                .iter()
                .any(|t| !t.contains(&v) && hides(&t.map(|u| points[u as usize]), points[v as usize], epsilon))
        })
        .count()
}

/// Pairs `(i, j)`, i < j, in `candidates` that collide or of which one hides the other.
fn brute_force_edges(rig: &RigView, params: &PackingParams, active: &[Vec<u32>], candidates: &[(usize, usize)]) -> (Vec<(usize, usize)>, Vec<(usize, usize)>) {
    let diagonal = rig.bbox_diagonal();
    let collisions: Vec<(usize, usize)> = if params.collision_conflicts {
        candidates.iter().copied().filter(|&(a, b)| added_curve(rig, a, b)[1] > params.collision_tolerance * diagonal).collect()
    } else {
        Vec::new()
    };
    let occlusions = if params.occlusion_conflicts {
        let hidden_by = |h: usize, by: usize| {
            let alone = seen(rig, &[h], &active[h], params.camera_direction);
            alone > 0 && (seen(rig, &[h, by], &active[h], params.camera_direction) as f64) < params.occlusion_keep * alone as f64
        };
        candidates
            .iter()
            .copied()
            .filter(|p| !collisions.contains(p))
            .filter(|&(a, b)| hidden_by(a, b) || hidden_by(b, a))
            .collect()
    } else {
        Vec::new()
    };
    (collisions, occlusions)
}

/// The collision and occlusion edges a packing must have, recomputed the long way: between
/// placeable shapes whose active sets are disjoint and that are neither antagonists nor kept
/// apart (the method: any of those already forbids the pair).
pub(super) fn brute_force_poseability(
    rig: &RigView,
    params: &PackingParams,
    active: &[Vec<usize>],
    placeable: &[bool],
    antagonists: &[(usize, usize)],
) -> Vec<(usize, usize)> {
    let listed = |list: &[(usize, usize)], i: usize, j: usize| list.contains(&(i, j)) || list.contains(&(j, i));
    let k = placeable.len();
    let candidates: Vec<(usize, usize)> = (0..k)
        .flat_map(|i| (i + 1..k).map(move |j| (i, j)))
        .filter(|&(i, j)| placeable[i] && placeable[j] && !active[i].iter().any(|v| active[j].contains(v)))
        .filter(|&(i, j)| !listed(antagonists, i, j) && !listed(&params.keep_apart, i, j))
        .collect();
    let active32: Vec<Vec<u32>> = active.iter().map(|a| a.iter().map(|&v| v as u32).collect()).collect();
    let (mut edges, occlusions) = brute_force_edges(rig, params, &active32, &candidates);
    edges.extend(occlusions);
    edges
}

/// A grid of `cols` x `rows` vertices: `origin + i * step_u + j * step_v`.
fn sheet(points: &mut Vec<[f32; 3]>, triangles: &mut Vec<[u32; 3]>, origin: Vec3, step_u: Vec3, step_v: Vec3, cols: u32, rows: u32) -> std::ops::Range<usize> {
    let first = points.len() as u32;
    for j in 0..rows {
        for i in 0..cols {
            points.push(std::array::from_fn(|a| (origin[a] + i as f64 * step_u[a] + j as f64 * step_v[a]) as f32));
        }
    }
    triangles.extend(crate::geometry::topology::grid_triangles(cols, rows, first));
    first as usize..points.len()
}

fn shape_index(packing: &Packing, inst: &Instance, name: &str) -> usize {
    let k = inst.names.iter().position(|n| n == name).unwrap();
    assert!(packing.importance[k] > 0.0);
    k
}

fn together(packing: &Packing, a: usize, b: usize) -> bool {
    packing.expressions.iter().any(|e| e.shapes.contains(&a) && e.shapes.contains(&b))
}

fn reasons_of(packing: &Packing, a: usize, b: usize) -> Option<Vec<ConflictReason>> {
    let (first, second) = (a.min(b), a.max(b));
    packing.conflicts.iter().find(|c| (c.first, c.second) == (first, second)).map(|c| c.reasons.clone())
}

/// Lips in two parallel vertical sheets (upper at y = 0, lower at y = 0.02, the mouth
/// between z = -0.05 and 0.05) and a horizontal tongue behind them at z = 0. tongueOut slides
/// the tongue 0.8 forward through the mouth; mouthClose brings the lips together across
/// z = 0; jawOpen drops the lower lip.
fn mouth() -> Instance {
    let (mut points, mut triangles) = (Vec::new(), Vec::new());
    let upper = sheet(&mut points, &mut triangles, [1.0, 0.0, 0.05], [0.25, 0.0, 0.0], [0.0, 0.0, 0.15], 9, 4);
    let lower = sheet(&mut points, &mut triangles, [1.0, 0.02, -0.05], [0.25, 0.0, 0.0], [0.0, 0.0, -0.15], 9, 4);
    let tongue = sheet(&mut points, &mut triangles, [1.6, 0.25, 0.0], [0.2, 0.0, 0.0], [0.0, 0.2, 0.0], 5, 5);
    let n = points.len();
    let mut deltas = vec![[0.0f32; 3]; 3 * n];
    for v in tongue {
        deltas[v] = [0.0, -0.8, 0.0];
    }
    for (range, sign) in [(upper, -1.0f32), (lower.clone(), 1.0)] {
        for v in range.clone() {
            let row = (v - range.start) / 9;
            deltas[n + v] = [0.0, 0.0, sign * [0.15, 0.1, 0.05, 0.0][row]];
        }
    }
    for v in lower {
        deltas[2 * n + v] = [0.0, 0.0, -0.3];
    }
    Instance { points, triangles, deltas, names: ["tongueOut", "mouthClose", "jawOpen"].map(String::from).to_vec() }
}

#[test]
fn tongue_out_collides_with_closed_lips_but_not_with_an_open_jaw() {
    let inst = mouth();
    let params = PackingParams::default();
    let packing = pack_expressions(&inst.rig(), None, &params, &NoProgress).unwrap();
    check_packing(&inst, &params, &packing);
    let (tongue, close, jaw) = (shape_index(&packing, &inst, "tongueOut"), shape_index(&packing, &inst, "mouthClose"), shape_index(&packing, &inst, "jawOpen"));
    assert_eq!(reasons_of(&packing, tongue, close), Some(vec![ConflictReason::Collision]));
    assert!(!together(&packing, tongue, close));
    assert!(together(&packing, tongue, jaw), "{:?}", packing.expressions);
    // Known answer: the tongue (0.8 wide) crosses each closed lip along one line.
    let collision = packing.poseability.collisions[0];
    let expected = 2.0 * 0.8 / inst.rig().bbox_diagonal();
    assert!((collision.added - expected).abs() < 1e-5, "{} vs {expected}", collision.added);
    assert!((collision.between_pieces - expected).abs() < 1e-5, "the tongue is a piece of its own");
    assert!(packing.poseability.collisions.iter().all(|c| (c.first, c.second) == (tongue, close)));

    // Switched off, the edge is gone and only the overlap keeps the lips from the jaw.
    let off = PackingParams { collision_conflicts: false, ..params };
    let packing = pack_expressions(&inst.rig(), None, &off, &NoProgress).unwrap();
    check_packing(&inst, &off, &packing);
    assert_eq!(reasons_of(&packing, tongue, close), None);
    assert!(packing.poseability.collisions.is_empty() && packing.poseability.collision_pairs_tested == 0);
}

/// An eyeball (a patch at y = 0.1) under an open lid (a patch at y = 0 above it), seen from
/// -Y, and a mouth far below. eyeLookIn turns the eyeball sideways, eyeBlink slides the lid
/// down over all but the eyeball's lowest row, mouthFunnel pushes the mouth forward.
fn eye() -> Instance {
    let (mut points, mut triangles) = (Vec::new(), Vec::new());
    let ball = sheet(&mut points, &mut triangles, [1.0, 0.1, 1.0], [0.2, 0.0, 0.0], [0.0, 0.0, 0.2], 6, 6);
    let lid = sheet(&mut points, &mut triangles, [0.8, 0.0, 2.1], [0.2, 0.0, 0.0], [0.0, 0.0, 0.2], 9, 6);
    let mouth = sheet(&mut points, &mut triangles, [1.0, 0.0, -2.0], [0.2, 0.0, 0.0], [0.0, 0.0, 0.2], 6, 6);
    let n = points.len();
    let mut deltas = vec![[0.0f32; 3]; 3 * n];
    ball.for_each(|v| deltas[v] = [0.2, 0.0, 0.0]);
    lid.for_each(|v| deltas[n + v] = [0.0, 0.0, -1.0]);
    mouth.for_each(|v| deltas[2 * n + v] = [0.0, -0.3, 0.0]);
    Instance { points, triangles, deltas, names: ["eyeLookIn", "eyeBlink", "mouthFunnel"].map(String::from).to_vec() }
}

#[test]
fn a_closing_lid_hides_the_eyeball_turn_but_a_mouth_shape_does_not() {
    let inst = eye();
    let params = PackingParams::default();
    let packing = pack_expressions(&inst.rig(), None, &params, &NoProgress).unwrap();
    check_packing(&inst, &params, &packing);
    let (look, blink, funnel) = (shape_index(&packing, &inst, "eyeLookIn"), shape_index(&packing, &inst, "eyeBlink"), shape_index(&packing, &inst, "mouthFunnel"));
    assert_eq!(reasons_of(&packing, look, blink), Some(vec![ConflictReason::Occlusion]));
    assert_eq!(reasons_of(&packing, look, funnel), None);
    assert!(!together(&packing, look, blink));
    // Known answer: of the 36 eyeball vertices, only the lowest row of 6 stays in sight.
    assert_eq!(packing.poseability.occlusions.len(), 1);
    let o = packing.poseability.occlusions[0];
    assert_eq!((o.hidden, o.by), (look, blink));
    assert!((o.kept - 6.0 / 36.0).abs() < 1e-12, "{}", o.kept);
    // The mouth is far from the eye in 3-D and in the front view: never tested.
    assert_eq!(packing.poseability.occlusion_directions_tested, 2);

    // Switched off, all three share one expression.
    let off = PackingParams { occlusion_conflicts: false, ..params };
    let packing = pack_expressions(&inst.rig(), None, &off, &NoProgress).unwrap();
    check_packing(&inst, &off, &packing);
    assert_eq!(packing.expressions.len(), 1);
}

/// Two 5 x 5 sheets, at z = 0 and z = 0.6 (shifted by half a cell), with `third` a smaller
/// 4 x 4 one at z = 0.3 (three pieces: two outside the largest, whose crossings the
/// collision test finds from the lower triangle), and K blobs, each on one sheet: full
/// displacement inside a radius, a tenth in a ring, a fiftieth beyond, along +-z by 0.9
/// (through the other sheet) or along x or y by 0.6.
fn two_sheets(rng: &mut ChaCha8Rng, k_count: usize, third: bool) -> Instance {
    let (mut points, mut triangles) = (Vec::new(), Vec::new());
    let mut sheets = vec![
        sheet(&mut points, &mut triangles, [1.0, 1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], 5, 5),
        sheet(&mut points, &mut triangles, [1.5, 1.5, 0.6], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], 5, 5),
    ];
    if third {
        sheets.push(sheet(&mut points, &mut triangles, [1.7, 1.2, 0.3], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0], 4, 4));
    }
    let mut deltas = Vec::new();
    for _ in 0..k_count {
        let range = sheets[rng.random_range(0..sheets.len())].clone();
        let centre = points[rng.random_range(range.clone())];
        let radius = rng.random_range(0.5f32..1.6);
        let mut direction = [0.0f32; 3];
        let axis = rng.random_range(0..4).min(2);
        direction[axis] = if axis == 2 { 0.9 } else { 0.6 } * if rng.random_bool(0.5) { 1.0 } else { -1.0 };
        for (v, p) in points.iter().enumerate() {
            let d = ((p[0] - centre[0]).powi(2) + (p[1] - centre[1]).powi(2)).sqrt();
            let scale = match d {
                _ if !range.contains(&v) => 0.0,
                d if d <= radius => 1.0,
                d if d <= radius + 1.0 => 0.1,
                d if d <= radius + 2.0 => 0.02, // a tail below MOVING_FRACTION: posed still
                _ => 0.0,
            };
            deltas.push(direction.map(|c| c * scale));
        }
    }
    Instance { points, triangles, deltas, names: (0..k_count).map(|k| format!("s{k}")).collect() }
}

/// The pruned tests (moving regions' boxes, moved triangles only, curve between pieces
/// searched from the pieces outside the largest, shared hierarchies) find exactly the pairs the
/// long way finds when every pair is tested, with the same added curve; packing with those
/// edges still gives brute-force optimal expressions.
#[test]
fn pruned_tests_equal_testing_every_pair_and_packings_stay_optimal() {
    let mut rng = ChaCha8Rng::seed_from_u64(29);
    let (mut collided, mut hid, mut tested, mut pairs, mut packed_edges) = (0, 0, 0, 0, 0);
    for trial in 0..40 {
        let k_count = rng.random_range(2..=8);
        let inst = two_sheets(&mut rng, k_count, trial % 4 == 3);
        let rig = inst.rig();
        let params = PackingParams {
            camera_direction: if trial % 2 == 0 { [0.0, 0.0, 1.0] } else { [0.3, -1.0, 0.2] },
            collision_tolerance: [1e-6, 0.02, 0.1][trial % 3],
            pairs: Some(Vec::new()),
            fewest: true,
            ..PackingParams::default()
        };
        let (_, active) = setup::binary_blendshapes(&rig, params.mu);
        let all: Vec<(usize, usize)> = (0..k_count).flat_map(|i| (i + 1..k_count).map(move |j| (i, j))).collect();
        let regions = moving_regions(&rig, &vec![true; k_count]);
        let (found, n_tested) = find_collisions(&rig, &RestHierarchy::new(&rig, &regions), &regions, &all, params.collision_tolerance, INTERACTION_MARGIN);
        let diagonal = rig.bbox_diagonal();
        let expected: Vec<(usize, usize)> =
            all.iter().copied().filter(|&(a, b)| added_curve(&rig, a, b)[1] > params.collision_tolerance * diagonal).collect();
        assert_eq!(found.iter().map(|c| (c.first, c.second)).collect::<Vec<_>>(), expected, "trial {trial}");
        for c in &found {
            let [added, between] = added_curve(&rig, c.first, c.second);
            assert!((c.added * diagonal - added).abs() < 1e-9 && (c.between_pieces * diagonal - between).abs() < 1e-9);
        }
        let (hidden, n_directions) =
            find_occlusions(&rig, &RestHierarchy::new(&rig, &regions), &regions, &active, &all, params.occlusion_keep, INTERACTION_MARGIN, params.camera_direction).unwrap();
        let mut hidden_pairs: Vec<(usize, usize)> = hidden.iter().map(|o| (o.hidden.min(o.by), o.hidden.max(o.by))).collect();
        hidden_pairs.sort_unstable();
        hidden_pairs.dedup();
        let only_occlusion = PackingParams { collision_conflicts: false, ..params.clone() };
        assert_eq!(hidden_pairs, brute_force_edges(&rig, &only_occlusion, &active, &all).1, "trial {trial}");
        collided += found.len();
        hid += hidden_pairs.len();
        tested += n_tested + n_directions;
        pairs += 3 * all.len();

        let packing = pack_expressions(&rig, None, &params, &NoProgress).unwrap();
        check_packing(&inst, &params, &packing);
        packed_edges += packing.poseability.collisions.len() + packing.poseability.occlusions.len();
    }
    assert!(collided > 10 && hid > 10 && packed_edges > 10, "too few to tell: {collided} collisions, {hid} occlusions, {packed_edges} edges");
    assert!(tested < pairs, "the pruning tested {tested} of {pairs}");
}

/// Each shape's moved triangles, posed by it alone, are the region's triangles at the shape's
/// pose, whether the occlusion test takes them over from the collision test (which no longer
/// holds them) or they are cut afresh (still held elsewhere, or never cut).
#[test]
fn moved_triangles_handed_over_are_those_posed_alone() {
    let mut rng = ChaCha8Rng::seed_from_u64(37);
    let inst = two_sheets(&mut rng, 5, true);
    let rig = inst.rig();
    let regions = moving_regions(&rig, &[true; 5]);
    let shared = RestHierarchy::new(&rig, &regions);
    for k in 0..5 {
        let points = posed(&rig, &[k]);
        let check = |set: &PosedTriangles| {
            let mut listed = set.triangles.clone();
            listed.sort_unstable();
            assert!(!listed.is_empty() && listed == regions[k].triangles, "shape {k}");
            for (&t, c) in set.triangles.iter().zip(&set.corners) {
                assert_eq!(*c, rig.triangles[t as usize].map(|v| points[v as usize]), "shape {k}, triangle {t}");
            }
        };
        let held = shared.alone(k);
        check(&shared.take_alone(k));
        check(held.as_ref());
        drop(held);
        drop(shared.alone(k));
        check(&shared.take_alone(k));
        check(&shared.take_alone(k));
    }
}

#[test]
fn unusable_poseability_settings_are_rejected_with_a_reason() {
    let inst = eye();
    for (params, message) in [
        (PackingParams { collision_tolerance: 0.0, ..PackingParams::default() }, "collision_tolerance"),
        (PackingParams { occlusion_keep: 1.5, ..PackingParams::default() }, "occlusion_keep"),
        (PackingParams { camera_direction: [0.0, 0.0, 0.0], ..PackingParams::default() }, "camera direction"),
        (PackingParams { camera_direction: [f64::NAN, 1.0, 0.0], ..PackingParams::default() }, "camera direction"),
    ] {
        match pack_expressions(&inst.rig(), None, &params, &NoProgress) {
            Err(crate::error::ShapesmithError::InvalidInput(m)) => assert!(m.contains(message), "{m}"),
            other => panic!("{message}: {other:?}"),
        }
    }
}

/// Packing again with an earlier packing's results ([`PackingParams::known`]) gives the same
/// conflicts, to the bit and in the same order, and the same expressions, testing only the
/// pairs the results do not decide: all of them given, none tested; a random part given (as
/// after a change of the candidates), the rest tested; results naming shapes the rig lacks
/// are refused.
#[test]
fn known_results_are_reused_and_give_the_same_packing() {
    let mut rng = ChaCha8Rng::seed_from_u64(31);
    let (mut reused_some, mut conflicts) = (0, 0);
    for trial in 0..24 {
        let k_count = rng.random_range(3..=8);
        let inst = two_sheets(&mut rng, k_count, trial % 3 == 2);
        let rig = inst.rig();
        let params = PackingParams {
            camera_direction: [0.0, 0.0, 1.0],
            collision_tolerance: [1e-6, 0.02][trial % 2],
            pairs: Some(Vec::new()),
            ..PackingParams::default()
        };
        let cold = pack_expressions(&rig, None, &params, &NoProgress).unwrap();
        let known = cold.poseability.known.clone();
        let same = |warm: &Packing| {
            assert_eq!(warm.poseability.collisions, cold.poseability.collisions, "trial {trial}");
            assert_eq!(warm.poseability.occlusions, cold.poseability.occlusions, "trial {trial}");
            assert_eq!(warm.expressions.iter().map(|e| &e.shapes).collect::<Vec<_>>(), cold.expressions.iter().map(|e| &e.shapes).collect::<Vec<_>>());
            assert_eq!(warm.conflicts, cold.conflicts);
        };
        let all = PackingParams { known: Some(known.clone()), ..params.clone() };
        let warm = pack_expressions(&rig, None, &all, &NoProgress).unwrap();
        same(&warm);
        assert_eq!((warm.poseability.collision_pairs_tested, warm.poseability.occlusion_directions_tested), (0, 0));
        assert_eq!(warm.poseability.pairs_reused, known.collision_tested.len());

        // Half the decided pairs forgotten: those are tested again, and the answers agree.
        let keep = |list: &[(usize, usize)], rng: &mut ChaCha8Rng| list.iter().copied().filter(|_| rng.random_bool(0.5)).collect::<Vec<_>>();
        let collision_tested = keep(&known.collision_tested, &mut rng);
        let occlusion_tested = keep(&known.occlusion_tested, &mut rng);
        let part = KnownPoseability {
            collisions: known.collisions.iter().copied().filter(|c| collision_tested.contains(&(c.first, c.second))).collect(),
            occlusions: known
                .occlusions
                .iter()
                .copied()
                .filter(|o| occlusion_tested.contains(&(o.hidden.min(o.by), o.hidden.max(o.by))))
                .collect(),
            collision_tested,
            occlusion_tested,
        };
        let warm = pack_expressions(&rig, None, &PackingParams { known: Some(part), ..params.clone() }, &NoProgress).unwrap();
        same(&warm);
        assert_eq!(warm.poseability.known.collision_tested.len(), known.collision_tested.len());
        reused_some += usize::from(warm.poseability.pairs_reused > 0 && warm.poseability.pairs_reused < known.collision_tested.len());
        conflicts += cold.poseability.collisions.len() + cold.poseability.occlusions.len();
    }
    assert!(reused_some > 5 && conflicts > 5, "too few to tell: {reused_some} partly reused, {conflicts} conflicts");

    let inst = eye();
    let stale = KnownPoseability { collision_tested: vec![(0, 7)], ..KnownPoseability::default() };
    match pack_expressions(&inst.rig(), None, &PackingParams { known: Some(stale), ..PackingParams::default() }, &NoProgress) {
        Err(crate::error::ShapesmithError::InvalidInput(m)) => assert!(m.contains("do not belong"), "{m}"),
        other => panic!("{other:?}"),
    }
}
