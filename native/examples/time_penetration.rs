//! Times `measure_rig_penetration` (the template's own penetration, a sweep of every shape)
//! on the arrays `scripts/bench_transfer.py -- --save-arrays DIR` writes:
//!
//!     cargo run --release --example time_penetration -- DIR/<head>
//!
//! Prints the wall seconds and a hash of every shape's length, pairs and part between
//! pieces, so that two builds run one after the other compare for speed and sameness.

use std::time::Instant;

use shapesmith_native::transfer::measure_rig_penetration;

#[path = "common/arrays.rs"]
mod arrays;
use arrays::{points, read};

fn main() {
    let dir = std::env::args().nth(1).expect("usage: time_penetration DIR");
    let source = points(&format!("{dir}/source.f32"));
    let deltas = points(&format!("{dir}/deltas.f32"));
    let triangles = read(&format!("{dir}/triangles.u32"));
    let started = Instant::now();
    let rig = measure_rig_penetration(&source, &deltas, &triangles).expect("penetration");
    let seconds = started.elapsed().as_secs_f64();
    // FNV-1a over each shape's numbers: equal only when every shape's are.
    let hash = rig
        .shapes
        .iter()
        .flat_map(|p| [p.length.to_bits(), p.pairs as u64, p.between_pieces.to_bits()])
        .fold(0xcbf2_9ce4_8422_2325u64, |h, v| (h ^ v).wrapping_mul(0x0100_0000_01b3));
    println!("{} vertices, {} shapes: penetration {seconds:.3} s; hash {hash:016x}", source.len(), rig.shapes.len());
}
