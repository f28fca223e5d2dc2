"""Render Landmarks: a front-view PNG of the head with its landmarks drawn."""

import bpy
from bpy_extras.io_utils import ExportHelper

from ..blender.landmark_picture import render_landmarks
from .base import expected_errors, poll_landmarks


class SHAPESMITH_OT_render_landmarks(bpy.types.Operator, ExportHelper):
    bl_idname = "shapesmith.render_landmarks"
    bl_label = "Render Picture"
    bl_description = "Render the head from the front with its landmarks drawn, to a PNG (the .blend is not changed)"
    bl_options = {"REGISTER"}

    filename_ext = ".png"
    filter_glob: bpy.props.StringProperty(default="*.png", options={"HIDDEN"})
    resolution: bpy.props.IntProperty(name="Resolution", default=768, min=64, max=4096)

    @classmethod
    def poll(cls, context):
        return poll_landmarks(cls, context)

    def execute(self, context):
        try:
            render_landmarks(context.active_object, self.filepath, self.resolution)
        except (OSError, *expected_errors()) as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        self.report({"INFO"}, f"wrote {self.filepath}")
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_render_landmarks,))
