"""Long operators with progress and Cancel (`blender.jobs`): from the panel the work runs as a
threaded job stepped by a modal timer, with the bar in the status bar and Esc or the panel's
Cancel stopping it; in background Blender and from scripts (`execute`) it runs blocking, and
`jobs.cancel()` from another thread stops it the same way. Either way the operator's `run`
solves in full before it writes, so a cancelled job leaves the file as it was."""

import bpy

from ..blender import jobs
from .base import expected_errors, progress_cursor


class JobOperator:
    """Subclasses give `label`, `arguments(context)` (what `run` needs, read on the main
    thread), `run(progress, **arguments)` (the work, writing at its end) and
    `finished(context, value)` (reports; returns the operator's result)."""

    label = "Shapesmith"

    def arguments(self, context):
        return {}

    def execute(self, context):
        try:
            arguments = self.arguments(context)
            with progress_cursor(context, self.label) as progress:
                value = jobs.run_blocking(self.run, progress, **arguments)
        except jobs.JobCancelled:
            self.report({"WARNING"}, f"{self.label} cancelled: nothing was changed")
            return {"CANCELLED"}
        except expected_errors() as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        return self.finished(context, value)

    def invoke(self, context, event):
        if bpy.app.background or context.window is None:
            return self.execute(context)
        try:
            arguments = self.arguments(context)
            self._job = jobs.ThreadedJob(self.label, self.run, **arguments)
        except expected_errors() + (RuntimeError,) as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        window_manager = context.window_manager
        self._timer = window_manager.event_timer_add(0.05, window=context.window)
        window_manager.modal_handler_add(self)
        window_manager.progress_begin(0, 100)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        if event.type == "ESC":
            jobs.cancel()
            return {"RUNNING_MODAL"}
        if event.type != "TIMER":
            # Clicks reach the panel (its Cancel button); keys that would edit the scene do not.
            return {"PASS_THROUGH"} if event.type in {"LEFTMOUSE", "MOUSEMOVE", "WHEELUPMOUSE", "WHEELDOWNMOUSE"} else {"RUNNING_MODAL"}
        job = self._job
        running = job.step()
        window_manager = context.window_manager
        window_manager.progress_update(int(100 * job.fraction))
        workspace = getattr(context, "workspace", None)
        if workspace is not None:
            state = "cancelling" if jobs.cancelling() else f"{int(100 * job.fraction)}% (Esc cancels)"
            workspace.status_text_set(f"{self.label}: {state}")
        for area in context.screen.areas if context.screen else ():
            if area.type == "VIEW_3D":
                area.tag_redraw()
        if running:
            return {"RUNNING_MODAL"}
        window_manager.event_timer_remove(self._timer)
        window_manager.progress_end()
        if workspace is not None:
            workspace.status_text_set(None)
        if job.state == "cancelled":
            self.report({"WARNING"}, f"{self.label} cancelled: nothing was changed")
            return {"CANCELLED"}
        if job.state == "failed":
            if isinstance(job.error, expected_errors()):
                self.report({"ERROR"}, str(job.error))
                return {"CANCELLED"}
            raise job.error
        return self.finished(context, job.value)


class SHAPESMITH_OT_cancel_job(bpy.types.Operator):
    bl_idname = "shapesmith.cancel_job"
    bl_label = "Cancel"
    bl_description = "Stop the running Generate, Wrap or Transfer; nothing is written and the file stays as it was"
    bl_options = {"INTERNAL"}

    @classmethod
    def poll(cls, context):
        if jobs.current() is None or jobs.cancelling():
            cls.poll_message_set("Nothing is running")
            return False
        return True

    def execute(self, context):
        jobs.cancel()
        return {"FINISHED"}


def draw_running(layout):
    """The running job's progress and its Cancel button, when one runs (True)."""
    job = jobs.current()
    if job is None:
        return False
    row = layout.row(align=True)
    row.label(text=f"{job.label}: {int(100 * job.fraction)}%", icon="TIME")
    row.operator("shapesmith.cancel_job", icon="CANCEL")
    return True


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_cancel_job,))
