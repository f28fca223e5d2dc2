"""The transfer's collision pass on heads resembling production rigs, run with the bpy Python:

    python scripts/bench_contact.py [-- --json OUT.json] [--runs R]

The heads are made by code from the cached sample as scripts/production_heads.py makes them:
`many_<target>` (82 pieces crossing the skin at rest: helper pieces grown and moved to the
front, lashes copied) and `lips_<target>` (a template whose neutral's lips cross onto the clean
target). On each, the native transfer as the add-on calls it (penetration report on, the
template's own numbers given) runs with the collision pass (the default) and without it
(virtual edges alone), alternately, R times each in one run: the best wall time of each and
their ratio, the pass's own seconds, and the shapes worse than the template by the report's
criterion (its `excess` beyond 1e-3 of the target's diagonal) before and after the pass.
Nothing is asserted: the numbers go to docs/transfer.md and docs/benchmarks.md.
"""

import argparse
import os
import sys
import time

import bpy
import numpy as np

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
import batch  # noqa: E402
import production_heads  # noqa: E402

WORSE = 1e-3  # of the target's bounding-box diagonal, as contact_counts and the panel judge


def heads(rig, targets, rest_positions):
    """name -> (template neutral, deltas (K, N, 3), target neutral, triangles), float32/int32;
    `many_self` is the first many-piece template onto itself."""
    out = {}
    for index, target in enumerate(targets):
        head = {
            "source": rig.neutral.astype(np.float64),
            "target": rest_positions(target).astype(np.float64),
            "deltas": rig.deltas.reshape(-1, 3).astype(np.float64),
            "triangles": rig.triangles.astype(np.int64),
        }
        many = production_heads.many_pieces(head)
        made_heads = [("many_" + target.name, many), ("lips_" + target.name, production_heads.crossing_lips(head, list(rig.names)))]
        if index == 0:
            made_heads.append(("many_self", {**many, "target": many["source"]}))
        for name, made in made_heads:
            n = len(made["source"])
            out[name] = (
                np.ascontiguousarray(made["source"], dtype=np.float32),
                np.ascontiguousarray(made["deltas"].reshape(-1, n, 3), dtype=np.float32),
                np.ascontiguousarray(made["target"], dtype=np.float32),
                np.ascontiguousarray(made["triangles"], dtype=np.int32),
            )
    return out


def worse(report, diagonal, key):
    rows = report["penetration"]
    return [r["name"] for r in rows if sum(r[key].values()) > WORSE * diagonal]


def bench_head(nat, names, arrays, runs):
    source, deltas, target, triangles = arrays
    template = nat.measure_penetration(source, deltas, triangles)
    diagonal = float(np.linalg.norm(target.max(0) - target.min(0)))
    best = {"default": None, "virtual edges alone": None}
    reports = {}
    for _ in range(runs):
        for label, settings in (("default", None), ("virtual edges alone", {"transfer": {"contact": None}})):
            start = time.perf_counter()
            _, report = nat.transfer_shapes(source, deltas, target, triangles, names, settings, template_penetration=template)
            wall = time.perf_counter() - start
            if best[label] is None or wall < best[label]:
                best[label] = wall
                reports[label] = report
    default = reports["default"]
    return {
        "vertices": len(source),
        "pieces_crossing_at_rest_pairs": default["neutral_penetration"]["pairs"],
        "default_seconds": best["default"],
        "virtual_edges_seconds": best["virtual edges alone"],
        "ratio": best["default"] / best["virtual edges alone"],
        "pass_seconds": default["seconds"]["contact"],
        "worse_virtual_edges": worse(default, diagonal, "before_contact_excess"),
        "worse_with_pass": worse(default, diagonal, "excess"),
    }


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="bench_contact.py --")
    cache = os.environ.get("SHAPESMITH_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "shapesmith"))
    parser.add_argument("--json", default=os.path.join(cache, "bench", "collision_pass.json"))
    parser.add_argument("--runs", type=int, default=3, help="runs of each variant, alternately (best taken)")
    args = parser.parse_args(argv)
    shapesmith = batch.load_shapesmith()
    from importlib import import_module

    mesh_arrays = import_module(shapesmith.__name__ + ".blender.mesh_arrays")
    transfer_module = import_module(shapesmith.__name__ + ".blender.transfer")
    nat = shapesmith.native.module()
    bpy.ops.wm.open_mainfile(filepath=batch.cached_sample())
    rig = mesh_arrays.read_rig(bpy.data.objects["Template"])
    targets = sorted((o for o in bpy.data.objects if o.name.startswith("Target_")), key=lambda o: o.name)
    names = list(rig.names)
    result = {}
    print("== Collision pass: default transfer against virtual edges alone (report on, best of "
          f"{args.runs} alternating runs each)")
    for name, arrays in heads(rig, targets, transfer_module.rest_positions).items():
        row = bench_head(nat, names, arrays, args.runs)
        result[name] = row
        print(
            f"  {name}: {row['vertices']} vertices, {row['pieces_crossing_at_rest_pairs']} pairs crossing at rest; "
            f"default {row['default_seconds']:.2f} s (pass {row['pass_seconds']:.2f} s), virtual edges alone "
            f"{row['virtual_edges_seconds']:.2f} s: x{row['ratio']:.2f}; worse than the template "
            f"{len(row['worse_virtual_edges'])} -> {len(row['worse_with_pass'])} {row['worse_with_pass']}",
            flush=True,
        )
    batch.write_json(args.json, result)
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
