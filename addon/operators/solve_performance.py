"""Solve Performance: the head's pose and shape weights per frame from tracked landmarks
(trajectories file or Movie Clip), keyed on the shape keys and the head's transform."""

import json

import bpy

from ..blender import performance
from .base import expected_errors, poll_mesh, progress_cursor


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
        "(one key per frame on each shape key and on the head's transform)"
    )
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return poll_mesh(cls, context)

    def execute(self, context):
        obj = context.active_object
        scene = context.scene
        settings = scene.shapesmith_performance
        try:
            tracks = read_tracks(obj, settings, scene)
            with progress_cursor(context, "Solve Performance") as progress:
                document = performance.solve(obj, tracks, smoothing=settings.smoothing,
                                             solve_scale=settings.solve_scale, progress=progress)
        except expected_errors() as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        performance.write_animation(obj, document, settings.target)
        lines = performance.summary_lines(document)
        settings.done = True
        settings.summary = "\n".join(lines)
        settings.document = json.dumps(document)
        for warning in document["warnings"]:
            self.report({"WARNING"}, warning)
        self.report({"INFO"}, "; ".join(lines[:2]))
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_solve_performance,))
