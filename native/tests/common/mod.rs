//! The test face every cross-tool test reads: a wavy sheet symmetric about x = 0 with a box
//! of teeth behind it, and its shapes.

/// A face: a wavy sheet symmetric about x = 0 (piece 0) and a closed box of teeth behind it
/// (piece 1), welded.
pub fn face() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
    let (w, h) = (17u32, 13u32);
    let mut points = Vec::new();
    for y in 0..h {
        for x in 0..w {
            let (fx, fy) = (x as f32 / (w - 1) as f32 - 0.5, y as f32 / (h - 1) as f32);
            points.push([fx, fy, 0.1 * (2.0 * fx).cos() * (1.5 * fy).sin()]);
        }
    }
    let mut triangles = Vec::new();
    for y in 0..h - 1 {
        for x in 0..w - 1 {
            let v = y * w + x;
            triangles.push([v, v + 1, v + w + 1]);
            triangles.push([v, v + w + 1, v + w]);
        }
    }
    let start = points.len() as u32;
    for c in 0..8u32 {
        points.push([-0.15 + 0.3 * (c & 1) as f32, 0.2 + 0.08 * ((c >> 1) & 1) as f32, -0.15 + 0.08 * (c >> 2) as f32]);
    }
    for q in [[0u32, 1, 3, 2], [4, 6, 7, 5], [0, 4, 5, 1], [2, 3, 7, 6], [0, 2, 6, 4], [1, 5, 7, 3]] {
        triangles.push([start + q[0], start + q[1], start + q[2]]);
        triangles.push([start + q[0], start + q[2], start + q[3]]);
    }
    (points, triangles)
}

/// Mirrored smiles, a jaw (lower face and the teeth), brows, and a cheek puff on the left.
pub fn shapes(points: &[[f32; 3]]) -> (Vec<[f32; 3]>, Vec<String>) {
    let n = points.len();
    let sheet = n - 8;
    let mut deltas = vec![[0.0f32; 3]; 5 * n];
    let bump = |p: &[f32; 3], x: f32, y: f32, r: f32| (-((p[0] - x).powi(2) + (p[1] - y).powi(2)) / r).exp();
    for (v, p) in points.iter().enumerate().take(sheet) {
        for (k, side) in [(0, -0.25f32), (1, 0.25)] {
            let b = bump(p, side, 0.35, 0.01);
            if b > 1e-3 {
                deltas[k * n + v] = [0.03 * b * side.signum(), 0.02 * b, 0.04 * b];
            }
        }
        if p[1] < 0.3 {
            deltas[2 * n + v] = [0.0, -0.05 * (0.3 - p[1]) / 0.3, 0.01];
        }
        let brow = bump(p, 0.0, 0.85, 0.03);
        if brow > 1e-3 {
            deltas[3 * n + v] = [0.0, 0.03 * brow, 0.01 * brow];
        }
        let puff = bump(p, -0.3, 0.6, 0.005);
        if puff > 1e-3 {
            deltas[4 * n + v] = [-0.01 * puff, 0.0, 0.05 * puff];
        }
    }
    for v in sheet..n {
        deltas[2 * n + v] = [0.0, -0.04, 0.0];
    }
    (deltas, ["smileLeft", "smileRight", "jawOpen", "browUp", "cheekPuffLeft"].map(String::from).to_vec())
}

pub fn warp(p: &[f32; 3]) -> [f32; 3] {
    [1.1 * p[0], 1.2 * p[1] + 0.1 * p[0] * p[0], 0.9 * p[2] + 0.05 * p[1] * p[1]]
}

