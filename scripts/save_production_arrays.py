"""Writes the transfer target of `bench_production.py` (Target_OldMan of the cached sample,
subdivided 0, 1 and 2 times as `production_rig.subdivide` does: 4.9k, 19k and 77k vertices)
as the arrays the native timing examples read, run with the bpy Python:

    python scripts/save_production_arrays.py -- DIR

DIR/production_<level>/target.f32 and triangles.u32 (little-endian, the triangles as the
add-on reads them), then for example

    cargo run --release --example time_virtual_edges -- DIR/production_2
"""

import importlib.util
import os
import sys

import bpy
import numpy as np

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
import production_rig  # noqa: E402
import sample_blend  # noqa: E402


def mesh_arrays():
    """The add-on's `blender/mesh_arrays.py` from this checkout (numpy only, no install)."""
    path = os.path.join(SCRIPTS, "..", "addon", "blender", "mesh_arrays.py")
    spec = importlib.util.spec_from_file_location("mesh_arrays", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    if len(argv) != 1:
        raise SystemExit("usage: save_production_arrays.py -- DIR")
    arrays = mesh_arrays()
    bpy.ops.wm.open_mainfile(filepath=sample_blend.cached_sample())
    target = bpy.data.objects[production_rig.TARGET]
    for level in range(3):
        production_rig.subdivide(target, 1 if level else 0)
        folder = os.path.join(argv[0], f"production_{level}")
        os.makedirs(folder, exist_ok=True)
        np.ascontiguousarray(production_rig.positions(target), dtype="<f4").tofile(os.path.join(folder, "target.f32"))
        np.ascontiguousarray(arrays.read_triangles(target), dtype="<u4").tofile(os.path.join(folder, "triangles.u32"))
        print(f"{folder}: {len(target.data.vertices)} vertices")


main()
