//! The broad phase: a bounding-volume hierarchy over boxes (each primitive's box swept over
//! the step and grown by half of `d_hat`), queried with other boxes. A pair whose boxes do
//! not meet can neither come within `d_hat` nor touch during the step, so only the pairs it
//! reports reach the distances and the CCD.

/// An axis-aligned box.
#[derive(Clone, Copy, Debug)]
pub struct Box3 {
    pub lo: [f64; 3],
    pub hi: [f64; 3],
}

impl Box3 {
    /// The box around `points`, grown by `margin` on every side.
    pub fn around(points: impl IntoIterator<Item = [f64; 3]>, margin: f64) -> Self {
        let mut b = Box3 { lo: [f64::INFINITY; 3], hi: [f64::NEG_INFINITY; 3] };
        for p in points {
            for a in 0..3 {
                b.lo[a] = b.lo[a].min(p[a]);
                b.hi[a] = b.hi[a].max(p[a]);
            }
        }
        for a in 0..3 {
            b.lo[a] -= margin;
            b.hi[a] += margin;
        }
        b
    }

    pub fn overlaps(&self, o: &Box3) -> bool {
        (0..3).all(|a| self.lo[a] <= o.hi[a] && o.lo[a] <= self.hi[a])
    }

    fn union(&self, o: &Box3) -> Box3 {
        Box3 { lo: std::array::from_fn(|a| self.lo[a].min(o.lo[a])), hi: std::array::from_fn(|a| self.hi[a].max(o.hi[a])) }
    }
}

const LEAF: usize = 4;

/// Nodes in one array; a leaf holds `items[first..first + count]`, an inner node's children
/// are `left` and `left + 1`.
#[derive(Clone, Copy)]
struct Node {
    bounds: Box3,
    first: usize,
    count: usize,
    left: usize,
}

/// A hierarchy over boxes, built by median splits on the longest axis.
pub struct BoxTree {
    nodes: Vec<Node>,
    items: Vec<u32>,
    boxes: Vec<Box3>,
}

impl BoxTree {
    /// The tree over `boxes`; queries report indices into it.
    pub fn build(boxes: Vec<Box3>) -> Self {
        let mut items: Vec<u32> = (0..boxes.len() as u32).collect();
        let mut nodes = Vec::with_capacity(2 * boxes.len() / LEAF + 1);
        if !boxes.is_empty() {
            nodes.push(Node { bounds: boxes[0], first: 0, count: boxes.len(), left: 0 });
            let mut stack = vec![0usize];
            while let Some(i) = stack.pop() {
                let Node { first, count, .. } = nodes[i];
                let slice = &mut items[first..first + count];
                let bounds = slice.iter().skip(1).fold(boxes[slice[0] as usize], |b, &k| b.union(&boxes[k as usize]));
                nodes[i].bounds = bounds;
                if count <= LEAF {
                    continue;
                }
                let axis = (0..3).max_by(|&a, &b| (bounds.hi[a] - bounds.lo[a]).total_cmp(&(bounds.hi[b] - bounds.lo[b]))).unwrap_or(0);
                let centre = |k: u32| boxes[k as usize].lo[axis] + boxes[k as usize].hi[axis];
                let half = count / 2;
                slice.select_nth_unstable_by(half, |&a, &b| centre(a).total_cmp(&centre(b)));
                let left = nodes.len();
                nodes[i].left = left;
                nodes[i].count = 0;
                nodes.push(Node { bounds, first, count: half, left: 0 });
                nodes.push(Node { bounds, first: first + half, count: count - half, left: 0 });
                stack.push(left);
                stack.push(left + 1);
            }
        }
        Self { nodes, items, boxes }
    }

    /// Calls `visit` with every box of the tree that overlaps `query`.
    pub fn for_each_overlap(&self, query: &Box3, mut visit: impl FnMut(u32)) {
        if self.nodes.is_empty() {
            return;
        }
        let mut stack = vec![0usize];
        while let Some(i) = stack.pop() {
            let node = self.nodes[i];
            if !node.bounds.overlaps(query) {
                continue;
            }
            if node.count > 0 {
                for &k in &self.items[node.first..node.first + node.count] {
                    if self.boxes[k as usize].overlaps(query) {
                        visit(k);
                    }
                }
            } else {
                stack.push(node.left);
                stack.push(node.left + 1);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geometry::contact::distance::tests_support::Lcg;

    #[test]
    fn the_tree_reports_exactly_the_overlapping_boxes() {
        let mut rng = Lcg(9);
        let boxes: Vec<Box3> = (0..500).map(|_| Box3::around([rng.point(), rng.point().map(|c| c * 0.1)], 0.01)).collect();
        let tree = BoxTree::build(boxes.clone());
        for _ in 0..100 {
            let q = Box3::around([rng.point()], 0.2);
            let mut found = Vec::new();
            tree.for_each_overlap(&q, |k| found.push(k));
            found.sort_unstable();
            let brute: Vec<u32> = (0..boxes.len() as u32).filter(|&k| boxes[k as usize].overlaps(&q)).collect();
            assert_eq!(found, brute);
        }
    }
}
