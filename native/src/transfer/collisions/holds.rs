//! Which vertices went through another surface, and where each is held: the module docs' "Which
//! vertices, and where to" (`collisions/mod.rs`).

use std::collections::BTreeMap;

use super::{Attempt, CollisionGuard, Targets};
use crate::transfer::deformation::DeformationTransfer;
use crate::transfer::gradients::{add, cross, dot, length, scale, sub, Vec3};

impl DeformationTransfer {
    /// The free vertices that went through the other surface of a new pair, with the target
    /// position that puts each back on its rest side plus the margin, flooding from the
    /// pairs' corners to the vertices beyond the crossing. Against a static piece (teeth,
    /// an eyeball, lashes where the target has them) the target is the closest point of
    /// that piece's surface plus the margin along its normal; against a surface that moves
    /// too (lip through lip), a push along the obstacle triangle's normal.
    pub(super) fn offending_vertices(
        &self,
        guard: &CollisionGuard,
        positions: &[Vec3],
        pairs: &[(u32, u32)],
        free: &[bool],
        static_piece: &[bool],
        attempt: &Attempt,
    ) -> Targets {
        let margin = attempt.margin;
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
        let obstacle_piece = |u: usize, t: u32| {
            let p = self.triangle_piece(t);
            (p != self.piece[u] && static_piece[p as usize]).then_some(p)
        };
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
                        Some(piece) => self.push_off_piece(guard, positions, u, piece, margin),
                        None => self.push_out(guard, positions, u, obstacle as usize, free, margin),
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
                    if let Some(push) = self.push_off_piece(guard, positions, w, piece, margin) {
                        keep(w, push, obstacle, &mut pushes, &mut queue);
                    }
                    continue;
                }
                let Some(beneath) = self.obstacle_below(guard, positions, w, obstacle) else { continue };
                if let Some(push) = self.push_out(guard, positions, w, beneath as usize, free, margin) {
                    keep(w, push, beneath, &mut pushes, &mut queue);
                }
            }
        }
        pushes.into_iter().map(|(u, push)| (u, add(positions[u], push))).collect()
    }

    /// The push of vertex `u` out of the static piece `piece`, when it is on the other side
    /// of that piece's surface than at rest: to the closest point of the surface plus the
    /// margin along the surface's normal, on the rest side. The side is read at the closest
    /// point (through its face's normal, or the mean normal around its nearest corner when it
    /// lies on an edge or corner), at rest and now.
    fn push_off_piece(&self, guard: &CollisionGuard, positions: &[Vec3], u: usize, piece: u32, margin: f64) -> Option<Vec3> {
        let side_at = |q: Vec3| -> Option<(f64, Vec3, Vec3)> {
            let hit = guard.closest_on_piece(&q, piece)?;
            let normal = self.surface_normal(guard, hit.triangle, &hit.barycentric)?;
            Some((dot(normal, sub(q, hit.point)), hit.point, normal))
        };
        let (rest_height, _, _) = side_at(self.target_neutral[u])?;
        let (height, point, normal) = side_at(positions[u])?;
        if rest_height == 0.0 || rest_height * height > 0.0 || height.abs() > MAX_DEPTH * guard.edge_length[u] {
            return None;
        }
        let target = add(point, scale(normal, rest_height.signum() * margin * guard.margin(u)));
        Some(sub(target, positions[u]))
    }

    /// The unit normal of the target's neutral surface at a point of triangle `t`: the face's
    /// inside it, the mean of the faces around the nearest corner on an edge or a corner
    /// (where the face's own normal can point the wrong way for a point outside).
    fn surface_normal(&self, guard: &CollisionGuard, t: u32, barycentric: &[f64; 3]) -> Option<Vec3> {
        let unit = |t: u32| {
            let p = self.triangles[t as usize].map(|v| self.target_neutral[v as usize]);
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
    /// plus its margin, when it is on the other side now (half of it when `t` can move too).
    fn push_out(&self, guard: &CollisionGuard, positions: &[Vec3], u: usize, t: usize, free: &[bool], margin: f64) -> Option<Vec3> {
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
        // On its rest side, or so far behind the plane that it is not this triangle it went
        // through (a fold of the plane's far extension).
        if side * height >= 0.0 || height.abs() > MAX_DEPTH * guard.edge_length[u] {
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
