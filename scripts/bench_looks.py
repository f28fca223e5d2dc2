"""Where riggers look first, measured on every wrap bench character and on stylised ones (run
with the bpy Python):

    python scripts/bench_looks.py [-- --json OUT.json]

Characters, each with point pairs known by construction and the same-topology truth sampled
at its vertices:
- bench_wrap's: Target_OldMan subdivided and collapse-decimated to about 10k and 25k vertices,
  in centimetres with Y up; the sample's Character_YoungWoman (its stored pairs);
- stylised (scripts/stylised.py): the template warped to cartoon proportions, its keys warped
  by the same map, copied decimated to half and subdivided-then-decimated, in centimetres Y up,
  metres facing +X and millimetres.
Per character, per key (the native `look_at_keys`, as the wrap report has them): the eyes'
gap after each blink (closed: at most 5% of the rest opening), triangles turned over, the lid
line's and the lip contour's turning against the template's, jawOpen's opening against the
template's relative to the face, the share of it mouthClose closes, and the keys' roughness
against the truth's; the keys' error against the truth beside the nearest-vertex copy's. And
bench_wrap's perfect-alignment row: the carry's error against the nearest-vertex copy's.
"""

import argparse
import os
import sys

import bpy
import numpy as np

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
import batch  # noqa: E402
import bench_wrap  # noqa: E402
import makehuman  # noqa: E402
import stylised  # noqa: E402
from wrap_copies import barycentric_copy, moving_error, nearest_vertex_copy  # noqa: E402


def modules(shapesmith):
    from importlib import import_module

    return {name: import_module(f"{shapesmith.__name__}.blender.{name}") for name in ("wrap", "mesh_arrays", "transfer")}


def chain(shapesmith, character, entries, truth, template_points=None):
    """The whole chain (pairs `entries`, or stored ones when None) onto `character`; its keys'
    looks with `truth` (K, Nc, 3) given, their error against it and the nearest-vertex copy's."""
    m = modules(shapesmith)
    template = bpy.data.objects["Template"]
    if entries is None:
        template_points, character_points = m["wrap"].stored_pairs(character, template)
    else:
        template_points, character_points = m["wrap"].pairs_from_list(entries, template, character)
    wrapped = m["wrap"].wrap_object(template, character, template_points, character_points)
    wrapped_object = m["wrap"].show_wrapped(wrapped)
    result = m["wrap"].carry_onto_character(template, character, wrapped_object, truth=truth)
    diagonal = wrapped.report["diagonal"]
    points = bench_wrap.positions(character)
    wrapped_positions = bench_wrap.positions(wrapped_object)
    wrapped_deltas = m["transfer"].transfer_object(template, wrapped_object).deltas.astype(np.float64)
    m["wrap"].remove_object(wrapped_object)
    # The same measures read on the truth itself: what a perfect carry would read.
    rest = bench_wrap.positions(template)
    own = np.stack([bench_wrap.block_positions(template, n) - rest for n in result.names])
    f32 = lambda a: np.ascontiguousarray(a, dtype=np.float32)  # noqa: E731
    truth_looks = shapesmith.native.module().look_at_keys(
        f32(rest), f32(own), m["mesh_arrays"].read_triangles(template), list(result.names), f32(wrapped_positions),
        f32(wrapped_deltas), f32(points), m["mesh_arrays"].read_triangles(character), f32(truth), f32(truth))
    return {
        "vertices": len(points),
        "looks": result.report["looks"],
        "truth_looks": truth_looks,
        "error": {
            "carry": moving_error(result.deltas.astype(np.float64), truth, diagonal),
            "nearest vertex": moving_error(nearest_vertex_copy(wrapped_positions, wrapped_deltas, points), truth, diagonal),
        },
    }


def summary(row, which="looks"):
    """The looks of one character's keys (`which`: the carried "looks" or the "truth_looks")
    as a rigger reads them."""
    shapes = {s["name"]: s for s in row[which]["shapes"]}
    out = {}
    for name in ("eyeBlinkLeft", "eyeBlinkRight"):
        s = shapes.get(name, {})
        if s.get("eye_gap") is not None:
            out[name] = {"gap": s["eye_gap"], "template gap": s["template_eye_gap"], "closes": s["eyes_close"],
                         "lid turning / template's": s["lid_turning"] / max(s["template_lid_turning"], 1e-12)}
    jaw, close = shapes.get("jawOpen", {}), shapes.get("mouthClose", {})
    if jaw.get("mouth_opening") is not None:
        out["jawOpen"] = {"opening / template's": jaw["mouth_opening"] / max(jaw["template_mouth_opening"], 1e-12),
                          "lip turning / template's": jaw["lip_turning"] / max(jaw["template_lip_turning"], 1e-12)}
    if close.get("mouth_closing") is not None:
        out["mouthClose"] = {"closes": close["mouth_closing"], "template closes": close["template_mouth_closing"]}
    ratios = [s["roughness"] / s["truth_roughness"] for s in shapes.values() if s.get("truth_roughness")]
    out["roughness / truth's"] = {"median": float(np.median(ratios)), "max": float(np.max(ratios)),
                                  "over 1.1": sorted(n for n, s in shapes.items() if s.get("truth_roughness") and s["roughness"] > 1.1 * s["truth_roughness"])}
    out["turned over"] = {n: s["turned_over"] for n, s in shapes.items() if s["turned_over"]}
    out["error"] = row["error"]
    return out


def bench_characters(shapesmith):
    """bench_wrap's 10k and 25k characters and the sample's Character_YoungWoman."""
    m = modules(shapesmith)
    nat = shapesmith.native.module()
    template, identity = bpy.data.objects["Template"], bpy.data.objects[bench_wrap.IDENTITY]
    truth = m["transfer"].transfer_object(template, identity).deltas.astype(np.float64)
    skin = makehuman.largest_piece(len(template.data.vertices), [tuple(p.vertices) for p in template.data.polygons])
    pair_vertices = makehuman.pair_vertices(bench_wrap.positions(template), skin)
    rows = {}
    for label, vertices in bench_wrap.SIZES.items():
        character = bench_wrap.build_character(identity, f"Character_{label}", vertices)
        points = bench_wrap.positions(character)
        back = (points - bench_wrap.SHIFT) / bench_wrap.SCALE
        back = np.stack([back[:, 0], -back[:, 2], back[:, 1]], axis=1)
        reference = barycentric_copy(nat, back, bench_wrap.positions(identity), m["mesh_arrays"].read_triangles(identity), truth)
        reference = np.stack([makehuman.character_frame(r, bench_wrap.SCALE) for r in reference])
        entries = [[int(v), [float(x) for x in q]] for v, q in zip(pair_vertices, bench_wrap.to_character(bench_wrap.positions(identity)[pair_vertices]))]
        rows[f"{bench_wrap.IDENTITY} {label}"] = chain(shapesmith, character, entries, reference)
    young = bpy.data.objects["Character_YoungWoman"]
    young_truth = m["transfer"].transfer_object(template, bpy.data.objects["Target_YoungWoman"]).deltas.astype(np.float64)
    rows["Character_YoungWoman"] = chain(shapesmith, young, None, bench_wrap.young_reference(shapesmith, young, young_truth))
    return rows


def stylised_characters(shapesmith, copies=None, frames=None):
    """The stylised head's copies (`stylised.COPIES` x `stylised.FRAMES`)."""
    m = modules(shapesmith)
    nat = shapesmith.native.module()
    template = bpy.data.objects["Template"]
    head, names, truth = stylised.stylised_head(template)
    warped = bench_wrap.positions(head)
    head_triangles = m["mesh_arrays"].read_triangles(head)
    skin = makehuman.largest_piece(len(warped), [tuple(p.vertices) for p in template.data.polygons])
    pair_vertices = makehuman.pair_vertices(bench_wrap.positions(template), skin)
    rows = {}
    for copy in copies or stylised.COPIES:
        for frame in frames or stylised.FRAMES:
            to_frame = stylised.FRAMES[frame]
            character = stylised.stylised_character(head, f"Stylised_{len(rows)}", copy, frame)
            # The character's vertices back in the head's frame (the frames are similarities).
            origin = to_frame(np.zeros((1, 3)))[0]
            linear = np.stack([to_frame(np.eye(3)[[i]])[0] - origin for i in range(3)])
            back = np.linalg.solve(linear.T, (bench_wrap.positions(character) - origin).T).T
            reference = barycentric_copy(nat, back, warped, head_triangles, truth)
            reference = np.einsum("kvi,ij->kvj", reference, linear)
            entries = [[int(v), [float(x) for x in q]] for v, q in zip(pair_vertices, to_frame(warped[pair_vertices]))]
            rows[f"stylised, {copy}, {frame}"] = chain(shapesmith, character, entries, reference)
            bpy.data.objects.remove(character)
    return rows, names


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="bench_looks.py --")
    cache = os.environ.get("SHAPESMITH_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "shapesmith"))
    parser.add_argument("--json", default=os.path.join(cache, "bench", "bench_looks.json"))
    parser.add_argument("--stylised-only", action="store_true")
    args = parser.parse_args(argv)
    shapesmith = batch.load_shapesmith()
    bpy.ops.wm.open_mainfile(filepath=batch.cached_sample())
    rows = {} if args.stylised_only else bench_characters(shapesmith)
    rows.update(stylised_characters(shapesmith)[0])
    result = {label: {"summary": summary(row), "vertices": row["vertices"]} for label, row in rows.items()}
    for label, row in rows.items():
        result[f"{label}: the truth itself"] = {"summary": {k: v for k, v in summary(row, "truth_looks").items() if k != "error"}}
    if not args.stylised_only:
        perfect = bench_wrap.run_perfect(shapesmith)
        error = perfect["error"]
        perfect["closer than the nearest-vertex copy"] = 1.0 - error["carry"] / error["nearest vertex"]
        result["perfect alignment"] = perfect
    for label, row in result.items():
        print(f"\n== {label}")
        for key, value in (row.get("summary") or row).items():
            print(f"  {key}: {value}")
    batch.write_json(args.json, {"characters": result, "rows": {k: v["looks"] for k, v in rows.items()}})
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
