"""Shape keys <-> numpy through `foreach_get`/`foreach_set`: the one place that reads a rig
out of Blender. Every check that can fail happens before anything is written.

Key positions go through `ShapeKey.points` (Blender 4.1+), not `ShapeKey.data`: `points` holds
the coordinates alone and copies them in one block, where `data` walks its items one by one
(150 keys of a 77k-vertex head: 0.013 s against 1.7 s to read, 100x faster to write)."""

from contextvars import ContextVar
from dataclasses import dataclass, field

import numpy as np

# Called as `(done, total, writing)` after each shape key read or written, so that an
# operator's progress advances through the Blender side of a big rig (150 keys of a 100k-vertex
# head take seconds to read and to write) as well as through the native work. A context
# variable rather than a parameter: keys are read several calls below every tool (face parts,
# training expressions, a wrap's two transfers), and written by one shared function.
key_progress = ContextVar("key_progress", default=None)


def report_key(done, total, writing=False):
    callback = key_progress.get()
    if callback is not None:
        callback(done, total, writing)


class MeshDataError(ValueError):
    """The object cannot be used as a rig as it is; the message says what to change."""


@dataclass
class Rig:
    """A rig as plain arrays: neutral (N, 3), deltas (K, N, 3) against the reference key,
    triangles (T, 3) from `loop_triangles`, shape key names; float32/int32, C-contiguous."""

    neutral: np.ndarray
    deltas: np.ndarray
    triangles: np.ndarray
    names: list
    warnings: list = field(default_factory=list)


def check_mesh(obj, need_shape_keys=True, topology=True):
    """Raises MeshDataError unless `obj` is a mesh in Object Mode with usable faces (and
    shape keys beyond the Basis when asked), and, with `topology`, without the faults
    `check_topology` names."""
    if obj is None:
        raise MeshDataError("no object given: select a mesh")
    if obj.type != "MESH":
        raise MeshDataError(f"'{obj.name}' is a {obj.type.lower()}, not a mesh")
    if obj.mode == "EDIT":
        raise MeshDataError(f"'{obj.name}' is in Edit Mode: switch to Object Mode first")
    mesh = obj.data
    if len(mesh.vertices) == 0 or len(mesh.polygons) == 0:
        raise MeshDataError(f"'{obj.name}' has no faces")
    sizes = np.empty(len(mesh.polygons), dtype=np.int32)
    mesh.polygons.foreach_get("loop_total", sizes)
    ngons = np.flatnonzero(sizes > 4)
    if len(ngons):
        raise MeshDataError(
            f"'{obj.name}' has {len(ngons)} n-gon(s) (faces with more than 4 corners, e.g. face {ngons[0]}): "
            "triangulate or quadrangulate them first"
        )
    if topology:
        check_topology(obj)
    if need_shape_keys:
        keys = mesh.shape_keys
        if keys is None or len(keys.key_blocks) < 2:
            raise MeshDataError(f"'{obj.name}' has no shape keys besides the Basis")


def check_topology(obj):
    """Raises MeshDataError for the faults the native `mesh_faults` finds (the same for the
    panel and batch), naming the first offending edge, vertex or face. Loose edges are no
    fault: the tools read faces only."""
    from .. import native

    mesh = obj.data
    triangles = read_triangles(obj)
    faces = np.empty(len(mesh.loop_triangles), dtype=np.int32)
    mesh.loop_triangles.foreach_get("polygon_index", faces)
    positions = read_positions(obj)
    if mesh.shape_keys is not None:  # the rest shape, which the vertex array can lag behind
        mesh.shape_keys.reference_key.points.foreach_get("co", positions.reshape(-1))
    faults = native.module().mesh_faults(positions, triangles)
    name = obj.name
    fault = faults["duplicate_triangles"]
    if fault["count"]:
        earlier, later = (int(faces[t]) for t in fault["first"])
        raise MeshDataError(
            f"'{name}' has faces listed twice ({fault['count']} triangle(s); e.g. face {later} repeats face {earlier}): "
            "delete the copies"
        )
    fault = faults["zero_area_triangles"]
    if fault["count"]:
        raise MeshDataError(
            f"'{name}' has degenerate faces of zero area ({fault['count']} triangle(s); e.g. face {int(faces[fault['first']])}): "
            "remove them (Edit Mode > Mesh > Clean Up > Degenerate Dissolve)"
        )
    fault = faults["non_manifold_edges"]
    if fault["count"]:
        a, b = fault["first"]
        raise MeshDataError(
            f"'{name}' has {fault['count']} edge(s) shared by three or more faces (e.g. the edge between "
            f"vertices {a} and {b}): split or delete the extra faces (Select > Select All by Trait > Non Manifold)"
        )
    fault = faults["loose_vertices"]
    if fault["count"]:
        raise MeshDataError(
            f"'{name}' has {fault['count']} loose vertices in no face (e.g. vertex {fault['first']}): "
            "delete them (Edit Mode > Mesh > Clean Up > Delete Loose)"
        )


def read_positions(obj):
    """Vertex positions of the mesh itself (its Basis), float32 (N, 3)."""
    mesh = obj.data
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def rest_positions(obj):
    """The mesh's rest shape, float32 (N, 3): its reference key when it has shape keys (the
    vertex array can lag behind a reference key written by script), else its vertices."""
    mesh = obj.data
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    if mesh.shape_keys is not None:
        mesh.shape_keys.reference_key.points.foreach_get("co", co)
    else:
        mesh.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def read_triangles(obj):
    mesh = obj.data
    mesh.calc_loop_triangles()
    tris = np.empty(len(mesh.loop_triangles) * 3, dtype=np.int32)
    mesh.loop_triangles.foreach_get("vertices", tris)
    return tris.reshape(-1, 3)


def group_weights(obj, names):
    """{group name: float32 weights (N,)} of `obj`'s vertex groups `names` (those it has);
    vertices outside a group weigh 0. One pass over the vertices for all groups."""
    wanted = {obj.vertex_groups[name].index: name for name in set(names) if name in obj.vertex_groups}
    weights = {name: np.zeros(len(obj.data.vertices), dtype=np.float32) for name in wanted.values()}
    if not wanted:
        return weights
    for vertex in obj.data.vertices:
        for membership in vertex.groups:
            name = wanted.get(membership.group)
            if name is not None:
                weights[name][vertex.index] = membership.weight
    return weights


def key_masks(obj, blocks):
    """{key name: weights (N,)} for the keys of `blocks` masked by a vertex group `obj` has
    (a Left/Right split done with groups). Blender shows such a key as its delta times the
    group's weight; a group name the object lacks masks nothing, as in Blender."""
    weights = group_weights(obj, [block.vertex_group for block in blocks if block.vertex_group])
    return {block.name: weights[block.vertex_group] for block in blocks if block.vertex_group in weights}


def read_rig(obj):
    """The object's rig: the delta of every shape key as Blender shows it (method, section 0): against
    the reference key, or, for a corrective (a key relative to another key), against its
    own base; a key masked by a vertex group times the group's weight. Pairing, Pack,
    Landmarks and Transfer all see the half a split key moves and what a corrective adds. The
    `REF_` keys Pack Expressions baked are mixes of the others, not shapes of the rig: every
    tool leaves them out."""
    check_mesh(obj, need_shape_keys=True)
    keys = obj.data.shape_keys
    reference = keys.reference_key
    n = len(obj.data.vertices)
    neutral = np.empty(n * 3, dtype=np.float32)
    reference.points.foreach_get("co", neutral)
    neutral = neutral.reshape(n, 3)
    baked = {b.name for b in obj.shapesmith.pack.baked}
    blocks = [kb for kb in keys.key_blocks if kb != reference and kb.name not in baked]
    if not blocks:
        raise MeshDataError(f"'{obj.name}' has only the shape keys Bake wrote: no shapes to work on")
    deltas = np.empty((len(blocks), n, 3), dtype=np.float32)
    masks = key_masks(obj, blocks)
    buffer, base = np.empty(n * 3, dtype=np.float32), np.empty(n * 3, dtype=np.float32)
    for k, block in enumerate(blocks):
        block.points.foreach_get("co", buffer)
        if block.relative_key in (reference, block):
            np.subtract(buffer.reshape(n, 3), neutral, out=deltas[k])
        else:
            block.relative_key.points.foreach_get("co", base)
            np.subtract(buffer, base, out=deltas[k].reshape(-1))
        if block.name in masks:
            deltas[k] *= masks[block.name][:, None]
        report_key(k + 1, len(blocks))
    return Rig(neutral, deltas, read_triangles(obj), [b.name for b in blocks], [])


def show_mesh(name, mesh, beside):
    """The object `name` showing `mesh`: a new one linked to the first collection of `beside`
    (else the scene's), or the existing one given `mesh` (its old mesh removed when nothing
    else uses it). For previews that a second run replaces."""
    import bpy

    obj = bpy.data.objects.get(name)
    if obj is None:
        obj = bpy.data.objects.new(name, mesh)
        collection = beside.users_collection[0] if beside.users_collection else bpy.context.scene.collection
        collection.objects.link(obj)
    else:
        old = obj.data
        obj.data = mesh
        if old.users == 0:
            bpy.data.meshes.remove(old)
    return obj
