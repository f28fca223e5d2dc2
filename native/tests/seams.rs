//! A rig split along UV seams, as Blender's glTF and FBX importers leave it (every seam
//! vertex copied, the copies exactly on top of each other), gives every tool the results of
//! the same rig welded, and every copy of a seam vertex the same delta to the bit.

use shapesmith_native::analysis::{analyze_rig, AnalysisParams};
use shapesmith_native::geometry::topology::connected_components;
use shapesmith_native::geometry::weld::Weld;
use shapesmith_native::landmarks::{place_landmarks, LandmarkParams};
use shapesmith_native::packing::{pack_expressions, PackingParams};
use shapesmith_native::transfer::{measure_rig_penetration, transfer_shapes, TransferShapesParams};
use shapesmith_native::wrap::{carry_shapes, wrap_template, CarryParams, PointPairs, WrapParams};
use shapesmith_native::{NoProgress, RigView};

mod common;
use common::{face, shapes, warp};

/// The mesh split along UV seams: the sheet's upper half (triangles whose centroid is above
/// y = 0.55) and the teeth's top face are islands whose boundary vertices are copied at the
/// end of the vertex list. Returns, per vertex of the split mesh, its welded vertex, and the
/// split triangles.
fn split(points: &[[f32; 3]], triangles: &[[u32; 3]]) -> (Vec<u32>, Vec<[u32; 3]>) {
    let top_of_teeth = |t: &[u32; 3]| t.iter().all(|&v| v as usize >= points.len() - 8 && points[v as usize][1] > 0.25);
    let island = |t: &[u32; 3]| t.iter().map(|&v| points[v as usize][1]).sum::<f32>() / 3.0 > 0.55 && (t[0] as usize) < points.len() - 8;
    let in_island: Vec<bool> = triangles.iter().map(|t| island(t) || top_of_teeth(t)).collect();
    let (mut inside, mut outside) = (vec![false; points.len()], vec![false; points.len()]);
    for (t, tri) in triangles.iter().enumerate() {
        for &v in tri {
            if in_island[t] { inside[v as usize] = true } else { outside[v as usize] = true }
        }
    }
    let mut source: Vec<u32> = (0..points.len() as u32).collect();
    let mut copy = vec![u32::MAX; points.len()];
    for v in 0..points.len() {
        if inside[v] && outside[v] {
            copy[v] = source.len() as u32;
            source.push(v as u32);
        }
    }
    let split = triangles
        .iter()
        .zip(&in_island)
        .map(|(tri, &isl)| if isl { tri.map(|v| if copy[v as usize] != u32::MAX { copy[v as usize] } else { v }) } else { *tri })
        .collect();
    (source, split)
}

/// `rows` (blocks of N rows) on the split mesh's vertices.
fn pick(rows: &[[f32; 3]], source: &[u32], n: usize) -> Vec<[f32; 3]> {
    rows.chunks(n).flat_map(|block| source.iter().map(|&v| block[v as usize])).collect()
}

struct Rigs {
    points: Vec<[f32; 3]>,
    triangles: Vec<[u32; 3]>,
    deltas: Vec<[f32; 3]>,
    names: Vec<String>,
    source: Vec<u32>,
    split_points: Vec<[f32; 3]>,
    split_triangles: Vec<[u32; 3]>,
    split_deltas: Vec<[f32; 3]>,
}

fn rigs() -> Rigs {
    let (points, triangles) = face();
    let (deltas, names) = shapes(&points);
    let (source, split_triangles) = split(&points, &triangles);
    let n = points.len();
    let (split_points, split_deltas) = (pick(&points, &source, n), pick(&deltas, &source, n));
    Rigs { points, triangles, deltas, names, source, split_points, split_triangles, split_deltas }
}

#[test]
fn the_split_face_welds_back_into_the_face() {
    let r = rigs();
    assert!(r.source.len() > r.points.len() + 20, "the split should copy the seam: {} copies", r.source.len() - r.points.len());
    let weld = Weld::new(&r.split_points, &r.split_triangles);
    assert_eq!(weld.n_welded(), r.points.len());
    assert_eq!(weld.triangles, r.triangles);
    assert_eq!((weld.seam_groups(), weld.seam_vertices()), (r.source.len() - r.points.len(), 2 * (r.source.len() - r.points.len())));
    // Pieces are the welded surface's: a sheet and the teeth, not four islands.
    assert_eq!(connected_components(r.points.len(), &r.triangles).1, 2);
    assert_eq!(connected_components(r.split_points.len(), &r.split_triangles).1, 4);
    assert_eq!(connected_components(weld.n_welded(), &weld.triangles).1, 2);
    let analysis = analyze_rig(&RigView::new(&r.split_points, &r.split_deltas, &r.split_triangles, &r.names).unwrap(), &AnalysisParams::default()).unwrap();
    let welded = analyze_rig(&RigView::new(&r.points, &r.deltas, &r.triangles, &r.names).unwrap(), &AnalysisParams::default()).unwrap();
    assert_eq!((analysis.seam_groups, analysis.seam_vertices), (weld.seam_groups(), weld.seam_vertices()));
    assert_eq!((welded.seam_groups, welded.seam_vertices), (0, 0));
    let pairs = |a: &shapesmith_native::analysis::RigAnalysis| a.symmetric_pairs.iter().map(|p| (p.first.clone(), p.second.clone(), p.mirror_error)).collect::<Vec<_>>();
    assert_eq!(pairs(&analysis), pairs(&welded));
    assert!(!pairs(&welded).is_empty());
    assert_eq!(analysis.unmatched_vertices, welded.unmatched_vertices);
}

#[test]
fn transfer_onto_a_split_target_closes_every_seam_and_equals_the_welded_transfer() {
    let r = rigs();
    let n = r.points.len();
    let target: Vec<[f32; 3]> = r.points.iter().map(warp).collect();
    let split_target = pick(&target, &r.source, n);
    let params = TransferShapesParams { measure_penetration: true, ..Default::default() };
    let (welded, welded_report) = transfer_shapes(&r.points, &r.deltas, &target, &r.triangles, &r.names, None, None, &params, &NoProgress).unwrap();
    let (deltas, report) =
        transfer_shapes(&r.split_points, &r.split_deltas, &split_target, &r.split_triangles, &r.names, None, None, &params, &NoProgress).unwrap();
    // Every copy has its welded vertex's delta, to the bit: no seam opens, and the result is
    // the welded rig's.
    assert_eq!(deltas, pick(&welded, &r.source, n));
    assert!(welded.iter().any(|d| *d != [0.0; 3]));
    assert_eq!(report.penetration, welded_report.penetration);
    assert_eq!(report.virtual_edges, welded_report.virtual_edges);
    // The penetration metric sees the seam's triangles as neighbours.
    assert_eq!(
        measure_rig_penetration(&r.split_points, &r.split_deltas, &r.split_triangles).unwrap(),
        measure_rig_penetration(&r.points, &r.deltas, &r.triangles).unwrap()
    );
}

#[test]
fn packing_and_landmarks_on_the_split_face_equal_the_welded_ones() {
    let r = rigs();
    let split = RigView::new(&r.split_points, &r.split_deltas, &r.split_triangles, &r.names).unwrap();
    let welded = RigView::new(&r.points, &r.deltas, &r.triangles, &r.names).unwrap();
    let params = PackingParams::default();
    let (a, b) = (pack_expressions(&split, None, &params, &NoProgress).unwrap(), pack_expressions(&welded, None, &params, &NoProgress).unwrap());
    let shapes = |p: &shapesmith_native::packing::Packing| p.expressions.iter().map(|e| (e.shapes.clone(), e.vertices)).collect::<Vec<_>>();
    assert_eq!(shapes(&a), shapes(&b));
    assert_eq!(a.pairs, b.pairs);
    // The sheet tints every copy of a moving point.
    let weld = Weld::new(&r.split_points, &r.split_triangles);
    for (k, active) in a.active.iter().enumerate() {
        assert_eq!(*active, weld.expand(&b.active[k]), "shape {k}");
    }
    for symmetric in [false, true] {
        let params = LandmarkParams { symmetric, ..Default::default() };
        let (a, b) = (place_landmarks(&split, &params, &NoProgress).unwrap(), place_landmarks(&welded, &params, &NoProgress).unwrap());
        // A landmark is a welded point, reported as its lowest vertex (here the original).
        assert_eq!(a.landmarks, b.landmarks, "symmetric {symmetric}");
        assert!(!a.landmarks.is_empty());
    }
}

#[test]
fn wrap_and_carry_onto_a_split_character_weld_its_seams() {
    let r = rigs();
    let n = r.points.len();
    let character: Vec<[f32; 3]> = r.points.iter().map(warp).collect();
    let split_character = pick(&character, &r.source, n);
    let pairs = PointPairs { template: &[], character: &[] };
    let params = WrapParams { align_only: true, ..Default::default() };
    let welded = wrap_template(&r.points, &r.triangles, &character, &r.triangles, pairs, &params, &NoProgress).unwrap();
    // The template split too: its copies land together, where the welded template's land.
    let split = wrap_template(&r.split_points, &r.split_triangles, &split_character, &r.split_triangles, pairs, &params, &NoProgress).unwrap();
    assert_eq!(split.wrapped, pick(&welded.wrapped, &r.source, n));
    let carry = CarryParams { collision_pass: false, ..Default::default() };
    let plain = carry_shapes(&welded.wrapped, &r.triangles, &r.deltas, &character, &r.triangles, None, None, None, &carry, &NoProgress).unwrap();
    let onto_split = carry_shapes(&welded.wrapped, &r.triangles, &r.deltas, &split_character, &r.split_triangles, None, None, None, &carry, &NoProgress).unwrap();
    assert_eq!(onto_split.deltas, pick(&plain.deltas, &r.source, n));
}
