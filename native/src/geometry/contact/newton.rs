//! Projected Newton on `E(x) = 1/2 (x - x*)^T (A + mu diag A) (x - x*) + kappa sum_pairs
//! m b(d^2)` over a region's vertices, the rest held (IPC, Li et al. 2020, algorithm 1,
//! without inertia: a static solve). `A` is the caller's quadratic energy (the transfer's
//! gradient and virtual-edge terms, the carry's screened Poisson term) and `x*` its minimiser,
//! so without contact the solve returns `x*`; `mu diag A` screens it (the same minimiser, and
//! a piece floating free inside the region keeps a finite stiffness). Each Newton step's
//! matrix is `A` per coordinate plus each close pair's barrier Hessian projected to positive
//! semi-definite, factorised sparse (faer, a fill-reducing order per step: the pairs change
//! the pattern); the step is cut to what the additive CCD finds safe for every candidate
//! pair, then backtracked until the energy decreases (Armijo). The start must have no non-exempt pair touching; every iterate
//! then keeps every non-exempt pair apart.


use super::barrier::{mollifier_threshold, pair_derivatives, pair_energy, pair_squared, project_pair_psd, PairKind};
use super::broad::{Box3, BoxTree};
use super::ccd::{additive_ccd, relative_motion, CONSERVATIVE_RESCALING};
use super::dual::N;
use super::exemptions::Exemptions;
use rustc_hash::FxHashMap;

use crate::error::ShapesmithResult;
use crate::geometry::mat3::sub;
use crate::sparse::{MatrixRows, SymmetricMatrix};

/// The surface contacts are sought on, with its exemptions.
#[derive(Clone, Copy)]
pub struct ContactMesh<'a> {
    pub triangles: &'a [[u32; 3]],
    /// Unique edges `(a, b)`.
    pub edges: &'a [(u32, u32)],
    /// Rest positions: the mollifier's edge lengths and the exemption of pairs close at rest
    /// are read here.
    pub rest: &'a [[f64; 3]],
    /// Per vertex `d_hat`; a pair's is the least of its four vertices' (a coarse piece, teeth
    /// or an eyeball, does not widen the skin's).
    pub d_hat: &'a [f64],
    /// Pairs of vertices whose primitives carry no barrier (the artist's contacts).
    pub exempt: &'a Exemptions,
}

/// The pairs met so far in one solve, by kind (edge-edge or not) and vertices: each pair's
/// [`ContactMesh::pair`] (`None` when exempt).
pub type KnownPairs = FxHashMap<(bool, [u32; 4]), Option<Pair>>;

/// One non-exempt pair: its kind and vertices (`[p, t0, t1, t2]` or `[a0, a1, b0, b1]`),
/// `s_hat = d_hat^2` (or less, below) and the barrier's weight.
#[derive(Clone, Copy, Debug)]
pub struct Pair {
    pub kind: PairKind,
    pub vertices: [u32; 4],
    pub s_hat: f64,
    /// `(d_hat^2 / s_hat)^2`: `b` grows as `s_hat^2`, so a pair whose range is cut below
    /// `d_hat` is weighted back to push as hard near contact as any other; unweighted, lips
    /// resting a thousandth of `d_hat` apart would be held by a barrier `1e-12` as strong,
    /// squeezed to where positions written in single precision cross.
    pub weight: f64,
}

/// A pair met by a broad phase along a step: its distance at the step's start and the most
/// the whole step closes it, so that at a fraction `t` of the step it is at least
/// `distance - t closing` apart.
#[derive(Clone, Copy, Debug)]
pub struct Candidate {
    pub pair: Pair,
    pub distance: f64,
    pub closing: f64,
}

impl Pair {
    pub fn points(&self, x: &[[f64; 3]]) -> [[f64; 3]; 4] {
        self.vertices.map(|v| x[v as usize])
    }
}

impl ContactMesh<'_> {
    /// A pair's `d_hat`: the least of its four vertices'.
    fn pair_d_hat(&self, vertices: [u32; 4]) -> f64 {
        vertices.iter().map(|&v| self.d_hat[v as usize]).fold(f64::INFINITY, f64::min)
    }

    fn pair(&self, kind: PairKind, vertices: [u32; 4]) -> Option<Pair> {
        let (a, b): (&[u32], &[u32]) = match kind {
            PairKind::PointTriangle => (&vertices[..1], &vertices[1..]),
            PairKind::EdgeEdge { .. } => (&vertices[..2], &vertices[2..]),
        };
        if a.iter().any(|v| b.contains(v)) || self.exempt.primitives(a, b) {
            return None;
        }
        let d_hat = self.pair_d_hat(vertices);
        let s_hat = d_hat * d_hat;
        let rest: [[f64; 3]; 4] = vertices.map(|v| self.rest[v as usize]);
        let kind = match kind {
            PairKind::EdgeEdge { .. } => PairKind::EdgeEdge { mollifier: mollifier_threshold(sub(rest[1], rest[0]), sub(rest[3], rest[2])) },
            k => k,
        };
        // Closer than d_hat at rest: its barrier starts at half its rest distance, so that it
        // is inactive at rest and still keeps the pair from crossing; touching at rest, exempt.
        // So is one the template's shape presses closer: half its distance there.
        let rest_squared = pair_squared(kind, &rest);
        let template_squared = self.exempt.template_squared(kind, vertices).unwrap_or(f64::INFINITY);
        let closest = rest_squared.min(template_squared);
        if closest == 0.0 {
            return None;
        }
        let cut = s_hat.min(0.25 * closest);
        Some(Pair { kind, vertices, s_hat: cut, weight: (s_hat / cut).powi(2) })
    }

    /// The non-exempt pairs with a vertex in the region whose boxes, swept from `x` to
    /// `x + step` and grown ([`ContactMesh::swept`]), meet: every pair that can come within
    /// `within` of its `d_hat` (at most 1) or touch along the step, each with its distance at
    /// `x` and the most the step closes it ([`relative_motion`]). A pair's exemption, range and weight depend on its
    /// vertices alone: `known` keeps them across the calls of one solve.
    pub fn candidates(&self, broad: &SolveBroadPhase, x: &[[f64; 3]], step: &[[f64; 3]], within: f64, known: &mut KnownPairs) -> Vec<Candidate> {
        let mut pairs = Vec::new();
        broad.pairs(self, x, step, within, |kind, vertices| {
            // Boxes meet far more often than primitives come close: a pair whose distance at
            // `x`, less the most its step can close it, stays beyond `within d_hat` is none.
            let d_hat = self.pair_d_hat(vertices);
            let (_, closing) = relative_motion(kind, &vertices.map(|v| step[v as usize]));
            let distance = pair_squared(kind, &vertices.map(|v| x[v as usize])).sqrt();
            if distance - closing >= within * d_hat {
                return;
            }
            let key = (matches!(kind, PairKind::EdgeEdge { .. }), vertices);
            if let Some(pair) = *known.entry(key).or_insert_with(|| self.pair(kind, vertices)) {
                pairs.push(Candidate { pair, distance, closing });
            }
        });
        pairs
    }

    /// A primitive's box swept from `x` to `x + step`, grown by half its vertices' least
    /// `d_hat`: two primitives that come within their pair's `d_hat` (the least of the four)
    /// somewhere on the step come within half the sum of theirs, so their boxes meet. Grown by
    /// the largest instead, the boxes met on pairs up to twice as far, and the candidates'
    /// distances were the broad phase's largest cost.
    fn swept(&self, vertices: &[u32], x: &[[f64; 3]], step: &[[f64; 3]], within: f64) -> Box3 {
        let grow = 0.5 * within * vertices.iter().map(|&v| self.d_hat[v as usize]).fold(f64::INFINITY, f64::min);
        Box3::around(
            vertices.iter().flat_map(|&v| {
                let (p, d) = (x[v as usize], step[v as usize]);
                [p, [p[0] + d[0], p[1] + d[1], p[2] + d[2]]]
            }),
            grow,
        )
    }
}

/// The broad phase of one solve. The primitives with no vertex in the region do not move in
/// it: their trees are built once; a step sweeps only the region's points, the triangles and
/// edges with a vertex there, and a tree over the moving ones (the tree rebuilt per step over
/// every primitive near the region was a fifth of the solve's time).
pub struct SolveBroadPhase {
    points: Vec<u32>,
    triangles: Vec<u32>,
    edges: Vec<u32>,
    fixed_points: (BoxTree, Vec<u32>),
    fixed_triangles: (BoxTree, Vec<u32>),
    fixed_edges: (BoxTree, Vec<u32>),
}

impl SolveBroadPhase {
    /// The split of `mesh` by `in_region`, the fixed primitives' boxes at `x`.
    pub fn new(mesh: &ContactMesh, x: &[[f64; 3]], in_region: &[bool]) -> Self {
        let moves = |vs: &[u32]| vs.iter().any(|&v| in_region[v as usize]);
        let edge = |e: u32| [mesh.edges[e as usize].0, mesh.edges[e as usize].1];
        let zero = vec![[0.0; 3]; x.len()];
        let split = |count: usize, vertices: &dyn Fn(u32) -> Vec<u32>| {
            let (moving, fixed): (Vec<u32>, Vec<u32>) = (0..count as u32).partition(|&k| moves(&vertices(k)));
            let tree = BoxTree::build(fixed.iter().map(|&k| mesh.swept(&vertices(k), x, &zero, 1.0)).collect());
            (moving, (tree, fixed))
        };
        let (points, fixed_points) = split(x.len(), &|v| vec![v]);
        let (triangles, fixed_triangles) = split(mesh.triangles.len(), &|t| mesh.triangles[t as usize].to_vec());
        let (edges, fixed_edges) = split(mesh.edges.len(), &|e| edge(e).to_vec());
        Self { points, triangles, edges, fixed_points, fixed_triangles, fixed_edges }
    }

    /// Every point-triangle and edge-edge pair with a vertex in the region whose boxes, swept
    /// from `x` to `x + step` and grown ([`ContactMesh::swept`]), meet, each once, passed to
    /// `emit`. The moving primitives' boxes grow by `within` of half their `d_hat`: a pair
    /// that comes within `within` of its `d_hat` still has meeting boxes (the fixed ones are
    /// grown by the whole half), and a search for pairs nearly touching meets far fewer.
    fn pairs(&self, mesh: &ContactMesh, x: &[[f64; 3]], step: &[[f64; 3]], within: f64, mut emit: impl FnMut(PairKind, [u32; 4])) {
        let swept = |vs: &[u32]| mesh.swept(vs, x, step, within);
        let triangle = |t: u32| mesh.triangles[t as usize];
        let edge = |e: u32| [mesh.edges[e as usize].0, mesh.edges[e as usize].1];
        // Point-triangle: moving points against every triangle, moving triangles against the
        // fixed points.
        let triangle_boxes: Vec<Box3> = self.triangles.iter().map(|&t| swept(&triangle(t))).collect();
        let moving_triangles = BoxTree::build(triangle_boxes.clone());
        for &v in &self.points {
            let b = swept(&[v]);
            let mut take = |t: u32| {
                let tri = triangle(t);
                if !tri.contains(&v) {
                    emit(PairKind::PointTriangle, [v, tri[0], tri[1], tri[2]]);
                }
            };
            self.fixed_triangles.0.for_each_overlap(&b, |k| take(self.fixed_triangles.1[k as usize]));
            moving_triangles.for_each_overlap(&b, |k| take(self.triangles[k as usize]));
        }
        for (&t, b) in self.triangles.iter().zip(&triangle_boxes) {
            let tri = triangle(t);
            self.fixed_points.0.for_each_overlap(b, |k| {
                let v = self.fixed_points.1[k as usize];
                emit(PairKind::PointTriangle, [v, tri[0], tri[1], tri[2]]);
            });
        }
        // Edge-edge: moving edges against the fixed ones, and against each other once.
        let edge_boxes: Vec<Box3> = self.edges.iter().map(|&e| swept(&edge(e))).collect();
        let moving_edges = BoxTree::build(edge_boxes.clone());
        let apart = |[a0, a1]: [u32; 2], [b0, b1]: [u32; 2]| a0 != b0 && a0 != b1 && a1 != b0 && a1 != b1;
        for (k, (&e, b)) in self.edges.iter().zip(&edge_boxes).enumerate() {
            let a = edge(e);
            let mut take = |f: u32| {
                let other = edge(f);
                if apart(a, other) {
                    emit(PairKind::EdgeEdge { mollifier: 0.0 }, [a[0], a[1], other[0], other[1]]);
                }
            };
            self.fixed_edges.0.for_each_overlap(b, |j| take(self.fixed_edges.1[j as usize]));
            moving_edges.for_each_overlap(b, |j| {
                if j as usize > k {
                    take(self.edges[j as usize]);
                }
            });
        }
    }
}

/// Settings of [`solve`].
#[derive(Clone, Copy, Debug)]
pub struct NewtonParams {
    /// Stop when the Newton step, in the norm of the Newton matrix, is no longer than moving
    /// every vertex of the region by this fraction of its `d_hat`, in the norm of the
    /// energy's diagonal (the Newton decrement, [`solve`]).
    pub tolerance: f64,
    pub max_iterations: usize,
}

impl Default for NewtonParams {
    fn default() -> Self {
        Self { tolerance: 1e-2, max_iterations: 100 }
    }
}

/// What [`solve`] returns.
#[derive(Clone, Debug, Default)]
pub struct NewtonResult {
    pub positions: Vec<[f64; 3]>,
    pub iterations: usize,
    /// Pairs closer than their `d_hat` at the end.
    pub contacts: usize,
    pub converged: bool,
}

/// Each of `n` vertices' place among the unknowns `region` (`usize::MAX` outside it), and
/// whether it is one.
pub(super) fn region_slots(n: usize, region: &[usize]) -> (Vec<usize>, Vec<bool>) {
    let mut slot = vec![usize::MAX; n];
    for (s, &v) in region.iter().enumerate() {
        slot[v] = s;
    }
    let in_region = slot.iter().map(|&s| s != usize::MAX).collect();
    (slot, in_region)
}

/// Minimises `E` (module docs) over the vertices `region` from `start` (all N positions; the
/// rest held there), `rows` the rows of `A`, `minimiser` `x*` (all N), `screening` `mu` per
/// vertex (a fraction of its diagonal).
pub fn solve(
    mesh: &ContactMesh,
    rows: &MatrixRows,
    minimiser: &[[f64; 3]],
    screening: &[f64],
    region: &[usize],
    start: Vec<[f64; 3]>,
    params: &NewtonParams,
) -> ShapesmithResult<NewtonResult> {
    let n = start.len();
    let (slot, in_region) = region_slots(n, region);
    let mut x = start;
    if region.is_empty() {
        return Ok(NewtonResult { positions: x, converged: true, ..Default::default() });
    }
    let diagonal = |v: usize| rows.row(v).iter().find(|&&(u, _)| u == v).map_or(0.0, |&(_, a)| a);
    let mean_diagonal = region.iter().map(|&v| diagonal(v)).sum::<f64>() / region.len() as f64;
    let mean_d_hat = region.iter().map(|&v| mesh.d_hat[v]).sum::<f64>() / region.len() as f64;
    // The barrier's stiffness (module docs of mod.rs): the energy's mean diagonal per unit of
    // squared d_hat. A hundredth of it moves pressed lips only 8% closer (the barrier grows
    // logarithmically) and lets pairs come so close that the positions written in single
    // precision cross (the crossed strips of the transfer's tests).
    let kappa = mean_diagonal / (mean_d_hat * mean_d_hat);
    let quadratic = |x: &[[f64; 3]]| {
        let mut e = 0.0;
        for &v in region {
            let dv = sub(x[v], minimiser[v]);
            for &(u, a) in rows.row(v) {
                if in_region[u] {
                    let du = sub(x[u], minimiser[u]);
                    e += 0.5 * a * (dv[0] * du[0] + dv[1] * du[1] + dv[2] * du[2]);
                }
            }
            e += 0.5 * screening[v] * diagonal(v) * (dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2]);
        }
        e
    };
    let energy = |x: &[[f64; 3]], pairs: &[Pair]| quadratic(x) + kappa * pairs.iter().map(|p| p.weight * pair_energy(p.kind, &p.points(x), p.s_hat)).sum::<f64>();
    let zero = vec![[0.0; 3]; n];
    let mut result = NewtonResult::default();
    let mut step = zero.clone();
    let mut known = KnownPairs::default();
    // The pairs that can be within `d_hat` of each other at `x`: at the start, those of `x`
    // itself; after a step, those swept along it (they hold every pair that came close on the
    // way, so one broad phase per iteration serves both the line search and the next
    // derivatives).
    let broad = SolveBroadPhase::new(mesh, &x, &in_region);
    let mut pairs: Vec<Pair> = mesh.candidates(&broad, &x, &zero, 1.0, &mut known).into_iter().map(|c| c.pair).collect();
    // The stop (Boyd and Vandenberghe 9.5.1, the Newton decrement `lambda^2 = -g . p`, the
    // step's length in the Newton matrix's norm), against the same length of a step moving
    // each vertex by `tolerance d_hat` under the energy's diagonal. A step along which the
    // energy is nearly flat (contacts sliding past each other) is long in distance and
    // short in this norm: the infinity norm of the step kept a shape's lips sliding at a
    // tenth of `d_hat` per step for fifty steps that lowered the energy by 0.1%.
    let decrement_floor: f64 = region.iter().map(|&v| diagonal(v) * (params.tolerance * mesh.d_hat[v]).powi(2)).sum();
    for iteration in 0..params.max_iterations {
        result.iterations = iteration + 1;
        // Gradient and Hessian.
        let mut gradient = vec![0.0; 3 * region.len()];
        let mut entries: Vec<(usize, usize, f64)> = Vec::new();
        for (s, &v) in region.iter().enumerate() {
            let dv = sub(x[v], minimiser[v]);
            for &(u, a) in rows.row(v) {
                if !in_region[u] {
                    continue;
                }
                let du = sub(x[u], minimiser[u]);
                for c in 0..3 {
                    gradient[3 * s + c] += a * du[c];
                }
                if slot[u] <= s {
                    let extra = if u == v { screening[v] * a } else { 0.0 };
                    for c in 0..3 {
                        entries.push((3 * s + c, 3 * slot[u] + c, a + extra));
                    }
                }
            }
            for c in 0..3 {
                gradient[3 * s + c] += screening[v] * diagonal(v) * dv[c];
            }
        }
        let mut close = 0;
        for pair in &pairs {
            let d = pair_derivatives(pair.kind, &pair.points(&x), pair.s_hat);
            if d.v == 0.0 && d.g.iter().all(|&g| g == 0.0) {
                continue;
            }
            close += 1;
            let h = project_pair_psd(&d.h);
            let dof = |i: usize| {
                let v = pair.vertices[i / 3] as usize;
                in_region[v].then(|| 3 * slot[v] + i % 3)
            };
            for i in 0..N {
                let Some(r) = dof(i) else { continue };
                gradient[r] += kappa * pair.weight * d.g[i];
                for j in 0..N {
                    if let Some(c) = dof(j) {
                        if r >= c && h[i][j] != 0.0 {
                            entries.push((r, c, kappa * pair.weight * h[i][j]));
                        }
                    }
                }
            }
        }
        result.contacts = close;
        let matrix = SymmetricMatrix::from_triplets(3 * region.len(), entries);
        // The pattern is the step's own (its pairs come and go): ordered once for the first
        // step's pattern, a mouth's region (553 vertices, 1.4k pairs pressing the lips) filled
        // in as pairs across the lips came in, and its factorisations took about 4x as long.
        let order = matrix.fill_reducing_order()?;
        let factor = matrix.factor(&order)?;
        let rhs: Vec<[f64; 3]> = gradient.iter().map(|&g| [-g, 0.0, 0.0]).collect();
        let direction = factor.solve_points(&rhs);
        for (s, &v) in region.iter().enumerate() {
            step[v] = std::array::from_fn(|c| direction[3 * s + c][0]);
        }
        let slope: f64 = region.iter().enumerate().map(|(s, &v)| (0..3).map(|c| gradient[3 * s + c] * step[v][c]).sum::<f64>()).sum();
        if -slope <= decrement_floor {
            result.converged = true;
            break;
        }
        // The pairs already near bound the step first (the first steps from the neutral are
        // tens of `d_hat` long and cut to a few percent by a pair in contact): the broad phase
        // then sweeps only the part of the step that can be taken, whose boxes are that much
        // smaller. Every pair that can come close along the part is still found.
        let reach = pairs.iter().map(|p| additive_ccd(p.kind, &p.points(&x), &p.vertices.map(|v| step[v as usize]), 1.0)).fold(1.0, f64::min);
        for &v in region {
            step[v] = step[v].map(|c| reach * c);
        }
        let slope = reach * slope;
        // The largest safe step along the direction: the additive CCD's first advance is
        // `eta d / l_p` ([`additive_ccd`]), so a pair whose bound is already beyond the step
        // found so far cannot shorten it, and the pairs are taken in the order of that bound.
        let mut swept = mesh.candidates(&broad, &x, &step, 1.0, &mut known);
        let bound = |c: &Candidate| if c.closing > 0.0 { CONSERVATIVE_RESCALING * c.distance / c.closing } else { f64::INFINITY };
        swept.sort_unstable_by(|a, b| bound(a).total_cmp(&bound(b)));
        let mut alpha = 1.0f64;
        for c in &swept {
            if bound(c) >= alpha {
                break;
            }
            let p = &c.pair;
            alpha = alpha.min(additive_ccd(p.kind, &p.points(&x), &p.vertices.map(|v| step[v as usize]), alpha));
        }
        // Then Armijo backtracking over `[0, alpha]`, on the pairs that can come within their
        // range there (the others add nothing to the energy along it).
        let swept: Vec<Pair> = swept.iter().filter(|c| c.distance - alpha * c.closing < c.pair.s_hat.sqrt()).map(|c| c.pair).collect();
        let e0 = energy(&x, &swept);
        let trial = |alpha: f64| {
            let mut y = x.clone();
            for &v in region {
                for c in 0..3 {
                    y[v][c] += alpha * step[v][c];
                }
            }
            y
        };
        let mut next = trial(alpha);
        while energy(&next, &swept) > e0 + 1e-4 * alpha * slope && alpha > 1e-10 {
            alpha *= 0.5;
            next = trial(alpha);
        }
        x = next;
        pairs = swept;
    }
    result.positions = x;
    Ok(result)
}
