"""Export Landmarks: the layout as JSON (the full report) or CSV (one row per landmark)."""

import bpy
from bpy_extras.io_utils import ExportHelper

from ..blender.landmarks import stored_document, write_csv, write_json
from .base import expected_errors, poll_landmarks


class SHAPESMITH_OT_export_landmarks(bpy.types.Operator, ExportHelper):
    bl_idname = "shapesmith.export_landmarks"
    bl_label = "Export Landmarks"
    bl_description = "Write the landmark layout (vertex, position, covered shapes, visibility) to a file"
    bl_options = {"REGISTER"}

    filename_ext = ".json"
    filter_glob: bpy.props.StringProperty(default="*.json;*.csv", options={"HIDDEN"})
    file_format: bpy.props.EnumProperty(
        name="Format",
        items=(("JSON", "JSON", "The full report: landmarks, optimality, reconstruction error, parameters"),
               ("CSV", "CSV", "One row per landmark")),
        default="JSON",
    )

    def check(self, context):
        # Keep the file name's extension in step with the chosen format.
        self.filename_ext = "." + self.file_format.lower()
        return super().check(context)

    @classmethod
    def poll(cls, context):
        return poll_landmarks(cls, context)

    def execute(self, context):
        obj = context.active_object
        try:
            document = stored_document(obj)
            (write_csv if self.file_format == "CSV" else write_json)(self.filepath, document)
        except (OSError, *expected_errors()) as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        self.report({"INFO"}, f"wrote {len(document['landmarks'])} landmarks to {self.filepath}")
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_export_landmarks,))
