"""What a rigger does with packed expressions on the rig itself: preview one, keyframe all of
them for a scanning session, or bake each into a `REF_01`-style shape key."""

import bpy

from ..blender.packing import animate_expressions, bake_expressions, preview_expression
from .base import expected_errors, poll_packed


class SHAPESMITH_OT_preview_expression(bpy.types.Operator):
    bl_idname = "shapesmith.preview_expression"
    bl_label = "Preview"
    bl_description = "Pose the selected expression: its shape keys at 1, all others at 0"
    bl_options = {"REGISTER", "UNDO"}

    index: bpy.props.IntProperty(name="Expression", description="0-based; -1: the one selected in the list", default=-1)

    @classmethod
    def poll(cls, context):
        return poll_packed(cls, context)

    def execute(self, context):
        obj = context.active_object
        index = obj.shapesmith.pack.active_expression if self.index < 0 else self.index
        try:
            preview_expression(obj, index)
        except expected_errors() as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        return {"FINISHED"}


class SHAPESMITH_OT_animate_expressions(bpy.types.Operator):
    bl_idname = "shapesmith.animate_expressions"
    bl_label = "Animate"
    bl_description = "Keyframe one expression per frame from frame 1, for a scanning session"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return poll_packed(cls, context)

    def execute(self, context):
        try:
            count = animate_expressions(context.active_object, context.scene)
        except expected_errors() as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        self.report({"INFO"}, f"expressions keyframed on frames 1 to {count}")
        return {"FINISHED"}


class SHAPESMITH_OT_bake_expressions(bpy.types.Operator):
    bl_idname = "shapesmith.bake_expressions"
    bl_label = "Bake"
    bl_description = "Write each expression as a shape key REF_01, REF_02, ... (replacing an earlier bake)"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return poll_packed(cls, context)

    def execute(self, context):
        try:
            names = bake_expressions(context.active_object)
        except expected_errors() as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        self.report({"INFO"}, f"baked {len(names)} shape keys ({names[0]} to {names[-1]})" if names else "nothing to bake")
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory(
    (
        SHAPESMITH_OT_preview_expression,
        SHAPESMITH_OT_animate_expressions,
        SHAPESMITH_OT_bake_expressions,
    )
)
