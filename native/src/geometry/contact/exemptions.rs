//! Which pairs a shape may leave crossing, and how close the rest may come (method, section 3).
//!
//! A shape may keep the crossings its target's neutral has (skin resting through the teeth)
//! and those its template's shape makes that the template's neutral does not (the artist's:
//! lips rolled through each other), each by triangle index. Skin resting through the teeth
//! slides over them in a shape, onto triangles next to those it crossed: a pair of triangles
//! may cross when each lies within one ring (shares a corner with) a pair that crossed.
//!
//! The barrier must agree with that. A point-triangle or edge-edge pair is exempt when a
//! triangle holding its first primitive and one holding its second crossed; a pair of
//! triangles that newly crosses first touches through one of its primitive pairs, each of
//! whose holders lies within one ring of the two triangles, so every crossing the barrier
//! lets happen is one the triangle rule allows. Pairs close in the template's shape keep a
//! barrier that starts below half the template's distance: pressed lips may press as close.

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
    fn around(&self, t: u32) -> Vec<u32> {
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
/// shape) and the template's pose its pressed pairs are read in.
#[derive(Clone)]
pub struct Exemptions {
    topology: Arc<Topology>,
    rest: Arc<Crossed>,
    shape: Crossed,
    template: Option<TemplatePose>,
}

impl Exemptions {
    pub fn new(topology: Arc<Topology>, rest: Arc<Crossed>, shape: Crossed, template: Option<TemplatePose>) -> Self {
        Self { topology, rest, shape, template }
    }

    fn crossed(&self, a: u32, b: u32) -> bool {
        self.rest.partners(a).contains(&b) || self.shape.partners(a).contains(&b)
    }

    /// Whether triangles `a` and `b` may cross: each within one ring of a pair that crossed.
    pub fn triangles(&self, a: u32, b: u32) -> bool {
        let near_b = self.topology.around(b);
        self.topology.around(a).into_iter().any(|x| {
            self.rest.partners(x).iter().chain(self.shape.partners(x)).any(|y| near_b.binary_search(y).is_ok())
        })
    }

    /// Whether the primitives `first` and `second` (vertex lists) may touch or cross: a
    /// triangle holding each crossed.
    pub fn primitives(&self, first: &[u32], second: &[u32]) -> bool {
        if self.rest.is_empty() && self.shape.is_empty() {
            return false;
        }
        self.topology.holding(first).any(|x| self.topology.holding(second).any(|y| self.crossed(x, y)))
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
