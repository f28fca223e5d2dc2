//! What the collision pass needs of the two neutrals, computed once per transfer: their
//! hierarchies, the pairs crossing at rest, the pieces and the mesh's rings
//! ([`CollisionGuard`]), and the closest point of a static piece's surface.

use std::collections::{HashMap, HashSet};
use std::sync::{Mutex, OnceLock};

use super::CollisionParams;
use crate::geometry::bvh::{RefitLinks, TriangleBvh};
use crate::geometry::closest_point::SurfacePoint;
use crate::geometry::penetration::{crossings, shape_penetration, triangle_pieces, Penetration};
use crate::geometry::topology::{Adjacency, VertexTriangles};
use crate::transfer::deformation::DeformationTransfer;
use crate::transfer::gradients::Vec3;

/// What the pass needs of the two neutrals, computed once per transfer.
pub(in crate::transfer) struct CollisionGuard {
    pub(super) params: CollisionParams,
    /// Pairs `(a, b)`, `a < b`, crossing at the target's rest, sorted, with their lengths,
    /// swept on the written positions (the target's own frame and precision, as the report
    /// measures them).
    pub(super) rest_pairs: Vec<(u32, u32)>,
    pub(super) rest_lengths: Vec<f64>,
    /// The same on the template's neutral.
    pub(super) template_rest_pairs: Vec<(u32, u32, f64)>,
    /// Over the target neutral: refitted to each result, and the static obstacles' surface.
    pub(super) bvh: TriangleBvh,
    /// Where `bvh`'s triangles and nodes sit, for refitting a few of them in place.
    pub(super) refit_links: RefitLinks,
    /// Over the template neutral, refitted to each template shape that needs it.
    pub(super) template_bvh: TriangleBvh,
    /// Per vertex, the mean length of its edges on the target neutral.
    pub(super) edge_length: Vec<f64>,
    /// The target neutral's bounding-box diagonal.
    pub(super) diagonal: f64,
    /// The target neutral as given (its own frame, f32): results are swept where they are
    /// written, `written_neutral + delta` in f32, so the report can take the pass's numbers.
    written_neutral: Vec<[f32; 3]>,
    /// The connected piece of each triangle, and the target neutral's own penetration.
    pub(super) triangle_piece: Vec<u32>,
    pub(in crate::transfer) rest_penetration: Penetration,
    pub(super) adjacency: Adjacency,
    /// Triangles around each vertex.
    rings: VertexTriangles,
    /// Per triangle, itself and the triangles sharing a corner with it (compressed rows,
    /// each sorted).
    around_offsets: Vec<usize>,
    around_triangles: Vec<u32>,
    /// Per neutral (`bvh`, `template_bvh`) and piece, which nodes hold one of the piece's
    /// triangles, made on the first query against that piece
    /// ([`CollisionGuard::closest_on_piece`]).
    piece_nodes: [Vec<OnceLock<Vec<bool>>>; 2],
    /// Per neutral, the side of a static piece each vertex rests on (`(vertex, piece)` ->
    /// its height over the piece's surface, [`CollisionGuard::rest_side`]): the same for every
    /// shape, round and attempt that asks, so each is found once per transfer.
    rest_sides: [SideMemo; 2],
    /// The (triangle, piece) pairs crossing at the target's rest, made on first use.
    embedded: OnceLock<HashSet<(u32, u32)>>,
    /// The triangles of pairs crossing inside one piece at the template's rest, when asked.
    template_resting: OnceLock<HashSet<u32>>,
}

/// Which of the two neutrals a query reads.
#[derive(Clone, Copy)]
pub(super) enum Neutral {
    Target = 0,
    Template = 1,
}

impl CollisionGuard {
    /// `neutral` is the target's neutral in the working frame, `written_neutral` as given.
    pub(in crate::transfer) fn new(
        source: &[Vec3],
        neutral: &[Vec3],
        written_neutral: &[[f32; 3]],
        triangles: &[[u32; 3]],
        params: CollisionParams,
    ) -> Self {
        let n = neutral.len();
        let (bvh, template_bvh) = (TriangleBvh::build(neutral, triangles), TriangleBvh::build(source, triangles));
        let written: Vec<Vec3> = written_neutral.iter().map(|p| p.map(f64::from)).collect();
        let rest = crossings(&written, triangles, &bvh.refitted(&written, triangles), None);
        let triangle_piece = triangle_pieces(n, triangles);
        let rest_penetration = shape_penetration(&[], &rest, &vec![false; triangles.len()], &triangle_piece);
        let (rest_pairs, rest_lengths) = rest.into_iter().map(|(a, b, l)| ((a, b), l)).unzip();
        let template_rest_pairs = crossings(source, triangles, &template_bvh, None);
        let adjacency = Adjacency::from_triangles(n, triangles);
        let edge_length = adjacency.mean_edge_lengths(neutral);
        let rings = VertexTriangles::new(n, triangles);
        // Per triangle, itself and the triangles sharing a corner with it, sorted: the
        // template-contact test reads them for every pair that crosses in every round.
        let mut around_offsets = Vec::with_capacity(triangles.len() + 1);
        around_offsets.push(0);
        let mut around_triangles = Vec::with_capacity(13 * triangles.len());
        let mut near = Vec::new();
        for tri in triangles {
            near.clear();
            near.extend(tri.iter().flat_map(|&v| rings.of(v as usize).iter().copied()));
            near.sort_unstable();
            near.dedup();
            around_triangles.extend_from_slice(&near);
            around_offsets.push(around_triangles.len());
        }
        let diagonal = crate::rig::bbox_diagonal(&neutral.iter().map(|p| p.map(|x| x as f32)).collect::<Vec<_>>());
        let n_pieces = triangle_piece.iter().max().map_or(0, |&p| p as usize + 1);
        Self {
            piece_nodes: [0, 1].map(|_| (0..n_pieces).map(|_| OnceLock::new()).collect()),
            rest_sides: [SideMemo::default(), SideMemo::default()],
            embedded: OnceLock::new(),
            template_resting: OnceLock::new(),
            params,
            diagonal,
            written_neutral: written_neutral.to_vec(),
            triangle_piece,
            rest_penetration,
            rest_pairs,
            rest_lengths,
            template_rest_pairs,
            refit_links: bvh.refit_links(),
            bvh,
            template_bvh,
            edge_length,
            adjacency,
            rings,
            around_offsets,
            around_triangles,
        }
    }

    pub(super) fn triangles_at(&self, v: u32) -> &[u32] {
        self.rings.of(v as usize)
    }

    /// Triangle `t` and the triangles sharing a corner with it, sorted.
    pub(super) fn around(&self, t: u32) -> &[u32] {
        &self.around_triangles[self.around_offsets[t as usize]..self.around_offsets[t as usize + 1]]
    }

    /// The point of piece `piece`'s surface on `neutral` closest to `query`: the hierarchy's
    /// query among that piece's triangles, never entering a subtree without one (the same
    /// point to the bit as filtering the whole hierarchy's triangles).
    pub(super) fn closest_on_piece(&self, neutral: Neutral, query: &Vec3, piece: u32) -> Option<SurfacePoint> {
        let bvh = match neutral {
            Neutral::Target => &self.bvh,
            Neutral::Template => &self.template_bvh,
        };
        let holding = self.piece_nodes[neutral as usize].get(piece as usize)?.get_or_init(|| {
            let marked: Vec<bool> = self.triangle_piece.iter().map(|&p| p == piece).collect();
            bvh.nodes_holding(&marked)
        });
        bvh.closest_point_among(query, f64::INFINITY, holding, |t| self.triangle_piece[t as usize] == piece)
    }

    /// The side of static piece `piece` vertex `u` rests on, on `neutral`: its signed height
    /// over the piece's surface, `find(u, piece)` computing it the first time it is asked.
    pub(super) fn rest_side(&self, neutral: Neutral, u: usize, piece: u32, find: impl FnOnce() -> Option<f64>) -> Option<f64> {
        self.rest_sides[neutral as usize].get_or(u, piece, find)
    }

    /// The (triangle, piece) pairs crossing at the target's rest: each of a rest pair's two
    /// triangles with the other's piece.
    pub(super) fn embedded(&self, piece_of: impl Fn(u32) -> u32) -> &HashSet<(u32, u32)> {
        self.embedded.get_or_init(|| self.rest_pairs.iter().flat_map(|&(a, b)| [(a, piece_of(b)), (b, piece_of(a))]).collect())
    }

    /// The triangles of the pairs crossing inside one piece at the template's rest (lips
    /// resting through each other), found once per transfer.
    pub(super) fn template_resting(&self, piece_of: impl Fn(u32) -> u32) -> &HashSet<u32> {
        self.template_resting.get_or_init(|| {
            self.template_rest_pairs.iter().filter(|&&(a, b, _)| piece_of(a) == piece_of(b)).flat_map(|&(a, b, _)| [a, b]).collect()
        })
    }

    /// [`DeformationTransfer::written_positions`] of the vertices `vertices` only, whose
    /// deltas are `deltas` (in order): each vertex's the same to the bit.
    pub(super) fn written_at(&self, dt: &DeformationTransfer, vertices: &[usize], deltas: &[Vec3]) -> Vec<Vec3> {
        let written = dt.to_target_frame(deltas);
        vertices.iter().zip(written).map(|(&v, d)| [0, 1, 2].map(|a| (self.written_neutral[v][a] + d[a]) as f64)).collect()
    }

    /// The distance kept from the other surface at vertex `u`.
    pub(super) fn margin(&self, u: usize) -> f64 {
        (self.params.margin * self.edge_length[u]).max(self.params.min_margin * self.diagonal)
    }
}

/// Per `(vertex, static piece)`, the side of the piece's surface a vertex is on (its signed
/// height, `None` where it has no closest point), found the first time it is asked and then
/// looked up: the rest sides of a transfer, the template shape's sides of one shape.
#[derive(Default)]
pub(super) struct SideMemo(Mutex<HashMap<(u32, u32), Option<f64>>>);

impl SideMemo {
    pub(super) fn get_or(&self, u: usize, piece: u32, find: impl FnOnce() -> Option<f64>) -> Option<f64> {
        let key = (u as u32, piece);
        if let Some(&known) = self.0.lock().ok().as_ref().and_then(|m| m.get(&key)) {
            return known;
        }
        let found = find();
        if let Ok(mut sides) = self.0.lock() {
            sides.insert(key, found);
        }
        found
    }
}
