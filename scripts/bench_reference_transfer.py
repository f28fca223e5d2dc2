"""Transfer Shape Keys against a C++ reference deformation transfer (a report, not a test),
run with the bpy Python:

    python scripts/bench_reference_transfer.py [-- --runs 3 --json OUT.json --keep DIR]

Builds `scripts/reference_transfer/reference_transfer.cpp` (Eigen, Debian's libeigen3-dev;
one g++ line, into the cache), a deformation transfer as pmp-library's: the target's cotangent
Laplacian, each shape's deformation gradients, its static vertices locked and its system
assembled and factorised afresh with Eigen's SimplicialLDLT, single-threaded. Then, on the
bundled head (Template onto the first Target_*), the 25k head of `bench_transfer.py` and the
many-piece version of that head (`production_heads.py`'s recipe: pieces grown through the
skin, the lashes copied), in one run:

1. sameness: Shapesmith's plain transfer (no virtual edges, no collision pass, no rotation
   alignment: the reference's energy and constraints) against the reference's deltas, the
   largest difference over the shape's largest delta; the comparison below is fair only if
   this is small (`SAME_WITHIN`);
2. speed: best-of-`runs` wall seconds of the reference (reading and writing excluded), of the
   plain transfer and of the virtual-edge transfer with the collision pass off (the default
   transfer without the pass), and the ratio reference / virtual edges.

`--keep DIR` leaves each head's arrays in DIR/<head>/ for
`cargo run --release --example time_transfer -- DIR/<head> --no-contact --no-report`.
"""

import argparse
import json
import os
import resource
import shutil
import subprocess
import sys
import tempfile
import time

import bpy
import numpy as np

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
import batch  # noqa: E402
import bench_transfer  # noqa: E402
import production_heads  # noqa: E402

SOURCE = os.path.join(SCRIPTS, "reference_transfer", "reference_transfer.cpp")
EIGEN = "/usr/include/eigen3"
SAME_WITHIN = 1e-4  # of each shape's largest delta: solver round-off is far below, a wrong energy far above
GOAL_RATIO = 2.0


def build_reference(cache):
    """The reference binary, rebuilt when its source is newer (g++ -O3 -march=native, as a
    release build of pmp would be)."""
    if not os.path.isdir(EIGEN):
        raise SystemExit(f"Eigen is not installed ({EIGEN} missing): apt-get install libeigen3-dev (scripts/setup does)")
    binary = os.path.join(cache, "reference_transfer")
    if not os.path.exists(binary) or os.path.getmtime(binary) < os.path.getmtime(SOURCE):
        os.makedirs(cache, exist_ok=True)
        subprocess.run(["g++", "-std=c++17", "-O3", "-march=native", "-DNDEBUG", f"-I{EIGEN}", SOURCE, "-o", binary], check=True)
    return binary


def children_cpu():
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def run_reference(binary, folder, runs):
    """Best-of-`runs` seconds the reference reports (with the CPU seconds of that run, reading
    and writing included), and its deltas (K, N, 3)."""
    out = os.path.join(folder, "reference_deltas.f32")
    best = None
    for _ in range(runs):
        cpu = children_cpu()
        done = subprocess.run([binary, folder, out], check=True, capture_output=True, text=True)
        seconds = dict(json.loads(done.stdout), cpu=children_cpu() - cpu)
        if best is None or seconds["seconds"] < best["seconds"]:
            best = seconds
    return best, np.fromfile(out, dtype="<f4")


def run_native(nat, head, names, runs, transfer):
    """Best-of-`runs` wall seconds of `transfer_shapes` with the `transfer` part of its
    settings (penetration report off), the CPU seconds of that run (all threads), and its
    deltas."""
    best, deltas = {"wall": float("inf")}, None
    k = len(names)
    source_deltas = np.ascontiguousarray(head["deltas"].reshape(k, -1, 3), dtype=np.float32)
    arrays = [np.ascontiguousarray(head[key], dtype=dtype) for key, dtype in
              (("source", np.float32), ("target", np.float32), ("triangles", np.int32))]
    for _ in range(runs):
        started, cpu = time.perf_counter(), time.process_time()
        deltas, _ = nat.transfer_shapes(arrays[0], source_deltas, arrays[1], arrays[2], names,
                                       {"transfer": transfer, "measure_penetration": False})
        wall = time.perf_counter() - started
        if wall < best["wall"]:
            best = {"wall": wall, "cpu": time.process_time() - cpu}
    return best, deltas


def largest_difference(ours, reference, shapes):
    """Over the shapes, the largest |ours - reference| at a vertex over the shape's largest
    delta (reference side; shapes that do not move are skipped)."""
    ours, reference = ours.reshape(shapes, -1, 3), reference.reshape(shapes, -1, 3)
    worst = 0.0
    for k in range(shapes):
        scale = np.linalg.norm(reference[k], axis=1).max()
        if scale > 0.0:
            worst = max(worst, float(np.linalg.norm(ours[k] - reference[k], axis=1).max() / scale))
    return worst


def heads(mesh_arrays, rest_positions):
    """The benched heads as arrays: source, target, deltas, triangles."""
    template = bpy.data.objects["Template"]
    target = sorted((o for o in bpy.data.objects if o.name.startswith("Target_")), key=lambda o: o.name)[0]

    def arrays(source_obj, target_obj):
        rig = mesh_arrays.read_rig(source_obj)
        return {
            "source": rig.neutral.astype(np.float64),
            "target": rest_positions(target_obj).astype(np.float64),
            "deltas": rig.deltas.reshape(-1, 3).astype(np.float64),
            "triangles": rig.triangles.astype(np.int64),
        }, rig.names

    bundled, names = arrays(template, target)
    face = (
        bench_transfer.subdivided(template, "TemplateDenseFace", bench_transfer.FACE_EDGES),
        bench_transfer.subdivided(target, "TargetDenseFace", bench_transfer.FACE_EDGES, template=template),
    )
    dense, _ = arrays(*face)
    return {"bundled": bundled, "25k": dense, "25k, many pieces": production_heads.many_pieces(dense)}, names


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="bench_reference_transfer.py --")
    parser.add_argument("--runs", type=int, default=3)
    parser.add_argument("--json", default=os.path.join(bench_transfer.batch_cache(), "bench", "reference_transfer.json"))
    parser.add_argument("--keep", metavar="DIR", help="leave each head's arrays in DIR/<head>/")
    args = parser.parse_args(argv)
    binary = build_reference(os.path.join(bench_transfer.batch_cache(), "reference_transfer"))
    shapesmith = batch.load_shapesmith()
    from importlib import import_module

    mesh_arrays = import_module(shapesmith.__name__ + ".blender.mesh_arrays")
    rest_positions = import_module(shapesmith.__name__ + ".blender.transfer").rest_positions
    nat = shapesmith.native.module()
    bpy.ops.wm.open_mainfile(filepath=batch.cached_sample())
    benched, names = heads(mesh_arrays, rest_positions)
    work = args.keep or tempfile.mkdtemp(prefix="shapesmith-reference-")
    rows = {}
    try:
        for label, head in benched.items():
            folder = os.path.join(work, label.replace(", ", "_").replace(" ", "_"))
            production_heads.write_head(head, folder)
            reference, reference_deltas = run_reference(binary, folder, args.runs)
            plain, plain_deltas = run_native(nat, head, names, args.runs,
                                              {"virtual_edges": None, "contact": None, "align_rotation": False})
            edges, _ = run_native(nat, head, names, args.runs, {"contact": None})
            rows[label] = {
                "vertices": len(head["source"]),
                "triangles": len(head["triangles"]),
                "pieces": int(production_heads.pieces(len(head["source"]), head["triangles"]).max() + 1),
                "shapes": len(names),
                "reference": reference,
                "plain": plain,
                "virtual_edges": edges,
                "plain_vs_reference": largest_difference(plain_deltas, reference_deltas, len(names)),
            }
    finally:
        if not args.keep:
            shutil.rmtree(work, ignore_errors=True)
    print(f"\n== Transfer against the C++ Eigen reference (best of {args.runs}, wall seconds, CPU seconds of that run in "
          f"brackets; reference single-threaded, Shapesmith on {os.cpu_count()} cores, load {os.getloadavg()[0]:.1f})")
    print(f"  {'head':18s} {'vertices':>8s} {'pieces':>6s} {'reference':>15s} {'plain':>15s} {'VE':>15s} {'ref/VE':>6s} "
          f"{'ref/plain':>9s} {'plain vs ref':>12s}")
    for label, row in rows.items():
        reference, plain, edges = row["reference"], row["plain"], row["virtual_edges"]
        row["ratio"] = reference["seconds"] / edges["wall"]
        same = row["plain_vs_reference"] <= SAME_WITHIN
        print(f"  {label:18s} {row['vertices']:8d} {row['pieces']:6d} {reference['seconds']:7.3f} ({reference['cpu']:5.3f}) "
              f"{plain['wall']:7.3f} ({plain['cpu']:5.3f}) {edges['wall']:7.3f} ({edges['cpu']:5.3f}) {row['ratio']:6.2f} "
              f"{reference['seconds'] / plain['wall']:9.2f} "
              f"{row['plain_vs_reference']:12.2e}{'' if same else '  NOT THE SAME: the ratio compares different work'}")
    setups = ", ".join(f"{label} {row['reference']['setup']:.3f}" for label, row in rows.items())
    print(f"  (reference setup: {setups} s; goal: ref/VE >= {GOAL_RATIO})")
    batch.write_json(args.json, rows)
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
