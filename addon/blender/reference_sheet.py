"""The reference sheet: per packed expression, a front view and a three-quarter view side by
side, each member's strongly moving region (its binary blendshape, as packing computed it)
tinted in the member's own colour and the member names written in those colours under the
front view as the legend, tiled into one PNG to show an actor what to pose and what moves.

Blender's Python has no PIL, so labels are text objects rendered inside each tile (one
material per member, set per character), and the tiles are put together with numpy. The
rig is rendered through a temporary copy of its mesh, which carries the tint as face
materials, so the user's mesh is never touched. Everything is rendered headless with
Workbench in a scene made for the purpose, which is removed afterwards with everything it
created."""

import json
import math
import os
import tempfile
import textwrap

import numpy as np

import bpy
from mathutils import Matrix

from .face_parts import face_objects
from .front import to_front_view, view_front
from .mesh_arrays import MeshDataError, read_positions

MARGIN = 0.06  # of the head's height, around the head in each tile
LABEL_SHARE = 0.24  # of each tile's height, under the head, for the member names
BACKGROUND = 1.0
GRID = 0.75
SKIN = (0.8, 0.8, 0.8, 1.0)
INK = (0.05, 0.05, 0.05, 1.0)
THREE_QUARTER = math.radians(40)  # the second view, turned towards the face's left
# One colour per member, dark enough to read as text on white and to tint a grey face.
PALETTE = [
    (0.85, 0.16, 0.12), (0.12, 0.42, 0.85), (0.10, 0.62, 0.22), (0.80, 0.45, 0.02),
    (0.55, 0.20, 0.75), (0.02, 0.60, 0.62), (0.80, 0.18, 0.55), (0.45, 0.45, 0.05),
    (0.35, 0.25, 0.15), (0.30, 0.55, 0.95), (0.95, 0.35, 0.35), (0.15, 0.35, 0.30),
]


def member_colour(index):
    return (*PALETTE[index % len(PALETTE)], 1.0)


def render_reference_sheet(obj, path, tile_width=320, tile_height=400, columns=None):
    """Renders the expressions stored on `obj` and writes the sheet to `path` (PNG): each
    expression's tile is two views, each `tile_width` wide. Returns (width, height)."""
    result = obj.shapesmith.pack.result
    if not result.done or not result.expressions:
        raise MeshDataError(f"'{obj.name}' has no packed expressions: run Pack Expressions first")
    # A face in several objects is drawn by its head: a key only a part has (tongueOut in the
    # teeth) is named in the legend, and the regions keep the head's vertices (they come first).
    known = {kb.name for o in face_objects(obj) if o.data.shape_keys for kb in o.data.shape_keys.key_blocks}
    expressions = [[m.name for m in e.members] for e in result.expressions]
    missing = sorted({name for names in expressions for name in names if name not in known})
    if missing:
        raise MeshDataError(f"shape key(s) {', '.join(missing)} no longer exist: pack again")
    regions = json.loads(result.regions_json or "{}")
    unknown = sorted({name for names in expressions for name in names if name not in regions})
    if unknown:
        raise MeshDataError(f"the stored result has no moving regions for {', '.join(unknown)}: pack again")
    columns = columns or math.ceil(math.sqrt(len(expressions)))
    rows = math.ceil(len(expressions) / columns)
    pair_width = 2 * tile_width
    sheet = np.full((rows * tile_height, columns * pair_width, 4), BACKGROUND, dtype=np.float32)
    stage = _Stage(obj, tile_width, tile_height, view_front(obj))
    try:
        for j, members in enumerate(expressions):
            front, side = stage.render(f"{j + 1}", members, [regions[name] for name in members])
            row, column = divmod(j, columns)
            top = (rows - 1 - row) * tile_height  # image rows run bottom-up
            left = column * pair_width
            sheet[top : top + tile_height, left : left + tile_width] = front
            sheet[top : top + tile_height, left + tile_width : left + pair_width] = side
    finally:
        stage.remove()
    sheet[:, ::pair_width, :3] = GRID
    sheet[::tile_height, :, :3] = GRID
    _save_png(sheet, path)
    return sheet.shape[1], sheet.shape[0]


class _Stage:
    """A throwaway scene: a copy of the rig (its own mesh, so tinting never touches the
    user's), turned so that the face's front (mesh coordinates, `front` and `up`) looks towards
    -Y with its up along +Z whatever the mesh's or the object's orientation, an orthographic
    camera looking along +Y at it and one turned to three-quarters, and two text objects for
    the number and the legend."""

    def __init__(self, obj, tile_width, tile_height, front_and_up):
        self.created = []
        self.materials = []
        self.folder = tempfile.mkdtemp(prefix="shapesmith-sheet-")
        self.scene = bpy.data.scenes.new("Shapesmith Reference Sheet")
        render = self.scene.render
        render.engine = "BLENDER_WORKBENCH"
        render.resolution_x, render.resolution_y, render.resolution_percentage = tile_width, tile_height, 100
        render.film_transparent = True
        render.image_settings.file_format = "PNG"
        render.image_settings.color_mode = "RGBA"
        self.scene.view_settings.view_transform = "Standard"
        shading = self.scene.display.shading
        shading.light, shading.color_type = "STUDIO", "MATERIAL"

        self.rig = self._add("Shapesmith Sheet Rig", obj.data.copy())
        turn = to_front_view(*front_and_up)
        self.rig.matrix_world = Matrix([[*row, 0.0] for row in turn] + [[0.0, 0.0, 0.0, 1.0]])
        self.rig.data.materials.clear()
        self.rig.data.materials.append(self._material(SKIN))
        polygons = self.rig.data.polygons
        self.loop_start = np.empty(len(polygons), np.int32)
        polygons.foreach_get("loop_start", self.loop_start)
        self.loop_total = np.empty(len(polygons), np.int32)
        polygons.foreach_get("loop_total", self.loop_total)
        self.loop_vertex = np.empty(len(self.rig.data.loops), np.int32)
        self.rig.data.loops.foreach_get("vertex_index", self.loop_vertex)

        world = read_positions(obj).astype(np.float64) @ turn.T
        low, high = world.min(axis=0), world.max(axis=0)
        head_height = high[2] - low[2]
        label_height = head_height * LABEL_SHARE / (1 - LABEL_SHARE)
        frame_height = head_height * (1 + 2 * MARGIN) + label_height
        frame_height = max(frame_height, (high[0] - low[0]) * (1 + 2 * MARGIN) * tile_height / tile_width)
        self.frame_width = frame_height * tile_width / tile_height
        centre_x = (low[0] + high[0]) / 2
        top = high[2] + head_height * MARGIN
        front = low[1] - 0.01 * frame_height

        camera = self._add("Shapesmith Sheet Camera", bpy.data.cameras.new("Shapesmith Sheet Camera"))
        camera.data.type, camera.data.sensor_fit, camera.data.ortho_scale = "ORTHO", "VERTICAL", frame_height
        distance = 10 * (high - low).max()
        camera.data.clip_end = 2 * distance + (high - low).max()
        self.camera = camera
        self.front_view = ((centre_x, low[1] - distance, top - frame_height / 2), (math.pi / 2, 0.0, 0.0))
        # Turned about the head's vertical axis: looks along (-sin t, cos t, 0), Z up.
        centre_y = (low[1] + high[1]) / 2
        turned = (centre_x + distance * math.sin(THREE_QUARTER), centre_y - distance * math.cos(THREE_QUARTER))
        self.side_view = ((*turned, top - frame_height / 2), (math.pi / 2, 0.0, THREE_QUARTER))
        self.scene.camera = camera

        self.line_height = label_height / 4.6
        self.number = self._text("Shapesmith Sheet Number", 1.6 * self.line_height, "LEFT")
        self.number.location = (centre_x - self.frame_width / 2 + 0.35 * self.line_height, front, top - 1.2 * self.line_height)
        self.members = self._text("Shapesmith Sheet Members", self.line_height, "CENTER")
        self.members.location = (centre_x, front, top - frame_height + label_height - 0.9 * self.line_height)

    def _add(self, name, data):
        obj = bpy.data.objects.new(name, data)
        self.scene.collection.objects.link(obj)
        self.created.append(obj)
        return obj

    def _material(self, colour):
        material = bpy.data.materials.new("Shapesmith Sheet Colour")
        material.diffuse_color = colour
        self.materials.append(material)
        return material

    def _text(self, name, size, align):
        text = self._add(name, bpy.data.curves.new(name, "FONT"))
        text.data.size, text.data.align_x = size, align
        text.rotation_euler = (math.pi / 2, 0.0, 0.0)  # reads towards -Y, up along Z
        text.data.materials.append(self._material(INK))
        return text

    def _fit(self, text):
        """(size, wrapped text): the largest of a few sizes at which `text` fits the label area."""
        for scale in (1.0, 0.8, 0.65, 0.55, 0.45):
            size = self.line_height * scale
            lines = textwrap.wrap(text, max(12, int(self.frame_width / (0.48 * size))), break_long_words=False)
            if len(lines) * scale <= 4:
                break
        return size, "\n".join(lines)

    def _pose(self, members, regions):
        """Members' keys at 1 (the rest at 0) and each member's region tinted: a face takes
        the colour of the first member whose region holds all its corners."""
        for block in self.rig.data.shape_keys.key_blocks:
            block.value = 1.0 if block.name in members else 0.0
        mesh = self.rig.data
        while len(mesh.materials) > 1:
            mesh.materials.pop()
        face = np.zeros(len(mesh.polygons), np.int32)
        polygon_of_loop = np.repeat(np.arange(len(mesh.polygons)), self.loop_total)
        for index, region in enumerate(regions):
            mesh.materials.append(self._material(member_colour(index)))
            inside = np.zeros(len(mesh.vertices), bool)
            region = np.asarray(region, dtype=np.int64)
            inside[region[region < len(inside)]] = True
            corners_inside = np.bincount(polygon_of_loop, weights=inside[self.loop_vertex], minlength=len(face))
            face[(face == 0) & (corners_inside == self.loop_total)] = index + 1
        mesh.polygons.foreach_set("material_index", face)
        mesh.update()

    def _legend(self, members):
        """The member names, each in its colour, wrapped to the label area."""
        curve = self.members.data
        while len(curve.materials) > 1:
            curve.materials.pop()
        curve.size, curve.body = self._fit(", ".join(members))
        start = 0
        for index, name in enumerate(members):
            curve.materials.append(self.rig.data.materials[index + 1])
            at = curve.body.find(name, start)
            for i in range(at, at + len(name)):
                curve.body_format[i].material_index = index + 1
            start = at + len(name)

    def render(self, number, members, regions):
        """The expression's front view (with its number and legend) and its three-quarter view,
        each composed over the background: float RGBA (height, width, 4)."""
        self._pose(members, regions)
        self.number.data.body = number
        self._legend(members)
        views = []
        for (location, rotation), labelled in ((self.front_view, True), (self.side_view, False)):
            self.camera.location, self.camera.rotation_euler = location, rotation
            for text in (self.number, self.members):
                text.hide_render = not labelled
            views.append(self._shot(f"{number}_{len(views)}"))
        return views

    def _shot(self, name):
        path = os.path.join(self.folder, f"tile_{name}.png")
        self.scene.render.filepath = path
        bpy.ops.render.render(write_still=True, scene=self.scene.name)
        image = bpy.data.images.load(path)
        try:
            width, height = image.size
            pixels = np.empty(width * height * 4, dtype=np.float32)
            image.pixels.foreach_get(pixels)
        finally:
            bpy.data.images.remove(image)
            os.remove(path)
        tile = pixels.reshape(height, width, 4)
        alpha = tile[:, :, 3:]
        tile[:, :, :3] = tile[:, :, :3] * alpha + BACKGROUND * (1 - alpha)
        tile[:, :, 3] = 1.0
        return tile

    def remove(self):
        for obj in self.created:
            data = obj.data
            bpy.data.objects.remove(obj)
            if isinstance(data, bpy.types.Camera):
                bpy.data.cameras.remove(data)
            elif isinstance(data, bpy.types.Mesh):
                bpy.data.meshes.remove(data)
            else:
                bpy.data.curves.remove(data)
        for material in self.materials:
            bpy.data.materials.remove(material)
        bpy.data.scenes.remove(self.scene)
        os.rmdir(self.folder)


def _save_png(pixels, path):
    height, width = pixels.shape[:2]
    image = bpy.data.images.new("Shapesmith Reference Sheet", width, height, alpha=False)
    try:
        image.pixels.foreach_set(pixels.ravel())
        image.filepath_raw = os.path.abspath(path)
        image.file_format = "PNG"
        image.save()
    finally:
        bpy.data.images.remove(image)

