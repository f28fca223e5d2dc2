"""Place Landmarks benchmark (method, sections 2 and 4), run with the bpy Python:

    python scripts/bench_landmarks.py [-- --input SAMPLE.blend] [--json OUT] [--picture OUT.png]

On the bundled Template (about 5k vertices) and its 4x denser version:
1. The cover alone: landmarks M per epsilon in {0.3, 0.5, 0.7}, visibility and solve
   seconds, rays per second, reconstruction error (measured) and predicted error.
2. Conditioned layouts (the single cover at eps 0.5, then landmarks added for reconstruction)
   at M = 18, 26, 34, and the predicted-error curve (`--curve`, a PNG).
3. The comparison the paper makes: a conventional 68-point layout (jaw line, brows, nose,
   eyelids, lip contours, placed by the geometric rule in `conventional_layout`) scored with
   the same noisy reconstruction. Target: at M <= 34, a mean error at least 10% below it.
4. Visibility speed: rays cast and rays/s traced exhaustively and with the savings (reuse
   across poses, pool vertices asked only their threshold; same layout asserted), on both
   rigs, on a ~25k-vertex head whose face is cut once more (bench_transfer's timing mesh),
   where visibility + cover + selection should take < 3 s, and on its many-piece version
   (`many_piece_head.py`: eyes, teeth, tongue and lashes grown through the skin, the lashes
   copied), where the layout should take < 2 s; wall and CPU seconds.
   `--speed-only` runs this section alone. `--stages RIG` runs only the call with the savings
   on one of those rigs (Template, Template_4x, Template_25k, Template_many_pieces) and prints
   its seconds per stage,
   wall and CPU: on a shared machine, run it with two builds alternately to compare them.
Needs the extension installed (scripts/install_extension.py) in this Blender's user directory.
"""

import argparse
from importlib import import_module
import os
import sys
import time

import bpy
import bmesh  # noqa: I001  (bmesh loads only after bpy)
import numpy as np

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(SCRIPTS)
sys.path.insert(0, SCRIPTS)
import batch  # noqa: E402  (the same extension loading as the pipelines)

EPSILONS = (0.3, 0.5, 0.7)
COUNTS = (18, 26, 34)
# The core of the conditioned layouts: the single cover at this epsilon.
DESIGN_EPSILON = 0.5


def dense_copy(obj):
    """The rig with every face split in four (edges cut once, grid fill): bmesh carries each
    shape key along as a layer, so every shape is subdivided the same way as the basis."""
    mesh = obj.data.copy()
    bm = bmesh.new()
    bm.from_mesh(mesh)
    bmesh.ops.subdivide_edges(bm, edges=bm.edges[:], cuts=1, use_grid_fill=True)
    bm.to_mesh(mesh)
    bm.free()
    dense = bpy.data.objects.new(obj.name + "_4x", mesh)
    bpy.context.scene.collection.objects.link(dense)
    return dense


def front_surface_vertex(points, normals, allowed, target_xz, reach=0.003, widen=True, facing=-0.2):
    """The vertex a camera straight in front (looking along +Y) sees at `target_xz`: among
    allowed vertices facing the camera (normal y below `facing`) within `reach` in the image
    plane (widening if none and `widen`, else None), the frontmost (smallest y)."""
    distance = np.hypot(points[:, 0] - target_xz[0], points[:, 2] - target_xz[1])
    usable = allowed & (normals[:, 1] < facing)
    for reach in (reach, 2 * reach, 4 * reach, np.inf) if widen else (reach,):
        near = np.flatnonzero(usable & (distance < reach))
        if len(near):
            return int(near[np.argmin(points[near, 1])])
    return None


def conventional_layout(obj, parts):
    """A 68-point layout as face trackers place it (iBUG 300-W order: 17 jaw, 10 brows, 9 nose,
    12 eyes, 20 lips), chosen by a geometric rule on the neutral, never by hand-typed indices:

    - Skin = the largest loose part. Eye centres c = the centroids of the two most cube-shaped
      other parts (the eyeballs), eye radius r = half their width.
    - Every point is the skin vertex a front camera sees at an image-plane point (x, z)
      (`front_surface_vertex`).
    - Eyes: 6 points on the eyelid opening, an ellipse around c with semi-axes (0.9 r, 0.35 r) at
      0, 60, ..., 300 degrees (corners, two upper, two lower lid points).
    - Brows: 5 points per side at x = c_x + r * (-1.2, -0.6, 0, 0.6, 1.2), z = c_z + 1.6 r
      with a 0.3 r arch.
    - Nose: the tip is the frontmost skin vertex; 4 bridge points on the midline from eye level
      to the tip; 5 points at the nostril base (x = (-1, -0.5, 0, 0.5, 1) x half the gap between
      the eyeballs' inner edges) at the subnasale, the most receded midline point just below the tip.
    - Lips: on the midline profile (sampled every mm) the subnasale is the most receded point
      within 15 mm below the tip; within the next 8 mm each: the upper lip is the most forward
      point, the stomion the most receded, the lower lip the most forward. Mouth
      half width w = 0.8 c_x (the mouth is about 80% of the interpupillary distance). Outer
      contour: corners and 5 upper points at x = (+-0.6, +-0.3, 0) w on the upper lip line
      plus 5 lower ones on the lower lip line; inner contour: corners at +-0.85 w and 3 upper,
      3 lower points at x = (-0.4, 0, 0.4) w just above and below the stomion.
    - Jaw line: the menton is the last midline profile point below the labiomental fold (the
      most receded point within 15 mm under the lower lip) before the surface faces more
      down than forward (the underside of the chin). 17 rays in the image plane from
      (0, c_z - r), sweeping from one side down to the other, each take the farthest vertex
      of the head's front half above the menton: the face outline seen from the front.
    Returns (indices, {group: indices})."""
    mesh = obj.data
    n = len(mesh.vertices)
    points = np.empty(n * 3, dtype=np.float64)
    mesh.shape_keys.reference_key.data.foreach_get("co", points)
    points = points.reshape(-1, 3)
    normals = np.empty(n * 3, dtype=np.float64)
    mesh.vertices.foreach_get("normal", normals)
    normals = normals.reshape(-1, 3)
    labels = parts["part_of_vertex"]
    part_ids, sizes = np.unique(labels, return_counts=True)
    skin = labels == part_ids[np.argmax(sizes)]
    others = [p for p in part_ids if p != part_ids[np.argmax(sizes)]]
    extents = {p: np.ptp(points[labels == p], axis=0) for p in others}
    eyeballs = sorted(others, key=lambda p: extents[p].max() / max(extents[p].min(), 1e-9))[:2]
    centres = sorted((points[labels == p].mean(axis=0) for p in eyeballs), key=lambda c: c[0])
    r = float(np.mean([extents[p][0] for p in eyeballs]) / 2)
    cx, cz = float(np.mean([abs(c[0]) for c in centres])), float(np.mean([c[2] for c in centres]))
    pick = lambda x, z, reach=0.003: front_surface_vertex(points, normals, skin, (x, z), reach)  # noqa: E731
    groups = {}
    groups["brows"] = [pick(side * (cx + r * t), cz + 1.6 * r + 0.3 * r * (1 - (t / 1.2) ** 2))
                       for side in (-1, 1) for t in ((1.2, 0.6, 0.0, -0.6, -1.2) if side < 0 else (-1.2, -0.6, 0.0, 0.6, 1.2))]

    tip = int(np.flatnonzero(skin & (normals[:, 1] < -0.2))[np.argmin(points[skin & (normals[:, 1] < -0.2), 1])])
    tip_z = float(points[tip, 2])
    profile_z = np.arange(tip_z, cz - 10 * r, -0.001)
    profile_y = np.array([points[pick(0.0, z, reach=0.0012), 1] for z in profile_z])
    below = lambda i, forward, span: i + int(np.argmin(profile_y[i:i + span] * (1 if forward else -1)))  # noqa: E731
    subnasale = below(2, False, 15)
    upper_lip = below(subnasale + 1, True, 8)
    stomion = below(upper_lip + 1, False, 8)
    lower_lip = below(stomion + 1, True, 8)
    z_sn, z_ul, z_st, z_ll = (float(profile_z[i]) for i in (subnasale, upper_lip, stomion, lower_lip))
    # Menton: below the labiomental fold (the most receded point within 15 mm under the lower
    # lip), the last midline point before the surface faces more down than forward.
    fold = below(lower_lip + 1, False, 15)
    turned = [normals[v, 2] < normals[v, 1] for v in (pick(0.0, z, reach=0.0012) for z in profile_z[fold:])]
    menton = fold + int(np.argmax(turned))
    z_menton = float(profile_z[menton - 1])
    # Jaw line: the outline of the front half above the menton, seen from the front.
    front = skin & (points[:, 1] < 0.5 * (points[skin, 1].min() + points[skin, 1].max())) & (points[:, 2] >= z_menton)
    origin = np.array([0.0, cz - r])
    rel = points[:, [0, 2]] - origin
    angle, radius = np.arctan2(-rel[:, 1], rel[:, 0]), np.hypot(rel[:, 0], rel[:, 1])
    jaw = []
    for phi in np.linspace(np.pi, 0.0, 17):
        window = np.flatnonzero(front & (np.abs(angle - phi) < np.pi / 32))
        jaw.append(int(window[np.argmax(radius[window])]))
    groups["jaw"] = jaw
    half_nose = 0.5 * (2 * cx - 2 * r)
    groups["nose"] = [pick(0.0, cz + (tip_z - cz) * t) for t in (0.0, 1 / 3, 2 / 3)] + [tip] + \
        [pick(half_nose * t, z_sn) for t in (-1.0, -0.5, 0.0, 0.5, 1.0)]

    groups["eyes"] = [pick(c[0] + 0.9 * r * np.cos(a), c[2] + 0.35 * r * np.sin(a))
                      for c in centres for a in np.radians((180, 120, 60, 0, 300, 240))]

    w = 0.8 * cx
    outer = [pick(-w, z_st)] + [pick(t * w, z_ul) for t in (-0.6, -0.3, 0.0, 0.3, 0.6)] + [pick(w, z_st)] + \
        [pick(t * w, z_ll) for t in (0.6, 0.3, 0.0, -0.3, -0.6)]
    gap = 0.2 * (z_ul - z_st)
    inner = [pick(-0.85 * w, z_st)] + [pick(t * w, z_st + gap) for t in (-0.4, 0.0, 0.4)] + [pick(0.85 * w, z_st)] + \
        [pick(t * w, z_st - gap) for t in (0.4, 0.0, -0.4)]
    groups["lips"] = outer + inner
    groups = {name: groups[name] for name in ("jaw", "brows", "nose", "eyes", "lips")}
    indices = [v for group in groups.values() for v in group]
    return indices, groups


def place(module, obj, epsilon, **params):
    """One layout with the settings `epsilon` and `params` (`LandmarkSettings` fields)."""
    from importlib import import_module

    settings = import_module(module.__name__.rsplit(".", 1)[0] + ".settings")
    document = module.place_landmarks(obj, settings.LandmarkSettings(epsilon=epsilon, **params))
    return {
        "epsilon": epsilon,
        "landmarks": len(document["landmarks"]),
        "added": sum(1 for lm in document["landmarks"] if lm["added"] is not None),
        "predicted_error": document["predicted_error"],
        "seconds_design": document["seconds"]["design"],
        "rays_cast": document["rays_cast"],
        "rays_reused": document["rays_reused"],
        "visibility_vertices": document["visibility_vertices"],
        "optimal": document["optimal"],
        "uncovered": document["uncovered"],
        "rounds": document["rounds"],
        "seconds_io": document["seconds"]["io"],
        "seconds_visibility": document["seconds"]["visibility"],
        "seconds_solve": document["seconds"]["solve"],
        "rays_per_second": document["rays_per_second"],
        "mean_error": document["reconstruction"]["mean"],
        "max_error": document["reconstruction"]["max"],
    }, document


def conventional_on(obj, template, conventional):
    """The conventional layout's vertices on `obj`: the same indices when `obj` keeps the
    template's vertices first (subdivision appends the new ones), checked by position."""
    rest = lambda o: np.array([v.co[:] for v in o.data.shape_keys.reference_key.data])  # noqa: E731
    if not np.allclose(rest(obj)[conventional], rest(template)[conventional], atol=1e-7):
        raise RuntimeError(f"{obj.name} does not keep the template's vertex order")
    return conventional


def score_conventional(landmarks, obj, vertices):
    obj.vertex_groups.new(name="Conventional68").add(vertices, 1.0, "REPLACE")
    return landmarks.score_group(obj, "Conventional68")


def cover_table(landmarks, obj, documents):
    rows = []
    for epsilon in EPSILONS:
        row, document = place(landmarks, obj, epsilon)
        rows.append(row)
        documents[(obj.name, "cover", epsilon)] = document
        print(f"{obj.name:<18}{len(obj.data.vertices):>9}{epsilon:>6.1f}{row['landmarks']:>5}"
              f"{'yes' if row['optimal'] else 'no':>5}{row['seconds_visibility']:>8.2f}{row['seconds_solve']:>9.2f}"
              f"{row['rays_per_second']:>10.3g}{row['mean_error']:>10.2e}{row['predicted_error']:>10.2e}")
    return rows


def design_table(landmarks, obj, documents):
    rows = []
    for count in COUNTS:
        row, document = place(landmarks, obj, DESIGN_EPSILON, max_per_shape=1, landmarks=count)
        row["requested"] = count
        rows.append(row)
        documents[(obj.name, "design", count)] = document
        print(f"{obj.name:<18}{count:>5}{row['landmarks']:>5}{row['landmarks'] - row['added']:>7}{row['added']:>7}"
              f"{row['seconds_visibility']:>8.2f}{row['seconds_solve']:>9.2f}{row['seconds_design']:>9.2f}"
              f"{row['mean_error']:>10.2e}{row['max_error']:>9.2e}{row['predicted_error']:>10.2e}")
    return rows


def speed_row(landmarks, obj, **params):
    """Visibility, solve and selection at M = 34 traced exhaustively (every measured vertex
    through every pose) and with the savings (reuse across poses, pool vertices asked only
    their threshold); the two layouts must be identical. Wall and CPU seconds of the whole
    call (the machine may be shared: CPU time says what the work cost)."""
    runs, clocks = {}, {}
    for reuse in (False, True):
        wall, cpu = time.perf_counter(), time.process_time()
        _, document = place(landmarks, obj, DESIGN_EPSILON, max_per_shape=1, landmarks=34, reuse_visibility=reuse, **params)
        runs[reuse], clocks[reuse] = document, (time.perf_counter() - wall, time.process_time() - cpu)
        document["clock"] = clocks[reuse]
    before, after = runs[False], runs[True]
    if [lm["vertex"] for lm in before["landmarks"]] != [lm["vertex"] for lm in after["landmarks"]] or \
            [lm["visibility"] for lm in before["landmarks"]] != [lm["visibility"] for lm in after["landmarks"]]:
        raise RuntimeError(f"{obj.name}: the reused visibility changed the layout")
    row = {"vertices": len(obj.data.vertices), "visibility_vertices": after["visibility_vertices"]}
    for name, document in (("before", before), ("after", after)):
        seconds = document["seconds"]
        row[name] = {
            "rays_cast": document["rays_cast"],
            "rays_reused": document["rays_reused"],
            "rays_per_second": document["rays_per_second"],
            "seconds_visibility": seconds["visibility"],
            "seconds_solve": seconds["solve"],
            "seconds_design": seconds["design"],
            "seconds_total": seconds["visibility"] + seconds["solve"] + seconds["design"],
            "seconds_call_wall": document["clock"][0],
            "seconds_call_cpu": document["clock"][1],
        }
    b, a = row["before"], row["after"]
    print(f"{obj.name:<18}{row['vertices']:>9}{row['visibility_vertices']:>9}{b['rays_cast']:>12}{a['rays_cast']:>12}"
          f"{a['rays_reused']:>12}{b['seconds_visibility']:>8.2f}{a['seconds_visibility']:>8.2f}"
          f"{b['rays_per_second']:>10.3g}{a['rays_per_second']:>10.3g}{b['seconds_total']:>8.2f}{a['seconds_total']:>8.2f}"
          f"{a['seconds_call_cpu']:>8.2f}")
    return row


def speed(results, landmarks, template, dense):
    import bench_transfer  # the 25k timing mesh
    import many_piece_head

    print("\n4. Visibility + cover + selection at M = 34, 64 rays: exhaustive (before) / with the savings (after)")
    print(f"{'rig':<18}{'vertices':>9}{'traced':>9}{'rays before':>12}{'rays after':>12}{'reused':>12}"
          f"{'vis s':>8}{'vis s':>8}{'rays/s':>10}{'rays/s':>10}{'total s':>8}{'total s':>8}{'cpu s':>8}")
    face = bench_transfer.subdivided(template, "Template_25k", bench_transfer.FACE_EDGES)
    many = many_piece_head.build(template, import_module(landmarks.__package__ + ".mesh_arrays"))
    results["speed"] = {obj.name: speed_row(landmarks, obj) for obj in (template, dense, face, many)}
    results["speed_cores"] = os.cpu_count()
    results["speed_load_average"] = os.getloadavg()


def stages(results, landmarks, rig):
    """One call with the savings on `rig`: the native stage seconds (wall), the call's wall and
    CPU seconds, rays cast and rays/s, and the load average."""
    wall, cpu = time.perf_counter(), time.process_time()
    _, document = place(landmarks, rig, DESIGN_EPSILON, max_per_shape=1, landmarks=34, reuse_visibility=True)
    row = {"seconds": document["seconds"], "call_wall": time.perf_counter() - wall, "call_cpu": time.process_time() - cpu,
           "rays_cast": document["rays_cast"], "rays_per_second": document["rays_per_second"], "load_average": os.getloadavg()}
    results["stages"] = {rig.name: row}
    seconds = row["seconds"]
    print(f"{rig.name}: visibility {seconds['visibility']:.2f} s, solve {seconds['solve']:.2f} s, design {seconds['design']:.2f} s, "
          f"call {row['call_wall']:.2f} s wall / {row['call_cpu']:.2f} s CPU, {row['rays_cast']} rays at "
          f"{row['rays_per_second']:.3g}/s, load {row['load_average'][0]:.1f}")


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="bench_landmarks.py --")
    cache = os.environ.get("SHAPESMITH_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "shapesmith"))
    parser.add_argument("--input", help="a sample.blend (default: the cached one, built when missing)")
    parser.add_argument("--json", default=os.path.join(cache, "bench", "landmarks.json"))
    parser.add_argument("--picture", default=os.path.join(ROOT, "docs", "landmarks_front.png"))
    parser.add_argument("--conventional-picture", default=os.path.join(ROOT, "docs", "landmarks_conventional68.png"))
    parser.add_argument("--design-picture", default=os.path.join(ROOT, "docs", "landmarks_conditioned34.png"))
    parser.add_argument("--curve", default=os.path.join(ROOT, "docs", "landmarks_curve.png"))
    parser.add_argument("--speed-only", action="store_true", help="only the visibility speed table (section 4)")
    parser.add_argument("--stages", choices=("Template", "Template_4x", "Template_25k", "Template_many_pieces"),
                        help="only the call with the savings on this rig, seconds per stage")
    args = parser.parse_args(argv)

    shapesmith = batch.load_shapesmith()

    landmarks = import_module(shapesmith.__name__ + ".blender.landmarks")
    picture = import_module(shapesmith.__name__ + ".blender.landmark_picture")
    curve = import_module(shapesmith.__name__ + ".blender.landmark_curve")
    batch.open_blend(args.input or batch.cached_sample())
    template = bpy.data.objects["Template"]
    started = time.perf_counter()
    dense = dense_copy(template)
    subdivide_seconds = time.perf_counter() - started
    parts = landmarks.mesh_parts(template)
    conventional, groups = conventional_layout(template, parts)

    results = {"rigs": {}, "subdivide_seconds": subdivide_seconds}
    documents = {}
    if args.stages:
        import bench_transfer  # the 25k timing mesh
        import many_piece_head

        rigs = {"Template": lambda: template, "Template_4x": lambda: dense,
                "Template_25k": lambda: bench_transfer.subdivided(template, "Template_25k", bench_transfer.FACE_EDGES),
                "Template_many_pieces": lambda: many_piece_head.build(template, import_module(landmarks.__package__ + ".mesh_arrays"))}
        stages(results, landmarks, rigs[args.stages]())
        batch.write_json(args.json, results)
        return
    if args.speed_only:
        speed(results, landmarks, template, dense)
        batch.write_json(args.json, results)
        return
    print("1. The cover alone (multi-cover, 2 rounds)")
    print(f"{'rig':<18}{'vertices':>9}{'eps':>6}{'M':>5}{'opt':>5}{'vis s':>8}{'solve s':>9}"
          f"{'rays/s':>10}{'mean err':>10}{'predicted':>10}")
    for obj in (template, dense):
        results["rigs"][obj.name] = {"vertices": len(obj.data.vertices), "runs": cover_table(landmarks, obj, documents)}

    print(f"\n2. Conditioned layouts: the single cover at eps {DESIGN_EPSILON}, then landmarks added for reconstruction")
    print(f"{'rig':<18}{'ask':>5}{'M':>5}{'cover':>7}{'added':>7}{'vis s':>8}{'solve s':>9}{'design s':>9}"
          f"{'mean err':>10}{'max err':>9}{'predicted':>10}")
    for obj in (template, dense):
        results["rigs"][obj.name]["conditioned"] = design_table(landmarks, obj, documents)

    print("\n3. Against the conventional 68-point layout (same noise, same poses)")
    comparison = {"groups": {k: len(v) for k, v in groups.items()}, "points": len(conventional)}
    scores = {}
    for obj in (template, dense):
        score = scores[obj.name] = score_conventional(landmarks, obj, conventional_on(obj, template, conventional))
        rig = results["rigs"][obj.name]
        rows = [dict(r, layout=f"cover eps {r['epsilon']:.1f}") for r in rig["runs"]] + \
            [dict(r, layout=f"conditioned M={r['requested']}") for r in rig["conditioned"]]
        best = min((r for r in rows if r["landmarks"] <= 34), key=lambda r: r["mean_error"])
        comparison[obj.name] = {
            "conventional": {"distinct_vertices": score["landmarks"], "mean_error": score["mean"],
                             "max_error": score["max"], "predicted_error": score["predicted"]},
            "layouts": [{"layout": r["layout"], "landmarks": r["landmarks"], "mean_error": r["mean_error"],
                         "ratio": r["mean_error"] / score["mean"]} for r in rows],
            "best_at_most_34": {"layout": best["layout"], "landmarks": best["landmarks"],
                                "mean_error": best["mean_error"], "ratio": best["mean_error"] / score["mean"]},
            "target_met": best["mean_error"] <= 0.9 * score["mean"],
        }
        print(f"{obj.name}: conventional {score['landmarks']} vertices, mean {score['mean']:.2e}, "
              f"max {score['max']:.2e}, predicted {score['predicted']:.2e}")
        for row in rows:
            print(f"  {row['layout']:<22}{row['landmarks']:>4} landmarks ({row['landmarks'] / score['landmarks']:.0%}), "
                  f"mean {row['mean_error']:.2e} ({row['mean_error'] / score['mean'] - 1:+.0%})")
        print(f"  best at M <= 34: {best['layout']} with {best['landmarks']}: "
              f"{best['mean_error'] / score['mean'] - 1:+.0%} against the conventional layout "
              f"(target -10%: {'met' if comparison[obj.name]['target_met'] else 'NOT met'})")
    results["comparison"] = comparison

    speed(results, landmarks, template, dense)

    # Pictures: the cover, the conventional layout, the conditioned layout at 34 and its curve.
    landmarks.build_layout(template, documents[(template.name, "cover", 0.5)], bpy.context.scene)
    os.makedirs(os.path.dirname(os.path.abspath(args.picture)), exist_ok=True)
    picture.render_landmarks(template, os.path.abspath(args.picture))
    picture.render_vertices(template, conventional, os.path.abspath(args.conventional_picture), colour=(0.1, 0.3, 0.9, 1.0))
    conditioned = documents[(template.name, "design", 34)]
    landmarks.build_layout(template, conditioned, bpy.context.scene)
    picture.render_landmarks(template, os.path.abspath(args.design_picture))
    conditioned["comparison"] = scores[template.name]
    curve.write_curve_png(conditioned, os.path.abspath(args.curve))
    results["curve"] = conditioned["curve"]
    batch.write_json(args.json, results)
    print(f"\nwrote {args.json}, {args.picture}, {args.conventional_picture}, {args.design_picture} and {args.curve}")


if __name__ == "__main__":
    main()
