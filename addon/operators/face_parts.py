"""The Face Parts list of a head: the separate meshes (teeth, tongue, eyes, lashes, brows)
every tool reads together with it. Each button is one undo step."""

import bpy


def _head(context):
    obj = context.active_object
    return obj if obj is not None and obj.type == "MESH" else None


class SHAPESMITH_OT_add_face_parts(bpy.types.Operator):
    bl_idname = "shapesmith.add_face_parts"
    bl_label = "Add Selected Parts"
    bl_description = (
        "List the selected meshes (teeth, tongue, eyes, lashes, brows) as face parts of the active head; "
        "parts already listed are kept once"
    )
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        head = _head(context)
        if head is None:
            cls.poll_message_set("Make the head the active mesh")
            return False
        if not any(o.type == "MESH" and o != head for o in context.selected_objects):
            cls.poll_message_set("Select the part meshes, then the head last (active)")
            return False
        return True

    def execute(self, context):
        head = _head(context)
        parts = head.shapesmith.face_parts
        listed = {item.object for item in parts}
        added = [o for o in context.selected_objects if o.type == "MESH" and o != head and o not in listed]
        for obj in sorted(added, key=lambda o: o.name):
            parts.add().object = obj
        head.shapesmith.active_face_part = len(parts) - 1
        self.report({"INFO"}, f"{len(added)} face part(s) added to '{head.name}'" if added else "every selected part was listed")
        return {"FINISHED"}


class SHAPESMITH_OT_remove_face_part(bpy.types.Operator):
    bl_idname = "shapesmith.remove_face_part"
    bl_label = "Remove Part"
    bl_description = "Take the selected part off the head's Face Parts list (the object itself is kept)"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        head = _head(context)
        return head is not None and 0 <= head.shapesmith.active_face_part < len(head.shapesmith.face_parts)

    def execute(self, context):
        props = _head(context).shapesmith
        props.face_parts.remove(props.active_face_part)
        props.active_face_part = min(props.active_face_part, len(props.face_parts) - 1)
        return {"FINISHED"}


class SHAPESMITH_OT_move_face_part(bpy.types.Operator):
    bl_idname = "shapesmith.move_face_part"
    bl_label = "Move Part"
    bl_description = "Move the selected part up or down the list (a target's parts pair with the template's in list order)"
    bl_options = {"REGISTER", "UNDO"}

    direction: bpy.props.EnumProperty(items=(("UP", "Up", ""), ("DOWN", "Down", "")))

    @classmethod
    def poll(cls, context):
        head = _head(context)
        return head is not None and 0 <= head.shapesmith.active_face_part < len(head.shapesmith.face_parts)

    def execute(self, context):
        props = _head(context).shapesmith
        index = props.active_face_part
        other = index - 1 if self.direction == "UP" else index + 1
        if not 0 <= other < len(props.face_parts):
            return {"CANCELLED"}
        props.face_parts.move(index, other)
        props.active_face_part = other
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory(
    (SHAPESMITH_OT_add_face_parts, SHAPESMITH_OT_remove_face_part, SHAPESMITH_OT_move_face_part)
)
