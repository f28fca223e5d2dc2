"""The Transfer panel: the template, Transfer first, then what a rerun keeps and which keys go;
the last transfer's result on the active mesh in the head's own units. Personalise and the
advanced settings (virtual edges, keeping surfaces apart) in sub-panels."""

import bpy

from ..operators.job_operator import draw_running
from .panels import ShapesmithPanel
from . import presets

# Where a shape's extra crossing lies (`blender.transfer.where_added`), in a rigger's words.
WHERE_WORDS = {"inside one piece": "lips or lids", "between pieces": "through eyes, teeth or lashes"}


def scene_length(context, value):
    """`value` (scene units) as the scene shows lengths: 3 mm, 0.12 in, or plain units."""
    unit = context.scene.unit_settings
    if unit.system == "NONE":
        return f"{value:.3g}"
    return bpy.utils.units.to_string(unit.system, "LENGTH", value * unit.scale_length, precision=2)


class SHAPESMITH_UL_key_choice(bpy.types.UIList):
    """The template's keys, each ticked to be transferred."""

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index):
        layout.prop(item, "chosen", text=item.name)


class SHAPESMITH_PT_transfer(ShapesmithPanel, bpy.types.Panel):
    bl_label = "Transfer"
    bl_order = 3
    bl_options = {"DEFAULT_CLOSED"}

    def draw_header_preset(self, context):
        presets.draw_header(self.layout, "transfer")

    def draw(self, context):
        layout = self.layout
        settings = context.scene.shapesmith.transfer
        layout.operator("shapesmith.transfer_shape_keys", icon="SHAPEKEY_DATA")
        draw_running(layout)
        layout.prop(settings, "source")
        obj = context.active_object
        if obj is not None and obj.type == "MESH":
            layout.label(text=f"Target: {obj.name}", icon="MESH_DATA")

        col = layout.column(align=True)
        col.prop(settings, "overwrite")
        sub = col.column(align=True)
        sub.active = settings.overwrite
        sub.prop(settings, "keep_sculpted")
        col.prop(settings, "copy_drivers")
        if settings.copy_drivers:
            col.prop(settings, "driver_map")
        self.draw_key_choice(layout, settings)

        if obj is None or obj.type != "MESH" or not obj.shapesmith.transfer.done:
            return
        self.draw_result(context, layout, obj.shapesmith.transfer)

    @staticmethod
    def draw_result(context, layout, result):
        box = layout.box()
        col = box.column(align=True)
        col.label(text=f"From '{result.source}': {result.written} keys written in {result.seconds:.2f} s")
        if result.skipped:
            col.label(text=f"Kept: {result.skipped}")
        col.label(text=f"Virtual edges: {result.virtual_edges}")
        if result.carried:
            col.label(text="Carried from the wrapped template (Wrap); judged on this mesh")
        if result.contact:
            before = f", {result.worse_before_contact} worse than the template before it" if result.worse_before_contact >= 0 else ""
            where = " on the wrapped template" if result.carried else ""
            col.label(text=f"Surfaces kept apart in {result.contact_resolved} shapes{where}{before}")
        if result.examples:
            col.label(text=f"Training expressions: {result.examples}")
        worse = [s for s in result.shapes if s.worse]
        if not worse:
            col.label(text="No shape passes through itself more than the template's: good", icon="CHECKMARK")
            return
        fix = "sculpt or re-run" if result.contact or result.carried else "Advanced > Keep Surfaces Apart takes them apart"
        col.label(text=f"Passing through more than the template's: {len(worse)} ({fix})", icon="ERROR")
        col.label(text="Crossing line beyond the template's, and where:")
        for shape in sorted(worse, key=lambda s: -s.added)[:12]:
            row = col.row(align=True)
            row.label(text=f"  {shape.name}: {scene_length(context, shape.added)}, {WHERE_WORDS.get(shape.where, shape.where)}")
            row.operator("shapesmith.show_crossings", text="", icon="RESTRICT_SELECT_OFF").shape = shape.name
        if len(worse) > 12:
            col.label(text=f"  ... and {len(worse) - 12} more (batch --json lists all)")

    @staticmethod
    def draw_key_choice(layout, settings):
        """Only Ticked Keys and the template's keys to tick."""
        row = layout.row(align=True)
        row.prop(settings, "only_ticked")
        row.operator("shapesmith.list_template_keys", text="", icon="FILE_REFRESH")
        if not settings.only_ticked:
            return
        layout.template_list("SHAPESMITH_UL_key_choice", "key_choice", settings, "key_choice", settings,
                             "active_key_choice", rows=4)
        row = layout.row(align=True)
        row.operator("shapesmith.list_template_keys", text="Tick All").tick = "ALL"
        row.operator("shapesmith.list_template_keys", text="Tick None").tick = "NONE"


class SHAPESMITH_PT_transfer_personalise(ShapesmithPanel, bpy.types.Panel):
    """Transfer fitted to scans of the actor (training expressions)."""

    bl_label = "Personalise"
    bl_parent_id = "SHAPESMITH_PT_transfer"
    bl_options = {"DEFAULT_CLOSED"}
    bl_order = 1

    def draw(self, context):
        layout = self.layout
        settings = context.scene.shapesmith.transfer
        layout.operator("shapesmith.personalise_shape_keys", icon="USER")
        layout.prop(settings, "training")
        row = layout.row(align=True)
        row.prop(settings, "beta_reg")
        row.prop(settings, "refine_weights", text="Refine")


class SHAPESMITH_PT_transfer_advanced(ShapesmithPanel, bpy.types.Panel):
    """Virtual edges (lips and lids held as the template holds them) and keeping surfaces apart."""

    bl_label = "Advanced"
    bl_parent_id = "SHAPESMITH_PT_transfer"
    bl_options = {"DEFAULT_CLOSED"}
    bl_order = 2

    def draw(self, context):
        layout = self.layout
        settings = context.scene.shapesmith.transfer
        col = layout.column(align=True)
        col.prop(settings, "virtual_edges")
        sub = col.column(align=True)
        sub.active = settings.virtual_edges
        sub.prop(settings, "tau_d")
        sub.prop(settings, "tau_r")
        sub.prop(settings, "edge_weight")
        sub.prop(settings, "compare_plain")
        layout.operator("shapesmith.preview_virtual_edges", icon="MOD_WIREFRAME")

        col = layout.column(align=True)
        col.prop(settings, "contact")
        sub = col.column(align=True)
        sub.active = settings.contact
        sub.prop(settings, "contact_distance")


register, unregister = bpy.utils.register_classes_factory(
    (SHAPESMITH_UL_key_choice, SHAPESMITH_PT_transfer, SHAPESMITH_PT_transfer_personalise, SHAPESMITH_PT_transfer_advanced)
)
