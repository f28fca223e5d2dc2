"""Solve Performance as plain functions: the operator and `scripts/batch.py solve` both call
them (method, section 6).

The landmarks are the empties Place Landmarks made (each records its vertex); the tracks
follow them by name, from a trajectories file (3D) or a Movie Clip's tracks (2D, through the
clip's tracking camera and a scene camera placed for the shot). `solve` reads everything and
returns a JSON-ready document without writing; `write_animation` then keys the shape keys
and the head's transform, one key per frame.
"""

import csv
import json
import math
import os

import numpy as np
from mathutils import Matrix

from .. import native
from .keyframes import key_channel, key_transforms
from .mesh_arrays import MeshDataError, read_rig
from .settings import PerformanceSettings

# Axis suffixes of a trajectory CSV's columns: `<landmark>_x` (or `.x`, ` x`, `:x`).
AXES = "xyz"
# TRC's Units row: metres per unit.
TRC_UNITS = {"mm": 0.001, "cm": 0.01, "m": 1.0, "dm": 0.1, "in": 0.0254}


class Tracks:
    """The tracked landmarks: `values` (T, L, 3) positions or (T, L, 2) pixels (NaN = lost),
    the scene frame of each row, and what did not match."""

    def __init__(self, names, vertices, values, frames, source, camera=None, unknown=(), untracked=(), fps=None):
        self.names, self.vertices, self.values, self.frames = names, vertices, values, frames
        self.source, self.camera, self.unknown, self.untracked, self.fps = source, camera, list(unknown), list(untracked), fps


def layout_landmarks(obj, collection=None):
    """(names, vertices) of the landmark empties in `collection` (default: the object's
    layout from Place Landmarks), sorted by name. Each empty records its vertex (custom
    property `vertex`, else its parent vertex)."""
    collection = collection or obj.shapesmith.landmarks.collection
    if collection is None:
        raise MeshDataError(f"'{obj.name}' has no landmark layout: run Place Landmarks, or choose a Landmarks collection")
    found = []
    for empty in collection.all_objects:
        if "vertex" in empty.keys():
            vertex = int(empty["vertex"])
        elif empty.parent == obj and empty.parent_type == "VERTEX":
            vertex = int(empty.parent_vertices[0])
        else:
            continue
        if not 0 <= vertex < len(obj.data.vertices):
            raise MeshDataError(f"landmark '{empty.name}' records vertex {vertex}, but '{obj.name}' has {len(obj.data.vertices)}")
        found.append((empty.name, vertex))
    if not found:
        raise MeshDataError(f"collection '{collection.name}' holds no landmark empties (made by Place Landmarks)")
    found.sort()
    return [name for name, _ in found], [vertex for _, vertex in found]


def _column_landmark(column, by_name):
    """(landmark index, axis) a trajectory column names, or None."""
    lowered = column.strip().lower()
    for separator in ("_", ".", " ", ":"):
        for axis, letter in enumerate(AXES):
            suffix = separator + letter
            if lowered.endswith(suffix) and lowered[: -len(suffix)] in by_name:
                return by_name[lowered[: -len(suffix)]], axis
    return None


def _number(cell):
    try:
        return float(cell)
    except (TypeError, ValueError):
        return math.nan


def read_trajectories(path, names, vertices, start_frame, scale=1.0):
    """3D trajectories from a CSV (a header row; one `<landmark>_x, _y, _z` column triple per
    landmark, case-insensitive; a `frame` or `time` column and any other column ignored and
    listed) or a TRC file (its marker names on row 4, its Units honoured). Values times
    `scale` are in the scene's units; empty or non-numeric cells are lost landmarks."""
    if not os.path.isfile(path):
        raise MeshDataError(f"trajectories file not found: {path}")
    with open(path, newline="") as handle:
        text = handle.read()
    by_name = {name.lower(): l for l, name in enumerate(names)}
    fps = None
    if path.lower().endswith(".trc"):
        columns, rows, unit, fps = _parse_trc(text, path)
        scale *= unit
    else:
        table = [row for row in csv.reader(text.splitlines()) if row]
        if len(table) < 2:
            raise MeshDataError(f"'{path}' has no data rows under its header")
        columns, rows = table[0], table[1:]
    values = np.full((len(rows), len(names), 3), np.nan)
    unknown, used = [], set()
    for c, column in enumerate(columns):
        match = _column_landmark(column, by_name)
        if match is None:
            if column.strip().lower() not in ("frame", "time", "frame#", "timecode", ""):
                unknown.append(column.strip())
            continue
        used.add(match[0])
        values[:, match[0], match[1]] = [_number(row[c]) * scale if c < len(row) else math.nan for row in rows]
    if not used:
        raise MeshDataError(
            f"no column of '{os.path.basename(path)}' names a landmark: expected '<landmark>_x', '_y', '_z' for "
            f"landmarks such as {', '.join(names[:3])}"
        )
    untracked = [names[l] for l in range(len(names)) if l not in used]
    frames = [start_frame + t for t in range(len(rows))]
    return Tracks(names, vertices, values, frames, os.path.abspath(path), unknown=unknown, untracked=untracked, fps=fps)


def _parse_trc(text, path):
    """Columns (`<marker>_x` ...), data rows, metres per unit and frame rate of a TRC file."""
    lines = text.splitlines()
    if len(lines) < 6:
        raise MeshDataError(f"'{path}' is too short for a TRC file (5 header rows, then data)")
    keys, values = lines[1].split("\t"), lines[2].split("\t")
    header = dict(zip((k.strip() for k in keys), (v.strip() for v in values)))
    unit = TRC_UNITS.get(header.get("Units", "m").lower())
    if unit is None:
        raise MeshDataError(f"'{path}': unknown TRC units '{header.get('Units')}' (mm, cm, m)")
    markers = lines[3].split("\t")
    columns = ["frame", "time"]
    for cell in markers[2:]:
        if cell.strip():
            columns += [f"{cell.strip()}_{axis}" for axis in AXES]
    rows = [line.split("\t") for line in lines[5:] if line.strip()]
    return columns, rows, unit, _number(header.get("DataRate")) or None


def clip_tracks(clip, names, vertices, camera_object):
    """2D tracks of a Movie Clip: the track named after each landmark, its markers in pixels
    (muted or missing markers are lost), through the clip's tracking camera and
    `camera_object`'s placement. Rows are the clip's frames; keys go on the scene frames the
    clip occupies."""
    if camera_object is None or camera_object.type != "CAMERA":
        raise MeshDataError(
            f"movie clip '{clip.name}' needs a scene camera placed for the shot: set the scene's camera "
            "(or choose one) where the footage was filmed from"
        )
    tracking = clip.tracking
    intrinsics = tracking.camera
    if intrinsics.distortion_model != "POLYNOMIAL":
        raise MeshDataError(
            f"movie clip '{clip.name}' uses the {intrinsics.distortion_model.title()} lens model: only the "
            "Polynomial model (k1, k2, k3) is supported"
        )
    width, height = clip.size
    if width == 0 or height == 0:
        raise MeshDataError(f"movie clip '{clip.name}' has no image size: is its footage missing?")
    by_name = {track.name.lower(): track for track in tracking.tracks}
    duration = clip.frame_duration
    values = np.full((duration, len(names), 2), np.nan)
    untracked = []
    for l, name in enumerate(names):
        track = by_name.get(name.lower())
        if track is None:
            untracked.append(name)
            continue
        for marker in track.markers:
            frame = marker.frame - 1
            # Blender clamps a marker's position to the image: one on the border has left the
            # frame, and its clamped place would pull the solve, so it is lost.
            inside = 0.0 < marker.co[0] < 1.0 and 0.0 < marker.co[1] < 1.0
            if 0 <= frame < duration and not marker.mute and inside:
                values[frame, l] = (marker.co[0] * width, marker.co[1] * height)
    if len(untracked) == len(names):
        raise MeshDataError(
            f"movie clip '{clip.name}' has no track named after a landmark (tracks: "
            f"{', '.join(t.name for t in tracking.tracks) or 'none'}; landmarks such as {', '.join(names[:3])})"
        )
    landmark_names = {name.lower() for name in names}
    unknown = [t.name for t in tracking.tracks if t.name.lower() not in landmark_names]
    focal = intrinsics.focal_length_pixels
    world_to_camera = camera_object.matrix_world.normalized().inverted()
    camera = {
        "focal": (focal, focal * intrinsics.pixel_aspect),
        "principal": tuple(intrinsics.principal_point_pixels),
        "distortion": (intrinsics.k1, intrinsics.k2, intrinsics.k3),
        "rotation": [list(row[:3]) for row in world_to_camera.to_3x3()],
        "translation": list(world_to_camera.translation),
    }
    frames = [clip.frame_start + t for t in range(duration)]
    return Tracks(names, vertices, values, frames, f"clip:{clip.name}", camera=camera, unknown=unknown,
                  untracked=untracked, fps=clip.fps or None)


def start_pose(obj):
    """The head's world placement as the solve's start: rotation (3 x 3), translation, scale
    (the mean of the object's three)."""
    location, rotation, scale = obj.matrix_world.decompose()
    return [list(row) for row in rotation.to_matrix()], list(location), float(sum(scale) / 3.0)


class SolveRequest:
    """Everything one solve needs, read from Blender on the main thread: the rig's arrays, the
    tracks and the settings. `run` then needs no Blender at all, so it may run on a worker
    thread (`performance_job.SolveJob`)."""

    def __init__(self, obj, tracks, settings=None):
        self.object_name = obj.name
        self.rig = read_rig(obj)
        self.tracks = tracks
        self.settings = settings or PerformanceSettings()
        self.rotation, self.translation, self.scale = start_pose(obj)

    def run(self, progress=None):
        """The native solve (GIL released); `progress(fraction)` returning False stops it
        (`CancelledError`)."""
        rig, tracks = self.rig, self.tracks
        return native.module().solve_performance(
            rig.neutral, rig.deltas, rig.triangles, rig.names, tracks.vertices, np.ascontiguousarray(tracks.values),
            self.settings.as_native(), camera=tracks.camera, start_rotation=self.rotation,
            start_translation=self.translation, start_scale=self.scale, progress=progress,
        )

    def document(self, solved):
        """The JSON-ready report of a finished solve."""
        rig, tracks = self.rig, self.tracks
        diagonal = float(np.linalg.norm(rig.neutral.max(axis=0) - rig.neutral.min(axis=0))) * self.scale
        residuals = solved["residuals"]
        units = "pixels" if tracks.camera else "scene units"
        return {
            "object": self.object_name,
            "source": tracks.source,
            "kind": "2d" if tracks.camera else "3d",
            "frames": tracks.frames,
            "fps": tracks.fps,
            "landmarks": tracks.names,
            "vertices": list(tracks.vertices),
            "shapes": rig.names,
            "weights": solved["weights"],
            "rotations": solved["rotations"],
            "quaternions": solved["quaternions"],
            "translations": solved["translations"],
            "scales": solved["scales"],
            "residuals": residuals,
            "residual_units": units,
            "residuals_of_diagonal": None if tracks.camera else [None if r is None else r / diagonal for r in residuals],
            "observed": solved["observed"],
            "kept_frames": [tracks.frames[t] for t in solved["kept"]],
            "rigid_landmarks": [tracks.names[l] for l in solved["rigid"]],
            "unseen_shapes": solved["unseen"],
            "inert_shapes": solved["inert"],
            "unknown_columns": tracks.unknown,
            "untracked_landmarks": tracks.untracked,
            "smoothing": self.settings.smoothing,
            "warnings": rig.warnings,
        }


def solve(obj, tracks, settings=None, progress=None):
    """Solves the pose and weights of every frame with `settings` (a
    `settings.PerformanceSettings`; None: the defaults), from the head's placement, blocking;
    returns the document (writes nothing)."""
    request = SolveRequest(obj, tracks, settings)
    return request.document(request.run(progress))


def pose_matrices(document):
    """The head's world matrix per frame (mathutils)."""
    matrices = []
    for rotation, translation, scale in zip(document["rotations"], document["translations"], document["scales"]):
        matrix = Matrix(rotation).to_4x4() @ Matrix.Diagonal((scale, scale, scale, 1.0))
        matrix.translation = translation
        matrices.append(matrix)
    return matrices


def write_animation(obj, document, target=None):
    """Keys every solved shape key's value and the pose on `target` (default the head): one
    linear key per frame. A target other than the head keeps its current offset from it, so an
    empty the head is parented to carries the head along."""
    keys = obj.data.shape_keys.key_blocks
    frames = document["frames"]
    weights = np.asarray(document["weights"], dtype=np.float64)
    for k, name in enumerate(document["shapes"]):
        key_channel(keys[name], "value", -1, frames, weights[:, k], group="Shapesmith Performance")
    target = target or obj
    offset = obj.matrix_world.inverted_safe() @ target.matrix_world
    key_transforms(target, frames, [matrix @ offset for matrix in pose_matrices(document)])


def write_json(path, document):
    with open(path, "w") as handle:
        json.dump(document, handle, indent=2)


def summary_lines(document):
    solved = [r for r in document["residuals"] if r is not None]
    unit = document["residual_units"]
    lines = [
        f"{len(document['frames'])} frames from {document['source']} ({document['kind'].upper()}), "
        f"{len(document['landmarks'])} landmarks ({len(document['rigid_landmarks'])} rigid), {len(document['shapes'])} shapes",
        f"residual per frame (RMS, {unit}): mean {np.mean(solved):.3g}, max {np.max(solved):.3g}",
    ]
    if document["kept_frames"]:
        lines.append(f"frames with no landmark tracked (kept from a neighbour): {document['kept_frames']}")
    for what, key in (("unknown columns or tracks (ignored)", "unknown_columns"), ("landmarks without data", "untracked_landmarks"),
                      ("shapes no landmark moves (held at 0)", "unseen_shapes")):
        if document[key]:
            lines.append(f"{what}: {', '.join(document[key])}")
    return lines + [f"warning: {w}" for w in document["warnings"]]
