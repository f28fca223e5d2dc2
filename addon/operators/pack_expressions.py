"""Pack Expressions: the fewest reference expressions for the active rig's shape keys, stored
on it (replacing any earlier result)."""

import bpy

from .. import preferences
from ..blender.packing import pack_object, packing_options, store_packing
from .base import poll_mesh
from .job_operator import JobOperator


def pack_and_store(progress, obj, options):
    """Packs in full, then stores the result (nothing before: a cancelled pack changes nothing)."""
    report = pack_object(obj, progress=progress, **options)
    store_packing(obj, report)
    return report


class SHAPESMITH_OT_pack_expressions(JobOperator, bpy.types.Operator):
    bl_idname = "shapesmith.pack_expressions"
    bl_label = "Pack Expressions"
    bl_description = (
        "Group the shape keys into as few reference expressions as possible, each posing shapes whose "
        "strongly moving regions do not overlap, most important first. Esc or Cancel stops it"
    )
    label = "Pack Expressions"
    run = staticmethod(pack_and_store)
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return poll_mesh(cls, context)

    def arguments(self, context):
        obj = context.active_object
        prefs = preferences.get(context)
        time_limit = prefs.solver_time_limit if prefs and prefs.solver_time_limit > 0 else None
        return {"obj": obj, "options": packing_options(obj, axis=int(context.scene.shapesmith.symmetry_axis), time_limit=time_limit)}

    def finished(self, context, report):
        for warning in report["warnings"]:
            self.report({"WARNING"}, warning)
        unproven = sum(not e["optimal"] for e in report["expressions"])
        if unproven:
            self.report({"WARNING"}, f"{unproven} expression(s) not proven optimal (solver time limit)")
        left = f", {len(report['unplaced'])} shapes left over (the At Most limit)" if report["unplaced"] else ""
        reused = report["poseability"].get("pairs_reused", 0)
        cached = f", collision and occlusion results of {reused} pairs reused" if reused else ""
        self.report({"INFO"}, f"{len(report['expressions'])} expressions from {len(report['names'])} shapes{left}{cached}")
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_pack_expressions,))
