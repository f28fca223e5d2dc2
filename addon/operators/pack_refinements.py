"""The artist's refinements of Pack Expressions (paper 000, section 4.5.3): shapes pinned
together, shapes kept apart, shapes excluded. The solve honours them as constraints."""

import bpy

_KINDS = (
    ("PIN", "Pin Together", "Two shapes that must share an expression"),
    ("APART", "Keep Apart", "Two shapes that must not share an expression"),
    ("EXCLUDE", "Exclude", "A shape never packed"),
)
# kind -> (collection, index property) on `Object.shapesmith.pack`
_LISTS = {"PIN": ("pin_together", "active_pin"), "APART": ("keep_apart", "active_apart"), "EXCLUDE": ("exclude", "active_exclude")}


def _poll_mesh_with_keys(context):
    obj = context.active_object
    return obj is not None and obj.type == "MESH" and obj.data.shape_keys is not None


class SHAPESMITH_OT_add_pack_refinement(bpy.types.Operator):
    bl_idname = "shapesmith.add_pack_refinement"
    bl_label = "Add Refinement"
    bl_description = "Add an entry to fill in with shape keys"
    bl_options = {"REGISTER", "UNDO"}

    kind: bpy.props.EnumProperty(items=_KINDS)

    @classmethod
    def poll(cls, context):
        return _poll_mesh_with_keys(context)

    def execute(self, context):
        settings = context.active_object.shapesmith.pack
        collection, index = _LISTS[self.kind]
        entries = getattr(settings, collection)
        entry = entries.add()
        if self.kind != "EXCLUDE":
            entry.source = "USER"
        setattr(settings, index, len(entries) - 1)
        return {"FINISHED"}


class SHAPESMITH_OT_remove_pack_refinement(bpy.types.Operator):
    bl_idname = "shapesmith.remove_pack_refinement"
    bl_label = "Remove Refinement"
    bl_description = "Remove the selected entry"
    bl_options = {"REGISTER", "UNDO"}

    kind: bpy.props.EnumProperty(items=_KINDS)

    @classmethod
    def poll(cls, context):
        return _poll_mesh_with_keys(context)

    def execute(self, context):
        settings = context.active_object.shapesmith.pack
        collection, index = _LISTS[self.kind]
        entries = getattr(settings, collection)
        selected = getattr(settings, index)
        if not 0 <= selected < len(entries):
            return {"CANCELLED"}
        entries.remove(selected)
        setattr(settings, index, min(selected, len(entries) - 1))
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory(
    (
        SHAPESMITH_OT_add_pack_refinement,
        SHAPESMITH_OT_remove_pack_refinement,
    )
)
