"""Writes the arrays `native/examples/contact_counts.rs` reads, run with the bpy Python:

    python scripts/save_contact_arrays.py -- DIR

DIR/<head>/ for each Target_* head of the cached sample, for the 19k and 25k heads of
scripts/bench_transfer.py (its subdivided Template / first target pairs), and DIR/warp/ for
scripts/bench_personalise.py's warp ground truth (with `truth.f32`, the true shapes' deltas);
DIR/face_<head>/ for the face region alone of each Target_* head and of the 19k head (one surface: the skin's
moving vertices and two rings around them, no eyes, teeth or lashes; what a face-region rig
is); DIR/names.txt holds the template's shape names, one
a line. Then

    cargo run --release --example contact_counts -- DIR/<head> DIR/names.txt

prints the shapes worse than the template plain, with virtual edges and
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
import makehuman  # noqa: E402


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    if len(argv) != 1:
        raise SystemExit("usage: save_contact_arrays.py -- DIR")
    out = argv[0]
    shapesmith = batch.load_shapesmith()
    mesh_arrays = import_module(shapesmith.__name__ + ".blender.mesh_arrays")
    transfer = import_module(shapesmith.__name__ + ".blender.transfer")
    bpy.ops.wm.open_mainfile(filepath=batch.cached_sample())
    template = bpy.data.objects["Template"]
    rig = mesh_arrays.read_rig(template)
    targets = sorted((o for o in bpy.data.objects if o.name.startswith("Target_")), key=lambda o: o.name)
    region = FaceRegion(rig)
    for target in targets:
        rest = transfer.rest_positions(target)
        bench_transfer.save_arrays(rig, rest, os.path.join(out, target.name))
        bench_transfer.save_arrays(region.cut(rig), rest[region.kept], os.path.join(out, "face_" + target.name))
    dense = bench_transfer.subdivided(template, "TemplateDense"), bench_transfer.subdivided(targets[0], "TargetDense")
    face = (
        bench_transfer.subdivided(template, "TemplateDenseFace", bench_transfer.FACE_EDGES),
        bench_transfer.subdivided(targets[0], "TargetDenseFace", bench_transfer.FACE_EDGES, template=template),
    )
    for head, (source, target) in (("19k", dense), ("25k", face)):
        dense_rig, dense_rest = mesh_arrays.read_rig(source), transfer.rest_positions(target)
        bench_transfer.save_arrays(dense_rig, dense_rest, os.path.join(out, head))
        if head == "19k":
            dense_region = FaceRegion(dense_rig)
            bench_transfer.save_arrays(dense_region.cut(dense_rig), dense_rest[dense_region.kept], os.path.join(out, "face_19k"))
    truth = bench_personalise.WarpGroundTruth(shapesmith.native.module(), rig, {})
    bench_transfer.save_arrays(rig, truth.target, os.path.join(out, "warp"))
    np.ascontiguousarray(truth.truth, dtype="<f4").tofile(os.path.join(out, "warp", "truth.f32"))
    with open(os.path.join(out, "names.txt"), "w") as f:
        f.write("\n".join(rig.names))
    print(f"wrote {2 * len(targets) + 4} heads to {out}")


class FaceRegion:
    """The skin's face as one surface: the vertices of the largest connected piece that move
    in some shape (more than 1e-4 of the diagonal), grown by two rings over the skin's
    triangles, and the triangles with every corner among them."""

    def __init__(self, rig):
        triangles = rig.triangles.astype(np.int64)
        n = len(rig.neutral)
        skin = np.zeros(n, dtype=bool)
        skin[makehuman.largest_piece(n, triangles)] = True
        diagonal = np.linalg.norm(rig.neutral.max(0) - rig.neutral.min(0))
        chosen = skin & (np.linalg.norm(rig.deltas, axis=2).max(0) > 1e-4 * diagonal)
        for _ in range(2):
            touched = chosen[triangles].any(1)
            chosen[triangles[touched].ravel()] = True
            chosen &= skin
        self.kept = np.flatnonzero(chosen)
        index = np.full(n, -1)
        index[self.kept] = np.arange(len(self.kept))
        self.triangles = index[triangles[chosen[triangles].all(1)]].astype(np.uint32)

    def cut(self, rig):
        return type(rig)(
            neutral=rig.neutral[self.kept], deltas=rig.deltas[:, self.kept], triangles=self.triangles, names=rig.names
        )


if __name__ == "__main__":
    main()
