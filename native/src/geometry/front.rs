//! The rig's front: the direction from the face towards a viewer in front of it, and the
//! face's up, both in the mesh's own coordinates, found from the rig itself so that a face
//! stored in any orientation (facing -Y with Z up, facing +Z with Y up, ...) is seen from
//! its front by the occlusion conflicts and the reference sheet.
//!
//! How it is found:
//! 1. **Where the face moves.** Each vertex carries the weight `w_v = sum_k |D_k[v]| /
//!    max_n |D_k[n]|` over the non-inert shapes (every shape counts alike, whatever its
//!    amplitude), so the weight lies on the moving regions: eyelids, brows, lips, jaw.
//! 2. **Which way they face.** The raw front is `sum_v w_v n_v`, the motion-weighted mean of
//!    the unit (area-weighted) vertex normals: the moving regions of a face look at whoever
//!    faces it. Normals are taken outward: when the mesh's signed volume about its centroid is
//!    negative (triangles wound inwards) every normal is flipped.
//! 3. **The symmetry plane.** The mirror map across the caller's lateral axis
//!    ([`MirrorMap`]) is tried first, then the two other coordinate planes; the first that
//!    matches at least [`SYMMETRIC_SHARE`] of the vertices, and across which the weights are
//!    mirrored (within [`MOTION_ASYMMETRY`]), is the face's symmetry plane, its
//!    normal the left-right axis, and the front is the raw front with its left-right
//!    component removed. Without such a plane (a face turned off the axes, or not centred on
//!    a coordinate plane), the raw front is used as it is.
//! 4. **Snapped to the mesh's axes.** Faces are modelled axis-aligned and the moving regions'
//!    mean normal tilts a little (lips and chin look slightly down), so a front within
//!    [`SNAP_DEGREES`] of a signed mesh axis is that axis exactly: the camera a rigger would
//!    set with the numpad.
//! 5. **Up.** The eyes are above the mouth: up is the direction, perpendicular to the front,
//!    from the moving regions of the shapes named for the mouth and jaw (`mouth`, `jaw`,
//!    `lip`, `chin`, `tongue`) to those named for the eyes and brows (`eye`, `blink`, `brow`,
//!    `lid`, `squint`), in the symmetry plane when there is one, and snapped to an axis like
//!    the front. A rig whose names say neither gets +Z (Blender's up), or +Y (the glTF and
//!    FBX up) when the front is along Z, and [`UpSource::Assumed`] says so.

use serde::Serialize;

use super::mat3::{add, cross, dot, length, scale, sub, to_f64, unit, Vec3};
use super::mirror::MirrorMap;
use crate::error::ShapesmithResult;
use crate::invalid;
use crate::rig::{norm, RigView, INERT_FRACTION};

/// The share of vertices the mirror map must match for a coordinate plane to be the face's
/// symmetry plane.
pub const SYMMETRIC_SHARE: f64 = 0.5;

/// How far the motion weights may differ from their mirror images, as a share of their
/// total, across the face's symmetry plane.
pub const MOTION_ASYMMETRY: f64 = 0.25;

/// A found direction within this angle of a signed mesh axis is snapped to it.
pub const SNAP_DEGREES: f64 = 25.0;

/// Mirror tolerance, as a fraction of the bounding-box diagonal (as the mirror map's).
const MIRROR_TOLERANCE: f64 = 1e-3;

/// Names that mark a shape as moving the upper face (eyes, brows) or the lower (mouth, jaw).
const UPPER_NAMES: [&str; 5] = ["eye", "blink", "brow", "lid", "squint"];
const LOWER_NAMES: [&str; 5] = ["mouth", "jaw", "lip", "chin", "tongue"];

/// How the up direction was found.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum UpSource {
    /// From the mouth's moving regions to the eyes'.
    Names,
    /// No shape named for the eyes or the mouth moves: +Z, or +Y for a front along Z.
    Assumed,
}

/// The rig's front and up (unit vectors in mesh coordinates) and how they were found.
#[derive(Clone, Debug, Serialize)]
pub struct Front {
    /// From the face towards a viewer in front of it.
    pub front: Vec3,
    /// Perpendicular to `front`: from the mouth towards the eyes.
    pub up: Vec3,
    /// The coordinate axis normal to the face's symmetry plane, when one was found.
    pub lateral_axis: Option<usize>,
    pub up_source: UpSource,
    /// Whether `front` is a mesh axis exactly (within [`SNAP_DEGREES`] of the found one).
    pub snapped: bool,
    /// Angle, in degrees, between the found front and the one returned (0 when not snapped).
    pub snap_degrees: f64,
}

/// Finds the front and up of `rig` (see the module docs); `axis` is the lateral axis the
/// caller's symmetry settings name, tried first. Errors when no shape moves.
pub fn find_front(rig: &RigView, axis: usize) -> ShapesmithResult<Front> {
    if axis > 2 {
        return Err(invalid!("the symmetry axis must be 0, 1 or 2, got {axis}"));
    }
    let weights = motion_weights(rig);
    if weights.iter().all(|&w| w == 0.0) {
        return Err(invalid!("no shape key moves the mesh: the face's front cannot be found"));
    }
    let points: Vec<Vec3> = rig.neutral.iter().map(to_f64).collect();
    let normals = outward_normals(&points, rig.triangles);
    let mut raw = [0.0; 3];
    for (n, &w) in normals.iter().zip(&weights) {
        raw = add(raw, scale(*n, w));
    }
    let lateral_axis = symmetry_axis(rig.neutral, &weights, axis);
    if let Some(a) = lateral_axis {
        raw[a] = 0.0;
    }
    let Some(found) = unit(raw) else {
        return Err(invalid!("the moving regions' normals cancel out: the face's front cannot be found; pick a camera"));
    };
    let (front, snapped) = snap(found, None);
    let snap_degrees = if snapped { angle_degrees(found, front) } else { 0.0 };
    let (up, up_source) = find_up(rig, front, lateral_axis);
    Ok(Front { front, up, lateral_axis, up_source, snapped, snap_degrees })
}

/// `w_v = sum_k |D_k[v]| / max_n |D_k[n]|` over the non-inert shapes.
fn motion_weights(rig: &RigView) -> Vec<f64> {
    let floor = INERT_FRACTION * rig.bbox_diagonal();
    let mut weights = vec![0.0; rig.n_vertices()];
    for k in 0..rig.n_shapes() {
        let max = rig.max_displacement(k);
        if max > floor {
            for (w, d) in weights.iter_mut().zip(rig.delta(k)) {
                *w += norm(d) / max;
            }
        }
    }
    weights
}

/// Unit area-weighted vertex normals (zero at a vertex in no triangle), flipped when the
/// signed volume about the centroid says the triangles are wound inwards.
pub(crate) fn outward_normals(points: &[Vec3], triangles: &[[u32; 3]]) -> Vec<Vec3> {
    let centroid = scale(points.iter().fold([0.0; 3], |s, &p| add(s, p)), 1.0 / points.len().max(1) as f64);
    let mut normals = vec![[0.0; 3]; points.len()];
    let mut volume = 0.0;
    for t in triangles {
        let [a, b, c] = t.map(|v| sub(points[v as usize], centroid));
        let n = cross(sub(b, a), sub(c, a));
        volume += dot(a, cross(b, c));
        for &v in t {
            normals[v as usize] = add(normals[v as usize], n);
        }
    }
    let sign = if volume < 0.0 { -1.0 } else { 1.0 };
    normals.iter().map(|&n| unit(n).map_or([0.0; 3], |u| scale(u, sign))).collect()
}

/// The first of `preferred`, then the other axes, across whose zero plane the mirror map
/// matches at least [`SYMMETRIC_SHARE`] of the vertices and the motion is mirrored too: the
/// weights differ from their mirror images by at most [`MOTION_ASYMMETRY`] of their total
/// (a head can be as round front to back as left to right; only its left-right plane
/// mirrors what moves).
fn symmetry_axis(points: &[[f32; 3]], weights: &[f64], preferred: usize) -> Option<usize> {
    let order = [preferred, (preferred + 1) % 3, (preferred + 2) % 3];
    order.into_iter().find(|&axis| {
        let map = MirrorMap::new(points, axis, MIRROR_TOLERANCE);
        if ((points.len() - map.unmatched.len()) as f64) < SYMMETRIC_SHARE * points.len() as f64 {
            return false;
        }
        let (mut difference, mut total) = (0.0, 0.0);
        for (v, partner) in map.partner.iter().enumerate() {
            if let Some(m) = partner {
                difference += (weights[v] - weights[*m as usize]).abs();
                total += weights[v];
            }
        }
        total > 0.0 && difference <= MOTION_ASYMMETRY * total
    })
}

/// Up: perpendicular to `front`, from the lower face's moving regions to the upper's.
fn find_up(rig: &RigView, front: Vec3, lateral_axis: Option<usize>) -> (Vec3, UpSource) {
    let upper = region_centroid(rig, &UPPER_NAMES, |_| true);
    let lower = region_centroid(rig, &LOWER_NAMES, |_| true);
    // Within the symmetry plane, up is one of the two directions perpendicular to the front.
    let plane_up = lateral_axis.and_then(|a| unit(cross(front, axis_vector(a, 1.0))));
    if let (Some(upper), Some(lower)) = (upper, lower) {
        let rise = sub(upper, lower);
        let up = match plane_up {
            Some(u) => Some(if dot(u, rise) < 0.0 { scale(u, -1.0) } else { u }),
            None => unit(sub(rise, scale(front, dot(rise, front)))).map(|u| snap(u, Some(front)).0),
        };
        if let Some(up) = up {
            if length(rise) > 1e-3 * rig.bbox_diagonal() {
                return (up, UpSource::Names);
            }
        }
    }
    (assumed_up(front), UpSource::Assumed)
}

/// The motion-weighted centroid of the shapes whose names contain one of `words`
/// (case-insensitive), over the rest points `keep` accepts, or `None` when none of them moves.
pub(crate) fn region_centroid(rig: &RigView, words: &[&str], keep: impl Fn(Vec3) -> bool) -> Option<Vec3> {
    let floor = INERT_FRACTION * rig.bbox_diagonal();
    let mut sum = [0.0; 3];
    let mut total = 0.0;
    for k in 0..rig.n_shapes() {
        let name = rig.names[k].to_lowercase();
        let max = rig.max_displacement(k);
        if max <= floor || !words.iter().any(|w| name.contains(w)) {
            continue;
        }
        for (p, d) in rig.neutral.iter().zip(rig.delta(k)) {
            let p = to_f64(p);
            if !keep(p) {
                continue;
            }
            let w = norm(d) / max;
            sum = add(sum, scale(p, w));
            total += w;
        }
    }
    (total > 0.0).then(|| scale(sum, 1.0 / total))
}

/// +Z (Blender's up), or +Y (the glTF and FBX up) for a front along Z, made perpendicular to
/// `front`.
fn assumed_up(front: Vec3) -> Vec3 {
    let e = axis_vector(if front[2].abs() < 0.7 { 2 } else { 1 }, 1.0);
    unit(sub(e, scale(front, dot(e, front)))).map_or(e, |u| snap(u, Some(front)).0)
}

/// `direction` (unit) snapped to the nearest signed mesh axis when within [`SNAP_DEGREES`]
/// (and, given `perpendicular_to`, perpendicular to it), with whether it was.
fn snap(direction: Vec3, perpendicular_to: Option<Vec3>) -> (Vec3, bool) {
    let best = (0..3).max_by(|&a, &b| direction[a].abs().total_cmp(&direction[b].abs())).unwrap_or(0);
    let axis = axis_vector(best, direction[best].signum());
    let square = perpendicular_to.is_none_or(|p| dot(p, axis).abs() < 1e-9);
    if square && angle_degrees(direction, axis) <= SNAP_DEGREES {
        (axis, true)
    } else {
        (direction, false)
    }
}

fn axis_vector(axis: usize, sign: f64) -> Vec3 {
    let mut e = [0.0; 3];
    e[axis] = sign;
    e
}

fn angle_degrees(a: Vec3, b: Vec3) -> f64 {
    dot(a, b).clamp(-1.0, 1.0).acos().to_degrees()
}

#[cfg(test)]
#[path = "front_tests.rs"]
mod tests;
