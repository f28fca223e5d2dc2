//! The weighted set cover of Eq. (5), its exact reductions, and the adaptive multi-cover of
//! Algorithm 1 (Sec. 3.3.2).

use std::collections::BTreeMap;
use std::time::Instant;

use crate::error::ShapesmithResult;
use crate::geometry::neighbours::PointTree;
use crate::ilp::{solve_binary, BinaryProgram, IlpOptions, Sense, SolveStatus};
use crate::progress::Progress;

/// One candidate vertex as a column of Eq. (5): the shapes it covers (ascending), its cost
/// `cost[n]`, and a tie-break among equally cheap columns with the same shapes.
#[derive(Clone, Debug, PartialEq)]
pub struct Column {
    pub vertex: u32,
    pub shapes: Vec<usize>,
    pub cost: f64,
    /// Larger is better: the summed relative displacement, i.e. the larger landmark rows of
    /// `D` and so the better-conditioned reconstruction.
    pub preference: f64,
}

/// Exact reductions before the solve: a column covering nothing can only add cost; of the
/// columns covering the same set of shapes an optimum needs only the cheapest (then the most
/// preferred, then the lowest vertex, so the result is deterministic). Sorted by vertex.
pub fn reduce(columns: &[Column]) -> Vec<Column> {
    let mut best: BTreeMap<&[usize], &Column> = BTreeMap::new();
    for column in columns.iter().filter(|c| !c.shapes.is_empty()) {
        let better = |held: &&Column| {
            column.cost.total_cmp(&held.cost).then(held.preference.total_cmp(&column.preference)).then(column.vertex.cmp(&held.vertex))
                == std::cmp::Ordering::Less
        };
        match best.get(column.shapes.as_slice()) {
            Some(held) if !better(held) => {}
            _ => {
                best.insert(&column.shapes, column);
            }
        }
    }
    let mut kept: Vec<Column> = best.into_values().cloned().collect();
    kept.sort_by_key(|c| c.vertex);
    kept
}

/// A solved cover: the chosen vertices (ascending) and how sure HiGHS is of the optimum.
#[derive(Clone, Debug)]
pub struct Cover {
    pub vertices: Vec<u32>,
    pub status: SolveStatus,
}

/// Costs go to HiGHS in units of 1/1000 landmark, rounded: an integral objective lets HiGHS
/// close the gap exactly, where float noise in a fractional one reads as "not proven optimal".
/// Quality differences below 0.001 become ties.
pub const COST_UNITS: f64 = 1000.0;

/// Eq. (5): minimise `sum_n cost[n] f_n` s.t. every shape named by some column is covered
/// at least once, `f` binary; on the reduced columns, costs in [`COST_UNITS`].
pub fn solve_cover(columns: &[Column], options: &IlpOptions) -> ShapesmithResult<Cover> {
    let reduced = reduce(columns);
    let mut covering: BTreeMap<usize, Vec<(usize, f64)>> = BTreeMap::new();
    for (j, column) in reduced.iter().enumerate() {
        for &k in &column.shapes {
            covering.entry(k).or_default().push((j, 1.0));
        }
    }
    let mut program = BinaryProgram::new(Sense::Minimise, reduced.iter().map(|c| (c.cost * COST_UNITS).round()).collect());
    for terms in covering.into_values() {
        program.at_least(terms, 1.0);
    }
    let solution = solve_binary(&program, options)?;
    let vertices = reduced.iter().zip(&solution.x).filter(|p| *p.1).map(|p| p.0.vertex).collect();
    Ok(Cover { vertices, status: solution.status })
}

/// `cost[n] = 1 + gamma * q[n]`, with `q[n]` the mean over the covered shapes of
/// `(1 - alpha)(1 - r_k[n]) + alpha (1 - l[n])` (the method's reading of Eq. 1 and 5a: the count
/// stays dominant, quality breaks ties).
pub fn vertex_cost(covered: &[(usize, f64)], visibility: f64, alpha: f64, gamma: f64) -> f64 {
    if covered.is_empty() {
        return 1.0;
    }
    let q: f64 = covered.iter().map(|&(_, r)| (1.0 - alpha) * (1.0 - r) + alpha * (1.0 - visibility)).sum::<f64>()
        / covered.len() as f64;
    1.0 + gamma * q
}

#[derive(Clone, Debug)]
pub struct MultiCoverSettings {
    pub alpha: f64,
    pub gamma: f64,
    pub max_per_shape: usize,
    /// Exclusion radius around every landmark for later rounds, in mesh units.
    pub radius: f64,
    /// A landmark serving more than this fraction of all shapes is shared too widely to be a
    /// shape's only one (the paper's 10% rule).
    pub share_limit: f64,
    pub ilp: IlpOptions,
}

/// What the rounds chose. `landmarks` holds `(vertex, round)` including mirrored partners.
#[derive(Clone, Debug)]
pub struct MultiCover {
    pub landmarks: Vec<(u32, usize)>,
    pub statuses: Vec<SolveStatus>,
    pub seconds_solve: f64,
}

/// Algorithm 1, adaptive multi-cover. Round 1 is the single cover of Eq. (5). Every later
/// round removes the chosen vertices and all vertices within `radius` of a landmark from the
/// candidates, keeps only the shapes that still have candidates and whose landmarks each serve
/// more than `share_limit` of the `n_shapes` shapes (and have fewer than `max_per_shape`),
/// and solves Eq. (5) again for them. Stops after `max_per_shape` rounds or when no shape
/// asks for more.
///
/// `relation[n]` lists the shapes vertex n is a candidate for, with `r_k[n]`; `visibility`
/// is `l[n]` (only read where `relation[n]` is not empty); `positions` are the neutral's,
/// for the radius; with `partners`, every chosen vertex brings its mirror partner into the
/// layout (symmetric layouts, Sec. 3.3.1).
#[allow(clippy::too_many_arguments)]
pub fn adaptive_multi_cover(
    relation: &[Vec<(usize, f64)>],
    visibility: &[f64],
    n_shapes: usize,
    partners: Option<&[Option<u32>]>,
    positions: &[[f32; 3]],
    settings: &MultiCoverSettings,
    progress: &dyn Progress,
) -> ShapesmithResult<MultiCover> {
    let n_vertices = relation.len();
    let tree = PointTree::new(positions);
    let mut excluded = vec![false; n_vertices];
    let mut landmarks_of: BTreeMap<usize, Vec<u32>> = BTreeMap::new();
    let mut out = MultiCover { landmarks: Vec::new(), statuses: Vec::new(), seconds_solve: 0.0 };
    let widely_shared = |v: u32| relation[v as usize].len() as f64 > settings.share_limit * n_shapes as f64;
    for round in 0..settings.max_per_shape {
        progress.checkpoint(round as f64 / settings.max_per_shape as f64)?;
        let asks = |k: usize| match landmarks_of.get(&k) {
            None => true,
            Some(held) => held.len() < settings.max_per_shape && held.iter().all(|&v| widely_shared(v)),
        };
        let columns: Vec<Column> = (0..n_vertices)
            .filter(|&n| !excluded[n])
            .map(|n| {
                let covered: Vec<(usize, f64)> = relation[n].iter().copied().filter(|&(k, _)| asks(k)).collect();
                Column {
                    vertex: n as u32,
                    shapes: covered.iter().map(|c| c.0).collect(),
                    cost: vertex_cost(&covered, visibility[n], settings.alpha, settings.gamma),
                    preference: covered.iter().map(|c| c.1).sum(),
                }
            })
            .collect();
        if columns.iter().all(|c| c.shapes.is_empty()) {
            break;
        }
        let started = Instant::now();
        let cover = solve_cover(&columns, &settings.ilp)?;
        out.seconds_solve += started.elapsed().as_secs_f64();
        out.statuses.push(cover.status);
        for &v in &cover.vertices {
            for &(k, _) in &relation[v as usize] {
                landmarks_of.entry(k).or_default().push(v);
            }
            let partner = partners.and_then(|p| p[v as usize]);
            for u in std::iter::once(v).chain(partner) {
                out.landmarks.push((u, round));
                excluded[u as usize] = true;
                let centre = positions[u as usize].map(f64::from);
                for (near, _) in tree.within(centre, settings.radius) {
                    excluded[near] = true;
                }
            }
        }
    }
    progress.checkpoint(1.0)?;
    out.landmarks.sort();
    out.landmarks.dedup_by_key(|l| l.0);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::progress::NoProgress;
    use rand::{Rng, SeedableRng};

    /// The cheapest cover by trying every subset of the unreduced columns.
    fn brute_force(columns: &[Column]) -> f64 {
        let shapes: std::collections::BTreeSet<usize> = columns.iter().flat_map(|c| c.shapes.clone()).collect();
        let mut best = f64::INFINITY;
        for mask in 0u32..(1 << columns.len()) {
            let chosen: Vec<&Column> = (0..columns.len()).filter(|j| mask >> j & 1 == 1).map(|j| &columns[j]).collect();
            let covered: std::collections::BTreeSet<usize> = chosen.iter().flat_map(|c| c.shapes.clone()).collect();
            if covered == shapes {
                best = best.min(chosen.iter().map(|c| c.cost).sum());
            }
        }
        best
    }

    #[test]
    fn reduced_cover_matches_brute_force() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for trial in 0..60 {
            let n_shapes = rng.random_range(1..6);
            let n_columns = rng.random_range(1..13);
            // Few distinct costs and small shape sets: many duplicate coverage sets and ties,
            // and some empty columns, so that the reductions have work to do.
            let columns: Vec<Column> = (0..n_columns)
                .map(|v| Column {
                    vertex: v as u32,
                    shapes: (0..n_shapes).filter(|_| rng.random_bool(0.35)).collect(),
                    cost: 1.0 + 0.25 * rng.random_range(0..3) as f64,
                    preference: rng.random(),
                })
                .collect();
            let reduced = reduce(&columns);
            assert!(reduced.iter().all(|c| !c.shapes.is_empty()));
            let distinct: std::collections::BTreeSet<&Vec<usize>> = reduced.iter().map(|c| &c.shapes).collect();
            assert_eq!(distinct.len(), reduced.len(), "trial {trial}: one column per coverage set");
            let want = brute_force(&columns);
            let cover = solve_cover(&columns, &IlpOptions::default()).unwrap();
            assert_eq!(cover.status, SolveStatus::Optimal);
            let got: f64 = cover.vertices.iter().map(|&v| columns[v as usize].cost).sum();
            if want.is_finite() {
                assert!((got - want).abs() < 1e-9, "trial {trial}: {got} vs brute force {want}");
            }
        }
    }

    #[test]
    fn reduction_keeps_the_cheapest_then_the_preferred() {
        let column = |vertex, shapes: Vec<usize>, cost, preference| Column { vertex, shapes, cost, preference };
        let columns = vec![
            column(0, vec![0, 1], 1.2, 0.0),
            column(1, vec![0, 1], 1.1, 0.0),
            column(2, vec![0, 1], 1.1, 0.5),
            column(3, vec![], 0.5, 9.0),
            column(4, vec![2], 1.0, 0.1),
        ];
        let kept: Vec<u32> = reduce(&columns).iter().map(|c| c.vertex).collect();
        assert_eq!(kept, vec![2, 4]);
    }

    #[test]
    fn cost_prefers_strong_visible_vertices_and_gamma_zero_counts() {
        let strong_visible = vertex_cost(&[(0, 1.0)], 1.0, 0.5, 0.5);
        let weak_hidden = vertex_cost(&[(0, 0.5)], 0.0, 0.5, 0.5);
        assert_eq!(strong_visible, 1.0);
        assert!((weak_hidden - (1.0 + 0.5 * (0.25 + 0.5))).abs() < 1e-12);
        assert_eq!(vertex_cost(&[(0, 0.5)], 0.0, 0.5, 0.0), 1.0);
    }

    /// A line of 40 vertices; shape k is a candidate at vertices 4k..4k+3 (shapes 0..9), and
    /// "broad" shapes 10 and 11 are candidates everywhere in the first half.
    #[test]
    fn multi_cover_rounds_follow_algorithm_1() {
        let points: Vec<[f32; 3]> = (0..40).map(|i| [i as f32, 0.0, 0.0]).collect();
        let mut relation: Vec<Vec<(usize, f64)>> = (0..40).map(|n| vec![(n / 4, 1.0 - 0.1 * (n % 4) as f64)]).collect();
        for entry in relation.iter_mut().take(20) {
            entry.extend([(10, 0.8), (11, 0.8)]);
            entry.sort_by_key(|e| e.0);
        }
        let settings = MultiCoverSettings {
            alpha: 0.5,
            gamma: 0.5,
            max_per_shape: 2,
            radius: 1.5,
            share_limit: 0.1,
            ilp: IlpOptions::default(),
        };
        let visibility = vec![1.0; 40];
        let result = adaptive_multi_cover(&relation, &visibility, 12, None, &points, &settings, &NoProgress).unwrap();
        assert_eq!(result.statuses, vec![SolveStatus::Optimal; 2]);
        let first: Vec<u32> = result.landmarks.iter().filter(|l| l.1 == 0).map(|l| l.0).collect();
        let second: Vec<u32> = result.landmarks.iter().filter(|l| l.1 == 1).map(|l| l.0).collect();
        // Round 1: one vertex per narrow shape, the strongest (4k), the broad ones ride along.
        assert_eq!(first, (0..10).map(|k| 4 * k).collect::<Vec<u32>>());
        // Landmarks in the first half serve 3 of 12 shapes (> 10%): shapes 0..4 ask again
        // (the broad shapes already hold 5); round 2 stays out of the 1.5 radius: 4k + 2.
        assert_eq!(second, (0..5).map(|k| 4 * k + 2).collect::<Vec<u32>>());

        let single = MultiCoverSettings { max_per_shape: 1, ..settings };
        let result = adaptive_multi_cover(&relation, &visibility, 12, None, &points, &single, &NoProgress).unwrap();
        assert_eq!(result.landmarks.len(), 10);
    }
}
