//! Counts the shapes worse than the template by the report's criterion (method, section 3),
//! plain, with virtual edges before the contact solve and after it, on the arrays
//! `scripts/save_contact_arrays.py -- DIR` writes (or `scripts/bench_transfer.py --
//! --save-arrays DIR`, or `scripts/production_heads.py DIR` from those):
//!
//!     cargo run --release --example contact_counts -- DIR/<head> [DIR/names.txt]
//!
//! The criterion as the native report computes it (`excess`, read by the add-on): the
//! intersection curve of the triangle pairs a shape crosses that neither the target's neutral
//! nor the template's shape crosses (one ring wider where skin slides along a rest crossing),
//! per part (inside one piece, between pieces); worse when beyond 1e-3 of the target's
//! bounding-box diagonal. NAMES, a file of one shape name per line, names the shapes still
//! worse after the solve. It also prints the pairs crossing at rest on both neutrals and the
//! pieces. When DIR holds `truth.f32` (the true target shapes' deltas, as
//! `scripts/bench_personalise.py`'s warp ground truth makes them), it also prints the warp
//! error, mean over shapes of the mean error on each shape's active vertices / diagonal, with
//! virtual edges and with the solve, and the true shapes judged both by the criterion and by
//! curve length (the shape's added curve against the template's allowance,
//! [`AddedCurve::excess_parts`]: the judge the wrap keeps for keys carried onto another mesh).
//! Per shape the solve acts on, its largest change against the virtual-edge solve over its
//! largest motion, "(at rest)" where the untangling left a crossing; and, counted outside the
//! report through the contact module's own exemptions, the shapes adding crossing pairs
//! beyond them with virtual edges and with the solve (and the truth).

use shapesmith_native::transfer::{measure_rig_penetration, AddedCurve, ContactParams, PenetrationBaseline, TransferShapesParams, transfer_shapes};
use shapesmith_native::geometry::bvh::TriangleBvh;
use shapesmith_native::geometry::contact::{ContactScene, TemplateShape};
use shapesmith_native::geometry::penetration::crossings;
use shapesmith_native::NoProgress;

#[path = "common/arrays.rs"]
mod arrays;
use arrays::{points, read};

fn main() {
    let dir = std::env::args().nth(1).expect("usage: contact_counts DIR [NAMES]");
    let source = points(&format!("{dir}/source.f32"));
    let target = points(&format!("{dir}/target.f32"));
    let deltas = points(&format!("{dir}/deltas.f32"));
    let triangles = read(&format!("{dir}/triangles.u32"));
    let count = deltas.len() / source.len();
    let names: Vec<String> = match std::env::args().nth(2) {
        Some(file) => std::fs::read_to_string(file).expect("names file").lines().map(str::to_owned).collect(),
        None => (0..count).map(|k| format!("shape {k}")).collect(),
    };
    assert_eq!(names.len(), count, "one name per shape");
    let template = measure_rig_penetration(&source, &deltas, &triangles).expect("template penetration");
    let mut params = TransferShapesParams { measure_penetration: true, compare_plain: true, ..Default::default() };
    params.transfer.contact = Some(ContactParams::default());
    let started = std::time::Instant::now();
    let (with, report) =
        transfer_shapes(&source, &deltas, &target, &triangles, &names, None, Some(&template), &params, &NoProgress).expect("transfer");
    let wall = started.elapsed().as_secs_f64();
    let mut plain_params = params;
    plain_params.transfer.contact = None;
    plain_params.measure_penetration = false;
    plain_params.compare_plain = false;
    let (without, _) =
        transfer_shapes(&source, &deltas, &target, &triangles, &names, None, None, &plain_params, &NoProgress).expect("transfer");
    let diagonal = shapesmith_native::rig::bbox_diagonal(&target);
    let mut line = Vec::new();
    let mut worse_after = Vec::new();
    for label in ["plain", "virtual edges", "pass"] {
        let (mut worse, mut added) = (0, 0.0);
        for row in &report.penetration {
            // The report's own criterion, as the add-on reads it.
            let AddedCurve { inside, between } = match label {
                "plain" => row.plain_excess.expect("compare_plain"),
                "virtual edges" => row.before_contact_excess.unwrap_or(row.excess),
                _ => row.excess,
            };
            added += inside + between;
            if inside + between > 1e-3 * diagonal {
                worse += 1;
                if label == "pass" {
                    worse_after.push(format!("{} {:+.2}/{:+.2}cm", row.name, 100.0 * inside, 100.0 * between));
                }
            }
        }
        line.push(format!("{label} {worse} ({added:.3} m)"));
    }
    println!("{}: {}; wall {wall:.2} s, pass {:.2} s", dir.rsplit('/').next().unwrap_or(&dir), line.join(", "), report.seconds.contact);
    let rest = |p: Option<shapesmith_native::transfer::Penetration>| p.map_or(0, |p| p.pairs);
    let pieces = shapesmith_native::geometry::topology::connected_components(source.len(), &triangles).1;
    println!(
        "  pairs crossing at rest: template {}, target {}; {pieces} pieces",
        rest(report.template_neutral_penetration),
        rest(report.neutral_penetration)
    );
    println!("  still worse: {}", worse_after.join(", "));
    // How far the solve moves each shape it acts on from the virtual-edge solve: its largest
    // change over the shape's largest motion.
    let n = source.len();
    let norm = |d: [f32; 3]| d.iter().map(|&x| f64::from(x).powi(2)).sum::<f64>().sqrt();
    let mut changes: Vec<(f64, String)> = (0..count)
        .filter(|&k| report.penetration[k].contact.is_some_and(|c| c.applied))
        .map(|k| {
            let (a, b) = (&with[k * n..(k + 1) * n], &without[k * n..(k + 1) * n]);
            let largest = b.iter().map(|&d| norm(d)).fold(0.0, f64::max);
            let change = a.iter().zip(b).map(|(p, q)| norm([p[0] - q[0], p[1] - q[1], p[2] - q[2]])).fold(0.0, f64::max);
            let tangled = if report.penetration[k].contact.is_some_and(|c| c.untangled) { "" } else { " (at rest)" };
            (change / largest.max(f64::MIN_POSITIVE), format!("{}{tangled}", names[k]))
        })
        .collect();
    changes.sort_by(|a, b| b.0.total_cmp(&a.0));
    let median = changes.get(changes.len() / 2).map_or(0.0, |c| c.0);
    let largest: Vec<String> = changes.iter().take(8).map(|(c, name)| format!("{name} {:.0}%", 100.0 * c)).collect();
    println!("  change against virtual edges on the {} shapes solved: median {:.0}%; largest {}", changes.len(), 100.0 * median, largest.join(", "));
    // And by the contact solve's rule: crossing pairs beyond its exemptions.
    let f64s = |p: &[[f32; 3]]| -> Vec<[f64; 3]> { p.iter().map(|q| q.map(f64::from)).collect() };
    let (source64, target64) = (f64s(&source), f64s(&target));
    let scene = ContactScene::new(&target64, &triangles, 0.25);
    let template_scene = ContactScene::new(&source64, &triangles, 0.25);
    let tree = TriangleBvh::build(&target64, &triangles);
    let added = |k: usize, shape: &[[f32; 3]]| -> usize {
        let delta = &deltas[k * n..(k + 1) * n];
        let moving: Vec<bool> = delta.iter().map(|d| *d != [0.0; 3]).collect();
        let positions: Vec<[f64; 3]> = source64.iter().zip(delta).map(|(p, d)| [0, 1, 2].map(|a| p[a] + f64::from(d[a]))).collect();
        let exempt = scene.exemptions(Some(TemplateShape { scene: &template_scene, positions: &positions, moving: &moving, scale: 1.0 }));
        let posed: Vec<[f64; 3]> = target64.iter().zip(shape).map(|(p, d)| [0, 1, 2].map(|a| p[a] + f64::from(d[a]))).collect();
        let swept = crossings(&posed, &triangles, &tree.refitted(&posed, &triangles), None);
        scene.added_crossings(&swept, &exempt).len()
    };
    let beyond = |shapes: &[[f32; 3]]| {
        let counts: Vec<(String, usize)> = (0..count).map(|k| (names[k].clone(), added(k, &shapes[k * n..(k + 1) * n]))).filter(|c| c.1 > 0).collect();
        format!("{} {:?}", counts.len(), counts)
    };
    println!("  shapes adding crossings beyond the exemptions: virtual edges {}", beyond(&without));
    println!("  shapes adding crossings beyond the exemptions: contact {}", beyond(&with));
    let truth_path = format!("{dir}/truth.f32");
    if !std::path::Path::new(&truth_path).exists() {
        return;
    }
    let truth = points(&truth_path);
    let error = |predicted: &[[f32; 3]]| warp_error(predicted, &truth, source.len(), diagonal);
    let (a, b) = (error(&without), error(&with));
    println!("  warp: virtual edges {a:.4e}, with the pass {b:.4e} ({:+.1}%)", 100.0 * (b / a - 1.0));
    // The truth judged by curve length: the judge a faithful shape should pass.
    let baseline = PenetrationBaseline::new(&target, &triangles);
    let neutral = baseline.neutral();
    let mut truth_worse = Vec::new();
    for (row, shape) in report.penetration.iter().zip(truth.chunks(source.len())) {
        let AddedCurve { inside, between } = AddedCurve::from_penetrations(&baseline.shape(shape), &neutral).excess_parts(&row.allowed);
        if inside + between > 1e-3 * diagonal {
            truth_worse.push(format!("{} {:+.2}/{:+.2}cm", row.name, 100.0 * inside, 100.0 * between));
        }
    }
    println!("  the truth worse by curve length: {} ({})", truth_worse.len(), truth_worse.join(", "));
    println!("  truth: shapes adding crossings beyond the exemptions {}", beyond(&truth));
}

/// Mean over shapes of the mean error on the shape's active vertices (moving at least 0.3 of
/// its largest true displacement), / diagonal (`mean_active_error` of bench_personalise.py).
fn warp_error(predicted: &[[f32; 3]], truth: &[[f32; 3]], n: usize, diagonal: f64) -> f64 {
    let norm = |d: [f32; 3]| (d.iter().map(|&x| f64::from(x) * f64::from(x)).sum::<f64>()).sqrt();
    let mut errors = Vec::new();
    for (p, t) in predicted.chunks(n).zip(truth.chunks(n)) {
        let largest = t.iter().map(|&d| norm(d)).fold(0.0, f64::max);
        if largest == 0.0 {
            continue;
        }
        let active: Vec<f64> = p
            .iter()
            .zip(t)
            .filter(|(_, &d)| norm(d) >= 0.3 * largest)
            .map(|(&a, &b)| norm([a[0] - b[0], a[1] - b[1], a[2] - b[2]]))
            .collect();
        errors.push(active.iter().sum::<f64>() / active.len() as f64 / diagonal);
    }
    errors.iter().sum::<f64>() / errors.len() as f64
}
