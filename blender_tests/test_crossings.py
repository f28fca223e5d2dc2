"""Show Crossings and batch `crossings`: on a small mesh built here, the faces a shape key
pushes through another part of the mesh (and only those, not the neutral's own crossings) are
selected or listed, the key is shown alone, and a bad request changes nothing."""

import json

import bpy
import numpy as np
import pytest

from conftest import file_digest, make_active, run_batch


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


def test_batch_lists_each_keys_crossing_faces_and_saves_the_selection(sample, tmp_path):
    """The batch counterpart lists the same faces as the button, per key, and with --select
    saves a copy showing that key alone with its faces selected; the input file is unchanged."""
    build_sheets()
    source = str(tmp_path / "sheets.blend")
    bpy.ops.wm.save_as_mainfile(filepath=source, copy=True)
    digest = file_digest(source)
    out, saved = tmp_path / "crossings.json", str(tmp_path / "selected.blend")
    proc = run_batch("crossings", "--input", source, "--object", "Sheets", "--select", "through",
                     "--json", str(out), "--output", saved, check=True)
    assert "1 of 2 keys add crossings" in proc.stdout
    report = json.loads(out.read_text())
    assert report["faces_total"] == 3
    assert report["shapes"] == {"through": {"count": 2, "faces": [0, 1]}, "clear": {"count": 0, "faces": []}}
    assert file_digest(source) == digest
    bpy.ops.wm.open_mainfile(filepath=saved)
    obj = bpy.data.objects["Sheets"]
    assert selected_faces(obj) == [0, 1] and obj.active_shape_key.name == "through" and obj.show_only_shape_key


@pytest.mark.parametrize("args, message", [
    (("--object", "Sheets", "--shapes", "through,nope"), "has no shape key 'nope'"),
    (("--object", "Nope"), "no object named 'Nope'"),
    (("--object", "Sheets", "--select", "through"), "--select SHAPE and --output OUT.blend go together"),
])
def test_batch_refuses_bad_requests_with_one_line(sample, tmp_path, args, message):
    build_sheets()
    source = str(tmp_path / "sheets.blend")
    bpy.ops.wm.save_as_mainfile(filepath=source, copy=True)
    proc = run_batch("crossings", "--input", source, *args)
    assert proc.returncode == 2 and message in proc.stderr and len(proc.stderr.strip().splitlines()) == 1
