"""Files for the capture session: the shot list (JSON and CSV side by side) and the rendered
reference sheet (PNG) an actor is shown."""

import os

import bpy
from bpy_extras.io_utils import ExportHelper

from ..blender.packing import stored_report, write_shot_list_csv, write_shot_list_json
from ..blender.reference_sheet import render_reference_sheet
from .base import expected_errors, poll_packed


class SHAPESMITH_OT_export_shot_list(bpy.types.Operator, ExportHelper):
    bl_idname = "shapesmith.export_shot_list"
    bl_label = "Export Shot List"
    bl_description = (
        "Write the packed expressions as JSON and, beside it, as a CSV shot list (with Explain, also every pair "
        "of shapes kept apart and why)"
    )
    bl_options = {"REGISTER"}

    filename_ext = ".json"
    filter_glob: bpy.props.StringProperty(default="*.json", options={"HIDDEN"})

    @classmethod
    def poll(cls, context):
        return poll_packed(cls, context)

    def execute(self, context):
        csv_path = os.path.splitext(self.filepath)[0] + ".csv"
        try:
            report = stored_report(context.active_object)
            write_shot_list_json(self.filepath, report)
            write_shot_list_csv(csv_path, report, explain=context.active_object.shapesmith.pack.explain)
        except (OSError, *expected_errors()) as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        self.report({"INFO"}, f"wrote {self.filepath} and {csv_path}")
        return {"FINISHED"}


class SHAPESMITH_OT_render_reference_sheet(bpy.types.Operator, ExportHelper):
    bl_idname = "shapesmith.render_reference_sheet"
    bl_label = "Render Reference Sheet"
    bl_description = "Render one labelled front view per expression into one PNG, to show an actor what to pose"
    bl_options = {"REGISTER"}

    filename_ext = ".png"
    filter_glob: bpy.props.StringProperty(default="*.png", options={"HIDDEN"})
    tile_width: bpy.props.IntProperty(name="Tile Width", default=320, min=64, max=2048, subtype="PIXEL")
    tile_height: bpy.props.IntProperty(name="Tile Height", default=400, min=64, max=2048, subtype="PIXEL")

    @classmethod
    def poll(cls, context):
        return poll_packed(cls, context)

    def execute(self, context):
        try:
            width, height = render_reference_sheet(context.active_object, self.filepath, self.tile_width, self.tile_height)
        except (OSError, *expected_errors()) as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        self.report({"INFO"}, f"wrote {self.filepath} ({width} x {height})")
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory(
    (
        SHAPESMITH_OT_export_shot_list,
        SHAPESMITH_OT_render_reference_sheet,
    )
)
