"""Copy Drivers: the template's drivers on its key values recreated on the target's keys,
every variable pointed at the target's side of the rig.

What a variable points at is carried over, in this order:
- the template's objects, meshes and keys -> the target's (object i onto object i);
- the user's driver map (`template object = target object`, a Text in the panel or
  `--driver-map FILE`), by object name;
- the template's armature (its Armature modifier's object, else its armature parent) -> the
  target's;
- an object whose name holds the template's name (`Template_FaceControls`) -> the object
  named with the target's name in its place (`Boy_FaceControls`), when there is one.
Anything else keeps pointing where it pointed, and is reported; a bone the new armature lacks
is reported too. A path naming one of the template's keys (`key_blocks["eyeBlinkLeft"]`)
names the target's key for that shape.
"""

import re

import bpy

from .mesh_arrays import MeshDataError


def value_path(name):
    return f'key_blocks["{bpy.utils.escape_identifier(name)}"].value'


def key_drivers(source, names):
    """The template's drivers on the values of the keys `names`: {name: F-curve}."""
    animation = source.data.shape_keys.animation_data
    if animation is None:
        return {}
    by_path = {fcurve.data_path: fcurve for fcurve in animation.drivers}
    return {name: by_path[value_path(name)] for name in names if value_path(name) in by_path}


def armature_of(obj):
    """The armature deforming `obj`: its Armature modifier's object, else its armature parent."""
    for modifier in obj.modifiers:
        if modifier.type == "ARMATURE" and modifier.object is not None:
            return modifier.object
    parent = obj.parent
    return parent if parent is not None and parent.type == "ARMATURE" else None


def driver_targets(pairs, driver_map=None):
    """{template ID: target ID} for the drivers' variables: `pairs` are (template object,
    target object); `driver_map` the user's {template object name: target object name}.
    Raises MeshDataError naming an object of the map the file does not have."""
    mapping = {}
    for source, target in pairs:
        template_rig, target_rig = armature_of(source), armature_of(target)
        if template_rig is not None and target_rig is not None:
            mapping.setdefault(template_rig, target_rig)
            mapping.setdefault(template_rig.data, target_rig.data)
        for obj in bpy.data.objects:
            if source.name in obj.name and obj not in mapping and obj != source:
                counterpart = bpy.data.objects.get(obj.name.replace(source.name, target.name))
                if counterpart is not None and counterpart != obj:
                    mapping.setdefault(obj, counterpart)
    for template_name, target_name in (driver_map or {}).items():
        missing = [n for n in (template_name, target_name) if n not in bpy.data.objects]
        if missing:
            raise MeshDataError(f"the driver map names {', '.join(repr(n) for n in missing)}, which the file does not have")
        mapping[bpy.data.objects[template_name]] = bpy.data.objects[target_name]
    for source, target in pairs:
        mapping.update({source: target, source.data: target.data})
    return mapping


# What a variable can point at on the template's side of a rig (a scene or world property is
# the same for both heads).
_RIG_TYPES = (bpy.types.Object, bpy.types.Mesh, bpy.types.Key, bpy.types.Armature)
_KEY_PATH = re.compile(r'key_blocks\["((?:[^"\\]|\\.)*)"\]')


def _renamed_path(path, onto):
    """`path` with a template key's name replaced by the target's name for that shape."""
    return _KEY_PATH.sub(lambda m: f'key_blocks["{bpy.utils.escape_identifier(onto.get(m.group(1), m.group(1)))}"]', path)


def copy_driver(fcurve, keys, mapping, onto=None):
    """Recreates the driver F-curve `fcurve` on the Key `keys`: expression, variables (their
    targets mapped through `mapping`, template ID -> target ID, and key names through
    `onto`), keyframes and Generator modifiers. Returns warnings for what could not be
    carried over or still points at the template's side."""
    onto = onto or {}
    warnings = []
    path = _renamed_path(fcurve.data_path, onto)
    if keys.animation_data is not None and keys.animation_data.drivers.find(path) is not None:
        keys.driver_remove(path)
    new = keys.driver_add(path)
    # driver_add starts with a default Generator (4.x) or default keyframes (5.x)
    for modifier in list(new.modifiers):
        new.modifiers.remove(modifier)
    new.keyframe_points.clear()
    driver, source_driver = new.driver, fcurve.driver
    driver.type = source_driver.type
    driver.use_self = source_driver.use_self
    driver.expression = source_driver.expression
    retargeted = set(mapping.values())
    for variable in source_driver.variables:
        copy = driver.variables.new()
        copy.name = variable.name
        copy.type = variable.type
        for source_target, target in zip(variable.targets, copy.targets):
            if variable.type == "SINGLE_PROP":
                target.id_type = source_target.id_type
            target.id = mapping.get(source_target.id, source_target.id) if source_target.id is not None else None
            target.data_path = _renamed_path(source_target.data_path, onto) if target.id == keys else source_target.data_path
            target.bone_target = source_target.bone_target
            target.transform_type = source_target.transform_type
            target.transform_space = source_target.transform_space
            target.rotation_mode = source_target.rotation_mode
            if isinstance(target.id, _RIG_TYPES) and target.id not in retargeted:
                warnings.append(
                    f"driver on {path}: variable '{variable.name}' still points at '{target.id.name}' "
                    "(no counterpart found: add it to the driver map)"
                )
            elif (target.bone_target and getattr(target.id, "type", None) == "ARMATURE"
                  and target.bone_target not in target.id.data.bones):
                warnings.append(f"driver on {path}: variable '{variable.name}' reads bone '{target.bone_target}', "
                                f"which '{target.id.name}' does not have")
    new.extrapolation = fcurve.extrapolation
    points = fcurve.keyframe_points
    new.keyframe_points.add(len(points))
    for point, copy in zip(points, new.keyframe_points):
        copy.co = point.co
        copy.interpolation = point.interpolation
        copy.handle_left_type, copy.handle_right_type = point.handle_left_type, point.handle_right_type
        copy.handle_left, copy.handle_right = point.handle_left, point.handle_right
    for modifier in fcurve.modifiers:
        if modifier.type != "GENERATOR":
            warnings.append(f"driver on {path}: its {modifier.type.lower()} modifier was not copied")
            continue
        copy = new.modifiers.new("GENERATOR")
        copy.mode, copy.poly_order, copy.use_additive = modifier.mode, modifier.poly_order, modifier.use_additive
        copy.coefficients = modifier.coefficients
    return warnings
