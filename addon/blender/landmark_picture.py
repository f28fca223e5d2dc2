"""A front view of the head with its landmarks drawn, rendered headless with Workbench.

Everything the picture needs (scene, camera, head stand-in, spheres) is created in a scratch
scene and removed afterwards, so rendering never changes the .blend.
"""

import math

import bmesh
import bpy
import numpy as np
from mathutils import Matrix

from .front import front_view_matrix
from .landmarks import bbox_diagonal
from .mesh_arrays import MeshDataError

HEAD_COLOUR = (0.78, 0.74, 0.70, 1.0)
# First-round landmarks (the single cover) red; backup rounds of the multi-cover orange.
ROUND_COLOURS = ((0.85, 0.05, 0.05, 1.0), (1.0, 0.55, 0.0, 1.0))
SPHERE_SIZE = 0.007  # radius, as a fraction of the bbox diagonal
MARGIN = 1.1


def evaluated_world_positions(obj, depsgraph):
    """World positions of the evaluated mesh (current shape key values)."""
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        co = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
        mesh.vertices.foreach_get("co", co)
    finally:
        evaluated.to_mesh_clear()
    matrix = np.array(obj.matrix_world)
    return co.reshape(-1, 3) @ matrix[:3, :3].T + matrix[:3, 3]


def render_landmarks(obj, path, resolution=768):
    """Renders `obj` from its front (`render_points`) with a sphere at each empty of its
    landmark layout, in the pose the shape keys are in now, and writes a PNG to `path`."""
    layout = obj.shapesmith.landmarks
    if not layout.done or layout.collection is None or not layout.collection.objects:
        raise MeshDataError(f"'{obj.name}' has no landmark layout yet: run Place Landmarks first")
    depsgraph = bpy.context.evaluated_depsgraph_get()
    dots = [(np.array(empty.evaluated_get(depsgraph).matrix_world.translation),
             ROUND_COLOURS[min(empty.get("round", 0), len(ROUND_COLOURS) - 1)])
            for empty in layout.collection.objects]
    return render_points(obj, dots, path, resolution)


def render_vertices(obj, vertices, path, colour=ROUND_COLOURS[0], resolution=768):
    """The same front view with a sphere on each of `vertices` (e.g. a vertex group's layout)."""
    head = evaluated_world_positions(obj, bpy.context.evaluated_depsgraph_get())
    return render_points(obj, [(head[v], colour) for v in vertices], path, resolution)


def render_points(obj, dots, path, resolution):
    """The front view of `obj` with a sphere at each (world position, colour) of `dots`, seen
    from the face's front (`front.view_front`): the picture is staged in a frame where the
    front looks towards -Y and up is +Z, whatever the mesh's or the object's orientation."""
    view = front_view_matrix(obj)
    head = evaluated_world_positions(obj, bpy.context.evaluated_depsgraph_get()) @ view[:3, :3].T + view[:3, 3]
    dots = [(view[:3, :3] @ np.asarray(position) + view[:3, 3], colour) for position, colour in dots]
    low, high = head.min(axis=0), head.max(axis=0)
    radius = SPHERE_SIZE * bbox_diagonal(obj)
    context_scene = bpy.context.scene

    scene = bpy.data.scenes.new("Shapesmith Landmark Picture")
    created_objects, created_meshes = [], []
    camera_data = bpy.data.cameras.new("Shapesmith Picture Camera")
    try:
        scene.render.engine = "BLENDER_WORKBENCH"
        scene.render.resolution_x = scene.render.resolution_y = resolution
        scene.render.resolution_percentage = 100
        scene.render.image_settings.file_format = "PNG"
        scene.render.filepath = path
        shading = scene.display.shading
        shading.light = "STUDIO"
        shading.color_type = "OBJECT"
        shading.show_specular_highlight = False
        scene.view_settings.view_transform = "Standard"
        scene.world = context_scene.world

        stand_in = bpy.data.objects.new("Shapesmith Picture Head", obj.data)  # shares the posed shape keys
        stand_in.matrix_world = Matrix((view @ np.array(obj.matrix_world)).tolist())
        stand_in.color = HEAD_COLOUR
        created_objects.append(stand_in)

        sphere = bpy.data.meshes.new("Shapesmith Picture Sphere")
        created_meshes.append(sphere)
        bm = bmesh.new()
        bmesh.ops.create_icosphere(bm, subdivisions=2, radius=radius)
        bm.to_mesh(sphere)
        bm.free()
        for position, colour in dots:
            dot = bpy.data.objects.new("Shapesmith Picture Landmark", sphere)
            dot.location = position
            dot.color = colour
            created_objects.append(dot)

        camera_data.type = "ORTHO"
        camera_data.ortho_scale = MARGIN * float(max(high[0] - low[0], high[2] - low[2]))
        depth = float(high[1] - low[1])
        camera_data.clip_end = 4.0 * depth + 1.0
        camera = bpy.data.objects.new("Shapesmith Picture Camera", camera_data)
        camera.location = (0.5 * (low[0] + high[0]), low[1] - depth, 0.5 * (low[2] + high[2]))
        camera.rotation_euler = (math.pi / 2, 0.0, 0.0)  # local -Z (the view) onto world +Y
        created_objects.append(camera)
        for created in created_objects:
            scene.collection.objects.link(created)
        scene.camera = camera
        bpy.ops.render.render(write_still=True, scene=scene.name)
    finally:
        for created in created_objects:
            bpy.data.objects.remove(created, do_unlink=True)
        for mesh in created_meshes:
            bpy.data.meshes.remove(mesh)
        bpy.data.cameras.remove(camera_data)
        bpy.data.scenes.remove(scene)
    return path
