//! The carry's collision pass made symmetric: the pass holds each shape on its own, and on a
//! character whose triangles do not mirror the two sides of a Left/Right pair (or the two
//! halves of a self-symmetric shape) cross at different places, so the pass holds them apart
//! differently. For each mirror pair of shapes the pass changed (either side), the pair is
//! replaced by the first of these whose every side meets the criterion or adds no more than
//! the pass's own result:
//! 1. each side averaged with the mirror of the other's (the holds of both sides act on both),
//!    Right as the mirror of Left, Left as the mirror of Right; a self-symmetric shape by its
//!    average with its own mirror;
//! 2. failing those, the averaged pair re-solved by the pass (holds where the average still
//!    crosses, the rest of it kept), averaged again, up to [`SYMMETRIC_ROUNDS`] times: the
//!    first average meeting the criterion. Where none does, the re-solved pair that misses its
//!    mirror least, when it meets the criterion and misses less than the pass's results.
//!
//! Otherwise the pass's results stay. Either way the collision rows describe what was kept.

use rayon::prelude::*;

use crate::error::ShapesmithResult;
use crate::geometry::mat3::{add, scale, to_f64, Vec3};
use crate::geometry::penetration::Penetration;
use crate::sparse::SymmetricMatrix;

use super::carry::{apply_points, CarriedShape, SymmetricCarry};
use super::collisions::{AddedCurve, CarryCollision, Guard};
use super::symmetry;

/// Re-solves of an averaged pair at most (step 2 of the module docs). Measured on the sample
/// and the 10k / 25k bench characters (`carry_counts`): with 3, the sample's jawLeft/jawRight
/// stays held apart (5.7% worst-vertex miss); with 4 every pair's average meets the criterion,
/// and more change nothing.
pub(super) const SYMMETRIC_ROUNDS: usize = 4;

/// One side of a replacement: the shape, its excess and whether it meets the criterion, its
/// penetration.
type Replacement = (usize, Vec<[f32; 3]>, (f64, bool, Penetration));

/// What [`symmetric_holds`] did to a pair.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum PairOutcome {
    /// A mirrored version meets the criterion: the pair mirrors itself.
    Mirrored,
    /// No mirrored version meets it: the pass's holds stay (re-solved from the pair's average
    /// when that misses less).
    HeldApart,
}

/// The pass's results in `shapes` made symmetric pair by pair (module docs); the pairs it
/// changed with what became of them. `static_vertex` per shape, `laplacian` the character's
/// screened matrix (the pass's re-solve).
pub(super) fn symmetric_holds(
    shapes: &mut [CarriedShape],
    symmetric: &SymmetricCarry,
    guard: &Guard,
    allowed: impl Fn(usize) -> AddedCurve + Sync,
    static_vertex: &[Vec<bool>],
    laplacian: &SymmetricMatrix,
) -> ShapesmithResult<Vec<((usize, usize), PairOutcome)>> {
    let applied = |k: usize| shapes[k].1.is_some_and(|(outcome, _)| outcome.applied);
    let changed: Vec<(usize, usize)> = symmetric.pairs.iter().copied().filter(|&(i, j)| applied(i) || applied(j)).collect();
    let field = |k: usize| -> Vec<Vec3> { shapes[k].0.iter().map(to_f64).collect() };
    let mirror = &symmetric.mirror;
    let mirrored = |other: &[Vec3], own: &[Vec3]| -> Vec<[f32; 3]> {
        (0..own.len()).map(|v| mirror.mirrored(other, v).unwrap_or(own[v]).map(|x| x as f32)).collect()
    };
    // Each side averaged with the mirror of the other's, as often as the carry averages before
    // the pass (`symmetry::MIRROR_AVERAGE_ROUNDS`): once leaves what mirroring twice misses.
    let averaged = |own: &[Vec3], other: &[Vec3]| -> (Vec<[f32; 3]>, Vec<[f32; 3]>) {
        let once = |own: &[Vec3], other: &[Vec3]| -> Vec<Vec3> {
            (0..own.len()).map(|v| mirror.mirrored(other, v).map_or(own[v], |image| scale(add(own[v], image), 0.5))).collect()
        };
        let (mut a, mut b) = (own.to_vec(), other.to_vec());
        for _ in 0..symmetry::MIRROR_AVERAGE_ROUNDS {
            (a, b) = (once(&a, &b), once(&b, &a));
        }
        let single = |field: Vec<Vec3>| -> Vec<[f32; 3]> { field.into_iter().map(|d| d.map(|x| x as f32)).collect() };
        (single(a), single(b))
    };
    let miss = |a: &[Vec3], b: &[Vec3]| symmetry::worst_miss(a, b, |f, v| mirror.mirrored(f, v));
    let current = |k: usize| shapes[k].1.map_or(0.0, |(outcome, _)| outcome.excess);
    // Every side of `candidate` judged; `None` when one is worse than the pass's result.
    let judged = |candidate: Vec<(usize, Vec<[f32; 3]>)>| -> Option<Vec<Replacement>> {
        candidate
            .into_iter()
            .map(|(k, deltas)| {
                let verdict = guard.judge(&deltas, &allowed(k));
                (verdict.1 || verdict.0 <= current(k)).then_some((k, deltas, verdict))
            })
            .collect()
    };
    let resolved = |k: usize, deltas: &[[f32; 3]]| -> ShapesmithResult<Vec<[f32; 3]>> {
        let solved: Vec<Vec3> = deltas.iter().map(to_f64).collect();
        let rhs = apply_points(laplacian, &solved);
        Ok(guard.resolve(&solved, &rhs, &static_vertex[k], &allowed(k), laplacian)?.0)
    };
    let replacements: Vec<(Vec<Replacement>, PairOutcome)> = changed
        .par_iter()
        .map(|&(i, j)| -> ShapesmithResult<(Vec<Replacement>, PairOutcome)> {
            let (di, dj) = (field(i), field(j));
            let (ai, aj) = averaged(&di, &dj);
            let candidates: Vec<Vec<(usize, Vec<[f32; 3]>)>> = if i == j {
                vec![vec![(i, ai)]]
            } else {
                vec![vec![(i, ai), (j, aj)], vec![(j, mirrored(&di, &dj))], vec![(i, mirrored(&dj, &di))]]
            };
            if let Some(found) = candidates.into_iter().find_map(judged) {
                return Ok((found, PairOutcome::Mirrored));
            }
            let (mut ci, mut cj) = (di.clone(), dj.clone());
            let mut closest: (f64, Vec<Replacement>) = (miss(&di, &dj), Vec::new());
            for _ in 0..SYMMETRIC_ROUNDS {
                let (ai, aj) = averaged(&ci, &cj);
                let average = if i == j { vec![(i, ai)] } else { vec![(i, ai), (j, aj)] };
                if let Some(found) = judged(average.clone()) {
                    return Ok((found, PairOutcome::Mirrored));
                }
                let sides: Vec<(usize, Vec<[f32; 3]>)> =
                    average.iter().map(|(k, a)| Ok((*k, resolved(*k, a)?))).collect::<ShapesmithResult<_>>()?;
                (ci, cj) = (sides[0].1.iter().map(to_f64).collect(), sides[sides.len() - 1].1.iter().map(to_f64).collect());
                let round_miss = miss(&ci, &cj);
                if round_miss < closest.0 {
                    if let Some(found) = judged(sides) {
                        closest = (round_miss, found);
                    }
                }
            }
            Ok((closest.1, PairOutcome::HeldApart))
        })
        .collect::<ShapesmithResult<_>>()?;
    let outcomes = changed.iter().zip(&replacements).map(|(pair, (_, outcome))| (*pair, *outcome)).collect();
    for (k, deltas, (excess, _, penetration)) in replacements.into_iter().flat_map(|(r, _)| r) {
        if let Some((outcome, _)) = shapes[k].1 {
            shapes[k] = (deltas, Some((CarryCollision { excess, applied: true, ..outcome }, penetration)));
        }
    }
    Ok(outcomes)
}
