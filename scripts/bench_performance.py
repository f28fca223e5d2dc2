"""Solve Performance benchmark (never asserted): milliseconds per frame and the known-answer
weight errors on the bundled Template (and on its 25k-vertex subdivision for speed).

    python scripts/bench_performance.py -- [--json OUT.json] [--frames 100] [--plot OUT.png]

A known performance: random smooth weights (clamped sines) and a rigid head motion; the
landmarks' positions with Gaussian noise of 0.1% of the head's diagonal, as 3D trajectories
and as pixels through a distorting camera. Layouts: Place Landmarks' cover with landmarks
added for reconstruction up to 68, and the conventional 68-point layout of
`bench_landmarks.py`, at the same noise.
"""

import argparse
import json
import math
import os
import sys
import time

import bpy
import numpy as np
from mathutils import Euler

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
import batch  # noqa: E402

NOISE = 0.001
FOCAL = 1800.0
DISTANCE = 0.6
DISTORTION = (-0.08, 0.02, 0.0)
# The plot's shapes: one each of the jaw, the mouth corners, the lids and the brows.
PLOT_SHAPES = ["jawOpen", "mouthSmileLeft", "eyeBlinkLeft", "browInnerUp"]


def truth(k, frames, seed=0):
    rng = np.random.default_rng(seed)
    t = np.arange(frames)[:, None]
    weights = np.clip(0.2 + 0.7 * np.sin(rng.uniform(0, 2 * np.pi, k) + rng.uniform(0.03, 0.12, k) * t), 0.0, 1.0)
    poses = []
    for f in range(frames):
        rotation = np.array(Euler((0.14 * math.sin(0.05 * f), 0.08 * math.sin(0.07 * f + 1), 0.1 * math.cos(0.04 * f))).to_matrix())
        poses.append((rotation, np.array([0.02 * math.sin(0.03 * f), 0.01 * math.cos(0.05 * f), 0.015 * math.sin(0.02 * f)])))
    return weights, poses


def world(rig, vertices, weights, poses):
    local = rig.neutral[vertices][None] + np.einsum("tk,kln->tln", weights, rig.deltas[:, vertices])
    return np.stack([local[f] @ r.T + t for f, (r, t) in enumerate(poses)])


def camera_for(rig):
    """A camera DISTANCE in front of the head (along -Y, looking +Y), world to camera."""
    centre = rig.neutral.mean(axis=0)
    rotation = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])
    position = centre + np.array([0.0, -DISTANCE, 0.0])
    return {"focal": (FOCAL, FOCAL), "principal": (960.0, 540.0), "distortion": DISTORTION,
            "rotation": rotation.tolist(), "translation": (-rotation @ position).tolist()}


def project(camera, points):
    rotation, translation = np.array(camera["rotation"]), np.array(camera["translation"])
    p = points @ rotation.T + translation
    x, y = p[..., 0] / -p[..., 2], p[..., 1] / -p[..., 2]
    r2 = x * x + y * y
    k1, k2, k3 = camera["distortion"]
    factor = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    return np.stack([FOCAL * x * factor + camera["principal"][0], FOCAL * y * factor + camera["principal"][1]], axis=-1)


def run(native, rig, vertices, frames, kind, smoothing=1.0, seed=0):
    """(ms per frame, weight RMS error, weight max error, the native result) of one
    known-answer solve."""
    weights, poses = truth(len(rig.names), frames, seed)
    points = world(rig, vertices, weights, poses)
    diagonal = float(np.linalg.norm(rig.neutral.max(0) - rig.neutral.min(0)))
    rng = np.random.default_rng(seed + 1)
    camera = None
    if kind == "3d":
        tracks = points + rng.normal(0, NOISE * diagonal, points.shape)
    else:
        camera = camera_for(rig)
        tracks = project(camera, points) + rng.normal(0, NOISE * diagonal * FOCAL / DISTANCE, points.shape[:2] + (2,))
    started = time.perf_counter()
    solved = native.solve_performance(rig.neutral, rig.deltas, rig.triangles, rig.names, list(vertices),
                                      np.ascontiguousarray(tracks), {"smoothing": smoothing}, camera=camera)
    seconds = time.perf_counter() - started
    error = np.asarray(solved["weights"]) - weights
    return 1000 * seconds / frames, float(np.sqrt(np.mean(error ** 2))), float(np.abs(error).max()), solved


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="bench_performance.py --")
    cache = os.environ.get("SHAPESMITH_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "shapesmith"))
    parser.add_argument("--json", default=os.path.join(cache, "bench", "performance.json"))
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--plot", help="also write the Performance panel's plot of the 3D solve with the designed layout (PNG)")
    args = parser.parse_args(argv)

    shapesmith = batch.load_shapesmith()
    from importlib import import_module

    landmarks = import_module(shapesmith.__name__ + ".blender.landmarks")
    mesh_arrays = import_module(shapesmith.__name__ + ".blender.mesh_arrays")
    native = import_module(shapesmith.__name__ + ".native").module()
    import bench_landmarks

    batch.open_blend(batch.cached_sample())
    template = bpy.data.objects["Template"]
    rig = mesh_arrays.read_rig(template)
    conventional, _ = bench_landmarks.conventional_layout(template, landmarks.mesh_parts(template))
    conventional = sorted(set(conventional))
    settings = import_module(shapesmith.__name__ + ".blender.settings")
    document = landmarks.place_landmarks(template, settings.LandmarkSettings(epsilon=0.5, max_per_shape=1, landmarks=68))
    designed = [lm["vertex"] for lm in document["landmarks"]]
    results = {"frames": args.frames, "noise": NOISE, "layouts": {}, "speed": {}}
    run(native, rig, designed, 10, "3d")  # warm-up: the first call starts the thread pool
    print(f"Known answer, {args.frames} frames, noise {NOISE:.1%} of the diagonal, smoothing 1")
    print(f"{'layout':<28}{'L':>4}{'kind':>6}{'ms/frame':>10}{'w rms':>9}{'w max':>8}")
    for name, vertices in (("added for reconstruction", designed), ("conventional 68", conventional)):
        for kind in ("3d", "2d"):
            ms, rms, worst, solved = run(native, rig, vertices, args.frames, kind)
            if args.plot and kind == "3d" and name == "added for reconstruction":
                plot = import_module(shapesmith.__name__ + ".blender.performance_plot")
                document = {"frames": list(range(1, args.frames + 1)), "residuals": solved["residuals"],
                            "weights": solved["weights"], "shapes": rig.names, "kind": "3d"}
                plot.write_plot_png(document, args.plot, PLOT_SHAPES)
            results["layouts"].setdefault(name, {"landmarks": len(vertices)})[kind] = {"ms_per_frame": ms, "weight_rms": rms, "weight_max": worst}
            print(f"{name:<28}{len(vertices):>4}{kind:>6}{ms:>10.2f}{rms:>9.4f}{worst:>8.3f}")
    import bench_transfer

    dense = bench_transfer.subdivided(template, "Template_25k", bench_transfer.FACE_EDGES)
    dense_rig = mesh_arrays.read_rig(dense)
    for kind in ("3d", "2d"):
        ms, rms, worst, _ = run(native, dense_rig, designed, args.frames, kind)
        results["speed"][f"25k_{kind}"] = {"vertices": len(dense_rig.neutral), "ms_per_frame": ms, "weight_rms": rms}
        print(f"{'25k head, same vertices':<28}{len(designed):>4}{kind:>6}{ms:>10.2f}{rms:>9.4f}{worst:>8.3f}")
    os.makedirs(os.path.dirname(os.path.abspath(args.json)), exist_ok=True)
    with open(args.json, "w") as handle:
        json.dump(results, handle, indent=2)
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
