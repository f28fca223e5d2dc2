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
        if attempt.along_path && attempt.between {
            return self.along_path_off_pieces(positions, pairs, free, static_piece);
        }
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
            for t in [a, b] {
                self.hold_back_along_motion(t, ALONG_PATH_STEP, positions, free, &mut targets);
            }
        }
        targets
    }

    /// The last attempt's holds (module docs' "Backing off"): each free corner of a pair
    /// between a moving piece and a static one an eighth of the way back along its own motion,
    /// `t_u = x_u + (B0_u - x_u) / 8`, renewed each round. Skin that rests across the teeth
    /// slides onto new teeth triangles without any corner changing side, which no rest-side
    /// push sees; going back the way it came ends where it rests, crossing as at rest. Held
    /// back, the inner lip presses into the other lip: an eighth (not the lips' quarter) stops
    /// at a round where both parts meet the criterion on the crossing-lips heads.
    fn along_path_off_pieces(&self, positions: &[Vec3], pairs: &[(u32, u32)], free: &[bool], static_piece: &[bool]) -> Targets {
        let mut targets = Targets::new();
        for &(a, b) in pairs {
            let (p, q) = (self.triangle_piece(a), self.triangle_piece(b));
            if p == q {
                continue;
            }
            for (side, other) in [(a, q), (b, p)] {
                if static_piece[other as usize] {
                    self.hold_back_along_motion(side, BACK_OFF_STEP, positions, free, &mut targets);
                }
            }
        }
        targets
    }

    /// Holds each free corner `u` of `triangle` that moved a `share` of the way back along its
    /// own motion: `t_u = x_u + (B0_u - x_u) * share`.
    fn hold_back_along_motion(&self, triangle: u32, share: f64, positions: &[Vec3], free: &[bool], targets: &mut Targets) {
        for &u in &self.triangles[triangle as usize] {
            let u = u as usize;
            let back = sub(self.target_neutral[u], positions[u]);
            if free[u] && length(back) > 0.0 {
                targets.insert(u, add(positions[u], scale(back, share)));
            }
        }
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

/// The share of its own motion a lip vertex of the along-path attempt is held back by each
/// round ([`DeformationTransfer::along_path_holds`]).
const ALONG_PATH_STEP: f64 = 0.25;

/// The share of its own motion a vertex of the last attempt is held back by each round
/// ([`DeformationTransfer::along_path_off_pieces`]).
const BACK_OFF_STEP: f64 = 0.125;

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
#[path = "holds_tests.rs"]
mod tests;
