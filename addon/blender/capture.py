"""Import ARKit capture (method, section 6): per-frame ARKit weights from Live Link Face (CSV) or
Face Cap (TXT) keyed onto the rig's shape keys by name, and the head's rotation onto the
object. The operator and `scripts/batch.py import-capture` both call `import_capture`.

Formats:
- Live Link Face CSV: a header `Timecode,BlendShapeCount,EyeBlinkLeft,...,TongueOut,HeadYaw,
  HeadPitch,HeadRoll,LeftEyeYaw,...`, one row per captured frame, timecode
  `HH:MM:SS:FF.mmm` (FF the frame at the capture's rate, .mmm a fraction of a frame). The rate
  is not in the file: the largest FF + 1, rounded up to a standard rate, unless given.
- Face Cap TXT: `info,...` lines, one `bs,<name>,<name>,...` line naming the shapes, then one
  `k,<milliseconds>,<head x,y,z>,<head euler x,y,z in degrees>,<left eye x,y>,<right eye x,y>,
  <weights...>` line per captured frame.

Head angles (yaw, pitch, roll) turn the head about its own axes, found from the rig (the front
Pack Expressions uses: its stored front, else `front.rig_front`): left = up x front, up,
front. The rotation is R = R_front(roll) R_up(yaw) R_left(pitch) by the right-hand rule, so
positive pitch nods the face down, positive yaw turns it to its own left, positive roll tilts
it to its right shoulder (Apple's ARKit face coordinates: x to the face's left, y up, z out of
the face). Live Link Face stores radians (the Diffeomorphic DAZ importer's and the Maya Live
Link importer's reading); the signs of its yaw and pitch follow how the phone was held (the
Blender LiveLinkFace add-on notes them inverted in landscape), so each angle can be inverted.
Face Cap stores degrees, Euler x, y, z = pitch, yaw, roll.

Lost tracking: a row where the phone lost the face (only `timecode,0`, or fewer cells than the
header) is skipped and counted; the keys hold the last tracked values across the gap (the key
before it is constant) rather than slide towards the next tracked frame.

Timing: captured frame i is keyed at `start + (t_i - t_0) x scene fps` (t in seconds): one key
per captured frame, on whole frames when the capture's rate is the scene's, between frames
otherwise, so the performance keeps its speed. Values are keyed exactly as captured.
"""

import csv
import json
import math
import os

import numpy as np
from mathutils import Matrix

from .front import view_front
from .keyframes import key_channel, key_transforms
from .mesh_arrays import MeshDataError
from .names import shape_key

HEAD_ANGLES = ("YAW", "PITCH", "ROLL")

# Columns of a Live Link Face CSV that are not shapes, in any letter case (phones write
# `BlendShapeCount` and `BlendshapeCount` alike).
LIVE_LINK_HEAD = ("headyaw", "headpitch", "headroll")
LIVE_LINK_OTHER = ("timecode", "blendshapecount", "lefteyeyaw", "lefteyepitch", "lefteyeroll", "righteyeyaw",
                   "righteyepitch", "righteyeroll")
STANDARD_RATES = (24, 25, 30, 48, 50, 60, 100, 120, 240)


def match_columns(columns, keys, mapping=None, name_map=None):
    """{column: [rig keys]} for the capture's shape columns. `mapping` (column -> key or list
    of keys, names as spelled) comes first; then names match as `names.shape_key` reads them
    (any convention, `name_map` the user's table); a column without side that the rig splits
    in halves (`cheekPuff` -> `cheekPuff_L`, `cheekPuff_R`) drives both. Returns (matched,
    unmatched columns, unmatched keys)."""
    mapping = mapping or {}
    by_key = {}
    for key in keys:
        by_key.setdefault(shape_key(key, name_map), []).append(key)
    lowered = {k.lower(): k for k in keys}
    matched, unmatched = {}, []
    for column in columns:
        if column in mapping:
            targets = mapping[column] if isinstance(mapping[column], list) else [mapping[column]]
            missing = [t for t in targets if t not in keys and t.lower() not in lowered]
            if missing:
                raise MeshDataError(f"the mapping sends '{column}' to {', '.join(missing)}, which the rig does not have")
            matched[column] = [lowered.get(t.lower(), t) for t in targets]
            continue
        base, side = shape_key(column, name_map)
        targets = by_key.get((base, side), [])
        if not targets and side is None:
            targets = by_key.get((base, "L"), []) + by_key.get((base, "R"), [])
        if targets:
            matched[column] = targets
        else:
            unmatched.append(column)
    driven = {key for targets in matched.values() for key in targets}
    return matched, unmatched, [key for key in keys if key not in driven]


class Capture:
    """A parsed capture: shape columns with their values per frame, times in seconds, head
    rotation per frame (radians: pitch, yaw, roll) or None, the capture's rate, and what else
    the file held."""

    def __init__(self, columns, values, times, head, fps, format_name, ignored=(), lost=()):
        self.columns, self.values, self.times, self.head = columns, values, times, head
        self.fps, self.format, self.ignored = fps, format_name, list(ignored)
        # Timecodes of the rows where the phone lost the face (skipped), and, per kept frame,
        # whether tracking was lost right after it (its value holds across the gap).
        self.lost = list(lost)
        self.hold = np.zeros(len(times), dtype=bool)


def _timecode_seconds(code, fps):
    hours, minutes, seconds, frame = code.strip().split(":")
    return int(hours) * 3600 + int(minutes) * 60 + int(seconds) + float(frame) / fps


def read_live_link(path, fps=None):
    """A Live Link Face CSV. Rows where the phone lost the face hold only a timecode (and a
    0 count) or fewer cells than the header: they are skipped, and the frame before each such
    gap is marked to hold its values until tracking resumes."""
    with open(path, newline="", encoding="utf-8-sig") as handle:
        rows = [row for row in csv.reader(handle) if row]
    if len(rows) < 2 or rows[0][0].strip().lower() != "timecode":
        raise MeshDataError(f"'{os.path.basename(path)}' is not a Live Link Face CSV: its header must start with Timecode")
    header = [cell.strip() for cell in rows[0]]
    lowered = [name.lower() for name in header]
    tracked = [len(row) >= len(header) for row in rows[1:]]
    lost = [row[0] for row, kept in zip(rows[1:], tracked) if not kept]
    rows = [rows[0]] + [row for row, kept in zip(rows[1:], tracked) if kept]
    if len(rows) < 2:
        raise MeshDataError(f"'{os.path.basename(path)}': the phone lost the face on every row: nothing to key")
    try:
        codes = [row[0] for row in rows[1:]]
        if fps is None:
            largest = max(int(code.split(":")[3].split(".")[0]) for code in codes + lost)
            fps = next((rate for rate in STANDARD_RATES if rate > largest), largest + 1)
        times = [_timecode_seconds(code, fps) for code in codes]
        lost_times = [_timecode_seconds(code, fps) for code in lost]
    except (IndexError, ValueError):
        raise MeshDataError(f"'{os.path.basename(path)}': a timecode is not HH:MM:SS:FF.mmm")
    shape_columns = [c for c, name in enumerate(lowered) if name not in LIVE_LINK_HEAD + LIVE_LINK_OTHER]
    head_columns = [lowered.index(name) if name in lowered else None for name in LIVE_LINK_HEAD]

    try:
        # Every cell after the timecode is a number: parsed at once (a 10-minute take is 2M cells).
        table = np.array([row[1:len(header)] for row in rows[1:]], dtype=np.float64)
    except ValueError:
        table = None
    if table is None or table.shape != (len(rows) - 1, len(header) - 1):
        for row in rows[1:]:
            for c in range(1, len(header)):
                try:
                    float(row[c])
                except (IndexError, ValueError):
                    raise MeshDataError(
                        f"'{os.path.basename(path)}': column '{header[c]}' has a value that is not a number: {row[c:c + 1]}")
    values = table[:, [c - 1 for c in shape_columns]]
    head = None
    if all(c is not None for c in head_columns):
        # Pitch, yaw, roll in radians (see the module's header).
        head = table[:, [head_columns[1] - 1, head_columns[0] - 1, head_columns[2] - 1]].tolist()
    ignored = [name for name, low in zip(header, lowered) if low in LIVE_LINK_OTHER]
    capture = Capture([header[c] for c in shape_columns], values, times, head, fps, "Live Link Face CSV", ignored, lost)
    # A kept frame holds when a lost row comes after it and before the next kept frame.
    following = np.searchsorted(np.asarray(times), np.asarray(lost_times), side="right") - 1
    capture.hold[following[following >= 0]] = True
    return capture


def read_face_cap(path):
    names, values, times, head = None, [], [], []
    with open(path, encoding="utf-8-sig") as handle:
        for number, line in enumerate(handle, 1):
            words = [w.strip() for w in line.strip().split(",")]
            if words[0] == "bs":
                names = words[1:]
            elif words[0] == "k":
                if names is None or len(words) != 12 + len(names):
                    raise MeshDataError(f"'{os.path.basename(path)}' line {number}: a key line needs 12 values and one per 'bs' shape")
                try:
                    numbers = [float(w) for w in words[1:]]
                except ValueError:
                    raise MeshDataError(f"'{os.path.basename(path)}' line {number}: a value is not a number")
                times.append(numbers[0] / 1000.0)
                # Head Euler angles x, y, z in degrees: pitch, yaw, roll.
                head.append(tuple(math.radians(a) for a in numbers[4:7]))
                values.append(numbers[11:])
            elif words[0] not in ("info", ""):
                raise MeshDataError(f"'{os.path.basename(path)}' line {number} is not a Face Cap line (info, bs or k)")
    if names is None or not values:
        raise MeshDataError(f"'{os.path.basename(path)}' is not a Face Cap TXT: no 'bs' line or no 'k' lines")
    steps = [b - a for a, b in zip(times, times[1:]) if b > a]
    fps = round(1.0 / sorted(steps)[len(steps) // 2], 3) if steps else None
    return Capture(names, values, times, head, fps, "Face Cap TXT")


def read_capture(path, fps=None):
    if not os.path.isfile(path):
        raise MeshDataError(f"capture file not found: {path}")
    if path.lower().endswith(".txt"):
        return read_face_cap(path)
    return read_live_link(path, fps)


def read_mapping(text):
    """A user mapping from JSON text: {"column": "key"} or {"column": ["key", ...]}."""
    try:
        mapping = json.loads(text) if text.strip() else {}
    except json.JSONDecodeError as error:
        raise MeshDataError(f"the capture mapping is not valid JSON: {error}")
    if not isinstance(mapping, dict):
        raise MeshDataError('the capture mapping must be a JSON object: {"column": "shape key"}')
    return mapping


def key_frames(capture, scene_fps, start):
    """The scene frame of each captured frame (whole frames where they land within 1e-4)."""
    first = capture.times[0]
    frames = []
    for t in capture.times:
        frame = start + (t - first) * scene_fps
        frames.append(float(round(frame)) if abs(frame - round(frame)) < 1e-4 else frame)
    return frames


def head_axes(obj):
    """(left, up, front) unit vectors of the face in `obj`'s mesh coordinates and the warnings
    of finding them (a mesh the tools cannot read keeps Blender's front view: -Y, up +Z)."""
    try:
        front, up = view_front(obj)
        warnings = []
    except MeshDataError as error:
        front, up = (0.0, -1.0, 0.0), (0.0, 0.0, 1.0)
        warnings = [f"the face's front was not found ({error}): the head turns about -Y (front) and +Z (up)"]
    front, up = np.asarray(front, dtype=np.float64), np.asarray(up, dtype=np.float64)
    return np.cross(up, front), up, front, warnings


def head_rotations(angles, axes, invert=()):
    """The head's rotation per captured frame (3 x 3 mathutils, mesh coordinates) from (pitch,
    yaw, roll) in radians: R_front(roll) R_up(yaw) R_left(pitch); the angles named in `invert`
    (YAW, PITCH, ROLL) change sign first."""
    left, up, front = axes
    signs = {name: -1.0 if name in invert else 1.0 for name in HEAD_ANGLES}
    return [Matrix.Rotation(signs["ROLL"] * roll, 3, front) @ Matrix.Rotation(signs["YAW"] * yaw, 3, up)
            @ Matrix.Rotation(signs["PITCH"] * pitch, 3, left) for pitch, yaw, roll in angles]


def import_capture(obj, path, scene, mapping=None, fps=None, head=True, invert_head=(), name_map=None):
    """Keys the capture onto `obj`'s shape keys (and its rotation when the capture has the
    head's and `head`, about the face's own axes; `invert_head` names angles whose sign to
    change; `name_map`: the user's name table, `names.read_name_map`); returns the report.
    Everything is read and matched before any key."""
    keys = obj.data.shape_keys
    if obj.type != "MESH" or keys is None or len(keys.key_blocks) < 2:
        raise MeshDataError(f"'{obj.name}' has no shape keys to drive")
    unknown = set(invert_head) - set(HEAD_ANGLES)
    if unknown:
        raise MeshDataError(f"unknown head angle {', '.join(sorted(unknown))}: invert YAW, PITCH or ROLL")
    capture = read_capture(path, fps)
    names = [block.name for block in keys.key_blocks if block != keys.reference_key]
    matched, unmatched_columns, unmatched_keys = match_columns(capture.columns, names, mapping, name_map)
    if not matched:
        raise MeshDataError(
            f"no column of '{os.path.basename(path)}' matches a shape key of '{obj.name}' (columns such as "
            f"{', '.join(capture.columns[:3])}): give a mapping"
        )
    keyed_head = head and capture.head is not None
    warnings = []
    if keyed_head:
        left, up, front, warnings = head_axes(obj)
        rotations = head_rotations(capture.head, (left, up, front), invert_head)
    scene_fps = scene.render.fps / scene.render.fps_base
    frames = key_frames(capture, scene_fps, scene.frame_start)
    values = np.asarray(capture.values, dtype=np.float64)
    for column, targets in matched.items():
        c = capture.columns.index(column)
        column_values = values[:, c]
        for target in targets:
            key_channel(keys.key_blocks[target], "value", -1, frames, column_values, group="Shapesmith Capture",
                        hold=capture.hold)
    if keyed_head:
        rest = obj.matrix_world.copy()
        key_transforms(obj, frames, [rest @ rotation.to_4x4() for rotation in rotations], hold=capture.hold)
    return {
        "object": obj.name,
        "capture": os.path.abspath(path),
        "format": capture.format,
        "frames": len(frames),
        "first_frame": frames[0],
        "last_frame": frames[-1],
        "capture_fps": capture.fps,
        "scene_fps": scene_fps,
        "columns_used": matched,
        "unmatched_columns": unmatched_columns,
        "unmatched_keys": unmatched_keys,
        "ignored_columns": capture.ignored,
        "lost_tracking_rows": len(capture.lost),
        "lost_tracking_timecodes": capture.lost,
        "held_frames": [frames[i] for i in np.flatnonzero(capture.hold)],
        "head_rotation": keyed_head,
        "head_axes": {"left": list(left), "up": list(up), "front": list(front)} if keyed_head else None,
        "inverted_head_angles": sorted(invert_head),
        "warnings": warnings,
    }


def lost_tracking_line(report):
    """One line on the rows skipped where the phone lost the face, for the panel and batch."""
    if not report["lost_tracking_rows"]:
        return "lost tracking: none"
    return (f"lost tracking: {report['lost_tracking_rows']} rows skipped (from {report['lost_tracking_timecodes'][0]}); "
            f"the keys hold after frames {', '.join(f'{f:g}' for f in report['held_frames'][:10])}"
            + (" ..." if len(report["held_frames"]) > 10 else ""))
