//! Which vertices went through another surface, and where each is held: the module docs' "Which
//! vertices, and where to" (`collisions/mod.rs`). A vertex the template's own shape takes
//! across the same obstacle is not held (`template_crosses`). Also the local re-solve's region
//! (`grow_region`) and the triangles the virtual-edge springs folded (`spring_folds`, the
//! module docs' "Folds").

use std::cmp;
use std::collections::{BTreeMap, BinaryHeap, HashMap, HashSet};

use super::contacts::TemplateContacts;
use super::{Attempt, CollisionGuard, Neutral, Targets};
use crate::transfer::deformation::DeformationTransfer;
use crate::transfer::gradients::{add, cross, dot, length, scale, sub, Vec3};

impl DeformationTransfer {
    /// The free vertices that went through the other surface of a new pair, with the target
    /// position that puts each back on its rest side plus the margin, flooding from the
    /// pairs' corners to the vertices beyond the crossing. Against a static piece (teeth,
    /// an eyeball, lashes where the target has them) the target is the closest point of
    /// that piece's surface plus the margin along its normal; against a surface that moves
    /// too (lip through lip), a push along the obstacle triangle's normal. `template` is the
    /// template's shape (positions): a vertex it takes across the same obstacle is not held.
    pub(super) fn offending_vertices(
        &self,
        guard: &CollisionGuard,
        positions: &[Vec3],
        pairs: &[(u32, u32)],
        free: &[bool],
        static_piece: &[bool],
        attempt: &Attempt,
        template: &TemplateContacts,
    ) -> Targets {
        let margin = attempt.margin;
        let template_positions = &template.positions;
        // A vertex the template's own shape takes to the other side of the corresponding
        // obstacle is left where the solve put it: the target only follows the artist there.
        let hold = |u: usize, obstacle: u32, piece: Option<u32>, push: Option<Vec3>| {
            push.filter(|_| attempt.follow || attempt.clear || !self.template_crosses(guard, template, u, obstacle, piece))
        };
        let mut pushes: BTreeMap<usize, Vec3> = BTreeMap::new();
        let mut queue: Vec<(u32, u32)> = Vec::new();
        let keep = |u: usize, push: Vec3, obstacle: u32, pushes: &mut BTreeMap<usize, Vec3>, queue: &mut Vec<(u32, u32)>| {
            match pushes.get_mut(&u) {
                Some(old) => {
                    if length(push) > length(*old) {
                        *old = push;
                    }
                }
                None => {
                    pushes.insert(u, push);
                    queue.push((u as u32, obstacle));
                }
            }
        };
        // With `attempt.embedded`, the (triangle, piece) pairs crossing at the target's rest.
        let no_pairs = HashSet::new();
        let embedded = if attempt.embedded { guard.embedded(|t| self.triangle_piece(t)) } else { &no_pairs };
        // A vertex meets the same piece in several pairs (each of its triangles, each of theirs
        // crossing the piece) and again in the flood: its push off that piece, a closest-point
        // query, is found once per call (the same positions and margin throughout).
        let mut pushed_off: HashMap<(usize, u32), Option<Vec3>> = HashMap::new();
        let mut push_off_piece = |u: usize, piece: u32| *pushed_off.entry((u, piece)).or_insert_with(|| self.push_off_piece(guard, positions, u, piece, margin));
        let obstacle_piece = |u: usize, t: u32| {
            let p = self.triangle_piece(t);
            (p != self.piece[u] && static_piece[p as usize]).then_some(p)
        };
        if attempt.along_path {
            return self.along_path_holds(guard, positions, pairs, free);
        }
        for &(a, b) in pairs {
            for (side, obstacle) in [(a, b), (b, a)] {
                for &u in &self.triangles[side as usize] {
                    let u = u as usize;
                    if !free[u] {
                        continue;
                    }
                    let moved_by = length(sub(positions[u], self.target_neutral[u]));
                    let push = match obstacle_piece(u, obstacle) {
                        // A corner that barely moves goes back to rest, where its triangle
                        // crosses the static piece exactly as in the neutral.
                        Some(_) if moved_by > 0.0 && moved_by <= REST_SNAP * guard.edge_length[u] => {
                            Some(sub(self.target_neutral[u], positions[u]))
                        }
                        // Where the template's shape adds no curve against the piece, the
                        // criterion allows none: a triangle at rest crosses a static piece
                        // exactly as in the neutral, whatever side its corners rest on.
                        Some(piece)
                            if attempt.embedded
                                && moved_by > 0.0
                                && (embedded.contains(&(side, piece)) || push_off_piece(u, piece).is_none()) =>
                        {
                            Some(sub(self.target_neutral[u], positions[u]))
                        }
                        Some(piece) if attempt.rest && moved_by > 0.0 && template.adds_none(self.piece[u], piece) => {
                            Some(sub(self.target_neutral[u], positions[u]))
                        }
                        Some(piece) => hold(u, obstacle, Some(piece), push_off_piece(u, piece)),
                        None => self.lip_hold(guard, positions, u, obstacle, free, attempt, template_positions, &hold),
                    };
                    if let Some(push) = push {
                        keep(u, push, obstacle, &mut pushes, &mut queue);
                    }
                }
            }
        }
        while let Some((u, obstacle)) = queue.pop() {
            for &w in guard.adjacency.neighbours(u as usize) {
                let w = w as usize;
                if !free[w] || pushes.contains_key(&w) {
                    continue;
                }
                if let Some(piece) = obstacle_piece(w, obstacle) {
                    let push = match push_off_piece(w, piece) {
                        // Gone through the piece, where the template's shape adds no curve
                        // against it: back to rest, as the pairs' corners.
                        Some(_) if attempt.rest && template.adds_none(self.piece[w], piece) => {
                            Some(sub(self.target_neutral[w], positions[w]))
                        }
                        push => hold(w, obstacle, Some(piece), push),
                    };
                    if let Some(push) = push {
                        keep(w, push, obstacle, &mut pushes, &mut queue);
                    }
                    continue;
                }
                let Some(beneath) = self.obstacle_below(guard, positions, w, obstacle) else { continue };
                if let Some(push) = self.lip_hold(guard, positions, w, beneath, free, attempt, template_positions, &hold) {
                    keep(w, push, beneath, &mut pushes, &mut queue);
                }
            }
        }
        pushes.into_iter().map(|(u, push)| (u, add(positions[u], push))).collect()
    }

    /// The along-path attempt's holds: each free corner of a pair inside one piece whose
    /// triangles lie beside a pair the template's neutral crosses (lips resting through each
    /// other) a quarter of the way back along its own motion, `t_u = x_u + (B0_u - x_u) / 4`,
    /// renewed each round. Where the template's lips rest crossed, the side of the other
    /// lip's plane a corner rested on says nothing of where it belongs, and the rest-side
    /// pushes add curve round after round; stopping short along the way it came does not.
    fn along_path_holds(&self, guard: &CollisionGuard, positions: &[Vec3], pairs: &[(u32, u32)], free: &[bool]) -> Targets {
        let resting = guard.template_resting(|t| self.triangle_piece(t));
        let beside = |t: u32| guard.around(t).iter().any(|s| resting.contains(s));
        let mut targets = Targets::new();
        for &(a, b) in pairs.iter().filter(|&&(a, b)| self.triangle_piece(a) == self.triangle_piece(b) && (beside(a) || beside(b))) {
            for &u in self.triangles[a as usize].iter().chain(&self.triangles[b as usize]) {
                let u = u as usize;
                let back = sub(self.target_neutral[u], positions[u]);
                if free[u] && length(back) > 0.0 {
                    targets.insert(u, add(positions[u], scale(back, 0.25)));
                }
            }
        }
        targets
    }

    /// Per triangle, whether the virtual-edge springs `springs` folded it over in the plain
    /// solve (`plain`, deltas): turned over against the target's neutral while the template's
    /// shape (`template`, positions) keeps it upright, with a corner a spring pulls at.
    pub(super) fn spring_folds(&self, springs: &[(usize, usize, f64, Vec3)], plain: &[Vec3], template: &[Vec3]) -> Vec<bool> {
        let mut spring_end = vec![false; plain.len()];
        for &(i, j, _, _) in springs {
            spring_end[i] = true;
            spring_end[j] = true;
        }
        let positions: Vec<Vec3> = self.target_neutral.iter().zip(plain).map(|(p, d)| add(*p, *d)).collect();
        let normal = |t: &[u32; 3], p: &[Vec3]| {
            let c = t.map(|v| p[v as usize]);
            cross(sub(c[1], c[0]), sub(c[2], c[0]))
        };
        self.triangles
            .iter()
            .map(|t| {
                t.iter().any(|&v| spring_end[v as usize])
                    && dot(normal(t, &positions), normal(t, &self.target_neutral)) < 0.0
                    && dot(normal(t, template), normal(t, &self.source_neutral)) >= 0.0
            })
            .collect()
    }

    /// Adds to `region` the free vertices within reach of the seeds `(u, reach)` along the
    /// target neutral's edges: `REGION_RINGS` of `u`'s edge lengths, or `REGION_SPREAD` times
    /// the distance `u` is pushed, whichever is more. Outside the region the shape stays as
    /// solved; inside, the energy spreads the push smoothly instead of folding the vertices
    /// next to a held one.
    pub(super) fn grow_region(&self, guard: &CollisionGuard, seeds: &[(usize, f64)], free: &[bool], region: &mut [bool]) {
        #[derive(PartialEq)]
        struct Budget(f64, usize);
        impl Eq for Budget {}
        impl PartialOrd for Budget {
            fn partial_cmp(&self, other: &Self) -> Option<cmp::Ordering> {
                Some(self.cmp(other))
            }
        }
        impl Ord for Budget {
            fn cmp(&self, other: &Self) -> cmp::Ordering {
                self.0.total_cmp(&other.0).then(self.1.cmp(&other.1))
            }
        }
        // Per vertex, the most budget it was reached with (none yet: below any budget).
        let mut best = vec![f64::NEG_INFINITY; region.len()];
        let mut heap = BinaryHeap::new();
        for &(u, reach) in seeds {
            let budget = (REGION_RINGS * guard.edge_length[u]).max(REGION_SPREAD * reach);
            heap.push(Budget(budget, u));
        }
        while let Some(Budget(budget, v)) = heap.pop() {
            if best[v] >= budget {
                continue;
            }
            best[v] = budget;
            region[v] = true;
            for &w in guard.adjacency.neighbours(v) {
                let w = w as usize;
                let left = budget - length(sub(self.target_neutral[w], self.target_neutral[v]));
                if free[w] && left >= 0.0 && best[w] < left {
                    heap.push(Budget(left, w));
                }
            }
        }
    }

    /// The push of vertex `u` against triangle `t` of a surface that moves too: across its
    /// plane to the rest side ([`Self::push_out`]), or with `attempt.follow`, where `u`
    /// went through, to where the template's shape (`template`) has `u` relative to the same
    /// triangle: the same barycentric coordinates in its plane and the same height over it,
    /// scaled by the triangles' size ratio (half of it when `t` can move too).
    #[allow(clippy::too_many_arguments)]
    fn lip_hold(
        &self,
        guard: &CollisionGuard,
        positions: &[Vec3],
        u: usize,
        t: u32,
        free: &[bool],
        attempt: &Attempt,
        template: &[Vec3],
        hold: &dyn Fn(usize, u32, Option<u32>, Option<Vec3>) -> Option<Vec3>,
    ) -> Option<Vec3> {
        let push = self.push_out(guard, positions, u, t as usize, free, attempt.margin, attempt.strip);
        if !attempt.follow {
            return hold(u, t, None, push);
        }
        push?;
        let tri = self.triangles[t as usize];
        let frame = |p: &[Vec3]| {
            let c = tri.map(|v| p[v as usize]);
            let n = cross(sub(c[1], c[0]), sub(c[2], c[0]));
            let area = length(n);
            let size = length(sub(c[1], c[0])) + length(sub(c[2], c[1])) + length(sub(c[0], c[2]));
            (area > 0.0).then(|| (c, scale(n, 1.0 / area), size))
        };
        let (s, s_normal, s_size) = frame(template)?;
        let (c, normal, size) = frame(positions)?;
        let offset = sub(template[u], s[0]);
        let height = dot(offset, s_normal);
        let (e1, e2) = (sub(s[1], s[0]), sub(s[2], s[0]));
        let in_plane = sub(offset, scale(s_normal, height));
        let (g11, g12, g22) = (dot(e1, e1), dot(e1, e2), dot(e2, e2));
        let (r1, r2) = (dot(in_plane, e1), dot(in_plane, e2));
        let det = g11 * g22 - g12 * g12;
        if det <= 0.0 {
            return None;
        }
        let (b1, b2) = ((r1 * g22 - r2 * g12) / det, (r2 * g11 - r1 * g12) / det);
        let at = add(add(c[0], add(scale(sub(c[1], c[0]), b1), scale(sub(c[2], c[0]), b2))), scale(normal, height * size / s_size));
        // Where the template has `u` far from the triangle (beyond a triangle's width of it,
        // or a target further than MAX_DEPTH edges), the triangle says nothing of `u`: held
        // as the first attempt holds it.
        let placed = sub(at, positions[u]);
        if length(placed) > MAX_DEPTH * guard.edge_length[u] {
            return hold(u, t, None, push);
        }
        let share = if tri.iter().any(|&v| free[v as usize]) { 0.5 } else { 1.0 };
        Some(scale(placed, share))
    }

    /// The push of vertex `u` out of the static piece `piece`, when it is on the other side
    /// of that piece's surface than at rest: to the closest point of the surface plus the
    /// margin along the surface's normal, on the rest side. The side is read at the closest
    /// point (through its face's normal, or the mean normal around its nearest corner when it
    /// lies on an edge or corner), at rest and now.
    fn push_off_piece(&self, guard: &CollisionGuard, positions: &[Vec3], u: usize, piece: u32, margin: f64) -> Option<Vec3> {
        let rest_height = guard.rest_side(Neutral::Target, u, piece, || {
            self.piece_side(guard, Neutral::Target, self.target_neutral[u], piece).map(|(height, _, _)| height)
        })?;
        let (height, point, normal) = self.piece_side(guard, Neutral::Target, positions[u], piece)?;
        if rest_height == 0.0 || rest_height * height > 0.0 || height.abs() > MAX_DEPTH * guard.edge_length[u] {
            return None;
        }
        let target = add(point, scale(normal, rest_height.signum() * margin * guard.margin(u)));
        Some(sub(target, positions[u]))
    }

    /// Whether the template's own shape (`contacts.positions`) has vertex `u` on the
    /// other side of the obstacle than at the template's rest: of the static piece `piece`'s
    /// surface (read at the closest point, as [`Self::push_off_piece`] reads the target's), or
    /// else of triangle `obstacle`'s plane (as [`Self::push_out`] reads it). Template and
    /// target share the topology, so the corresponding vertex and obstacle are the same indices.
    fn template_crosses(&self, guard: &CollisionGuard, contacts: &TemplateContacts, u: usize, obstacle: u32, piece: Option<u32>) -> bool {
        let (rest, template) = (&self.source_neutral, &contacts.positions);
        match piece {
            Some(piece) => {
                let side_at = |q: Vec3| self.piece_side(guard, Neutral::Template, q, piece).map(|(height, _, _)| height);
                let before = guard.rest_side(Neutral::Template, u, piece, || side_at(rest[u]));
                let now = || contacts.side(u, piece, || side_at(template[u]));
                before.is_some_and(|before| now().is_some_and(|now| before * now < 0.0))
            }
            None => {
                let tri = self.triangles[obstacle as usize];
                let side = |p: &[Vec3]| {
                    let c = tri.map(|v| p[v as usize]);
                    dot(cross(sub(c[1], c[0]), sub(c[2], c[0])), sub(p[u], c[0]))
                };
                side(rest) * side(template) < 0.0
            }
        }
    }

    /// Which side of the static piece `piece`'s surface on `neutral` the point `q` is on: its
    /// signed height over the surface's closest point, that point and the normal there.
    fn piece_side(&self, guard: &CollisionGuard, neutral: Neutral, q: Vec3, piece: u32) -> Option<(f64, Vec3, Vec3)> {
        let hit = guard.closest_on_piece(neutral, &q, piece)?;
        let points = match neutral {
            Neutral::Target => &self.target_neutral,
            Neutral::Template => &self.source_neutral,
        };
        let normal = self.surface_normal(points, guard, hit.triangle, &hit.barycentric)?;
        Some((dot(normal, sub(q, hit.point)), hit.point, normal))
    }

    /// The unit normal of the neutral surface `points` at a point of triangle `t`: the face's
    /// inside it, the mean of the faces around the nearest corner on an edge or a corner
    /// (where the face's own normal can point the wrong way for a point outside).
    fn surface_normal(&self, points: &[Vec3], guard: &CollisionGuard, t: u32, barycentric: &[f64; 3]) -> Option<Vec3> {
        let unit = |t: u32| {
            let p = self.triangles[t as usize].map(|v| points[v as usize]);
            let n = cross(sub(p[1], p[0]), sub(p[2], p[0]));
            let l = length(n);
            (l > 0.0).then(|| scale(n, 1.0 / l))
        };
        if barycentric.iter().all(|&b| b > 1e-9) {
            return unit(t);
        }
        let corner = (0..3).max_by(|&i, &j| barycentric[i].total_cmp(&barycentric[j]))?;
        let around = guard.triangles_at(self.triangles[t as usize][corner]);
        let sum = around.iter().filter_map(|&s| unit(s)).fold([0.0; 3], add);
        let l = length(sum);
        (l > 0.0).then(|| scale(sum, 1.0 / l))
    }

    /// The push of vertex `u` back across triangle `t`'s plane to the side it was on at rest,
    /// plus its margin, when it is on the other side now (half of it when `t` can move too);
    /// with `strip`, also when it is on its rest side but nearer than the margin.
    fn push_out(&self, guard: &CollisionGuard, positions: &[Vec3], u: usize, t: usize, free: &[bool], margin: f64, strip: bool) -> Option<Vec3> {
        let tri = self.triangles[t];
        let rest = tri.map(|v| self.target_neutral[v as usize]);
        let rest_side = dot(cross(sub(rest[1], rest[0]), sub(rest[2], rest[0])), sub(self.target_neutral[u], rest[0]));
        let now = tri.map(|v| positions[v as usize]);
        let normal = cross(sub(now[1], now[0]), sub(now[2], now[0]));
        let norm = length(normal);
        if rest_side == 0.0 || norm == 0.0 {
            return None;
        }
        let (side, normal) = (rest_side.signum(), scale(normal, 1.0 / norm));
        let height = dot(normal, sub(positions[u], now[0]));
        // On its rest side (farther than the margin, when the whole contact strip is held), or
        // so far behind the plane that it is not this triangle it went through (a fold of the
        // plane's far extension).
        let in_strip = strip && side * height >= 0.0 && side * height < margin * guard.margin(u);
        if !in_strip && (side * height >= 0.0 || height.abs() > MAX_DEPTH * guard.edge_length[u]) {
            return None;
        }
        let share = if tri.iter().any(|&v| free[v as usize]) { 0.5 } else { 1.0 };
        Some(scale(normal, (side * margin * guard.margin(u) - height) * share))
    }

    /// Among `near` and the triangles around its corners (not touching `w`), the one whose
    /// plane `w` projects into (barycentric coordinates above -0.25), nearest to its plane.
    fn obstacle_below(&self, guard: &CollisionGuard, positions: &[Vec3], w: usize, near: u32) -> Option<u32> {
        let mut best: Option<(f64, u32)> = None;
        for &corner in &self.triangles[near as usize] {
            for &t in guard.triangles_at(corner) {
                let tri = self.triangles[t as usize];
                if tri.contains(&(w as u32)) {
                    continue;
                }
                let p = tri.map(|v| positions[v as usize]);
                let Some((inside, height)) = projection(p, positions[w]) else { continue };
                if inside >= -0.25 && best.is_none_or(|(h, _)| height.abs() < h) {
                    best = Some((height.abs(), t));
                }
            }
        }
        best.map(|(_, t)| t)
    }
}

/// How far the local re-solve reaches from a held vertex, in its edge lengths at least, and
/// in multiples of the distance it is pushed.
const REGION_RINGS: f64 = 3.0;
const REGION_SPREAD: f64 = 3.0;

/// A corner of a pair against a static piece that moves at most this many of its edge lengths
/// is held at rest instead of pushed to the surface plus the margin: the MakeHuman lids and
/// lips already cross their eyeballs and teeth at rest, and a sub-millimetre drift there
/// (the solve spreading a mouth shape up to the lids) adds centimetres of curve.
const REST_SNAP: f64 = 0.5;

/// How deep behind an obstacle's plane (in the vertex's edge lengths) a vertex still counts as
/// having gone through it.
const MAX_DEPTH: f64 = 4.0;

/// The smallest barycentric coordinate of `q`'s projection onto triangle `p`'s plane, and
/// `q`'s signed distance to that plane; `None` for a degenerate triangle.
fn projection(p: [Vec3; 3], q: Vec3) -> Option<(f64, f64)> {
    let normal = cross(sub(p[1], p[0]), sub(p[2], p[0]));
    let area2 = dot(normal, normal);
    if area2 == 0.0 {
        return None;
    }
    let coordinate = |i: usize| dot(cross(sub(p[(i + 2) % 3], p[(i + 1) % 3]), sub(q, p[(i + 1) % 3])), normal) / area2;
    let smallest = coordinate(0).min(coordinate(1)).min(coordinate(2));
    Some((smallest, dot(normal, sub(q, p[0])) / area2.sqrt()))
}

#[cfg(test)]
mod tests {
    use super::super::{Attempt, CollisionGuard, CollisionParams, ATTEMPTS};
    use super::TemplateContacts;
    use crate::geometry::bvh::TriangleBvh;
    use crate::geometry::penetration::crossings;
    use crate::transfer::gradients::{add, to_f64, Vec3};
    use crate::transfer::collision_tests::skin_over_teeth;
    use crate::transfer::tests::{lip_closing, lips};
    use crate::transfer::virtual_edges::VirtualEdgeParams;
    use crate::transfer::{DeformationTransfer, TransferParams};

    /// `neutral + delta` as positions.
    fn posed(neutral: &[Vec3], delta: Vec<[f32; 3]>) -> Vec<Vec3> {
        neutral.iter().zip(&delta).map(|(p, d)| add(*p, to_f64(d))).collect()
    }

    /// Template lips 0.1 apart, the target's 0.04 closed by `amount` each: the transfer, its
    /// guard, the target's positions and their crossing pairs (some).
    fn closed_target_lips(amount: f32) -> (Vec<[f32; 3]>, DeformationTransfer, CollisionGuard, Vec<Vec3>, Vec<(u32, u32)>) {
        let (source, tris) = lips(0.1);
        let (target, _) = lips(0.04);
        let dt = DeformationTransfer::new(&source, &target, &tris, &TransferParams::default()).unwrap();
        let guard = CollisionGuard::new(&dt.source_neutral, &dt.target_neutral, &target, &tris, CollisionParams::default());
        let positions = posed(&dt.target_neutral, lip_closing(&target, 0.04, amount));
        let bvh = TriangleBvh::build(&positions, &tris);
        let pairs: Vec<(u32, u32)> = crossings(&positions, &tris, &bvh, None).into_iter().map(|(a, b, _)| (a, b)).collect();
        assert!(!pairs.is_empty());
        (source, dt, guard, positions, pairs)
    }

    /// `lip_closing`'s bump at `p`, 1 in the middle of the lips: along^2 x across^2.
    fn bump(p: &[f32; 3]) -> f32 {
        let along = (std::f32::consts::PI * p[0] / 1.5).sin().max(0.0);
        let across = (std::f32::consts::PI * (p[1] + 0.5)).sin().max(0.0);
        along.powi(2) * across.powi(2)
    }

    #[test]
    fn a_fold_is_the_springs_only_where_a_spring_pulls_and_the_template_stays_upright() {
        // The two-layer lips with virtual edges between the layers. A plain solve that turns
        // over a triangle with a spring at a corner is a spring fold (its springs are released,
        // its corners not held); not when the template's shape turns it over too, nor a
        // triangle no spring pulls at.
        let (source, tris) = lips(0.1);
        let (target, _) = lips(0.04);
        let params = TransferParams { virtual_edges: Some(VirtualEdgeParams { tau_d: 0.05, ..Default::default() }), edge_weight: 1.0, ..Default::default() };
        let dt = DeformationTransfer::new(&source, &target, &tris, &params).unwrap();
        let springs = dt.springs(&vec![[0.0; 3]; source.len()]);
        assert!(!springs.is_empty());
        let pulled = |v: u32| springs.iter().any(|&(i, j, _, _)| i == v as usize || j == v as usize);
        let with = tris.iter().position(|t| t.iter().any(|&v| pulled(v))).unwrap();
        let without = tris.iter().position(|t| t.iter().all(|&v| !pulled(v))).expect("a triangle no spring pulls at");
        // Each turned over by taking its first corner across the opposite edge.
        let turn = |points: &[Vec3], t: usize, out: &mut Vec<Vec3>| {
            let [a, b, c] = tris[t].map(|v| v as usize);
            out[a] = add(out[a], [0, 1, 2].map(|k| points[b][k] + points[c][k] - 2.0 * points[a][k]));
        };
        let mut plain = vec![[0.0; 3]; source.len()];
        turn(&dt.target_neutral, with, &mut plain);
        turn(&dt.target_neutral, without, &mut plain);
        let upright = dt.source_neutral.clone();
        let folds = dt.spring_folds(&springs, &plain, &upright);
        assert!(folds[with] && !folds[without]);
        let mut turned = upright.clone();
        turn(&dt.source_neutral, with, &mut turned);
        assert!(!dt.spring_folds(&springs, &plain, &turned)[with]);
        // Nothing turned over, nothing folded.
        assert!(!dt.spring_folds(&springs, &vec![[0.0; 3]; source.len()], &upright).iter().any(|&f| f));
    }

    #[test]
    fn vertices_the_templates_own_shape_takes_through_the_other_lip_are_not_held() {
        // The target's lips closed by 0.045 each cross wherever the bump f (lip_closing's
        // along^2 x across^2) exceeds 0.44.
        let (source, dt, guard, positions, pairs) = closed_target_lips(0.045);
        let free = vec![true; positions.len()];
        let held = |amount: f32| {
            let moved = vec![true; dt.triangles.len()];
            let template = dt.template_contacts(&guard, &lip_closing(&source, 0.1, amount), &moved);
            dt.offending_vertices(&guard, &positions, &pairs, &free, &[false], &ATTEMPTS[0], &template)
        };
        let bump = |v: usize| bump(&source[v]);
        // A template closing 90% of its gap crosses nowhere: the crossing target vertices are
        // held, the middle of the lips among them.
        let open = held(0.045);
        assert!(open.keys().any(|&v| bump(v) > 0.95), "{open:?}");
        // A template pressing its lips 0.02 into each other crosses where f > 0.83: the target
        // follows it there and is held only around it.
        let pressed = held(0.06);
        assert!(!pressed.is_empty() && pressed.keys().all(|v| open.contains_key(v)));
        assert!(pressed.keys().all(|&v| bump(v) < 0.95), "{pressed:?}");
    }

    #[test]
    fn the_clear_attempt_holds_the_vertices_the_template_takes_through_the_other_lip_too() {
        // The template presses its lips 0.02 into each other (a template whose neutral's lips
        // cross presses its shapes' lips through each other): the first attempt follows it and
        // leaves the middle of the target's crossed lips alone; the clear attempt holds every
        // vertex that went through, as for a template that crosses nowhere, to the same point.
        let (source, dt, guard, positions, pairs) = closed_target_lips(0.045);
        let free = vec![true; positions.len()];
        let moved = vec![true; dt.triangles.len()];
        let held = |amount: f32, attempt: &Attempt| {
            let template = dt.template_contacts(&guard, &lip_closing(&source, 0.1, amount), &moved);
            dt.offending_vertices(&guard, &positions, &pairs, &free, &[false], attempt, &template)
        };
        let clear = ATTEMPTS.iter().find(|a| a.clear).expect("a clear attempt");
        assert!(!clear.follow && !clear.strip && !clear.rest && !clear.embedded);
        let (followed, cleared, uncrossed) = (held(0.06, &ATTEMPTS[0]), held(0.06, clear), held(0.045, &ATTEMPTS[0]));
        assert!(cleared.len() > followed.len(), "{} held against {}", cleared.len(), followed.len());
        assert_eq!(cleared.len(), uncrossed.len());
        for (v, target) in &uncrossed {
            let at = cleared.get(v).unwrap_or_else(|| panic!("vertex {v} is not held"));
            assert!((0..3).all(|a| (at[a] - target[a]).abs() < 1e-12), "vertex {v}: {at:?} against {target:?}");
        }
    }

    #[test]
    fn the_contacts_attempt_acts_beside_the_templates_own_contacts_and_still_follows_them() {
        // The template presses its lips 0.02 into each other where the bump exceeds 0.83; the
        // target's, closed by 0.045 each across 0.04, cross wider (bump over 0.44). The first
        // attempt leaves the target's pairs within two one-rings of the template's contacts
        // alone; the contacts attempt acts on them too, so it holds more, yet none of the
        // vertices the template itself takes through the other lip.
        let (source, dt, guard, positions, pairs) = closed_target_lips(0.045);
        let moved = vec![true; dt.triangles.len()];
        let acted = |contacts: &TemplateContacts, attempt: &Attempt| -> Vec<(u32, u32)> {
            let pieces = |a: u32, b: u32| (dt.triangle_piece(a), dt.triangle_piece(b));
            pairs.iter().copied().filter(|&(a, b)| contacts.acts_on(&guard, attempt, (a, b), pieces(a, b))).collect()
        };
        let pressed = dt.template_contacts(&guard, &lip_closing(&source, 0.1, 0.06), &moved);
        let beside_contacts = ATTEMPTS.iter().find(|a| a.contacts).expect("a contacts attempt");
        assert!(beside_contacts.strip && !beside_contacts.follow && !beside_contacts.clear && !beside_contacts.along_path);
        let (first, beside) = (acted(&pressed, &ATTEMPTS[0]), acted(&pressed, beside_contacts));
        assert_eq!(beside, pairs);
        assert!(!first.is_empty() && first.len() < pairs.len(), "{} of {}", first.len(), pairs.len());
        assert!(pairs.iter().filter(|p| !first.contains(p)).all(|&(a, b)| pressed.near(&guard, a, b)));
        // A template that keeps its lips apart has no contacts: every attempt acts on every pair.
        let apart = dt.template_contacts(&guard, &lip_closing(&source, 0.1, 0.045), &moved);
        assert!(ATTEMPTS.iter().all(|attempt| acted(&apart, attempt) == pairs));
        let free = vec![true; positions.len()];
        let held = |pairs: &[(u32, u32)], attempt: &Attempt| dt.offending_vertices(&guard, &positions, pairs, &free, &[false], attempt, &pressed);
        let (held_first, held_last) = (held(&first, &ATTEMPTS[0]), held(&beside, beside_contacts));
        assert!(held_first.keys().all(|v| held_last.contains_key(v)) && held_last.len() > held_first.len());
        assert!(held_last.keys().all(|&v| bump(&source[v]) < 0.95), "{held_last:?}");
    }

    #[test]
    fn the_along_path_attempt_holds_lips_back_along_their_motion_only_where_the_templates_rest_crossed() {
        // The target's lips (0.04 apart) closed by 0.045 each cross in the middle. Under a
        // template whose neutral's lips rest pressed 0.02 into each other there, every corner of
        // a crossing pair is held a quarter of the way back to its rest; under a template whose
        // lips rest apart, the attempt holds nothing (the rest sides are read there).
        let (source, tris) = lips(0.1);
        let (target, _) = lips(0.04);
        let crossed: Vec<[f32; 3]> = source.iter().zip(lip_closing(&source, 0.1, 0.06)).map(|(p, d)| [p[0], p[1], p[2] + d[2]]).collect();
        let dt = DeformationTransfer::new(&crossed, &target, &tris, &TransferParams::default()).unwrap();
        let guard = CollisionGuard::new(&dt.source_neutral, &dt.target_neutral, &target, &tris, CollisionParams::default());
        assert!(!guard.template_rest_pairs.is_empty());
        let positions = posed(&dt.target_neutral, lip_closing(&target, 0.04, 0.045));
        let bvh = TriangleBvh::build(&positions, &tris);
        let pairs: Vec<(u32, u32)> = crossings(&positions, &tris, &bvh, None).into_iter().map(|(a, b, _)| (a, b)).collect();
        let free = vec![true; positions.len()];
        let held = dt.along_path_holds(&guard, &positions, &pairs, &free);
        assert!(!held.is_empty());
        let corners: Vec<usize> = pairs.iter().flat_map(|&(a, b)| tris[a as usize].into_iter().chain(tris[b as usize])).map(|v| v as usize).collect();
        for (&u, at) in &held {
            assert!(corners.contains(&u), "vertex {u} is not a corner of a crossing pair");
            let expected = [0, 1, 2].map(|k| positions[u][k] + 0.25 * (dt.target_neutral[u][k] - positions[u][k]));
            assert!((0..3).all(|k| (at[k] - expected[k]).abs() < 1e-12), "vertex {u}: {at:?} against {expected:?}");
        }
        let (_, clean, clean_guard, _, _) = closed_target_lips(0.045);
        assert!(clean_guard.template_rest_pairs.is_empty());
        assert!(clean.along_path_holds(&clean_guard, &positions, &pairs, &free).is_empty());
    }

    #[test]
    fn the_strip_attempt_also_holds_lip_vertices_nearer_than_the_margin() {
        // The target's lips (0.04 apart) closed by 0.02 each where the bump is full: they
        // touch in the middle and cross nowhere else, so near the crossing some vertices are
        // on their own side but nearer the other lip than the margin (a quarter of the 0.1
        // edges).
        let (_, dt, guard, positions, pairs) = closed_target_lips(0.024);
        let free = vec![true; positions.len()];
        // The template's shape leaves its lips apart: nothing is filtered.
        let template = dt.template_contacts(&guard, &vec![[0.0; 3]; positions.len()], &vec![true; dt.triangles.len()]);
        let held = |strip: bool| {
            let attempt = Attempt { stiffness: 1.0, margin: 1.0, strip, rest: false, follow: false, embedded: false, clear: false, contacts: false, along_path: false };
            dt.offending_vertices(&guard, &positions, &pairs, &free, &[false], &attempt, &template)
        };
        let (through, strip) = (held(false), held(true));
        assert!(!through.is_empty() && through.keys().all(|v| strip.contains_key(v)));
        // Each layer's vertex and the one facing it on the other layer (folded_strip: 22
        // profile points a cross-section, the upper layer's in reverse).
        let gap = |v: usize| {
            let (i, r) = (v / 22, v % 22);
            let (lower, upper) = if r < 11 { (v, i * 22 + 21 - r) } else { (i * 22 + 21 - r, v) };
            positions[upper][2] - positions[lower][2]
        };
        let near: Vec<usize> = strip.keys().copied().filter(|v| !through.contains_key(v)).collect();
        assert!(!near.is_empty(), "the strip holds more than the vertices that went through");
        for v in near {
            // On its own side, within the margin, and held away from the other lip.
            assert!(gap(v) > 0.0 && gap(v) < 0.05, "vertex {v}: gap {}", gap(v));
            let away = if v % 22 < 11 { positions[v][2] - strip[&v][2] } else { strip[&v][2] - positions[v][2] };
            assert!(away > 0.0, "vertex {v} is held towards the other lip");
        }
    }

    #[test]
    fn the_follow_attempt_holds_lip_vertices_where_the_templates_own_shape_has_them() {
        // The template presses its lips 0.02 through each other in the middle (0.06 each
        // across its 0.1 gap); the target's, closed by 0.045 each across 0.04, go 0.05
        // through. The first attempt leaves the middle alone (the template crosses there);
        // the follow attempt holds it where the template has it against the other lip's
        // triangle, half way (both lips move): still through, but less deep.
        let (source, dt, guard, positions, pairs) = closed_target_lips(0.045);
        let free = vec![true; positions.len()];
        let moved = vec![true; dt.triangles.len()];
        let template = dt.template_contacts(&guard, &lip_closing(&source, 0.1, 0.06), &moved);
        let held = |attempt: &Attempt| dt.offending_vertices(&guard, &positions, &pairs, &free, &[false], attempt, &template);
        let (first, follow) = (held(&ATTEMPTS[0]), held(&ATTEMPTS[5]));
        assert!(ATTEMPTS[5].follow);
        // The vertex facing `v` on the other layer (folded_strip: 22 profile points a
        // cross-section, the upper layer's in reverse), and `v`'s signed gap to it at `z`.
        let facing = |v: usize| v / 22 * 22 + 21 - v % 22;
        let gap = |v: usize, z: f64| if v % 22 < 11 { positions[facing(v)][2] - z } else { z - positions[facing(v)][2] };
        let middle: Vec<usize> = follow.keys().copied().filter(|&v| gap(v, positions[v][2]) < -0.049).collect();
        assert!(!middle.is_empty(), "{follow:?}");
        for v in middle {
            assert!(!first.contains_key(&v), "vertex {v} is held by the first attempt");
            let (now, then) = (gap(v, positions[v][2]), gap(v, follow[&v][2]));
            assert!(now < then && then < -0.02 && then > -0.045, "vertex {v}: gap {now} held at {then}");
        }
    }

    #[test]
    fn the_rest_attempt_sends_skin_through_a_piece_the_template_adds_nothing_to_back_to_rest() {
        // The skin plane rests inside the teeth (it cuts their walls). A rise of `height` in
        // the middle, 0.1 around (no closer to the walls than an edge, so the curve along them
        // stays as at rest), of 0.06: it stays inside the template's teeth (top at 0.2) and
        // pokes through the target's (0.02). Only the middle vertex moves more than half an
        // edge (0.07): its neighbours go back to rest in every attempt.
        let (source, tris) = skin_over_teeth(0.2);
        let (target, _) = skin_over_teeth(0.02);
        let n = source.len();
        let rise = |height: f32| -> Vec<[f32; 3]> {
            let bump = |p: &[f32; 3]| (1.0 - ((p[0] - 0.5).powi(2) + (p[1] - 0.5).powi(2)) / 0.01).max(0.0).powi(2);
            (0..n).map(|v| if v < 15 * 15 { [0.0, 0.0, height * bump(&source[v])] } else { [0.0; 3] }).collect()
        };
        let dt = DeformationTransfer::new(&source, &target, &tris, &TransferParams::default()).unwrap();
        let guard = CollisionGuard::new(&dt.source_neutral, &dt.target_neutral, &target, &tris, CollisionParams::default());
        let positions = posed(&dt.target_neutral, rise(0.06));
        let (skin, teeth) = (dt.piece[0], dt.piece[n - 1]);
        let sweep = |p: &[Vec3]| -> Vec<(u32, u32)> {
            crossings(p, &tris, &TriangleBvh::build(p, &tris), None).into_iter().map(|(a, b, _)| (a, b)).collect()
        };
        let rest = sweep(&dt.target_neutral);
        let pairs: Vec<(u32, u32)> = sweep(&positions).into_iter().filter(|p| !rest.contains(p)).collect();
        assert!(!pairs.is_empty());
        let free: Vec<bool> = (0..n).map(|v| dt.piece[v] == skin).collect();
        let mut static_piece = vec![false; 2];
        static_piece[teeth as usize] = true;
        let moved = vec![true; tris.len()];
        let held = |height: f32, attempt: &Attempt| {
            let contacts = dt.template_contacts(&guard, &rise(height), &moved);
            let targets = dt.offending_vertices(&guard, &positions, &pairs, &free, &static_piece, attempt, &contacts);
            (contacts.adds_none(skin, teeth), targets)
        };
        let at_rest = |targets: &super::super::Targets| {
            targets.iter().all(|(&u, t)| (0..3).all(|a| (t[a] - dt.target_neutral[u][a]).abs() < 1e-9))
        };
        // The template's rise adds no curve against its teeth: the first attempt pushes the
        // middle to the target's teeth top (a margin inside, the side it rests on); the rest
        // attempt sends it back to rest, where it crosses the teeth exactly as in the neutral.
        let (adds_none, first) = held(0.06, &ATTEMPTS[0]);
        let (_, back) = held(0.06, &ATTEMPTS[4]);
        assert!(adds_none && ATTEMPTS[4].rest);
        assert!(first.len() == back.len() && !at_rest(&first), "{first:?}");
        assert!(!back.is_empty() && at_rest(&back), "{back:?}");
        // A template rising 0.3, through its own teeth's top, adds curve against them: the rest
        // attempt holds as the first one does.
        let (adds_none, through) = held(0.3, &ATTEMPTS[0]);
        assert!(!adds_none);
        assert_eq!(held(0.3, &ATTEMPTS[4]).1, through);
    }

    #[test]
    fn the_embedded_attempt_puts_skin_resting_across_a_static_piece_back_at_rest() {
        // The skin plane cuts the teeth's walls at rest. Sliding it 0.06 along y (more than
        // half an edge, less than one) takes the triangles straddling the wall x = 0.3 across
        // the wall's diagonal: new pairs whose corners all stay on the side of the teeth they
        // rest on, so the follow attempt holds none of them. The embedded attempt puts the
        // corners of a triangle that crosses the teeth at rest back at rest, and every corner
        // that kept its side.
        let (source, tris) = skin_over_teeth(0.2);
        let (target, _) = skin_over_teeth(0.02);
        let n = source.len();
        let slide: Vec<[f32; 3]> = (0..n).map(|v| if v < 15 * 15 { [0.0, 0.06, 0.0] } else { [0.0; 3] }).collect();
        let dt = DeformationTransfer::new(&source, &target, &tris, &TransferParams::default()).unwrap();
        let guard = CollisionGuard::new(&dt.source_neutral, &dt.target_neutral, &target, &tris, CollisionParams::default());
        let positions = posed(&dt.target_neutral, slide.clone());
        let (skin, teeth) = (dt.piece[0], dt.piece[n - 1]);
        let sweep = |p: &[Vec3]| -> Vec<(u32, u32)> {
            crossings(p, &tris, &TriangleBvh::build(p, &tris), None).into_iter().map(|(a, b, _)| (a, b)).collect()
        };
        let rest = sweep(&dt.target_neutral);
        let pairs: Vec<(u32, u32)> = sweep(&positions).into_iter().filter(|p| !rest.contains(p)).collect();
        let free: Vec<bool> = (0..n).map(|v| dt.piece[v] == skin).collect();
        let mut static_piece = vec![false; 2];
        static_piece[teeth as usize] = true;
        let moved = vec![true; tris.len()];
        let contacts = dt.template_contacts(&guard, &slide, &moved);
        let held = |attempt: &Attempt| dt.offending_vertices(&guard, &positions, &pairs, &free, &static_piece, attempt, &contacts);
        let (follow, embedded) = (held(&ATTEMPTS[5]), held(&ATTEMPTS[6]));
        assert!(ATTEMPTS[6].embedded && !ATTEMPTS[5].embedded);
        // The skin corners of the new pairs whose skin triangle crosses the teeth at rest
        // (skin triangles come first, so they are a pair's first).
        let resting: Vec<usize> = pairs
            .iter()
            .filter(|&&(a, _)| rest.iter().any(|&(r, _)| r == a))
            .flat_map(|&(a, _)| tris[a as usize].map(|v| v as usize))
            .collect();
        assert!(!resting.is_empty(), "{pairs:?}");
        for &u in &resting {
            let at = embedded.get(&u).unwrap_or_else(|| panic!("vertex {u} is not held"));
            assert!((0..3).all(|a| (at[a] - dt.target_neutral[u][a]).abs() < 1e-9), "vertex {u} held at {at:?}");
        }
        assert!(resting.iter().any(|u| !follow.contains_key(u)), "{follow:?}");
        // Every other skin corner of a new pair on the side of the teeth (inside the box's
        // walls or outside) it rests on goes back to rest too: the teeth's edge went through
        // its triangle, not the corner through the teeth.
        let inside = |p: &Vec3| (0.3..=0.7).contains(&p[0]) && (0.3..=0.7).contains(&p[1]);
        let kept_side: Vec<usize> = pairs
            .iter()
            .flat_map(|&(a, _)| tris[a as usize].map(|v| v as usize))
            .filter(|&u| inside(&dt.target_neutral[u]) == inside(&positions[u]) && !resting.contains(&u))
            .collect();
        assert!(!kept_side.is_empty());
        for &u in &kept_side {
            let at = embedded.get(&u).unwrap_or_else(|| panic!("vertex {u} is not held"));
            assert!((0..3).all(|a| (at[a] - dt.target_neutral[u][a]).abs() < 1e-9), "vertex {u} held at {at:?}");
        }
    }
}
