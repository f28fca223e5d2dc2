"""Solve Performance and Import Capture on the bundled Template: a known performance (random
smooth weights, a rigid head motion) sampled at the landmarks as 3D trajectories and as 2D
tracks in a Movie Clip, solved back; ARKit captures written from known weights, imported."""

import csv
import importlib
import json
import math
import os

import bpy
import numpy as np
import pytest
from mathutils import Euler, Matrix

from conftest import run_batch

FRAMES = 100
# Tracker noise per coordinate, a fraction of the head's diagonal.
NOISE = 0.001


def module(shapesmith, name):
    return importlib.import_module(f"{shapesmith.__name__}.blender.{name}")


def truth(rig, frames=FRAMES, seed=0):
    """Random smooth weights in [0, 1] (clamped sines: each shape rests at 0 part of the take)
    and a rigid head motion (up to ~8 degrees, ~2 cm) per frame."""
    rng = np.random.default_rng(seed)
    k = len(rig.names)
    t = np.arange(frames)[:, None]
    phase, speed = rng.uniform(0, 2 * np.pi, k), rng.uniform(0.03, 0.12, k)
    weights = np.clip(0.2 + 0.7 * np.sin(phase + speed * t), 0.0, 1.0)
    matrices = []
    for f in range(frames):
        rotation = Euler((0.14 * math.sin(0.05 * f), 0.08 * math.sin(0.07 * f + 1), 0.1 * math.cos(0.04 * f)), "XYZ")
        matrix = rotation.to_matrix().to_4x4()
        matrix.translation = (0.02 * math.sin(0.03 * f), 0.01 * math.cos(0.05 * f), 0.015 * math.sin(0.02 * f))
        matrices.append(matrix)
    return weights, matrices


def landmark_world(rig, vertices, weights, matrices):
    """(T, L, 3) world positions of the landmark vertices."""
    local = rig.neutral[vertices][None] + np.einsum("tk,kln->tln", weights, rig.deltas[:, vertices])
    out = np.empty_like(local, dtype=np.float64)
    for f, matrix in enumerate(matrices):
        m = np.array(matrix)
        out[f] = local[f] @ m[:3, :3].T + m[:3, 3]
    return out


def make_layout(obj, vertices, name="Landmarks"):
    """Landmark empties (as Place Landmarks records them) for the given vertices."""
    collection = bpy.data.collections.new(name)
    bpy.context.scene.collection.children.link(collection)
    for vertex in vertices:
        empty = bpy.data.objects.new(f"LM_{vertex}", None)
        empty["vertex"] = int(vertex)
        collection.objects.link(empty)
    return collection


def write_csv(path, names, positions, extra=True):
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        header = ["frame"] + [f"{n}_{a}" for n in names for a in "xyz"] + (["Unknown_x"] if extra else [])
        writer.writerow(header)
        for f, row in enumerate(positions):
            cells = ["" if not np.isfinite(v) else repr(float(v)) for v in row.ravel()]
            writer.writerow([f] + cells + (["1.0"] if extra else []))


def weight_error(document, weights):
    solved = np.asarray(document["weights"])
    return float(np.sqrt(np.mean((solved - weights) ** 2))), float(np.abs(solved - weights).max())


@pytest.fixture
def head(sample, shapesmith):
    obj = bpy.data.objects["Template"]
    rig = module(shapesmith, "mesh_arrays").read_rig(obj)
    return obj, rig


def rigid_vertices(rig, count=6):
    """Vertices no shape moves, spread over the mesh: the stabilising markers a capture puts
    on the forehead and temples besides the face's landmarks (they fix the first pose)."""
    motion = np.linalg.norm(rig.deltas, axis=2).max(axis=0)
    return [int(v) for v in np.flatnonzero(motion < 1e-7)[::97][:count]]


def reconstruction_layout(shapesmith, obj, rig, count=60):
    """Place Landmarks' layout with Add for Reconstruction up to `count` landmarks (every shape
    gets a landmark that moves strongly in it, then the ones that best separate the shapes),
    plus the rigid markers, as one collection. A layout of merely the most moving vertices
    (all around the mouth) leaves the brows, eyes, cheeks and nose unseen: their weights
    cannot come back from any solve."""
    landmarks = module(shapesmith, "landmarks")
    settings = module(shapesmith, "settings").LandmarkSettings(epsilon=0.5, max_per_shape=2, landmarks=count)
    document = landmarks.place_landmarks(obj, settings)
    assert document["uncovered"] == [] and document["inert"] == []
    collection = landmarks.build_layout(obj, document, bpy.context.scene)
    for vertex in rigid_vertices(rig):
        empty = bpy.data.objects.new(f"LM_rigid_{vertex}", None)
        empty["vertex"] = vertex
        collection.objects.link(empty)
    return collection


def vertex_error(rig, document, weights):
    """RMS over frames and vertices of the distance between the face the solved weights
    make and the true one, as a fraction of the diagonal: what the weights are for. Shapes
    that move the landmarks by less than the noise have weights no solve can pin down, but
    then they move the face little too."""
    error = np.asarray(document["weights"]) - weights
    moved = np.einsum("tk,knc->tnc", error, rig.deltas.astype(np.float64))
    diagonal = float(np.linalg.norm(rig.neutral.max(0) - rig.neutral.min(0)))
    return float(np.sqrt((moved ** 2).sum(axis=2).mean())) / diagonal


def test_3d_trajectories_give_back_the_weights_and_pose_with_lost_landmarks_and_an_empty_frame(head, shapesmith, tmp_path):
    performance = module(shapesmith, "performance")
    obj, rig = head
    collection = reconstruction_layout(shapesmith, obj, rig)
    names, ordered = performance.layout_landmarks(obj, collection)
    weights, matrices = truth(rig)
    exact = landmark_world(rig, ordered, weights, matrices)
    diagonal = float(np.linalg.norm(rig.neutral.max(0) - rig.neutral.min(0)))
    rng = np.random.default_rng(3)
    lost = rng.random(exact.shape[:2]) < 0.1
    lost[40] = True  # every landmark lost on one frame
    start = bpy.context.scene.frame_start

    def solve(positions, name):
        positions = positions.copy()
        positions[lost] = np.nan
        path = str(tmp_path / name)
        write_csv(path, names, positions)
        tracks = performance.read_trajectories(path, names, ordered, start)
        assert tracks.unknown == ["Unknown_x"] and not tracks.untracked
        document = performance.solve(obj, tracks, module(shapesmith, "settings").PerformanceSettings(smoothing=1.0))
        assert document["unseen_shapes"] == [] and document["kept_frames"] == [start + 40]
        assert document["weights"][40] == document["weights"][39]
        assert document["observed"][0] == int((~lost[0]).sum())
        # The kept frame repeats its neighbour's pose (the head turns up to 0.007 radians a frame).
        rotation_error = max(np.abs(np.array(r) - np.array(m.to_3x3())).max()
                             for t, (r, m) in enumerate(zip(document["rotations"], matrices)) if t != 40)
        residuals = [r for r in document["residuals_of_diagonal"] if r is not None]
        return document, rotation_error, float(np.median(residuals))

    # Noise-free: every frame's landmarks are explained exactly by the true weights and pose,
    # so what is left is the smoothing's lag (a weight change of 1 costs one noise unit), the
    # kept frame (weights move up to 0.08 a frame) and the frames where a shape's only
    # landmark is lost (its weight is then held near the previous frame's). Those stay within
    # a few hundredths (measured rms 0.007, 23 of 5200 weights off by more than 0.05), where
    # shapes unseen by the layout (rms 0.34) or a failing optimiser (weights 0.1 to 0.9 off)
    # are far above.
    document, rotation_error, residual = solve(exact, "exact.csv")
    rms, worst = weight_error(document, weights)
    off = float(np.mean(np.abs(np.asarray(document["weights"]) - weights) > 0.05))
    print(f"3D noise-free weight error: rms {rms:.4f}, max {worst:.3f}, share off by > 0.05: {off:.4f}; "
          f"rotation {rotation_error:.2e}, median residual {residual:.2e} of the diagonal")
    assert rms < 0.03 and off < 0.01, (rms, worst, off)
    assert rotation_error < 1e-3 and residual < 0.1 * NOISE, (rotation_error, residual)
    # With noise of 0.1% of the diagonal, shapes that move the landmarks by about the noise
    # (the eyes' looks, the dimples) have weights no solve can pin down: the unconstrained
    # least-squares spread of this layout's weights is 0.17 rms at the true pose (the solve's
    # residual, below the noise, is lower than the truth's). What comes back is the face: the
    # solved weights make it within about the noise (measured 0.09% of the diagonal), where
    # zero weights are 1.7% off and a layout of the most moving vertices alone (23 shapes
    # unseen) 0.6%.
    noisy = exact + rng.normal(0, NOISE * diagonal, exact.shape)
    document, rotation_error, residual = solve(noisy, "noisy.csv")
    rms, worst = weight_error(document, weights)
    face = vertex_error(rig, document, weights)
    zero = vertex_error(rig, {"weights": np.zeros_like(weights)}, weights)
    print(f"3D noisy weight error: rms {rms:.4f}, max {worst:.3f}; face error {face:.2e} of the diagonal "
          f"(zero weights: {zero:.2e}); rotation {rotation_error:.2e}, median residual {residual:.2e}")
    assert face < 1.5 * NOISE, (face, rms, worst)
    assert rotation_error < 0.01
    # The residual of a solve that explains the landmarks: about sqrt(3) noise units per landmark.
    assert residual < 3 * NOISE
    # Keyed: one key per frame on each shape key and on the head's transform.
    performance.write_animation(obj, document)
    scene = bpy.context.scene
    key = obj.data.shape_keys.key_blocks[document["shapes"][5]]
    for f in (0, 17, 63):
        scene.frame_set(start + f)
        assert key.value == pytest.approx(document["weights"][f][5], abs=1e-6)
        assert np.allclose(np.array(obj.matrix_world)[:3, 3], document["translations"][f], atol=1e-5)


def test_2d_tracks_in_a_movie_clip_through_a_distorting_camera(head, shapesmith, tmp_path):
    performance = module(shapesmith, "performance")
    obj, rig = head
    frames = 40
    collection = reconstruction_layout(shapesmith, obj, rig)
    names, ordered = performance.layout_landmarks(obj, collection)
    weights, matrices = truth(rig, frames, seed=4)
    positions = landmark_world(rig, ordered, weights, matrices)
    # A short image sequence gives the clip its frames and size: large enough that every
    # landmark stays in frame (Blender clamps a marker to the image's border).
    width, height = 640, 480
    image = bpy.data.images.new("frame", width, height)
    for f in range(frames):
        image.filepath_raw = str(tmp_path / f"frame_{f + 1:04d}.png")
        image.file_format = "PNG"
        image.save()
    clip = bpy.data.movieclips.load(str(tmp_path / "frame_0001.png"))
    assert clip.frame_duration == frames and tuple(clip.size) == (width, height)
    intrinsics = clip.tracking.camera
    intrinsics.distortion_model = "POLYNOMIAL"
    intrinsics.focal_length_pixels = 700.0
    intrinsics.k1, intrinsics.k2, intrinsics.k3 = -0.08, 0.02, 0.0
    centre = rig.neutral.mean(axis=0)
    camera = bpy.data.objects.new("ShotCamera", bpy.data.cameras.new("ShotCamera"))
    bpy.context.scene.collection.objects.link(camera)
    camera.location = (centre[0], centre[1] - 0.6, centre[2])
    camera.rotation_euler = (math.pi / 2, 0.0, 0.0)
    bpy.context.view_layer.update()
    to_camera = np.array(camera.matrix_world.inverted())
    principal = np.array(intrinsics.principal_point_pixels)
    diagonal = float(np.linalg.norm(rig.neutral.max(0) - rig.neutral.min(0)))
    noise_px = NOISE * diagonal * 700.0 / 0.6
    # The true pixels: the pinhole and the Polynomial lens of Blender's tracking camera.
    seen = np.einsum("rc,tlc->tlr", to_camera[:3, :3], positions) + to_camera[:3, 3]
    x, y = seen[..., 0] / -seen[..., 2], seen[..., 1] / -seen[..., 2]
    r2 = x * x + y * y
    factor = 1 - 0.08 * r2 + 0.02 * r2 * r2
    exact = np.stack([700.0 * x * factor + principal[0], 700.0 * y * factor + principal[1]], axis=2)
    noisy = exact + np.random.default_rng(5).normal(0, noise_px, exact.shape)
    assert (noisy > 0).all() and (noisy[..., 0] < width).all() and (noisy[..., 1] < height).all()
    for l, name in enumerate(names):
        track = clip.tracking.tracks.new(name=name, frame=1)
        for f in range(frames):
            track.markers.insert_frame(f + 1, co=(noisy[f, l, 0] / width, noisy[f, l, 1] / height))
    # A clip without a camera is a clear error.
    with pytest.raises(ValueError, match="scene camera"):
        performance.clip_tracks(clip, names, ordered, None)
    # A marker that left the frame: Blender clamps it to the border, where it is no position.
    outside = clip.tracking.tracks[names[0]].markers.insert_frame(frames + 1, co=(1.3, 0.5))
    assert tuple(outside.co) == (1.0, 0.5)
    clip.tracking.tracks[names[1]].markers.find_frame(3).co = (-0.2, 0.5)
    tracks = performance.clip_tracks(clip, names, ordered, camera)
    assert tracks.values.shape == (frames, len(names), 2)
    lost = ~np.isfinite(tracks.values).all(axis=2)
    assert np.argwhere(lost).tolist() == [[2, 1]]
    # The markers store float32 fractions of the image: a thousandth of a pixel.
    assert np.abs(tracks.values - noisy)[~lost].max() < 1e-3
    tracks.values[2, 1] = noisy[2, 1]
    # With the clip's noise (0.44 pixels, the 3D test's 0.1% of the diagonal seen from 0.6 m),
    # one camera sees even less of what the eyes' looks and the dimples do than 3D markers
    # (and nothing of the depth): what comes back is the face, within twice the noise
    # (measured 0.11% of the diagonal; zero weights are 1.7% off, a third of the shapes
    # unseen 0.6%).
    document = performance.solve(obj, tracks, module(shapesmith, "settings").PerformanceSettings(smoothing=1.0))
    rms, worst = weight_error(document, weights)
    face = vertex_error(rig, document, weights)
    residual = float(np.median([r for r in document["residuals"] if r is not None]))
    print(f"2D noisy weight error: rms {rms:.4f}, max {worst:.3f}; face error {face:.2e} of the diagonal; "
          f"median residual {residual:.3f} px")
    assert face < 2 * NOISE, (face, rms, worst)
    assert residual < 3 * noise_px
    # The same tracks without noise: the weights themselves come back (only the smoothing's
    # lag is left: a weight change of 1 costs one noise unit, 1 pixel; measured rms 0.02,
    # where the noisy solve is 0.09 and unseen shapes 0.34).
    tracks.values = exact
    document = performance.solve(obj, tracks, module(shapesmith, "settings").PerformanceSettings(smoothing=1.0))
    rms, worst = weight_error(document, weights)
    print(f"2D noise-free weight error: rms {rms:.4f}, max {worst:.3f}")
    assert rms < 0.03, (rms, worst)


def test_a_clip_without_matching_tracks_is_a_clear_error(head, shapesmith, tmp_path):
    performance = module(shapesmith, "performance")
    obj, rig = head
    collection = make_layout(obj, rigid_vertices(rig, 5))
    names, ordered = performance.layout_landmarks(obj, collection)
    image = bpy.data.images.new("still", 64, 64)
    image.filepath_raw = str(tmp_path / "still.png")
    image.file_format = "PNG"
    image.save()
    clip = bpy.data.movieclips.load(str(tmp_path / "still.png"))
    clip.tracking.tracks.new(name="SomethingElse", frame=1)
    camera = bpy.data.objects.new("Cam", bpy.data.cameras.new("Cam"))
    with pytest.raises(ValueError, match="no track named after a landmark"):
        performance.clip_tracks(clip, names, ordered, camera)


def test_batch_solve_writes_keys_json_and_plot_and_leaves_the_input(head, shapesmith, tmp_path):
    performance = module(shapesmith, "performance")
    obj, rig = head
    collection = reconstruction_layout(shapesmith, obj, rig)
    names, ordered = performance.layout_landmarks(obj, collection)
    blend = str(tmp_path / "with_layout.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    weights, matrices = truth(rig, 30, seed=7)
    path = str(tmp_path / "t.csv")
    write_csv(path, names, landmark_world(rig, ordered, weights, matrices))
    out, report, plot = (str(tmp_path / n) for n in ("out.blend", "r.json", "plot.png"))
    before = os.path.getmtime(blend)
    run_batch("solve", "--input", blend, "--object", "Template", "--trajectories", path, "--output", out,
              "--json", report, "--plot", plot, "--smoothing", "0.5", check=True)
    assert os.path.getmtime(blend) == before
    document = json.load(open(report))
    assert document["unknown_columns"] == ["Unknown_x"] and len(document["residuals"]) == 30
    # Noise-free, every landmark tracked: only the light smoothing's lag is left, on every
    # weight (measured max 0.004; a wrong frame, unit or unseen shape is off by tenths).
    rms, worst = weight_error(document, weights)
    print(f"batch weight error: rms {rms:.4f}, max {worst:.3f}")
    assert worst < 0.02, (rms, worst)
    assert os.path.getsize(plot) > 1000
    bad = run_batch("solve", "--input", blend, "--object", "Template", "--clip", "Nope", "--output", out)
    assert bad.returncode == 2 and bad.stderr.startswith("shapesmith: error:")


ARKIT = (
    "EyeBlinkLeft", "EyeLookDownLeft", "EyeLookInLeft", "EyeLookOutLeft", "EyeLookUpLeft", "EyeSquintLeft", "EyeWideLeft",
    "EyeBlinkRight", "EyeLookDownRight", "EyeLookInRight", "EyeLookOutRight", "EyeLookUpRight", "EyeSquintRight",
    "EyeWideRight", "JawForward", "JawRight", "JawLeft", "JawOpen", "MouthClose", "MouthFunnel", "MouthPucker", "MouthRight",
    "MouthLeft", "MouthSmileLeft", "MouthSmileRight", "MouthFrownLeft", "MouthFrownRight", "MouthDimpleLeft",
    "MouthDimpleRight", "MouthStretchLeft", "MouthStretchRight", "MouthRollLower", "MouthRollUpper", "MouthShrugLower",
    "MouthShrugUpper", "MouthPressLeft", "MouthPressRight", "MouthLowerDownLeft", "MouthLowerDownRight", "MouthUpperUpLeft",
    "MouthUpperUpRight", "BrowDownLeft", "BrowDownRight", "BrowInnerUp", "BrowOuterUpLeft", "BrowOuterUpRight", "CheekPuff",
    "CheekSquintLeft", "CheekSquintRight", "NoseSneerLeft", "NoseSneerRight", "TongueOut",
)


def test_an_arkit_csv_comes_back_as_the_same_keyframes(head, shapesmith, tmp_path):
    capture = module(shapesmith, "capture")
    obj, _ = head
    scene = bpy.context.scene
    fps = round(scene.render.fps / scene.render.fps_base)
    rng = np.random.default_rng(8)
    values = np.round(rng.random((50, len(ARKIT))), 6)
    path = str(tmp_path / "take.csv")
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["Timecode", "BlendShapeCount", *ARKIT, "FooBar", "HeadYaw", "HeadPitch", "HeadRoll",
                         "LeftEyeYaw", "LeftEyePitch", "LeftEyeRoll", "RightEyeYaw", "RightEyePitch", "RightEyeRoll"])
        for f, row in enumerate(values):
            code = f"00:00:{10 + f // fps:02d}:{f % fps:02d}.000"
            writer.writerow([code, 61, *row, 0.5, 0.1, -0.05, 0.02, 0, 0, 0, 0, 0, 0])
    report = capture.import_capture(obj, path, scene, fps=fps)
    assert report["unmatched_columns"] == ["FooBar"] and report["frames"] == 50
    assert report["head_rotation"] and report["first_frame"] == scene.frame_start
    keys = obj.data.shape_keys.key_blocks
    for column, targets in report["columns_used"].items():
        c = ARKIT.index(column)
        for target in targets:
            for f in (0, 13, 49):
                scene.frame_set(scene.frame_start + f)
                assert keys[target].value == pytest.approx(values[f, c], abs=1e-6), (column, target, f)
    assert len(report["columns_used"]) == len(ARKIT)


def test_names_match_case_and_side_spellings_and_split_halves(shapesmith):
    capture = module(shapesmith, "capture")
    keys = ["browInnerUp_L", "browInnerUp_R", "eyeBlink_L", "EyeBlinkRight", "jawOpen", "mouthLeft", "extra"]
    columns = ["BrowInnerUp", "EyeBlinkLeft", "eyeBlink_R", "JAWOPEN", "MouthLeft", "Mystery"]
    matched, unmatched, undriven = capture.match_columns(columns, keys, {"Mystery": "extra"})
    assert matched == {"BrowInnerUp": ["browInnerUp_L", "browInnerUp_R"], "EyeBlinkLeft": ["eyeBlink_L"],
                       "eyeBlink_R": ["EyeBlinkRight"], "JAWOPEN": ["jawOpen"], "MouthLeft": ["mouthLeft"],
                       "Mystery": ["extra"]}
    assert unmatched == [] and undriven == []


def test_a_face_cap_take_comes_back_and_batch_lists_what_it_used(head, shapesmith, tmp_path):
    obj, _ = head
    scene = bpy.context.scene
    fps = scene.render.fps / scene.render.fps_base
    names = ["eyeBlink_L", "eyeBlink_R", "jawOpen", "browInnerUp", "notAShape"]
    values = np.round(np.random.default_rng(2).random((20, len(names))), 5)
    path = str(tmp_path / "take.txt")
    with open(path, "w") as handle:
        handle.write("info,version,1\n")
        handle.write("bs," + ",".join(names) + "\n")
        for f, row in enumerate(values):
            ms = f * 1000.0 / fps
            handle.write(f"k,{ms:.6f},0,0,0,5,-3,1,0,0,0,0," + ",".join(repr(float(v)) for v in row) + "\n")
    blend = str(tmp_path / "in.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    out, report_path = str(tmp_path / "out.blend"), str(tmp_path / "capture.json")
    run_batch("import-capture", "--input", blend, "--object", "Template", "--capture", path, "--output", out,
              "--json", report_path, check=True)
    report = json.load(open(report_path))
    assert report["unmatched_columns"] == ["notAShape"]
    assert set(report["columns_used"]) == set(names[:4])
    assert "mouthClose" in report["unmatched_keys"]
    bpy.ops.wm.open_mainfile(filepath=out)
    template = bpy.data.objects["Template"]
    keys = template.data.shape_keys.key_blocks
    for f in (0, 7, 19):
        scene = bpy.context.scene
        scene.frame_set(scene.frame_start + f)
        assert keys["jawOpen"].value == pytest.approx(values[f, 2], abs=1e-6)
    rotation = Matrix(np.array(template.matrix_world)[:3, :3].tolist())
    assert rotation.to_euler().x == pytest.approx(math.radians(5), abs=1e-4)
