"""Place Landmarks: the fewest tracked vertices that catch every shape key with a strongly
moving, visible landmark; built as empties on the vertices, replacing the previous layout."""

import bpy

from .. import preferences
from ..blender.landmarks import (
    build_layout,
    camera_positions,
    comparison_group,
    comparison_line,
    place_landmarks,
)
from ..blender.settings import landmark_settings
from .base import poll_mesh
from .job_operator import JobOperator


def place_and_build(progress, obj, settings, cameras, compare_group, scene):
    """Places the landmarks in full, then builds the layout (nothing before)."""
    document = place_landmarks(obj, settings, cameras=cameras, progress=progress, compare_group=compare_group)
    build_layout(obj, document, scene)
    return obj, document


class SHAPESMITH_OT_place_landmarks(JobOperator, bpy.types.Operator):
    bl_idname = "shapesmith.place_landmarks"
    bl_label = "Place Landmarks"
    bl_description = (
        "Choose the fewest vertices that move strongly and stay visible in every shape key, and mark "
        "each with an empty parented to its vertex (replaces the previous layout)"
    )
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return poll_mesh(cls, context)

    label = "Place Landmarks"
    run = staticmethod(place_and_build)

    def arguments(self, context):
        obj = context.active_object
        scene = context.scene
        settings = scene.shapesmith.landmarks
        prefs = preferences.get(context)
        tool = landmark_settings(settings, axis=int(scene.shapesmith.symmetry_axis))
        tool.time_limit = prefs.solver_time_limit if prefs and prefs.solver_time_limit > 0 else None
        return {
            "obj": obj, "settings": tool, "cameras": camera_positions(obj, settings.camera_source, scene, settings.camera_collection),
            "compare_group": comparison_group(obj, settings.score_group), "scene": scene,
        }

    def finished(self, context, value):
        obj, document = value
        for warning in document["warnings"]:
            self.report({"WARNING"}, warning)
        if document["uncovered"]:
            self.report({"WARNING"}, f"no landmark candidate for: {', '.join(document['uncovered'])}")
        rec = document["reconstruction"]
        self.report(
            {"INFO"},
            f"{len(document['landmarks'])} landmarks ({'optimal' if document['optimal'] else 'not proven optimal'} cover"
            f"{', %d added for reconstruction' % obj.shapesmith.landmarks.added if document['design_stop'] else ''}); "
            f"reconstruction error mean {rec['mean']:.2%}, max {rec['max']:.2%} of the head's diagonal, "
            f"predicted {document['predicted_error']:.2%}",
        )
        if document.get("comparison"):
            self.report({"INFO"}, comparison_line(document))
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_place_landmarks,))
