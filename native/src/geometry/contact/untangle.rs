//! The contact solve's start on the minimiser's side of what lies between it and the neutral
//! (method, section 3). A key's straight path from the neutral is not a way a surface can go:
//! a closing lid passes through the bulge of a coarse eyeball on the way though neither its
//! rest nor its closed place does, and the minimisation started at the neutral stops against
//! that bulge. So the solve starts from the minimiser itself, untangled: intersection contour
//! minimisation (Volino and Magnenat-Thalmann 2006), the length of the added crossings'
//! intersection curve shortened by a gradient flow, and pairs closer than [`NEAR`] of their
//! barrier's range pushed apart, until neither is left or [`STEPS`] steps have run.
//!
//! The flow moves the region in the shape energy's own metric: each step solves
//! `(A_RR + mu D) p = g` (`g` the gradient of the curve's length and of the near pairs'
//! closeness, `A_RR` the energy's block over the region, `mu D` the solve's screening), so a
//! crossing is undone by bending the surface around it as the energy bends it, not by dragging
//! the crossing triangles' corners alone (a plain gradient step folds a lid's margin).

use super::barrier::pair_squared;
use super::exemptions::Exemptions;
use super::newton::{region_slots, ContactMesh, KnownPairs, Pair, SolveBroadPhase};
use super::shape::ContactScene;
use crate::error::ShapesmithResult;
use crate::geometry::penetration::{crossings, intersection_length};
use crate::sparse::{MatrixRows, SymmetricMatrix};

/// Steps of the flow at most; a shape whose curve is not gone by then starts at rest around
/// what is left ([`ContactScene::resolve`]).
const STEPS: usize = 200;

/// A pair closer than this fraction of its barrier's range is pushed apart: from closer, the
/// barrier's first Newton steps crawl.
const NEAR: f64 = 1e-2;

/// The farthest vertex of the first step moves this many of its `d_hat`; the reach grows by
/// half while the curve shortens, up to [`LONGEST_REACH`], and halves when it does not.
const FIRST_REACH: f64 = 0.25;
const LONGEST_REACH: f64 = 2.0;

/// Central differences of the curve's length and of a pair's distance, at this fraction of a
/// vertex's `d_hat`.
const DIFFERENCE: f64 = 1e-3;

/// What the flow reached: all N positions (the minimiser outside the region) and whether
/// the region is untangled (no added crossing and no pair nearer than [`NEAR`]).
pub(super) struct Untangled {
    pub positions: Vec<[f64; 3]>,
    pub clean: bool,
}

/// The minimiser's region untangled by the flow (module docs). `screening` is the solve's
/// `mu` (a fraction of each vertex's diagonal).
pub(super) fn untangle(
    scene: &ContactScene,
    mesh: &ContactMesh,
    exempt: &Exemptions,
    rows: &MatrixRows,
    minimiser: &[[f64; 3]],
    region: &[usize],
    screening: f64,
) -> ShapesmithResult<Untangled> {
    let (slot, in_region) = region_slots(minimiser.len(), region);
    let metric = region_metric(rows, region, &slot, screening);
    let factor = metric.factor(&metric.fill_reducing_order()?)?;
    let touched: Vec<bool> = scene.triangles().iter().map(|t| t.iter().any(|&v| in_region[v as usize])).collect();
    let d_hat = |v: usize| mesh.d_hat[v];
    let sweep = |x: &[[f64; 3]]| crossings(x, scene.triangles(), &scene.bvh.refitted(x, scene.triangles()), Some(&touched));
    // Only the region moves in the flow: the fixed primitives' trees serve every step, and a
    // pair's exemption and range are its vertices' alone (rebuilt per step, the trees over the
    // whole mesh were two thirds of the flow's time).
    let broad = SolveBroadPhase::new(mesh, minimiser, &in_region);
    let mut known = KnownPairs::default();
    let mut x = minimiser.to_vec();
    let (mut reach, mut last_curve) = (FIRST_REACH, f64::INFINITY);
    for _ in 0..STEPS {
        let swept = sweep(&x);
        let near = nearer(mesh, &broad, &x, &mut known, NEAR);
        let added = scene.added_crossings(&swept, exempt);
        if added.is_empty() && near.is_empty() {
            return Ok(Untangled { positions: x, clean: true });
        }
        let mut gradient = vec![[0.0f64; 3]; region.len()];
        let mut curve = 0.0;
        for &(a, b) in &added {
            let corners = [scene.triangles()[a as usize], scene.triangles()[b as usize]];
            let mut points = corners.map(|t| t.map(|v| x[v as usize]));
            curve += intersection_length(points[0], points[1]).unwrap_or(0.0);
            for (side, corner) in (0..2).flat_map(|side| (0..3).map(move |corner| (side, corner))) {
                let v = corners[side][corner] as usize;
                if !in_region[v] {
                    continue;
                }
                let h = DIFFERENCE * d_hat(v);
                for c in 0..3 {
                    let held = points[side][corner][c];
                    let mut length_at = |offset: f64| {
                        points[side][corner][c] = held + offset;
                        intersection_length(points[0], points[1]).unwrap_or(0.0)
                    };
                    let slope = (length_at(h) - length_at(-h)) / (2.0 * h);
                    points[side][corner][c] = held;
                    gradient[slot[v]][c] += slope;
                }
            }
        }
        for pair in &near {
            let mut points = pair.points(&x);
            for (i, &v) in pair.vertices.iter().enumerate() {
                let v = v as usize;
                if !in_region[v] {
                    continue;
                }
                let h = DIFFERENCE * d_hat(v);
                for c in 0..3 {
                    let held = points[i][c];
                    let mut distance_at = |offset: f64| {
                        points[i][c] = held + offset;
                        pair_squared(pair.kind, &points).sqrt()
                    };
                    // Closeness counts as curve: its descent pushes the pair apart.
                    let slope = (distance_at(h) - distance_at(-h)) / (2.0 * h);
                    points[i][c] = held;
                    gradient[slot[v]][c] -= slope;
                }
            }
        }
        let direction = factor.solve_points(&gradient);
        let farthest = region.iter().zip(&direction).map(|(&v, p)| (p[0] * p[0] + p[1] * p[1] + p[2] * p[2]).sqrt() / d_hat(v)).fold(0.0, f64::max);
        if farthest == 0.0 {
            break;
        }
        reach = if curve < last_curve { (1.5 * reach).min(LONGEST_REACH) } else { 0.5 * reach };
        last_curve = curve;
        let step = reach / farthest;
        for (&v, p) in region.iter().zip(&direction) {
            for c in 0..3 {
                x[v][c] -= step * p[c];
            }
        }
    }
    Ok(Untangled { positions: x, clean: false })
}

/// `A_RR + mu D`: the energy's rows restricted to the region, its diagonal screened.
fn region_metric(rows: &MatrixRows, region: &[usize], slot: &[usize], screening: f64) -> SymmetricMatrix {
    let mut entries = Vec::new();
    for (s, &v) in region.iter().enumerate() {
        for &(u, a) in rows.row(v) {
            if slot[u] != usize::MAX && slot[u] <= s {
                entries.push((s, slot[u], if u == v { (1.0 + screening) * a } else { a }));
            }
        }
    }
    SymmetricMatrix::from_triplets(region.len(), entries)
}

/// The pairs with a vertex in the region closer than `fraction` of their barrier's range at `x`.
pub(super) fn pairs_nearer(mesh: &ContactMesh, x: &[[f64; 3]], in_region: &[bool], fraction: f64) -> Vec<Pair> {
    nearer(mesh, &SolveBroadPhase::new(mesh, x, in_region), x, &mut KnownPairs::default(), fraction)
}

/// [`pairs_nearer`] with the region's broad phase `broad` (its fixed primitives where they
/// are at `x`) and the pairs met so far `known`.
fn nearer(mesh: &ContactMesh, broad: &SolveBroadPhase, x: &[[f64; 3]], known: &mut KnownPairs, fraction: f64) -> Vec<Pair> {
    let still = vec![[0.0; 3]; x.len()];
    let candidates = mesh.candidates(broad, x, &still, fraction, known);
    candidates.into_iter().filter(|c| c.distance < fraction * c.pair.s_hat.sqrt()).map(|c| c.pair).collect()
}

#[cfg(test)]
mod tests {
    use super::super::NewtonParams;
    use super::*;
    use crate::geometry::bvh::TriangleBvh;
    use crate::geometry::topology::grid_triangles;

    /// A plate whose solved place lies beyond a static wall, where a static spike pokes up
    /// through it (a closing lid beyond the bulge of an eyeball, a lash through it). The way
    /// from its rest to there goes through the wall, which no iterate may cross: started at
    /// rest the solve stays behind the wall. Untangled, the plate starts beyond it, off the
    /// spike's tip, and ends there with no crossing.
    #[test]
    fn a_plate_whose_solved_place_lies_beyond_a_wall_ends_there_apart() {
        let w = 3u32;
        let plate = |dx: f64| -> Vec<[f64; 3]> { (0..w * w).map(|v| [dx + f64::from(v % w) * 0.2, f64::from(v / w) * 0.2, 0.5]).collect() };
        let wall: Vec<[f64; 3]> = (0..16u32).map(|v| [1.0, -0.5 + f64::from(v % 4) * 0.5, f64::from(v / 4) / 3.0]).collect();
        let spike = [[2.15, 0.1, 0.3], [2.25, 0.1, 0.3], [2.2, 0.1, 0.6]];
        let rest = [plate(0.0), wall, spike.to_vec()].concat();
        let mut triangles = grid_triangles(w, w, 0);
        triangles.extend(grid_triangles(4, 4, w * w));
        let first_spike = w * w + 16;
        triangles.push([first_spike, first_spike + 1, first_spike + 2]);
        let n = rest.len();
        let minimiser = [plate(2.0), rest[(w * w) as usize..].to_vec()].concat();
        let movable: Vec<bool> = (0..n).map(|v| v < (w * w) as usize).collect();
        let identity = SymmetricMatrix::from_triplets(n, (0..n).map(|v| (v, v, 1.0)).collect());
        let scene = ContactScene::new(&rest, &triangles, 0.25);
        let exempt = scene.exemptions(None);
        let added = scene.added_crossings(&crossings(&minimiser, &triangles, &TriangleBvh::build(&minimiser, &triangles), None), &exempt);
        assert!(!added.is_empty(), "the spike should pierce the solved plate");
        let resolved = scene.resolve(&identity.rows(), &minimiser, &movable, &added, &exempt, &NewtonParams::default()).unwrap();
        let x = &resolved.newton.positions;
        assert!(crossings(x, &triangles, &TriangleBvh::build(x, &triangles), None).is_empty());
        assert!(x[..(w * w) as usize].iter().all(|p| p[0] > 1.5), "the plate stayed behind the wall: {:?}", &x[..(w * w) as usize]);
        // Off the spike: the plate's vertex over it is lifted above the tip.
        let over = x[..(w * w) as usize].iter().filter(|p| (p[0] - 2.2).abs() < 0.05).map(|p| p[2]).fold(f64::NEG_INFINITY, f64::max);
        assert!(over > 0.6, "{over}");
        assert_eq!(&x[(w * w) as usize..], &rest[(w * w) as usize..]);
        assert!(resolved.untangled);
    }

    /// Lips closing through each other at every scale: whatever the mesh's units, the result
    /// has no crossing (every pair of triangles sharing no vertex tested) and the upper lip
    /// lies above the lower one wherever one is over the other.
    #[test]
    fn lips_pulled_through_each_other_end_apart_and_in_order_at_any_scale() {
        for scale in [1e-3, 1.0, 1e3] {
            for lips in [folded_lips(scale, 0.8, 1), folded_lips(scale, 2.0, 4), close_sheets(scale, 0.5)] {
                let Lips { rest, triangles, minimiser, lower, upper, .. } = &lips;
                let n = rest.len();
                let scene = ContactScene::new(rest, triangles, 0.25);
                let exempt = scene.exemptions(None);
                let added = scene.added_crossings(&crossings(minimiser, triangles, &TriangleBvh::build(minimiser, triangles), None), &exempt);
                assert!(!added.is_empty(), "{}, scale {scale}: the minimiser should cross", lips.name);
                let resolved = scene.resolve(&membrane(n, triangles).rows(), minimiser, &vec![true; n], &added, &exempt, &NewtonParams::default()).unwrap();
                let x = &resolved.newton.positions;
                assert!(brute_force_crossings(x, triangles).is_empty(), "{}, scale {scale}: crossing", lips.name);
                assert!(in_order(x, triangles, lower, upper), "{}, scale {scale}: the lips passed through each other", lips.name);
            }
        }
    }

    /// Two lips, the rest, the minimiser pulling them through each other, and which vertices
    /// make the lower lip and the upper one (the walls joining them in neither).
    struct Lips {
        name: &'static str,
        rest: Vec<[f64; 3]>,
        triangles: Vec<[u32; 3]>,
        minimiser: Vec<[f64; 3]>,
        lower: Vec<bool>,
        upper: Vec<bool>,
    }

    /// `1 - cos`-shaped bump, 1 at the middle of `[0, 1]` and 0 at its ends.
    fn bump(t: f64) -> f64 {
        (std::f64::consts::PI * t).sin().powi(2)
    }

    /// Two sheets joined at their ends: a strip folded into a closed profile (the lower lip at
    /// z = 0, the upper at z = 0.1, joined by walls at y = 0 and y = 1), 16 cross-sections 0.1
    /// apart along x. The minimiser moves each lip `pull` times the gap towards the other at
    /// the middle, by the bump along times the bump across to the power `1 / power` (1: a peak,
    /// higher: a plateau reaching towards the walls): from `pull` 0.5 on they pass each other.
    fn folded_lips(scale: f64, pull: f64, power: i32) -> Lips {
        let (sections, steps, gap) = (16usize, 10usize, 0.1);
        let mut profile: Vec<[f64; 2]> = (0..=steps).map(|s| [s as f64 / steps as f64, 0.0]).collect();
        profile.extend((0..=steps).rev().map(|s| [s as f64 / steps as f64, gap]));
        let rows = profile.len();
        let mut rest = Vec::new();
        let mut minimiser = Vec::new();
        for i in 0..sections {
            let along = bump(i as f64 / (sections - 1) as f64);
            for (r, q) in profile.iter().enumerate() {
                rest.push([i as f64 * 0.1, q[0], q[1]]);
                let towards = if r <= steps { 1.0 } else { -1.0 };
                minimiser.push([i as f64 * 0.1, q[0], q[1] + towards * pull * gap * (along * bump(q[0])).powf(1.0 / f64::from(power))]);
            }
        }
        let mut triangles = Vec::new();
        for i in 0..sections - 1 {
            for r in 0..rows {
                let (a, b) = ((i * rows + r) as u32, (i * rows + (r + 1) % rows) as u32);
                let (c, d) = (a + rows as u32, b + rows as u32);
                triangles.extend([[a, b, d], [a, d, c]]);
            }
        }
        let inner = |v: usize, upper: bool| {
            let r = v % rows;
            let on_layer = if upper { r > steps } else { r <= steps };
            on_layer && (1..steps).contains(&if upper { rows - 1 - r } else { r })
        };
        let lower = (0..rest.len()).map(|v| inner(v, false)).collect();
        let upper = (0..rest.len()).map(|v| inner(v, true)).collect();
        Lips { name: "folded lips", rest: scaled(rest, scale), triangles, minimiser: scaled(minimiser, scale), lower, upper }
    }

    /// Two close sheets, 8 x 8 vertices 0.2 apart, 0.1 over each other, separate pieces: the
    /// minimiser pulls the upper one's middle `pull` down and the lower one's 0.05 up.
    fn close_sheets(scale: f64, pull: f64) -> Lips {
        let w = 8u32;
        let sheet = |z: f64, pull: f64| -> Vec<[f64; 3]> {
            (0..w * w)
                .map(|v| {
                    let (i, j) = (f64::from(v % w), f64::from(v / w));
                    let t = |k: f64| k / f64::from(w - 1);
                    [i * 0.2, j * 0.2, z + pull * bump(t(i)) * bump(t(j))]
                })
                .collect()
        };
        let rest = [sheet(0.0, 0.0), sheet(0.1, 0.0)].concat();
        let minimiser = [sheet(0.0, 0.05), sheet(0.1, -pull)].concat();
        let mut triangles = grid_triangles(w, w, 0);
        triangles.extend(grid_triangles(w, w, w * w));
        let lower = (0..2 * w * w).map(|v| v < w * w).collect();
        let upper = (0..2 * w * w).map(|v| v >= w * w).collect();
        Lips { name: "close sheets", rest: scaled(rest, scale), triangles, minimiser: scaled(minimiser, scale), lower, upper }
    }

    fn scaled(points: Vec<[f64; 3]>, scale: f64) -> Vec<[f64; 3]> {
        points.into_iter().map(|p| p.map(|c| c * scale)).collect()
    }

    /// A membrane energy's matrix: the mesh's graph Laplacian plus the identity.
    fn membrane(n: usize, triangles: &[[u32; 3]]) -> SymmetricMatrix {
        let edges = crate::geometry::topology::unique_edges(triangles);
        let mut entries: Vec<(usize, usize, f64)> = (0..n).map(|v| (v, v, 1.0)).collect();
        for &(a, b) in &edges {
            entries.extend([(a as usize, a as usize, 1.0), (b as usize, b as usize, 1.0), (a as usize, b as usize, -1.0)]);
        }
        SymmetricMatrix::from_triplets(n, entries)
    }

    /// Every pair of triangles sharing no vertex that crosses, by testing all pairs.
    fn brute_force_crossings(x: &[[f64; 3]], triangles: &[[u32; 3]]) -> Vec<(usize, usize)> {
        let corners = |t: &[u32; 3]| t.map(|v| x[v as usize]);
        let mut found = Vec::new();
        for a in 0..triangles.len() {
            for b in a + 1..triangles.len() {
                if !triangles[a].iter().any(|v| triangles[b].contains(v)) && intersection_length(corners(&triangles[a]), corners(&triangles[b])).is_some() {
                    found.push((a, b));
                }
            }
        }
        found
    }

    /// Whether every vertex of the upper lip lies above the lower lip's surface wherever that
    /// surface is under it (seen along z), and every vertex of the lower lip below the upper's.
    fn in_order(x: &[[f64; 3]], triangles: &[[u32; 3]], lower: &[bool], upper: &[bool]) -> bool {
        let on = |layer: &[bool]| -> Vec<[u32; 3]> { triangles.iter().copied().filter(|t| t.iter().all(|&v| layer[v as usize])).collect() };
        let height = |t: &[u32; 3], p: [f64; 3]| -> Option<f64> {
            let [a, b, c] = t.map(|v| x[v as usize]);
            let det = (b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1]);
            let u = ((p[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (p[1] - a[1])) / det;
            let v = ((b[0] - a[0]) * (p[1] - a[1]) - (p[0] - a[0]) * (b[1] - a[1])) / det;
            (u >= 0.0 && v >= 0.0 && u + v <= 1.0).then(|| a[2] + u * (b[2] - a[2]) + v * (c[2] - a[2]))
        };
        let (lower_triangles, upper_triangles) = (on(lower), on(upper));
        let above = (0..x.len()).filter(|&v| upper[v]).all(|v| lower_triangles.iter().filter_map(|t| height(t, x[v])).all(|z| x[v][2] > z));
        let below = (0..x.len()).filter(|&v| lower[v]).all(|v| upper_triangles.iter().filter_map(|t| height(t, x[v])).all(|z| x[v][2] < z));
        above && below
    }
}
