"""A known performance on a rig, shared by `bench_performance.py`, `render_performance_loop.py`
and `blender_tests/test_performance.py`, so that the benchmark's numbers, the README's picture
and the tests' bounds all come from one set-up:

- random smooth weights in [0, 1] (clamped sines: each shape rests at 0 part of the take) and
  a rigid head motion (up to ~8 degrees, ~2 cm) per frame;
- the landmarks' positions with Gaussian noise of NOISE (0.1%) of the head's diagonal, as 3D
  trajectories, or as pixels through a distorting camera DISTANCE in front of the head (the
  same noise seen from there);
- two layouts of (about) 68 landmarks: Place Landmarks' cover with landmarks added for
  reconstruction, and the conventional 68-point layout of `bench_landmarks.py`.
"""

import importlib
import math
import time

import numpy as np
from mathutils import Euler

NOISE = 0.001
FOCAL = 1800.0
DISTANCE = 0.6
DISTORTION = (-0.08, 0.02, 0.0)
LAYOUT_SIZE = 68


def truth(k, frames, seed=0):
    """(weights (T, K), rotations (T, 3, 3), translations (T, 3)) of the known performance."""
    rng = np.random.default_rng(seed)
    t = np.arange(frames)[:, None]
    weights = np.clip(0.2 + 0.7 * np.sin(rng.uniform(0, 2 * np.pi, k) + rng.uniform(0.03, 0.12, k) * t), 0.0, 1.0)
    rotations = np.array([
        np.array(Euler((0.14 * math.sin(0.05 * f), 0.08 * math.sin(0.07 * f + 1), 0.1 * math.cos(0.04 * f)), "XYZ").to_matrix())
        for f in range(frames)
    ])
    translations = np.array([(0.02 * math.sin(0.03 * f), 0.01 * math.cos(0.05 * f), 0.015 * math.sin(0.02 * f))
                             for f in range(frames)])
    return weights, rotations, translations


def world(rig, vertices, weights, rotations, translations):
    """(T, L, 3) world positions of the landmark vertices under the weights and poses."""
    local = rig.neutral[vertices][None].astype(np.float64) + np.einsum("tk,kln->tln", weights, rig.deltas[:, vertices])
    return np.einsum("trc,tlc->tlr", rotations, local) + translations[:, None, :]


def diagonal(rig):
    return float(np.linalg.norm(rig.neutral.max(0) - rig.neutral.min(0)))


def camera_for(rig):
    """The native camera dict of a camera DISTANCE in front of the head (along -Y, looking +Y),
    world to camera, 1920 x 1080 pixels."""
    centre = rig.neutral.mean(axis=0)
    rotation = np.array([[1.0, 0, 0], [0, 0, 1.0], [0, -1.0, 0]])
    position = centre + np.array([0.0, -DISTANCE, 0.0])
    return {"focal": (FOCAL, FOCAL), "principal": (960.0, 540.0), "distortion": DISTORTION,
            "rotation": rotation.tolist(), "translation": (-rotation @ position).tolist()}


def project(camera, points):
    """Pixels (from the bottom-left corner) of world points: pinhole, then the Polynomial lens."""
    rotation, translation = np.array(camera["rotation"]), np.array(camera["translation"])
    p = points @ rotation.T + translation
    x, y = p[..., 0] / -p[..., 2], p[..., 1] / -p[..., 2]
    r2 = x * x + y * y
    k1, k2, k3 = camera["distortion"]
    factor = 1 + r2 * (k1 + r2 * (k2 + r2 * k3))
    return np.stack([FOCAL * x * factor + camera["principal"][0], FOCAL * y * factor + camera["principal"][1]], axis=-1)


def tracks(rig, vertices, frames, kind, seed=0):
    """(true weights, noisy tracks, camera or None) of the known performance at `vertices`:
    3D positions with noise NOISE x diagonal, or 2D pixels with that noise seen from DISTANCE."""
    weights, rotations, translations = truth(len(rig.names), frames, seed)
    points = world(rig, vertices, weights, rotations, translations)
    rng = np.random.default_rng(seed + 1)
    sigma = NOISE * diagonal(rig)
    if kind == "3d":
        return weights, points + rng.normal(0, sigma, points.shape), None
    camera = camera_for(rig)
    pixels = project(camera, points) + rng.normal(0, sigma * FOCAL / DISTANCE, points.shape[:2] + (2,))
    return weights, pixels, camera


def solve(native, rig, vertices, frames, kind, smoothing=1.0, seed=0):
    """(seconds, weight RMS error, weight max error, the native result) of one known-answer
    solve of `frames` frames."""
    weights, values, camera = tracks(rig, vertices, frames, kind, seed)
    started = time.perf_counter()
    solved = native.solve_performance(rig.neutral, rig.deltas, rig.triangles, rig.names, list(vertices),
                                      np.ascontiguousarray(values), {"smoothing": smoothing}, camera=camera)
    seconds = time.perf_counter() - started
    error = np.asarray(solved["weights"]) - weights
    return seconds, float(np.sqrt(np.mean(error ** 2))), float(np.abs(error).max()), solved


def designed_layout(landmarks_module, obj, count=LAYOUT_SIZE):
    """The vertices of Place Landmarks' cover (one landmark a shape) with landmarks added for
    reconstruction up to `count`."""
    settings = importlib.import_module(landmarks_module.__name__.rsplit(".", 1)[0] + ".settings")
    document = landmarks_module.place_landmarks(obj, settings.LandmarkSettings(epsilon=0.5, max_per_shape=1, landmarks=count))
    return [lm["vertex"] for lm in document["landmarks"]]


def conventional_layout(landmarks_module, obj):
    """The conventional 68-point layout's distinct vertices (`bench_landmarks.py`; two of its
    points land on one vertex of the bundled head, so 66)."""
    import bench_landmarks

    vertices, _ = bench_landmarks.conventional_layout(obj, landmarks_module.mesh_parts(obj))
    return sorted(set(vertices))
