"""The ARKit template the extension ships (`assets/arkit_template.npz`, made by the build from
the CC0 MakeHuman head and its 52 ARKit face units, see scripts/arkit_template.py): added to
the scene as a head with its 52 keys and its eyes, teeth, tongue and lashes as face parts, so
that a rigger who installed only the zip has a template to wrap from."""

import os

import numpy as np

from .face_parts import store_parts
from .mesh_arrays import MeshDataError

ASSET = os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "assets", "arkit_template.npz")
NAME = "ARKit Template"
# Marks the objects Add ARKit Template made (the head holds the asset's credit).
PROPERTY = "shapesmith_bundled_template"


def load():
    """The asset's arrays, the keys made dense: {neutral (N, 3), faces (F, 4), uv (F, 4, 2),
    face_part (F,), part_names, shape_names, deltas (K, N, 3), credit}."""
    if not os.path.isfile(ASSET):
        raise MeshDataError(
            f"the bundled ARKit template is missing from this Shapesmith ({ASSET}): reinstall the extension"
        )
    with np.load(ASSET, allow_pickle=False) as stored:
        arrays = {name: stored[name] for name in stored.files}
    offsets = arrays["key_offsets"]
    deltas = np.zeros((len(arrays["shape_names"]), len(arrays["neutral"]), 3), dtype=np.float32)
    for k in range(len(offsets) - 1):
        rows = slice(int(offsets[k]), int(offsets[k + 1]))
        deltas[k, arrays["key_vertices"][rows]] = arrays["key_deltas"][rows] * arrays["key_scale"][k]
    arrays["deltas"] = deltas
    return arrays


def _part_mesh(name, arrays, part):
    """The mesh of one part: its faces, their vertices renumbered, its UVs. Returns (mesh,
    the asset's vertex of each of its vertices)."""
    import bpy

    faces = arrays["faces"][arrays["face_part"] == part].astype(np.int64)
    used = np.unique(faces)
    local = np.searchsorted(used, faces)
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(arrays["neutral"][used].tolist(), [], local.tolist())
    uv = mesh.uv_layers.new(name="UVMap")
    uv.data.foreach_set("uv", arrays["uv"][arrays["face_part"] == part].astype(np.float32).ravel())
    mesh.shade_smooth()
    mesh.validate()
    return mesh, used


def add_template(scene, location=(0.0, 0.0, 0.0), collection=None):
    """The bundled template as objects in `scene`: the head `ARKit Template` with a Basis and
    the 52 keys (at value 0), each face part (`ARKit Template Eyes`, ...) parented to it with
    the keys that move it, listed as the head's face parts. Returns the head."""
    import bpy

    arrays = load()
    collection = collection or scene.collection
    objects = []
    for part, part_name in enumerate(arrays["part_names"]):
        name = NAME if part == 0 else f"{NAME} {part_name}"
        mesh, used = _part_mesh(name, arrays, part)
        obj = bpy.data.objects.new(name, mesh)
        collection.objects.link(obj)
        obj[PROPERTY] = str(arrays["credit"]) if part == 0 else NAME
        own = arrays["deltas"][:, used]
        moving = [k for k in range(len(own)) if part == 0 or np.any(own[k] != 0.0)]
        if moving:
            obj.shape_key_add(name="Basis", from_mix=False)
            rest = arrays["neutral"][used]
            for k in moving:
                key = obj.shape_key_add(name=str(arrays["shape_names"][k]), from_mix=False)
                key.points.foreach_set("co", (rest + own[k]).astype(np.float32).ravel())
                key.value = 0.0  # shape_key_add defaults to 1.0 in Blender 5.x
        if part:
            obj.parent = objects[0]
        objects.append(obj)
    head = objects[0]
    head.location = location
    store_parts(head, objects[1:])
    return head


def template_objects(head):
    """The head and the parts Add ARKit Template made with it."""
    return [head, *(child for child in head.children if PROPERTY in child.keys())]


def remove_template(head):
    """Removes the objects and meshes `add_template` made."""
    import bpy

    for obj in template_objects(head):
        mesh = obj.data
        bpy.data.objects.remove(obj)
        if mesh.users == 0:
            bpy.data.meshes.remove(mesh)
