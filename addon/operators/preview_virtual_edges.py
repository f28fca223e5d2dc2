"""Preview Virtual Edges: the pairs that transfer will hold apart, drawn as a wire mesh
`<target>_VirtualEdges` parented to the active mesh (replaced on every run)."""

import bpy

from ..blender.settings import VirtualEdgeSettings
from ..blender.transfer import find_virtual_edges, show_virtual_edges
from .base import expected_errors, poll_mesh


class SHAPESMITH_OT_preview_virtual_edges(bpy.types.Operator):
    bl_idname = "shapesmith.preview_virtual_edges"
    bl_label = "Preview Virtual Edges"
    bl_description = "Show the virtual edges of the active mesh (opposite lips, eyelids, nostril walls) as a wire mesh"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        return poll_mesh(cls, context)

    def execute(self, context):
        settings = context.scene.shapesmith.transfer
        target = context.active_object
        try:
            edges, positions = find_virtual_edges(target, VirtualEdgeSettings(tau_d=settings.tau_d, tau_r=settings.tau_r))
        except expected_errors() as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        preview = show_virtual_edges(target, edges, positions)
        self.report({"INFO"}, f"{len(edges)} virtual edges on '{target.name}' (shown as '{preview.name}')")
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_OT_preview_virtual_edges,))
