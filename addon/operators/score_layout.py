"""Score Layout: how well a vertex group you already track reconstructs the rig's poses
(the measure Place Landmarks reports for its own layout)."""

import bpy

from ..blender.landmarks import score_group, store_score
from ..blender.mesh_arrays import MeshDataError
from .base import poll_mesh
from .job_operator import JobOperator


def score_and_store(progress, obj, group):
    """Scores in full, then stores the score (nothing before)."""
    score = score_group(obj, group, progress=progress)
    store_score(obj, score)
    return group, score


class SHAPESMITH_OT_score_layout(JobOperator, bpy.types.Operator):
    bl_idname = "shapesmith.score_layout"
    bl_label = "Score Layout"
    bl_description = (
        "Reconstruct every shape key, and random mixes, from noisy positions of the group's vertices; "
        "report the mean and largest error relative to the head's diagonal"
    )
    bl_options = {"REGISTER", "UNDO"}

    group: bpy.props.StringProperty(name="Vertex Group", description="Defaults to the Landmarks panel's choice")

    @classmethod
    def poll(cls, context):
        if not poll_mesh(cls, context):
            return False
        if not context.active_object.vertex_groups:
            cls.poll_message_set("The mesh has no vertex groups: put the vertices you track in one")
            return False
        return True

    label = "Score Layout"
    run = staticmethod(score_and_store)

    def arguments(self, context):
        group = self.group or context.scene.shapesmith.landmarks.score_group
        if not group:
            raise MeshDataError("choose the vertex group to score")
        return {"obj": context.active_object, "group": group}

    def finished(self, context, value):
        group, score = value
        self.report(
            {"INFO"},
            f"'{group}' ({score['landmarks']} vertices): error mean {score['mean']:.2%}, "
            f"max {score['max']:.2%} of the head's diagonal over {score['poses']} poses",
        )
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_score_layout,))
