"""Propose Pairs: the character's point pairs filled from the same features found on both
heads (eye and mouth corners, nose tip, chin), for the rigger to review and move
instead of clicking each."""

import bpy

from ..blender.wrap import propose_pairs, refresh_markers, store_proposed_pairs
from .base import expected_errors, poll_character, progress_cursor


class SHAPESMITH_OT_propose_point_pairs(bpy.types.Operator):
    bl_idname = "shapesmith.propose_point_pairs"
    bl_label = "Propose Pairs"
    bl_description = (
        "Replace the point pairs with ones found on both heads: eye and mouth corners, "
        "nose tip and chin (the template's from its keys and shape, the character's from its shape)"
    )
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return poll_character(cls, context)

    def execute(self, context):
        character = context.active_object
        template = context.scene.shapesmith.transfer.source
        try:
            with progress_cursor(context) as progress:
                proposal = propose_pairs(template, character, progress=progress)
            count = store_proposed_pairs(character, template, proposal)
        except expected_errors() as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        refresh_markers(character, template)
        for warning in proposal["warnings"]:
            self.report({"WARNING"}, warning)
        self.report({"INFO"}, f"{count} point pairs proposed: check them (Show Markers) and move any that are off")
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_propose_point_pairs,))
