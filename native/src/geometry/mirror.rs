//! Bilateral symmetry: the vertex mirror map, symmetric shape pairs (eyeBlinkLeft and
//! eyeBlinkRight) and mirror antagonists (jawLeft and jawRight). Method, section 0 and the
//! antagonist rule of section 1.
//!
//! A symmetric pair moves mirrored regions and is posed together; a mirror antagonist is a
//! mirror pair that moves the *same* region in opposite directions and can never be posed
//! together. Both satisfy the mirror test, so the region overlap (IoU of the binary
//! blendshapes) and the sign of the cosine tell them apart.

use faer::linalg::matmul::matmul;
use faer::{Accum, Mat, MatRef, Par};
use serde::Serialize;

use super::neighbours::PointTree;
use crate::rig::{norm, RigView};

/// For each vertex, the vertex nearest its mirror image across `axis = 0`, if within `tol`.
#[derive(Clone, Debug, Serialize)]
pub struct MirrorMap {
    /// The lateral axis (0 = X) whose sign the mirror flips.
    pub axis: usize,
    pub partner: Vec<Option<u32>>,
    pub unmatched: Vec<u32>,
}

impl MirrorMap {
    /// `tol_fraction` is relative to the bounding-box diagonal (the method: 1e-3).
    pub fn new(points: &[[f32; 3]], axis: usize, tol_fraction: f64) -> Self {
        let tol = tol_fraction * crate::rig::bbox_diagonal(points);
        let tree = PointTree::new(points);
        let partner: Vec<Option<u32>> = points
            .iter()
            .map(|p| {
                let mut q = p.map(f64::from);
                q[axis] = -q[axis];
                let (m, d) = tree.nearest(q);
                (d <= tol).then_some(m as u32)
            })
            .collect();
        let unmatched = (0..points.len() as u32).filter(|&v| partner[v as usize].is_none()).collect();
        Self { axis, partner, unmatched }
    }

    /// `M(D)[n] = S D[m(n)]`: the field mirrored across the plane at vertex `n` (S flips
    /// the lateral component); zero at an unmatched vertex.
    pub fn mirrored_at(&self, field: &[[f32; 3]], n: usize) -> [f32; 3] {
        match self.partner[n] {
            Some(m) => {
                let mut d = field[m as usize];
                d[self.axis] = -d[self.axis];
                d
            }
            None => [0.0; 3],
        }
    }
}

#[derive(Clone, Debug, Serialize, serde::Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct SymmetryParams {
    /// Mirror test: `||M(D_i) - D_j|| / max(||D_i||, ||D_j||)` below this (the method: 0.25).
    pub pair_tolerance: f64,
    /// A mirror pair whose binary blendshapes overlap above this IoU, with a negative
    /// cosine, is an antagonist pair (method, section 1: 0.6).
    pub antagonist_iou: f64,
    /// Threshold of the binary blendshapes used for the IoU (the method: mu = 0.3).
    pub mu: f64,
    /// Pair shapes by name (Left/Right, _L/_R, .L/.R, _l/_r) where geometry finds no partner.
    pub use_names: bool,
}

impl Default for SymmetryParams {
    fn default() -> Self {
        Self { pair_tolerance: 0.25, antagonist_iou: 0.6, mu: 0.3, use_names: true }
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum PairSource {
    Geometry,
    Name,
}

#[derive(Clone, Debug, Serialize)]
pub struct ShapePair {
    pub first: usize,
    pub second: usize,
    pub mirror_error: f64,
    pub source: PairSource,
}

#[derive(Clone, Debug, Serialize)]
pub struct Antagonist {
    pub first: usize,
    pub second: usize,
    pub iou: f64,
    pub cosine: f64,
}

#[derive(Clone, Debug, Default, Serialize)]
pub struct Symmetry {
    pub pairs: Vec<ShapePair>,
    pub antagonists: Vec<Antagonist>,
    /// Shapes that are their own mirror image (jawOpen): they pair with nobody.
    pub self_symmetric: Vec<usize>,
    /// Geometric pairs whose names say otherwise (e.g. `browDownLeft` with `eyeBlinkRight`).
    pub name_conflicts: Vec<(usize, usize)>,
}

impl Symmetry {
    /// The partner of shape `k` in a symmetric pair, if any.
    pub fn partner_of(&self, k: usize) -> Option<usize> {
        self.pairs.iter().find_map(|p| match (p.first == k, p.second == k) {
            (true, _) => Some(p.second),
            (_, true) => Some(p.first),
            _ => None,
        })
    }
}

/// Mirror errors below `pair_tolerance + SCREEN_MARGIN` by the expanded (Gram) form are
/// recomputed exactly; the rest cannot pass. The expanded form loses about `3N * eps` of
/// `|D|^2` to cancellation (about 1e-10 for N = 10^5, hence at most 1e-5 in the relative
/// error), far below this margin: the screen never drops a pair the exact test would
/// accept, and every reported error is the exact one, as before the screen existed.
const SCREEN_MARGIN: f64 = 1e-3;

/// Finds symmetric pairs (greedy by smallest mirror error), mirror antagonists, and falls
/// back to names for shapes geometry leaves unpaired. Inert shapes take part in nothing.
pub fn find_symmetry(rig: &RigView, map: &MirrorMap, params: &SymmetryParams) -> Symmetry {
    let active: Vec<Vec<u32>> = (0..rig.n_shapes()).map(|k| rig.active_vertices(k, params.mu)).collect();
    find_symmetry_given(rig, map, params, &rig.inert_shapes(), &active)
}

/// [`find_symmetry`] for a caller that already holds the inert shapes and the binary
/// blendshapes at `params.mu` (the packer), so that neither is computed twice.
///
/// The K^2 mirror errors are screened with one Gram product ([`delta_inner_products`]):
/// `|M D_i - D_j|^2 = |M D_i|^2 + |D_j|^2 - 2 <M D_i, D_j>`, so only the few pairs that may
/// pass are measured with a full pass over the vertices.
pub fn find_symmetry_given(
    rig: &RigView,
    map: &MirrorMap,
    params: &SymmetryParams,
    inert: &[usize],
    active: &[Vec<u32>],
) -> Symmetry {
    let k_count = rig.n_shapes();
    let live: Vec<usize> = (0..k_count).filter(|k| !inert.contains(k)).collect();
    let products = delta_inner_products(rig, |k, n| map.mirrored_at(rig.delta(k), n).map(f64::from));
    let (gram, mirrored_norms_sq) = (&products.gram, &products.left_norms_sq);
    let norms: Vec<f64> = products.right_norms_sq.iter().map(|s| s.sqrt()).collect();
    // Both directions: on a mesh with unmatched vertices one direction alone would pair a
    // small shape with any large one (the mirrored field is zero where no partner exists).
    let estimated_error = |i: usize, j: usize| {
        let forward = mirrored_norms_sq[i] + products.right_norms_sq[j] - 2.0 * gram[(i, j)];
        let backward = mirrored_norms_sq[j] + products.right_norms_sq[i] - 2.0 * gram[(j, i)];
        forward.max(backward).max(0.0).sqrt() / norms[i].max(norms[j])
    };
    let mirror_error = |i: usize, j: usize| {
        let forward = mirrored_difference_norm(map, rig.delta(i), rig.delta(j));
        let backward = mirrored_difference_norm(map, rig.delta(j), rig.delta(i));
        forward.max(backward) / norms[i].max(norms[j])
    };
    let passes = |i: usize, j: usize| {
        (estimated_error(i, j) < params.pair_tolerance + SCREEN_MARGIN)
            .then(|| mirror_error(i, j))
            .filter(|&e| e < params.pair_tolerance)
    };

    let mut out = Symmetry {
        self_symmetric: live.iter().copied().filter(|&k| passes(k, k).is_some()).collect(),
        ..Default::default()
    };

    let mut candidates = Vec::new();
    for (a, &i) in live.iter().enumerate() {
        for &j in &live[a + 1..] {
            if out.self_symmetric.contains(&i) || out.self_symmetric.contains(&j) {
                continue;
            }
            if let Some(e) = passes(i, j) {
                candidates.push((e, i, j));
            }
        }
    }
    candidates.sort_by(|a, b| a.0.total_cmp(&b.0));
    let mut used = vec![false; k_count];
    for (e, i, j) in candidates {
        if used[i] || used[j] {
            continue;
        }
        used[i] = true;
        used[j] = true;
        let iou = intersection_over_union(&active[i], &active[j]);
        let cosine = cosine(rig.delta(i), rig.delta(j));
        if iou > params.antagonist_iou && cosine < 0.0 {
            out.antagonists.push(Antagonist { first: i, second: j, iou, cosine });
        } else {
            let named = name_partner(&rig.names[i]).is_some_and(|n| n == rig.names[j]);
            if !named && (name_partner(&rig.names[i]).is_some() || name_partner(&rig.names[j]).is_some()) {
                out.name_conflicts.push((i, j));
            }
            out.pairs.push(ShapePair { first: i, second: j, mirror_error: e, source: PairSource::Geometry });
        }
    }

    if params.use_names {
        for &i in &live {
            let Some(other) = name_partner(&rig.names[i]) else { continue };
            let Some(j) = rig.names.iter().position(|n| *n == other) else { continue };
            if j <= i || used[i] || used[j] || inert.contains(&j) {
                continue;
            }
            let iou = intersection_over_union(&active[i], &active[j]);
            let cosine = cosine(rig.delta(i), rig.delta(j));
            used[i] = true;
            used[j] = true;
            if iou > params.antagonist_iou && cosine < 0.0 {
                out.antagonists.push(Antagonist { first: i, second: j, iou, cosine });
            } else {
                out.pairs.push(ShapePair { first: i, second: j, mirror_error: mirror_error(i, j), source: PairSource::Name });
            }
        }
    }
    out
}

/// The name a mirror partner would carry: `Left`<->`Right` anywhere (last occurrence), or a
/// `_L/_R`, `.L/.R`, `_l/_r`, `.l/.r` suffix.
pub fn name_partner(name: &str) -> Option<String> {
    for (a, b) in [("Left", "Right"), ("Right", "Left"), ("left", "right"), ("right", "left")] {
        if let Some(at) = name.rfind(a) {
            return Some(format!("{}{}{}", &name[..at], b, &name[at + a.len()..]));
        }
    }
    for (a, b) in [("_L", "_R"), ("_R", "_L"), (".L", ".R"), (".R", ".L"), ("_l", "_r"), ("_r", "_l"), (".l", ".r"), (".r", ".l")] {
        if let Some(stem) = name.strip_suffix(a) {
            return Some(format!("{stem}{b}"));
        }
    }
    None
}

/// Intersection over union of two sorted index sets; 0 when both are empty.
pub fn intersection_over_union(a: &[u32], b: &[u32]) -> f64 {
    let (mut i, mut j, mut common) = (0, 0, 0usize);
    while i < a.len() && j < b.len() {
        match a[i].cmp(&b[j]) {
            std::cmp::Ordering::Less => i += 1,
            std::cmp::Ordering::Greater => j += 1,
            std::cmp::Ordering::Equal => {
                common += 1;
                i += 1;
                j += 1;
            }
        }
    }
    let union = a.len() + b.len() - common;
    if union == 0 { 0.0 } else { common as f64 / union as f64 }
}

/// Cosine of two flattened delta fields; 0 when either is zero.
pub fn cosine(a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    let dot: f64 = a.iter().zip(b).map(|(p, q)| (0..3).map(|c| p[c] as f64 * q[c] as f64).sum::<f64>()).sum();
    let (na, nb) = (field_norm(a), field_norm(b));
    if na == 0.0 || nb == 0.0 { 0.0 } else { dot / (na * nb) }
}

pub fn field_norm(field: &[[f32; 3]]) -> f64 {
    field.iter().map(|d| norm(d).powi(2)).sum::<f64>().sqrt()
}

/// `|M(a) - b|` (see [`MirrorMap::mirrored_at`]) without building `M(a)`.
fn mirrored_difference_norm(map: &MirrorMap, a: &[[f32; 3]], b: &[[f32; 3]]) -> f64 {
    b.iter()
        .enumerate()
        .map(|(n, q)| {
            let p = map.mirrored_at(a, n);
            (0..3).map(|c| (p[c] as f64 - q[c] as f64).powi(2)).sum::<f64>()
        })
        .sum::<f64>()
        .sqrt()
}

/// Vertices per block of [`delta_inner_products`]: a block's two 3B x K operands stay in
/// cache, and the memory used does not grow with N.
const GRAM_BLOCK_VERTICES: usize = 256;

/// What [`delta_inner_products`] returns.
pub struct InnerProducts {
    /// `gram[(i, j)] = <L_i, D_j>` (K x K).
    pub gram: Mat<f64>,
    /// `|L_i|^2`.
    pub left_norms_sq: Vec<f64>,
    /// `|D_j|^2`.
    pub right_norms_sq: Vec<f64>,
}

/// The inner products of the fields `L_i`, given per shape and vertex by `left(i, n)`, with
/// every delta field `D_j`, in f64, and the squared norms of both. One matrix product per
/// block of vertices replaces K^2 scalar passes over the mesh: the cost stays linear in N
/// and runs at the speed of the matrix kernel.
///
/// A shape of a face moves a small part of it (a quarter of the (vertex, shape) deltas of a
/// 26k-vertex ARKit head are non-zero), and a column that is zero over a block adds nothing
/// to any product. So the vertices are taken in the order of which fields are non-zero at
/// them (vertices moved by the same shapes fall in the same blocks), and each block's
/// product has only the columns non-zero in it: the same sums over fewer terms (about a
/// fifth of the dense product's on that head), in another order.
pub fn delta_inner_products(rig: &RigView, left: impl Fn(usize, usize) -> [f64; 3]) -> InnerProducts {
    let (n_vertices, k_count) = (rig.n_vertices(), rig.n_shapes());
    let mut gram = Mat::<f64>::zeros(k_count, k_count);
    let (mut left_norms_sq, mut right_norms_sq) = (vec![0.0; k_count], vec![0.0; k_count]);
    // Per vertex, which left and right fields are non-zero there: one bit per shape, for the
    // left fields then the right ones.
    let words = (2 * k_count).div_ceil(64);
    let mut pattern = vec![0u64; n_vertices * words];
    for k in 0..k_count {
        let delta = rig.delta(k);
        for n in 0..n_vertices {
            let bits = &mut pattern[n * words..(n + 1) * words];
            if left(k, n) != [0.0; 3] {
                bits[k / 64] |= 1 << (k % 64);
            }
            if delta[n] != [0.0; 3] {
                bits[(k_count + k) / 64] |= 1 << ((k_count + k) % 64);
            }
        }
    }
    let of = |n: usize| &pattern[n * words..(n + 1) * words];
    let mut order: Vec<usize> = (0..n_vertices).filter(|&n| of(n).iter().any(|&w| w != 0)).collect();
    order.sort_by(|&a, &b| of(a).cmp(of(b)));
    let capacity = 3 * GRAM_BLOCK_VERTICES.min(n_vertices) * k_count;
    let (mut left_block, mut right_block, mut products) = (vec![0.0; capacity], vec![0.0; capacity], Mat::<f64>::zeros(0, 0));
    for block in order.chunks(GRAM_BLOCK_VERTICES) {
        let mut union = vec![0u64; words];
        for &n in block {
            union.iter_mut().zip(of(n)).for_each(|(u, w)| *u |= w);
        }
        let set = |bit: usize| union[bit / 64] >> (bit % 64) & 1 == 1;
        let lefts: Vec<usize> = (0..k_count).filter(|&k| set(k)).collect();
        let rights: Vec<usize> = (0..k_count).filter(|&k| set(k_count + k)).collect();
        let rows = 3 * block.len();
        for (c, &k) in lefts.iter().enumerate() {
            let l = &mut left_block[c * rows..(c + 1) * rows];
            for (v, &n) in block.iter().enumerate() {
                l[3 * v..3 * v + 3].copy_from_slice(&left(k, n));
            }
            left_norms_sq[k] += l.iter().map(|x| x * x).sum::<f64>();
        }
        for (c, &k) in rights.iter().enumerate() {
            let (r, delta) = (&mut right_block[c * rows..(c + 1) * rows], rig.delta(k));
            for (v, &n) in block.iter().enumerate() {
                r[3 * v..3 * v + 3].copy_from_slice(&delta[n].map(f64::from));
            }
            right_norms_sq[k] += r.iter().map(|x| x * x).sum::<f64>();
        }
        if lefts.is_empty() || rights.is_empty() {
            continue;
        }
        let l = MatRef::from_column_major_slice(&left_block[..rows * lefts.len()], rows, lefts.len());
        let r = MatRef::from_column_major_slice(&right_block[..rows * rights.len()], rows, rights.len());
        products.resize_with(lefts.len(), rights.len(), |_, _| 0.0);
        matmul(&mut products, Accum::Replace, l.transpose(), r, 1.0, Par::Seq);
        for (a, &i) in lefts.iter().enumerate() {
            for (b, &j) in rights.iter().enumerate() {
                gram[(i, j)] += products[(a, b)];
            }
        }
    }
    InnerProducts { gram, left_norms_sq, right_norms_sq }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A mirrored grid of 2 x 7 x 5 vertices (x in -3..3), with shapes whose true relations
    /// are known: a bump on each side (a symmetric pair, named misleadingly for one of them),
    /// a central bump (self-symmetric), a sideways shift of the centre in each direction
    /// (mirror antagonists), and an inert shape.
    fn mirrored_rig() -> (Vec<[f32; 3]>, Vec<[f32; 3]>, Vec<String>) {
        let mut pts = Vec::new();
        for x in -3..=3 {
            for y in 0..5 {
                for z in 0..2 {
                    pts.push([x as f32, y as f32, z as f32 * 0.5 + 0.01 * (y * y) as f32]);
                }
            }
        }
        let n = pts.len();
        let bump = |cx: f32, dir: [f32; 3]| -> Vec<[f32; 3]> {
            pts.iter()
                .map(|p| {
                    let w = (-((p[0] - cx).powi(2) + (p[1] - 2.0).powi(2))).exp();
                    dir.map(|c| c * w)
                })
                .collect()
        };
        let shapes = [
            ("smileLeft", bump(2.0, [0.3, 0.5, 0.1])),
            ("wrinkle", bump(-2.0, [-0.3, 0.5, 0.1])),
            ("jawOpen", bump(0.0, [0.0, -1.0, 0.2])),
            ("jawLeft", bump(0.0, [1.0, 0.0, 0.0])),
            ("jawRight", bump(0.0, [-1.0, 0.0, 0.0])),
            ("nothing", vec![[0.0; 3]; n]),
        ];
        let names = shapes.iter().map(|s| s.0.to_string()).collect();
        let deltas = shapes.into_iter().flat_map(|s| s.1).collect();
        (pts, deltas, names)
    }

    #[test]
    fn mirror_map_matches_every_vertex_of_a_mirrored_grid() {
        let (pts, _, _) = mirrored_rig();
        let map = MirrorMap::new(&pts, 0, 1e-3);
        assert!(map.unmatched.is_empty());
        for (v, m) in map.partner.iter().enumerate() {
            let m = m.unwrap() as usize;
            assert_eq!(pts[m][0], -pts[v][0]);
            assert_eq!(pts[m][1..], pts[v][1..]);
        }
        // A vertex moved off its mirror position is reported.
        let mut moved = pts.clone();
        moved[0][1] += 0.3;
        assert_eq!(MirrorMap::new(&moved, 0, 1e-3).unmatched.len(), 2);
    }

    #[test]
    fn finds_true_pairs_antagonists_and_self_symmetric_shapes() {
        let (pts, deltas, names) = mirrored_rig();
        let tris = [];
        let rig = RigView::new(&pts, &deltas, &tris, &names).unwrap();
        let map = MirrorMap::new(&pts, 0, 1e-3);
        let sym = find_symmetry(&rig, &map, &SymmetryParams::default());
        assert_eq!(sym.pairs.len(), 1);
        assert_eq!((sym.pairs[0].first, sym.pairs[0].second), (0, 1));
        assert_eq!(sym.pairs[0].source, PairSource::Geometry);
        assert!(sym.pairs[0].mirror_error < 1e-6);
        assert_eq!(sym.name_conflicts, vec![(0, 1)]);
        assert_eq!(sym.self_symmetric, vec![2]);
        assert_eq!(sym.antagonists.len(), 1);
        let a = &sym.antagonists[0];
        assert_eq!((a.first, a.second), (3, 4));
        assert!(a.iou > 0.99 && a.cosine < -0.99);
        assert_eq!(sym.partner_of(1), Some(0));
        assert_eq!(sym.partner_of(5), None);
    }

    #[test]
    fn names_pair_what_geometry_cannot() {
        let (pts, mut deltas, mut names) = mirrored_rig();
        let n = pts.len();
        // Break the geometric mirror of shape 1 and give the pair matching names.
        for d in &mut deltas[n..2 * n] {
            d[2] *= -4.0;
        }
        names[0] = "smile_L".into();
        names[1] = "smile_R".into();
        let tris = [];
        let rig = RigView::new(&pts, &deltas, &tris, &names).unwrap();
        let map = MirrorMap::new(&pts, 0, 1e-3);
        let sym = find_symmetry(&rig, &map, &SymmetryParams::default());
        let pair = sym.pairs.iter().find(|p| p.first == 0).unwrap();
        assert_eq!((pair.second, pair.source), (1, PairSource::Name));
        let off = find_symmetry(&rig, &map, &SymmetryParams { use_names: false, ..Default::default() });
        assert!(off.pairs.is_empty());
    }

    #[test]
    fn no_pairs_without_mirror_partners() {
        // A lopsided mesh (nothing mirrors) with a small and a large shape on one side.
        let pts: Vec<[f32; 3]> = (0..12).map(|i| [1.0 + i as f32, (i % 3) as f32, 0.0]).collect();
        let mut deltas = vec![[0.0f32; 3]; 24];
        deltas[2] = [0.0, 0.0, 0.01];
        deltas[12 + 5] = [0.0, 0.0, 1.0];
        let names = vec!["small".to_string(), "large".to_string()];
        let tris = [];
        let rig = RigView::new(&pts, &deltas, &tris, &names).unwrap();
        let map = MirrorMap::new(&pts, 0, 1e-3);
        assert_eq!(map.unmatched.len(), 12);
        let sym = find_symmetry(&rig, &map, &SymmetryParams::default());
        assert!(sym.pairs.is_empty() && sym.antagonists.is_empty(), "{sym:?}");
    }

    #[test]
    fn blocked_inner_products_match_direct_sums_across_block_boundaries() {
        // More vertices than one block, a lopsided mesh (many unmatched vertices), more
        // shapes than one word of the non-zero patterns holds, and fields of every sparsity
        // (dense, patchy, one vertex, none): every <M D_i, D_j> must equal the plain sum over
        // vertices, whichever columns a block skips.
        let (n, k_count) = (2 * GRAM_BLOCK_VERTICES + 37, 70);
        let pts: Vec<[f32; 3]> =
            (0..n).map(|v| [((v % 23) as f32 - 9.0) * 0.1, (v / 23) as f32 * 0.1, (v % 5) as f32 * 0.01]).collect();
        let names: Vec<String> = (0..k_count).map(|k| format!("s{k}")).collect();
        let moves = |k: usize, v: usize| match k % 10 {
            0 => true,
            1 => v == 7 * k,
            2 => false,
            _ => (v * 31 + k * 17) % 97 < 5 + k % 40,
        };
        let deltas: Vec<[f32; 3]> = (0..k_count * n)
            .map(|i| {
                let value = [((i * 7) % 11) as f32 - 5.0, ((i * 3) % 13) as f32 * 0.2, ((i * 5) % 7) as f32 - 3.0];
                if moves(i / n, i % n) { value } else { [0.0; 3] }
            })
            .collect();
        let rig = RigView::new(&pts, &deltas, &[], &names).unwrap();
        let map = MirrorMap::new(&pts, 0, 1e-3);
        assert!(!map.unmatched.is_empty() && map.unmatched.len() < n);
        let products = delta_inner_products(&rig, |k, v| map.mirrored_at(rig.delta(k), v).map(f64::from));
        let gram = &products.gram;
        for i in 0..k_count {
            for j in 0..k_count {
                let direct: f64 = (0..n)
                    .map(|v| {
                        let (p, q) = (map.mirrored_at(rig.delta(i), v), rig.delta(j)[v]);
                        (0..3).map(|c| p[c] as f64 * q[c] as f64).sum::<f64>()
                    })
                    .sum();
                assert!((gram[(i, j)] - direct).abs() <= 1e-9 * direct.abs().max(1.0), "{i} {j}: {} vs {direct}", gram[(i, j)]);
            }
            let mirrored: f64 = (0..n).map(|v| norm(&map.mirrored_at(rig.delta(i), v)).powi(2)).sum();
            assert!((products.left_norms_sq[i] - mirrored).abs() <= 1e-9 * mirrored.max(1.0));
            assert!((products.right_norms_sq[i] - field_norm(rig.delta(i)).powi(2)).abs() <= 1e-9 * mirrored.max(1.0));
        }
    }

    #[test]
    fn name_partners() {
        assert_eq!(name_partner("eyeBlinkLeft").as_deref(), Some("eyeBlinkRight"));
        assert_eq!(name_partner("brow_R").as_deref(), Some("brow_L"));
        assert_eq!(name_partner("lid.l").as_deref(), Some("lid.r"));
        assert_eq!(name_partner("jawOpen"), None);
    }
}
