//! Optimal-step non-rigid ICP (Amberg, Romdhani & Vetter 2007), in the displacement form
//! described in the module's Deviations: for each stiffness `alpha` of a decreasing schedule,
//! closest points on the character are found, the normal system is factorised once, and a
//! few closest-point iterations back-substitute into that factor.
//!
//! Energy of one step, over the skin's displacements `d = x - x_rest` (Eq. (12) of Amberg et
//! al. with their stiffness term replaced by a bending energy on the displacements, see the
//! module's Deviations):
//! $$ E(d) = \sum_i w_i |x^{rest}_i + d_i - u_i|^2 + \alpha \sum_i \Big| \frac{1}{|N(i)|}
//!           \sum_{j \in N(i)} d_j - d_i \Big|^2 + \beta \sum_l |B_l (x^{rest} + d) - q_l|^2 $$
//! `u_i` the closest character point, `w_i` 1 or 0 (rejected); for a rim vertex of a paired
//! hole (`rims`) `u_i` is instead its fixed place on the character's hole and `w_i` the rim
//! weight (the matrix keeps its pattern: only the diagonal weights change); `N(i)` the template neighbours
//! of skin vertex `i` (the uniform Laplacian `L`, so the stiffness block is `alpha L^T L`),
//! `B_l` the barycentric row of landmark `l` on the template, `q_l` its character point.

use rayon::prelude::*;

use crate::error::ShapesmithResult;
use crate::geometry::bvh::TriangleBvh;
use crate::geometry::closest_point::SurfacePoint;
use crate::geometry::mat3::{add, dot, length, sub, vertex_normals, Vec3};
use crate::geometry::topology::{boundary_edges, unique_edges};
use crate::progress::Progress;
use crate::sparse::SymmetricMatrix;

use super::rims::RimTarget;
use super::symmetry::{symmetrize, MirrorPlane};
use super::FitParams;

/// A symmetric fit's mirror: the template's vertex map, the character's plane, and the
/// vertices it averages (the skin).
pub struct FitMirror<'a> {
    pub partner: &'a [Option<u32>],
    pub plane: MirrorPlane,
    pub used: &'a [bool],
}

/// A template point tied to a character point: barycentric on a template skin triangle.
#[derive(Clone, Copy, Debug)]
pub struct Landmark {
    pub corners: [u32; 3],
    pub barycentric: Vec3,
    pub target: Vec3,
}

/// The character's surface as the fit sees it: the triangles it may snap to, their unit
/// normals, and which edges and vertices lie on its boundary.
pub struct TargetSurface<'a> {
    pub bvh: TriangleBvh,
    pub triangles: &'a [[u32; 3]],
    pub normals: Vec<Vec3>,
    boundary_edges: std::collections::HashSet<(u32, u32)>,
    boundary_vertices: Vec<bool>,
}

impl<'a> TargetSurface<'a> {
    pub fn new(points: &[Vec3], triangles: &'a [[u32; 3]]) -> Self {
        let normals = triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|v| points[v as usize]);
                let n = crate::geometry::mat3::cross(sub(b, a), sub(c, a));
                let len = length(n);
                if len > 0.0 { n.map(|x| x / len) } else { n }
            })
            .collect();
        let boundary_edges = boundary_edges(triangles);
        let mut boundary_vertices = vec![false; points.len()];
        for &(a, b) in &boundary_edges {
            boundary_vertices[a as usize] = true;
            boundary_vertices[b as usize] = true;
        }
        Self { bvh: TriangleBvh::build(points, triangles), triangles, normals, boundary_edges, boundary_vertices }
    }

    /// Whether a closest point lies on the surface's boundary (an edge of one triangle, or a
    /// corner on such an edge): there the closest point is where the template runs past the
    /// character's open edge, not a true correspondence.
    pub fn on_boundary(&self, hit: &SurfacePoint) -> bool {
        let t = self.triangles[hit.triangle as usize];
        let zeros: Vec<usize> = (0..3).filter(|&i| hit.barycentric[i] == 0.0).collect();
        match zeros.len() {
            0 => false,
            1 => {
                let (a, b) = (t[(zeros[0] + 1) % 3], t[(zeros[0] + 2) % 3]);
                self.boundary_edges.contains(&(a.min(b), a.max(b)))
            }
            _ => (0..3).any(|i| hit.barycentric[i] != 0.0 && self.boundary_vertices[t[i] as usize]),
        }
    }
}

/// What the fit reached.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct FitStats {
    /// Stiffness steps run and closest-point iterations in all.
    pub steps: usize,
    pub iterations: usize,
    /// Skin vertices with an accepted closest point at the last step, as a fraction.
    pub matched_fraction: f64,
}

/// Fits the skin vertices `skin` (sorted) of the template at `rest` (already aligned) onto
/// `surface`; returns every vertex's fitted position (non-skin vertices as at rest).
/// `skin_triangles` are the template triangles among skin vertices. With `mirror`, the
/// positions are averaged with their mirror after every solve (`symmetry`), so that both
/// sides see alike closest points and the fit comes out symmetric.
#[allow(clippy::too_many_arguments)]
pub fn fit_skin(
    rest: &[Vec3],
    skin: &[u32],
    skin_triangles: &[[u32; 3]],
    landmarks: &[Landmark],
    rims: &[RimTarget],
    surface: &TargetSurface,
    params: &FitParams,
    diagonal: f64,
    mirror: Option<&FitMirror>,
    progress: &dyn Progress,
) -> ShapesmithResult<(Vec<Vec3>, FitStats)> {
    let n = skin.len();
    let mut local = vec![u32::MAX; rest.len()];
    for (i, &v) in skin.iter().enumerate() {
        local[v as usize] = i as u32;
    }
    let edges: Vec<(usize, usize)> = unique_edges(skin_triangles).into_iter().map(|(a, b)| (local[a as usize] as usize, local[b as usize] as usize)).collect();
    let max_distance = params.max_distance * diagonal;
    let cos_max_angle = params.max_angle_degrees.to_radians().cos();
    let mut positions: Vec<Vec3> = rest.to_vec();
    let mut stats = FitStats::default();
    // A tiny pull towards the rest shape keeps the system definite when every vertex of the
    // skin is rejected; it is far below every other weight.
    let ridge = 1e-8;
    let bending = bending_entries(n, &edges);
    // Rim vertices target their place on the character's matching hole (`rims`), with the
    // rim weight, whatever their closest point.
    let mut rim_target: Vec<Option<Vec3>> = vec![None; n];
    for rim in rims {
        rim_target[local[rim.vertex as usize] as usize] = Some(rim.target);
    }
    // `W + alpha L^T L + beta B^T B`; its pattern is the same at every step, so it is ordered
    // once.
    let assemble = |weights: &[f64], alpha: f64, beta: f64| {
        let mut entries = Vec::with_capacity(n + bending.len() + 6 * landmarks.len());
        entries.extend((0..n).map(|i| (i, i, weights[i] + ridge)));
        entries.extend(bending.iter().map(|&(a, b, value)| (a, b, alpha * value)));
        for l in landmarks {
            for r in 0..3 {
                for c in 0..=r {
                    let (vr, vc) = (local[l.corners[r] as usize] as usize, local[l.corners[c] as usize] as usize);
                    entries.push((vr, vc, beta * l.barycentric[r] * l.barycentric[c]));
                }
            }
        }
        SymmetricMatrix::from_triplets(n, entries)
    };
    let order = assemble(&vec![1.0; n], 1.0, 1.0).fill_reducing_order()?;
    let steps = params.stiffness.len();
    for (step, &alpha) in params.stiffness.iter().enumerate() {
        progress.checkpoint(step as f64 / steps as f64)?;
        let beta = params.landmark_weight * alpha;
        let matches = closest_points(&positions, skin, skin_triangles, surface, max_distance, cos_max_angle);
        let weights: Vec<f64> = matches
            .iter()
            .zip(&rim_target)
            .map(|(m, rim)| if rim.is_some() { params.rim_weight } else if m.is_some() { 1.0 } else { 0.0 })
            .collect();
        let matrix = assemble(&weights, alpha, beta);
        let factor = matrix.factor(&order)?;
        let mut matches = matches;
        for _ in 0..params.iterations {
            stats.iterations += 1;
            // Right-hand side: data targets (a vertex accepted at the step's start but not now
            // is held where it is), landmark targets.
            let mut rhs: Vec<Vec3> = (0..n)
                .map(|i| {
                    let v = skin[i] as usize;
                    if weights[i] == 0.0 {
                        return [0.0; 3];
                    }
                    let target = rim_target[i].unwrap_or_else(|| matches[i].map_or(positions[v], |hit| hit.point));
                    sub(target, rest[v]).map(|x| x * weights[i])
                })
                .collect();
            for l in landmarks {
                let current: Vec3 = (0..3).fold([0.0; 3], |acc, k| add(acc, rest[l.corners[k] as usize].map(|x| x * l.barycentric[k])));
                let residual = sub(l.target, current);
                for k in 0..3 {
                    let i = local[l.corners[k] as usize] as usize;
                    rhs[i] = add(rhs[i], residual.map(|x| x * beta * l.barycentric[k]));
                }
            }
            let displacement = factor.solve_points(&rhs);
            let mut largest_move: f64 = 0.0;
            for (i, d) in displacement.iter().enumerate() {
                let v = skin[i] as usize;
                let moved = add(rest[v], *d);
                largest_move = largest_move.max(length(sub(moved, positions[v])));
                positions[v] = moved;
            }
            if let Some(mirror) = mirror {
                symmetrize(&mut positions, mirror.partner, mirror.used, &mirror.plane);
            }
            if largest_move < params.tolerance * diagonal {
                break;
            }
            matches = closest_points(&positions, skin, skin_triangles, surface, max_distance, cos_max_angle);
        }
        stats.steps = step + 1;
    }
    let last = closest_points(&positions, skin, skin_triangles, surface, max_distance, cos_max_angle);
    stats.matched_fraction = last.iter().filter(|m| m.is_some()).count() as f64 / n.max(1) as f64;
    Ok((positions, stats))
}

/// The lower triangle of `L^T L`, `L` the uniform Laplacian of the graph (`(L d)_i` = the mean
/// of `d` over `i`'s neighbours minus `d_i`), as `(row, column, value)` with each off-diagonal
/// pair once: row `i` of `L` couples `i` and its neighbours, so `L^T L` reaches two rings.
fn bending_entries(n: usize, edges: &[(usize, usize)]) -> Vec<(usize, usize, f64)> {
    let mut neighbours = vec![Vec::new(); n];
    for &(a, b) in edges {
        neighbours[a].push(b);
        neighbours[b].push(a);
    }
    let mut entries = Vec::new();
    for (i, around) in neighbours.iter().enumerate() {
        if around.is_empty() {
            continue;
        }
        let share = 1.0 / around.len() as f64;
        let row: Vec<(usize, f64)> = std::iter::once((i, -1.0)).chain(around.iter().map(|&j| (j, share))).collect();
        for &(a, la) in &row {
            for &(b, lb) in &row {
                if a >= b {
                    entries.push((a, b, la * lb));
                }
            }
        }
    }
    entries
}

/// Each skin vertex's accepted closest point on the character: within `max_distance`, the
/// surface normal within the angle of the template's vertex normal, not on the boundary.
fn closest_points(
    positions: &[Vec3],
    skin: &[u32],
    skin_triangles: &[[u32; 3]],
    surface: &TargetSurface,
    max_distance: f64,
    cos_max_angle: f64,
) -> Vec<Option<SurfacePoint>> {
    let normals = vertex_normals(positions, skin_triangles);
    skin.par_iter()
        .map(|&v| {
            let v = v as usize;
            let hit = surface.bvh.closest_point(&positions[v], max_distance)?;
            let compatible = dot(normals[v], surface.normals[hit.triangle as usize]) >= cos_max_angle;
            (compatible && !surface.on_boundary(&hit)).then_some(hit)
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::bending_entries;

    /// `L^T L` from the entries against the dense product on a small graph (a square with a
    /// diagonal and a pendant vertex): every entry, both triangles summed once.
    #[test]
    fn bending_entries_are_the_dense_laplacian_squared() {
        let n = 5;
        let edges = [(0, 1), (1, 2), (2, 3), (3, 0), (0, 2), (3, 4)];
        let mut laplacian = vec![vec![0.0; n]; n];
        let mut degree = vec![0.0; n];
        for &(a, b) in &edges {
            degree[a] += 1.0;
            degree[b] += 1.0;
        }
        for &(a, b) in &edges {
            laplacian[a][b] = 1.0 / degree[a];
            laplacian[b][a] = 1.0 / degree[b];
        }
        (0..n).for_each(|i| laplacian[i][i] = -1.0);
        let mut assembled = vec![vec![0.0; n]; n];
        for (row, column, value) in bending_entries(n, &edges) {
            assert!(row >= column);
            assembled[row][column] += value;
            if row != column {
                assembled[column][row] += value;
            }
        }
        for r in 0..n {
            for c in 0..n {
                let dense: f64 = (0..n).map(|i| laplacian[i][r] * laplacian[i][c]).sum();
                assert!((assembled[r][c] - dense).abs() < 1e-12, "({r}, {c}): {} vs {dense}", assembled[r][c]);
            }
        }
    }
}
