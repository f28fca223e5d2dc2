//! A rig with the faults real character files carry (zero-area faces, faces listed twice,
//! which also make their edges non-manifold, loose vertices a key moves) gives every tool the
//! clean rig's results on the shared vertices, within 1e-6 of the diagonal; a loose vertex
//! is carried by the motion of its nearest surface point, never left behind.

use shapesmith_native::analysis::{analyze_rig, AnalysisParams};
use shapesmith_native::geometry::mesh_faults::find_mesh_faults;
use shapesmith_native::geometry::weld::Weld;
use shapesmith_native::landmarks::{place_landmarks, score_layout, LandmarkParams, ScoreParams};
use shapesmith_native::packing::{pack_expressions, PackingParams};
use shapesmith_native::performance::{solve_performance, PerformanceParams, Tracks};
use shapesmith_native::rig::bbox_diagonal;
use shapesmith_native::transfer::{transfer_shapes, TransferShapesParams};
use shapesmith_native::wrap::{carry_shapes, wrap_template, CarryParams, PointPairs, WrapParams};
use shapesmith_native::{NoProgress, RigView};

mod common;
use common::{face, shapes, warp};

struct Faulty {
    points: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
    deltas: Vec<[f32; 3]>,
    /// The loose vertex resting just off the sheet, over triangle `over`'s middle.
    hovering: usize,
    over: usize,
}

/// The clean face with, after its own vertices and triangles: a zero-area triangle on a new
/// vertex halfway along an edge, one repeating a corner, two triangles listed again (one
/// wound the other way), and three loose vertices (one hovering over the sheet, one behind
/// it, the halfway vertex whose only face is flat), all moved by the jaw as a stray key would.
fn faulty(points: &[[f32; 3]], triangles: &[[u32; 3]], deltas: &[[f32; 3]]) -> Faulty {
    let n = points.len();
    let mut out = points.to_vec();
    let over = 100;
    let t = triangles[over];
    let middle = (0..3).map(|a| t.iter().map(|&v| points[v as usize][a]).sum::<f32>() / 3.0).collect::<Vec<_>>();
    let edge = triangles[0];
    let halfway = (0..3).map(|a| 0.5 * (points[edge[0] as usize][a] + points[edge[1] as usize][a])).collect::<Vec<_>>();
    out.push([middle[0], middle[1], middle[2] + 0.002]);
    out.push([0.0, 0.5, -0.12]);
    out.push([halfway[0], halfway[1], halfway[2]]);
    let mut tris = triangles.to_vec();
    tris.push([edge[0], edge[1], n as u32 + 2]);
    tris.push([5, 5, 6]);
    tris.push(triangles[10]);
    let d = triangles[40];
    tris.push([d[2], d[1], d[0]]);
    let k = deltas.len() / n;
    let mut rows = Vec::with_capacity(k * (n + 3));
    for (s, block) in deltas.chunks(n).enumerate() {
        rows.extend_from_slice(block);
        rows.extend((0..3).map(|i| [0.3 * (s % 2) as f32, 0.1 * i as f32, -0.2 * (s % 3) as f32]));
    }
    Faulty { points: out, triangles: tris, deltas: rows, hovering: n, over }
}

fn close(a: &[[f32; 3]], b: &[[f32; 3]], tolerance: f64) -> f64 {
    assert_eq!(a.len(), b.len());
    let worst = a.iter().zip(b).map(|(p, q)| (0..3).map(|i| (f64::from(p[i]) - f64::from(q[i])).powi(2)).sum::<f64>().sqrt()).fold(0.0, f64::max);
    assert!(worst <= tolerance, "differ by {worst:e} > {tolerance:e}");
    worst
}

/// The first `n` rows of each block of `rows` (blocks of `m` rows).
fn shared(rows: &[[f32; 3]], m: usize, n: usize) -> Vec<[f32; 3]> {
    rows.chunks(m).flat_map(|block| block[..n].to_vec()).collect()
}

#[test]
fn the_faults_are_named_and_left_out_of_the_surface() {
    let (points, triangles) = face();
    let (deltas, _) = shapes(&points);
    let f = faulty(&points, &triangles, &deltas);
    let (n, t) = (points.len(), triangles.len() as u32);
    let faults = find_mesh_faults(&f.points, &f.triangles).unwrap();
    assert_eq!(faults.zero_area_triangles.all, vec![t, t + 1]);
    assert_eq!(faults.duplicate_triangles.all, vec![[10, t + 2], [40, t + 3]]);
    assert_eq!(faults.loose_vertices.all, vec![n as u32, n as u32 + 1, n as u32 + 2]);
    assert_eq!(faults.non_manifold_edges.count, 0, "the copies are left out, so their edges are the face's own");
    let weld = Weld::new(&f.points, &f.triangles);
    assert_eq!(weld.triangles, triangles);
    assert_eq!(weld.n_welded(), n);
    assert_eq!(weld.carried.iter().map(|c| c.vertex as usize).collect::<Vec<_>>(), vec![n, n + 1, n + 2]);
    // The hovering vertex is read over the triangle it hovers above, inside it.
    let hovering = &weld.carried[0];
    let mut corners = hovering.corners;
    corners.sort_unstable();
    let mut expected = triangles[f.over];
    expected.sort_unstable();
    assert_eq!(corners, expected);
    assert!(hovering.weights.iter().all(|&w| w > 0.2), "{:?}", hovering.weights);
}

#[test]
fn analysis_pack_landmarks_score_and_performance_equal_the_clean_rigs() {
    let (points, triangles) = face();
    let (deltas, names) = shapes(&points);
    let f = faulty(&points, &triangles, &deltas);
    let clean = RigView::new(&points, &deltas, &triangles, &names).unwrap();
    let dirty = RigView::new(&f.points, &f.deltas, &f.triangles, &names).unwrap();

    let (a, b) = (analyze_rig(&dirty, &AnalysisParams::default()).unwrap(), analyze_rig(&clean, &AnalysisParams::default()).unwrap());
    let pairs = |r: &shapesmith_native::analysis::RigAnalysis| r.symmetric_pairs.iter().map(|p| (p.first.clone(), p.second.clone())).collect::<Vec<_>>();
    assert_eq!(pairs(&a), pairs(&b));
    assert!(!pairs(&b).is_empty());
    assert_eq!((a.inert.clone(), a.unmatched_vertices.clone()), (b.inert.clone(), b.unmatched_vertices.clone()));
    for (p, q) in a.symmetric_pairs.iter().zip(&b.symmetric_pairs) {
        assert!((p.mirror_error - q.mirror_error).abs() <= 1e-6 * b.bbox_diagonal, "{} {}", p.mirror_error, q.mirror_error);
    }

    let params = PackingParams::default();
    let (a, b) = (pack_expressions(&dirty, None, &params, &NoProgress).unwrap(), pack_expressions(&clean, None, &params, &NoProgress).unwrap());
    let packed = |p: &shapesmith_native::packing::Packing| p.expressions.iter().map(|e| (e.shapes.clone(), e.vertices)).collect::<Vec<_>>();
    assert_eq!(packed(&a), packed(&b));
    assert_eq!((a.pairs.clone(), a.active.clone()), (b.pairs.clone(), b.active.clone()), "no loose vertex is in an active set");

    for symmetric in [false, true] {
        let params = LandmarkParams { symmetric, ..Default::default() };
        let (a, b) = (place_landmarks(&dirty, &params, &NoProgress).unwrap(), place_landmarks(&clean, &params, &NoProgress).unwrap());
        assert_eq!(a.landmarks, b.landmarks, "symmetric {symmetric}");
        assert!(!a.landmarks.is_empty());
    }
    let layout: Vec<u32> = (0..points.len() as u32).step_by(9).collect();
    let (a, b) = (score_layout(&dirty, &layout, &ScoreParams::default()).unwrap(), score_layout(&clean, &layout, &ScoreParams::default()).unwrap());
    assert!((a.mean - b.mean).abs() <= 1e-6 && (a.max - b.max).abs() <= 1e-6, "{} {} / {} {}", a.mean, a.max, b.mean, b.max);

    // A performance tracked on the clean rig's own poses: the same weights from either rig.
    let landmarks: Vec<u32> = (0..points.len() as u32).step_by(11).collect();
    let n = points.len();
    let tracks: Vec<[f64; 3]> = [0.3f32, 0.8]
        .iter()
        .flat_map(|&w| landmarks.iter().map(move |&v| (v, w)))
        .map(|(v, w)| [0, 1, 2].map(|a| f64::from(points[v as usize][a] + w * (deltas[v as usize][a] + deltas[2 * n + v as usize][a]))))
        .collect();
    let params = PerformanceParams::default();
    let solve = |rig: &RigView| solve_performance(rig, &landmarks, &Tracks::Points(&tracks), &params, &NoProgress).unwrap();
    let (a, b) = (solve(&dirty), solve(&clean));
    for (p, q) in a.frames.iter().zip(&b.frames) {
        for (x, y) in p.weights.iter().zip(&q.weights) {
            assert!((x - y).abs() <= 1e-6, "{x} {y}");
        }
    }
}

#[test]
fn transfer_equals_the_clean_rigs_and_carries_a_loose_vertex_with_its_surface_point() {
    let (points, triangles) = face();
    let (deltas, names) = shapes(&points);
    let f = faulty(&points, &triangles, &deltas);
    let (n, m) = (points.len(), f.points.len());
    let target: Vec<[f32; 3]> = points.iter().map(warp).collect();
    let faulty_target: Vec<[f32; 3]> = f.points.iter().map(warp).collect();
    let params = TransferShapesParams { measure_penetration: true, ..Default::default() };
    let (clean, _) = transfer_shapes(&points, &deltas, &target, &triangles, &names, None, None, &params, &NoProgress).unwrap();
    let (dirty, _) = transfer_shapes(&f.points, &f.deltas, &faulty_target, &f.triangles, &names, None, None, &params, &NoProgress).unwrap();
    let diagonal = bbox_diagonal(&target);
    close(&shared(&dirty, m, n), &clean, 1e-6 * diagonal);
    // The hovering vertex moves as the surface point under it, in every key.
    // Read where the template rests: the transfer carries by its surface.
    let weld = Weld::new(&f.points, &f.triangles);
    let carried = weld.carried.iter().find(|c| c.vertex as usize == f.hovering).unwrap();
    for k in 0..names.len() {
        let mix: Vec<f64> = (0..3)
            .map(|a| (0..3).map(|i| carried.weights[i] * f64::from(clean[k * n + weld.vertex(carried.corners[i]) as usize][a])).sum())
            .collect();
        let got = dirty[k * m + f.hovering];
        assert!((0..3).all(|a| (f64::from(got[a]) - mix[a]).abs() <= 1e-6 * diagonal), "key {k}: {got:?} vs {mix:?}");
    }
    assert!(dirty[2 * m + f.hovering] != [0.0; 3], "the jaw moves the sheet under the hovering vertex");
}

#[test]
fn wrap_and_carry_equal_the_clean_meshes_and_carry_loose_vertices() {
    let (points, triangles) = face();
    let (deltas, _) = shapes(&points);
    let f = faulty(&points, &triangles, &deltas);
    let (n, m) = (points.len(), f.points.len());
    let character: Vec<[f32; 3]> = points.iter().map(warp).collect();
    // The character's faults made on its own shape (the warp would bend a flat triangle).
    let fc = faulty(&character, &triangles, &deltas);
    let faulty_character = fc.points.clone();
    let pairs = PointPairs { template: &[], character: &[] };
    let params = WrapParams { align_only: true, ..Default::default() };
    let clean = wrap_template(&points, &triangles, &character, &triangles, pairs, &params, &NoProgress).unwrap();
    let dirty = wrap_template(&f.points, &f.triangles, &faulty_character, &f.triangles, pairs, &params, &NoProgress).unwrap();
    let diagonal = bbox_diagonal(&character);
    close(&dirty.wrapped[..n], &clean.wrapped, 1e-6 * diagonal);
    // A loose template vertex keeps its offset from the surface point under it.
    let offset = |wrapped: &[[f32; 3]], v: usize| (0..3).map(|a| wrapped[v][a] - f.points[v][a]).collect::<Vec<f32>>();
    assert_ne!(offset(&dirty.wrapped, f.hovering), vec![0.0; 3], "moved with the surface, not left behind");

    let carry = CarryParams { collision_pass: false, ..Default::default() };
    let plain = carry_shapes(&clean.wrapped, &triangles, &deltas, &character, &triangles, None, None, None, &carry, &NoProgress).unwrap();
    let onto = carry_shapes(&clean.wrapped, &triangles, &deltas, &faulty_character, &f.triangles, None, None, None, &carry, &NoProgress).unwrap();
    close(&shared(&onto.deltas, m, n), &plain.deltas, 1e-6 * diagonal);
    assert!(onto.deltas[2 * m + fc.hovering] != [0.0; 3], "the loose vertex follows the jaw");
}

