"""Add and remove rows of the user's name table (Rig > Shape Key Names)."""

import bpy


class SHAPESMITH_OT_add_name_row(bpy.types.Operator):
    bl_idname = "shapesmith.add_name_row"
    bl_label = "Add Name"
    bl_description = "Add a row: a name as your rig or capture spells it, and the name it stands for"
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        settings = context.scene.shapesmith
        settings.name_map.add()
        settings.active_name_row = len(settings.name_map) - 1
        return {"FINISHED"}


class SHAPESMITH_OT_remove_name_row(bpy.types.Operator):
    bl_idname = "shapesmith.remove_name_row"
    bl_label = "Remove Name"
    bl_description = "Remove the selected row of the name table"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        settings = context.scene.shapesmith
        return 0 <= settings.active_name_row < len(settings.name_map)

    def execute(self, context):
        settings = context.scene.shapesmith
        settings.name_map.remove(settings.active_name_row)
        settings.active_name_row = min(settings.active_name_row, len(settings.name_map) - 1)
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_add_name_row, SHAPESMITH_OT_remove_name_row))
