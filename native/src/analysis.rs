//! Analyze Rig: what a rigger checks before running any tool. Counts, inert shapes,
//! degenerate triangles, the mirror map's unmatched vertices, and the symmetric pairs and
//! mirror antagonists found geometrically (with the name fallback), and the seams welded.
//! Method, section 0.

use serde::Serialize;

use crate::error::ShapesmithResult;
use crate::geometry::mirror::{find_symmetry, MirrorMap, PairSource, SymmetryParams};
use crate::geometry::weld::WeldedRig;
use crate::rig::{degenerate_triangles, validate_points, RigView};

/// Analyze Rig's settings ([`crate::settings`]).
#[derive(Clone, Debug, Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct AnalysisParams {
    /// Lateral axis of the symmetry plane (0 = local X).
    pub axis: usize,
    /// Mirror-map tolerance relative to the bounding-box diagonal (the method: 1e-3).
    pub mirror_tolerance: f64,
    pub symmetry: SymmetryParams,
}

impl Default for AnalysisParams {
    fn default() -> Self {
        Self { axis: 0, mirror_tolerance: 1e-3, symmetry: SymmetryParams::default() }
    }
}

#[derive(Clone, Debug, Serialize)]
pub struct NamedPair {
    pub first: String,
    pub second: String,
    pub mirror_error: f64,
    pub source: PairSource,
}

#[derive(Clone, Debug, Serialize)]
pub struct NamedAntagonist {
    pub first: String,
    pub second: String,
    pub iou: f64,
    pub cosine: f64,
}

#[derive(Clone, Debug, Serialize)]
pub struct RigAnalysis {
    pub vertices: usize,
    pub triangles: usize,
    pub shapes: usize,
    pub bbox_diagonal: f64,
    pub inert: Vec<String>,
    pub degenerate_triangles: Vec<u32>,
    /// Mirror-unmatched welded points, each as its representative vertex.
    pub unmatched_vertices: Vec<u32>,
    /// Vertices that share their point with a copy (split along a UV seam or hard edge) and
    /// the welded points they make: every tool reads them as one.
    pub seam_vertices: usize,
    pub seam_groups: usize,
    pub symmetric_pairs: Vec<NamedPair>,
    pub antagonists: Vec<NamedAntagonist>,
    pub self_symmetric: Vec<String>,
    /// Geometric pairs whose names disagree, for the user to review.
    pub name_conflicts: Vec<(String, String)>,
}

/// Analyzes the rig. Non-finite coordinates are an error (nothing can be measured);
/// degenerate triangles are listed, not fatal, since only transfer cannot use them.
pub fn analyze_rig(rig: &RigView, params: &AnalysisParams) -> ShapesmithResult<RigAnalysis> {
    validate_points(rig.neutral, "neutral")?;
    for k in 0..rig.n_shapes() {
        validate_points(rig.delta(k), &format!("shape key '{}'", rig.names[k]))?;
    }
    crate::rig::validate_triangle_indices(rig.n_vertices(), rig.triangles)?;
    if params.axis > 2 {
        return Err(crate::invalid!("the symmetry axis must be 0, 1 or 2, got {}", params.axis));
    }
    // The mirror map and the pairs on the welded surface: a seam's copies are one point.
    let welded_rig = WeldedRig::new(rig);
    let (weld, welded) = (&welded_rig.weld, welded_rig.view());
    let map = MirrorMap::new(welded.neutral, params.axis, params.mirror_tolerance);
    let sym = find_symmetry(&welded, &map, &params.symmetry);
    let name = |k: usize| rig.names[k].clone();
    Ok(RigAnalysis {
        vertices: rig.n_vertices(),
        triangles: rig.triangles.len(),
        shapes: rig.n_shapes(),
        bbox_diagonal: rig.bbox_diagonal(),
        inert: rig.inert_shapes().into_iter().map(name).collect(),
        degenerate_triangles: degenerate_triangles(rig.neutral, rig.triangles),
        unmatched_vertices: map.unmatched.iter().map(|&w| weld.vertex(w)).collect(),
        seam_vertices: weld.seam_vertices(),
        seam_groups: weld.seam_groups(),
        symmetric_pairs: sym
            .pairs
            .iter()
            .map(|p| NamedPair { first: name(p.first), second: name(p.second), mirror_error: p.mirror_error, source: p.source })
            .collect(),
        antagonists: sym
            .antagonists
            .iter()
            .map(|a| NamedAntagonist { first: name(a.first), second: name(a.second), iou: a.iou, cosine: a.cosine })
            .collect(),
        self_symmetric: sym.self_symmetric.iter().map(|&k| name(k)).collect(),
        name_conflicts: sym.name_conflicts.iter().map(|&(i, j)| (name(i), name(j))).collect(),
    })
}
