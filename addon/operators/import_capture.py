"""Import Capture: an ARKit capture (Live Link Face CSV, Face Cap TXT) keyed onto the active
head's shape keys by name, and its head rotation onto the object."""

import bpy

from ..blender import capture
from ..blender.names import scene_name_map
from .base import expected_errors, poll_mesh


class SHAPESMITH_OT_import_capture(bpy.types.Operator):
    bl_idname = "shapesmith.import_capture"
    bl_label = "Import Capture"
    bl_description = (
        "Key an ARKit capture onto the shape keys of the same names (Left/Right and _L/_R alike; a shape the rig "
        "splits in halves drives both), one key per captured frame from the scene's start"
    )
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return poll_mesh(cls, context)

    def execute(self, context):
        obj = context.active_object
        settings = context.scene.shapesmith_performance
        try:
            if not settings.capture:
                raise capture.MeshDataError("choose the capture file (Live Link Face CSV or Face Cap TXT)")
            mapping = capture.read_mapping(settings.mapping.as_string()) if settings.mapping else None
            report = capture.import_capture(obj, bpy.path.abspath(settings.capture), context.scene, mapping,
                                            settings.capture_fps or None, settings.capture_head,
                                            set(settings.capture_head_invert), scene_name_map(context.scene))
        except expected_errors() as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        lines = [
            f"{report['frames']} frames of {report['format']} ({report['capture_fps']} fps) on frames "
            f"{report['first_frame']:g}-{report['last_frame']:g} at {report['scene_fps']:g} fps",
            f"{len(report['columns_used'])} columns used",
            f"unmatched columns: {', '.join(report['unmatched_columns']) or 'none'}",
            f"keys not driven: {', '.join(report['unmatched_keys']) or 'none'}",
            capture.lost_tracking_line(report),
        ]
        settings.done = True
        settings.summary = "\n".join(lines)
        settings.document = ""
        for warning in report["warnings"]:
            self.report({"WARNING"}, warning)
        self.report({"INFO"}, "; ".join(lines[:2]))
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_import_capture,))
