"""The reference sheet: one front-view picture per packed expression, labelled with its
number and member shapes, tiled into one PNG to show an actor what to pose.

Blender's Python has no PIL, so labels are text objects rendered inside each tile, and the
tiles are put together with numpy. Everything is rendered headless with Workbench in a
scene made for the purpose, which is removed afterwards with everything it created; the
rig's shape key values are put back as they were."""

import math
import os
import tempfile
import textwrap

import numpy as np

import bpy

from .mesh_arrays import MeshDataError, read_positions

MARGIN = 0.06  # of the head's height, around the head in each tile
LABEL_SHARE = 0.24  # of each tile's height, under the head, for the member names
BACKGROUND = 1.0
GRID = 0.75


def render_reference_sheet(obj, path, tile_width=320, tile_height=400, columns=None):
    """Renders the expressions stored on `obj` and writes the sheet to `path` (PNG). Returns
    (width, height) of the sheet."""
    result = obj.shapesmith.pack.result
    if not result.done or not result.expressions:
        raise MeshDataError(f"'{obj.name}' has no packed expressions: run Pack Expressions first")
    key_blocks = obj.data.shape_keys.key_blocks if obj.data.shape_keys else {}
    expressions = [[m.name for m in e.members] for e in result.expressions]
    missing = sorted({name for names in expressions for name in names if name not in key_blocks})
    if missing:
        raise MeshDataError(f"shape key(s) {', '.join(missing)} no longer exist: pack again")
    columns = columns or math.ceil(math.sqrt(len(expressions)))
    rows = math.ceil(len(expressions) / columns)
    sheet = np.full((rows * tile_height, columns * tile_width, 4), BACKGROUND, dtype=np.float32)
    values = {kb.name: kb.value for kb in key_blocks}
    stage = _Stage(obj, tile_width, tile_height)
    try:
        for j, members in enumerate(expressions):
            for block in key_blocks:
                block.value = 1.0 if block.name in members else 0.0
            tile = stage.render(f"{j + 1}", members)
            row, column = divmod(j, columns)
            top = (rows - 1 - row) * tile_height  # image rows run bottom-up
            sheet[top : top + tile_height, column * tile_width : (column + 1) * tile_width] = tile
    finally:
        for name, value in values.items():
            key_blocks[name].value = value
        stage.remove()
    sheet[:, ::tile_width, :3] = GRID
    sheet[::tile_height, :, :3] = GRID
    _save_png(sheet, path)
    return sheet.shape[1], sheet.shape[0]


class _Stage:
    """A throwaway scene: the rig, an orthographic camera looking along +Y at the face (which
    looks towards -Y), and two text objects for the number and the members."""

    def __init__(self, obj, tile_width, tile_height):
        self.created = []
        self.folder = tempfile.mkdtemp(prefix="shapesmith-sheet-")
        self.scene = bpy.data.scenes.new("Shapesmith Reference Sheet")
        self.scene.collection.objects.link(obj)
        render = self.scene.render
        render.engine = "BLENDER_WORKBENCH"
        render.resolution_x, render.resolution_y, render.resolution_percentage = tile_width, tile_height, 100
        render.film_transparent = True
        render.image_settings.file_format = "PNG"
        render.image_settings.color_mode = "RGBA"
        self.scene.view_settings.view_transform = "Standard"
        shading = self.scene.display.shading
        shading.light, shading.color_type = "STUDIO", "OBJECT"

        world = np.c_[read_positions(obj), np.ones(len(obj.data.vertices))] @ np.array(obj.matrix_world).T
        low, high = world[:, :3].min(axis=0), world[:, :3].max(axis=0)
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
        camera.data.clip_end = 2 * distance + (high[1] - low[1])
        camera.location = (centre_x, low[1] - distance, top - frame_height / 2)
        camera.rotation_euler = (math.pi / 2, 0.0, 0.0)  # looks along +Y, Z up
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

    def _text(self, name, size, align):
        text = self._add(name, bpy.data.curves.new(name, "FONT"))
        text.data.size, text.data.align_x = size, align
        text.rotation_euler = (math.pi / 2, 0.0, 0.0)  # reads towards -Y, up along Z
        text.color = (0.05, 0.05, 0.05, 1.0)
        return text

    def _fit(self, text):
        """(size, wrapped text): the largest of a few sizes at which `text` fits the label area."""
        for scale in (1.0, 0.8, 0.65, 0.55, 0.45):
            size = self.line_height * scale
            lines = textwrap.wrap(text, max(12, int(self.frame_width / (0.48 * size))))
            if len(lines) * scale <= 4:
                break
        return size, "\n".join(lines)

    def render(self, number, members):
        """One tile, composed over the background: float RGBA (height, width, 4)."""
        self.number.data.body = number
        self.members.data.size, self.members.data.body = self._fit(", ".join(members))
        path = os.path.join(self.folder, f"tile_{number}.png")
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
            (bpy.data.cameras if isinstance(data, bpy.types.Camera) else bpy.data.curves).remove(data)
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

