"""Save Report: the last solve's JSON, and beside it (same name, .png) the plot of the
per-frame residual and the chosen shapes' weights."""

import json
import os

import bpy
from bpy_extras.io_utils import ExportHelper

from ..blender.performance import write_json
from ..blender.performance_plot import write_plot_png


class SHAPESMITH_OT_save_performance_report(bpy.types.Operator, ExportHelper):
    bl_idname = "shapesmith.save_performance_report"
    bl_label = "Save Report"
    bl_description = "Write the last solve's report (JSON) and its plot (PNG beside it)"
    filename_ext = ".json"

    @classmethod
    def poll(cls, context):
        if not context.scene.shapesmith_performance.document:
            cls.poll_message_set("Solve a performance first")
            return False
        return True

    def execute(self, context):
        settings = context.scene.shapesmith_performance
        document = json.loads(settings.document)
        write_json(self.filepath, document)
        shapes = [s.strip() for s in settings.plot_shapes.split(",") if s.strip()] or None
        plot = os.path.splitext(self.filepath)[0] + ".png"
        write_plot_png(document, plot, shapes)
        self.report({"INFO"}, f"wrote {self.filepath} and {plot}")
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_save_performance_report,))
