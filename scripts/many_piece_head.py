"""The benches' many-piece head, in Blender: the 25k head of `bench_transfer.py` (the
Template with every edge cut once and its face cut again) given production_heads.py's many
pieces (every helper piece grown through the skin and moved to the front, the lashes copied,
each copy moving with its lashes in every shape), as a mesh object with the same shape keys.

    import many_piece_head
    obj = many_piece_head.build(template, mesh_arrays)   # in a bench run with the bpy Python
"""

import bpy
import numpy as np

import bench_transfer
import production_heads


def arrays(template, mesh_arrays):
    """The many-piece head's arrays (`production_heads.many_pieces` of the 25k head, the
    template onto itself: source = target) and its shape names; `mesh_arrays` is the
    extension's `blender.mesh_arrays`."""
    dense = bench_transfer.subdivided(template, template.name + "_25k_pieces_base", bench_transfer.FACE_EDGES)
    rig = mesh_arrays.read_rig(dense)
    bpy.data.objects.remove(dense)
    neutral = rig.neutral.astype(np.float64)
    head = {"source": neutral, "target": neutral, "deltas": rig.deltas.reshape(-1, 3).astype(np.float64),
            "triangles": rig.triangles.astype(np.int64)}
    return production_heads.many_pieces(head), rig.names


def build(template, mesh_arrays, name="Template_many_pieces"):
    """The many-piece head as a linked mesh object with a Basis and one key per shape."""
    head, names = arrays(template, mesh_arrays)
    n = len(head["source"])
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(head["source"].tolist(), [], head["triangles"].tolist())
    mesh.update()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.shape_key_add(name="Basis", from_mix=False)
    deltas = head["deltas"].reshape(len(names), n, 3)
    for k, shape in enumerate(names):
        key = obj.shape_key_add(name=shape, from_mix=False)
        key.value = 0.0  # shape_key_add's default differs between Blender versions
        key.data.foreach_set("co", np.ascontiguousarray(head["source"] + deltas[k], dtype=np.float32).ravel())
    return obj
