//! Shapes of the wrap's carried keys worse than the template by the criterion of method, section 3, with the
//! carry's collision pass and without it, on the arrays `scripts/save_wrap_arrays.py -- DIR`
//! writes (one directory per character):
//!
//!     cargo run --release --example carry_counts -- DIR/<character>
//!
//! Prints, per shape the pass acted on, its plain and kept excess (/ diagonal), its re-solves
//! and held vertices, and the shapes still worse; the largest mirror miss of the carried
//! Left/Right pairs and the pairs the pass held apart; and the carry's seconds.

use shapesmith_native::wrap::{AddedCurve, CarryParams, TemplateCurve};
use shapesmith_native::NoProgress;

#[path = "common/arrays.rs"]
mod arrays;
use arrays::{points, read};

fn curve(path: &str) -> Vec<AddedCurve> {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("cannot read {path}: {e}"));
    let values: Vec<f64> = bytes.chunks_exact(8).map(|c| f64::from_le_bytes(c.try_into().unwrap())).collect();
    values.chunks_exact(2).map(|p| AddedCurve { inside: p[0], between: p[1] }).collect()
}

fn main() {
    let dir = std::env::args().nth(1).expect("usage: carry_counts DIR");
    let wrapped = points(&format!("{dir}/wrapped.f32"));
    let wrapped_triangles = read(&format!("{dir}/wrapped.u32"));
    let deltas = points(&format!("{dir}/deltas.f32"));
    let character = points(&format!("{dir}/character.f32"));
    let character_triangles = read(&format!("{dir}/character.u32"));
    let neutral = points(&format!("{dir}/template.f32"));
    let shapes = points(&format!("{dir}/template_deltas.f32"));
    let names: Vec<String> = std::fs::read_to_string(format!("{dir}/names.txt")).expect("names").lines().map(str::to_owned).collect();
    let template_curve: Vec<TemplateCurve> =
        curve(&format!("{dir}/added.f64")).into_iter().zip(curve(&format!("{dir}/crossing.f64"))).map(|(added, crossing)| TemplateCurve { added, crossing }).collect();
    let diagonal = shapesmith_native::rig::bbox_diagonal(&character);
    let only: Option<String> = std::env::args().nth(2);
    for pass in [false, true] {
        let params = CarryParams { collision_pass: pass, ..CarryParams::default() };
        let started = std::time::Instant::now();
        let result = shapesmith_native::wrap::carry_shapes(
            &wrapped, &wrapped_triangles, &deltas, &character, &character_triangles, Some(&template_curve), Some(&neutral), Some(&shapes), &params, &NoProgress,
        )
        .expect("carry");
        let seconds = started.elapsed().as_secs_f64();
        let penetration = result.penetration.expect("judged");
        let worse: Vec<String> = penetration
            .excess
            .iter()
            .enumerate()
            .filter(|(_, e)| e.inside + e.between > 1e-3 * diagonal)
            .map(|(k, e)| format!("{} {:.4}/{:.4}", names[k], e.inside / diagonal, e.between / diagonal))
            .collect();
        println!("{} pass {pass}: {} worse in {seconds:.2} s: {}", dir, worse.len(), worse.join(", "));
        if let Some(symmetry) = result.symmetry.as_ref().filter(|s| s.symmetric) {
            let worst = symmetry.shapes.iter().max_by(|a, b| a.carried.total_cmp(&b.carried));
            let held: Vec<String> = symmetry.shapes.iter().filter(|m| m.held_apart).map(|m| format!("{}/{} {:.1}%", names[m.first], names[m.second], 100.0 * m.carried)).collect();
            if let Some(m) = worst {
                println!("  largest mirror miss {:.1}% ({} / {}); held apart: {}", 100.0 * m.carried, names[m.first], names[m.second], held.join(", "));
            }
        }
        if pass {
            for (k, c) in result.collisions.iter().enumerate() {
                if c.plain_excess > 0.0 && only.as_deref().is_none_or(|o| names[k].contains(o)) {
                    println!("  {}: plain {:.5} kept {:.5} applied {} solves {} held {}", names[k], c.plain_excess / diagonal, c.excess / diagonal, c.applied, c.solves, c.held_vertices);
                }
            }
        }
    }
}
