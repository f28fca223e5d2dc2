"""Presets: a rigger saves a panel's settings under a name (a studio's rig convention, a kind
of head) and picks them for the next rig, from the preset icon in the panel's header, as
Blender's own presets work. Each is a small script in the user's presets folder
(`presets/shapesmith/<panel>/`) that sets the values listed here: the settings, never a
rig's own objects, results or picked template. The Rig preset carries the Shape Key Names
table, so a naming convention is one click on the next head.

The extension ships Rig presets for common rigs (`presets/shapesmith/rig/` beside this
package: ARKit, Character Creator, Daz Genesis 8.1, Unified Expressions, `.L`/`.R` and `_L`/`_R`
suffixes) on Blender's preset path, so they are listed with the user's own; Blender refuses
to delete them (they live in the extension)."""

import os

import bpy
from bl_operators.presets import AddPresetBase
from bl_ui.utils import PresetPanel

# Per panel: where its settings live, and the settings a preset keeps.
PRESETS = {
    "rig": ("settings = bpy.context.scene.shapesmith", ("symmetry_axis", "pair_by_name", "name_map")),
    "pack": (
        "settings = bpy.context.active_object.shapesmith.pack",
        ("symmetric", "limit_expressions", "max_expressions", "mu", "a", "beta", "antagonist_cosine",
         "collision_conflicts", "collision_tolerance", "occlusion_conflicts", "occlusion_keep", "fewest"),
    ),
    "landmarks": (
        "settings = bpy.context.scene.shapesmith.landmarks",
        ("symmetric", "camera_source", "design", "landmarks", "target_error", "epsilon", "alpha", "gamma",
         "max_per_shape", "radius", "rays"),
    ),
    "transfer": (
        "settings = bpy.context.scene.shapesmith.transfer",
        ("overwrite", "keep_sculpted", "copy_drivers", "virtual_edges", "tau_d", "tau_r", "edge_weight",
         "compare_plain", "contact", "contact_distance", "beta_reg", "refine_weights"),
    ),
}


def _classes(panel):
    define, names = PRESETS[panel]
    subdir = f"shapesmith/{panel}"
    title = panel.title()
    presets_panel = type(f"SHAPESMITH_PT_{panel}_presets", (PresetPanel, bpy.types.Panel), {
        "bl_label": f"{title} Presets",
        "preset_subdir": subdir,
        "preset_operator": "script.execute_preset",
        "preset_add_operator": f"shapesmith.add_{panel}_preset",
    })
    add_operator = type(f"SHAPESMITH_OT_add_{panel}_preset", (AddPresetBase, bpy.types.Operator), {
        "bl_idname": f"shapesmith.add_{panel}_preset",
        "bl_label": f"Add {title} Preset",
        "bl_description": f"Save the {title} panel's settings as a preset, or remove the preset",
        "preset_menu": presets_panel.__name__,
        "preset_subdir": subdir,
        "preset_defines": [define],
        "preset_values": [f"settings.{name}" for name in names],
    })
    if panel == "pack":  # the pack's settings are the active mesh's
        add_operator.poll = classmethod(lambda cls, context: context.active_object is not None
                                        and context.active_object.type == "MESH")
    return presets_panel, add_operator


_PANELS = {panel: _classes(panel) for panel in PRESETS}


# The folder holding `presets/shapesmith/<panel>/`: the presets shipped with the extension.
_SHIPPED = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def draw_header(layout, panel):
    """The preset icon in a panel's header (its `draw_header_preset`)."""
    _PANELS[panel][0].draw_panel_header(layout)


def preset_names(panel):
    """The names `panel`'s preset menu lists (shipped and the user's), sorted."""
    subdir = f"shapesmith/{panel}"
    return sorted({bpy.path.display_name(f, title_case=False) for folder in bpy.utils.preset_paths(subdir)
                   for f in os.listdir(folder) if f.endswith(".py")}, key=str.lower)


def apply_preset(panel, name):
    """Picks `panel`'s preset `name` (as its menu lists it, or its file name without `.py`) as
    the menu does; False when there is none."""
    subdir = f"shapesmith/{panel}"
    path = bpy.utils.preset_find(name, subdir) or bpy.utils.preset_find(name, subdir, display_name=True)
    if path is None:
        return False
    return bpy.ops.script.execute_preset(filepath=path, menu_idname=_PANELS[panel][0].__name__) == {"FINISHED"}


_register_classes, _unregister_classes = bpy.utils.register_classes_factory(
    [cls for pair in _PANELS.values() for cls in pair])


def register():
    _register_classes()
    bpy.utils.register_preset_path(_SHIPPED)


def unregister():
    bpy.utils.unregister_preset_path(_SHIPPED)
    _unregister_classes()
