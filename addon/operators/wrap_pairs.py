"""Edit the point pairs stored on the character: add one (each side from the object's one
selected vertex, else the 3D cursor snapped to its surface), move one side of the active
pair the same way, remove, clear, load from JSON. The markers (when shown) follow every
edit."""

import json

import bpy
import numpy as np
from bpy_extras.io_utils import ImportHelper

from .. import native
from ..blender.mesh_arrays import MeshDataError, read_triangles
from ..blender.transfer import rest_positions
from ..blender.wrap import pairs_from_json, refresh_markers, store_pairs
from .base import expected_errors, poll_mesh


def poll_character(cls, context):
    """A mesh (the character) in Object or Edit Mode, and a template that is another mesh."""
    obj = context.active_object
    if obj is None or obj.type != "MESH":
        cls.poll_message_set("Make the character (a mesh) active")
        return False
    template = context.scene.shapesmith.transfer.source
    if template is None or template == obj:
        cls.poll_message_set("Pick the template in the Transfer panel, and make another mesh active")
        return False
    return True


def pair_point(obj, cursor_world):
    """(vertex index or -1, local point): the object's one selected vertex, else the 3D
    cursor snapped to the object's surface."""
    if obj.mode == "EDIT":
        obj.update_from_editmode()
    mesh = obj.data
    selected = np.zeros(len(mesh.vertices), dtype=bool)
    mesh.vertices.foreach_get("select", selected)
    chosen = np.flatnonzero(selected)
    if len(chosen) == 1:
        return int(chosen[0]), rest_positions(obj)[int(chosen[0])]
    positions, triangles = rest_positions(obj), read_triangles(obj)
    if len(triangles) == 0:
        raise MeshDataError(f"'{obj.name}' has no faces")
    local = np.array(obj.matrix_world.inverted() @ cursor_world, dtype=np.float32).reshape(1, 3)
    triangle, barycentric, _ = native.module().bind_to_surface(local, positions, triangles)
    corners = positions[triangles[triangle[0]]]
    return -1, (barycentric[0] @ corners).astype(np.float32)


class SHAPESMITH_OT_add_point_pair(bpy.types.Operator):
    bl_idname = "shapesmith.add_point_pair"
    bl_label = "Add Point Pair"
    bl_description = (
        "Pair a point on the template with one on the active character: on each, its one selected vertex "
        "(Edit Mode), else the 3D cursor snapped to its surface"
    )
    bl_options = {"REGISTER", "UNDO"}

    name: bpy.props.StringProperty(name="Name", description="What the pair marks, e.g. nose tip")

    @classmethod
    def poll(cls, context):
        return poll_character(cls, context)

    def execute(self, context):
        character = context.active_object
        template = context.scene.shapesmith.transfer.source
        cursor = context.scene.cursor.location
        try:
            template_vertex, template_co = pair_point(template, cursor)
            character_vertex, character_co = pair_point(character, cursor)
        except expected_errors() as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        if template_vertex < 0 and character_vertex < 0:
            self.report({"ERROR"}, "select one vertex on the template or on the character (Edit Mode); the 3D cursor gives the other")
            return {"CANCELLED"}
        settings = character.shapesmith_wrap
        pair = settings.pairs.add()
        pair.name = self.name or f"Pair {len(settings.pairs)}"
        pair.template_vertex, pair.character_vertex = template_vertex, character_vertex
        pair.template_co, pair.character_co = template_co.tolist(), character_co.tolist()
        settings.active_pair = len(settings.pairs) - 1
        refresh_markers(character, template)
        return {"FINISHED"}


class SHAPESMITH_OT_move_point_pair(bpy.types.Operator):
    bl_idname = "shapesmith.move_point_pair"
    bl_label = "Move Point"
    bl_description = (
        "Move one end of the active point pair: to the object's one selected vertex (Edit Mode), "
        "else to the 3D cursor snapped to its surface"
    )
    bl_options = {"REGISTER", "UNDO"}

    side: bpy.props.EnumProperty(
        name="Side",
        items=(("TEMPLATE", "On Template", "Move the point on the template"), ("CHARACTER", "On Character", "Move the point on the character")),
    )

    @classmethod
    def poll(cls, context):
        if not poll_character(cls, context):
            return False
        settings = context.active_object.shapesmith_wrap
        if not 0 <= settings.active_pair < len(settings.pairs):
            cls.poll_message_set("Pick a point pair in the list")
            return False
        return True

    def execute(self, context):
        character = context.active_object
        template = context.scene.shapesmith.transfer.source
        obj = template if self.side == "TEMPLATE" else character
        try:
            vertex, co = pair_point(obj, context.scene.cursor.location)
        except expected_errors() as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        pair = character.shapesmith_wrap.pairs[character.shapesmith_wrap.active_pair]
        side = self.side.lower()
        setattr(pair, f"{side}_vertex", vertex)
        setattr(pair, f"{side}_co", co.tolist())
        refresh_markers(character, template)
        self.report({"INFO"}, f"'{pair.name}' now at {'vertex %d' % vertex if vertex >= 0 else 'the snapped 3D cursor'} of '{obj.name}'")
        return {"FINISHED"}


class SHAPESMITH_OT_remove_point_pair(bpy.types.Operator):
    bl_idname = "shapesmith.remove_point_pair"
    bl_label = "Remove Point Pair"
    bl_description = "Remove the selected point pair"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        return obj is not None and obj.type == "MESH" and 0 <= obj.shapesmith_wrap.active_pair < len(obj.shapesmith_wrap.pairs)

    def execute(self, context):
        settings = context.active_object.shapesmith_wrap
        settings.pairs.remove(settings.active_pair)
        settings.active_pair = max(min(settings.active_pair, len(settings.pairs) - 1), 0)
        refresh_markers(context.active_object, context.scene.shapesmith.transfer.source)
        return {"FINISHED"}


class SHAPESMITH_OT_clear_point_pairs(bpy.types.Operator):
    bl_idname = "shapesmith.clear_point_pairs"
    bl_label = "Clear Point Pairs"
    bl_description = "Remove every point pair of the active character"
    bl_options = {"REGISTER", "UNDO"}

    @classmethod
    def poll(cls, context):
        obj = context.active_object
        return obj is not None and obj.type == "MESH" and len(obj.shapesmith_wrap.pairs) > 0

    def execute(self, context):
        context.active_object.shapesmith_wrap.pairs.clear()
        context.active_object.shapesmith_wrap.active_pair = 0
        refresh_markers(context.active_object, context.scene.shapesmith.transfer.source)
        return {"FINISHED"}


class SHAPESMITH_OT_load_point_pairs(bpy.types.Operator, ImportHelper):
    bl_idname = "shapesmith.load_point_pairs"
    bl_label = "Load Point Pairs"
    bl_description = (
        "Replace the character's point pairs with a JSON file: [[template_vertex, character_vertex], ...] "
        "or [[[x, y, z], [x, y, z]], ...] in each object's local space"
    )
    bl_options = {"REGISTER", "UNDO"}

    filename_ext = ".json"
    filter_glob: bpy.props.StringProperty(default="*.json", options={"HIDDEN"})

    @classmethod
    def poll(cls, context):
        return poll_character(cls, context) and poll_mesh(cls, context)

    def execute(self, context):
        character = context.active_object
        template = context.scene.shapesmith.transfer.source
        try:
            pairs_from_json(self.filepath, template, character)  # validates before anything changes
            with open(self.filepath) as f:
                store_pairs(character, json.load(f), template)
        except expected_errors() as error:
            self.report({"ERROR"}, str(error))
            return {"CANCELLED"}
        refresh_markers(character, template)
        self.report({"INFO"}, f"{len(character.shapesmith_wrap.pairs)} point pairs loaded")
        return {"FINISHED"}


register, unregister = bpy.utils.register_classes_factory(
    (
        SHAPESMITH_OT_add_point_pair,
        SHAPESMITH_OT_move_point_pair,
        SHAPESMITH_OT_remove_point_pair,
        SHAPESMITH_OT_clear_point_pairs,
        SHAPESMITH_OT_load_point_pairs,
    )
)
