"""Place Landmarks benchmark (SPEC sections 2 and 4), run with the bpy Python:

    python scripts/bench_landmarks.py [-- --input SAMPLE.blend] [--json OUT] [--picture OUT.png]

On the bundled Template (about 5k vertices) and its 4x denser version: landmarks M per
epsilon in {0.3, 0.5, 0.7}, visibility and solve seconds, rays per second, reconstruction
error. Then the comparison the paper makes: a conventional 68-point layout (jaw line, brows,
nose, eyelids, lip contours, placed by the geometric rule in `conventional_layout`) scored
with the same noisy reconstruction as the optimised layouts. Needs the extension installed
(scripts/install_extension.py) in this Blender's user directory.
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
ROOT = os.path.dirname(SCRIPTS)
sys.path.insert(0, SCRIPTS)
import batch  # noqa: E402  (the same extension loading as the pipelines)

EPSILONS = (0.3, 0.5, 0.7)


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


def place(landmarks, obj, epsilon):
    document = landmarks.place_landmarks(obj, epsilon=epsilon)
    return {
        "epsilon": epsilon,
        "landmarks": len(document["landmarks"]),
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


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="bench_landmarks.py --")
    cache = os.environ.get("SHAPESMITH_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "shapesmith"))
    parser.add_argument("--input", default=os.path.join(cache, "sample-%d.%d.blend" % bpy.app.version[:2]))
    parser.add_argument("--json", default=os.path.join(cache, "bench", "landmarks.json"))
    parser.add_argument("--picture", default=os.path.join(ROOT, "docs", "landmarks_front.png"))
    parser.add_argument("--conventional-picture", default=os.path.join(ROOT, "docs", "landmarks_conventional68.png"))
    args = parser.parse_args(argv)

    shapesmith = batch.load_shapesmith()
    from importlib import import_module

    landmarks = import_module(shapesmith.__name__ + ".blender.landmarks")
    picture = import_module(shapesmith.__name__ + ".blender.landmark_picture")
    if not os.path.isfile(args.input):
        batch.run_sample(argparse.Namespace(output=args.input))
    batch.open_blend(args.input)
    template = bpy.data.objects["Template"]
    started = time.perf_counter()
    dense = dense_copy(template)
    subdivide_seconds = time.perf_counter() - started

    results = {"rigs": {}, "subdivide_seconds": subdivide_seconds}
    print(f"{'rig':<14}{'vertices':>9}{'eps':>6}{'M':>5}{'opt':>5}{'vis s':>8}{'solve s':>9}"
          f"{'rays/s':>10}{'mean err':>10}{'max err':>9}")
    documents = {}
    for obj in (template, dense):
        rows = []
        for epsilon in EPSILONS:
            row, document = place(landmarks, obj, epsilon)
            rows.append(row)
            documents[(obj.name, epsilon)] = document
            print(f"{obj.name:<14}{len(obj.data.vertices):>9}{epsilon:>6.1f}{row['landmarks']:>5}"
                  f"{'yes' if row['optimal'] else 'no':>5}{row['seconds_visibility']:>8.2f}{row['seconds_solve']:>9.2f}"
                  f"{row['rays_per_second']:>10.3g}{row['mean_error']:>10.2e}{row['max_error']:>9.2e}")
        results["rigs"][obj.name] = {"vertices": len(obj.data.vertices), "runs": rows}

    # The paper's comparison: the conventional layout against the optimised ones, same noise.
    parts = landmarks.mesh_parts(template)
    conventional, groups = conventional_layout(template, parts)
    template.vertex_groups.new(name="Conventional68").add(conventional, 1.0, "REPLACE")
    score = landmarks.score_group(template, "Conventional68")
    comparison = {
        "conventional": {"points": len(conventional), "distinct_vertices": score["landmarks"],
                         "mean_error": score["mean"], "max_error": score["max"],
                         "groups": {k: len(v) for k, v in groups.items()}},
        "optimised": [{"epsilon": r["epsilon"], "landmarks": r["landmarks"], "mean_error": r["mean_error"],
                       "max_error": r["max_error"]} for r in results["rigs"][template.name]["runs"]],
    }
    results["comparison"] = comparison
    print(f"\nconventional 68-point layout: {score['landmarks']} distinct vertices, "
          f"mean {score['mean']:.2e}, max {score['max']:.2e} (noise {score['noise']:.1%} of the diagonal)")
    for row in comparison["optimised"]:
        ratio = row["landmarks"] / score["landmarks"]
        print(f"optimised eps {row['epsilon']:.1f}: {row['landmarks']} landmarks ({ratio:.0%} of the conventional count), "
              f"mean {row['mean_error']:.2e} ({row['mean_error'] / score['mean']:.2f}x), max {row['max_error']:.2e}")

    landmarks.build_layout(template, documents[(template.name, 0.5)], bpy.context.scene)
    os.makedirs(os.path.dirname(os.path.abspath(args.picture)), exist_ok=True)
    picture.render_landmarks(template, os.path.abspath(args.picture))
    picture.render_vertices(template, conventional, os.path.abspath(args.conventional_picture), colour=(0.1, 0.3, 0.9, 1.0))
    os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
    with open(args.json, "w") as f:
        json.dump(results, f, indent=2)
    print(f"\nwrote {args.json}, {args.picture} and {args.conventional_picture}")


if __name__ == "__main__":
    main()
