//! Everything computed once before the first expression (paper 000, Algorithm 1's header):
//! validation, binary blendshapes, importance, symmetric pairs, antagonists, collisions,
//! occlusions and the conflict graph.

use std::collections::{HashMap, HashSet};
use std::time::Instant;

use super::collisions::find_collisions;
use super::conflicts::{overlapping, validate_shape_pairs, ConflictGraph, ShapeRelations};
use super::occlusion::find_occlusions;
use super::regions::{moving_regions, rest_bvh, RestHierarchy};
use super::importance::{cosine_matrix, displacement_strength, triangle_distortion, triangle_scores, IMPORTANCE_FLOOR};
use super::collisions::Collision;
use super::occlusion::Occlusion;
use super::{KnownPoseability, PackingParams, PoseabilityReport, INTERACTION_MARGIN};
use crate::error::{ShapesmithError, ShapesmithResult};
use crate::geometry::mirror::{find_symmetry_given, MirrorMap, SymmetryParams};
use crate::geometry::weld::{Weld, WeldedRig};
use crate::invalid;
use crate::progress::Progress;
use rayon::prelude::*;

use crate::rig::{norm, validate_points, validate_triangles, RigView, INERT_FRACTION};

pub struct Prepared {
    /// Binary blendshapes $b_k$ (Eq. (2)), sorted vertex lists; empty for inert shapes.
    pub active: Vec<Vec<u32>>,
    /// $a\,\mathrm{Dis}_k + (1-a)\,\mathrm{TD}_k + 0.01$ (Eq. (4) without U); 0 for inert shapes.
    pub base_importance: Vec<f64>,
    /// Cosines of the flattened deltas, for Eq. (8); present only when beta > 0.
    pub cosines: Option<Vec<Vec<f64>>>,
    pub graph: ConflictGraph,
    pub inert: Vec<usize>,
    pub excluded: Vec<usize>,
    /// Mirror and cosine antagonists among moving shapes, `(i, j)` with i < j, sorted.
    pub antagonists: Vec<(usize, usize)>,
    pub poseability: PoseabilityReport,
    /// The welded surface the rig was read on (`active` holds welded points).
    pub weld: Weld,
}

/// `progress` sees the poseability tests, the only long part (regions, then collisions, then
/// occlusions, each a share of the whole in proportion to its usual cost).
///
/// Everything is read on the welded surface ([`WeldedRig`]): regions, the mirror map,
/// collisions and occlusion see a seam's copies as one point; the target neutral is read at
/// the same points.
pub fn prepare(rig: &RigView, target_neutral: Option<&[[f32; 3]]>, params: &PackingParams, progress: &dyn Progress) -> ShapesmithResult<Prepared> {
    let welded = WeldedRig::new(rig);
    let weld = &welded.weld;
    let target = match target_neutral {
        Some(target) if target.len() == rig.n_vertices() => Some(weld.gather(target)),
        Some(_) => return prepare_welded(rig, target_neutral, params, progress),
        None => None,
    };
    let prepared = prepare_welded(&welded.view(), target.as_deref(), params, progress)?;
    Ok(Prepared { weld: welded.weld, ..prepared })
}

fn prepare_welded(rig: &RigView, target_neutral: Option<&[[f32; 3]]>, params: &PackingParams, progress: &dyn Progress) -> ShapesmithResult<Prepared> {
    rig.validate()?;
    let k_count = rig.n_shapes();
    if k_count == 0 {
        return Err(invalid!("the mesh has no shape keys: add the shapes to pack"));
    }
    validate_params(params, rig)?;
    if let Some(target) = target_neutral {
        if target.len() != rig.n_vertices() {
            return Err(invalid!(
                "the target neutral has {} vertices but the rig has {}: it must share the rig's topology",
                target.len(),
                rig.n_vertices()
            ));
        }
        validate_points(target, "target neutral")?;
        validate_triangles(target, rig.triangles).map_err(|e| invalid!("target neutral: {e}"))?;
    }

    let (inert, active) = binary_blendshapes(rig, params.mu);
    let excluded: Vec<usize> = {
        let mut e: Vec<usize> = params.exclude.iter().copied().filter(|k| !inert.contains(k)).collect();
        e.sort_unstable();
        e.dedup();
        e
    };
    let placeable: Vec<bool> = (0..k_count).map(|k| !inert.contains(&k) && !excluded.contains(&k)).collect();
    for &(i, j) in &params.pin_together {
        for k in [i, j] {
            if inert.contains(&k) {
                return Err(invalid!("'{}' is pinned but it is inert (it moves no vertex): remove the pin", rig.names[k]));
            }
            if excluded.contains(&k) {
                return Err(invalid!("'{}' is both pinned and excluded: remove one of the two", rig.names[k]));
            }
        }
    }

    let dis = displacement_strength(rig, &active);
    let td = match target_neutral {
        Some(target) => {
            let scores = triangle_scores(rig.neutral, target, rig.triangles);
            triangle_distortion(&scores, rig.triangles, &active, rig.n_vertices())
        }
        None => vec![0.0; k_count],
    };
    let base_importance: Vec<f64> = (0..k_count)
        .map(|k| if inert.contains(&k) { 0.0 } else { params.a * dis[k] + (1.0 - params.a) * td[k] + IMPORTANCE_FLOOR })
        .collect();

    // Mirror antagonists are found whether or not pairs are used: they decide poseability.
    // The symmetry (mirror map, mirrored Gram product, exact mirror errors) and the cosine
    // Gram product are independent passes over N x K: one on each core.
    let (symmetry, cosines) = rayon::join(
        || {
            let map = MirrorMap::new(rig.neutral, params.axis, params.mirror_tolerance);
            let symmetry_params = SymmetryParams {
                pair_tolerance: params.pair_tolerance,
                antagonist_iou: params.antagonist_iou,
                mu: params.mu,
                use_names: true,
            };
            find_symmetry_given(rig, &map, &symmetry_params, &inert, &active)
        },
        || cosine_matrix(rig),
    );
    let mut antagonists: Vec<(usize, usize)> =
        symmetry.antagonists.iter().map(|a| (a.first.min(a.second), a.first.max(a.second))).collect();
    for i in (0..k_count).filter(|k| !inert.contains(k)) {
        for j in (i + 1..k_count).filter(|k| !inert.contains(k)) {
            if cosines[i][j] < params.antagonist_cosine {
                antagonists.push((i, j));
            }
        }
    }
    antagonists.sort_unstable();
    antagonists.dedup();

    let pairs: Vec<(usize, usize)> = match (&params.pairs, params.symmetric) {
        (Some(given), _) => given.clone(),
        (None, true) => symmetry.pairs.iter().map(|p| (p.first, p.second)).collect(),
        (None, false) => Vec::new(),
    };
    let overlap = overlapping(&active, &placeable, rig.n_vertices());
    let poseability = poseability(rig, params, &active, &placeable, &overlap, &antagonists, progress)?;
    let graph = ConflictGraph::build(&ShapeRelations {
        overlap: &overlap,
        placeable: &placeable,
        pairs: &pairs,
        antagonists: &antagonists,
        collisions: &poseability.collisions.iter().map(|c| (c.first, c.second)).collect::<Vec<_>>(),
        occlusions: &poseability.occlusions.iter().map(|o| (o.hidden, o.by)).collect::<Vec<_>>(),
        pin_together: &params.pin_together,
        keep_apart: &params.keep_apart,
        names: rig.names,
    })?;
    let cosines = (params.beta > 0.0).then_some(cosines);
    let weld = Weld::identity(rig.n_vertices(), rig.triangles);
    Ok(Prepared { active, base_importance, cosines, graph, inert, excluded, antagonists, poseability, weld })
}

/// Collision and occlusion conflicts (method, section 1, poseable and observable), tested only
/// between placeable shapes that nothing else keeps apart (no overlap, not antagonists, not
/// kept apart by the user): any other reason already forbids the pair.
fn poseability(
    rig: &RigView,
    params: &PackingParams,
    active: &[Vec<u32>],
    placeable: &[bool],
    overlap: &[Vec<bool>],
    antagonists: &[(usize, usize)],
    progress: &dyn Progress,
) -> ShapesmithResult<PoseabilityReport> {
    let listed = |list: &[(usize, usize)], i: usize, j: usize| list.contains(&(i, j)) || list.contains(&(j, i));
    let k_count = placeable.len();
    let candidates: Vec<(usize, usize)> = (0..k_count)
        .flat_map(|i| (i + 1..k_count).map(move |j| (i, j)))
        .filter(|&(i, j)| placeable[i] && placeable[j] && !overlap[i][j])
        .filter(|&(i, j)| !listed(antagonists, i, j) && !listed(&params.keep_apart, i, j))
        .collect();
    let mut report = PoseabilityReport::default();
    if candidates.is_empty() || !(params.collision_conflicts || params.occlusion_conflicts) {
        return Ok(report);
    }
    let mut known = params.known.clone().unwrap_or_default();
    validate_known(&known, k_count)?;
    let missing = |decided: &[(usize, usize)], pairs: &[(usize, usize)]| -> Vec<(usize, usize)> {
        let decided: HashSet<(usize, usize)> = decided.iter().copied().collect();
        pairs.iter().copied().filter(|p| !decided.contains(p)).collect()
    };
    let collision_missing = if params.collision_conflicts { missing(&known.collision_tested, &candidates) } else { Vec::new() };
    let started = Instant::now();
    let mut wanted = vec![false; k_count];
    collision_missing.iter().for_each(|&(i, j)| (wanted[i], wanted[j]) = (true, true));
    if params.occlusion_conflicts {
        // The occlusion candidates are not known before the collisions are: any shape that
        // might be tested.
        missing(&known.occlusion_tested, &candidates).iter().for_each(|&(i, j)| (wanted[i], wanted[j]) = (true, true));
    }
    // Both tests need the hierarchy as soon as a pair is tested: built beside the regions.
    let (regions, built) = rayon::join(|| moving_regions(rig, &wanted), || wanted.contains(&true).then(|| rest_bvh(rig)));
    let rest_hierarchy = RestHierarchy::with(rig, &regions, built);
    report.seconds_regions = started.elapsed().as_secs_f64();
    progress.checkpoint(0.05)?;
    let position: HashMap<(usize, usize), usize> = candidates.iter().enumerate().map(|(i, &p)| (p, i)).collect();
    let mut rest = candidates.clone();
    if params.collision_conflicts {
        let started = Instant::now();
        let (found, tested) = find_collisions(rig, &rest_hierarchy, &regions, &collision_missing, params.collision_tolerance, INTERACTION_MARGIN);
        known.collision_tested.extend(&collision_missing);
        known.collisions.extend(&found);
        // In the order of the candidates, as a packing that tests them all finds them.
        let mut collisions: Vec<Collision> = known.collisions.iter().copied().filter(|c| position.contains_key(&(c.first, c.second))).collect();
        collisions.sort_by_key(|c| position[&(c.first, c.second)]);
        rest.retain(|&(i, j)| !collisions.iter().any(|c| (c.first, c.second) == (i, j)));
        (report.collisions, report.collision_pairs_tested) = (collisions, tested);
        report.seconds_collisions = started.elapsed().as_secs_f64();
        progress.checkpoint(0.7)?;
    }
    let mut tested_now: HashSet<(usize, usize)> = collision_missing.iter().copied().collect();
    if params.occlusion_conflicts {
        let started = Instant::now();
        let occlusion_missing = missing(&known.occlusion_tested, &rest);
        let (found, tested) =
            find_occlusions(rig, &rest_hierarchy, &regions, active, &occlusion_missing, params.occlusion_keep, INTERACTION_MARGIN, params.camera_direction)
                .ok_or_else(|| invalid!("the camera direction must be a finite, non-zero vector, got {:?}", params.camera_direction))?;
        known.occlusion_tested.extend(&occlusion_missing);
        known.occlusions.extend(&found);
        // Directions (a, b) before (b, a), pairs in the order of the candidates.
        let order = |o: &Occlusion| {
            let pair = (o.hidden.min(o.by), o.hidden.max(o.by));
            rest.contains(&pair).then(|| (position[&pair], o.hidden > o.by))
        };
        let mut occlusions: Vec<Occlusion> = known.occlusions.iter().copied().filter(|o| order(o).is_some()).collect();
        occlusions.sort_by_key(order);
        (report.occlusions, report.occlusion_directions_tested) = (occlusions, tested);
        report.seconds_occlusions = started.elapsed().as_secs_f64();
        tested_now.extend(occlusion_missing);
    }
    report.pairs_reused = candidates.len() - tested_now.len();
    report.known = known;
    progress.checkpoint(1.0)?;
    Ok(report)
}

/// Known results must name shapes of this rig, each pair once in order, and a result only
/// for a pair marked decided: anything else did not come from a packing of this rig.
fn validate_known(known: &KnownPoseability, k_count: usize) -> ShapesmithResult<()> {
    let stale = || invalid!("the stored poseability results do not belong to this rig: pack again without them");
    let valid = |&(i, j): &(usize, usize)| i < j && j < k_count;
    let decided = |list: &[(usize, usize)], pair: (usize, usize)| list.contains(&pair);
    let ok = known.collision_tested.iter().all(valid)
        && known.occlusion_tested.iter().all(valid)
        && known.collisions.iter().all(|c| decided(&known.collision_tested, (c.first, c.second)))
        && known.occlusions.iter().all(|o| o.hidden != o.by && decided(&known.occlusion_tested, (o.hidden.min(o.by), o.hidden.max(o.by))));
    if ok {
        Ok(())
    } else {
        Err(stale())
    }
}

/// The inert shapes and the binary blendshapes $b_k$ (Eq. (2)), exactly as
/// [`RigView::inert_shapes`] and [`RigView::active_vertices`] give them, but with one norm
/// per vertex and shape (those recompute the maximum and the diagonal on every call).
pub fn binary_blendshapes(rig: &RigView, mu: f64) -> (Vec<usize>, Vec<Vec<u32>>) {
    let floor = INERT_FRACTION * rig.bbox_diagonal();
    let active: Vec<Option<Vec<u32>>> = (0..rig.n_shapes())
        .into_par_iter()
        .map(|k| {
            let norms: Vec<f64> = rig.delta(k).iter().map(norm).collect();
            let max = norms.iter().copied().fold(0.0, f64::max);
            (max > floor).then(|| (0..norms.len() as u32).filter(|&n| norms[n as usize] >= mu * max).collect())
        })
        .collect();
    let inert = (0..active.len()).filter(|&k| active[k].is_none()).collect();
    (inert, active.into_iter().map(Option::unwrap_or_default).collect())
}

fn validate_params(p: &PackingParams, rig: &RigView) -> ShapesmithResult<()> {
    let k_count = rig.n_shapes();
    let check = |ok: bool, message: String| if ok { Ok(()) } else { Err(ShapesmithError::InvalidInput(message)) };
    check(p.mu > 0.0 && p.mu <= 1.0, format!("mu must be in (0, 1] (the paper uses 0.25 to 0.4), got {}", p.mu))?;
    check((0.0..=1.0).contains(&p.a), format!("a must be in [0, 1], got {}", p.a))?;
    check(p.beta >= 0.0 && p.beta.is_finite(), format!("beta must be a finite number >= 0, got {}", p.beta))?;
    check(p.max_expressions != Some(0), "max_expressions must be at least 1 (or unset for no limit)".into())?;
    check(p.axis <= 2, format!("the symmetry axis must be 0, 1 or 2, got {}", p.axis))?;
    check(
        p.mirror_tolerance > 0.0 && p.mirror_tolerance.is_finite(),
        format!("mirror_tolerance must be a positive number, got {}", p.mirror_tolerance),
    )?;
    check(
        p.pair_tolerance > 0.0 && p.pair_tolerance.is_finite(),
        format!("pair_tolerance must be a positive number, got {}", p.pair_tolerance),
    )?;
    check((0.0..=1.0).contains(&p.antagonist_iou), format!("antagonist_iou must be in [0, 1], got {}", p.antagonist_iou))?;
    check(
        (-1.0..=1.0).contains(&p.antagonist_cosine),
        format!("antagonist_cosine must be in [-1, 1], got {}", p.antagonist_cosine),
    )?;
    check(
        p.collision_tolerance > 0.0 && p.collision_tolerance.is_finite(),
        format!("collision_tolerance must be a positive number (a fraction of the head's diagonal), got {}", p.collision_tolerance),
    )?;
    check(
        p.occlusion_keep > 0.0 && p.occlusion_keep <= 1.0,
        format!("occlusion_keep must be in (0, 1] (the share of visibility a shape must keep), got {}", p.occlusion_keep),
    )?;
    let direction = p.camera_direction;
    check(
        direction.iter().all(|x| x.is_finite()) && direction.iter().any(|&x| x != 0.0),
        format!("the camera direction must be a finite, non-zero vector, got {direction:?}"),
    )?;
    if let Some(limit) = p.time_limit {
        check(limit > 0.0 && limit.is_finite(), format!("time_limit must be a positive number of seconds, got {limit}"))?;
    }
    if let Some(pairs) = &p.pairs {
        validate_shape_pairs(pairs, k_count, rig.names, "symmetric pairs")?;
        let mut seen = vec![false; k_count];
        for k in pairs.iter().flat_map(|&(i, j)| [i, j]) {
            if std::mem::replace(&mut seen[k], true) {
                return Err(invalid!("symmetric pairs: '{}' is in two pairs; a shape has at most one partner", rig.names[k]));
            }
        }
    }
    validate_shape_pairs(&p.pin_together, k_count, rig.names, "pin_together")?;
    validate_shape_pairs(&p.keep_apart, k_count, rig.names, "keep_apart")?;
    if let Some(&k) = p.exclude.iter().find(|&&k| k >= k_count) {
        return Err(invalid!("exclude: shape index {k} is out of range (the rig has {k_count} shapes)"));
    }
    Ok(())
}
