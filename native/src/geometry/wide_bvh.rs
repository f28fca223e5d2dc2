//! A four-wide hierarchy for occlusion rays ("does anything lie on this segment?"), the
//! query landmark visibility asks tens of millions of times. Collapsed from a
//! [`TriangleBvh`] (Wald et al. 2008, "Getting rid of packets": each node keeps the boxes of
//! its four children side by side, so one node visit tests four boxes in single precision
//! and halves the depth), traversed nearest child first and left at the first hit.
//!
//! The answers are those of [`TriangleBvh::any_hit`]: the leaves hold the same prepared
//! triangles and run the same double-precision test; the single-precision boxes are padded
//! outward so that rounding can only make a box test more permissive, never drop a hit.

use super::bvh::{ray_meets, Node, PreparedTriangle, TriangleBvh, MAX_DEPTH};

const WIDTH: usize = 4;
/// A node pushes at most `WIDTH - 1` more entries than it pops, once per level.
const STACK: usize = (WIDTH - 1) * (MAX_DEPTH + 2) + 1;
/// Padding of each single-precision box, relative to the scene's extent plus its largest
/// coordinate: far above the rounding of a box corner, a ray origin or a slab distance to
/// f32 (about 6e-8 of the magnitudes involved), far below the size of a triangle.
const PAD: f64 = 1e-5;

/// Up to four children: their boxes by axis then slot, and for each either an inner node
/// (`count == 0`, `first` is its index), a leaf (triangles `first..first + count`) or nothing
/// (`count == UNUSED`, an empty box). 128 bytes on a 64-byte boundary: a node visit touches
/// two cache lines.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
struct WideNode {
    lo: [[f32; WIDTH]; 3],
    hi: [[f32; WIDTH]; 3],
    first: [u32; WIDTH],
    count: [u32; WIDTH],
}

/// The `count` of a slot a node does not use (its box is empty, `lo > hi`).
const UNUSED: u32 = u32::MAX;
const _: () = assert!(std::mem::size_of::<WideNode>() == 128);

pub struct OcclusionBvh {
    nodes: Vec<WideNode>,
    /// For each node's slots, the binary node it was taken from (for [`Self::refitted`]);
    /// `UNUSED` for an unused slot.
    sources: Vec<[u32; WIDTH]>,
    triangles: Vec<PreparedTriangle>,
}

impl OcclusionBvh {
    /// The four-wide version of `binary`: each node takes the binary tree's nodes two levels
    /// down, opening the largest (by surface area) inner one first.
    pub fn new(binary: &TriangleBvh) -> Self {
        let (mut nodes, mut sources) = (Vec::new(), Vec::new());
        if !binary.triangles.is_empty() {
            collapse(&binary.nodes, 0, &mut nodes, &mut sources);
        }
        let mut wide = Self { nodes, sources, triangles: binary.triangles.clone() };
        wide.fit_boxes(binary);
        wide
    }

    /// The same four-wide tree over `binary`, the hierarchy this was collapsed from refitted
    /// to moved corners ([`TriangleBvh::refitted`]: same nodes, new boxes and triangles):
    /// the boxes copied from it, its triangles taken over. A pose costs a copy of the nodes
    /// instead of a collapse and a copy of every triangle; the answers are those of
    /// [`Self::new`] on `binary` (the tree differs at most in the order children are
    /// visited, which an any-hit answer does not depend on).
    pub fn refitted(&self, binary: TriangleBvh) -> Self {
        let mut wide = Self { nodes: self.nodes.clone(), sources: self.sources.clone(), triangles: Vec::new() };
        wide.fit_boxes(&binary);
        wide.triangles = binary.triangles;
        wide
    }

    /// Each slot's box: its binary node's, padded outward (module docs) and rounded outward
    /// to single precision.
    fn fit_boxes(&mut self, binary: &TriangleBvh) {
        let Some(root) = binary.nodes.first().map(|n| &n.bounds) else { return };
        let magnitude = (0..3).map(|a| root.lo[a].abs().max(root.hi[a].abs())).fold(0.0, f64::max);
        let extent = (0..3).map(|a| root.hi[a] - root.lo[a]).fold(0.0, f64::max);
        let pad = PAD * (extent + magnitude);
        for (node, sources) in self.nodes.iter_mut().zip(&self.sources) {
            for (s, &n) in sources.iter().enumerate() {
                for a in 0..3 {
                    // `UNUSED` is no node's index.
                    (node.lo[a][s], node.hi[a][s]) = match binary.nodes.get(n as usize) {
                        Some(source) => (round_down(source.bounds.lo[a] - pad), round_up(source.bounds.hi[a] + pad)),
                        None => (f32::INFINITY, f32::NEG_INFINITY),
                    };
                }
            }
        }
    }

    /// Whether the ray `origin + t * direction` meets a triangle at some `t` in `(0, t_max)`:
    /// the answer of [`TriangleBvh::any_hit`] on the hierarchy this was collapsed from.
    pub fn any_hit(&self, origin: &[f64; 3], direction: &[f64; 3], t_max: f64) -> bool {
        if self.nodes.is_empty() {
            return false;
        }
        let ray = SlabRay::new(origin, direction, t_max);
        let mut stack = [0u32; STACK];
        let mut top = 1;
        while top > 0 {
            top -= 1;
            let node = &self.nodes[stack[top] as usize];
            let (entries, mut hit) = node.entries(&ray);
            // Leaves first (cheap to settle), then inner children far to near so that the
            // nearest is visited next.
            let mut inner: [(f32, u32); WIDTH] = [(0.0, 0); WIDTH];
            let mut inner_count = 0;
            while hit != 0 {
                let slot = hit.trailing_zeros() as usize;
                hit &= hit - 1;
                let (first, count) = (node.first[slot], node.count[slot]);
                if count == UNUSED {
                    // An empty box is never entered; kept from the traversal all the same.
                    continue;
                }
                if count > 0 {
                    let range = first as usize..(first + count) as usize;
                    if self.triangles[range].iter().any(|tri| ray_meets(tri, origin, direction, t_max)) {
                        return true;
                    }
                } else {
                    let t = entries[slot];
                    let mut i = inner_count;
                    while i > 0 && inner[i - 1].0 < t {
                        inner[i] = inner[i - 1];
                        i -= 1;
                    }
                    inner[i] = (t, first);
                    inner_count += 1;
                }
            }
            for &(_, child) in &inner[..inner_count] {
                stack[top] = child;
                top += 1;
            }
        }
        false
    }
}

/// A ray prepared for the slab tests in single precision: origin, inverse direction, end,
/// and per axis whether the direction is negative (the box's near plane is then `hi`).
struct SlabRay {
    origin: [f32; 3],
    inverse: [f32; 3],
    t_end: f32,
    negative: [bool; 3],
}

impl SlabRay {
    fn new(origin: &[f64; 3], direction: &[f64; 3], t_max: f64) -> Self {
        let inverse = direction.map(|d| (1.0 / d) as f32);
        Self { origin: origin.map(|x| x as f32), inverse, t_end: t_max as f32, negative: inverse.map(|i| i.is_sign_negative()) }
    }
}

impl WideNode {
    /// Slab tests of the four boxes: where the ray enters each, and a bit per slot the ray
    /// enters within `[0, t_end]`. The near plane per axis follows the direction's sign,
    /// so each slab costs one distance to each plane and no `min`/`max` between them. A NaN
    /// distance (an origin on the plane of a parallel ray) fails both comparisons and leaves
    /// the interval as it was: the box is kept, never wrongly dropped.
    #[inline]
    fn entries(&self, ray: &SlabRay) -> ([f32; WIDTH], u32) {
        let mut enter = [0.0f32; WIDTH];
        let mut exit = [ray.t_end; WIDTH];
        for a in 0..3 {
            let (near, far) = if ray.negative[a] { (&self.hi[a], &self.lo[a]) } else { (&self.lo[a], &self.hi[a]) };
            for s in 0..WIDTH {
                let t_near = (near[s] - ray.origin[a]) * ray.inverse[a];
                let t_far = (far[s] - ray.origin[a]) * ray.inverse[a];
                enter[s] = if t_near > enter[s] { t_near } else { enter[s] };
                exit[s] = if t_far < exit[s] { t_far } else { exit[s] };
            }
        }
        let mut hit = 0;
        for s in 0..WIDTH {
            hit |= ((enter[s] <= exit[s]) as u32) << s;
        }
        (enter, hit)
    }
}

/// Appends the wide node for binary node `index` (and, after it, its subtrees) with the
/// binary nodes of its slots (boxes are fitted after); returns its index. Children always
/// come after their parent.
fn collapse(binary: &[Node], index: usize, wide: &mut Vec<WideNode>, sources: &mut Vec<[u32; WIDTH]>) -> u32 {
    let mut slots = vec![index];
    while slots.len() < WIDTH {
        let widest = slots
            .iter()
            .enumerate()
            .filter(|(_, &n)| binary[n].count == 0)
            .max_by(|a, b| binary[*a.1].bounds.half_area().total_cmp(&binary[*b.1].bounds.half_area()));
        let Some((at, &n)) = widest else { break };
        let first = binary[n].first as usize;
        slots[at] = first;
        slots.push(first + 1);
    }
    let me = wide.len();
    wide.push(WideNode { lo: [[0.0; WIDTH]; 3], hi: [[0.0; WIDTH]; 3], first: [0; WIDTH], count: [UNUSED; WIDTH] });
    sources.push(std::array::from_fn(|s| slots.get(s).map_or(UNUSED, |&n| n as u32)));
    for (s, &n) in slots.iter().enumerate() {
        let node = &binary[n];
        if node.count > 0 {
            wide[me].first[s] = node.first;
            wide[me].count[s] = node.count;
        } else {
            wide[me].first[s] = collapse(binary, n, wide, sources);
            wide[me].count[s] = 0;
        }
    }
    me as u32
}

fn round_down(x: f64) -> f32 {
    let f = x as f32;
    if f as f64 > x { f.next_down() } else { f }
}

fn round_up(x: f64) -> f32 {
    let f = x as f32;
    if (f as f64) < x { f.next_up() } else { f }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::bvh::sub;
    use rand::{Rng, SeedableRng};

    /// Random small triangles, random segments and rays: the wide hierarchy, built and
    /// refitted to moved corners (collapsed from the refitted binary tree, or refitted
    /// itself), agrees with testing every triangle and with the binary one.
    #[test]
    fn agrees_with_brute_force_and_the_binary_tree() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(11);
        for (size, offset) in [(1usize, 0.0), (7, 0.0), (300, 0.0), (300, 1000.0)] {
            let points: Vec<[f64; 3]> = (0..size)
                .flat_map(|_| {
                    let centre: [f64; 3] = std::array::from_fn(|_| offset + rng.random::<f64>());
                    let corners: Vec<[f64; 3]> =
                        (0..3).map(|_| std::array::from_fn(|a| centre[a] + 0.15 * (rng.random::<f64>() - 0.5))).collect();
                    corners
                })
                .collect();
            let triangles: Vec<[u32; 3]> = (0..size as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
            let binary = TriangleBvh::build(&points, &triangles);
            let moved: Vec<[f64; 3]> = points.iter().map(|p| [p[0] + 0.2 * (p[1] - offset).powi(2), p[1], p[2] - 0.1 * (p[0] - offset)]).collect();
            let refitted = binary.refitted(&moved, &triangles);
            let collapsed = OcclusionBvh::new(&binary);
            let wides = [OcclusionBvh::new(&binary), collapsed.refitted(binary.refitted(&moved, &triangles))];
            for ((corners, binary), wide) in [(&points, &binary), (&moved, &refitted)].into_iter().zip(&wides) {
                let mut hits = 0;
                for _ in 0..4000 {
                    let origin: [f64; 3] = std::array::from_fn(|_| offset + rng.random_range(-0.2..1.2));
                    let mut direction: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
                    // Some axis-parallel rays, for the slab test's infinities.
                    if rng.random_bool(0.1) {
                        direction[rng.random_range(0..3)] = 0.0;
                    }
                    let t_max = if rng.random_bool(0.5) { f64::INFINITY } else { rng.random_range(0.1..2.0) };
                    let brute = triangles.iter().any(|t| {
                        let [a, b, c] = t.map(|v| corners[v as usize]);
                        ray_meets(&PreparedTriangle { a, ab: sub(&b, &a), ac: sub(&c, &a) }, &origin, &direction, t_max)
                    });
                    assert_eq!(wide.any_hit(&origin, &direction, t_max), brute, "{size} triangles at {offset}");
                    assert_eq!(binary.any_hit(&origin, &direction, t_max), brute);
                    hits += brute as usize;
                }
                if size == 300 {
                    assert!(hits > 200 && hits < 3800, "the test needs hits and misses, saw {hits}");
                }
            }
        }
        assert!(!OcclusionBvh::new(&TriangleBvh::build(&[], &[])).any_hit(&[0.0; 3], &[1.0, 0.0, 0.0], 1.0));
    }

    /// A hierarchy cut down to a subset of the triangles (a clustered one, a scattered one,
    /// none, all), and that cut refitted to moved corners, answer as testing every kept
    /// triangle does, in both the binary and the four-wide form.
    #[test]
    fn restricted_hierarchy_agrees_with_brute_force_on_the_kept_triangles() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(12);
        let size = 400;
        let points: Vec<[f64; 3]> = (0..3 * size).map(|_| std::array::from_fn(|_| rng.random::<f64>())).collect();
        // Small triangles around random centres.
        let points: Vec<[f64; 3]> = points.chunks(3).flat_map(|c| c.iter().map(|p| std::array::from_fn(|a| c[0][a] + 0.1 * (p[a] - c[0][a])))).collect();
        let triangles: Vec<[u32; 3]> = (0..size as u32).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        let moved: Vec<[f64; 3]> = points.iter().map(|p| [p[0] + 0.3 * p[1] * p[1], p[1], p[2] - 0.2 * p[0]]).collect();
        let full = TriangleBvh::build(&points, &triangles);
        let masks: [Vec<bool>; 4] = [
            triangles.iter().map(|t| points[t[0] as usize][0] < 0.3).collect(),
            (0..size).map(|_| rng.random_bool(0.2)).collect(),
            vec![false; size],
            vec![true; size],
        ];
        for keep in &masks {
            let cut = full.restricted(keep);
            assert_eq!(cut.triangles.len(), keep.iter().filter(|&&k| k).count());
            let wide = OcclusionBvh::new(&cut);
            let wide_moved = wide.refitted(cut.refitted(&moved, &triangles));
            for (corners, binary, wide) in [(&points, cut.refitted(&points, &triangles), &wide), (&moved, cut.refitted(&moved, &triangles), &wide_moved)] {
                let mut hits = 0;
                for _ in 0..2000 {
                    let origin: [f64; 3] = std::array::from_fn(|_| rng.random_range(-0.2..1.2));
                    let direction: [f64; 3] = std::array::from_fn(|_| rng.random_range(-1.0..1.0));
                    let brute = triangles.iter().zip(keep).filter(|(_, &k)| k).any(|(t, _)| {
                        let [a, b, c] = t.map(|v| corners[v as usize]);
                        ray_meets(&PreparedTriangle { a, ab: sub(&b, &a), ac: sub(&c, &a) }, &origin, &direction, f64::INFINITY)
                    });
                    assert_eq!(binary.any_hit(&origin, &direction, f64::INFINITY), brute);
                    assert_eq!(wide.any_hit(&origin, &direction, f64::INFINITY), brute);
                    hits += brute as usize;
                }
                let kept = keep.iter().filter(|&&k| k).count();
                assert!(kept == 0 || (hits > 20 && hits < 1980), "the test needs hits and misses: {hits} of 2000 with {kept} kept");
            }
        }
    }
}
