"""The Performance panel: drive the rig from tracked landmarks (trajectories or a Movie Clip)
or from an ARKit capture."""

import bpy

from ..blender import performance_job
from .panels import ShapesmithPanel


class SHAPESMITH_PT_performance(ShapesmithPanel, bpy.types.Panel):
    bl_label = "Performance"
    bl_order = 5
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        layout = self.layout
        settings = context.scene.shapesmith_performance
        layout.prop(settings, "source", expand=True)
        if settings.source == "CAPTURE":
            layout.prop(settings, "capture")
            layout.prop(settings, "mapping")
            row = layout.row(align=True)
            row.prop(settings, "capture_fps")
            row.prop(settings, "capture_head")
            if settings.capture_head:
                layout.row(align=True).prop(settings, "capture_head_invert")
            layout.operator("shapesmith.import_capture", icon="IMPORT")
        else:
            if settings.source == "TRAJECTORIES":
                layout.prop(settings, "trajectories")
                layout.prop(settings, "scale")
                layout.prop(settings, "solve_scale")
            else:
                layout.prop(settings, "clip")
                layout.prop(settings, "camera")
            layout.prop(settings, "landmarks")
            layout.prop(settings, "smoothing")
            layout.prop(settings, "target")
            job = performance_job.current()
            if job is None:
                layout.operator("shapesmith.solve_performance", icon="PLAY")
            else:
                row = layout.row(align=True)
                text = "Cancelling" if job.cancelling else f"Solving {100 * job.fraction:.0f}%"
                row.progress(factor=job.fraction, type="BAR", text=text)
                row.operator("shapesmith.cancel_performance_solve", text="", icon="CANCEL")
        if settings.done:
            box = layout.box().column(align=True)
            for line in settings.summary.splitlines():
                box.label(text=line)
            if settings.document:
                layout.prop(settings, "plot_shapes")
                layout.operator("shapesmith.save_performance_report", icon="GRAPH")


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_PT_performance,))
