"""The Performance panel: drive the rig from tracked landmarks (trajectories or a Movie Clip)
or from an ARKit capture; the source and its file, then Solve or Import Capture, then the
settings."""

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
            layout.operator("shapesmith.import_capture", icon="IMPORT")
            layout.prop(settings, "mapping")
            row = layout.row(align=True)
            row.prop(settings, "capture_fps")
            row.prop(settings, "capture_head")
            if settings.capture_head:
                layout.row(align=True).prop(settings, "capture_head_invert")
        else:
            if settings.source == "TRAJECTORIES":
                layout.prop(settings, "trajectories")
            else:
                layout.prop(settings, "clip")
            self.draw_solve_button(layout)
            if settings.source == "TRAJECTORIES":
                layout.prop(settings, "scale")
                layout.prop(settings, "solve_scale")
            else:
                layout.prop(settings, "camera")
            layout.prop(settings, "landmarks")
            layout.prop(settings, "smoothing")
            layout.prop(settings, "target")
        if settings.done:
            box = layout.box().column(align=True)
            for line in settings.summary.splitlines():
                box.label(text=line)
            if settings.document:
                layout.prop(settings, "plot_shapes")
                layout.operator("shapesmith.save_performance_report", icon="GRAPH")

    @staticmethod
    def draw_solve_button(layout):
        """Solve, or the running solve's progress with its Cancel."""
        job = performance_job.current()
        if job is None:
            layout.operator("shapesmith.solve_performance", icon="PLAY")
            return
        row = layout.row(align=True)
        text = "Cancelling" if job.cancelling else f"Solving {100 * job.fraction:.0f}%"
        row.progress(factor=job.fraction, type="BAR", text=text)
        row.operator("shapesmith.cancel_performance_solve", text="", icon="CANCEL")


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_PT_performance,))
