"""Keyframes written in bulk: one F-curve per channel, its points set through `foreach_set`
(Blender 4.2's single-layer actions and 4.4+/5.x's slotted actions alike). Used by Solve
Performance and Import Capture."""

import numpy as np


def _fcurves(id_data):
    """The F-curves of `id_data`'s action: the slot's channelbag on 4.4+ (layered actions),
    `action.fcurves` before."""
    animation = id_data.animation_data
    action = animation.action
    try:
        from bpy_extras.anim_utils import action_get_channelbag_for_slot
    except ImportError:
        return action.fcurves
    bag = action_get_channelbag_for_slot(action, animation.action_slot)
    return bag.fcurves if bag is not None else action.fcurves


def key_channel(owner, data_path, index, frames, values, group=None, hold=None):
    """Replaces the keyframes of `owner.data_path[index]` (index -1 for a scalar) with one
    linear key per frame; the keys where `hold` (bools, one per frame) is true are constant
    (their value holds until the next key). `owner` is the struct holding the property (an object, a shape key);
    the F-curve lives on its ID (the object, the Key)."""
    frames = np.asarray(frames, dtype=np.float32)
    values = np.asarray(values, dtype=np.float32)
    if len(frames) != len(values) or len(frames) == 0:
        raise ValueError(f"{len(frames)} frames but {len(values)} values for {data_path}")
    # The first key creates the action, its slot and the F-curve; then all keys are written.
    owner.keyframe_insert(data_path, index=index, frame=float(frames[0]), group=group or "")
    id_data = owner.id_data
    full_path = owner.path_from_id(data_path) if owner != id_data else data_path
    curve = _fcurves(id_data).find(full_path, index=max(index, 0))
    curve.keyframe_points.clear()
    curve.keyframe_points.add(len(frames))
    coordinates = np.empty(2 * len(frames), dtype=np.float32)
    coordinates[0::2], coordinates[1::2] = frames, values
    curve.keyframe_points.foreach_set("co", coordinates)
    interpolation = np.full(len(frames), _interpolation_code(curve, "LINEAR"), dtype=np.int32)
    if hold is not None:
        interpolation[np.asarray(hold, dtype=bool)] = _interpolation_code(curve, "CONSTANT")
    curve.keyframe_points.foreach_set("interpolation", interpolation)
    curve.update()
    return curve


def _interpolation_code(curve, name):
    """The enum number of a keyframe's interpolation `name` (foreach_set takes numbers)."""
    items = curve.keyframe_points[0].bl_rna.properties["interpolation"].enum_items
    return items[name].value


def key_transforms(obj, frames, matrices, hold=None):
    """One keyframe per frame on `obj`'s location, rotation (in its own rotation mode, Euler
    angles kept continuous) and scale, from its world matrices (mathutils.Matrix)."""
    from mathutils import Matrix

    parent_inverse = Matrix.Identity(4)
    if obj.parent is not None:
        parent_inverse = (obj.parent.matrix_world @ obj.matrix_parent_inverse).inverted_safe()
    locations, rotations, scales = [], [], []
    previous = None
    quaternion_mode = obj.rotation_mode == "QUATERNION"
    for matrix in matrices:
        location, rotation, scale = (parent_inverse @ matrix).decompose()
        locations.append(location[:])
        scales.append(scale[:])
        if quaternion_mode:
            rotations.append(rotation[:])
        elif obj.rotation_mode == "AXIS_ANGLE":
            axis, angle = rotation.to_axis_angle()
            rotations.append((angle, *axis))
        else:
            euler = rotation.to_euler(obj.rotation_mode, previous) if previous else rotation.to_euler(obj.rotation_mode)
            previous = euler
            rotations.append(euler[:])
    rotation_path = {"QUATERNION": "rotation_quaternion", "AXIS_ANGLE": "rotation_axis_angle"}.get(
        obj.rotation_mode, "rotation_euler")
    for path, rows in (("location", locations), (rotation_path, rotations), ("scale", scales)):
        rows = np.asarray(rows)
        for axis in range(rows.shape[1]):
            key_channel(obj, path, axis, frames, rows[:, axis], group="Object Transforms", hold=hold)
