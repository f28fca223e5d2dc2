//! Expression packing: the fewest reference expressions to scan, each a set of shapes whose
//! strongly moving regions do not overlap, important shapes first, symmetric shapes together.
//!
//! Carrigan, Zell, Guiard & McDonnell, "Expression Packing: As-Few-As-Possible Training
//! Expressions for Blendshape Transfer", Eurographics 2020 (`carrigan2020packing`);
//! Method, section 1.
//!
//! | Paper | Here |
//! |---|---|
//! | $b_k$, $\mu$ (Eq. (2)) | `Prepared::active` ([`RigView::active_vertices`]), [`PackingParams::mu`] |
//! | $\lambda_k(a, \beta)$ (Eq. (4)) | [`Packing::importance`], [`Expression::importance`] |
//! | $\lambda_{Dis}$ (Eq. (5)) | [`importance::displacement_strength`] |
//! | $s_t$, $\lambda_{TD}$ (Eqs. (6), (7)) | [`importance::triangle_scores`], [`importance::triangle_distortion`] |
//! | $\lambda_U$ (Eq. (8)) | [`importance::uniqueness`] |
//! | Eq. (3), one $x_j$ | [`programs::heaviest_independent_set`] on [`conflicts::ConflictGraph`] |
//! | $(w_x, w_p)$ (Eq. (3d)) | [`Packing::pairs`] (merged into one node) |
//! | $J_{max}$, Algorithm 1 | [`PackingParams::max_expressions`], [`pack_expressions`] |
//! | $w^j_k$ | [`Packing::weights`] |
//!
//! # Deviations
//! - Eq. (6) gets `- 2` so an undistorted triangle scores 0 (the method), and every importance
//!   gets a floor of 0.01 so that no shape has zero weight.
//! - Eq. (3b)'s N vertex rows become one row per clique of an edge clique cover of the
//!   conflict graph (same 0/1 solutions, N drops out); nodes without a remaining conflict are
//!   taken without a solve.
//! - Antagonists (mirror pairs moving the same region, and shapes whose deltas have a cosine
//!   below [`PackingParams::antagonist_cosine`]) conflict, and a pair of antagonists is no
//!   symmetric pair (the method). Mirror antagonists are searched even when `symmetric` is off.
//! - Ties in Eq. (3a) (equal sums, common since mirror shapes have equal importance) are
//!   broken by a second solve towards the nodes with the most remaining conflicts, so that
//!   hard-to-place shapes go early and J shrinks; the optimum itself is unchanged.
//! - Algorithm 1's loop test "K non-empty or J < Jmax" is read as "and" (the method).
//! - Refinements (the paper's section 4.5.3) are constraints: pins merge nodes, `keep_apart`
//!   adds an edge (and dissolves a symmetric pair it names), `exclude` removes shapes.
//! - The Dis and TD maxima (Eqs. (5), (7)) run over every moving shape, excluded ones
//!   included, so excluding a shape does not change the others' importance.
//! - Beyond the paper, for its goal 4 (poseable expressions): shapes that pass through each
//!   other when posed together ([`collisions`]) or of which one hides the other's motion
//!   from the camera ([`occlusion`]) conflict; every conflict edge carries its reasons
//!   ([`conflicts::ConflictReason`]).
//! - Beyond the paper: [`PackingParams::fewest`] proves the fewest expressions for the same
//!   conflicts (a graph colouring), and [`pack_greedy`] is the first-fit baseline.
//! - Not met: the method's 50 ms for a cold pack of a 26k-vertex head with both poseability tests
//!   (0.52 s; a re-pack reusing the stored results 0.15 s). Every part of the tests grows with
//!   the triangles the shapes move, so it asks for a tenth of the work (docs/design_pack.md).

pub mod collisions;
pub mod conflicts;
pub mod importance;
pub mod occlusion;
pub mod programs;
mod regions;
mod setup;

#[cfg(test)]
mod poseable_tests;
#[cfg(test)]
mod tests;

use serde::Serialize;

use crate::error::ShapesmithResult;
use collisions::Collision;
use conflicts::ShapeConflict;
use occlusion::Occlusion;
use crate::ilp::{IlpOptions, SolveStatus};
use crate::progress::{Progress, Stage};
use crate::rig::RigView;
use programs::{fewest_colours, first_fit, heaviest_independent_set};
use setup::{prepare, Prepared};

/// Pack Expressions' settings ([`crate::settings`]); the refinements and the stored results
/// are the rig's data (shape indices), `#[serde(skip)]`: the caller sets them.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct PackingParams {
    /// Binary blendshape threshold relative to each shape's largest displacement (Eq. (2)).
    pub mu: f64,
    /// Weight of displacement strength against triangle distortion (Eq. (4)).
    pub a: f64,
    /// Weight of uniqueness (Eq. (8)); 0 leaves it out.
    pub beta: f64,
    /// $J_{max}$; `None` packs until every shape is placed.
    pub max_expressions: Option<usize>,
    /// Pose geometric (and name-matched) mirror partners together (Eq. (3d)).
    pub symmetric: bool,
    /// Lateral axis of the symmetry plane (0 = local X).
    pub axis: usize,
    /// Mirror-map tolerance relative to the bounding-box diagonal.
    pub mirror_tolerance: f64,
    /// Mirror test threshold for symmetric pairs (method, section 0).
    pub pair_tolerance: f64,
    /// IoU of binary blendshapes above which a mirror pair is an antagonist pair.
    pub antagonist_iou: f64,
    /// Two shapes whose flattened deltas have a cosine below this are antagonists.
    pub antagonist_cosine: f64,
    /// The user's symmetric pairs; when given they replace the geometric ones (even with
    /// `symmetric` off).
    #[serde(skip)]
    pub pairs: Option<Vec<(usize, usize)>>,
    /// Shapes that must share an expression.
    #[serde(skip)]
    pub pin_together: Vec<(usize, usize)>,
    /// Shapes that must not share an expression.
    #[serde(skip)]
    pub keep_apart: Vec<(usize, usize)>,
    /// Shapes never placed.
    #[serde(skip)]
    pub exclude: Vec<usize>,
    /// Also prove the fewest expressions possible for the same conflicts.
    pub fewest: bool,
    /// Seconds per solve; `None` solves to proven optimality.
    pub time_limit: Option<f64>,
    /// Shapes that pass through each other when posed together conflict ([`collisions`]).
    pub collision_conflicts: bool,
    /// Intersection curve between pieces a mix may add beyond its shapes alone, as a
    /// fraction of the bounding-box diagonal, before the two conflict.
    pub collision_tolerance: f64,
    /// A shape whose motion the other hides from the camera conflicts ([`occlusion`]).
    pub occlusion_conflicts: bool,
    /// Share of its visible active vertices a shape must keep when posed with another.
    pub occlusion_keep: f64,
    /// From the face towards the camera, in the mesh's coordinates (the reference sheet's
    /// front camera: -Y for a face looking down -Y).
    pub camera_direction: [f64; 3],
    /// Collision and occlusion results of an earlier packing of the same rig with the same
    /// `mu`, tolerance, keep share and camera ([`PoseabilityReport::known`]): the pairs they
    /// decided are not tested again. The caller keeps them (the add-on on the object, keyed
    /// by a hash of the rig and those settings); the other options do not change them.
    #[serde(skip)]
    pub known: Option<KnownPoseability>,
}

/// Box margin, as a fraction of the diagonal, under which two moving regions count as able
/// to interact. Any margin >= 0 gives the same conflicts (the pruning is exact, see
/// `regions`); this one absorbs rounding.
pub const INTERACTION_MARGIN: f64 = 1e-3;

/// The share of [`pack_expressions`]' progress given to its preparation: with the collision
/// and occlusion tests on, they take most of a packing's time (the programs a few ms).
const PREPARE_SHARE: f64 = 0.8;

impl Default for PackingParams {
    fn default() -> Self {
        Self {
            mu: 0.3,
            a: 0.5,
            beta: 0.0,
            max_expressions: None,
            symmetric: true,
            axis: 0,
            mirror_tolerance: 1e-3,
            pair_tolerance: 0.25,
            antagonist_iou: 0.6,
            antagonist_cosine: -0.5,
            pairs: None,
            pin_together: Vec::new(),
            keep_apart: Vec::new(),
            exclude: Vec::new(),
            fewest: false,
            time_limit: None,
            collision_conflicts: true,
            collision_tolerance: DEFAULT_COLLISION_TOLERANCE,
            occlusion_conflicts: true,
            occlusion_keep: 0.5,
            camera_direction: [0.0, -1.0, 0.0],
            known: None,
        }
    }
}

/// Default [`PackingParams::collision_tolerance`]: calibrated on the bundled Template (see
/// docs/design_pack.md, "Poseable and observable expressions").
pub const DEFAULT_COLLISION_TOLERANCE: f64 = 0.11;

/// What the poseability tests found, and what they cost.
#[derive(Clone, Debug, Default, Serialize)]
pub struct PoseabilityReport {
    /// Pairs whose mix adds more than the tolerance of intersection curve between pieces.
    pub collisions: Vec<Collision>,
    /// Directions (hidden, by) where the first keeps less than `occlusion_keep` of its
    /// visibility.
    pub occlusions: Vec<Occlusion>,
    /// Pairs whose moving regions can touch, out of those nothing else keeps apart.
    pub collision_pairs_tested: usize,
    pub occlusion_directions_tested: usize,
    pub seconds_regions: f64,
    pub seconds_collisions: f64,
    pub seconds_occlusions: f64,
    /// Candidate pairs whose tests were taken from [`PackingParams::known`] instead of run.
    pub pairs_reused: usize,
    /// Everything decided so far, given and new: what a later packing of the same rig
    /// passes back as [`PackingParams::known`].
    pub known: KnownPoseability,
}

/// The poseability tests decide each pair of shapes on its own: whether two shapes collide
/// depends on the rig and the tolerance, whether one hides the other on the rig, `mu`, the
/// keep share and the camera, never on which other pairs are tested. So the pairs decided
/// once are kept, and a later packing tests only the candidates not among them (another
/// exclusion, antagonist cosine or refinement changes the candidates, not the answers).
#[derive(Clone, Debug, Default, Serialize)]
pub struct KnownPoseability {
    /// Pairs `(i, j)`, i < j, whose collision test ran (found colliding or not).
    pub collision_tested: Vec<(usize, usize)>,
    pub collisions: Vec<Collision>,
    /// Pairs `(i, j)`, i < j, whose occlusion test ran, in both directions.
    pub occlusion_tested: Vec<(usize, usize)>,
    pub occlusions: Vec<Occlusion>,
}

/// One reference expression $x_j$: the shapes posed at full weight together.
#[derive(Clone, Debug, Serialize)]
pub struct Expression {
    /// Shape indices, ascending.
    pub shapes: Vec<usize>,
    /// Sum of the members' importance in the iteration that chose them (Eq. (3a)).
    pub importance: f64,
    /// Vertices moved strongly: the size of the union of the members' active sets.
    pub vertices: usize,
    /// How the solve ended; `None` for the greedy packer, which solves nothing.
    pub status: Option<SolveStatus>,
    /// Proven to be the most important expression possible from the remaining shapes.
    pub optimal: bool,
}

#[derive(Clone, Debug, Serialize)]
pub struct FewestReport {
    /// The fewest expressions that place every shape (a colouring of the conflict graph).
    pub count: usize,
    /// `false` when the time limit stopped the solve: `count` is then only an upper bound.
    pub optimal: bool,
}

#[derive(Clone, Debug, Serialize)]
pub struct Packing {
    /// In solve order, which is the order of importance (Algorithm 1).
    pub expressions: Vec<Expression>,
    /// Per shape, the importance of the first iteration (Eq. (4) with U = 0); 0 when inert.
    pub importance: Vec<f64>,
    /// Shapes that do not move: never placed.
    pub inert: Vec<usize>,
    /// Shapes the user excluded (inert ones are listed under `inert` only).
    pub excluded: Vec<usize>,
    /// Shapes left over when `max_expressions` stopped the loop.
    pub unplaced: Vec<usize>,
    /// Symmetric pairs posed together.
    pub pairs: Vec<(usize, usize)>,
    /// Antagonists kept apart (mirror and cosine), `(i, j)` with i < j.
    pub antagonists: Vec<(usize, usize)>,
    /// Every conflict edge between shapes posed apart, with its reasons.
    pub conflicts: Vec<ShapeConflict>,
    /// Binary blendshapes $b_k$ (Eq. (2)) as sorted vertex lists (empty when inert): what
    /// the reference sheet tints.
    pub active: Vec<Vec<u32>>,
    pub poseability: PoseabilityReport,
    pub fewest: Option<FewestReport>,
}

impl Packing {
    /// The J x K 0/1 weights $w^j_k$: row j poses expression j.
    pub fn weights(&self) -> Vec<Vec<u8>> {
        self.expressions
            .iter()
            .map(|e| {
                let mut row = vec![0u8; self.importance.len()];
                for &k in &e.shapes {
                    row[k] = 1;
                }
                row
            })
            .collect()
    }
}

/// Algorithm 1: solves Eq. (3) for one expression at a time on the shapes not yet placed,
/// recomputing uniqueness (Eq. (8)) each time when `beta > 0`, until every moving,
/// non-excluded shape is placed or `max_expressions` expressions exist.
///
/// Errors: `InvalidInput` for an unusable rig, target or parameter (naming it),
/// `Infeasible` for pins between conflicting shapes, `Solver`, `Cancelled`.
pub fn pack_expressions(
    rig: &RigView,
    target_neutral: Option<&[[f32; 3]]>,
    params: &PackingParams,
    progress: &dyn Progress,
) -> ShapesmithResult<Packing> {
    progress.checkpoint(0.0)?;
    let prep = prepare(rig, target_neutral, params, &Stage { whole: progress, start: 0.0, span: PREPARE_SHARE })?;
    let progress = &Stage { whole: progress, start: PREPARE_SHARE, span: 1.0 - PREPARE_SHARE };
    let graph = &prep.graph;
    let options = IlpOptions { time_limit: params.time_limit, skip_feasibility_jump: true };
    let mut remaining = vec![true; graph.n_nodes()];
    let mut placed_shapes: Vec<usize> = Vec::new();
    let total: usize = graph.nodes.iter().map(Vec::len).sum();
    let mut expressions = Vec::new();
    while remaining.contains(&true) && params.max_expressions.is_none_or(|max| expressions.len() < max) {
        progress.checkpoint(placed_shapes.len() as f64 / total.max(1) as f64)?;
        let lambda = iteration_importance(&prep, &remaining, &placed_shapes, params.beta);
        let weight: Vec<f64> = graph.nodes.iter().map(|m| m.iter().map(|&k| lambda[k]).sum()).collect();
        let (chosen, status) = heaviest_independent_set(graph, &remaining, &weight, &options)?;
        for &v in &chosen {
            remaining[v] = false;
        }
        let shapes = sorted_members(graph, &chosen);
        placed_shapes.extend(&shapes);
        expressions.push(expression(&prep, shapes, &lambda, Some(status)));
    }
    let unplaced = sorted_members(graph, &(0..graph.n_nodes()).filter(|&v| remaining[v]).collect::<Vec<_>>());
    let fewest = if params.fewest {
        progress.checkpoint(0.95)?;
        // Any valid colouring bounds the program; the loop's is one when it placed everything.
        let greedy = first_fit(graph, &by_importance(&prep)).len();
        let bound = if unplaced.is_empty() { greedy.min(expressions.len()) } else { greedy };
        let (count, status) = fewest_colours(graph, bound, &options)?;
        Some(FewestReport { count, optimal: status.is_optimal() })
    } else {
        None
    };
    progress.checkpoint(1.0)?;
    Ok(finish(prep, expressions, unplaced, fewest))
}

/// The greedy baseline on the same conflict graph: nodes in order of first-iteration
/// importance, each into the first expression holding none of its conflicts
/// (`max_expressions` keeps the first groups; the rest are unplaced). Nothing is proven.
pub fn pack_greedy(
    rig: &RigView,
    target_neutral: Option<&[[f32; 3]]>,
    params: &PackingParams,
    progress: &dyn Progress,
) -> ShapesmithResult<Packing> {
    progress.checkpoint(0.0)?;
    let prep = prepare(rig, target_neutral, params, progress)?;
    let mut groups = first_fit(&prep.graph, &by_importance(&prep));
    let rest = groups.split_off(params.max_expressions.unwrap_or(usize::MAX).min(groups.len()));
    let unplaced = sorted_members(&prep.graph, &rest.concat());
    let expressions = groups
        .iter()
        .map(|g| expression(&prep, sorted_members(&prep.graph, g), &prep.base_importance, None))
        .collect();
    progress.checkpoint(1.0)?;
    Ok(finish(prep, expressions, unplaced, None))
}

/// Eq. (4) for this iteration: the fixed part plus `beta * U_k` over the remaining shapes.
fn iteration_importance(prep: &Prepared, remaining: &[bool], placed: &[usize], beta: f64) -> Vec<f64> {
    let mut lambda = prep.base_importance.clone();
    if let Some(cosines) = &prep.cosines {
        let candidates = sorted_members(&prep.graph, &(0..remaining.len()).filter(|&v| remaining[v]).collect::<Vec<_>>());
        for (l, u) in lambda.iter_mut().zip(importance::uniqueness(cosines, &candidates, placed)) {
            *l += beta * u;
        }
    }
    lambda
}

/// Nodes by decreasing first-iteration weight (ties by index).
fn by_importance(prep: &Prepared) -> Vec<usize> {
    let weight: Vec<f64> = prep.graph.nodes.iter().map(|m| m.iter().map(|&k| prep.base_importance[k]).sum()).collect();
    let mut order: Vec<usize> = (0..prep.graph.n_nodes()).collect();
    order.sort_by(|&u, &v| weight[v].total_cmp(&weight[u]).then(u.cmp(&v)));
    order
}

fn sorted_members(graph: &conflicts::ConflictGraph, nodes: &[usize]) -> Vec<usize> {
    let mut shapes: Vec<usize> = nodes.iter().flat_map(|&v| graph.nodes[v].iter().copied()).collect();
    shapes.sort_unstable();
    shapes
}

fn expression(prep: &Prepared, shapes: Vec<usize>, lambda: &[f64], status: Option<SolveStatus>) -> Expression {
    let mut moved: Vec<u32> = shapes.iter().flat_map(|&k| prep.active[k].iter().copied()).collect();
    moved.sort_unstable();
    moved.dedup();
    Expression {
        importance: shapes.iter().map(|&k| lambda[k]).sum(),
        vertices: moved.len(),
        optimal: status.is_some_and(SolveStatus::is_optimal),
        status,
        shapes,
    }
}

fn finish(prep: Prepared, expressions: Vec<Expression>, unplaced: Vec<usize>, fewest: Option<FewestReport>) -> Packing {
    // The sheet tints the user's vertices: every copy of a welded point.
    let active = prep.active.iter().map(|a| prep.weld.expand(a)).collect();
    Packing {
        expressions,
        importance: prep.base_importance,
        inert: prep.inert,
        excluded: prep.excluded,
        unplaced,
        pairs: prep.graph.pairs,
        antagonists: prep.antagonists,
        conflicts: prep.graph.conflicts,
        active,
        poseability: prep.poseability,
        fewest,
    }
}
