//! A compact bounding-volume hierarchy over triangles (median split on the longest axis)
//! for the self-overlap queries of the penetration metric.

use super::gradients::Vec3;

/// An axis-aligned box.
#[derive(Clone, Copy, Debug)]
pub struct Aabb {
    pub lo: Vec3,
    pub hi: Vec3,
}

impl Aabb {
    pub fn of_points(points: &[Vec3]) -> Self {
        let mut b = Aabb { lo: [f64::INFINITY; 3], hi: [f64::NEG_INFINITY; 3] };
        for p in points {
            b.grow(p);
        }
        b
    }

    fn grow(&mut self, p: &Vec3) {
        for (a, &x) in p.iter().enumerate() {
            self.lo[a] = self.lo[a].min(x);
            self.hi[a] = self.hi[a].max(x);
        }
    }

    fn merge(&self, other: &Aabb) -> Aabb {
        let mut b = *self;
        b.grow(&other.lo);
        b.grow(&other.hi);
        b
    }

    pub fn overlaps(&self, other: &Aabb) -> bool {
        (0..3).all(|a| self.lo[a] <= other.hi[a] && other.lo[a] <= self.hi[a])
    }
}

const LEAF_SIZE: usize = 4;

enum Node {
    Leaf { bounds: Aabb, start: usize, end: usize },
    Inner { bounds: Aabb, left: usize, right: usize },
}

/// Triangles `order[start..end]` live under each leaf.
pub struct Bvh {
    nodes: Vec<Node>,
    order: Vec<u32>,
    boxes: Vec<Aabb>,
}

impl Bvh {
    /// Builds over one box per item.
    pub fn new(boxes: &[Aabb]) -> Self {
        let mut bvh = Bvh { nodes: Vec::new(), order: (0..boxes.len() as u32).collect(), boxes: boxes.to_vec() };
        if !boxes.is_empty() {
            bvh.build(boxes, 0, boxes.len());
        }
        bvh
    }

    fn build(&mut self, boxes: &[Aabb], start: usize, end: usize) -> usize {
        let bounds = self.order[start..end]
            .iter()
            .fold(boxes[self.order[start] as usize], |b, &i| b.merge(&boxes[i as usize]));
        let index = self.nodes.len();
        if end - start <= LEAF_SIZE {
            self.nodes.push(Node::Leaf { bounds, start, end });
            return index;
        }
        let extent = [0, 1, 2].map(|a| bounds.hi[a] - bounds.lo[a]);
        let axis = (0..3).max_by(|&a, &b| extent[a].total_cmp(&extent[b])).unwrap_or(0);
        let centre = |i: u32| boxes[i as usize].lo[axis] + boxes[i as usize].hi[axis];
        let mid = (start + end) / 2;
        self.order[start..end].select_nth_unstable_by(mid - start, |&a, &b| centre(a).total_cmp(&centre(b)));
        // Placeholder replaced once both children exist.
        self.nodes.push(Node::Leaf { bounds, start, end });
        let left = self.build(boxes, start, mid);
        let right = self.build(boxes, mid, end);
        self.nodes[index] = Node::Inner { bounds, left, right };
        index
    }

    /// Calls `visit(item)` for every item whose box overlaps `query`.
    pub fn for_each_overlap(&self, query: &Aabb, mut visit: impl FnMut(u32)) {
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = vec![0usize];
        while let Some(n) = stack.pop() {
            match &self.nodes[n] {
                Node::Leaf { bounds, start, end } => {
                    if bounds.overlaps(query) {
                        for &i in &self.order[*start..*end] {
                            if self.boxes[i as usize].overlaps(query) {
                                visit(i);
                            }
                        }
                    }
                }
                Node::Inner { bounds, left, right } => {
                    if bounds.overlaps(query) {
                        stack.push(*left);
                        stack.push(*right);
                    }
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn overlap_query_matches_brute_force() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(7);
        let boxes: Vec<Aabb> = (0..300)
            .map(|_| {
                let lo: Vec3 = [rng.random::<f64>(), rng.random::<f64>(), rng.random::<f64>()];
                let size: Vec3 = [rng.random::<f64>() * 0.1, rng.random::<f64>() * 0.1, rng.random::<f64>() * 0.1];
                Aabb { lo, hi: [lo[0] + size[0], lo[1] + size[1], lo[2] + size[2]] }
            })
            .collect();
        let bvh = Bvh::new(&boxes);
        for q in boxes.iter().take(50) {
            let mut found = Vec::new();
            bvh.for_each_overlap(q, |i| found.push(i));
            found.sort();
            let expect: Vec<u32> = (0..boxes.len() as u32).filter(|&i| boxes[i as usize].overlaps(q)).collect();
            assert_eq!(found, expect);
        }
    }
}
