"""Pack Expressions benchmark (a report, not a test): the bundled Template and a denser copy
of it (every edge cut twice, about 9x the vertices, the same 52 shapes), timing Blender I/O
(reading the rig, storing the result) and native work separately, best of a few runs.

    python scripts/bench_pack.py [-- --repeats 5 --json OUT]     (bpy wheel, extension installed)

Target: every expression of the bundled rig in under 50 ms of native time.
"""

import argparse
import json
import os
import subprocess
import sys
import time

import bpy
import bmesh  # after bpy: the bpy wheel provides it

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from batch import BatchError, load_shapesmith  # noqa: E402

NATIVE_TARGET_SECONDS = 0.050


def denser_copy(obj, min_ratio=4.0):
    """A copy of `obj` with every edge cut twice (quads into nine): bmesh interpolates the
    shape key layers with the basis, so the shapes are the same surfaces, sampled finer."""
    dense = obj.copy()
    dense.data = obj.data.copy()
    dense.name = obj.name + "_dense"
    bpy.context.scene.collection.objects.link(dense)
    bm = bmesh.new()
    bm.from_mesh(dense.data)
    bmesh.ops.subdivide_edges(bm, edges=bm.edges[:], cuts=2, use_grid_fill=True)
    bm.to_mesh(dense.data)
    bm.free()
    ratio = len(dense.data.vertices) / len(obj.data.vertices)
    if ratio < min_ratio:
        raise BatchError(f"the denser copy has only {ratio:.2f}x the vertices")
    return dense


def measure(packing, obj, repeats):
    """Best-of-`repeats` seconds of reading, native packing and storing, and the result."""
    best = {"read": float("inf"), "native": float("inf"), "write": float("inf")}
    for _ in range(repeats):
        report = packing.pack_object(obj)
        started = time.perf_counter()
        packing.store_packing(obj, report)
        seconds = dict(report["seconds"], write=time.perf_counter() - started)
        best = {key: min(best[key], seconds[key]) for key in best}
    return report, best


def main():
    argv = sys.argv[sys.argv.index("--") + 1 :] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(description="Pack Expressions benchmark")
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--sample", default=os.path.join(
        os.environ.get("SHAPESMITH_CACHE", os.path.expanduser("~/.cache/shapesmith")), "sample-%d.%d.blend" % bpy.app.version[:2]))
    parser.add_argument("--json", help="write the measurements here")
    args = parser.parse_args(argv)

    shapesmith = load_shapesmith()
    if not os.path.isfile(args.sample):
        batch = os.path.join(os.path.dirname(os.path.abspath(__file__)), "batch.py")
        subprocess.run([sys.executable, batch, "--", "sample", "--output", args.sample], check=True)
    bpy.ops.wm.open_mainfile(filepath=args.sample)
    from importlib import import_module

    packing = import_module(shapesmith.__name__ + ".blender.packing")
    base = bpy.data.objects["Template"]
    dense = denser_copy(base)
    rows = {}
    for label, obj in (("base", base), ("dense", dense)):
        report, seconds = measure(packing, obj, args.repeats)
        rig = shapesmith.blender.mesh_arrays.read_rig(obj)
        greedy = shapesmith.native.module().pack_greedy(rig.neutral, rig.deltas, rig.triangles, rig.names)
        rows[label] = {
            "vertices": len(obj.data.vertices),
            "shapes": len(report["names"]),
            "J": len(report["expressions"]),
            "J_greedy": len(greedy["expressions"]),
            "all_optimal": all(e["optimal"] for e in report["expressions"]),
            "seconds": seconds,
        }
    print(f"{'rig':6} {'vertices':>9} {'J':>3} {'greedy J':>9} {'optimal':>8} {'read s':>9} {'native s':>9} {'write s':>9}")
    for label, row in rows.items():
        s = row["seconds"]
        print(f"{label:6} {row['vertices']:9d} {row['J']:3d} {row['J_greedy']:9d} {str(row['all_optimal']):>8} "
              f"{s['read']:9.4f} {s['native']:9.4f} {s['write']:9.4f}")
    ratios = {key: rows["dense"]["seconds"][key] / rows["base"]["seconds"][key] for key in ("read", "native", "write")}
    vertex_ratio = rows["dense"]["vertices"] / rows["base"]["vertices"]
    print(f"dense/base: vertices x{vertex_ratio:.2f}, read x{ratios['read']:.2f}, native x{ratios['native']:.2f}, "
          f"write x{ratios['write']:.2f}")
    native = rows["base"]["seconds"]["native"]
    verdict = "met" if native < NATIVE_TARGET_SECONDS else "NOT met"
    print(f"target: all expressions of the bundled rig in < {NATIVE_TARGET_SECONDS * 1000:.0f} ms native: "
          f"{native * 1000:.1f} ms, {verdict}")
    if args.json:
        with open(args.json, "w") as f:
            json.dump({"rows": rows, "ratios": ratios, "vertex_ratio": vertex_ratio, "repeats": args.repeats}, f, indent=2)


if __name__ == "__main__":
    main()
