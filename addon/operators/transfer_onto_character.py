"""Transfer onto Character: the template's keys transferred onto the wrapped template (same
topology, with the Transfer panel's options) and carried onto the character's own vertices,
solved in full before anything is written."""

import bpy

from ..blender.settings import transfer_settings
from ..blender.looks import store_looks
from ..blender.names import scene_name_map, text_name_map
from ..blender.shape_keys import write_transferred_keys
from ..blender.transfer import store_transfer, worse_than_template
from ..blender.wrap import carry_onto_character, store_symmetry
from .base import poll_mesh
from .job_operator import JobOperator


def transfer_onto(progress, character, template, wrapped_object, settings, name_map, driver_map):
    """Solves the transfer and the carry in full, then writes the keys (nothing before)."""
    result = carry_onto_character(template, character, wrapped_object, transfer_settings(settings), progress=progress)
    written, skipped, warnings = write_transferred_keys(
        result, overwrite=settings.overwrite, copy_drivers=settings.copy_drivers,
        keep_sculpted=settings.keep_sculpted, name_map=name_map, driver_map=driver_map,
    )
    return result, written, skipped, warnings


class SHAPESMITH_OT_transfer_onto_character(JobOperator, bpy.types.Operator):
    bl_idname = "shapesmith.transfer_onto_character"
    bl_label = "Transfer onto Character"
    bl_description = (
        "Transfer the template's shape keys onto the wrapped template, then carry them onto the active "
        "character's own vertices (any topology). Esc or Cancel stops it"
    )
    label = "Transfer onto Character"
    run = staticmethod(transfer_onto)
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        if not poll_mesh(cls, context):
            return False
        settings = context.active_object.shapesmith_wrap
        template = context.scene.shapesmith.transfer.source
        if template is None:
            cls.poll_message_set("Pick the template in the Transfer panel")
            return False
        if settings.stage != "WRAP" or settings.wrapped is None or settings.template != template.name:
            cls.poll_message_set("Wrap the template onto this character first")
            return False
        return True

    def arguments(self, context):
        settings = context.scene.shapesmith.transfer
        character = context.active_object
        return {
            "character": character, "template": settings.source, "wrapped_object": character.shapesmith_wrap.wrapped,
            "settings": settings, "name_map": scene_name_map(context.scene), "driver_map": text_name_map(settings.driver_map),
        }

    def finished(self, context, value):
        result, written, skipped, warnings = value
        character = result.target
        character.shapesmith_wrap.written = len(written)
        store_symmetry(character, result.report["symmetry"])
        store_looks(character, result.report["looks"])
        # The per-shape penetration on the character, listed by the Transfer panel with it active.
        store_transfer(result, written, skipped)
        for warning in result.warnings + warnings:
            self.report({"WARNING"}, warning)
        seconds = result.report["stage_seconds"]
        worse = worse_than_template(result.report)
        self.report(
            {"INFO"},
            f"{len(written)} shape keys written onto '{character.name}'"
            + (f", {len(skipped)} existing kept" if skipped else "")
            + f" (transfer {seconds['transfer']:.2f} s, carry {seconds['carry']:.2f} s); "
            + f"{len(worse)} add more intersection than on the template (Transfer panel lists them); "
            + f"{sum(1 for line in character.shapesmith_wrap.looks.splitlines() if line.startswith('!'))} "
            + "look(s) to check (Wrap panel: eyes, mouth, smooth keys)",
        )
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_transfer_onto_character,))
