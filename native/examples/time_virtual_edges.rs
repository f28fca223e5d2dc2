//! Times the virtual-edge search alone (`find_virtual_edges` at the default parameters) on the
//! target neutral of the arrays `scripts/bench_transfer.py -- --save-arrays DIR` (or
//! `scripts/bench_reference_transfer.py -- --keep DIR`, or `scripts/save_production_arrays.py
//! -- DIR` for the production bench's 4.9k / 19k / 77k target) writes:
//!
//!     cargo run --release --example time_virtual_edges -- DIR/<head> [RUNS [TAU_D]]
//!
//! Prints the best of RUNS (default 3) wall seconds, the number of edges and a hash of the
//! edge list, so that two builds run one after the other compare for speed and sameness (run
//! it with `RAYON_NUM_THREADS=1` for CPU seconds). TAU_D overrides the default distance
//! threshold (a fraction of the diagonal).

use std::time::Instant;

use shapesmith_native::transfer::{find_virtual_edges, VirtualEdgeParams};

#[path = "common/arrays.rs"]
mod arrays;
use arrays::{points, read};

fn main() {
    let mut args = std::env::args().skip(1);
    let dir = args.next().expect("usage: time_virtual_edges DIR [RUNS [TAU_D]]");
    let runs: usize = args.next().map_or(3, |r| r.parse().expect("RUNS is a count"));
    let target = points(&format!("{dir}/target.f32"));
    let triangles = read(&format!("{dir}/triangles.u32"));
    let params = match args.next() {
        Some(tau_d) => VirtualEdgeParams { tau_d: tau_d.parse().expect("TAU_D is a fraction of the diagonal"), ..Default::default() },
        None => VirtualEdgeParams::default(),
    };
    let mut best = f64::INFINITY;
    let mut edges = Vec::new();
    for _ in 0..runs {
        let started = Instant::now();
        edges = find_virtual_edges(&target, &triangles, &params);
        best = best.min(started.elapsed().as_secs_f64());
    }
    // FNV-1a over the pairs in order: equal only when the lists are.
    let hash = edges.iter().flat_map(|&(i, j)| [i, j]).fold(0xcbf2_9ce4_8422_2325u64, |h, v| (h ^ u64::from(v)).wrapping_mul(0x0100_0000_01b3));
    println!("{} vertices: virtual edges {best:.4} s (best of {runs}); {} edges, hash {hash:016x}", target.len(), edges.len());
}
