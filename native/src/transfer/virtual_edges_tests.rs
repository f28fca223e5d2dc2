//! Tests of the virtual-edge searches: the lazy search against the definition computed the
//! slow way, and the pairs a key brings into contact.

use super::*;
use crate::transfer::key_contacts::KeyContactSearch;

/// A flattened tube along x: its cross-section is a thin closed loop, a lower row at
/// z = 0 and an upper row at z = `gap` (y from -0.5 to 0.5), joined at y = +-0.5. Opposite
/// rows are close in space but far along the surface, like two lips joined at the
/// corners. `len` cross-sections 0.1 apart; returns positions and triangles.
pub fn folded_strip(len: usize, gap: f32) -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let steps = 10;
    let mut profile: Vec<[f32; 2]> = (0..=steps).map(|s| [-0.5 + s as f32 / steps as f32, 0.0]).collect();
    profile.extend((0..=steps).rev().map(|s| [-0.5 + s as f32 / steps as f32, gap]));
    let rows = profile.len();
    let mut pts = Vec::new();
    for i in 0..len {
        for q in &profile {
            pts.push([i as f32 * 0.1, q[0], q[1]]);
        }
    }
    let mut tris = Vec::new();
    for i in 0..len - 1 {
        for r in 0..rows {
            let a = (i * rows + r) as u32;
            let b = (i * rows + (r + 1) % rows) as u32;
            let c = a + rows as u32;
            let d = b + rows as u32;
            tris.push([a, b, d]);
            tris.push([a, d, c]);
        }
    }
    (pts, tris)
}

#[test]
fn pairs_across_a_thin_gap_only() {
    let (pts, tris) = folded_strip(12, 0.02);
    let params = VirtualEdgeParams { tau_d: 0.1, ..Default::default() };
    let edges = find_virtual_edges(&pts, &tris, &params);
    assert!(!edges.is_empty());
    let diag = bbox_diagonal(&pts) as f32;
    for &(i, j) in &edges {
        let (p, q) = (pts[i as usize], pts[j as usize]);
        let d = ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
        assert!(i < j && d < 0.1 * diag);
        // One end on each layer, away from the walls.
        assert!((p[2] - q[2]).abs() > 0.015, "{p:?} {q:?}");
    }
    let mut count = vec![0; pts.len()];
    for &(i, j) in &edges {
        count[i as usize] += 1;
        count[j as usize] += 1;
    }
    assert!(count.iter().all(|&c| c <= 3));
    // Thinning: no taken end is a one-ring neighbour of an end taken earlier.
    let adjacency = Adjacency::from_triangles(pts.len(), &tris);
    for (k, &(i, j)) in edges.iter().enumerate() {
        for &(a, b) in &edges[..k] {
            for end in [a, b] {
                let ring = adjacency.neighbours(end as usize);
                assert!(!ring.contains(&i) && !ring.contains(&j));
            }
        }
    }
}

/// The paper's definition, computed the slow way: full Dijkstra from every vertex, every
/// close pair of one piece with `g > tau_r d` kept, then the same thinning, shortest first.
fn by_definition(neutral: &[[f32; 3]], triangles: &[[u32; 3]], params: &VirtualEdgeParams) -> Vec<(u32, u32)> {
    by_definition_among(neutral, triangles, params, params.tau_d * bbox_diagonal(neutral), |_, _| true)
}

/// [`by_definition`] with the radius given and only the pairs `(i, j)`, `i < j`, with
/// `candidate(i, j)`.
fn by_definition_among(
    neutral: &[[f32; 3]],
    triangles: &[[u32; 3]],
    params: &VirtualEdgeParams,
    radius: f64,
    candidate: impl Fn(usize, usize) -> bool,
) -> Vec<(u32, u32)> {
    let n = neutral.len();
    let points: Vec<[f64; 3]> = neutral.iter().map(|p| p.map(f64::from)).collect();
    let adjacency = Adjacency::from_triangles(n, triangles);
    let mut far = Vec::new();
    for i in 0..n {
        let mut g = vec![f64::INFINITY; n];
        let mut done = vec![false; n];
        g[i] = 0.0;
        while let Some(v) = (0..n).filter(|&v| !done[v] && g[v].is_finite()).min_by(|&a, &b| g[a].total_cmp(&g[b])) {
            done[v] = true;
            for &u in adjacency.neighbours(v) {
                g[u as usize] = g[u as usize].min(g[v] + distance(&points[v], &points[u as usize]));
            }
        }
        for j in i + 1..n {
            let d = distance(&points[i], &points[j]);
            // Another piece (no path at all) is no candidate.
            if d < radius && g[j].is_finite() && g[j] > params.tau_r * d && candidate(i, j) {
                far.push((d, i as u32, j as u32));
            }
        }
    }
    far.sort_by(|a, b| a.0.total_cmp(&b.0).then(a.1.cmp(&b.1)).then(a.2.cmp(&b.2)));
    let (mut used, mut blocked, mut edges) = (vec![0; n], vec![false; n], Vec::new());
    for (_, i, j) in far {
        let (a, b) = (i as usize, j as usize);
        if blocked[a] || blocked[b] || used[a] >= params.max_per_vertex || used[b] >= params.max_per_vertex {
            continue;
        }
        used[a] += 1;
        used[b] += 1;
        edges.push((i, j));
        for end in [a, b] {
            for &nb in adjacency.neighbours(end) {
                blocked[nb as usize] = true;
            }
        }
    }
    edges
}

#[test]
fn lazy_search_gives_the_edges_of_the_definition() {
    // A jittered strip (uneven edges, so breadth-first paths are not shortest) and, with
    // the wider thresholds, close pairs around the folds whose short paths leave the
    // Euclidean ball: both of the lazy search's shortcuts are exercised.
    let (mut pts, tris) = folded_strip(12, 0.04);
    let mut state = 12345u64;
    for p in pts.iter_mut() {
        for coordinate in &mut p[..2] {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            *coordinate += ((state >> 33) as f32 / (1u64 << 31) as f32 - 0.5) * 0.06;
        }
    }
    for (tau_d, tau_r) in [(0.05, 4.0), (0.1, 4.0), (0.2, 2.0), (0.3, 1.5)] {
        let params = VirtualEdgeParams { tau_d, tau_r, ..Default::default() };
        let expected = by_definition(&pts, &tris, &params);
        assert!(!expected.is_empty(), "tau_d {tau_d}, tau_r {tau_r}: no edges to compare");
        assert_eq!(find_virtual_edges(&pts, &tris, &params), expected, "tau_d {tau_d}, tau_r {tau_r}");
    }
}

#[test]
fn landmark_bounds_keep_the_edges_of_the_definition_on_several_pieces() {
    // Two jittered strips of other shapes, far enough apart that no pair joins them: each
    // piece searches with its own landmarks (one multi-source Dijkstra per slot serves
    // both), and the pruned searches must still find exactly the definition's edges.
    let (first, first_tris) = folded_strip(10, 0.05);
    let (second, second_tris) = folded_strip(7, 0.03);
    let offset = first.len() as u32;
    let mut pts: Vec<[f32; 3]> = first.clone();
    pts.extend(second.iter().map(|p| [p[1] + 3.0, p[0] * 1.3, p[2] - 0.2]));
    let mut tris = first_tris;
    tris.extend(second_tris.iter().map(|t| t.map(|v| v + offset)));
    let mut state = 987654321u64;
    for p in pts.iter_mut() {
        for coordinate in p.iter_mut() {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            *coordinate += ((state >> 33) as f32 / (1u64 << 31) as f32 - 0.5) * 0.01;
        }
    }
    for (tau_d, tau_r) in [(0.02, 4.0), (0.04, 3.0), (0.08, 1.5)] {
        let params = VirtualEdgeParams { tau_d, tau_r, ..Default::default() };
        let expected = by_definition(&pts, &tris, &params);
        assert!(expected.iter().any(|&(i, _)| i < offset) && expected.iter().any(|&(i, _)| i >= offset), "tau_d {tau_d}: both pieces need edges");
        assert_eq!(find_virtual_edges(&pts, &tris, &params), expected, "tau_d {tau_d}, tau_r {tau_r}");
    }
}

#[test]
fn crossing_lips_among_many_pieces_give_the_edges_of_the_definition() {
    // A folded strip whose upper layer dips through the lower one mid-way (lips crossing
    // at rest), a second strip across it and a small one threaded through both (pieces
    // crossing the skin, as lashes and gums do), jittered: close pairs on both sides of
    // the crossing, far pairs between the layers, and other pieces within every ball.
    let (lips, lips_tris) = folded_strip(12, 0.04);
    let mut pts: Vec<[f32; 3]> = lips
        .iter()
        .map(|&[x, y, z]| {
            let dip = if z > 0.02 && y.abs() < 0.45 { 0.08 * (1.0 - (x - 0.55).abs() / 0.3).max(0.0) } else { 0.0 };
            [x, y, z - dip]
        })
        .collect();
    let mut tris = lips_tris;
    for (section, gap, place) in [(8, 0.05, [0.3f32, -0.2, -0.05]), (5, 0.02, [0.5, 0.1, 0.0])] {
        let (piece, piece_tris) = folded_strip(section, gap);
        let offset = pts.len() as u32;
        pts.extend(piece.iter().map(|p| [place[0] + p[1] * 0.6, place[1] + p[0], place[2] + p[2]]));
        tris.extend(piece_tris.iter().map(|t| t.map(|v| v + offset)));
    }
    let mut state = 424242u64;
    for p in pts.iter_mut() {
        for coordinate in p.iter_mut() {
            state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            *coordinate += ((state >> 33) as f32 / (1u64 << 31) as f32 - 0.5) * 0.01;
        }
    }
    let (labels, pieces) = connected_components(pts.len(), &tris);
    assert_eq!(pieces, 3);
    for (tau_d, tau_r) in [(0.03, 4.0), (0.06, 4.0), (0.1, 3.0), (0.2, 1.5)] {
        let params = VirtualEdgeParams { tau_d, tau_r, ..Default::default() };
        let expected = by_definition(&pts, &tris, &params);
        let with_edges = (0..3).filter(|&piece| expected.iter().any(|&(i, _)| labels[i as usize] == piece)).count();
        assert!(with_edges >= 2, "tau_d {tau_d}: edges on {with_edges} pieces");
        assert_eq!(find_virtual_edges(&pts, &tris, &params), expected, "tau_d {tau_d}, tau_r {tau_r}");
    }
}

#[test]
fn landmark_bound_is_a_lower_bound_on_every_pair() {
    let (pts, tris) = folded_strip(8, 0.04);
    let points: Vec<[f64; 3]> = pts.iter().map(|p| p.map(f64::from)).collect();
    let adjacency = Adjacency::from_triangles(pts.len(), &tris);
    let graph = EdgeGraph::new(&points, &adjacency);
    let (labels, _) = connected_components(pts.len(), &tris);
    let bounds = LandmarkBounds::new(&graph, &points, &labels);
    let mut tight = 0;
    for i in 0..pts.len() {
        // Dijkstra by scanning, as `by_definition` does.
        let mut g = vec![f64::INFINITY; pts.len()];
        let mut done = vec![false; pts.len()];
        g[i] = 0.0;
        while let Some(v) = (0..pts.len()).filter(|&v| !done[v] && g[v].is_finite()).min_by(|&a, &b| g[a].total_cmp(&g[b])) {
            done[v] = true;
            for &u in adjacency.neighbours(v) {
                g[u as usize] = g[u as usize].min(g[v] + distance(&points[v], &points[u as usize]));
            }
        }
        for j in 0..pts.len() {
            let bound = bounds.between(i, j);
            assert!(bound <= g[j] * (1.0 + 1e-12), "{i} {j}: bound {bound} above the distance {}", g[j]);
            tight += usize::from(bound > distance(&points[i], &points[j]) * 1.5);
        }
    }
    // Across the fold the bound is far above the straight distance: that is its use.
    assert!(tight > pts.len(), "only {tight} pairs with a bound above 1.5x the straight distance");
}

#[test]
fn flat_sheet_and_separate_pieces_have_none() {
    let (pts, tris) = folded_strip(6, 0.02);
    // A second copy shifted just beside the first: close, but another piece.
    let offset = pts.len() as u32;
    let mut all = pts.clone();
    all.extend(pts.iter().map(|p| [p[0], p[1], p[2] + 0.03]));
    let mut all_tris = tris.clone();
    all_tris.extend(tris.iter().map(|t| t.map(|v| v + offset)));
    let wide = VirtualEdgeParams { tau_d: 0.1, ..Default::default() };
    let within_first: Vec<_> = find_virtual_edges(&pts, &tris, &wide);
    let both = find_virtual_edges(&all, &all_tris, &wide);
    assert!(both.iter().all(|&(i, j)| (i < offset) == (j < offset)));
    assert!(!within_first.is_empty());
    // A thick slab: only same-layer neighbours are close, and they are close along the
    // surface too.
    let (open, open_tris) = folded_strip(6, 0.5);
    assert!(find_virtual_edges(&open, &open_tris, &wide).is_empty());
}

#[test]
fn a_keys_contacts_are_the_far_pairs_of_its_pose_apart_at_rest() {
    // Layers 0.1 apart at rest, closed unevenly by the key (most at the middle, a little
    // jitter): the pairs it brings within tau_d, to at most half their rest distance, far
    // along the posed surface, that were not within tau_d at rest; thinned as at rest. Once
    // with even cross-sections, once graded (edges along the strip from 0.01 to 0.2, so the
    // search's classes of edge length differ along it).
    let (even, tris) = folded_strip(12, 0.1);
    let graded: Vec<[f32; 3]> = even.iter().map(|p| [p[0] * p[0] / 1.1 + 0.01 * p[0], p[1], p[2]]).collect();
    for pts in [even, graded] {
        let mut state = 777u64;
        let key: Vec<[f32; 3]> = pts
            .iter()
            .map(|p| {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                let jitter = 1.0 + ((state >> 33) as f32 / (1u64 << 31) as f32 - 0.5) * 0.1;
                let along = (std::f32::consts::PI * p[0] / 1.1).sin().max(0.0).powi(2);
                let across = (std::f32::consts::PI * (p[1] + 0.5)).sin().max(0.0).powi(2);
                let bump = 0.047 * along * across * jitter;
                if p[2] > 0.05 {
                    [0.0, 0.0, -bump]
                } else {
                    [0.0, 0.0, bump]
                }
            })
            .collect();
        let n = pts.len();
        let rest: Vec<[f64; 3]> = pts.iter().map(|p| p.map(f64::from)).collect();
        let posed: Vec<[f32; 3]> = rest.iter().zip(&key).map(|(p, d)| [0, 1, 2].map(|a| (p[a] + f64::from(d[a])) as f32)).collect();
        let posed64: Vec<[f64; 3]> = posed.iter().map(|p| p.map(f64::from)).collect();
        let (labels, _) = connected_components(n, &tris);
        let adjacency = Adjacency::from_triangles(n, &tris);
        let diagonal = bbox_diagonal(&pts);
        let search = |resting: Vec<bool>, params: VirtualEdgeParams| {
            KeyContactSearch::new(&rest, Adjacency::from_triangles(n, &tris), resting, &labels, diagonal, params).edges(&rest, &key)
        };
        for (tau_d, tau_r) in [(0.03, 4.0), (0.04, 4.0), (0.05, 4.0), (0.04, 2.0)] {
            let params = VirtualEdgeParams { tau_d, tau_r, ..Default::default() };
            let radius = tau_d * diagonal;
            let edge = |v: usize| {
                let ring = adjacency.neighbours(v);
                ring.iter().map(|&u| distance(&rest[v], &rest[u as usize])).sum::<f64>() / ring.len() as f64
            };
            let brought_together = |i: usize, j: usize| {
                let (at_rest, posed) = (distance(&rest[i], &rest[j]), distance(&posed64[i], &posed64[j]));
                at_rest >= radius && 2.0 * posed <= at_rest && 2.0 * posed <= edge(i) + edge(j)
            };
            let expected = by_definition_among(&posed, &tris, &params, radius, brought_together);
            assert!(expected.len() >= 4, "tau_d {tau_d}: {} edges", expected.len());
            assert_eq!(search(vec![false; n], params), expected, "tau_d {tau_d}, tau_r {tau_r}");
            // Surfaces resting in contact take none: here every pair has an end on the upper layer.
            let upper: Vec<bool> = pts.iter().map(|p| p[2] > 0.05).collect();
            assert!(search(upper, params).is_empty());
            // None at rest: the key made them.
            assert!(find_virtual_edges(&pts, &tris, &params).is_empty());
        }
    }
}
