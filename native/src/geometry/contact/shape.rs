//! One shape's contact solve (method, section 3), shared by the transfer and the wrap's carry:
//! which crossings a shape may keep, which it adds, and the solve that removes the added ones.
//!
//! A shape may keep the crossings its target's neutral has and those the template's own shape
//! makes ([`super::exemptions`]); a shape adding no other crossing is returned as it is. Otherwise [`ContactScene::resolve`] minimises the caller's quadratic energy plus the
//! IPC barrier ([`super::newton::solve`]) over the vertices of the added crossings and a few
//! rings around them, the rest held as solved, started from the solved shape untangled
//! ([`super::untangle`]; at the target's neutral around what that leaves): from a start with no
//! added crossing the continuous collision check keeps every iterate so.

use std::sync::Arc;

use super::exemptions::{Crossed, Exemptions, TemplatePose, Topology};
use super::newton::{solve, ContactMesh, NewtonParams, NewtonResult};
use super::untangle::{pairs_nearer, untangle};
use crate::error::ShapesmithResult;
use crate::geometry::bvh::TriangleBvh;
use crate::geometry::penetration::{crossings, intersection_length, AddedCurve};
use crate::geometry::topology::{unique_edges, Adjacency};
use crate::sparse::MatrixRows;

/// Rings of mesh neighbours added around the vertices of the added crossings: the barrier
/// then has room to bend the surface around the contact instead of folding one ring.
const REGION_RINGS: usize = 3;

/// Newton's screening `mu` (a fraction of each vertex's diagonal): a piece floating free inside
/// the region keeps a finite stiffness; the minimiser is unchanged.
const SCREENING: f64 = 1e-3;

/// A pair closer than this fraction of its barrier's range at the start is touching: its
/// barrier's Hessian is then beyond `1e8` times its size at the range, more than a
/// factorisation in double precision resolves (a start whose region's rest met the solved
/// shape around it at `1e-15` of a pair's range was refused as not positive definite).
const TOUCHING: f64 = 1e-4;

/// One neutral as the contact solve sees it: its surface, rest crossings and `d_hat`.
pub struct ContactScene {
    topology: Arc<Topology>,
    edges: Vec<(u32, u32)>,
    rest: Vec<[f64; 3]>,
    d_hat: Vec<f64>,
    adjacency: Adjacency,
    /// Triangle pairs crossing at rest.
    rest_crossing: Arc<Crossed>,
    rest_swept: Vec<(u32, u32, f64)>,
    piece: Vec<u32>,
    pub(super) bvh: TriangleBvh,
}

/// A template's shape: its neutral's scene, its positions, the vertices it moves and the
/// factor that carries its lengths into the target's units.
#[derive(Clone, Copy)]
pub struct TemplateShape<'a> {
    pub scene: &'a ContactScene,
    pub positions: &'a [[f64; 3]],
    pub moving: &'a [bool],
    pub scale: f64,
}

/// What [`ContactScene::resolve`] did.
#[derive(Clone, Debug, Default)]
pub struct Resolved {
    pub newton: NewtonResult,
    /// The vertices solved for.
    pub region: Vec<usize>,
    /// Added crossings and touching pairs left at the start once the region covered every
    /// movable vertex of theirs, at rest (0 unless the neutral itself is not a clean start).
    pub unclean_start: usize,
    /// Whether the flow untangled the whole region ([`super::untangle`]); when not, the
    /// region starts at rest around what it left.
    pub untangled: bool,
}

impl ContactScene {
    /// `distance`: `d_hat` as a fraction of the mean length of the edges at each vertex.
    pub fn new(rest: &[[f64; 3]], triangles: &[[u32; 3]], distance: f64) -> Self {
        let adjacency = Adjacency::from_triangles(rest.len(), triangles);
        let d_hat = adjacency.mean_edge_lengths(rest).into_iter().map(|l| distance * l).collect();
        let bvh = TriangleBvh::build(rest, triangles);
        let rest_swept = crossings(rest, triangles, &bvh, None);
        Self {
            topology: Arc::new(Topology::new(rest.len(), triangles)),
            edges: unique_edges(triangles),
            rest: rest.to_vec(),
            d_hat,
            adjacency,
            rest_crossing: Arc::new(Crossed::from_pairs(rest_swept.iter().map(|&(a, b, _)| (a, b)))),
            rest_swept,
            piece: crate::geometry::penetration::triangle_pieces(rest.len(), triangles),
            bvh,
        }
    }

    pub fn n_vertices(&self) -> usize {
        self.rest.len()
    }

    /// Whether triangles `a` and `b` cross at rest.
    pub fn rest_crosses(&self, a: u32, b: u32) -> bool {
        self.rest_crossing.contains(a, b)
    }

    pub(super) fn triangles(&self) -> &[[u32; 3]] {
        &self.topology.triangles
    }

    pub(super) fn mesh<'a>(&'a self, exempt: &'a Exemptions) -> ContactMesh<'a> {
        ContactMesh { triangles: self.triangles(), edges: &self.edges, rest: &self.rest, d_hat: &self.d_hat, exempt }
    }

    /// What a shape may leave crossing: the pairs crossing at this neutral's rest and, given
    /// the template's shape (same topology), those crossing in it but not at the template's
    /// rest, unless this neutral crosses there too (a template whose lips rest through each
    /// other does not license the target's to cross) ([`Exemptions`]).
    pub fn exemptions(&self, template: Option<TemplateShape>) -> Exemptions {
        let Some(template) = template else {
            return Exemptions::new(self.topology.clone(), self.rest_crossing.clone(), Crossed::default(), Crossed::default(), None);
        };
        let moved: Vec<bool> = self.triangles().iter().map(|t| t.iter().any(|&v| template.moving[v as usize])).collect();
        let bvh = template.scene.bvh.refitted(template.positions, self.triangles());
        let swept = crossings(template.positions, self.triangles(), &bvh, Some(&moved));
        // The curve the template's shape adds per part (inside one piece, between two): its
        // swept pairs less the rest pairs of its moved triangles (an unmoved pair crosses as at rest).
        let part = |a: u32, b: u32| usize::from(self.piece[a as usize] != self.piece[b as usize]);
        let mut added = [0.0f64; 2];
        for &(a, b, l) in &swept {
            added[part(a, b)] += l;
        }
        for &(a, b, l) in template.scene.rest_swept.iter().filter(|&&(a, b, _)| moved[a as usize] || moved[b as usize]) {
            added[part(a, b)] -= l;
        }
        let added = AddedCurve { inside: added[0], between: added[1] };
        let pose = TemplatePose { positions: template.positions.to_vec(), scale: template.scale };
        self.template_exemptions(&template, swept.into_iter().map(|(a, b, _)| (a, b)), added, Some(pose))
    }

    /// The exemptions of a template's shape whose crossing pairs with a moved triangle are
    /// `crossing` and whose curve added to its neutral is `added`, per part: the pairs not
    /// crossing at the template's rest (or crossing at this neutral's too), each widening its
    /// ring in a part whose curve the shape grows.
    fn template_exemptions(&self, template: &TemplateShape, crossing: impl Iterator<Item = (u32, u32)>, added: AddedCurve, pose: Option<TemplatePose>) -> Exemptions {
        let shape: Vec<(u32, u32)> = crossing.filter(|&(a, b)| !template.scene.rest_crosses(a, b) || self.rest_crosses(a, b)).collect();
        let grows = |a: u32, b: u32| if self.piece[a as usize] == self.piece[b as usize] { added.inside > 0.0 } else { added.between > 0.0 };
        let widened = shape.iter().copied().filter(|&(a, b)| grows(a, b));
        Exemptions::new(self.topology.clone(), self.rest_crossing.clone(), Crossed::from_pairs(shape.iter().copied()), Crossed::from_pairs(widened), pose)
    }

    /// [`Self::exemptions`] enough to judge the pairs `asked` ([`Exemptions::triangles`]), the
    /// template's shape tested only at the pairs within one ring of them instead of swept
    /// whole: the judge reads no other pair of it. `added`: the curve the template's shape adds
    /// to its neutral, per part (which of its crossings widen).
    pub fn exemptions_near(&self, template: TemplateShape, added: AddedCurve, asked: &[(u32, u32)]) -> Exemptions {
        let triangles = self.triangles();
        let corners = |t: u32| triangles[t as usize].map(|v| template.positions[v as usize]);
        let moved = |t: u32| triangles[t as usize].iter().any(|&v| template.moving[v as usize]);
        let mut near: Vec<(u32, u32)> = Vec::new();
        for &(a, b) in asked {
            let around_b = self.topology.around(b);
            for x in self.topology.around(a) {
                for &y in &around_b {
                    let (lo, hi) = (x.min(y), x.max(y));
                    if lo != hi && !triangles[lo as usize].iter().any(|v| triangles[hi as usize].contains(v)) {
                        near.push((lo, hi));
                    }
                }
            }
        }
        near.sort_unstable();
        near.dedup();
        // As the whole sweep finds them: a pair with a moved triangle crossing in the template's
        // shape, tested lower index first.
        let crossing = near.into_iter().filter(|&(x, y)| (moved(x) || moved(y)) && intersection_length(corners(x), corners(y)).is_some());
        self.template_exemptions(&template, crossing, added, None)
    }

    /// The crossing triangle pairs of `swept` (as [`crossings`] lists them) a shape adds: not
    /// exempt (a pair crossing at rest is).
    pub fn added_crossings(&self, swept: &[(u32, u32, f64)], exempt: &Exemptions) -> Vec<(u32, u32)> {
        swept
            .iter()
            .filter(|&&(a, b, _)| !exempt.triangles(a, b))
            .map(|&(a, b, _)| (a, b))
            .collect()
    }

    /// The intersection curve of the crossings of `swept` a shape adds beyond `exempt`
    /// ([`Self::added_crossings`]), per part (inside one piece, between two): the criterion
    /// of method, section 3, as the report gives it. A faithful copy of the template's shape
    /// adds none (every pair it crosses, the template's shape or the neutral crosses too).
    pub fn added_curve(&self, swept: &[(u32, u32, f64)], exempt: &Exemptions) -> AddedCurve {
        let mut curve = AddedCurve::default();
        for &(a, b, length) in swept.iter().filter(|&&(a, b, _)| !exempt.triangles(a, b)) {
            let part = if self.piece[a as usize] == self.piece[b as usize] { &mut curve.inside } else { &mut curve.between };
            *part += length;
        }
        curve
    }

    /// Removes the crossings `added` from the solved positions `minimiser` (all N, the
    /// minimiser of the quadratic energy whose rows are `rows`): projected Newton with the
    /// barrier over the `movable` vertices of the added crossings and [`REGION_RINGS`] rings,
    /// started at `minimiser` untangled there ([`untangle`]) and as given elsewhere; around any
    /// added crossing or touching pair ([`TOUCHING`]) the start still has, the region starts at
    /// this neutral's rest and grows by a ring, so the start is clean. Positions outside the
    /// region are returned as given.
    pub fn resolve(
        &self,
        rows: &MatrixRows,
        minimiser: &[[f64; 3]],
        movable: &[bool],
        added: &[(u32, u32)],
        exempt: &Exemptions,
        params: &NewtonParams,
    ) -> ShapesmithResult<Resolved> {
        let n = self.n_vertices();
        let mut in_region = vec![false; n];
        let seed: Vec<u32> = added.iter().flat_map(|&(a, b)| self.triangles()[a as usize].into_iter().chain(self.triangles()[b as usize])).collect();
        let mut frontier = self.take_movable(&seed, movable, &mut in_region);
        for _ in 0..REGION_RINGS {
            frontier = self.grow(&frontier, movable, &mut in_region);
        }
        let first_region: Vec<usize> = (0..n).filter(|&v| in_region[v]).collect();
        let mesh = self.mesh(exempt);
        let untangled = untangle(self, &mesh, exempt, rows, minimiser, &first_region, SCREENING)?;
        // Each region vertex starts where the flow left it, except around a crossing or a
        // touching pair the start still has: there it starts at rest, and the region grows.
        let mut at_rest = vec![false; n];
        let (start, unclean_start) = loop {
            let mut start = minimiser.to_vec();
            for v in (0..n).filter(|&v| in_region[v]) {
                start[v] = if at_rest[v] { self.rest[v] } else { untangled.positions[v] };
            }
            let touched: Vec<bool> = self.triangles().iter().map(|t| t.iter().any(|&v| in_region[v as usize])).collect();
            let bvh = self.bvh.refitted(&start, self.triangles());
            let still = self.added_crossings(&crossings(&start, self.triangles(), &bvh, Some(&touched)), exempt);
            let touching = self.touching(&start, &in_region, exempt);
            if still.is_empty() && touching.is_empty() {
                break (start, 0);
            }
            let crossing_corners = still.iter().flat_map(|&(a, b)| self.triangles()[a as usize].into_iter().chain(self.triangles()[b as usize]));
            let corners: Vec<u32> = crossing_corners.chain(touching.iter().flatten().copied()).collect();
            let new = self.take_movable(&corners, movable, &mut in_region);
            let grown = self.grow(&new.iter().chain(&corners).copied().collect::<Vec<_>>(), movable, &mut in_region);
            let around: Vec<u32> = corners.iter().flat_map(|&v| self.adjacency.neighbours(v as usize).iter().copied().chain([v])).collect();
            let mut reset = 0;
            for v in around.into_iter().chain(new.iter().copied()).chain(grown.iter().copied()).map(|v| v as usize) {
                if in_region[v] && !at_rest[v] {
                    at_rest[v] = true;
                    reset += 1;
                }
            }
            if grown.is_empty() && new.is_empty() && reset == 0 {
                break (start, still.len() + touching.len());
            }
        };
        let region: Vec<usize> = (0..n).filter(|&v| in_region[v]).collect();
        let screening = vec![SCREENING; n];
        let newton = solve(&mesh, rows, minimiser, &screening, &region, start, params)?;
        Ok(Resolved { newton, region, unclean_start, untangled: untangled.clean })
    }

    /// The pairs (their vertices) with a vertex in the region that `start` brings within
    /// [`TOUCHING`] of their barrier's range (the region's rest meeting the solved shape
    /// held around it).
    fn touching(&self, start: &[[f64; 3]], in_region: &[bool], exempt: &Exemptions) -> Vec<[u32; 4]> {
        pairs_nearer(&self.mesh(exempt), start, in_region, TOUCHING).into_iter().map(|pair| pair.vertices).collect()
    }

    /// Marks the `movable` vertices of `vertices` not yet in the region; returns them.
    fn take_movable(&self, vertices: &[u32], movable: &[bool], in_region: &mut [bool]) -> Vec<u32> {
        let mut taken = Vec::new();
        for &v in vertices {
            if movable[v as usize] && !in_region[v as usize] {
                in_region[v as usize] = true;
                taken.push(v);
            }
        }
        taken
    }

    /// Adds the movable neighbours of `frontier` to the region; returns the ones added.
    fn grow(&self, frontier: &[u32], movable: &[bool], in_region: &mut [bool]) -> Vec<u32> {
        let next: Vec<u32> = frontier.iter().flat_map(|&v| self.adjacency.neighbours(v as usize).iter().copied()).collect();
        self.take_movable(&next, movable, in_region)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::topology::grid_triangles;
    use crate::sparse::SymmetricMatrix;

    /// Two 6 x 6 sheets 0.1 apart; the energy `1/2 |x - x*|^2` pulls the upper one's inner
    /// vertices 0.05 below the lower one, through it. The solve keeps it above.
    #[test]
    fn a_sheet_pulled_through_another_stays_above_it() {
        let w = 6u32;
        let sheet = |z: f64| -> Vec<[f64; 3]> { (0..w * w).map(|v| [f64::from(v % w) * 0.2, f64::from(v / w) * 0.2, z]).collect() };
        let rest = [sheet(0.0), sheet(0.1)].concat();
        let mut triangles = grid_triangles(w, w, 0);
        triangles.extend(grid_triangles(w, w, w * w));
        let n = rest.len();
        let scene = ContactScene::new(&rest, &triangles, 0.25);
        let inner = |v: u32| (1..w - 1).contains(&(v % w)) && (1..w - 1).contains(&(v / w));
        let pulled: Vec<[f64; 3]> = sheet(0.1).into_iter().enumerate().map(|(v, p)| if inner(v as u32) { [p[0], p[1], -0.05] } else { p }).collect();
        let minimiser = [sheet(0.0), pulled].concat();
        let movable: Vec<bool> = (0..n).map(|v| v >= (w * w) as usize).collect();
        let identity = SymmetricMatrix::from_triplets(n, (0..n).map(|v| (v, v, 1.0)).collect());
        let exempt = scene.exemptions(None);
        let bvh = TriangleBvh::build(&minimiser, &triangles);
        let added = scene.added_crossings(&crossings(&minimiser, &triangles, &bvh, None), &exempt);
        assert!(!added.is_empty(), "the minimiser should cross");
        let resolved = scene.resolve(&identity.rows(), &minimiser, &movable, &added, &exempt, &NewtonParams::default()).unwrap();
        let x = &resolved.newton.positions;
        let bvh = TriangleBvh::build(x, &triangles);
        assert!(crossings(x, &triangles, &bvh, None).is_empty());
        // The upper sheet rests on the lower one, within the contact distance (a quarter edge).
        let lowest = x[(w * w) as usize..].iter().map(|p| p[2]).fold(f64::INFINITY, f64::min);
        assert!(lowest > 0.0 && lowest < 0.05, "{lowest}");
        assert!(x[..(w * w) as usize] == rest[..(w * w) as usize]);
    }

    /// The same sheets and pull, with a free triangle far from them (no ring reaches it) whose
    /// solved place puts a corner on a border vertex of the upper sheet, which the pull does
    /// not move: the start, at rest or untangled, would have that pair touch at distance zero.
    /// The start is cleaned of it (the triangle joins the region, or the border vertex is
    /// pushed off), and the result has no crossing and keeps the pair apart.
    #[test]
    fn a_start_touching_the_solved_shape_around_the_region_is_cleaned() {
        let w = 6u32;
        let sheet = |z: f64| -> Vec<[f64; 3]> { (0..w * w).map(|v| [f64::from(v % w) * 0.2, f64::from(v / w) * 0.2, z]).collect() };
        let inner = |v: u32| (1..w - 1).contains(&(v % w)) && (1..w - 1).contains(&(v / w));
        let touched = 2 * w;
        let far = [[5.0, 5.0, 5.0], [5.2, 5.0, 5.0], [5.0, 5.2, 5.0]];
        let rest = [sheet(0.0), sheet(0.1), far.to_vec()].concat();
        let mut triangles = grid_triangles(w, w, 0);
        triangles.extend(grid_triangles(w, w, w * w));
        let first_far = 2 * w * w;
        triangles.push([first_far, first_far + 1, first_far + 2]);
        let n = rest.len();
        let scene = ContactScene::new(&rest, &triangles, 0.25);
        let pulled: Vec<[f64; 3]> = sheet(0.1).into_iter().enumerate().map(|(v, p)| if inner(v as u32) { [p[0], p[1], -0.05] } else { p }).collect();
        let on_rest = rest[(w * w + touched) as usize];
        let moved_far = [on_rest, [on_rest[0] + 0.2, on_rest[1], on_rest[2] + 0.3], [on_rest[0], on_rest[1] + 0.2, on_rest[2] + 0.3]];
        let minimiser = [sheet(0.0), pulled, moved_far.to_vec()].concat();
        let movable: Vec<bool> = (0..n).map(|v| v >= (w * w) as usize).collect();
        let identity = SymmetricMatrix::from_triplets(n, (0..n).map(|v| (v, v, 1.0)).collect());
        let exempt = scene.exemptions(None);
        let added = scene.added_crossings(&crossings(&minimiser, &triangles, &TriangleBvh::build(&minimiser, &triangles), None), &exempt);
        let far_triangle = (triangles.len() - 1) as u32;
        assert!(!added.is_empty() && added.iter().all(|&(a, b)| a != far_triangle && b != far_triangle), "only the sheets should cross");
        let resolved = scene.resolve(&identity.rows(), &minimiser, &movable, &added, &exempt, &NewtonParams::default()).unwrap();
        assert!(resolved.region.contains(&((w * w + touched) as usize)), "the border vertex should be in the region");
        let x = &resolved.newton.positions;
        assert!(crossings(x, &triangles, &TriangleBvh::build(x, &triangles), None).is_empty());
        assert!(x.iter().flatten().all(|c| c.is_finite()));
        let apart = (0..3).map(|c| (x[first_far as usize][c] - x[(w * w + touched) as usize][c]).powi(2)).sum::<f64>().sqrt();
        assert!(apart > 0.0, "the free corner still touches the border vertex");
    }
}
