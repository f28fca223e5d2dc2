//! Times `transfer_shapes` (virtual edges, contact solve, penetration report) outside
//! Blender, on the arrays `scripts/bench_transfer.py -- --save-arrays DIR` writes:
//!
//!     cargo run --release --example time_transfer -- DIR/<head> [RUNS] [--contact | --no-contact] [--no-report] [--template-inside]
//!
//! Prints the best of RUNS (default 3) runs' native seconds split as the bench reports them
//! (setup, virtual edges, solves, contact solve, report), the seconds of the template's own
//! per-shape numbers (measured once per template), and a checksum of the results (summed
//! intersection length and pairs, shapes the contact solve changed, summed excess over the template,
//! summed absolute deltas, local re-solves, and a hash of every written delta's bits) so that
//! two builds run one after the other can be compared for both speed and sameness.
//! `--contact` turns the contact solve on ("Keep Surfaces Apart", off by default), `--no-contact`
//! off (virtual edges alone) and `--no-report` the
//! penetration report, so that what each adds to the call is measured in one place (without
//! the report, the checksum's report fields are zero: only `|deltas|` and `bits` compare).
//! `--template-inside` leaves the template's numbers to the call, as the panel's transfer
//! does (they are then part of its wall and its report stage).

use std::time::Instant;

use shapesmith_native::transfer::{measure_rig_penetration, ContactParams, transfer_shapes, StageSeconds, TransferShapesParams};
use shapesmith_native::NoProgress;

#[path = "common/arrays.rs"]
mod arrays;
use arrays::{points, read};

fn main() {
    let usage = "usage: time_transfer DIR [RUNS] [--contact | --no-contact] [--no-report] [--template-inside]";
    let (flags, positional): (Vec<String>, Vec<String>) = std::env::args().skip(1).partition(|a| a.starts_with("--"));
    let dir = positional.first().expect(usage).clone();
    let runs: usize = positional.get(1).map_or(3, |r| r.parse().expect("RUNS is a count"));
    if let Some(unknown) = flags.iter().find(|f| !matches!(f.as_str(), "--contact" | "--no-contact" | "--no-report" | "--template-inside")) {
        panic!("unknown flag {unknown}; {usage}");
    }
    let source = points(&format!("{dir}/source.f32"));
    let target = points(&format!("{dir}/target.f32"));
    let deltas = points(&format!("{dir}/deltas.f32"));
    let triangles = read(&format!("{dir}/triangles.u32"));
    let names: Vec<String> = (0..deltas.len() / source.len()).map(|k| format!("shape {k}")).collect();
    let started = Instant::now();
    let template = measure_rig_penetration(&source, &deltas, &triangles).expect("template penetration");
    let template_seconds = started.elapsed().as_secs_f64();
    let mut params = TransferShapesParams { measure_penetration: !flags.iter().any(|f| f == "--no-report"), ..Default::default() };
    if flags.iter().any(|f| f == "--contact") {
        params.transfer.contact = Some(ContactParams::default());
    }
    if flags.iter().any(|f| f == "--no-contact") {
        params.transfer.contact = None;
    }
    let mut best: Option<(f64, StageSeconds)> = None;
    let mut checksum = (0.0, 0, 0, 0.0, 0.0, 0, 0u64);
    for _ in 0..runs {
        let started = Instant::now();
        let given = (!flags.iter().any(|f| f == "--template-inside")).then_some(&template);
        let (deltas, report) = transfer_shapes(&source, &deltas, &target, &triangles, &names, None, given, &params, &NoProgress)
            .expect("transfer");
        let wall = started.elapsed().as_secs_f64();
        let rows = &report.penetration;
        checksum = (
            rows.iter().map(|r| r.length).sum::<f64>(),
            rows.iter().map(|r| r.pairs).sum::<usize>(),
            rows.iter().filter(|r| r.contact.is_some_and(|c| c.applied)).count(),
            rows.iter().map(|r| r.excess.inside + r.excess.between).sum::<f64>(),
            deltas.iter().flatten().map(|&x| f64::from(x).abs()).sum::<f64>(),
            rows.iter().filter_map(|r| r.contact).map(|c| c.iterations).sum::<usize>(),
            // FNV-1a over the deltas' bits: equal only when every written number is.
            deltas.iter().flatten().fold(0xcbf2_9ce4_8422_2325u64, |h, &x| (h ^ u64::from(x.to_bits())).wrapping_mul(0x0100_0000_01b3)),
        );
        if best.as_ref().is_none_or(|b| wall < b.0) {
            best = Some((wall, report.seconds));
        }
    }
    let (wall, s) = best.expect("at least one run");
    println!(
        "{} vertices, {} shapes: wall {wall:.3} s; setup {:.3}, virtual edges {:.3}, solves {:.3}, contact {:.3}, \
         report {:.3}; template once {template_seconds:.3}",
        source.len(),
        names.len(),
        s.factorisation,
        s.virtual_edges,
        s.solves,
        s.contact,
        s.penetration
    );
    println!(
        "checksum: length {:.9}, pairs {}, shapes the contact solve changed {}, excess over the template summed {:.9}, |deltas| summed {:.9}; \
         local re-solves {}; bits {:016x}",
        checksum.0, checksum.1, checksum.2, checksum.3, checksum.4, checksum.5, checksum.6
    );
}
