"""Solve Performance: the head's pose and shape weights per frame from tracked landmarks
(trajectories file or Movie Clip), keyed on the shape keys and the head's transform. In the
UI the solve runs on a worker thread (`blender.performance_job`) and can be cancelled; in
background mode (batch, tests) it blocks."""

import json

import bpy

from ..blender import performance, performance_job
from ..blender.settings import performance_settings
from .base import expected_errors, poll_mesh, progress_cursor

# How often the timer steps a running solve (its progress, Esc, the end).
TIMER_SECONDS = 0.1


def read_tracks(obj, settings, scene):
    """The panel's source as Tracks (raises MeshDataError on a missing file, clip or camera)."""
    names, vertices = performance.layout_landmarks(obj, settings.landmarks)
    if settings.source == "CLIP":
        if settings.clip is None:
            raise performance.MeshDataError("choose the movie clip whose tracks follow the landmarks")
        return performance.clip_tracks(settings.clip, names, vertices, settings.camera or scene.camera)
    path = bpy.path.abspath(settings.trajectories)
    if not settings.trajectories:
        raise performance.MeshDataError("choose the trajectories file (CSV or TRC)")
    return performance.read_trajectories(path, names, vertices, scene.frame_start, settings.scale)


class SHAPESMITH_OT_solve_performance(bpy.types.Operator):
    bl_idname = "shapesmith.solve_performance"
    bl_label = "Solve"
    bl_description = (
        "Solve the head's pose and the shape-key weights of every frame from the tracked landmarks, and key them "
        "(one key per frame on each shape key and on the head's transform). Runs in the background with its "
        "progress in the panel and the status bar; Esc or Cancel stops it and keys nothing"
    )
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        if performance_job.current() is not None:
            cls.poll_message_set("A solve is running: wait for it or cancel it")
            return False
        return poll_mesh(cls, context)

    def execute(self, context):
        """The blocking solve (background mode, scripts, redo): keys the result when done."""
        obj = context.active_object
        scene = context.scene
        settings = scene.shapesmith_performance
        try:
            tracks = read_tracks(obj, settings, scene)
            with progress_cursor(context, "Solve Performance") as progress:
                document = performance.solve(obj, tracks, performance_settings(settings), progress=progress)
        except expected_errors() as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        performance.write_animation(obj, document, settings.target)
        return self.finish(settings, document)

    def invoke(self, context, event):
        """In the UI: the solve on a worker thread, stepped by a timer (modal operators and
        timers never run in background mode, so there the blocking solve runs)."""
        if bpy.app.background or context.window is None:
            return self.execute(context)
        obj = context.active_object
        scene = context.scene
        settings = scene.shapesmith_performance
        try:
            tracks = read_tracks(obj, settings, scene)
            self._job = performance_job.SolveJob(obj, tracks, performance_settings(settings), target=settings.target)
        except expected_errors() as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        window_manager = context.window_manager
        self._timer = window_manager.event_timer_add(TIMER_SECONDS, window=context.window)
        window_manager.modal_handler_add(self)
        self._show(context)
        return {"RUNNING_MODAL"}

    def modal(self, context, event):
        job = self._job
        if event.type == "ESC" and event.value == "PRESS":
            job.cancel()
        elif event.type != "TIMER":
            # The rest of Blender stays usable while the solve runs.
            return {"PASS_THROUGH"}
        if job.step():
            self._show(context)
            return {"RUNNING_MODAL"}
        self._end(context)
        if job.state == "cancelled":
            self.report({"INFO"}, "Solve cancelled: nothing was keyed")
            return {"CANCELLED"}
        if job.state == "failed":
            if not isinstance(job.error, expected_errors()):
                raise job.error
            self.report({"ERROR"}, str(job.error))
            return {"CANCELLED"}
        return self.finish(context.scene.shapesmith_performance, job.document)

    def cancel(self, context):
        """Blender ends the operator (a file is loaded, the window closes): stop the solve, and
        let the native call return before Blender goes on (it may be quitting)."""
        self._job.cancel()
        self._job.wait(1.0)
        self._end(context)

    def _show(self, context):
        job = self._job
        text = "cancelling" if job.cancelling else f"{100 * job.fraction:.0f}% (Esc to cancel)"
        context.workspace.status_text_set(f"Solve Performance: {text}")
        for area in context.screen.areas:
            if area.type == "VIEW_3D":
                area.tag_redraw()

    def _end(self, context):
        """Removes the timer and the status text (the window may be gone when Blender ends
        the operator)."""
        context.window_manager.event_timer_remove(self._timer)
        if context.workspace is not None:
            context.workspace.status_text_set(None)
        for area in context.screen.areas if context.screen is not None else ():
            if area.type == "VIEW_3D":
                area.tag_redraw()

    def finish(self, settings, document):
        lines = performance.summary_lines(document)
        settings.done = True
        settings.summary = "\n".join(lines)
        settings.document = json.dumps(document)
        for warning in document["warnings"]:
            self.report({"WARNING"}, warning)
        self.report({"INFO"}, "; ".join(lines[:2]))
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_solve_performance,))
