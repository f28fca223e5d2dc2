//! The conflict graph of paper 000's Eq. (3), built once per packing: which shapes cannot
//! share an expression, which must, and the cliques that become the program's rows.
//!
//! The vertex rows $\sum_k b_{k,n} w_k \le 1$ say that no two shapes active at one vertex are
//! both posed, so they are equivalent to one edge per pair of intersecting active sets. The
//! symmetry rows $w_x = w_p$ (Eq. (3d)) and the user's pins merge shapes into one *node*, and
//! a partner's overlap with its own partner is no conflict (paper fig. 2). Antagonists,
//! collisions, occlusions (method, section 1, poseable and observable) and the user's
//! `keep_apart` add edges, and each edge keeps its reasons for the report. The program then
//! needs one row per clique of a cover of the node graph's edges: the number of vertices N
//! drops out.

use crate::error::{ShapesmithError, ShapesmithResult};
use crate::invalid;

/// What the graph is built from, all as shape indices.
pub struct ShapeRelations<'a> {
    /// `overlap[i][j]`: the binary blendshapes (Eq. (2)) of placeable shapes i and j share a
    /// vertex ([`overlapping`]).
    pub overlap: &'a [Vec<bool>],
    /// Shapes that take part in the packing (not inert, not excluded).
    pub placeable: &'a [bool],
    /// Symmetric pairs proposed to be posed together (Eq. (3d)).
    pub pairs: &'a [(usize, usize)],
    /// Shapes that can never be posed together (mirror and cosine antagonists).
    pub antagonists: &'a [(usize, usize)],
    /// Shapes whose mix adds intersection curve ([`super::collisions`]).
    pub collisions: &'a [(usize, usize)],
    /// Shapes one of which hides the other's motion ([`super::occlusion`]).
    pub occlusions: &'a [(usize, usize)],
    pub pin_together: &'a [(usize, usize)],
    pub keep_apart: &'a [(usize, usize)],
    pub names: &'a [String],
}

/// Why two shapes may not share an expression, most binding first.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum ConflictReason {
    /// The user's `keep_apart`.
    User,
    /// Their motions oppose each other (mirror or cosine antagonists).
    Antagonist,
    /// Their strongly moving regions share a vertex (Eq. (3b)).
    Overlap,
    /// Posed together they pass through each other.
    Collision,
    /// Posed together one hides the other's motion from the camera.
    Occlusion,
}

impl ConflictReason {
    pub const ALL: [ConflictReason; 5] = [Self::User, Self::Antagonist, Self::Overlap, Self::Collision, Self::Occlusion];

    fn bit(self) -> u8 {
        1 << self as u8
    }

    /// Why a pinned pair cannot be posed, for the error message.
    fn because(self) -> &'static str {
        match self {
            Self::User => "you asked to keep them apart",
            Self::Antagonist => "they are antagonists (their motions oppose each other)",
            Self::Overlap => "their active regions overlap",
            Self::Collision => "posed together they pass through each other",
            Self::Occlusion => "posed together one hides the other from the camera",
        }
    }
}

/// A conflict edge between two shapes of different nodes, with every reason it has.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct ShapeConflict {
    pub first: usize,
    pub second: usize,
    pub reasons: Vec<ConflictReason>,
}

/// Nodes (sets of shapes posed together) and the conflicts between them.
#[derive(Clone, Debug)]
pub struct ConflictGraph {
    /// The shapes of each node, sorted; nodes ordered by their first shape.
    pub nodes: Vec<Vec<usize>>,
    /// `adjacent[u][v]`: nodes u and v cannot share an expression.
    pub adjacent: Vec<Vec<bool>>,
    /// Cliques of the node graph covering every edge; each is one `<= 1` row.
    pub cliques: Vec<Vec<usize>>,
    /// The symmetric pairs kept (both placeable, and no reason but overlap to keep them
    /// apart).
    pub pairs: Vec<(usize, usize)>,
    /// Every conflict between shapes of different nodes, `first < second`, in order.
    pub conflicts: Vec<ShapeConflict>,
}

impl ConflictGraph {
    pub fn build(rel: &ShapeRelations) -> ShapesmithResult<Self> {
        let k_count = rel.placeable.len();
        let reasons = shape_conflicts(rel);
        let conflict = |i: usize, j: usize| reasons[i][j] != 0;
        // A partner's overlap is no conflict (paper fig. 2); any other reason dissolves the pair.
        let pairs: Vec<(usize, usize)> = rel
            .pairs
            .iter()
            .copied()
            .filter(|&(i, j)| rel.placeable[i] && rel.placeable[j] && reasons[i][j] & !ConflictReason::Overlap.bit() == 0)
            .collect();
        let mut partner = vec![None; k_count];
        for &(i, j) in &pairs {
            partner[i] = Some(j);
            partner[j] = Some(i);
        }

        let mut groups = UnionFind::new(k_count);
        for &(i, j) in pairs.iter().chain(rel.pin_together) {
            groups.join(i, j);
        }
        let mut node_of = vec![usize::MAX; k_count];
        let mut nodes: Vec<Vec<usize>> = Vec::new();
        for k in (0..k_count).filter(|&k| rel.placeable[k]) {
            let root = groups.root(k);
            if node_of[root] == usize::MAX {
                node_of[root] = nodes.len();
                nodes.push(Vec::new());
            }
            node_of[k] = node_of[root];
            nodes[node_of[k]].push(k);
        }

        for members in &nodes {
            for (a, &i) in members.iter().enumerate() {
                for &j in &members[a + 1..] {
                    if conflict(i, j) && partner[i] != Some(j) {
                        let first = ConflictReason::ALL.into_iter().find(|r| reasons[i][j] & r.bit() != 0);
                        let why = first.map_or("", ConflictReason::because);
                        return Err(ShapesmithError::Infeasible(format!(
                            "'{}' and '{}' are pinned together (directly or through a symmetric partner) but {why}; remove that pin",
                            rel.names[i], rel.names[j]
                        )));
                    }
                }
            }
        }

        let mut adjacent = vec![vec![false; nodes.len()]; nodes.len()];
        let mut conflicts = Vec::new();
        for i in 0..k_count {
            for j in i + 1..k_count {
                let (u, v) = (node_of[i], node_of[j]);
                if conflict(i, j) && u != v {
                    adjacent[u][v] = true;
                    adjacent[v][u] = true;
                    let why = ConflictReason::ALL.into_iter().filter(|r| reasons[i][j] & r.bit() != 0).collect();
                    conflicts.push(ShapeConflict { first: i, second: j, reasons: why });
                }
            }
        }
        let cliques = clique_cover(&adjacent);
        Ok(Self { nodes, adjacent, cliques, pairs, conflicts })
    }

    pub fn n_nodes(&self) -> usize {
        self.nodes.len()
    }
}

/// Checks that a list of shape pairs names existing, distinct shapes; `what` names the list
/// in the error.
pub fn validate_shape_pairs(list: &[(usize, usize)], k_count: usize, names: &[String], what: &str) -> ShapesmithResult<()> {
    for &(i, j) in list {
        if i >= k_count || j >= k_count {
            return Err(invalid!("{what}: shape index {} is out of range (the rig has {k_count} shapes)", i.max(j)));
        }
        if i == j {
            return Err(invalid!("{what}: '{}' is paired with itself", names[i]));
        }
    }
    Ok(())
}

/// `overlap[i][j]` for placeable shapes: their binary blendshapes share a vertex. Found
/// through the shapes active at each vertex, so the cost is the sum over vertices of the
/// squared number of shapes active there.
pub fn overlapping(active: &[Vec<u32>], placeable: &[bool], n_vertices: usize) -> Vec<Vec<bool>> {
    let k_count = placeable.len();
    let mut overlap = vec![vec![false; k_count]; k_count];
    let mut at_vertex: Vec<Vec<usize>> = vec![Vec::new(); n_vertices];
    for k in (0..k_count).filter(|&k| placeable[k]) {
        for &n in &active[k] {
            at_vertex[n as usize].push(k);
        }
    }
    for shapes in &at_vertex {
        for (a, &i) in shapes.iter().enumerate() {
            for &j in &shapes[a + 1..] {
                overlap[i][j] = true;
                overlap[j][i] = true;
            }
        }
    }
    overlap
}

/// For placeable shapes, the [`ConflictReason`] bits of each pair (0: no conflict).
fn shape_conflicts(rel: &ShapeRelations) -> Vec<Vec<u8>> {
    let k_count = rel.placeable.len();
    let mut reasons = vec![vec![0u8; k_count]; k_count];
    for i in 0..k_count {
        for j in 0..k_count {
            if rel.overlap[i][j] {
                reasons[i][j] |= ConflictReason::Overlap.bit();
            }
        }
    }
    let lists = [
        (rel.keep_apart, ConflictReason::User),
        (rel.antagonists, ConflictReason::Antagonist),
        (rel.collisions, ConflictReason::Collision),
        (rel.occlusions, ConflictReason::Occlusion),
    ];
    for (list, reason) in lists {
        for &(i, j) in list {
            if rel.placeable[i] && rel.placeable[j] {
                reasons[i][j] |= reason.bit();
                reasons[j][i] |= reason.bit();
            }
        }
    }
    reasons
}

/// Greedy edge clique cover: every uncovered edge grows into a maximal clique (neighbours
/// with the most uncovered edges into it first). Each clique is a valid `<= 1` row and every
/// edge lies in one, so the rows say exactly "no two adjacent nodes", with far fewer rows
/// than one per edge on a face rig, where the mouth shapes form large cliques.
fn clique_cover(adjacent: &[Vec<bool>]) -> Vec<Vec<usize>> {
    let n = adjacent.len();
    let mut covered = vec![vec![false; n]; n];
    let mut cliques = Vec::new();
    for u in 0..n {
        for v in u + 1..n {
            if !adjacent[u][v] || covered[u][v] {
                continue;
            }
            let mut clique = vec![u, v];
            loop {
                let best = (0..n)
                    .filter(|w| !clique.contains(w) && clique.iter().all(|&c| adjacent[*w][c]))
                    .max_by_key(|&w| (clique.iter().filter(|&&c| !covered[w][c]).count(), std::cmp::Reverse(w)));
                match best {
                    Some(w) => clique.push(w),
                    None => break,
                }
            }
            for &a in &clique {
                for &b in &clique {
                    covered[a][b] = true;
                }
            }
            clique.sort_unstable();
            cliques.push(clique);
        }
    }
    cliques
}

struct UnionFind {
    parent: Vec<usize>,
}

impl UnionFind {
    fn new(n: usize) -> Self {
        Self { parent: (0..n).collect() }
    }

    fn root(&mut self, mut k: usize) -> usize {
        while self.parent[k] != k {
            self.parent[k] = self.parent[self.parent[k]];
            k = self.parent[k];
        }
        k
    }

    fn join(&mut self, a: usize, b: usize) {
        let (ra, rb) = (self.root(a), self.root(b));
        self.parent[ra.max(rb)] = ra.min(rb);
    }
}

#[cfg(test)]
#[allow(clippy::needless_range_loop)] // adjacency matrices read best indexed
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn clique_cover_covers_every_edge_with_cliques() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        for _ in 0..50 {
            let n = rng.random_range(1..14);
            let mut adjacent = vec![vec![false; n]; n];
            for u in 0..n {
                for v in u + 1..n {
                    let e = rng.random_bool(0.4);
                    adjacent[u][v] = e;
                    adjacent[v][u] = e;
                }
            }
            let cliques = clique_cover(&adjacent);
            for q in &cliques {
                for &a in q {
                    for &b in q {
                        assert!(a == b || adjacent[a][b], "{q:?} is not a clique");
                    }
                }
            }
            for u in 0..n {
                for v in u + 1..n {
                    if adjacent[u][v] {
                        assert!(cliques.iter().any(|q| q.contains(&u) && q.contains(&v)), "edge {u}-{v} uncovered");
                    }
                }
            }
        }
    }

    #[test]
    fn partners_merge_and_their_overlap_is_no_conflict() {
        let active = vec![vec![0, 1], vec![1, 2], vec![2, 3], vec![7]];
        let names: Vec<String> = ["a", "b", "c", "d"].map(String::from).to_vec();
        let placeable = [true; 4];
        let overlap = overlapping(&active, &placeable, 8);
        let rel = ShapeRelations {
            overlap: &overlap,
            placeable: &placeable,
            pairs: &[(0, 1)],
            antagonists: &[],
            collisions: &[],
            occlusions: &[],
            pin_together: &[],
            keep_apart: &[(2, 3)],
            names: &names,
        };
        let g = ConflictGraph::build(&rel).unwrap();
        assert_eq!(g.nodes, vec![vec![0, 1], vec![2], vec![3]]);
        assert!(g.adjacent[0][1] && g.adjacent[1][2] && !g.adjacent[0][2]);
        assert_eq!(g.pairs, vec![(0, 1)]);
        let reasons: Vec<_> = g.conflicts.iter().map(|c| (c.first, c.second, c.reasons.clone())).collect();
        assert_eq!(
            reasons,
            vec![(1, 2, vec![ConflictReason::Overlap]), (2, 3, vec![ConflictReason::User])]
        );

        // A pair that is also kept apart, or antagonist, is no pair.
        let rel = ShapeRelations { keep_apart: &[(1, 0)], ..rel };
        assert!(ConflictGraph::build(&rel).unwrap().pairs.is_empty());
        let rel = ShapeRelations { keep_apart: &[], antagonists: &[(0, 1)], ..rel };
        let g = ConflictGraph::build(&rel).unwrap();
        assert!(g.pairs.is_empty() && g.adjacent[0][1]);

        // Pinning b to c, which overlaps b, is infeasible and names both.
        let rel = ShapeRelations { antagonists: &[], pin_together: &[(1, 2)], ..rel };
        let err = ConflictGraph::build(&rel).unwrap_err();
        assert!(matches!(&err, ShapesmithError::Infeasible(m) if m.contains("'b' and 'c'")), "{err}");

        // A collision or an occlusion between partners dissolves the pair and is an edge;
        // pinning colliding shapes names the collision.
        let rel = ShapeRelations { pin_together: &[], collisions: &[(0, 1)], ..rel };
        let g = ConflictGraph::build(&rel).unwrap();
        assert!(g.pairs.is_empty() && g.adjacent[0][1]);
        assert_eq!(g.conflicts[0].reasons, vec![ConflictReason::Overlap, ConflictReason::Collision]);
        let rel = ShapeRelations { collisions: &[], occlusions: &[(0, 3)], pin_together: &[(0, 3)], pairs: &[], ..rel };
        let err = ConflictGraph::build(&rel).unwrap_err();
        assert!(matches!(&err, ShapesmithError::Infeasible(m) if m.contains("hides")), "{err}");
    }
}
