"""The rig's front and up, in the mesh's own coordinates (where the tools work): found by the
native `find_front` from the rig itself, or taken from a scene camera the user picks (its
view direction reversed is the front, its up the up). Packing's occlusion conflicts and the
reference sheet both see the face from this front."""

import json

import numpy as np

from .. import native
from .mesh_arrays import MeshDataError, read_rig

AXIS_NAMES = "XYZ"


def rig_front(obj, rig, axis=0, camera=None):
    """{"front", "up", "front_source", "front_camera", "warnings"} for `obj`'s `rig` (a
    `read_rig` Rig): from `camera` when given, else found with `axis` the symmetry axis tried
    first (`front_source` "found"; "default", -Y with up +Z and a warning, when the rig gives
    no front). Directions are unit 3-lists in `obj`'s mesh coordinates."""
    if camera is not None:
        return _camera_front(obj, camera)
    core = native.module()
    try:
        found = core.find_front(rig.neutral, rig.deltas, rig.triangles, rig.names, axis=axis)
    except core.InvalidInputError as error:
        # No key moves the mesh, a coordinate is not finite, or the normals cancel out: the
        # tools' own checks name the first two; otherwise the default front is used, and said.
        return {
            "front": [0.0, -1.0, 0.0],
            "up": [0.0, 0.0, 1.0],
            "front_source": "default",
            "front_camera": None,
            "warnings": [f"the front of '{obj.name}' was not found ({error}): -Y is used, up +Z"],
        }
    warnings = []
    lateral = found["lateral_axis"]
    if lateral is None:
        warnings.append(
            f"'{obj.name}' is not mirror-symmetric across X, Y or Z = 0: its front, {direction_label(found['front'])}, "
            "is the mean normal of its moving regions; pick a front camera in the Pack panel if it is wrong"
        )
    elif lateral != axis:
        warnings.append(
            f"'{obj.name}' is mirror-symmetric across {AXIS_NAMES[lateral]} = 0, not {AXIS_NAMES[axis]} = 0: "
            f"set the Rig panel's symmetry axis to {AXIS_NAMES[lateral]} for symmetric pairs"
        )
    if found["up_source"] == "assumed":
        warnings.append(
            f"no shape key named for the eyes or the mouth moves on '{obj.name}': its up is taken as "
            f"{direction_label(found['up'])}; pick a front camera in the Pack panel if it is wrong"
        )
    return {"front": found["front"], "up": found["up"], "front_source": "found", "front_camera": None, "warnings": warnings}


def _camera_front(obj, camera):
    """The camera's view reversed (towards the camera) and its up, taken into `obj`'s mesh
    coordinates: a direction d in the world is L^-1 d locally (L: the object's linear part)."""
    if camera.type != "CAMERA":
        raise MeshDataError(f"'{camera.name}' is a {camera.type.lower()}, not a camera")
    linear = np.array(obj.matrix_world.to_3x3(), dtype=np.float64)
    if abs(np.linalg.det(linear)) < 1e-12:
        raise MeshDataError(f"'{obj.name}' has a zero scale: its mesh directions cannot be found")
    view = np.array(camera.matrix_world.to_3x3(), dtype=np.float64)
    toward = np.linalg.solve(linear, view[:, 2])  # the camera looks along its local -Z
    up = np.linalg.solve(linear, view[:, 1])
    toward /= np.linalg.norm(toward)
    up -= toward * float(up @ toward)
    if np.linalg.norm(up) < 1e-9:
        raise MeshDataError(f"camera '{camera.name}' has no usable up direction for '{obj.name}'")
    up /= np.linalg.norm(up)
    return {
        "front": [float(x) for x in toward],
        "up": [float(x) for x in up],
        "front_source": "camera",
        "front_camera": camera.name,
        "warnings": [],
    }


def direction_label(vector):
    """'-Y' for a signed mesh axis, else the rounded components."""
    v = np.asarray(vector, dtype=np.float64)
    axis = int(np.argmax(np.abs(v)))
    if abs(abs(v[axis]) - 1.0) < 1e-6:
        return f"{'-' if v[axis] < 0 else '+'}{AXIS_NAMES[axis]}"
    return "(" + ", ".join(f"{x:.2f}" for x in v) + ")"


def front_summary(params):
    """'-Y (found), up +Z' or 'camera Camera' from a packing's stored params; None before any."""
    if "front" not in params:
        return None
    if params.get("front_source") == "camera":
        return f"camera {params.get('front_camera')}"
    source = params.get("front_source", "found")
    return f"{direction_label(params['front'])} ({source}), up {direction_label(params['up'])}"


def to_front_view(front, up):
    """The rotation (3 x 3) taking mesh coordinates to a frame where `front` is -Y and `up`
    is +Z: the reference sheet's fixed stage then shows the face from its front."""
    f, u = np.asarray(front, dtype=np.float64), np.asarray(up, dtype=np.float64)
    return np.array([np.cross(u, f), -f, u])


def view_front(obj):
    """(front, up) for the pictures of `obj`: those its last packing used (its occlusions
    looked from there, camera or found), else found now with the scene's symmetry axis."""
    import bpy

    result = obj.shapesmith.pack.result
    params = json.loads(result.params_json or "{}") if result.done else {}
    if "front" in params and "up" in params:
        return params["front"], params["up"]
    found = rig_front(obj, read_rig(obj), axis=int(bpy.context.scene.shapesmith.symmetry_axis))
    return found["front"], found["up"]


def front_view_matrix(obj):
    """4 x 4 (numpy) taking world coordinates to the pictures' frame: `obj`'s mesh coordinates
    turned by `to_front_view`, so that its front looks towards -Y with its up along +Z."""
    turn = np.eye(4)
    turn[:3, :3] = to_front_view(*view_front(obj))
    return turn @ np.linalg.inv(np.array(obj.matrix_world))
