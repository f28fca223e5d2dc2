//! Which pairs a shape may leave crossing, and how close the rest may come (method, section 3).
//!
//! A shape may keep the crossings its target's neutral has (skin resting through the teeth)
//! and those its template's shape makes that the template's neutral does not (the artist's:
//! lips rolled through each other), each by triangle index. Skin resting through the teeth
//! slides over them in a shape, onto triangles next to those it crossed: a pair of triangles
//! may cross when each lies within one ring (shares a corner with) a pair that crossed at
//! rest. The criterion counts curve per part (inside one piece, between two): a crossing of the
//! template's shape widens so only in a part whose curve the shape grows; where it does not, the
//! template only slid its own crossings, and the target may cross exactly where it does.
//!
//! The barrier must agree with that. A point-triangle or edge-edge pair carries no barrier
//! when a triangle holding each primitive crossed at rest or in a widened part, or when every
//! two triangles holding them (sharing no vertex) crossed; a pair of triangles that newly
//! crosses first touches through one of its primitive pairs, whose holders include the two
//! triangles and lie within one ring of them, so every crossing the barrier lets happen is one
//! the triangle rule allows. Pairs close in the template's shape keep a barrier that starts
//! below half the template's distance: pressed lips may press as close.

use std::collections::HashMap;
use std::sync::Arc;

use super::barrier::{pair_squared, PairKind};
use crate::geometry::topology::VertexTriangles;

/// A mesh's triangles and the triangles at each vertex.
pub struct Topology {
    pub triangles: Vec<[u32; 3]>,
    pub at_vertex: VertexTriangles,
}

impl Topology {
    pub fn new(n_vertices: usize, triangles: &[[u32; 3]]) -> Self {
        Self { triangles: triangles.to_vec(), at_vertex: VertexTriangles::new(n_vertices, triangles) }
    }

    /// The triangles holding every vertex of `primitive` (a vertex, an edge or a triangle).
    fn holding<'a>(&'a self, primitive: &'a [u32]) -> impl Iterator<Item = u32> + 'a {
        let first = self.at_vertex.of(primitive[0] as usize);
        first.iter().copied().filter(move |&t| primitive[1..].iter().all(|v| self.triangles[t as usize].contains(v)))
    }

    /// Triangle `t` and the triangles sharing a corner with it.
    pub(super) fn around(&self, t: u32) -> Vec<u32> {
        let mut near: Vec<u32> = self.triangles[t as usize].iter().flat_map(|&v| self.at_vertex.of(v as usize).iter().copied()).collect();
        near.sort_unstable();
        near.dedup();
        near
    }
}

/// Pairs of triangles that crossed, as each triangle's partners.
#[derive(Clone, Debug, Default)]
pub struct Crossed(HashMap<u32, Vec<u32>>);

impl Crossed {
    pub fn from_pairs(pairs: impl IntoIterator<Item = (u32, u32)>) -> Self {
        let mut partners: HashMap<u32, Vec<u32>> = HashMap::new();
        for (a, b) in pairs {
            partners.entry(a).or_default().push(b);
            partners.entry(b).or_default().push(a);
        }
        Self(partners)
    }

    fn partners(&self, t: u32) -> &[u32] {
        self.0.get(&t).map_or(&[], Vec::as_slice)
    }

    /// Whether triangles `a` and `b` crossed.
    pub fn contains(&self, a: u32, b: u32) -> bool {
        self.partners(a).contains(&b)
    }

    pub fn len(&self) -> usize {
        self.0.values().map(Vec::len).sum::<usize>() / 2
    }

    pub fn is_empty(&self) -> bool {
        self.0.is_empty()
    }
}

/// The template's shape on the same vertices, its lengths times `scale` in the target's units.
#[derive(Clone, Debug)]
pub struct TemplatePose {
    pub positions: Vec<[f64; 3]>,
    pub scale: f64,
}

/// What one shape may leave crossing ([`Crossed`] at the neutral's rest and in the template's
/// shape, and the template's crossings in the parts whose curve it grows) and the template's
/// pose its pressed pairs are read in.
#[derive(Clone)]
pub struct Exemptions {
    topology: Arc<Topology>,
    rest: Arc<Crossed>,
    shape: Crossed,
    widened: Crossed,
    template: Option<TemplatePose>,
}

impl Exemptions {
    /// `widened`: the pairs of `shape` that license their ring.
    pub fn new(topology: Arc<Topology>, rest: Arc<Crossed>, shape: Crossed, widened: Crossed, template: Option<TemplatePose>) -> Self {
        Self { topology, rest, shape, widened, template }
    }

    /// Whether triangles `a` and `b` crossed at rest or in the template's shape.
    fn crossed(&self, a: u32, b: u32) -> bool {
        self.rest.contains(a, b) || self.shape.contains(a, b)
    }

    /// Whether triangles `a` and `b` may cross: they crossed, or each lies within one ring of a
    /// pair that crossed at rest or a widened one.
    pub fn triangles(&self, a: u32, b: u32) -> bool {
        if self.crossed(a, b) {
            return true;
        }
        let near_b = self.topology.around(b);
        self.topology.around(a).into_iter().any(|x| self.widens(x).any(|y| near_b.binary_search(&y).is_ok()))
    }

    /// The partners of `t` that license their ring: crossed at rest or widened.
    fn widens(&self, t: u32) -> impl Iterator<Item = u32> + '_ {
        self.rest.partners(t).iter().chain(self.widened.partners(t)).copied()
    }

    /// Whether the primitives `first` and `second` (vertex lists) may touch or cross: a
    /// triangle holding each crossed at rest or in a widened part, or every two holding them
    /// that share no vertex crossed.
    pub fn primitives(&self, first: &[u32], second: &[u32]) -> bool {
        if self.rest.is_empty() && self.shape.is_empty() {
            return false;
        }
        if self.topology.holding(first).any(|x| self.topology.holding(second).any(|y| self.widens(x).any(|z| z == y))) {
            return true;
        }
        let corners = |t: u32| self.topology.triangles[t as usize];
        let mut holders = 0;
        for x in self.topology.holding(first) {
            for y in self.topology.holding(second).filter(|&y| !corners(x).iter().any(|v| corners(y).contains(v))) {
                if !self.crossed(x, y) {
                    return false;
                }
                holders += 1;
            }
        }
        holders > 0
    }

    /// The squared distance of the pair `vertices` (of `kind`) in the template's shape, in the
    /// target's units.
    pub fn template_squared(&self, kind: PairKind, vertices: [u32; 4]) -> Option<f64> {
        let pose = self.template.as_ref()?;
        Some(pair_squared(kind, &vertices.map(|v| pose.positions[v as usize])) * pose.scale * pose.scale)
    }

    /// Pairs of triangles exempt by the shape (not counting the neutral's).
    pub fn shape_pairs(&self) -> usize {
        self.shape.len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::topology::grid_triangles;

    /// Two 4 x 4 sheets; the template's shape crosses triangle 8 of the first with triangle 26
    /// of the second. Unwidened (its part's curve did not grow) only that pair may cross, and a
    /// corner of 8 may not touch 26 (the other triangles at the corner did not cross it);
    /// widened, the next triangle over may cross too, and the corner touch.
    #[test]
    fn a_template_crossing_widens_only_where_its_part_grows() {
        let mut triangles = grid_triangles(4, 4, 0);
        triangles.extend(grid_triangles(4, 4, 16));
        let topology = Arc::new(Topology::new(32, &triangles));
        let (a, b) = (8u32, 26u32);
        let neighbour = (0..18u32).find(|&t| t != a && triangles[t as usize].iter().filter(|v| triangles[a as usize].contains(v)).count() == 2).unwrap();
        let corner = [triangles[a as usize][0]];
        let exempt = |widened: bool| {
            let pairs = || Crossed::from_pairs([(a, b)]);
            Exemptions::new(topology.clone(), Arc::new(Crossed::default()), pairs(), if widened { pairs() } else { Crossed::default() }, None)
        };
        let (exact, wide) = (exempt(false), exempt(true));
        assert!(exact.triangles(a, b) && wide.triangles(a, b));
        assert!(!exact.triangles(neighbour, b) && wide.triangles(neighbour, b));
        assert!(!exact.primitives(&corner, &triangles[b as usize]) && wide.primitives(&corner, &triangles[b as usize]));
        // The crossed pair itself, each triangle its only holder: exempt.
        assert!(exact.primitives(&triangles[a as usize], &triangles[b as usize]));
    }
}
