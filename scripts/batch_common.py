"""What every command of scripts/batch.py shares: its error, the installed extension, the
input file and its objects, and the outputs (JSON, a saved copy)."""

import json
import os

import bpy


class BatchError(Exception):
    """Bad input: reported as one line on stderr, exit status 2."""


def load_shapesmith():
    """The installed Shapesmith extension's package, enabled."""
    import addon_utils
    import importlib

    names = [m.__name__ for m in addon_utils.modules(refresh=False) if m.__name__.rsplit(".", 1)[-1] == "shapesmith"]
    if not names:
        raise BatchError(
            "the Shapesmith extension is not installed in this Blender: build it with scripts/build and "
            "install dist/shapesmith-*.zip (Preferences > Get Extensions > Install from Disk)"
        )
    addon_utils.enable(names[0], default_set=True)
    return importlib.import_module(names[0])


def tool_settings():
    """The installed extension's `blender/settings.py`: each tool's settings dataclass, whose
    defaults are every tool flag's (the core's, as the panel's)."""
    from importlib import import_module

    return import_module(load_shapesmith().__name__ + ".blender.settings")


def open_blend(path):
    if not path or not os.path.isfile(path):
        raise BatchError(f"input file not found: {path}")
    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(path))


def find_object(name):
    obj = bpy.data.objects.get(name)
    if obj is None:
        meshes = ", ".join(o.name for o in bpy.data.objects if o.type == "MESH") or "none"
        raise BatchError(f"no object named '{name}' in the file (meshes: {meshes})")
    return obj


def find_face(value, shapesmith):
    """The head named first in a comma list `Head,Teeth,EyeLeft,EyeRight`, with the parts
    after it stored as its Face Parts list (every tool then reads them with it, and a saved
    copy keeps them); a head named alone keeps the list stored on it."""
    from importlib import import_module

    names = [name.strip() for name in value.split(",")]
    if not all(names):
        raise BatchError(f"'{value}' has an empty name: give the head, then its parts, separated by commas")
    objects = [find_object(name) for name in names]
    if len(objects) > 1:
        import_module(shapesmith.__name__ + ".blender.face_parts").store_parts(objects[0], objects[1:])
    return objects[0]


def template_or_bundled(value, shapesmith):
    """The template `value` names (`find_face`), else the bundled ARKit template, added to the
    scene and picked as the Transfer panel's template (a saved copy keeps it)."""
    from importlib import import_module

    if value:
        return find_face(value, shapesmith)
    template = import_module(shapesmith.__name__ + ".blender.bundled_template").add_template(bpy.context.scene)
    bpy.context.scene.shapesmith.transfer.source = template
    return template


def write_json(path, data):
    """Writes `data` to `path` (nothing when no path), making its folder if need be."""
    if path:
        os.makedirs(os.path.dirname(os.path.abspath(path)), exist_ok=True)
        with open(path, "w") as f:
            json.dump(data, f, indent=2)


def save_copy(path):
    """Saves the result to a new file; the input file is left as it was."""
    bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(path), copy=True)


NAME_MAP_HELP = ("your names for shapes: a file of lines 'your name = the name it means' (or a JSON object), or "
                 "the name of a Rig preset whose Shape Key Names table to use (shipped: 'ARKit', 'Character Creator', "
                 "'Daz Genesis 8.1', 'Unified Expressions', 'Suffix .L .R', 'Suffix L R (underscore)'; or one you "
                 "saved), read besides the conventions every tool knows (ARKit, _L/_R, .L/.R, L_, blendShape1., "
                 "Character Creator, Daz, Unified Expressions)")


def _table_file(path, shapesmith, flag):
    """A file of lines `theirs = ours` (or a JSON object) as a dict; None without a path."""
    from importlib import import_module

    if not path:
        return None
    if not os.path.isfile(path):
        raise BatchError(f"{flag.lstrip('-').replace('-', ' ')} not found: {path}")
    with open(path, encoding="utf-8") as handle:
        return import_module(shapesmith.__name__ + ".blender.names").read_name_map(handle.read(), f"{flag} {path}")


def name_map(args, shapesmith):
    """The user's name table of --name-map (None without it): a file's, else the Shape Key Names
    table of the Rig preset of that name, picked for the file's scene as the preset menu does
    (a saved copy keeps it)."""
    from importlib import import_module

    value = args.name_map
    if not value or os.path.isfile(value):
        return _table_file(value, shapesmith, "--name-map")
    presets = import_module(shapesmith.__name__ + ".ui.presets")
    if not presets.apply_preset("rig", value):
        raise BatchError(f"name map not found: {value} is neither a file nor a Rig preset "
                         f"({', '.join(presets.preset_names('rig'))})")
    return import_module(shapesmith.__name__ + ".blender.names").scene_name_map(bpy.context.scene)


def driver_map(args, shapesmith):
    """The --driver-map table {template object: target object} (None without it)."""
    return _table_file(args.driver_map, shapesmith, "--driver-map")


def print_looks(shapesmith, character, looks):
    """Prints where riggers look first, per key (the Wrap panel's lines), and keeps them on
    `character` for the panel."""
    from importlib import import_module

    module = import_module(shapesmith.__name__ + ".blender.looks")
    module.store_looks(character, looks)
    for line, good in module.look_lines(looks):
        print(("  ok    " if good else "  CHECK ") + line)
