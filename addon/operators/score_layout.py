"""Score Layout: how well a vertex group you already track reconstructs the rig's poses
(the measure Place Landmarks reports for its own layout)."""

import bpy

from ..blender.landmarks import score_group, store_score
from ..blender.mesh_arrays import MeshDataError
from .base import expected_errors, poll_mesh, progress_cursor


class SHAPESMITH_OT_score_layout(bpy.types.Operator):
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

    def execute(self, context):
        obj = context.active_object
        group = self.group or context.scene.shapesmith.landmarks.score_group
        try:
            if not group:
                raise MeshDataError("choose the vertex group to score")
            with progress_cursor(context, "Score Layout") as progress:
                score = score_group(obj, group, progress=progress)
        except expected_errors() as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        store_score(obj, score)
        self.report(
            {"INFO"},
            f"'{group}' ({score['landmarks']} vertices): error mean {score['mean']:.2%}, "
            f"max {score['max']:.2%} of the head's diagonal over {score['poses']} poses",
        )
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_score_layout,))
