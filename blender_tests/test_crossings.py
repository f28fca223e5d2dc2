"""Show Crossings: on a small mesh built here, the faces a shape key pushes through another
part of the mesh (and only those, not the neutral's own crossings) are selected, the key is
shown alone, and a bad request changes nothing."""

import bpy
import numpy as np
import pytest

from conftest import make_active


def build_sheets():
    """Three separate quads: A in z = 0, B above it in z = 0.5 (apart at rest), C upright
    through A's far edge (crossing A at rest: the neutral's own crossing). Key `through` drops
    B's near edge below A, so B, tilted, pierces A's middle; key `clear` lifts B further."""
    a = [(0, 0, 0), (1, 0, 0), (1, 1, 0), (0, 1, 0)]
    b = [(0.2, 0.2, 0.5), (0.8, 0.2, 0.5), (0.8, 0.8, 0.5), (0.2, 0.8, 0.5)]
    c = [(1.5, 0.9, -0.5), (1.5, 0.9, 0.5), (0.9, 0.9, 0.5), (0.9, 0.9, -0.5)]
    mesh = bpy.data.meshes.new("Sheets")
    mesh.from_pydata(a + b + c, [], [(0, 1, 2, 3), (4, 5, 6, 7), (8, 9, 10, 11)])
    obj = bpy.data.objects.new("Sheets", mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.shape_key_add(name="Basis")
    for name, near_edge, far_edge in (("through", -0.8, 0.0), ("clear", 0.3, 0.3)):
        key = obj.shape_key_add(name=name)
        key.value = 0.0
        for corner, dz in zip(range(4, 8), (near_edge, near_edge, far_edge, far_edge)):
            key.data[corner].co.z += dz
    return make_active(obj)


def selected_faces(obj):
    return [p.index for p in obj.data.polygons if p.select]


def test_the_faces_a_key_pushes_through_are_selected_and_the_rest_crossing_is_not(sample):
    obj = build_sheets()
    assert bpy.ops.shapesmith.show_crossings(shape="through") == {"FINISHED"}
    # A (face 0) and B (face 1) cross in the key; C (face 2) crosses A already at rest.
    assert selected_faces(obj) == [0, 1]
    assert obj.active_shape_key.name == "through" and obj.show_only_shape_key
    selected_vertices = [v.index for v in obj.data.vertices if v.select]
    assert selected_vertices == list(range(8))
    # Lifting B crosses nothing new: nothing selected (C through A is the neutral's own).
    assert bpy.ops.shapesmith.show_crossings(shape="clear") == {"FINISHED"}
    assert selected_faces(obj) == []


def test_an_unknown_key_is_refused_and_the_selection_kept(sample):
    obj = build_sheets()
    before = [p.select for p in obj.data.polygons]
    index = obj.active_shape_key_index
    with pytest.raises(RuntimeError, match="no shape key 'nope'"):
        bpy.ops.shapesmith.show_crossings(shape="nope")
    assert [p.select for p in obj.data.polygons] == before and obj.active_shape_key_index == index


def test_the_most_crossing_shape_of_a_transfer_has_a_few_faces_to_show(sample):
    """On a real transfer, the shape with the longest intersection curve has crossing faces,
    a small part of the head."""
    target = make_active(bpy.data.objects["Target_YoungWoman"])
    bpy.context.scene.shapesmith.transfer.source = bpy.data.objects["Template"]
    assert bpy.ops.shapesmith.transfer_shape_keys() == {"FINISHED"}
    longest = max(target.shapesmith.transfer.shapes, key=lambda s: s.length - s.template_length)
    assert bpy.ops.shapesmith.show_crossings(shape=longest.name) == {"FINISHED"}
    faces = np.array([p.select for p in target.data.polygons])
    assert 0 < faces.sum() < len(faces) // 10, (longest.name, faces.sum())
