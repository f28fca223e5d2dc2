"""Rig > Shape Key Names: the user's name table, read by Transfer, Wrap, Import Capture and
Analyze Rig's pairing beside the conventions they know (ARKit, _L/_R, .L/.R, L_ prefixes,
exporters' prefixes, Character Creator, Daz, Unified Expressions); the Rig panel's shipped
presets fill it with a common rig's names."""

import bpy

from .panels import ShapesmithPanel


class SHAPESMITH_UL_name_map(bpy.types.UIList):
    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index):
        row = layout.row(align=True)
        row.prop(item, "theirs", text="")
        row.label(text="", icon="FORWARD")
        row.prop(item, "standard", text="")


class SHAPESMITH_PT_names(ShapesmithPanel, bpy.types.Panel):
    bl_label = "Shape Key Names"
    bl_parent_id = "SHAPESMITH_PT_rig"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        settings = context.scene.shapesmith
        col = layout.column(align=True)
        col.label(text="Known: ARKit, _L/_R, .L/.R, L_, blendShape1.,")
        col.label(text="Character Creator, Daz, Unified Expressions")
        col.label(text="A common rig's table: Rig's preset icon")
        col.label(text="Yours (name -> the name it means):")
        row = layout.row()
        row.template_list("SHAPESMITH_UL_name_map", "name_map", settings, "name_map", settings, "active_name_row", rows=3)
        col = row.column(align=True)
        col.operator("shapesmith.add_name_row", icon="ADD", text="")
        col.operator("shapesmith.remove_name_row", icon="REMOVE", text="")


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_UL_name_map, SHAPESMITH_PT_names))
