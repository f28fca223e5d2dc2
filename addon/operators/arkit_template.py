"""Add ARKit Template (the bundled CC0 MakeHuman head with its 52 ARKit keys and face parts)
and Generate ARKit Keys (the whole wrap chain on the selected character in one click)."""

import bpy

from ..blender import bundled_template
from ..blender.generate import generate_keys, report_lines
from ..blender.settings import transfer_settings
from .base import poll_mesh
from .job_operator import JobOperator


class SHAPESMITH_OT_add_arkit_template(bpy.types.Operator):
    bl_idname = "shapesmith.add_arkit_template"
    bl_label = "Add ARKit Template"
    bl_description = (
        "Add the bundled ARKit template at the 3D cursor: the MakeHuman head (CC0) with the 52 ARKit shape keys "
        "and its eyes, teeth, tongue and lashes as face parts, picked as the Transfer panel's template"
    )
    bl_options = {"REGISTER", "UNDO"}

    def execute(self, context):
        try:
            head = bundled_template.add_template(context.scene, tuple(context.scene.cursor.location))
        except (bundled_template.MeshDataError, OSError) as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        context.scene.shapesmith.transfer.source = head
        self.report({"INFO"}, f"added '{head.name}' ({len(head.data.shape_keys.key_blocks) - 1} keys): {head[bundled_template.PROPERTY]}")
        return {"FINISHED"}


def generate(progress, character, template, region, settings, keep_sculpted, location):
    return generate_keys(character, template, region=region, transfer_settings=settings, keep_sculpted=keep_sculpted,
                         progress=progress, location=location)


class SHAPESMITH_OT_generate_arkit_keys(JobOperator, bpy.types.Operator):
    bl_idname = "shapesmith.generate_arkit_keys"
    bl_label = "Generate ARKit Keys"
    bl_description = (
        "Write the 52 ARKit shape keys onto the selected character in one step: point pairs proposed (or the "
        "stored ones), the template (the picked one, else the bundled one) wrapped, its keys transferred and "
        "carried. A full body gets keys on its head only (the Head Region group, else found above the neck). "
        "Esc or Cancel stops it"
    )
    bl_options = {"REGISTER", "UNDO"}
    label = "Generate ARKit Keys"
    run = staticmethod(generate)

    @classmethod
    def poll(cls, context):
        if not poll_mesh(cls, context):
            return False
        if context.active_object == context.scene.shapesmith.transfer.source:
            cls.poll_message_set("Select the character, not the template")
            return False
        return True

    def arguments(self, context):
        settings = context.scene.shapesmith.transfer
        character = context.active_object
        return {
            "character": character, "template": settings.source, "region": character.shapesmith_wrap.region or None,
            "settings": transfer_settings(settings), "keep_sculpted": settings.keep_sculpted,
            "location": tuple(context.scene.cursor.location),
        }

    def finished(self, context, generated):
        if generated.template_added:
            context.scene.shapesmith.transfer.source = generated.template
        for warning in generated.warnings:
            self.report({"WARNING"}, warning)
        for line in report_lines(generated):
            self.report({"INFO"}, line)
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_add_arkit_template, SHAPESMITH_OT_generate_arkit_keys))
