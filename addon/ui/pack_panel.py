"""The Pack Expressions panel: Pack first with the settings a rigger changes, the packed expressions
as a list with their members and what to do with them; your refinements and the advanced
settings in sub-panels."""

import json

import bpy

from ..blender.front import front_summary
from ..operators.job_operator import draw_running
from .panels import ShapesmithPanel
from . import presets


class SHAPESMITH_UL_expressions(bpy.types.UIList):
    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index):
        row = layout.row(align=True)
        row.label(text=f"{index + 1}", icon="CHECKMARK" if item.optimal else "ERROR")
        row.label(text=", ".join(m.name for m in item.members))


class SHAPESMITH_UL_shape_names(bpy.types.UIList):
    """Shape names picked from the mesh's shape keys (excluded shapes)."""

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index):
        keys = context.active_object.data.shape_keys
        if keys is None:
            layout.label(text=item.name)
        else:
            layout.prop_search(item, "name", keys, "key_blocks", text="")


def _refinement_list(layout, settings, title, kind, collection, index, list_type):
    layout.label(text=f"{title} ({len(getattr(settings, collection))})")
    row = layout.row()
    row.template_list(list_type, f"pack_{collection}", settings, collection, settings, index, rows=2)
    col = row.column(align=True)
    col.operator("shapesmith.add_pack_refinement", icon="ADD", text="").kind = kind
    col.operator("shapesmith.remove_pack_refinement", icon="REMOVE", text="").kind = kind


# Reasons that are not plain overlap: the ones a rigger may not expect.
_SURPRISING = {"antagonist", "collision", "occlusion", "user"}


def _kept_apart(layout, result, members):
    """The conflicts between this expression's members and other shapes, beyond overlap."""
    rows = [
        (c.first if c.first in members else c.second, c.second if c.first in members else c.first, c.reasons)
        for c in result.conflicts
        if (c.first in members) != (c.second in members) and _SURPRISING & set(c.reasons.split())
    ]
    if rows:
        layout.label(text="Kept apart (besides overlap):")
        for member, other, reasons in rows:
            layout.label(text=f"{member} / {other}: {reasons.replace(' ', ', ')}", icon="UNLINKED")


def _front_text(settings):
    """The front the next packing uses: the picked camera, or the one the last packing found."""
    if settings.front_camera is not None:
        return f"camera {settings.front_camera.name}"
    stored = front_summary(json.loads(settings.result.params_json or "{}")) if settings.result.done else None
    return stored if stored and not stored.startswith("camera") else "found when packing"


class SHAPESMITH_PT_pack(ShapesmithPanel, bpy.types.Panel):
    """Pack first, then the few settings a rigger changes; the rest under Advanced."""

    bl_label = "Pack Expressions"
    bl_order = 1
    bl_options = {"DEFAULT_CLOSED"}

    def draw_header_preset(self, context):
        presets.draw_header(self.layout, "pack")

    def draw(self, context):
        layout = self.layout
        obj = context.active_object
        if obj is None or obj.type != "MESH":
            layout.label(text="Select a mesh with shape keys", icon="INFO")
            return
        settings = obj.shapesmith.pack
        layout.operator("shapesmith.pack_expressions", icon="PACKAGE")
        draw_running(layout)
        layout.prop(settings, "target")
        layout.prop(settings, "symmetric")
        if settings.symmetric:
            pairs = obj.shapesmith.pairs
            source = f"{len(pairs)} pairs from Analyze Rig" if obj.shapesmith.analysis.done else "pairs found when packing"
            layout.label(text=source, icon="MOD_MIRROR")
        row = layout.row(align=True)
        row.prop(settings, "limit_expressions")
        sub = row.row(align=True)
        sub.active = settings.limit_expressions
        sub.prop(settings, "max_expressions")
        result = settings.result
        if not result.done:
            return
        self.draw_result(layout, settings, result)

    @staticmethod
    def draw_result(layout, settings, result):
        count = f"{len(result.expressions)} expressions to scan"
        if result.fewest:
            count += f" (fewest possible: {result.fewest}{'' if result.fewest_optimal else ', not proven'})"
        layout.label(text=count)
        layout.template_list("SHAPESMITH_UL_expressions", "", result, "expressions", settings, "active_expression", rows=5)
        if 0 <= settings.active_expression < len(result.expressions):
            expression = result.expressions[settings.active_expression]
            box = layout.box()
            box.label(text=f"{expression.name}: moves {expression.vertices} vertices, importance {expression.importance:.2f}")
            for member in expression.members:
                box.label(text=member.name, icon="SHAPEKEY_DATA")
            _kept_apart(box, result, {m.name for m in expression.members})
        for title, names in (("Never move", result.inert), ("Excluded", result.excluded), ("Left over", result.unplaced)):
            if names:
                layout.label(text=f"{title}: {', '.join(n.name for n in names)}")
        row = layout.row(align=True)
        row.operator("shapesmith.preview_expression", icon="HIDE_OFF")
        row.operator("shapesmith.animate_expressions", icon="KEYFRAME")
        row.operator("shapesmith.bake_expressions", icon="SHAPEKEY_DATA")
        row = layout.row(align=True)
        row.prop(settings, "explain", text="Explain")
        row.operator("shapesmith.export_shot_list", icon="EXPORT", text="Shot List")
        row.operator("shapesmith.render_reference_sheet", icon="RENDER_STILL", text="Reference Sheet")


class SHAPESMITH_PT_pack_refine(ShapesmithPanel, bpy.types.Panel):
    """Your own choices, honoured as constraints of the same program."""

    bl_label = "Pin, Keep Apart, Exclude"
    bl_parent_id = "SHAPESMITH_PT_pack"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        return context.active_object is not None and context.active_object.type == "MESH"

    def draw(self, context):
        settings = context.active_object.shapesmith.pack
        layout = self.layout
        _refinement_list(layout, settings, "Pin Together", "PIN", "pin_together", "active_pin", "SHAPESMITH_UL_pairs")
        _refinement_list(layout, settings, "Keep Apart", "APART", "keep_apart", "active_apart", "SHAPESMITH_UL_pairs")
        _refinement_list(layout, settings, "Exclude", "EXCLUDE", "exclude", "active_exclude", "SHAPESMITH_UL_shape_names")


class SHAPESMITH_PT_pack_advanced(ShapesmithPanel, bpy.types.Panel):
    """What counts as moving, what makes a shape important, and which conflicts keep shapes apart."""

    bl_label = "Advanced"
    bl_parent_id = "SHAPESMITH_PT_pack"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        return context.active_object is not None and context.active_object.type == "MESH"

    def draw(self, context):
        settings = context.active_object.shapesmith.pack
        layout = self.layout
        col = layout.column(align=True)
        col.prop(settings, "mu")
        col.prop(settings, "a")
        col.prop(settings, "beta")
        layout.prop(settings, "antagonist_cosine")
        col = layout.column(align=True)
        row = col.row(align=True)
        row.prop(settings, "collision_conflicts")
        sub = row.row(align=True)
        sub.active = settings.collision_conflicts
        sub.prop(settings, "collision_tolerance", text="Tolerance")
        row = col.row(align=True)
        row.prop(settings, "occlusion_conflicts")
        sub = row.row(align=True)
        sub.active = settings.occlusion_conflicts
        sub.prop(settings, "occlusion_keep", text="Keep")
        layout.prop(settings, "front_camera")
        layout.label(text=f"Front: {_front_text(settings)}", icon="VIEW_CAMERA")
        layout.prop(settings, "fewest")


register, unregister = bpy.utils.register_classes_factory(
    (
        SHAPESMITH_UL_expressions,
        SHAPESMITH_UL_shape_names,
        SHAPESMITH_PT_pack,
        SHAPESMITH_PT_pack_refine,
        SHAPESMITH_PT_pack_advanced,
    )
)
