"""Writes the arrays `native/examples/collision_counts.rs` reads, run with the bpy Python:

    python scripts/save_collision_arrays.py -- DIR

DIR/<head>/ for each Target_* head of the cached sample, for the 19k and 25k heads of
scripts/bench_transfer.py (its subdivided Template / first target pairs), and DIR/warp/ for
scripts/bench_personalise.py's warp ground truth (with `truth.f32`, the true shapes' deltas);
DIR/names.txt holds the template's shape names, one a line. Then

    cargo run --release --example collision_counts -- DIR/<head> DIR/names.txt

prints the shapes worse than the template (issue 9's criterion) plain, with virtual edges and
with the collision pass, and on DIR/warp the warp error with and without the pass.
"""

import os
import sys
from importlib import import_module

import bpy
import numpy as np

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
import batch  # noqa: E402
import bench_personalise  # noqa: E402
import bench_transfer  # noqa: E402


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    if len(argv) != 1:
        raise SystemExit("usage: save_collision_arrays.py -- DIR")
    out = argv[0]
    shapesmith = batch.load_shapesmith()
    mesh_arrays = import_module(shapesmith.__name__ + ".blender.mesh_arrays")
    transfer = import_module(shapesmith.__name__ + ".blender.transfer")
    bpy.ops.wm.open_mainfile(filepath=batch.cached_sample())
    template = bpy.data.objects["Template"]
    rig = mesh_arrays.read_rig(template)
    targets = sorted((o for o in bpy.data.objects if o.name.startswith("Target_")), key=lambda o: o.name)
    for target in targets:
        bench_transfer.save_arrays(rig, transfer.rest_positions(target), os.path.join(out, target.name))
    dense = bench_transfer.subdivided(template, "TemplateDense"), bench_transfer.subdivided(targets[0], "TargetDense")
    face = (
        bench_transfer.subdivided(template, "TemplateDenseFace", bench_transfer.FACE_EDGES),
        bench_transfer.subdivided(targets[0], "TargetDenseFace", bench_transfer.FACE_EDGES, template=template),
    )
    for head, (source, target) in (("19k", dense), ("25k", face)):
        bench_transfer.save_arrays(mesh_arrays.read_rig(source), transfer.rest_positions(target), os.path.join(out, head))
    truth = bench_personalise.WarpGroundTruth(shapesmith.native.module(), rig, {})
    bench_transfer.save_arrays(rig, truth.target, os.path.join(out, "warp"))
    np.ascontiguousarray(truth.truth, dtype="<f4").tofile(os.path.join(out, "warp", "truth.f32"))
    with open(os.path.join(out, "names.txt"), "w") as f:
        f.write("\n".join(rig.names))
    print(f"wrote {len(targets) + 3} heads to {out}")


if __name__ == "__main__":
    main()
