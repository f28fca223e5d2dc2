//! The binned surface-area-heuristic build of [`TriangleBvh`](super::TriangleBvh): each node
//! is split where the cheapest of `BINS - 1` boundaries on any axis puts it, or made a leaf
//! when no split beats testing its triangles.
//!
//! Per node, one pass bins the triangles on all three axes at once and one pass partitions
//! them; the children's boxes come from the chosen split's bins and their centroid boxes from
//! the partition (a box is the exact min and max of what it holds, in any order), and the
//! triangles move with their boxes and centroids instead of being read through an index. The
//! same tree as binning each axis in its own pass and measuring every node's triangles again
//! (the same bins, costs, ties and partition), with two passes over a node's triangles
//! instead of five; it saves less than that suggests (the binning is most of the work): the
//! target's and template's builds on the 25k head, one thread, 0.62 -> 0.60 G instructions,
//! and 0.41 G with the boxes grown by compare-and-select (`lower`, `higher`).

use super::{Aabb, Node, BINS, LEAF_SIZE, MAX_DEPTH};

/// A triangle as the build moves it: its box and centroid beside its index in the list.
#[derive(Clone, Copy)]
struct Item {
    bounds: Aabb,
    centroid: [f64; 3],
    triangle: u32,
}

/// The chosen split of a node: the axis, the bin boundary (bins below it go left) and the
/// boxes of the two sides.
struct Split {
    axis: usize,
    boundary: usize,
    left: Aabb,
    right: Aabb,
}

/// The nodes (root first, children side by side after their parent) and the triangles'
/// indices in leaf order, from each triangle's box and centroid.
pub(super) fn nodes(bounds: &[Aabb], centroids: &[[f64; 3]]) -> (Vec<Node>, Vec<u32>) {
    let mut items: Vec<Item> =
        bounds.iter().zip(centroids).enumerate().map(|(t, (&bounds, &centroid))| Item { bounds, centroid, triangle: t as u32 }).collect();
    let mut nodes = vec![Node { bounds: Aabb::EMPTY, first: 0, count: items.len() as u32 }];
    if !items.is_empty() {
        let (mut node_bounds, mut centroid_bounds) = (Aabb::EMPTY, Aabb::EMPTY);
        for item in &items {
            node_bounds.grow(&item.bounds);
            centroid_bounds.grow_point(&item.centroid);
        }
        split(&mut nodes, 0, &mut items, 0, &node_bounds, &centroid_bounds);
    }
    (nodes, items.iter().map(|item| item.triangle).collect())
}

/// Splits node `index` (covering `items`, its box `node_bounds`, its centroids' box
/// `centroid_bounds`) by the binned SAH, or makes it a leaf.
fn split(nodes: &mut Vec<Node>, index: usize, items: &mut [Item], depth: usize, node_bounds: &Aabb, centroid_bounds: &Aabb) {
    let start = nodes[index].first as usize;
    nodes[index].bounds = *node_bounds;
    let count = items.len();
    if count <= LEAF_SIZE || depth >= MAX_DEPTH {
        return;
    }
    let Some(Split { axis, boundary, left: left_bounds, right: right_bounds }) = best_split(items, centroid_bounds, node_bounds) else {
        return;
    };
    let lo = centroid_bounds.lo[axis];
    let scale = BINS as f64 / (centroid_bounds.hi[axis] - lo);
    // Partition: bins below `boundary` go left.
    let (mut left, mut left_centroids, mut right_centroids) = (0, Aabb::EMPTY, Aabb::EMPTY);
    for i in 0..count {
        let centroid = items[i].centroid;
        if ((((centroid[axis] - lo) * scale) as usize).min(BINS - 1)) < boundary {
            items.swap(i, left);
            left += 1;
            left_centroids.grow_point(&centroid);
        } else {
            right_centroids.grow_point(&centroid);
        }
    }
    let children = nodes.len();
    nodes[index].first = children as u32;
    nodes[index].count = 0;
    nodes.push(Node { bounds: Aabb::EMPTY, first: start as u32, count: left as u32 });
    nodes.push(Node { bounds: Aabb::EMPTY, first: (start + left) as u32, count: (count - left) as u32 });
    let (left_items, right_items) = items.split_at_mut(left);
    split(nodes, children, left_items, depth + 1, &left_bounds, &left_centroids);
    split(nodes, children + 1, right_items, depth + 1, &right_bounds, &right_centroids);
}

/// The cheapest SAH split, if it beats a leaf; axes in order, the first of equal costs.
fn best_split(items: &[Item], centroid_bounds: &Aabb, node_bounds: &Aabb) -> Option<Split> {
    let (lo, hi) = (centroid_bounds.lo, centroid_bounds.hi);
    let scale: [f64; 3] = std::array::from_fn(|a| BINS as f64 / (hi[a] - lo[a]));
    let mut bin_bounds = [[Aabb::EMPTY; BINS]; 3];
    let mut bin_counts = [[0usize; BINS]; 3];
    for item in items {
        for a in 0..3 {
            // An axis without extent gives NaN or infinite positions here; it is not used.
            let b = (((item.centroid[a] - lo[a]) * scale[a]) as usize).min(BINS - 1);
            bin_bounds[a][b].grow(&item.bounds);
            bin_counts[a][b] += 1;
        }
    }
    let mut best: Option<(f64, usize, usize)> = None;
    for axis in 0..3 {
        if hi[axis] - lo[axis] <= 0.0 {
            continue;
        }
        let (bin_bounds, bin_counts) = (&bin_bounds[axis], &bin_counts[axis]);
        // Sweep from the right to get the cost of every right part, then from the left.
        let mut right_area = [0.0; BINS];
        let mut right_count = [0usize; BINS];
        let mut acc = Aabb::EMPTY;
        let mut n = 0;
        for b in (1..BINS).rev() {
            acc.grow(&bin_bounds[b]);
            n += bin_counts[b];
            right_area[b] = acc.half_area();
            right_count[b] = n;
        }
        let mut acc = Aabb::EMPTY;
        let mut n = 0;
        for boundary in 1..BINS {
            acc.grow(&bin_bounds[boundary - 1]);
            n += bin_counts[boundary - 1];
            if n == 0 || right_count[boundary] == 0 {
                continue;
            }
            let cost = acc.half_area() * n as f64 + right_area[boundary] * right_count[boundary] as f64;
            if best.is_none_or(|(c, _, _)| cost < c) {
                best = Some((cost, axis, boundary));
            }
        }
    }
    let leaf_cost = node_bounds.half_area() * items.len() as f64;
    // One traversal step costs about as much as one triangle test.
    let (_, axis, boundary) = best.filter(|&(cost, _, _)| cost + node_bounds.half_area() < leaf_cost || items.len() > 4 * LEAF_SIZE)?;
    let (mut left, mut right) = (Aabb::EMPTY, Aabb::EMPTY);
    bin_bounds[axis][..boundary].iter().for_each(|b| left.grow(b));
    bin_bounds[axis][boundary..].iter().for_each(|b| right.grow(b));
    Some(Split { axis, boundary, left, right })
}
