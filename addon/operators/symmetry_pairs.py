"""Add and remove symmetric shape pairs by hand (the analysis only proposes them)."""

import bpy


class SHAPESMITH_OT_add_pair(bpy.types.Operator):
    bl_idname = "shapesmith.add_pair"
    bl_label = "Add Pair"
    bl_description = "Add a symmetric pair to fill in with two shape keys"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return context.active_object is not None and context.active_object.type == "MESH"

    def execute(self, context):
        props = context.active_object.shapesmith
        props.pairs.add().source = "USER"
        props.active_pair = len(props.pairs) - 1
        return {"FINISHED"}


class SHAPESMITH_OT_remove_pair(bpy.types.Operator):
    bl_idname = "shapesmith.remove_pair"
    bl_label = "Remove Pair"
    bl_description = "Remove the selected symmetric pair"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        return obj is not None and obj.type == "MESH" and 0 <= obj.shapesmith.active_pair < len(obj.shapesmith.pairs)

    def execute(self, context):
        props = context.active_object.shapesmith
        props.pairs.remove(props.active_pair)
        props.active_pair = min(props.active_pair, len(props.pairs) - 1)
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_add_pair, SHAPESMITH_OT_remove_pair))
