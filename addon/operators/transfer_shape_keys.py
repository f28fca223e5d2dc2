"""Transfer Shape Keys and Personalise: the template's keys onto the active mesh, solved in
full before anything is written, so an error or a Cancel (Esc, the panel's button) leaves the
target as it was (`job_operator.JobOperator`)."""

import bpy

from ..blender.names import scene_name_map, text_name_map
from ..blender.settings import transfer_settings
from ..blender.shape_keys import write_transferred_keys
from ..blender.transfer import store_transfer, transfer_object, worse_than_template
from .base import poll_mesh
from .job_operator import JobOperator


def ticked_keys(settings):
    """The keys ticked in the Transfer panel's list with Only Ticked Keys on, else None (all)."""
    if not settings.only_ticked:
        return None
    return [item.name for item in settings.key_choice if item.chosen]


def transfer_and_write(progress, source, target, settings, training_objects, name_map, driver_map):
    """Solves the transfer in full, then writes the keys (nothing before: a cancelled transfer
    changes nothing)."""
    transfer = transfer_object(
        source, target, transfer_settings(settings), training_objects=training_objects,
        keys=ticked_keys(settings), progress=progress,
    )
    written, skipped, warnings = write_transferred_keys(
        transfer, overwrite=settings.overwrite, copy_drivers=settings.copy_drivers,
        keep_sculpted=settings.keep_sculpted, name_map=name_map, driver_map=driver_map,
    )
    return transfer, written, skipped, warnings


class TransferOperator(JobOperator):
    bl_options = {"REGISTER", "UNDO"}
    run = staticmethod(transfer_and_write)

    @classmethod
    def poll(cls, context):
        if not poll_mesh(cls, context):
            return False
        if context.scene.shapesmith.transfer.source is None:
            cls.poll_message_set("Pick a template with shape keys")
            return False
        return True

    def training_objects(self, settings):
        return ()

    def arguments(self, context):
        settings = context.scene.shapesmith.transfer
        return {
            "source": settings.source, "target": context.active_object, "settings": settings,
            "training_objects": self.training_objects(settings), "name_map": scene_name_map(context.scene),
            "driver_map": text_name_map(settings.driver_map),
        }

    def finished(self, context, value):
        transfer, written, skipped, warnings = value
        target = transfer.target
        store_transfer(transfer, written, skipped)
        for warning in transfer.warnings + warnings:
            self.report({"WARNING"}, warning)
        if not written:
            self.report({"WARNING"}, f"every key already exists on '{target.name}': nothing written (tick Overwrite Existing Keys)")
        worse = worse_than_template(transfer.report)
        self.report(
            {"INFO"},
            f"{len(written)} shape keys written onto '{target.name}'"
            + (f", {len(skipped)} existing kept" if skipped else "")
            + f"; {transfer.report['virtual_edges']} virtual edges"
            + (f"; passing through more than the template's (the panel lists them): {', '.join(worse)}" if worse else ""),
        )
        return {"FINISHED"}


class SHAPESMITH_OT_transfer_shape_keys(TransferOperator, bpy.types.Operator):
    bl_idname = "shapesmith.transfer_shape_keys"
    bl_label = "Transfer"
    bl_description = "Transfer the template's shape keys onto the active mesh (same topology). Esc or Cancel stops it"
    label = "Transfer Shape Keys"


class SHAPESMITH_OT_personalise_shape_keys(TransferOperator, bpy.types.Operator):
    bl_idname = "shapesmith.personalise_shape_keys"
    bl_label = "Personalise"
    bl_description = (
        "Transfer the template's shape keys onto the active mesh and fit them to the training expressions: "
        "meshes of the target's topology named after the template's packed expressions (REF_01...) or shape keys. "
        "Esc or Cancel stops it"
    )
    label = "Personalise"

    @classmethod
    def poll(cls, context):
        if not super().poll(context):
            return False
        if context.scene.shapesmith.transfer.training is None:
            cls.poll_message_set("Pick a collection of training expressions")
            return False
        return True

    def training_objects(self, settings):
        return list(settings.training.all_objects)


register, unregister = bpy.utils.register_classes_factory(
    (
        SHAPESMITH_OT_transfer_shape_keys,
        SHAPESMITH_OT_personalise_shape_keys,
    )
)
