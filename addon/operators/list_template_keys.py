"""List Template Keys: the Transfer panel's list of the template's keys, each ticked to be
transferred (ticks of keys already listed are kept)."""

import bpy


class SHAPESMITH_OT_list_template_keys(bpy.types.Operator):
    bl_idname = "shapesmith.list_template_keys"
    bl_label = "List Template Keys"
    bl_description = "List the template's shape keys in the Transfer panel, to tick the ones to transfer"
    bl_options = {"REGISTER", "UNDO"}

    tick: bpy.props.EnumProperty(
        name="Tick",
        items=(("KEEP", "Keep", "Keep the ticks of keys already listed; new keys ticked"),
               ("ALL", "All", "Tick every key"), ("NONE", "None", "Untick every key")),
        default="KEEP",
    )

    @classmethod
    def poll(cls, context):
        source = context.scene.shapesmith.transfer.source
        if source is None or source.data.shape_keys is None:
            cls.poll_message_set("Pick a template with shape keys")
            return False
        return True

    def execute(self, context):
        settings = context.scene.shapesmith.transfer
        keys = settings.source.data.shape_keys
        ticked = {item.name: item.chosen for item in settings.key_choice}
        settings.key_choice.clear()
        for block in keys.key_blocks:
            if block == keys.reference_key:
                continue
            item = settings.key_choice.add()
            item.name = block.name
            item.chosen = {"ALL": True, "NONE": False}.get(self.tick, ticked.get(block.name, True))
        settings.active_key_choice = 0
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_list_template_keys,))
