//! Compact landmark layouts: Zell & McDonnell, "Compact Facial Landmark Layouts for
//! Performance Capture", Eurographics 2022 (`zell2022landmarks`). Method, section 2.
//!
//! The fewest vertices such that every shape has a landmark that moves strongly in it and
//! stays visible: a weighted set cover over candidate vertices, solved to proven optimality,
//! optionally symmetric and repeated as an adaptive multi-cover. [`score_layout`] judges any
//! layout by noisy reconstruction.
//!
//! | Paper | Here |
//! |---|---|
//! | `v_n^0`, `dv_n^k` | `rig.neutral`, `rig.delta(k)` |
//! | `r_n^k` (Eq. 2) | [`candidates::relative_displacement`] |
//! | `c_n^k`, `eps` (Eq. 3) | [`candidates::candidate_relation`], [`LandmarkParams::epsilon`] |
//! | `L_n^k`, `l_n` (Eq. 4) | [`visibility::worst_case_visibility`], [`Landmark::visibility`] |
//! | `w_n^k`, `alpha` (Eq. 1) | [`cover::vertex_cost`], [`LandmarkParams::alpha`], [`LandmarkParams::gamma`] |
//! | `f_n` (Eq. 5) | [`cover::solve_cover`] |
//! | `F`, `max` (Algorithm 1) | [`LandmarkLayout::landmarks`], [`LandmarkParams::max_per_shape`] |
//!
//! # Deviations
//! - Cost `1 + gamma q[n]` with `q[n]` the mean quality over the shapes a vertex covers
//!   (the method): Eq. (1)/(5a) read literally would punish a vertex for covering many shapes.
//! - Visibility rays are cosine-weighted (the paper samples "all directions"): grazing
//!   directions, from which no tracker sees a point well, count least. A vertex whose normal
//!   vanishes is sampled over the whole sphere.
//! - Symmetric layouts use the worse visibility of the two mirror vertices, since both become
//!   landmarks; only mutual mirror partners are folded, so the output is exactly symmetric.
//! - Algorithm 1's "sufficient landmarks" is read with the 10% rule: after the first round a
//!   shape asks for another landmark only while every landmark it has serves more than
//!   [`LandmarkParams::share_limit`] of the shapes and it has fewer than `max_per_shape`.
//! - [`LandmarkParams::min_visibility`] (off by default) removes candidates that some pose
//!   hides; shapes left without a candidate are reported in `uncovered`.

pub mod candidates;
pub mod cover;
pub mod design;
pub mod score;
pub mod visibility;

use std::time::Instant;

use serde::Serialize;

use crate::error::ShapesmithResult;
use crate::geometry::mirror::MirrorMap;
use crate::geometry::weld::WeldedRig;
use crate::ilp::{IlpOptions, SolveStatus};
use crate::invalid;
use crate::progress::Progress;
use crate::rig::{norm, RigView};
use candidates::{candidate_relation, mutual_partners};
use cover::{adaptive_multi_cover, MultiCoverSettings};
use design::{error_weight, extend_layout, predicted_error, DesignInput, DesignSettings};
pub use design::{Criterion, CurvePoint, DesignStop};
use visibility::{worst_case_visibility, Need, Sampling, Seen};
use crate::progress::NoProgress;

pub use score::{score_layout, score_layout_reporting, LayoutScore, ScoreParams};

/// Place Landmarks' settings ([`crate::settings`]); the cameras and the allowed vertices are
/// the caller's data, `#[serde(skip)]`.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct LandmarkParams {
    /// Candidate threshold on the relative displacement, in (0, 1] (Eq. 3; paper 0.3..0.8).
    pub epsilon: f64,
    /// Weight of visibility against displacement in a vertex's quality, in [0, 1] (Eq. 1).
    pub alpha: f64,
    /// Weight of quality against count in the cost; 0 gives the pure minimum count.
    pub gamma: f64,
    /// Hemisphere rays per vertex and pose (ignored with `cameras`).
    pub rays: usize,
    /// Known camera positions in the mesh's local space: one visibility segment each.
    #[serde(skip)]
    pub cameras: Option<Vec<[f64; 3]>>,
    pub symmetric: bool,
    /// Lateral axis of the symmetry plane (0 = local X).
    pub axis: usize,
    /// Mirror-map tolerance relative to the bounding-box diagonal (the method: 1e-3).
    pub mirror_tolerance: f64,
    /// Rounds of the adaptive multi-cover (Algorithm 1); 1 is the single cover of Eq. (5).
    pub max_per_shape: usize,
    /// Exclusion radius around landmarks for later rounds, relative to the diagonal.
    pub radius: f64,
    /// The 10% rule: a landmark serving more than this fraction of the shapes does not count
    /// as enough for any of them.
    pub share_limit: f64,
    /// Candidates whose worst-case visibility is below this are dropped (0 keeps all).
    pub min_visibility: f64,
    pub seed: u64,
    /// Seconds per HiGHS solve; `None` solves to proven optimality.
    pub time_limit: Option<f64>,
    /// Conditioned layout ([`design`]): add landmarks after the cover until the layout has
    /// this many in all (mirror partners count).
    pub landmarks: Option<usize>,
    /// Conditioned layout: add landmarks until the predicted error (fraction of the diagonal)
    /// is at most this. With `landmarks` too, whichever comes first.
    pub target_error: Option<f64>,
    pub criterion: Criterion,
    /// The design's pool: vertices whose relative displacement reaches this in some shape
    /// (`epsilon` when that is lower). Every pool vertex needs visibility rays, though only
    /// until it is certain to reach `pool_visibility` or not.
    pub pool_epsilon: f64,
    /// Pool vertices seen less than this in their worst pose are not added: a tracker
    /// would lose them (cover landmarks keep the paper's rule, `min_visibility`).
    pub pool_visibility: f64,
    /// Noise of the predicted error, per coordinate, as a fraction of the diagonal (the
    /// score's 0.2%).
    pub noise: f64,
    /// The predicted-error curve runs at least to this many landmarks (a conventional
    /// layout's 68), so that the user sees where more stop paying.
    pub curve_to: usize,
    /// Save visibility rays with the same layout ([`visibility::worst_case_visibility`]):
    /// reuse the neutral's ray outcomes where a pose does not move the region, and ask pool
    /// vertices that are no candidate only whether they reach `pool_visibility` (measured
    /// after the design if added). Off (every vertex traced through every pose) only to
    /// measure the saving.
    pub reuse_visibility: bool,
    /// Vertices a landmark may go on (`true`), one per vertex; `None` allows every vertex.
    /// A face whose teeth and eyes are pieces of the mesh keeps them as occluders and moving
    /// geometry while landmarks stay on the skin; a shape that moves only forbidden vertices
    /// is reported in `uncovered`.
    #[serde(skip)]
    pub allowed: Option<Vec<bool>>,
}

impl Default for LandmarkParams {
    fn default() -> Self {
        Self {
            epsilon: 0.5,
            alpha: 0.5,
            gamma: 0.5,
            rays: 64,
            cameras: None,
            symmetric: false,
            axis: 0,
            mirror_tolerance: 1e-3,
            max_per_shape: 2,
            radius: 0.03,
            share_limit: 0.1,
            min_visibility: 0.0,
            seed: 0,
            time_limit: None,
            landmarks: None,
            target_error: None,
            criterion: Criterion::A,
            pool_epsilon: 0.3,
            pool_visibility: 0.25,
            noise: 0.002,
            curve_to: 68,
            reuse_visibility: true,
            allowed: None,
        }
    }
}

impl LandmarkParams {
    fn validate(&self) -> ShapesmithResult<()> {
        let unit = |x: f64| (0.0..=1.0).contains(&x);
        if !(self.epsilon > 0.0 && self.epsilon <= 1.0) {
            return Err(invalid!("epsilon must be in (0, 1], got {}", self.epsilon));
        }
        if !unit(self.alpha) {
            return Err(invalid!("alpha must be in [0, 1], got {}", self.alpha));
        }
        if !(self.gamma.is_finite() && self.gamma >= 0.0) {
            return Err(invalid!("gamma must be finite and >= 0, got {}", self.gamma));
        }
        if !(self.radius.is_finite() && self.radius >= 0.0) {
            return Err(invalid!("radius must be a finite fraction >= 0 of the diagonal, got {}", self.radius));
        }
        if !unit(self.share_limit) || !unit(self.min_visibility) {
            return Err(invalid!(
                "share_limit and min_visibility must be in [0, 1], got {} and {}",
                self.share_limit,
                self.min_visibility
            ));
        }
        if self.max_per_shape == 0 {
            return Err(invalid!("max_per_shape must be at least 1"));
        }
        if self.landmarks == Some(0) {
            return Err(invalid!("landmarks must be at least 1, got 0"));
        }
        if self.target_error.is_some_and(|e| !(e.is_finite() && e > 0.0)) {
            return Err(invalid!(
                "target_error must be a positive fraction of the diagonal, got {}",
                self.target_error.unwrap_or_default()
            ));
        }
        if !(self.pool_epsilon > 0.0 && self.pool_epsilon <= 1.0) || !unit(self.pool_visibility) {
            return Err(invalid!(
                "pool_epsilon must be in (0, 1] and pool_visibility in [0, 1], got {} and {}",
                self.pool_epsilon,
                self.pool_visibility
            ));
        }
        if !(self.noise.is_finite() && self.noise > 0.0) {
            return Err(invalid!("noise must be a positive fraction of the diagonal, got {}", self.noise));
        }
        if self.axis > 2 {
            return Err(invalid!("the symmetry axis must be 0, 1 or 2, got {}", self.axis));
        }
        if self.time_limit.is_some_and(|t| t.is_nan() || t <= 0.0) {
            return Err(invalid!("time_limit must be positive seconds or None"));
        }
        if self.allowed.as_ref().is_some_and(|allowed| !allowed.contains(&true)) {
            return Err(invalid!("allowed forbids every vertex: allow at least the head's"));
        }
        match &self.cameras {
            None if self.rays == 0 => Err(invalid!("rays must be at least 1 (or give camera positions)")),
            Some(cameras) if cameras.is_empty() => {
                Err(invalid!("cameras is empty: give at least one position, or None for hemisphere visibility"))
            }
            Some(cameras) => match cameras.iter().position(|c| c.iter().any(|x| !x.is_finite())) {
                Some(i) => Err(invalid!("camera {i} has a non-finite position {:?}", cameras[i])),
                None => Ok(()),
            },
            None => Ok(()),
        }
    }
}

#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Landmark {
    pub vertex: u32,
    /// The neutral position.
    pub position: [f64; 3],
    /// Shapes this vertex is a candidate for (`r_k[n] >= eps`), strongest first.
    pub shapes: Vec<usize>,
    /// The shape that moves this vertex most (relative to its own maximum); names it.
    pub strongest: usize,
    /// Worst-case visibility `l[n]` (Eq. 4).
    pub visibility: f64,
    /// 0 for the single cover, 1 for the first backup round, ...; the design's additions
    /// come one round after the cover's last.
    pub round: usize,
    /// The design step (1-based) that added this landmark; `None` for the cover's.
    pub added: Option<usize>,
}

#[derive(Clone, Debug, Serialize)]
pub struct LandmarkLayout {
    /// Sorted by vertex.
    pub landmarks: Vec<Landmark>,
    /// Every round proven optimal.
    pub optimal: bool,
    pub statuses: Vec<SolveStatus>,
    /// Non-inert shapes with no candidate vertex (none unless `min_visibility` removed them).
    pub uncovered: Vec<usize>,
    pub inert: Vec<usize>,
    pub rounds: usize,
    pub seconds_visibility: f64,
    pub seconds_solve: f64,
    /// Seconds of the design stage (and of the predicted error).
    pub seconds_design: f64,
    pub rays_cast: u64,
    /// Rays answered without tracing the whole pose ([`visibility::worst_case_visibility`]).
    pub rays_reused: u64,
    /// Vertices whose visibility was measured (candidates, pool, their mirror partners).
    pub visibility_vertices: usize,
    /// Predicted RMS reconstruction error of the layout, fraction of the diagonal ([`design`]).
    pub predicted_error: f64,
    /// The cover's predicted error, then one point per greedy step (empty without a design).
    pub curve: Vec<CurvePoint>,
    /// Why the design stopped; `None` without a design.
    pub design_stop: Option<DesignStop>,
}

/// Places landmarks (method, section 2): candidates (Eq. 3), worst-case visibility over the
/// neutral and every shape (Eq. 4), then the adaptive multi-cover of Eq. (5), symmetric on
/// request. Progress: visibility is the first 80%, the covers the rest.
///
/// On the welded surface ([`WeldedRig`]): candidates, the mirror map and visibility see a
/// seam's copies as one point (rays do not slip through a seam), and a landmark is a welded
/// point, reported as its representative vertex (the lowest index among its copies).
pub fn place_landmarks(rig: &RigView, params: &LandmarkParams, progress: &dyn Progress) -> ShapesmithResult<LandmarkLayout> {
    let welded = WeldedRig::new(rig);
    let mut layout = place_welded(&welded.view(), params, progress)?;
    for landmark in &mut layout.landmarks {
        landmark.vertex = welded.weld.vertex(landmark.vertex);
    }
    Ok(layout)
}

fn place_welded(rig: &RigView, params: &LandmarkParams, progress: &dyn Progress) -> ShapesmithResult<LandmarkLayout> {
    rig.validate()?;
    params.validate()?;
    if rig.n_shapes() == 0 {
        return Err(invalid!("the rig has no shape keys: landmarks go where shapes move"));
    }
    if let Some(allowed) = params.allowed.as_ref().filter(|a| a.len() != rig.n_vertices()) {
        return Err(invalid!("allowed has {} entries but the mesh has {} vertices", allowed.len(), rig.n_vertices()));
    }
    if let Some(m) = params.landmarks.filter(|&m| m > rig.n_vertices()) {
        return Err(invalid!("landmarks = {m} is more than the mesh's {} vertices", rig.n_vertices()));
    }
    let inert = rig.inert_shapes();
    let live: Vec<usize> = (0..rig.n_shapes()).filter(|k| !inert.contains(k)).collect();
    let mut layout = LandmarkLayout {
        landmarks: Vec::new(),
        optimal: true,
        statuses: Vec::new(),
        uncovered: Vec::new(),
        inert,
        rounds: 0,
        seconds_visibility: 0.0,
        seconds_solve: 0.0,
        seconds_design: 0.0,
        rays_cast: 0,
        rays_reused: 0,
        visibility_vertices: 0,
        predicted_error: 0.0,
        curve: Vec::new(),
        design_stop: None,
    };
    if live.is_empty() {
        return Ok(layout);
    }
    let partners = params
        .symmetric
        .then(|| mutual_partners(&MirrorMap::new(rig.neutral, params.axis, params.mirror_tolerance)));
    let mut relation = candidate_relation(rig, &live, params.epsilon, partners.as_deref(), params.axis);
    let designing = params.landmarks.is_some() || params.target_error.is_some();
    // The design's pool (folded like the cover's candidates, so a pick brings its partner).
    let pool_epsilon = params.pool_epsilon.min(params.epsilon);
    let mut pool: Vec<bool> = if designing {
        let wide = candidate_relation(rig, &live, pool_epsilon, partners.as_deref(), params.axis);
        wide.iter().map(|shapes| !shapes.is_empty()).collect()
    } else {
        vec![false; rig.n_vertices()]
    };
    if let Some(allowed) = &params.allowed {
        for n in (0..rig.n_vertices()).filter(|&n| !allowed[n]) {
            relation[n].clear();
            pool[n] = false;
        }
    }

    // Visibility: exact for every candidate and its mirror partner (the cost uses it); for
    // the rest of the pool and its partners only whether it reaches `pool_visibility`.
    let mut needs: Vec<Option<Need>> = vec![None; rig.n_vertices()];
    for n in (0..rig.n_vertices()).filter(|&n| pool[n]) {
        let partner = partners.as_ref().and_then(|p| p[n]);
        for v in std::iter::once(n).chain(partner.map(|m| m as usize)) {
            needs[v].get_or_insert(Need::AtLeast(params.pool_visibility));
        }
    }
    for n in (0..rig.n_vertices()).filter(|&n| !relation[n].is_empty()) {
        needs[n] = Some(Need::Exact);
        if let Some(m) = partners.as_ref().and_then(|p| p[n]) {
            needs[m as usize] = Some(Need::Exact);
        }
    }
    let (vertices, vertex_needs): (Vec<u32>, Vec<Need>) =
        needs.iter().enumerate().filter_map(|(n, need)| need.map(|need| (n as u32, need))).unzip();
    let sampling = match &params.cameras {
        Some(cameras) => Sampling::Cameras(cameras),
        None => Sampling::Hemisphere { rays: params.rays, seed: params.seed },
    };
    let started = Instant::now();
    let stage = Stage { inner: progress, start: 0.0, span: 0.8 };
    let exhaustive: Vec<Need>;
    let vertex_needs = if params.reuse_visibility {
        &vertex_needs
    } else {
        exhaustive = vec![Need::Exact; vertices.len()];
        &exhaustive
    };
    let measured = worst_case_visibility(rig, &live, &vertices, vertex_needs, &sampling, params.reuse_visibility, &stage)?;
    layout.seconds_visibility = started.elapsed().as_secs_f64();
    layout.rays_cast = measured.rays_cast;
    layout.rays_reused = measured.rays_reused;
    layout.visibility_vertices = vertices.len();
    let mut seen: Vec<Option<Seen>> = vec![None; rig.n_vertices()];
    for (&v, &s) in vertices.iter().zip(&measured.worst) {
        seen[v as usize] = Some(s);
    }
    // `l[n]` where measured, NaN (not computed) elsewhere: the cover reads it only for
    // candidates, all measured.
    let mut visibility: Vec<f64> = seen.iter().map(|s| s.and_then(|s| s.exact()).unwrap_or(f64::NAN)).collect();
    let effective: Vec<f64> = match &partners {
        None => visibility.clone(),
        Some(p) => (0..rig.n_vertices()).map(|n| p[n].map_or(visibility[n], |m| visibility[n].min(visibility[m as usize]))).collect(),
    };
    if params.min_visibility > 0.0 {
        for (n, shapes) in relation.iter_mut().enumerate() {
            if effective[n] < params.min_visibility {
                shapes.clear();
            }
        }
    }
    let mut has_candidate = vec![false; rig.n_shapes()];
    relation.iter().flatten().for_each(|&(k, _)| has_candidate[k] = true);
    layout.uncovered = live.iter().copied().filter(|&k| !has_candidate[k]).collect();
    if layout.uncovered.len() == live.len() {
        if params.allowed.is_some() {
            return Err(invalid!(
                "no allowed vertex is a landmark candidate for any shape: the shapes move only where landmarks \
                 may not go, or their candidates are seen less than min_visibility = {}; allow more parts or \
                 lower epsilon (now {})",
                params.min_visibility,
                params.epsilon
            ));
        }
        return Err(invalid!(
            "no vertex is a landmark candidate for any shape: every candidate is seen less than \
             min_visibility = {} of the time in some pose; lower min_visibility or epsilon (now {})",
            params.min_visibility,
            params.epsilon
        ));
    }

    let settings = MultiCoverSettings {
        alpha: params.alpha,
        gamma: params.gamma,
        max_per_shape: params.max_per_shape,
        radius: params.radius * rig.bbox_diagonal(),
        share_limit: params.share_limit,
        ilp: IlpOptions { time_limit: params.time_limit, skip_feasibility_jump: false },
    };
    let chosen = adaptive_multi_cover(
        &relation,
        &effective,
        live.len(),
        partners.as_deref(),
        rig.neutral,
        &settings,
        &Stage { inner: progress, start: 0.8, span: 0.2 },
    )?;
    layout.optimal = chosen.statuses.iter().all(|s| s.is_optimal());
    layout.rounds = chosen.statuses.len();
    layout.statuses = chosen.statuses;
    layout.seconds_solve = chosen.seconds_solve;
    let mut placed: Vec<(u32, usize, Option<usize>)> = chosen.landmarks.iter().map(|&(v, round)| (v, round, None)).collect();
    let started = Instant::now();
    let deltas: Vec<&[[f32; 3]]> = live.iter().map(|&k| rig.delta(k)).collect();
    let cover: Vec<u32> = placed.iter().map(|p| p.0).collect();
    if let Some(m) = params.landmarks.filter(|&m| m < cover.len()) {
        return Err(invalid!(
            "the cover alone needs {} landmarks to give every shape one, more than landmarks = {m}: ask for at \
             least {}, or make the cover smaller (a higher epsilon, max_per_shape = 1)",
            cover.len(),
            cover.len()
        ));
    }
    if designing {
        let taken: std::collections::HashSet<u32> = cover.iter().copied().collect();
        let visible = |v: usize| seen[v].and_then(|s| s.at_least(params.pool_visibility)) == Some(true);
        let units: Vec<Vec<u32>> = (0..rig.n_vertices() as u32)
            .filter(|&n| pool[n as usize] && !taken.contains(&n))
            .map(|n| std::iter::once(n).chain(partners.as_ref().and_then(|p| p[n as usize])).collect::<Vec<u32>>())
            .filter(|unit| unit.iter().all(|&v| visible(v as usize)))
            .collect();
        let input = DesignInput {
            deltas,
            neutral: rig.neutral,
            pool: units,
            cover,
            radius: settings.radius,
            diagonal: rig.bbox_diagonal(),
        };
        let design_settings = DesignSettings {
            landmarks: params.landmarks,
            target_error: params.target_error,
            criterion: params.criterion,
            noise: params.noise,
            curve_to: params.curve_to,
        };
        let outcome = extend_layout(&input, &design_settings);
        for (step, vertices) in outcome.added.iter().enumerate() {
            placed.extend(vertices.iter().map(|&v| (v, layout.rounds, Some(step + 1))));
        }
        layout.predicted_error = outcome.curve[outcome.added.len()].predicted_error;
        layout.curve = outcome.curve;
        layout.design_stop = Some(outcome.stop);
    } else {
        let weight = error_weight(&deltas);
        let sigma = params.noise * rig.bbox_diagonal();
        layout.predicted_error = predicted_error(&deltas, &weight, &cover, sigma * sigma) / rig.bbox_diagonal();
    }
    layout.seconds_design = started.elapsed().as_secs_f64();
    placed.sort();
    // Added landmarks from the pool were only measured against the threshold: measure them
    // now (the same rays, so the value is the one a full computation gives).
    let started = Instant::now();
    let unmeasured: Vec<u32> = placed.iter().map(|p| p.0).filter(|&v| visibility[v as usize].is_nan()).collect();
    if !unmeasured.is_empty() {
        let needs = vec![Need::Exact; unmeasured.len()];
        let late = worst_case_visibility(rig, &live, &unmeasured, &needs, &sampling, params.reuse_visibility, &NoProgress)?;
        layout.rays_cast += late.rays_cast;
        layout.rays_reused += late.rays_reused;
        for (&v, s) in unmeasured.iter().zip(&late.worst) {
            visibility[v as usize] = s.exact().unwrap_or(f64::NAN);
        }
    }
    layout.seconds_visibility += started.elapsed().as_secs_f64();
    let maxima: Vec<f64> = (0..rig.n_shapes()).map(|k| rig.max_displacement(k)).collect();
    layout.landmarks = placed
        .iter()
        .map(|&(vertex, round, added)| {
            // Report in terms of the rig as it is (not folded), strongest first.
            let mut strengths: Vec<(usize, f64)> =
                live.iter().map(|&k| (k, norm(&rig.delta(k)[vertex as usize]) / maxima[k])).collect();
            strengths.sort_by(|a, b| b.1.total_cmp(&a.1).then(a.0.cmp(&b.0)));
            Landmark {
                vertex,
                position: rig.neutral[vertex as usize].map(f64::from),
                shapes: strengths.iter().filter(|s| s.1 >= params.epsilon).map(|s| s.0).collect(),
                strongest: strengths[0].0,
                visibility: visibility[vertex as usize],
                round,
                added,
            }
        })
        .collect();
    Ok(layout)
}

/// A sub-range `[start, start + span]` of the caller's progress.
struct Stage<'a> {
    inner: &'a dyn Progress,
    start: f64,
    span: f64,
}

impl Progress for Stage<'_> {
    fn report(&self, fraction: f64) -> bool {
        self.inner.report(self.start + self.span * fraction)
    }
}

#[cfg(test)]
mod tests;
