//! A key's contacts: the virtual edges a template key adds ([`KeyContactSearch::edges`]).
//!
//! The same definition as the rest's search ([`super::virtual_edges`]) on the template posed
//! by the key, among pairs apart at rest that it brings to touch: the lids a blink closes,
//! which the rest's search cannot see on an eye open wider than `tau_d`.
//!
//! Touching (`2 d_ij <= e_i + e_j`, `e` the rest mesh's mean edge length around a vertex)
//! confines the search: a source's partners lie within `(e_i + e_j) / 2` of it, about one
//! edge, not the whole `tau_d` ball. The vertices are sorted once into classes of `e`
//! (within a factor 2), a tree per class, and a source queries each class within
//! `(e_i + max e of the class) / 2`: every pair the whole ball held and touching passes is
//! found, so the edges are the same (the far-pair search is exact whatever region its
//! breadth-first pass covers, see [`super::virtual_edges::FarPairs`]).

use super::virtual_edges::{distance, spatial_order, EdgeGraph, FarPairs, PieceTrees, VirtualEdgeParams};
use crate::geometry::topology::Adjacency;

/// The template's side of the search for each key's contacts, computed once.
pub(super) struct KeyContactSearch {
    params: VirtualEdgeParams,
    adjacency: Adjacency,
    /// Vertices resting in contact, which take no contact.
    resting: Vec<bool>,
    /// Connected pieces of the template.
    labels: Vec<u32>,
    n_pieces: usize,
    /// `tau_d` times the template's bbox diagonal.
    radius: f64,
    /// Per vertex, the mean rest length of its one-ring edges (`e_i`).
    edge: Vec<f64>,
    /// Per vertex, its class of `e` ([`edge_classes`]); per class, its largest `e`.
    class: Vec<usize>,
    class_max: Vec<f64>,
}

impl KeyContactSearch {
    /// `neutral`: the template at rest; `resting`: its vertices resting in contact
    /// ([`resting_in_contact`]); `labels`: its connected pieces; `diagonal`: its bbox diagonal.
    pub(super) fn new(neutral: &[[f64; 3]], adjacency: Adjacency, resting: Vec<bool>, labels: &[u32], diagonal: f64, params: VirtualEdgeParams) -> Self {
        let n = neutral.len();
        let edge: Vec<f64> = (0..n)
            .map(|v| {
                let ring = adjacency.neighbours(v);
                ring.iter().map(|&u| distance(&neutral[v], &neutral[u as usize])).sum::<f64>() / ring.len().max(1) as f64
            })
            .collect();
        let (class, class_max) = edge_classes(&edge);
        Self {
            params,
            adjacency,
            resting,
            labels: labels.to_vec(),
            n_pieces: labels.iter().map(|&l| l as usize + 1).max().unwrap_or(0),
            radius: params.tau_d * diagonal,
            edge,
            class,
            class_max,
        }
    }

    /// The pairs of one piece that the template's key `delta` brings within `tau_d` from
    /// beyond it at rest, to at most half their rest distance, kept when far along the
    /// surface in the key's pose (`g_ij > tau_r d_ij`, both measured on the posed template),
    /// thinned as at rest: the upper and lower lid margins of a blink. Touching: within the
    /// rest mesh's edge length around the pair's ends. Halving leaves out pairs that merely
    /// slide past `tau_d`: their spring would hold nearly the rest vector (`rho > 1/4`), which
    /// the gradients give them anyway. It also bounds the search: such a pair's ends move
    /// apart by more than `tau_d / 2`, so one end moves by more than `tau_d / 4`, and only
    /// those vertices are searched from. Vertices resting in contact (lips touching at rest)
    /// take no contact: such surfaces slide along each other in jaw or roll keys, and a spring
    /// there pins one vertex to another where the target's lips need not match vertex for
    /// vertex.
    pub(super) fn edges(&self, neutral: &[[f64; 3]], delta: &[[f32; 3]]) -> Vec<(u32, u32)> {
        let (radius, resting, edge) = (self.radius, &self.resting, &self.edge);
        let reach = 0.25 * radius;
        let source: Vec<bool> =
            delta.iter().zip(resting).map(|(d, &rests)| !rests && d.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>() > reach * reach).collect();
        let sources: Vec<usize> = (0..neutral.len()).filter(|&v| source[v]).collect();
        if sources.is_empty() || radius <= 0.0 {
            return Vec::new();
        }
        // Posed in single precision, as the rest search measures a neutral as given.
        let posed32: Vec<[f32; 3]> = neutral.iter().zip(delta).map(|(p, d)| [0, 1, 2].map(|a| (p[a] + f64::from(d[a])) as f32)).collect();
        let posed: Vec<[f64; 3]> = posed32.iter().map(|p| p.map(f64::from)).collect();
        // Partners lie within `radius` of a source's posed place and rest in no contact.
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for &v in &sources {
            for a in 0..3 {
                lo[a] = lo[a].min(posed[v][a] - radius);
                hi[a] = hi[a].max(posed[v][a] + radius);
            }
        }
        let near: Vec<usize> = (0..neutral.len()).filter(|&v| !resting[v] && (0..3).all(|a| posed[v][a] >= lo[a] && posed[v][a] <= hi[a])).collect();
        let mut members = vec![Vec::new(); self.class_max.len()];
        for &v in &near {
            members[self.class[v]].push(v);
        }
        let trees: Vec<(PieceTrees, f64)> = members
            .iter()
            .zip(&self.class_max)
            .filter(|(members, _)| !members.is_empty())
            .map(|(members, &widest)| (PieceTrees::new(&posed32, &self.labels, self.n_pieces, members.iter().copied()), widest))
            .collect();
        // A partner `j` of class `c` touches `i` only within `(e_i + e_j) / 2 <= (e_i +
        // class_max[c]) / 2`; the margin covers the rounding of the tree's distances.
        let ball = |i: usize, ball: &mut Vec<(usize, f64)>| {
            for (tree, widest) in &trees {
                let within = radius.min(0.5 * (edge[i] + widest) * (1.0 + 1e-9));
                ball.extend(tree.within(self.labels[i], posed[i], within).filter(|&(j, d)| j != i && d < radius));
            }
        };
        let graph = EdgeGraph::measured(&posed, &self.adjacency);
        let search = FarPairs { points: &posed, labels: &self.labels, graph: &graph, params: &self.params };
        let source_points: Vec<[f64; 3]> = sources.iter().map(|&v| posed[v]).collect();
        let order: Vec<u32> = spatial_order(&source_points).into_iter().map(|k| sources[k as usize] as u32).collect();
        // Each pair once (from its lower end when both are sources), apart at rest, halved, and
        // touching.
        let brought_together = |i: usize, j: usize| {
            let (rest, posed) = (distance(&neutral[i], &neutral[j]), distance(&posed[i], &posed[j]));
            (j > i || !source[j]) && !resting[j] && rest >= radius && 2.0 * posed <= rest && 2.0 * posed <= edge[i] + edge[j]
        };
        search.thinned(order, ball, brought_together, false)
    }
}

/// Vertices resting in contact: the ends of the rest virtual edges `rest_edges` and their
/// one-rings.
pub(super) fn resting_in_contact(adjacency: &Adjacency, rest_edges: &[(u32, u32)]) -> Vec<bool> {
    let mut resting = vec![false; adjacency.offsets.len() - 1];
    for &(i, j) in rest_edges {
        for end in [i, j] {
            resting[end as usize] = true;
            for &v in adjacency.neighbours(end as usize) {
                resting[v as usize] = true;
            }
        }
    }
    resting
}

/// Per vertex, its class of `e`: `floor(log2(e / e_min))` over the positive `e` (class 0 for
/// `e = 0`, a vertex in no triangle), so that within a class `e` varies by less than a factor
/// 2; and per class, its largest `e`.
fn edge_classes(edge: &[f64]) -> (Vec<usize>, Vec<f64>) {
    let least = edge.iter().copied().filter(|&e| e > 0.0).fold(f64::INFINITY, f64::min);
    let class: Vec<usize> = edge.iter().map(|&e| if e > 0.0 { (e / least).log2().floor().max(0.0) as usize } else { 0 }).collect();
    let mut class_max = vec![0.0f64; class.iter().map(|&c| c + 1).max().unwrap_or(0)];
    for (&c, &e) in class.iter().zip(edge) {
        class_max[c] = class_max[c].max(e);
    }
    (class, class_max)
}
