"""Analyze Rig: counts, inert shapes, unmatched mirror vertices, symmetric pairs and
antagonists of the active mesh, stored on it for review."""

import bpy

from ..blender.analysis import analyze_object, store_analysis
from ..blender.names import scene_name_map
from ..blender.settings import analyze_settings
from .base import expected_errors, poll_mesh, progress_cursor


class SHAPESMITH_OT_analyze_rig(bpy.types.Operator):
    bl_idname = "shapesmith.analyze_rig"
    bl_label = "Analyze Rig"
    bl_description = "Check the active mesh's shape keys and find symmetric pairs and antagonists"
    bl_options = {"REGISTER", "UNDO"}

    reset_pairs: bpy.props.BoolProperty(
        name="Reset Pairs",
        description="Replace every pair, also those you added or edited (otherwise they are kept)",
        default=False,
    )

    @classmethod
    def poll(cls, context):
        return poll_mesh(cls, context)

    def execute(self, context):
        obj = context.active_object
        try:
            with progress_cursor(context, "Analyze Rig"):
                report = analyze_object(obj, analyze_settings(context.scene), name_map=scene_name_map(context.scene))
        except expected_errors() as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        store_analysis(obj, report, keep_edited=not self.reset_pairs)
        for warning in report["warnings"]:
            self.report({"WARNING"}, warning)
        self.report(
            {"INFO"},
            f"{report['shapes']} shapes: {len(report['symmetric_pairs'])} pairs, "
            f"{len(report['antagonists'])} antagonists, {len(report['inert'])} inert, "
            f"{report['seam_vertices']} seam vertices welded into {report['seam_groups']} points",
        )
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_analyze_rig,))
