"""The Wrap sub-panel of Transfer: Generate ARKit Keys first (the whole chain in one click),
then the chain step by step (Align, Wrap: the wrapped template coloured by its distance to
the character; Transfer onto Character) and its result; the point pairs in a sub-panel."""

import bpy

from ..blender.wrap import PAIRS_PROPERTY
from ..operators.job_operator import draw_running
from .panels import ShapesmithPanel


class SHAPESMITH_UL_point_pairs(bpy.types.UIList):
    def draw_item(self, context, layout, data, item, icon, active_data, active_propname, index):
        row = layout.row(align=True)
        row.prop(item, "name", text="", emboss=False)
        # Each end on a vertex or a surface point; the indices are the batch's business.
        row.label(text="", icon="VERTEXSEL" if item.template_vertex >= 0 else "SNAP_FACE")
        row.label(text="", icon="VERTEXSEL" if item.character_vertex >= 0 else "SNAP_FACE")


# A fit is close when it stays on average within 0.5% of the diagonal of the character (the
# sample character fits within 0.2%); the distance colours turn red at 1%, and a pair end
# missed by that much is visibly off.
CLOSE_FIT, PAIR_OFF = 0.005, 0.01


class SHAPESMITH_PT_wrap(ShapesmithPanel, bpy.types.Panel):
    bl_label = "Wrap (any topology)"
    bl_parent_id = "SHAPESMITH_PT_transfer"

    def draw(self, context):
        layout = self.layout
        template = context.scene.shapesmith.transfer.source
        obj = context.active_object
        layout.operator("shapesmith.generate_arkit_keys", icon="SHAPEKEY_DATA")
        draw_running(layout)
        if obj is None or obj.type != "MESH":
            layout.label(text="Make the character (a mesh) active", icon="INFO")
            layout.operator("shapesmith.add_arkit_template", icon="MONKEY")
            return
        layout.prop_search(obj.shapesmith_wrap, "region", obj, "vertex_groups")
        layout.label(text=f"Template: {template.name if template else 'none: the bundled ARKit template'}", icon="MESH_DATA")
        layout.label(text=f"Character: {obj.name}", icon="USER")
        layout.operator("shapesmith.add_arkit_template", icon="MONKEY")
        settings = obj.shapesmith_wrap
        layout.label(text="Step by step:")
        row = layout.row(align=True)
        row.operator("shapesmith.align_template", icon="ORIENTATION_GLOBAL")
        row.operator("shapesmith.wrap_template", icon="MOD_SHRINKWRAP")
        layout.operator("shapesmith.transfer_onto_character", icon="SHAPEKEY_DATA")
        if settings.done:
            box = layout.box().column(align=True)
            box.label(text=f"{settings.stage.title()} of '{settings.template}' ({settings.alignment})")
            box.label(text=f"Off the character: {100 * settings.mean_distance:.2f}% of the head's size on average, "
                           f"{100 * settings.max_distance:.1f}% at most (red on the fitted template)",
                      icon="CHECKMARK" if settings.mean_distance < CLOSE_FIT else "ERROR")
            box.label(text=f"Pairs missed by at most {100 * settings.max_pair_residual:.2f}% of the head's size",
                      icon="CHECKMARK" if settings.max_pair_residual < PAIR_OFF else "ERROR")
            if settings.symmetric:
                box.label(text="Symmetric: fit and carry mirrored", icon="MOD_MIRROR")
            else:
                box.label(text=f"Not symmetric: {settings.symmetry_note}", icon="INFO")
            if settings.worst_mirror_miss >= 0.0:
                box.label(text=f"Worst mirror miss: {100 * settings.worst_mirror_miss:.1f}% ({settings.worst_mirror_pair})")
            if settings.pieces:
                box.label(text=f"Pieces: {settings.pieces}")
                for line in settings.matches.splitlines():
                    box.label(text=line, icon="CHECKMARK" if " fitted onto " in line or " landed on " in line else "INFO")
            if settings.written:
                box.label(text=f"Shape keys written: {settings.written}", icon="CHECKMARK")
                result = obj.shapesmith.transfer
                if result.done and result.carried:
                    worse = sum(1 for shape in result.shapes if shape.worse)
                    box.label(
                        text=f"Passing through more than the template's: {worse} (the Transfer panel above lists them)",
                        icon="ERROR" if worse else "CHECKMARK",
                    )
                # Where riggers look first, per key (eyes close, the mouth, smooth lines and keys).
                for line in settings.looks.splitlines():
                    box.label(text=line[2:], icon="CHECKMARK" if line.startswith("+") else "ERROR")


class SHAPESMITH_PT_wrap_pairs(ShapesmithPanel, bpy.types.Panel):
    """The point pairs guiding the wrap: proposed when there are none, checked and moved here."""

    bl_label = "Point Pairs"
    bl_parent_id = "SHAPESMITH_PT_wrap"
    bl_options = {"DEFAULT_CLOSED"}

    @classmethod
    def poll(cls, context):
        return context.active_object is not None and context.active_object.type == "MESH"

    def draw(self, context):
        layout = self.layout
        obj = context.active_object
        settings = obj.shapesmith_wrap
        layout.operator("shapesmith.propose_point_pairs", icon="AUTOMERGE_ON")
        layout.label(text=f"Point pairs: {len(settings.pairs)} (none: Wrap proposes them)")
        if not len(settings.pairs) and PAIRS_PROPERTY in obj.keys():
            layout.label(text="Pairs stored by a script: Show Markers or Align lists them", icon="INFO")
        row = layout.row()
        row.template_list("SHAPESMITH_UL_point_pairs", "", settings, "pairs", settings, "active_pair", rows=4)
        col = row.column(align=True)
        col.operator("shapesmith.add_point_pair", icon="ADD", text="")
        col.operator("shapesmith.remove_point_pair", icon="REMOVE", text="")
        col.operator("shapesmith.clear_point_pairs", icon="X", text="")
        col.operator("shapesmith.load_point_pairs", icon="FILEBROWSER", text="")
        if 0 <= settings.active_pair < len(settings.pairs):
            pair = settings.pairs[settings.active_pair]
            box = layout.box().column(align=True)
            box.prop(pair, "template_co")
            box.prop(pair, "character_co")
            row = box.row(align=True)
            row.operator("shapesmith.move_point_pair", text="Move on Template", icon="EMPTY_SINGLE_ARROW").side = "TEMPLATE"
            row.operator("shapesmith.move_point_pair", text="Move on Character", icon="EMPTY_SINGLE_ARROW").side = "CHARACTER"
        layout.prop(settings, "show_markers", icon="HIDE_OFF")


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_UL_point_pairs, SHAPESMITH_PT_wrap, SHAPESMITH_PT_wrap_pairs))
