//! Times `pack_expressions` outside Blender, on the arrays `scripts/bench_pack.py --
//! --save-arrays DIR` writes:
//!
//!     cargo run --release --example time_pack -- DIR/<rig> [RUNS] [--same-as FILE]
//!
//! Prints the best of RUNS (default 3) runs' native seconds with the collision and occlusion
//! conflicts on and off, the poseability tests' parts, and what they found (the conflict
//! edges and their values, the symmetric pairs, antagonists and expressions, J and the fewest
//! count), so that two builds run one after the other can be compared for both speed and
//! sameness. With `--same-as FILE` (the output of another build, saved) it also says whether
//! everything after the timing line is the same as there, and fails when it is not. A
//! profiler can watch it alone.

use std::fmt::Write;
use std::time::Instant;

use shapesmith_native::packing::{pack_expressions, Packing, PackingParams};
use shapesmith_native::{NoProgress, RigView};

#[path = "common/arrays.rs"]
mod arrays;
use arrays::{points, read};

/// The best wall seconds of `runs` packings, and the last packing.
fn best_of(rig: &RigView, params: &PackingParams, runs: usize) -> (f64, Packing) {
    let mut best = (f64::INFINITY, None);
    for _ in 0..runs {
        let started = Instant::now();
        let packing = pack_expressions(rig, None, params, &NoProgress).expect("packing");
        best = (best.0.min(started.elapsed().as_secs_f64()), Some(packing));
    }
    (best.0, best.1.expect("at least one run"))
}

fn main() {
    let usage = "usage: time_pack DIR [RUNS] [--same-as FILE]";
    let args: Vec<String> = std::env::args().skip(1).collect();
    let (same_as, args) = match args.iter().position(|a| a == "--same-as") {
        Some(i) => (Some(args.get(i + 1).expect(usage).clone()), [&args[..i], &args[i + 2..]].concat()),
        None => (None, args),
    };
    let dir = args.first().expect(usage);
    let runs: usize = args.get(1).map_or(3, |r| r.parse().expect("RUNS is a count"));
    let neutral = points(&format!("{dir}/neutral.f32"));
    let deltas = points(&format!("{dir}/deltas.f32"));
    let triangles = read(&format!("{dir}/triangles.u32"));
    let names: Vec<String> = (0..deltas.len() / neutral.len()).map(|k| format!("shape {k}")).collect();
    let rig = RigView::new(&neutral, &deltas, &triangles, &names).expect("rig");
    let on = PackingParams { fewest: true, ..PackingParams::default() };
    let off = PackingParams { collision_conflicts: false, occlusion_conflicts: false, ..on.clone() };
    let (seconds_on, packing) = best_of(&rig, &on, runs);
    let (seconds_off, without) = best_of(&rig, &off, runs);
    let p = &packing.poseability;
    println!(
        "{} vertices, {} shapes: native on {seconds_on:.4} s, off {seconds_off:.4} s; regions {:.4}, collisions {:.4} \
         ({} pairs), occlusions {:.4} ({} directions)",
        neutral.len(),
        names.len(),
        p.seconds_regions,
        p.seconds_collisions,
        p.collision_pairs_tested,
        p.seconds_occlusions,
        p.occlusion_directions_tested,
    );
    let fewest = |p: &Packing| p.fewest.as_ref().map_or(0, |f| f.count);
    let mut found = String::new();
    let f = &mut found;
    writeln!(f, "J {} fewest {} (off: J {} fewest {})", packing.expressions.len(), fewest(&packing), without.expressions.len(), fewest(&without)).unwrap();
    writeln!(f, "pairs {:?}", packing.pairs).unwrap();
    writeln!(f, "antagonists {:?}", packing.antagonists).unwrap();
    for (j, e) in packing.expressions.iter().enumerate() {
        writeln!(f, "expression {} {:?} importance {:.12} optimal {}", j + 1, e.shapes, e.importance, e.optimal).unwrap();
    }
    for c in &p.collisions {
        writeln!(f, "collision {} {} added {:.9} between {:.9}", c.first, c.second, c.added, c.between_pieces).unwrap();
    }
    for o in &p.occlusions {
        writeln!(f, "occlusion {} by {} kept {:.9}", o.hidden, o.by, o.kept).unwrap();
    }
    print!("{found}");
    if let Some(file) = same_as {
        let saved = std::fs::read_to_string(&file).expect("the saved output");
        // The saved output's first line is its timing.
        let saved = saved.split_once('\n').map_or("", |(_, rest)| rest);
        match saved.lines().zip(found.lines()).position(|(a, b)| a != b) {
            None if saved.lines().count() == found.lines().count() => println!("same as {file}"),
            at => {
                println!("DIFFERENT from {file} (line {})", at.map_or(saved.lines().count().min(found.lines().count()), |i| i + 2));
                std::process::exit(1);
            }
        }
    }
}
