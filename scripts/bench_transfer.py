"""Transfer Shape Keys benchmark (method, section 4), run with the bpy Python:

    python scripts/bench_transfer.py [-- --json OUT.json]

1. Penetration on the MakeHuman identities (Target_*) and on the 25k head: per shape, the
   intersection curve the result adds to the target's neutral beyond what the template's
   shape adds to its own, for plain transfer, virtual edges before the collision pass and
   after it; shapes worse than the template, and the added curve summed. The cheap metric
   (only triangles with a moving corner re-tested) is checked against a full sweep; the
   virtual-edge weight is swept with the collision pass on.
2. Timings on the bundled rig, on a 4x denser subdivision of it (19k vertices) and on a
   25k-vertex version whose face, where the shapes move, is cut once more: native seconds
   split into setup, virtual edges, solves, collision pass and the penetration report.
   `--timings-only` skips part 1, `--heads` picks the timed heads, `--save-arrays DIR` writes
   their arrays for `cargo run --release --example time_transfer -- DIR/<head>`, which times
   the same native call outside Blender (two builds of it run alternately give before/after
   ratios in one run).
The warp ground truth of personalisation is scripts/bench_personalise.py.
"""

import argparse
import os
import sys
import time

import bpy
import bmesh  # noqa: I001  (bmesh loads only after bpy)
import numpy as np

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
import batch  # noqa: E402

FACE_EDGES = 4100  # edges cut again in the 25k timing mesh (19,337 -> 25,272 vertices)
HEADS = ("bundled", "4x denser", "25k, denser face")  # the timed heads: the sample's, subdivided, and its face cut again


def added_summary(transfer_module, report):
    """Shapes worse than the template and the added curve beyond the template's own summed
    over the shapes (positive parts only: a shape removing curve does not pay for another),
    for plain transfer, virtual edges before the collision pass, and the result."""
    out = {}
    for label, key in (("plain", "plain_length"), ("before collision pass", "before_contact_length"), ("result", "length")):
        if key not in report["penetration"][0]:
            continue
        added = [sum(transfer_module.added_beyond_template(report, row, key)) for row in report["penetration"]]
        out[label] = {
            "worse": transfer_module.worse_than_template(report, key=key),
            "added_curve": float(sum(max(a, 0.0) for a in added)),
        }
    return out


def penetration_benchmark(transfer_module, landmarks_module, settings, rig, template, targets):
    """Per target: total intersection-curve length with and without virtual edges beside the
    template's, and the shapes that add more intersection to the target's neutral than to
    the template's (plain, virtual edges before the collision pass, and after it). For each
    of those left, the extra curve inside one piece and between pieces, and the piece pairs
    whose crossing triangle pairs grew most beyond the template's (a diagnosis: pairs counted
    with Blender's BVHTree overlap)."""
    pieces = PieceCrossings(rig, landmarks_module.mesh_parts(template)["part_of_vertex"])
    template_rest = pieces.count(rig.neutral)
    template_penetration = transfer_module.measure_template_penetration(template)
    result = {}
    for target in targets:
        transfer = transfer_module.transfer_object(
            template, target, settings.TransferSettings(compare_plain=True), template_penetration=template_penetration
        )
        report = transfer.report
        rows = report["penetration"]
        worse = transfer_module.worse_than_template(report)
        target_rest = pieces.count(transfer.target_neutral)
        explained = {}
        for row in rows:
            if row["name"] not in worse:
                continue
            k = transfer.names.index(row["name"])
            inside, between = transfer_module.added_beyond_template(report, row)
            grown = pieces.growth(
                pieces.count(transfer.target_neutral + transfer.deltas[k]), target_rest,
                pieces.count(rig.neutral + rig.deltas[k]), template_rest,
            )
            explained[row["name"]] = {"inside_one_piece": inside, "between_pieces": between, "piece_pairs": grown[:2]}
        result[target.name] = {
            "virtual_edges": report["virtual_edges"],
            "length": sum(r["length"] for r in rows),
            "plain_length": sum(r["plain_length"] for r in rows),
            "template_length": sum(r["template_length"] for r in rows),
            "neutral_length": report["neutral_penetration"]["length"],
            "template_neutral_length": report["template_neutral_penetration"]["length"],
            "worse_than_template": worse,
            "worse_explained": explained,
            "plain_worse_than_template": transfer_module.worse_than_template(report, key="plain_length"),
            "summary": added_summary(transfer_module, report),
            "shapes": rows,
        }
    return result


def cheap_metric_check(nat, rig, target_neutral, deltas, count=8):
    """The per-shape metric (unmoved pairs taken from the rest sweep, only triangles with a
    moving corner re-tested) against a full sweep of the posed mesh, on `count` shapes spread
    over the rig: the largest differences in length and pair count."""
    cheap = nat.measure_penetration(target_neutral, deltas, rig.triangles)["shapes"]
    worst = {"length": 0.0, "pairs": 0, "shapes": 0}
    zero = np.zeros((1,) + target_neutral.shape, dtype=np.float32)
    for k in np.linspace(0, len(deltas) - 1, count).astype(int):
        posed = np.ascontiguousarray(target_neutral + deltas[k])
        full = nat.measure_penetration(posed, zero, rig.triangles)["neutral"]
        worst["length"] = max(worst["length"], abs(full["length"] - cheap[k]["length"]))
        worst["pairs"] = max(worst["pairs"], abs(full["pairs"] - cheap[k]["pairs"]))
        worst["shapes"] += 1
    return worst


def edge_weight_sweep(transfer_module, settings, template, targets, weights=(0.0, 1.0, 3.0, 10.0)):
    """Shapes worse than the template and added curve, per virtual-edge weight, with the
    collision pass on (weight 0: no virtual edges)."""
    template_penetration = transfer_module.measure_template_penetration(template)
    out = {}
    for weight in weights:
        row = {}
        for target in targets:
            chosen = settings.TransferSettings(transfer=settings.DeformationSettings(
                virtual_edges=settings.VirtualEdgeSettings() if weight > 0 else None, edge_weight=max(weight, 1e-9),
            ))
            report = transfer_module.transfer_object(template, target, chosen, template_penetration=template_penetration).report
            summary = added_summary(transfer_module, report)
            row[target.name] = {label: {"worse": len(v["worse"]), "added_curve": v["added_curve"]} for label, v in summary.items()}
        out[str(weight)] = row
    return out


class PieceCrossings:
    """Counts crossing triangle pairs (sharing no vertex) per pair of connected pieces, each
    piece named by its size and place (the sample head's skin, eyeballs, lashes, teeth and
    tongue are pieces of their own)."""

    def __init__(self, rig, part_of_vertex):
        """`part_of_vertex`: a label per vertex, one per loose part (`mesh_parts` of the
        add-on's landmarks module)."""
        self.triangles = [tuple(map(int, t)) for t in rig.triangles]
        roots, label = np.unique(part_of_vertex, return_inverse=True)
        names = []
        for k in range(len(roots)):
            members = label == k
            centre = rig.neutral[members].mean(0)
            names.append(f"{members.sum()} vertices at ({centre[0]:+.3f}, {centre[2]:.3f})")
        skin = int(np.argmax(np.bincount(label)))
        names[skin] = "skin"
        self.piece_of_triangle = [names[label[t[0]]] for t in self.triangles]

    def count(self, positions):
        from mathutils.bvhtree import BVHTree

        tree = BVHTree.FromPolygons([tuple(map(float, p)) for p in positions], self.triangles, all_triangles=True)
        counts = {}
        for a, b in tree.overlap(tree):
            if a < b and not set(self.triangles[a]) & set(self.triangles[b]):
                key = " - ".join(sorted((self.piece_of_triangle[a], self.piece_of_triangle[b])))
                counts[key] = counts.get(key, 0) + 1
        return counts

    @staticmethod
    def growth(shape, rest, template_shape, template_rest):
        """Piece pairs by how many more crossing pairs the shape adds than the template's
        shape adds, most first (only those that grew)."""
        keys = set(shape) | set(rest) | set(template_shape) | set(template_rest)

        def extra(key):
            return (shape.get(key, 0) - rest.get(key, 0)) - (template_shape.get(key, 0) - template_rest.get(key, 0))

        return [[key, extra(key)] for key in sorted(keys, key=lambda k: (-extra(k), k)) if extra(key) > 0]


def subdivided(obj, name, face_edges=0, template=None):
    """A copy of `obj` with every edge cut once (about 4x the vertices); shape keys are
    carried by bmesh as layers, so each key is subdivided exactly like the basis. With
    `face_edges`, that many more edges are cut again: those whose ends both move most in
    some shape of `template` (a subdivided copy with the same topology; `obj` itself when it
    has the keys), so template and target get the same cuts. Faces left with more than four
    corners are triangulated."""
    mesh = bmesh.new()
    mesh.from_mesh(obj.data)
    bmesh.ops.subdivide_edges(mesh, edges=mesh.edges[:], cuts=1, use_grid_fill=True)
    if face_edges:
        mesh.edges.ensure_lookup_table()
        chosen = most_moving_edges(template or obj, face_edges)
        bmesh.ops.subdivide_edges(mesh, edges=[mesh.edges[e] for e in chosen], cuts=1, use_grid_fill=True)
        bmesh.ops.triangulate(mesh, faces=[f for f in mesh.faces if len(f.verts) > 4])
    data = obj.data.copy()  # keeps the Key, whose blocks to_mesh fills from the layers
    mesh.to_mesh(data)
    mesh.free()
    copy = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(copy)
    return copy


def most_moving_edges(template, count):
    """Indices of the `count` edges of the once-subdivided `template` whose less moving end
    moves most, each vertex's motion being its largest displacement over the shapes relative
    to that shape's largest."""
    mesh = bmesh.new()
    mesh.from_mesh(template.data)
    bmesh.ops.subdivide_edges(mesh, edges=mesh.edges[:], cuts=1, use_grid_fill=True)
    layers = mesh.verts.layers.shape
    basis = np.array([v.co for v in mesh.verts])
    motion = np.zeros(len(basis))
    reference = template.data.shape_keys.reference_key.name
    for name in layers.keys():
        if name == reference:
            continue
        layer = layers[name]
        size = np.linalg.norm(np.array([v[layer] for v in mesh.verts]) - basis, axis=1)
        if size.max() > 0:
            motion = np.maximum(motion, size / size.max())
    ends = np.array([[e.verts[0].index, e.verts[1].index] for e in mesh.edges])
    mesh.free()
    return np.sort(np.argsort(-motion[ends].min(axis=1), kind="stable")[:count]).tolist()


def timing_benchmark(nat, mesh_arrays, transfer_module, template, target, rest_positions, runs=3):
    """Best-of-`runs` native seconds of all shapes with virtual edges, with and without the
    collision pass (penetration not measured), beside the baseline of the same run, reading
    the template's keys and the target's positions from Blender; the penetration report's
    seconds (the template's own per-shape numbers measured once beforehand, as batch does, and
    timed apart); the shapes worse than the template before and after the collision pass;
    and a personalisation with 8 single-shape training expressions."""
    read = float("inf")
    for _ in range(runs):
        started = time.perf_counter()
        rig = mesh_arrays.read_rig(template)
        neutral = rest_positions(target)
        read = min(read, time.perf_counter() - started)

    def best(settings, **arguments):
        chosen = None
        for _ in range(runs):
            started = time.perf_counter()
            _, report = nat.transfer_shapes(rig.neutral, rig.deltas, neutral, rig.triangles, rig.names, settings, **arguments)
            wall = time.perf_counter() - started
            if chosen is None or wall < chosen["wall"]:
                chosen = {"wall": wall, "native": report["seconds"], "virtual_edges": report["virtual_edges"]}
        return chosen

    started = time.perf_counter()
    template_penetration = nat.measure_penetration(rig.neutral, rig.deltas, rig.triangles)
    template_seconds = time.perf_counter() - started
    without = best({"measure_penetration": False, "transfer": {"contact": None}})
    with_pass = best({"measure_penetration": False})
    reported = best(None, template_penetration=template_penetration)
    _, report = nat.transfer_shapes(
        rig.neutral, rig.deltas, neutral, rig.triangles, rig.names, {"compare_plain": True},
        template_penetration=template_penetration,
    )
    report["diagonal"] = float(np.linalg.norm(neutral.max(0) - neutral.min(0)))
    chosen = np.arange(0, len(rig.names), max(1, len(rig.names) // 8))[:8]
    weights = np.zeros((len(chosen), len(rig.names)), dtype=np.float32)
    weights[np.arange(len(chosen)), chosen] = 1.0
    examples = np.stack([neutral + 1.1 * rig.deltas[k] for k in chosen]).astype(np.float32)
    started = time.perf_counter()
    _, personalised = nat.transfer_shapes(
        rig.neutral, rig.deltas, neutral, rig.triangles, rig.names,
        {"measure_penetration": False}, examples=examples, example_weights=weights.tolist(),
    )
    return {
        "vertices": len(rig.neutral),
        "triangles": len(rig.triangles),
        "shapes": len(rig.names),
        "read": read,
        "transfer_without_collision_pass": without,
        "transfer": with_pass,
        "with_report": reported,
        "template_penetration_seconds": template_seconds,
        "penetration": added_summary(transfer_module, report),
        "cheap_metric_vs_full_sweep": cheap_metric_check(nat, rig, neutral, np.ascontiguousarray(rig.deltas)),
        "personalise_8_examples": {"wall": time.perf_counter() - started, "native": personalised["seconds"]},
    }


def save_arrays(rig, target_neutral, folder):
    """The template's neutral, deltas and triangles and the target's neutral as raw
    little-endian files (float32, uint32), what `native/examples/time_transfer.rs` reads."""
    os.makedirs(folder, exist_ok=True)
    np.ascontiguousarray(rig.neutral, dtype="<f4").tofile(os.path.join(folder, "source.f32"))
    np.ascontiguousarray(rig.deltas, dtype="<f4").tofile(os.path.join(folder, "deltas.f32"))
    np.ascontiguousarray(rig.triangles, dtype="<u4").tofile(os.path.join(folder, "triangles.u32"))
    np.ascontiguousarray(target_neutral, dtype="<f4").tofile(os.path.join(folder, "target.f32"))


def print_summary(indent, summary):
    print(
        indent + "; ".join(
            f"{label}: {len(v['worse'])} worse than the template, {v['added_curve']:.4f} m added" for label, v in summary.items()
        )
    )


def print_report(result):
    print(
        "\n== Penetration on the identities (curve added to each neutral beyond what the template's shape adds to its "
        "own, positive parts summed over the shapes)"
    )
    for name, row in result.get("penetration", {}).items():
        print(f"  {name}: {row['virtual_edges']} virtual edges")
        print_summary("    ", row["summary"])
        for shape, extra in row["worse_explained"].items():
            print(
                f"    {shape:22s} {extra['inside_one_piece']:+.4f} m inside one piece, "
                f"{extra['between_pieces']:+.4f} m between pieces beyond the template; grew most: "
                + "; ".join(f"{pair} (+{count})" for pair, count in extra["piece_pairs"])
            )
    print("\n== Virtual-edge weight with the collision pass (shapes worse than the template after the pass / added m)")
    for weight, row in result.get("edge_weight_sweep", {}).items():
        print(
            f"  w_ve {weight:>5s}: "
            + "; ".join(f"{name} {v['result']['worse']} / {v['result']['added_curve']:.4f}" for name, v in row.items())
        )
    print("\n== Timings (best of 3, seconds; ratios to reading the rig from Blender, and to the bundled head)")
    bundled = result["timings"].get("bundled")
    for name, row in result["timings"].items():
        t, plain, reported = row["transfer"], row["transfer_without_collision_pass"], row["with_report"]
        print(
            f"  {name}: {row['vertices']} vertices, {row['shapes']} shapes: virtual edges + collision pass "
            f"{t['wall']:.3f} s ({', '.join(f'{k} {v:.3f}' for k, v in t['native'].items() if v)}); "
            f"without the pass {plain['wall']:.3f} s; with the report {reported['wall']:.3f} s "
            f"(report {reported['native']['penetration']:.3f}; the template's own numbers, once per template, "
            f"{row['template_penetration_seconds']:.3f}); personalise (8 examples) {row['personalise_8_examples']['wall']:.3f} s"
        )
        print_summary("    ", row["penetration"])
        check = row["cheap_metric_vs_full_sweep"]
        print(
            f"    cheap metric vs full sweep on {check['shapes']} shapes: largest difference {check['length']:.2e} m, "
            f"{check['pairs']} pairs"
        )
        scale = (
            f"; x{t['wall'] / bundled['transfer']['wall']:.1f} the bundled head's time "
            f"for x{row['vertices'] / bundled['vertices']:.1f} its vertices" if bundled else ""
        )
        print(f"    reading {row['read']:.3f} s; transfer x{t['wall'] / row['read']:.1f} of reading{scale}")


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="bench_transfer.py --")
    parser.add_argument("--json", default=os.path.join(batch_cache(), "bench", "transfer.json"))
    parser.add_argument(
        "--timings-only", action="store_true",
        help="only the timings (no penetration study on the identities, no weight sweep)",
    )
    parser.add_argument(
        "--heads", nargs="+", choices=HEADS, default=list(HEADS),
        help="the heads to time (default: all)",
    )
    parser.add_argument(
        "--save-arrays", metavar="DIR",
        help="also write each timed head's arrays to DIR/<head>/ for the native timing example "
        "(cargo run --release --example time_transfer -- DIR/<head>)",
    )
    args = parser.parse_args(argv)
    shapesmith = batch.load_shapesmith()
    from importlib import import_module

    mesh_arrays = import_module(shapesmith.__name__ + ".blender.mesh_arrays")
    transfer_module = import_module(shapesmith.__name__ + ".blender.transfer")
    landmarks_module = import_module(shapesmith.__name__ + ".blender.landmarks")
    settings = import_module(shapesmith.__name__ + ".blender.settings")
    rest_positions = transfer_module.rest_positions
    nat = shapesmith.native.module()
    bpy.ops.wm.open_mainfile(filepath=batch.cached_sample())
    template = bpy.data.objects["Template"]
    rig = mesh_arrays.read_rig(template)
    targets = sorted((o for o in bpy.data.objects if o.name.startswith("Target_")), key=lambda o: o.name)
    result = {"timings": {}}
    if not args.timings_only:
        result["penetration"] = penetration_benchmark(transfer_module, landmarks_module, settings, rig, template, targets)
        result["edge_weight_sweep"] = edge_weight_sweep(transfer_module, settings, template, targets)
    for head in args.heads:
        if head == "bundled":
            pair = template, targets[0]
        elif head == "4x denser":
            pair = subdivided(template, "TemplateDense"), subdivided(targets[0], "TargetDense")
        else:
            face_template = subdivided(template, "TemplateDenseFace", FACE_EDGES)
            pair = face_template, subdivided(targets[0], "TargetDenseFace", FACE_EDGES, template=template)
        result["timings"][head] = timing_benchmark(nat, mesh_arrays, transfer_module, *pair, rest_positions)
        if args.save_arrays:
            save_arrays(mesh_arrays.read_rig(pair[0]), rest_positions(pair[1]), os.path.join(args.save_arrays, head))
    print_report(result)
    batch.write_json(args.json, result)
    print(f"\nwrote {args.json}")


def batch_cache():
    return os.environ.get("SHAPESMITH_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "shapesmith"))


if __name__ == "__main__":
    main()
