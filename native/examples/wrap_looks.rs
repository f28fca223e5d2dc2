//! Where riggers look first (`wrap::looks`) on the wrap's carried keys, on the arrays
//! `scripts/save_wrap_arrays.py -- DIR` writes (one directory per character):
//!
//!     cargo run --release --example wrap_looks -- DIR/<character>
//!
//! Carries the wrapped template's keys as the wrap does (the collision pass judged by the
//! saved curves) and prints the blinks' gap and lid line against the template's, jawOpen's
//! opening and lip contour, mouthClose's closing, and every key that turns over more of the
//! skin it moves than the template's own key does.

use shapesmith_native::rig::RigView;
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
    let dir = std::env::args().nth(1).expect("usage: wrap_looks DIR");
    let wrapped = points(&format!("{dir}/wrapped.f32"));
    let triangles = read(&format!("{dir}/wrapped.u32"));
    let deltas = points(&format!("{dir}/deltas.f32"));
    let character = points(&format!("{dir}/character.f32"));
    let character_triangles = read(&format!("{dir}/character.u32"));
    let neutral = points(&format!("{dir}/template.f32"));
    let shapes = points(&format!("{dir}/template_deltas.f32"));
    let names: Vec<String> = std::fs::read_to_string(format!("{dir}/names.txt")).expect("names").lines().map(str::to_owned).collect();
    let template_curve: Vec<TemplateCurve> =
        curve(&format!("{dir}/added.f64")).into_iter().zip(curve(&format!("{dir}/crossing.f64"))).map(|(added, crossing)| TemplateCurve { added, crossing }).collect();
    let carried = shapesmith_native::wrap::carry_shapes(
        &wrapped, &triangles, &deltas, &character, &character_triangles, Some(&template_curve), Some(&neutral), Some(&shapes), &CarryParams::default(), &NoProgress,
    )
    .expect("carry");
    let rig = RigView::new(&neutral, &shapes, &triangles, &names).expect("template");
    let looks = shapesmith_native::wrap::looks::look_at_keys(&rig, &wrapped, &deltas, &character, &character_triangles, &carried.deltas, None).expect("looks");
    let ratio = |a: Option<f64>, b: Option<f64>| a.zip(b).map_or(f64::NAN, |(a, b)| a / b);
    for s in &looks.shapes {
        if let Some(gap) = s.eye_gap {
            let template = s.template_eye_gap.unwrap_or(f64::NAN);
            println!("{}: gap {:.1}% (template {:.1}%), lid line {:.2}x", s.name, 100.0 * gap, 100.0 * template, ratio(s.lid_turning, s.template_lid_turning));
        }
        if s.mouth_opening.is_some() {
            println!("{}: opening {:.2}x the template's, lip contour {:.2}x", s.name, ratio(s.mouth_opening, s.template_mouth_opening), ratio(s.lip_turning, s.template_lip_turning));
        }
        if let Some(closing) = s.mouth_closing {
            println!("{}: closes {:.0}% (template {:.0}%)", s.name, 100.0 * closing, 100.0 * s.template_mouth_closing.unwrap_or(f64::NAN));
        }
    }
    let over: Vec<String> = looks
        .shapes
        .iter()
        .filter(|s| s.turned_over > 0)
        .map(|s| format!("{} {} ({:.3}% / template {:.3}%)", s.name, s.turned_over, 100.0 * s.turned_over_share, 100.0 * s.template_turned_over_share))
        .collect();
    println!("turned over: {}", over.join(", "));
}
