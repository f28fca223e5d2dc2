//! Tests of the triangle hierarchy (`bvh.rs`) against testing every triangle.

use super::*;
use rand::{Rng, SeedableRng};

/// Random triangles in the unit cube, random segments: the BVH agrees with testing every
/// triangle.
#[test]
fn agrees_with_brute_force() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
    let points: Vec<[f64; 3]> = (0..600).map(|_| std::array::from_fn(|_| rng.random::<f64>())).collect();
    let triangles: Vec<[u32; 3]> = (0..200)
        .map(|i| {
            let a = 3 * i as u32;
            [a, a + 1, a + 2]
        })
        .collect();
    // Shrink triangles so that rays can pass between them.
    let points: Vec<[f64; 3]> = points
        .chunks(3)
        .flat_map(|c| {
            let centre: [f64; 3] = std::array::from_fn(|a| (c[0][a] + c[1][a] + c[2][a]) / 3.0);
            c.iter().map(move |p| std::array::from_fn(|a| centre[a] + 0.15 * (p[a] - centre[a]))).collect::<Vec<_>>()
        })
        .collect();
    let bvh = TriangleBvh::build(&points, &triangles);
    let mut hits = 0;
    for _ in 0..3000 {
        let origin: [f64; 3] = std::array::from_fn(|_| rng.random_range(-0.2..1.2));
        let direction: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
        let t_max = rng.random_range(0.1..2.0);
        let brute = triangles.iter().any(|t| {
            let [a, b, c] = t.map(|v| points[v as usize]);
            ray_meets(&PreparedTriangle { a, ab: sub(&b, &a), ac: sub(&c, &a) }, &origin, &direction, t_max)
        });
        assert_eq!(bvh.any_hit(&origin, &direction, t_max), brute);
        hits += brute as usize;
    }
    assert!(hits > 100 && hits < 2900, "the test should see both hits and misses, saw {hits} hits");
}

/// Random small boxes' triangles: the overlap query finds exactly the triangles whose
/// boxes a brute-force sweep finds.
#[test]
fn overlap_query_matches_brute_force() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
    let points: Vec<[f64; 3]> = (0..900)
        .map(|i| {
            let base = (i / 3) as f64;
            std::array::from_fn(|a| ((base * (a + 1) as f64 * 0.618).fract()) + 0.1 * rng.random::<f64>())
        })
        .collect();
    let triangles: Vec<[u32; 3]> = (0..300).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    let bvh = TriangleBvh::build(&points, &triangles);
    let boxes: Vec<Aabb> = triangles.iter().map(|t| Aabb::of_points(&t.map(|v| points[v as usize]))).collect();
    let mut seen = 0;
    for query in &boxes {
        let mut found = Vec::new();
        bvh.for_each_overlap(query, |t| found.push(t));
        found.sort_unstable();
        let expect: Vec<u32> = (0..triangles.len() as u32).filter(|&t| boxes[t as usize].overlaps(query)).collect();
        assert_eq!(found, expect);
        seen += expect.len();
    }
    assert!(seen > 2 * boxes.len(), "the boxes should overlap more than themselves, saw {seen}");
    // Refitted to moved corners, the tree answers like one built on them.
    let moved: Vec<[f64; 3]> = points.iter().map(|p| [p[0] + 0.3 * p[1] * p[1], p[1] - 0.2 * p[2], p[2]]).collect();
    let refitted = bvh.refitted(&moved, &triangles);
    let moved_boxes: Vec<Aabb> = triangles.iter().map(|t| Aabb::of_points(&t.map(|v| moved[v as usize]))).collect();
    for query in &moved_boxes {
        let mut found = Vec::new();
        refitted.for_each_overlap(query, |t| found.push(t));
        found.sort_unstable();
        let expect: Vec<u32> = (0..triangles.len() as u32).filter(|&t| moved_boxes[t as usize].overlaps(query)).collect();
        assert_eq!(found, expect);
    }
}

/// Random triangles moved in part: refitting in place only the moved ones gives the
/// boxes of a refit of all of them, and the pruned closest-point query among a subset
/// gives the unpruned filtered query's answer to the bit.
#[test]
fn partial_refit_and_pruned_closest_point_match_the_full_ones() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let points: Vec<[f64; 3]> = (0..900).map(|_| std::array::from_fn(|_| rng.random::<f64>())).collect();
    let triangles: Vec<[u32; 3]> = (0..300).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    let bvh = TriangleBvh::build(&points, &triangles);
    let changed: Vec<bool> = (0..triangles.len()).map(|_| rng.random::<f64>() < 0.2).collect();
    let moved: Vec<[f64; 3]> = points
        .iter()
        .enumerate()
        .map(|(v, p)| if changed[v / 3] { [p[0] + 0.3, p[1] - 0.1 * p[2], p[2]] } else { *p })
        .collect();
    let full = bvh.refitted(&moved, &triangles);
    let mut partial = bvh.clone();
    let listed: Vec<u32> = (0..triangles.len() as u32).filter(|&t| changed[t as usize]).collect();
    partial.refit_listed(&bvh.refit_links(), &moved, &triangles, &listed);
    let boxes = |b: &TriangleBvh| b.nodes.iter().map(|n| (n.bounds.lo, n.bounds.hi)).chain(b.boxes.iter().map(|x| (x.lo, x.hi))).collect::<Vec<_>>();
    assert_eq!(boxes(&partial), boxes(&full));
    assert!(partial.triangles.iter().zip(&full.triangles).all(|(a, b)| (a.a, a.ab, a.ac) == (b.a, b.ab, b.ac)));
    // The subset: a third of the triangles, mostly in one corner of the cube.
    let accept = |t: u32| t.is_multiple_of(3) && moved[3 * t as usize][0] < 0.6;
    let marked: Vec<bool> = (0..triangles.len() as u32).map(accept).collect();
    let holding = full.nodes_holding(&marked);
    assert!(holding.iter().any(|&h| !h), "some subtree should hold none of the subset");
    for _ in 0..500 {
        let q: [f64; 3] = std::array::from_fn(|_| rng.random_range(-0.5..1.5));
        let (a, b) = (full.closest_point_where(&q, f64::INFINITY, accept), full.closest_point_among(&q, f64::INFINITY, &holding, accept));
        let key = |p: Option<SurfacePoint>| p.map(|p| (p.triangle, p.point, p.barycentric, p.distance_squared));
        assert!(a.is_some_and(|p| accept(p.triangle)));
        assert_eq!(key(a), key(b));
    }
}

#[test]
fn subset_answers_like_a_tree_built_on_the_kept_triangles() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
    let points: Vec<[f64; 3]> = (0..1200).map(|_| std::array::from_fn(|_| rng.random::<f64>())).collect();
    let triangles: Vec<[u32; 3]> = (0..400).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    let bvh = TriangleBvh::build(&points, &triangles);
    let moved = |t: u32| triangles[t as usize].map(|v| points[v as usize].map(|x| x + 0.05 * (x * 7.0).sin()));
    let (empty, nothing, _) = bvh.subset(|_| false, moved);
    assert!(nothing.is_empty() && empty.subset(|_| true, moved).1.is_empty());
    for share in [0.0, 0.02, 0.3, 1.0] {
        let keep = |t: u32| ((t as f64 * 0.37).fract()) < share;
        let (subset, list, corners) = bvh.subset(keep, moved);
        assert!(list.iter().zip(&corners).all(|(&t, c)| *c == moved(t)));
        let mut sorted = list.clone();
        sorted.sort_unstable();
        assert_eq!(sorted, (0..triangles.len() as u32).filter(|&t| keep(t)).collect::<Vec<_>>());
        let boxes: Vec<Aabb> = list.iter().map(|&t| Aabb::of_points(&moved(t))).collect();
        for t in 0..triangles.len() as u32 {
            let query = Aabb::of_points(&moved(t));
            let mut found = Vec::new();
            subset.for_each_overlap(&query, |p| found.push(p));
            found.sort_unstable();
            let expect: Vec<u32> = (0..list.len() as u32).filter(|&p| boxes[p as usize].overlaps(&query)).collect();
            assert_eq!(found, expect, "share {share}, query {t}");
            let (origin, direction) = (moved(t)[0], [0.3, -0.2, 1.0]);
            let hit = list.iter().any(|&u| {
                let [a, b, c] = moved(u);
                ray_meets(&PreparedTriangle { a, ab: sub(&b, &a), ac: sub(&c, &a) }, &origin, &direction, 2.0)
            });
            assert_eq!(subset.any_hit(&origin, &direction, 2.0), hit, "share {share}, ray {t}");
        }
    }
}

/// [`TriangleBvh::overlapping_pairs`]' pairs, each as (smaller, larger), sorted.
fn sorted_pairs(bvh: &TriangleBvh, marked: &[bool]) -> Vec<(u32, u32)> {
    let mut found: Vec<(u32, u32)> = bvh
        .overlapping_pairs(marked, Vec::new, |f: &mut Vec<(u32, u32)>, a, b| f.push((a.min(b), a.max(b))))
        .into_iter()
        .flatten()
        .collect();
    found.sort_unstable();
    found
}

/// The pair descent reports every pair of overlapping boxes with a marked triangle exactly
/// once, on a built tree and on a restricted one (whose leaf order differs), for marks from
/// none to all: the small subtrees it tests pair by pair included.
#[test]
fn overlapping_pairs_match_brute_force_once_each() {
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(19);
    let points: Vec<[f64; 3]> = (0..1500)
        .map(|i| {
            let centre = ((i / 3) as f64 * 0.618).fract();
            std::array::from_fn(|a| centre * (a + 1) as f64 % 1.0 + 0.12 * rng.random::<f64>())
        })
        .collect();
    let triangles: Vec<[u32; 3]> = (0..500).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    let boxes: Vec<Aabb> = triangles.iter().map(|t| Aabb::of_points(&t.map(|v| points[v as usize]))).collect();
    let bvh = TriangleBvh::build(&points, &triangles);
    let kept: Vec<bool> = (0..triangles.len()).map(|t| t % 4 != 1).collect();
    let restricted = bvh.restricted(&kept);
    let mut seen = 0;
    for share in [0.0, 0.05, 0.5, 1.0] {
        let marked: Vec<bool> = (0..triangles.len()).map(|_| rng.random::<f64>() < share).collect();
        for (tree, keep) in [(&bvh, vec![true; triangles.len()]), (&restricted, kept.clone())] {
            let found = sorted_pairs(tree, &marked);
            let mut expect = Vec::new();
            for a in 0..triangles.len() {
                for b in a + 1..triangles.len() {
                    if keep[a] && keep[b] && (marked[a] || marked[b]) && boxes[a].overlaps(&boxes[b]) {
                        expect.push((a as u32, b as u32));
                    }
                }
            }
            seen += expect.len();
            assert_eq!(found, expect, "share {share}");
        }
    }
    assert!(seen > 1000, "the boxes should overlap often: {seen} pairs");
}

#[test]
fn axis_parallel_ray_and_segment_end() {
    let points = vec![[0.0, -1.0, -1.0], [0.0, 1.0, -1.0], [0.0, 0.0, 1.0]];
    let bvh = TriangleBvh::build(&points, &[[0, 1, 2]]);
    assert!(bvh.any_hit(&[-1.0, 0.0, 0.0], &[1.0, 0.0, 0.0], 2.0));
    assert!(!bvh.any_hit(&[-1.0, 0.0, 0.0], &[1.0, 0.0, 0.0], 0.9), "the wall is beyond the segment");
    assert!(!bvh.any_hit(&[-1.0, 0.0, 0.0], &[-1.0, 0.0, 0.0], 5.0), "the wall is behind the ray");
    assert!(!TriangleBvh::build(&points, &[]).any_hit(&[-1.0, 0.0, 0.0], &[1.0, 0.0, 0.0], 2.0));
}

/// A leaf of over 64 triangles (all at one spot: no split separates their centroids), whose
/// pairs [`TriangleBvh::overlapping_pairs`] tests in chunks of 64, gives every pair once.
#[test]
fn overlapping_pairs_cover_a_leaf_of_many_triangles() {
    let points: Vec<[f64; 3]> = (0..300).map(|i| [(i % 3) as f64, ((i % 3) / 2) as f64, 0.0]).collect();
    let triangles: Vec<[u32; 3]> = (0..100).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
    let bvh = TriangleBvh::build(&points, &triangles);
    for every_third in [false, true] {
        let marked: Vec<bool> = (0..triangles.len()).map(|t| !every_third || t % 3 == 0).collect();
        let found = sorted_pairs(&bvh, &marked);
        let expect: Vec<(u32, u32)> =
            (0..100u32).flat_map(|a| (a + 1..100).map(move |b| (a, b))).filter(|&(a, b)| marked[a as usize] || marked[b as usize]).collect();
        assert_eq!(found, expect, "every third marked: {every_third}");
    }
}
