"""Wrap benchmark (SPEC section 5), run with the bpy Python:

    python scripts/bench_wrap.py [-- --json OUT.json]

Characters of other topology with a known answer: the identity head Target_OldMan subdivided
and collapse-decimated to about 10k and 25k vertices, in centimetres with Y up, paired with
the template at 10 vertices known by construction. For each: seconds per stage of the whole
chain (io, align, wrap, transfer onto the wrapped template, carry onto the character), the
fit (mean and max distance to the character, / bbox diagonal), and the error of the keys
against the same-topology transfer onto the undecimated head sampled at the character's
vertices (mean over shapes of the mean error on vertices moving more than 1e-3 of the
diagonal, / diagonal), beside the nearest-vertex and plain barycentric copies of the
wrapped template's keys measured in the same run, and the fit's floor (the same-topology
keys copied from where the fit put each template vertex, as if the transfer onto the wrapped
template were exact: the error the fit's slide along the surface alone causes); and the
keys' roughness (mean norm of the uniform Laplacian of the deltas on moving vertices, /
diagonal); and the shapes of the carried keys that add more intersection curve to the
character's neutral than the template's shape allows (SPEC 3's criterion, excess over 1e-3
of the diagonal), with the carry's collision pass (the chain's default) and
without it (the plain carry of the same wrapped keys, timed in the same run).
"""

import argparse
import json
import os
import sys
import time

import bpy
import bmesh  # noqa: I001  (bmesh loads only after bpy)
import numpy as np

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
import batch  # noqa: E402
import makehuman  # noqa: E402
from wrap_copies import barycentric_copy, moving_error, nearest_vertex_copy  # noqa: E402

IDENTITY = "Target_OldMan"
SIZES = {"10k": 10_000, "25k": 25_000}
SCALE, SHIFT = 100.0, np.array([5.0, 160.0, -3.0])  # centimetres, Y up, moved


def to_character(points):
    return makehuman.character_frame(points, SCALE) + SHIFT


def positions(obj):
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", co)
    return co.reshape(-1, 3).astype(np.float64)


def build_character(identity, name, vertices):
    """The identity subdivided (bmesh, one cut per edge, grid fill) until it has more than
    `vertices`, then collapse-decimated to about that many, moved into the character frame."""
    mesh = bmesh.new()
    mesh.from_mesh(identity.data)
    while len(mesh.verts) < vertices:
        bmesh.ops.subdivide_edges(mesh, edges=mesh.edges[:], cuts=1, use_grid_fill=True)
    data = bpy.data.meshes.new(name)
    mesh.to_mesh(data)
    mesh.free()
    obj = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(obj)
    obj.modifiers.new("Decimate", "DECIMATE").ratio = vertices / len(data.vertices)
    decimated = bpy.data.meshes.new_from_object(obj.evaluated_get(bpy.context.evaluated_depsgraph_get()))
    obj.modifiers.clear()
    obj.data = decimated
    decimated.vertices.foreach_set("co", to_character(positions(obj)).astype(np.float32).ravel())
    decimated.update()
    return obj


def roughness(deltas, edges, reference, diagonal):
    """Mean norm of the uniform Laplacian of the deltas on moving vertices, / diagonal."""
    n = deltas.shape[1]
    degree = np.bincount(edges.ravel(), minlength=n).astype(np.float64)
    values = []
    for est, ref in zip(deltas, reference):
        summed = np.zeros((n, 3))
        np.add.at(summed, edges[:, 0], est[edges[:, 1]])
        np.add.at(summed, edges[:, 1], est[edges[:, 0]])
        laplacian = summed / np.maximum(degree, 1)[:, None] - est
        moving = np.linalg.norm(ref, axis=1) > 1e-3 * diagonal
        if moving.any():
            values.append(np.linalg.norm(laplacian[moving], axis=1).mean() / diagonal)
    return float(np.mean(values))


def run_size(shapesmith, label, vertices, truth):
    from importlib import import_module

    wrap = import_module(shapesmith.__name__ + ".blender.wrap")
    mesh_arrays = import_module(shapesmith.__name__ + ".blender.mesh_arrays")
    transfer = import_module(shapesmith.__name__ + ".blender.transfer")
    nat = shapesmith.native.module()
    template, identity = bpy.data.objects["Template"], bpy.data.objects[IDENTITY]
    character = build_character(identity, f"Character_{label}", vertices)
    skin = makehuman.largest_piece(len(template.data.vertices), [tuple(p.vertices) for p in template.data.polygons])
    pair_vertices = makehuman.pair_vertices(positions(template), skin)
    entries = [[int(v), [float(x) for x in q]] for v, q in zip(pair_vertices, to_character(positions(identity)[pair_vertices]))]
    started = time.perf_counter()
    template_points, character_points = wrap.pairs_from_list(entries, template, character)
    wrapped = wrap.wrap_object(template, character, template_points, character_points)
    wrapped_object = wrap.show_wrapped(wrapped)
    shown = time.perf_counter()
    result = wrap.carry_onto_character(template, character, wrapped_object, seconds=wrapped.seconds)
    total = time.perf_counter() - started
    seconds = dict(result.report["stage_seconds"])
    seconds["picture"] = shown - started - sum(wrapped.seconds.values())
    seconds["total"] = total
    diagonal = wrapped.report["diagonal"]
    # The same-topology result sampled at the character's vertices (back in the identity's frame).
    points = positions(character)
    identity_frame = (points - SHIFT) / SCALE
    identity_frame = np.stack([identity_frame[:, 0], -identity_frame[:, 2], identity_frame[:, 1]], axis=1)
    identity_triangles = mesh_arrays.read_triangles(identity)
    reference = barycentric_copy(nat, identity_frame, positions(identity), identity_triangles, truth)
    reference = np.stack([makehuman.character_frame(r, SCALE) for r in reference])
    wrapped_positions = positions(wrapped_object)
    wrapped_deltas = transfer.transfer_object(template, wrapped_object).deltas.astype(np.float64)
    # The same keys carried without the collision pass, judged on the character as the pass
    # judges (so both times include the sweep of every shape).
    plain_report = {k: v for k, v in result.report.items() if k != "carry"}
    plain_report["penetration"] = result.report["wrapped_penetration"]
    plain_started = time.perf_counter()
    plain, plain_carry = nat.carry_shapes(
        np.ascontiguousarray(wrapped_positions, dtype=np.float32),
        mesh_arrays.read_triangles(wrapped_object),
        np.ascontiguousarray(wrapped_deltas, dtype=np.float32),
        np.ascontiguousarray(points, dtype=np.float32),
        mesh_arrays.read_triangles(character),
        {"collision_pass": False},
        **wrap.template_curve(plain_report),
    )
    plain_seconds = time.perf_counter() - plain_started
    copies = {
        "carry": result.deltas.astype(np.float64),
        "plain carry": plain.astype(np.float64),
        "nearest vertex": nearest_vertex_copy(wrapped_positions, wrapped_deltas, points),
        "barycentric": barycentric_copy(nat, points, wrapped_positions, mesh_arrays.read_triangles(wrapped_object), wrapped_deltas),
    }
    # The fit's floor: the same-topology keys themselves (template vertex order) copied from
    # where the fit put each template vertex, as if the transfer onto the wrapped template
    # were exact; what is left is where the fit slid the template along the surface.
    true_keys = np.stack([makehuman.character_frame(r, SCALE) for r in truth])
    fit_floor = barycentric_copy(nat, points, wrapped_positions, mesh_arrays.read_triangles(wrapped_object), true_keys)
    edges = np.array([tuple(e.vertices) for e in character.data.edges])
    row = {
        "vertices": len(points),
        "template_vertices": len(wrapped_positions),
        "seconds": seconds,
        "fit": {k: wrapped.report[k] for k in ("mean_distance", "max_distance", "pair_residuals", "fit")},
        "error": {name: moving_error(d, reference, diagonal) for name, d in copies.items()},
        "fit_floor": moving_error(fit_floor, reference, diagonal),
        "roughness": {name: roughness(d, edges, reference, diagonal) for name, d in copies.items()},
    }
    row["roughness"]["same-topology (sampled)"] = roughness(reference, edges, reference, diagonal)
    plain_rows = wrap.character_rows(plain_report, plain_carry["penetration"])
    row["worse"] = {name: worse_than_template(rows, diagonal) for name, rows in (("carry", result.report["penetration"]), ("plain carry", plain_rows))}
    row["carry_seconds"] = {"carry": seconds["carry"], "plain carry": plain_seconds}
    # What the carry's collision pass did to each shape it acted on.
    names = [r["name"] for r in result.report["penetration"]]
    row["carry_collisions"] = {n: c for n, c in zip(names, result.report["carry"].get("collisions", [])) if c["plain_excess"] > 0}
    wrap.remove_object(wrapped_object)
    return row


def worse_than_template(rows, diagonal):
    """The shapes whose excess over the template (both parts, SPEC 3's criterion) is over
    1e-3 of the diagonal, name -> excess / diagonal."""
    excess = {row["name"]: (row["excess"]["inside"] + row["excess"]["between"]) / diagonal for row in rows}
    return {name: e for name, e in excess.items() if e > 1e-3}


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="bench_wrap.py --")
    cache = os.environ.get("SHAPESMITH_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "shapesmith"))
    parser.add_argument("--json", default=os.path.join(cache, "bench", "bench_wrap.json"))
    args = parser.parse_args(argv)
    shapesmith = batch.load_shapesmith()
    from importlib import import_module

    transfer = import_module(shapesmith.__name__ + ".blender.transfer")
    bpy.ops.wm.open_mainfile(filepath=batch.cached_sample())
    truth = transfer.transfer_object(bpy.data.objects["Template"], bpy.data.objects[IDENTITY]).deltas.astype(np.float64)
    result = {label: run_size(shapesmith, label, vertices, truth) for label, vertices in SIZES.items()}
    print("\n== Wrap + transfer + carry onto a character of other topology (seconds, one run, 2 cores)")
    for label, row in result.items():
        s = row["seconds"]
        print(
            f"  {label}: {row['vertices']} character vertices ({row['template_vertices']} template): "
            + ", ".join(f"{k} {v:.3f}" for k, v in s.items())
        )
        fit = row["fit"]
        print(
            f"    fit: mean {100 * fit['mean_distance']:.3f}% / max {100 * fit['max_distance']:.2f}% of the diagonal; "
            f"largest pair residual {100 * max(fit['pair_residuals']):.3f}%"
        )
        print("    error vs same-topology transfer: " + ", ".join(f"{k} {v:.2e}" for k, v in row["error"].items()))
        print(f"    the fit's floor (same-topology keys copied from the wrapped template, no transfer): {row['fit_floor']:.2e}")
        print("    roughness (Laplacian of deltas): " + ", ".join(f"{k} {v:.2e}" for k, v in row["roughness"].items()))
        for name, worse in row["worse"].items():
            print(
                f"    {name}: {len(worse)} shapes worse than the template, excess {sum(worse.values()):.4f} of the diagonal, "
                f"{row['carry_seconds'][name]:.3f} s: " + ", ".join(f"{k} {v:.4f}" for k, v in sorted(worse.items()))
            )
    os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
    with open(args.json, "w") as f:
        json.dump(result, f, indent=2)
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
