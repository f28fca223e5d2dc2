"""Where a shape key passes through the mesh itself: the faces whose triangles cross another
triangle when the mesh is posed at the key and did not cross it at rest (the pairs the
transfer report counts as added intersection). Used by Show Crossings and by
`scripts/render_transfer.py`."""

import numpy as np

from .. import native
from .mesh_arrays import MeshDataError, check_mesh, read_positions, read_triangles


def crossing_faces(obj, shape_name):
    """Bool per polygon of `obj`: True where the key `shape_name` makes a triangle of that face
    cross another one it did not cross at rest."""
    check_mesh(obj)
    mesh = obj.data
    key = mesh.shape_keys.key_blocks.get(shape_name)
    if key is None:
        raise MeshDataError(f"'{obj.name}' has no shape key '{shape_name}'")
    posed = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    key.points.foreach_get("co", posed)
    triangles = read_triangles(obj)
    crossed = native.module().intersecting_triangles(posed.reshape(-1, 3), triangles, rest=read_positions(obj))
    polygon_of_triangle = np.empty(len(mesh.loop_triangles), dtype=np.int32)
    mesh.loop_triangles.foreach_get("polygon_index", polygon_of_triangle)
    faces = np.zeros(len(mesh.polygons), dtype=bool)
    faces[polygon_of_triangle[crossed]] = True
    return faces


def face_corners(mesh, faces):
    """Bool per face corner (loop) of `mesh`: True on the corners of the faces `faces` marks."""
    loop_totals = np.empty(len(mesh.polygons), dtype=np.int32)
    mesh.polygons.foreach_get("loop_total", loop_totals)
    return np.repeat(faces, loop_totals)


def show_crossings(obj, shape_name):
    """Shows the key `shape_name` alone on `obj` and selects exactly its crossing faces (and
    their vertices), so Edit Mode or a face-select overlay points at what to fix. Returns the
    number of faces selected."""
    faces = crossing_faces(obj, shape_name)
    mesh = obj.data
    keys = mesh.shape_keys.key_blocks
    obj.active_shape_key_index = keys.find(shape_name)
    obj.show_only_shape_key = True
    corners = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("vertex_index", corners)
    vertices = np.zeros(len(mesh.vertices), dtype=bool)
    vertices[corners[face_corners(mesh, faces)]] = True
    mesh.vertices.foreach_set("select", vertices)
    mesh.edges.foreach_set("select", np.zeros(len(mesh.edges), dtype=bool))
    mesh.polygons.foreach_set("select", faces)
    mesh.update()
    return int(faces.sum())
