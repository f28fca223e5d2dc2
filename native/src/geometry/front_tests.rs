use super::*;
use crate::geometry::mat3::{mat_vec, Mat3, IDENTITY};

/// A unit sphere facing -Y with Z up: two eyelids above, a jaw and a smile pair below, all
/// mirror-symmetric across X = 0.
fn synthetic_face() -> (Vec<[f32; 3]>, Vec<Vec<[f32; 3]>>, Vec<[u32; 3]>, Vec<String>) {
    let (rings, segments) = (16usize, 32usize);
    let mut points = vec![[0.0f64, 0.0, 1.0]];
    for i in 1..rings {
        let theta = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segments {
            let phi = std::f64::consts::TAU * j as f64 / segments as f64;
            points.push([theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()]);
        }
    }
    points.push([0.0, 0.0, -1.0]);
    let ring = |i: usize, j: usize| (1 + (i - 1) * segments + j % segments) as u32;
    let last = (points.len() - 1) as u32;
    let mut triangles = Vec::new();
    for j in 0..segments {
        triangles.push([0, ring(1, j), ring(1, j + 1)]);
        triangles.push([last, ring(rings - 1, j + 1), ring(rings - 1, j)]);
        for i in 1..rings - 1 {
            triangles.push([ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)]);
            triangles.push([ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)]);
        }
    }
    let bump = |centre: Vec3, motion: Vec3| -> Vec<[f32; 3]> {
        let c = scale(centre, 1.0 / length(centre));
        points.iter().map(|&p| scale(motion, (1.0 - length(sub(p, c)) / 0.4).max(0.0)).map(|x| x as f32)).collect()
    };
    let shapes = vec![
        ("eyeBlinkLeft", bump([0.35, -1.0, 0.35], [0.0, 0.0, -0.1])),
        ("eyeBlinkRight", bump([-0.35, -1.0, 0.35], [0.0, 0.0, -0.1])),
        ("jawOpen", bump([0.0, -1.0, -0.45], [0.0, 0.03, -0.15])),
        ("mouthSmileLeft", bump([0.3, -1.0, -0.35], [0.05, 0.0, 0.05])),
        ("mouthSmileRight", bump([-0.3, -1.0, -0.35], [-0.05, 0.0, 0.05])),
    ];
    let points = points.iter().map(|p| p.map(|x| x as f32)).collect();
    let names = shapes.iter().map(|(n, _)| n.to_string()).collect();
    (points, shapes.into_iter().map(|(_, d)| d).collect(), triangles, names)
}

/// The face rotated by `r` (rows), its front found with lateral axis `axis` tried first.
fn found(r: &Mat3, axis: usize, names: Option<Vec<String>>, flip: bool) -> ShapesmithResult<Front> {
    let (points, shapes, mut triangles, default_names) = synthetic_face();
    let turn = |p: &[f32; 3]| mat_vec(r, to_f64(p)).map(|x| x as f32);
    let points: Vec<[f32; 3]> = points.iter().map(turn).collect();
    let deltas: Vec<[f32; 3]> = shapes.iter().flat_map(|d| d.iter().map(turn)).collect();
    if flip {
        triangles.iter_mut().for_each(|t| t.swap(1, 2));
    }
    let names = names.unwrap_or(default_names);
    let rig = RigView::new(&points, &deltas, &triangles, &names)?;
    find_front(&rig, axis)
}


/// 90 degrees about X: -Y (the front) goes to -Z, +Z (up) to -Y.
const ABOUT_X: Mat3 = [[1.0, 0.0, 0.0], [0.0, 0.0, -1.0], [0.0, 1.0, 0.0]];
/// 90 degrees about Z: -Y goes to +X, the lateral X to Y.
const ABOUT_Z: Mat3 = [[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]];
/// -90 about X: facing +Z with Y up.
const Y_UP: Mat3 = [[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]];

#[test]
fn the_front_turns_with_the_face() {
    for (r, lateral) in [(IDENTITY, 0), (ABOUT_X, 0), (ABOUT_Z, 1), (Y_UP, 0)] {
        let front = found(&r, 0, None, false).unwrap();
        assert_eq!(front.front, mat_vec(&r, [0.0, -1.0, 0.0]), "{r:?}");
        assert_eq!(front.up, mat_vec(&r, [0.0, 0.0, 1.0]), "{r:?}");
        assert_eq!(front.lateral_axis, Some(lateral));
        assert_eq!(front.up_source, UpSource::Names);
        assert!(front.snapped && front.snap_degrees < 10.0, "{front:?}");
    }
}

#[test]
fn an_oblique_face_has_no_symmetry_plane_and_keeps_its_found_front() {
    // -Y goes to (1, -1, 1) / sqrt 3, 54.7 degrees from every axis; +Z to (1, 2, 1) / sqrt 6.
    let toward = scale([1.0, -1.0, 1.0], 1.0 / 3f64.sqrt());
    let up = scale([1.0, 2.0, 1.0], 1.0 / 6f64.sqrt());
    let y = scale(toward, -1.0);
    let x = cross(y, up);
    let r: Mat3 = std::array::from_fn(|i| [x[i], y[i], up[i]]);
    let front = found(&r, 0, None, false).unwrap();
    assert_eq!(front.lateral_axis, None);
    assert!(!front.snapped);
    assert!(angle_degrees(front.front, toward) < 10.0, "{front:?}");
    assert!(angle_degrees(front.up, up) < 10.0, "{front:?}");
    assert!(dot(front.front, front.up).abs() < 1e-12);
}

#[test]
fn inward_triangles_face_the_same_way() {
    for r in [IDENTITY, ABOUT_X] {
        assert_eq!(found(&r, 0, None, true).unwrap().front, mat_vec(&r, [0.0, -1.0, 0.0]));
    }
}

#[test]
fn without_eye_or_mouth_names_up_is_assumed() {
    let names = (1..=5).map(|k| format!("shape{k}")).collect();
    let front = found(&Y_UP, 0, Some(names), false).unwrap();
    assert_eq!(front.front, [0.0, 0.0, 1.0]);
    assert_eq!(front.up, [0.0, 1.0, 0.0]);
    assert_eq!(front.up_source, UpSource::Assumed);
}

#[test]
fn a_still_rig_or_a_bad_axis_is_an_error() {
    let points = [[0.0f32, 0.0, 0.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]];
    let deltas = [[0.0f32; 3]; 3];
    let names = vec!["still".to_string()];
    let rig = RigView::new(&points, &deltas, &[[0, 1, 2]], &names).unwrap();
    assert!(find_front(&rig, 0).unwrap_err().to_string().contains("no shape key moves"));
    assert!(find_front(&rig, 3).unwrap_err().to_string().contains("symmetry axis"));
}
