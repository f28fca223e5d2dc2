"""The Shapesmith tab in the 3D View sidebar: one panel per tool under a Rig panel."""

import json

import bpy

from .. import native
from ..blender.landmarks import STOP_REASONS, VERTEX_GROUP_NAME, curve_lines
from ..operators.job_operator import draw_running
from . import presets


class SHAPESMITH_UL_pairs(bpy.types.UIList):
    """Shape pairs, editable in place: each name is picked from the mesh's shape keys."""

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index):
        keys = context.active_object.data.shape_keys
        row = layout.row(align=True)
        if keys is None:
            row.label(text=f"{item.first} / {item.second}")
            return
        row.prop_search(item, "first", keys, "key_blocks", text="")
        row.prop_search(item, "second", keys, "key_blocks", text="")
        row.label(text=item.source.title())


class SHAPESMITH_UL_face_parts(bpy.types.UIList):
    """A head's face parts: each picked from the file's meshes, ticked when landmarks may go on it."""

    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index):
        row = layout.row(align=True)
        row.prop(item, "object", text="", icon="MESH_DATA")
        row.prop(item, "landmarks", text="", icon="EMPTY_DATA")


class ShapesmithPanel:
    bl_space_type = "VIEW_3D"
    bl_region_type = "UI"
    bl_category = "Shapesmith"


class SHAPESMITH_PT_rig(ShapesmithPanel, bpy.types.Panel):
    bl_label = "Rig"
    bl_order = 0

    def draw_header_preset(self, context):
        presets.draw_header(self.layout, "rig")

    def draw(self, context):
        layout = self.layout
        if not native.STATUS.startswith("native core "):
            layout.label(text=native.STATUS, icon="ERROR")
        settings = context.scene.shapesmith
        row = layout.row(align=True)
        row.operator("shapesmith.analyze_rig", icon="VIEWZOOM")
        row.operator("shapesmith.analyze_rig", text="Reset Pairs", icon="LOOP_BACK").reset_pairs = True
        row = layout.row(align=True)
        row.prop(settings, "symmetry_axis", expand=True)
        layout.prop(settings, "pair_by_name")
        obj = context.active_object
        if obj is None or obj.type != "MESH":
            return
        summary = obj.shapesmith.analysis
        if not summary.done:
            return
        box = layout.box()
        col = box.column(align=True)
        col.label(text=f"{summary.vertices} vertices, {summary.triangles} triangles")
        col.label(text=f"{summary.shapes} shape keys")
        col.label(text=f"Inert: {summary.inert or 'none'}")
        col.label(text=f"Unmatched mirror vertices: {summary.unmatched_vertices}"
                       + ("" if summary.unmatched_vertices == 0 else " (0 on a mirror-symmetric face)"),
                  icon="CHECKMARK" if summary.unmatched_vertices == 0 else "INFO")
        if summary.seam_vertices:
            col.label(text=f"Seams welded: {summary.seam_vertices} vertices into {summary.seam_groups} points")
        if summary.degenerate_triangles:
            col.label(text=f"Degenerate triangles: {summary.degenerate_triangles}", icon="ERROR")
        layout.label(text=f"Symmetric Pairs ({len(obj.shapesmith.pairs)})")
        row = layout.row()
        row.template_list("SHAPESMITH_UL_pairs", "pairs", obj.shapesmith, "pairs", obj.shapesmith, "active_pair", rows=4)
        col = row.column(align=True)
        col.operator("shapesmith.add_pair", icon="ADD", text="")
        col.operator("shapesmith.remove_pair", icon="REMOVE", text="")
        if obj.shapesmith.antagonists:
            box = layout.box()
            box.label(text="Antagonists (never posed together)")
            for pair in obj.shapesmith.antagonists:
                box.label(text=f"{pair.first} / {pair.second}")


class SHAPESMITH_PT_face_parts(ShapesmithPanel, bpy.types.Panel):
    """The head's Face Parts: separate meshes (teeth, tongue, eyes, lashes) every tool reads with it."""

    bl_label = "Face Parts"
    bl_parent_id = "SHAPESMITH_PT_rig"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        return context.active_object is not None and context.active_object.type == "MESH"

    def draw_header(self, context):
        # The count shows with the sub-panel closed: a head with parts says so.
        self.layout.label(text=f"({len(context.active_object.shapesmith.face_parts)})")

    def draw(self, context):
        layout = self.layout
        props = context.active_object.shapesmith
        layout.label(text="Parts of this head, read with it by every tool:")
        row = layout.row()
        row.template_list("SHAPESMITH_UL_face_parts", "face_parts", props, "face_parts", props, "active_face_part", rows=3)
        col = row.column(align=True)
        col.operator("shapesmith.add_face_parts", icon="ADD", text="")
        col.operator("shapesmith.remove_face_part", icon="REMOVE", text="")
        col.separator()
        col.operator("shapesmith.move_face_part", icon="TRIA_UP", text="").direction = "UP"
        col.operator("shapesmith.move_face_part", icon="TRIA_DOWN", text="").direction = "DOWN"


class SHAPESMITH_PT_landmarks(ShapesmithPanel, bpy.types.Panel):
    bl_label = "Landmarks"
    bl_order = 2
    bl_options = {"DEFAULT_CLOSED"}

    def draw_header_preset(self, context):
        presets.draw_header(self.layout, "landmarks")

    def draw(self, context):
        layout = self.layout
        settings = context.scene.shapesmith.landmarks
        layout.operator("shapesmith.place_landmarks", icon="EMPTY_DATA")
        draw_running(layout)
        layout.prop(settings, "symmetric", text=f"Symmetric (across {'XYZ'[int(context.scene.shapesmith.symmetry_axis)]} = 0)")
        layout.prop(settings, "camera_source")
        if settings.camera_source == "COLLECTION":
            layout.prop(settings, "camera_collection")
        layout.prop(settings, "design")
        if settings.design == "COUNT":
            layout.prop(settings, "landmarks")
        elif settings.design == "TARGET":
            layout.prop(settings, "target_error")
        obj = context.active_object
        if obj is None or obj.type != "MESH":
            return
        result = obj.shapesmith.landmarks
        if result.done:
            box = layout.box()
            col = box.column(align=True)
            col.label(text=f"{result.count} landmarks, {result.rounds} round(s)")
            col.label(text="Proven optimal" if result.optimal else "Not proven optimal",
                      icon="CHECKMARK" if result.optimal else "ERROR")
            col.label(text=f"Rebuilt from noisy tracks: mean error {result.mean_error:.2%} of the head's size, "
                           f"worst {result.max_error:.2%}")
            col.label(text=f"Predicted error: {result.predicted_error:.3%} of the head's size (lower is better)")
            document = json.loads(result.document) if result.document else {}
            if result.design_stop:
                col.label(text=f"{result.added} added for reconstruction: {STOP_REASONS[result.design_stop]}")
            score = obj.shapesmith.landmark_score
            if score.done and score.group != VERTEX_GROUP_NAME:
                change = result.mean_error / score.mean_error - 1.0 if score.mean_error > 0 else 0.0
                col.label(text=f"vs '{score.group}' ({score.landmarks}): mean {score.mean_error:.2%} ({change:+.0%})",
                          icon="CHECKMARK" if change < 0 else "ERROR")
            if document.get("curve"):
                curve = box.column(align=True)
                curve.label(text="Predicted error per landmark count:")
                for line in curve_lines(document):
                    curve.label(text=line.strip())
                box.operator("shapesmith.render_landmark_curve", icon="GRAPH")
            if result.uncovered:
                col.label(text=f"Uncovered: {result.uncovered}", icon="ERROR")
            if result.inert:
                col.label(text=f"Inert: {result.inert}")
            box.label(text=result.mesh_note, icon="INFO")
            row = box.row(align=True)
            row.operator("shapesmith.export_landmarks", text="JSON", icon="EXPORT").file_format = "JSON"
            row.operator("shapesmith.export_landmarks", text="CSV", icon="EXPORT").file_format = "CSV"
            box.operator("shapesmith.render_landmarks", icon="RENDER_STILL")
        box = layout.box()
        box.label(text="Score a tracked layout")
        box.prop_search(settings, "score_group", obj, "vertex_groups")
        box.operator("shapesmith.score_layout", icon="DRIVER_DISTANCE")
        score = obj.shapesmith.landmark_score
        if score.done:
            box.label(text=f"'{score.group}' ({score.landmarks} vertices): "
                           f"mean {score.mean_error:.2%}, max {score.max_error:.2%}")


class SHAPESMITH_PT_landmarks_advanced(ShapesmithPanel, bpy.types.Panel):
    """What makes a vertex a good landmark, and how many per shape."""

    bl_label = "Advanced"
    bl_parent_id = "SHAPESMITH_PT_landmarks"
    bl_options = {"DEFAULT_CLOSED"}

    def draw(self, context):
        settings = context.scene.shapesmith.landmarks
        col = self.layout.column(align=True)
        for name in ("epsilon", "alpha", "gamma", "max_per_shape", "radius"):
            col.prop(settings, name)
        if settings.camera_source == "HEMISPHERE":
            self.layout.prop(settings, "rays")


register, unregister = bpy.utils.register_classes_factory(
    (
        SHAPESMITH_UL_pairs,
        SHAPESMITH_UL_face_parts,
        SHAPESMITH_PT_rig,
        SHAPESMITH_PT_face_parts,
        SHAPESMITH_PT_landmarks,
        SHAPESMITH_PT_landmarks_advanced,
    )
)
