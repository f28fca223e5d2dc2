"""Save Curve: the predicted reconstruction error per added landmark as a PNG, to pick M."""

import bpy
from bpy_extras.io_utils import ExportHelper

from ..blender.landmark_curve import write_curve_png
from ..blender.landmarks import stored_document
from .base import expected_errors, poll_landmarks


class SHAPESMITH_OT_render_landmark_curve(bpy.types.Operator, ExportHelper):
    bl_idname = "shapesmith.render_landmark_curve"
    bl_label = "Save Curve"
    bl_description = (
        "Plot the predicted reconstruction error against the number of landmarks added after the cover, "
        "to a PNG (the .blend is not changed)"
    )
    bl_options = {"REGISTER"}

    filename_ext = ".png"
    filter_glob: bpy.props.StringProperty(default="*.png", options={"HIDDEN"})

    @classmethod
    def poll(cls, context):
        return poll_landmarks(cls, context)

    def execute(self, context):
        try:
            write_curve_png(stored_document(context.active_object), self.filepath)
        except (OSError, *expected_errors()) as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        self.report({"INFO"}, f"wrote {self.filepath}")
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_render_landmark_curve,))
