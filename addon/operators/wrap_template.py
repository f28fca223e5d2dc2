"""Align and Wrap: the template fitted onto the active character, shown as an object
`<character>_Wrapped_<template>` coloured by its distance to the character, so the fit can be
inspected before any key is written."""

import bpy

from ..blender.settings import WrapSettings
from ..blender.wrap import pairs_or_proposed, refresh_markers, show_wrapped, store_wrap, wrap_object
from .base import expected_errors, poll_character, progress_cursor


class WrapOperator:
    bl_options = {"REGISTER", "UNDO"}
    align_only = False

    @classmethod
    def poll(cls, context):
        return poll_character(cls, context)

    def execute(self, context):
        character = context.active_object
        template = context.scene.shapesmith.transfer.source
        try:
            with progress_cursor(context, "Wrap") as progress:
                template_points, character_points, proposal = pairs_or_proposed(character, template, progress)
                wrapped = wrap_object(
                    template, character, template_points, character_points, WrapSettings(align_only=self.align_only),
                    progress=progress,
                )
            show_wrapped(wrapped)
        except expected_errors() as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        store_wrap(wrapped, "ALIGN" if self.align_only else "WRAP")
        if proposal is not None:
            refresh_markers(character, template)
            self.report({"INFO"}, f"no point pairs: {len(template_points)} proposed and used (listed in the panel to review)")
        for warning in (proposal or {}).get("warnings", []) + wrapped.report["warnings"]:
            self.report({"WARNING"}, warning)
        report = wrapped.report
        self.report(
            {"INFO"},
            f"{'aligned' if self.align_only else 'wrapped'} '{template.name}' onto '{character.name}': mean distance "
            f"{100 * report['mean_distance']:.3f}% of the diagonal, max {100 * report['max_distance']:.2f}%",
        )
        return {"FINISHED"}


class SHAPESMITH_OT_align_template(WrapOperator, bpy.types.Operator):
    bl_idname = "shapesmith.align_template"
    bl_label = "Align"
    bl_description = (
        "Move, turn and scale the template onto the active character from the point pairs (none: they are "
        "proposed first), shown as a wrapped-template object"
    )
    align_only = True


class SHAPESMITH_OT_wrap_template(WrapOperator, bpy.types.Operator):
    bl_idname = "shapesmith.wrap_template"
    bl_label = "Wrap"
    bl_description = (
        "Align, then fit the template's surface onto the active character (non-rigid ICP guided by the "
        "point pairs, proposed first when there are none); the wrapped template is coloured by its distance to the character"
    )


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_align_template, SHAPESMITH_OT_wrap_template))
