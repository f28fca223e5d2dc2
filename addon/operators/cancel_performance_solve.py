"""Cancel: stops the running Solve Performance (the panel's button; Esc does the same while
the pointer is over Blender). Nothing is keyed; the solve's operator ends at its next step."""

import bpy

from ..blender import performance_job


class SHAPESMITH_OT_cancel_performance_solve(bpy.types.Operator):
    bl_idname = "shapesmith.cancel_performance_solve"
    bl_label = "Cancel"
    bl_description = "Stop the running solve; nothing is keyed and the file stays as it was"
    bl_options = {"INTERNAL"}

    @classmethod
    def poll(cls, context):
        job = performance_job.current()
        if job is None or job.cancelling:
            cls.poll_message_set("No solve is running")
            return False
        return True

    def execute(self, context):
        performance_job.current().cancel()
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_cancel_performance_solve,))
