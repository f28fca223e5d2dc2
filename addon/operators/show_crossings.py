"""Show Crossings: poses the active mesh at one shape key (alone) and selects the faces that
pass through another part of the mesh there and did not at rest, so a rigger goes straight to
what the transfer report lists as still crossing."""

import bpy

from ..blender.crossings import show_crossings
from .base import expected_errors, poll_mesh


class SHAPESMITH_OT_show_crossings(bpy.types.Operator):
    bl_idname = "shapesmith.show_crossings"
    bl_label = "Show Crossings"
    bl_description = (
        "Show this shape key alone and select the faces that pass through lips, teeth, eyes or lashes "
        "in it (and did not at rest): Tab into Edit Mode to see and fix them"
    )
    bl_options = {"REGISTER", "UNDO"}

    shape: bpy.props.StringProperty(name="Shape Key", description="The shape key to examine")

    @classmethod
    def poll(cls, context):
        return poll_mesh(cls, context)

    def execute(self, context):
        obj = context.active_object
        try:
            count = show_crossings(obj, self.shape)
        except expected_errors() as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        if count:
            self.report({"INFO"}, f"'{self.shape}': {count} faces pass through the mesh (selected)")
        else:
            self.report({"INFO"}, f"'{self.shape}': no face passes through the mesh beyond the neutral's own crossings")
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_show_crossings,))
