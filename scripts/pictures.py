"""What the picture scripts (render_transfer.py, render_wrap.py, render_face_parts.py) share:
one object (or a face's objects) rendered alone by Workbench through an orthographic camera,
and tiles put side by side in one PNG."""

import bpy
import numpy as np


def render_alone(obj, location, direction, extent, size, path, *, clip_end=None):
    """Renders `obj` (an object, or a list of objects shown together; the scene's other
    meshes hidden) with the scene's Workbench shading, seen from `location` along `direction`
    through an orthographic camera `extent` across the frame's longer side, `size` pixels, to
    `path`. The caller sets the shading first."""
    scene = bpy.context.scene
    shown = set(obj) if isinstance(obj, (list, tuple)) else {obj}
    for other in scene.objects:
        other.hide_render = other not in shown and other.type == "MESH"
    camera = bpy.data.objects.get("RenderCamera")
    if camera is None:
        camera = bpy.data.objects.new("RenderCamera", bpy.data.cameras.new("RenderCamera"))
        scene.collection.objects.link(camera)
    camera.data.type = "ORTHO"
    camera.data.ortho_scale = extent
    if clip_end is not None:
        camera.data.clip_end = clip_end
    camera.location = location
    camera.rotation_euler = direction.to_track_quat("-Z", "Y").to_euler()
    scene.camera = camera
    scene.render.engine = "BLENDER_WORKBENCH"
    scene.render.resolution_x, scene.render.resolution_y = size
    scene.render.resolution_percentage = 100
    scene.render.filepath = path
    bpy.ops.render.render(write_still=True)


def tiled(paths, output):
    """The images at `paths` side by side with a white gap, saved as an 8-bit RGB PNG with
    full compression (a small file for the docs)."""
    images = [bpy.data.images.load(p, check_existing=False) for p in paths]
    width, height = images[0].size
    gap = np.ones((height, 6, 4), dtype=np.float32)
    row = []
    for image in images:
        row += [np.array(image.pixels[:], dtype=np.float32).reshape(height, width, 4), gap]
        bpy.data.images.remove(image)
    combined = np.concatenate(row[:-1], axis=1)
    result = bpy.data.images.new("tiled", combined.shape[1], height, alpha=False)
    result.pixels = combined.ravel()
    settings = bpy.context.scene.render.image_settings
    settings.file_format, settings.color_mode, settings.color_depth, settings.compression = "PNG", "RGB", "8", 100
    result.save_render(output)
    bpy.data.images.remove(result)
