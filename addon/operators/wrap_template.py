"""Align and Wrap: the template fitted onto the active character, shown as an object
`<character>_Wrapped_<template>` coloured by its distance to the character, so the fit can be
inspected before any key is written. With no template picked, the bundled ARKit template is
added and used. Progress and Cancel as every long tool's (`job_operator`)."""

import bpy

from ..blender import bundled_template
from ..blender.settings import WrapSettings
from ..blender.wrap import pairs_or_proposed, refresh_markers, show_wrapped, store_wrap, wrap_object
from .base import poll_character
from .job_operator import JobOperator


def wrap_onto(progress, character, template, align_only, scene):
    """The wrap (pairs proposed when none are stored), written only once it has succeeded: a
    failed or cancelled one removes the pairs it proposed and the template it added."""
    added = template is None
    if added:
        template = bundled_template.add_template(scene, tuple(scene.cursor.location))
    had_pairs = len(character.shapesmith_wrap.pairs) > 0
    try:
        template_points, character_points, proposal = pairs_or_proposed(character, template, progress)
        wrapped = wrap_object(
            template, character, template_points, character_points, WrapSettings(align_only=align_only), progress=progress,
        )
    except BaseException:
        if not had_pairs:
            character.shapesmith_wrap.pairs.clear()
        if added:
            bundled_template.remove_template(template)
        raise
    show_wrapped(wrapped)
    store_wrap(wrapped, "ALIGN" if align_only else "WRAP")
    if added:
        scene.shapesmith.transfer.source = template
    if proposal is not None:
        refresh_markers(character, template)
    return wrapped, proposal, template_points, added


class WrapOperator(JobOperator):
    bl_options = {"REGISTER", "UNDO"}
    align_only = False

    @classmethod
    def poll(cls, context):
        return poll_character(cls, context, bundled=True)

    def arguments(self, context):
        return {
            "character": context.active_object, "template": context.scene.shapesmith.transfer.source,
            "align_only": self.align_only, "scene": context.scene,
        }

    run = staticmethod(wrap_onto)

    def finished(self, context, value):
        wrapped, proposal, template_points, added = value
        template, character = wrapped.template, wrapped.character
        if added:
            self.report({"INFO"}, f"no template picked: the bundled '{template.name}' added and picked")
        if proposal is not None:
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
        "Move, turn and scale the template (none picked: the bundled ARKit template) onto the active character "
        "from the point pairs (none: they are proposed first), shown as a wrapped-template object"
    )
    label = "Align"
    align_only = True


class SHAPESMITH_OT_wrap_template(WrapOperator, bpy.types.Operator):
    bl_idname = "shapesmith.wrap_template"
    bl_label = "Wrap"
    bl_description = (
        "Align, then fit the template's surface (none picked: the bundled ARKit template) onto the active character "
        "(non-rigid ICP guided by the point pairs, proposed first when there are none); the wrapped template is "
        "coloured by its distance to the character. Esc or Cancel stops it"
    )
    label = "Wrap"


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_align_template, SHAPESMITH_OT_wrap_template))
