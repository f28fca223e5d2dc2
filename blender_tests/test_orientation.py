"""The rig's front in any orientation: the sample turned in its mesh data packs to the same
expressions and conflicts as it is, its found front and up are the turned -Y and +Z, the
object's own rotation changes nothing (the tools read mesh coordinates), a picked camera is
the front, and the reference sheet is the same picture whichever way the mesh is stored."""

import json

import bpy
import numpy as np
import pytest
from mathutils import Matrix

from conftest import file_digest, make_active, run_batch

# Signed permutations (exact in float32): 90 degrees about X takes -Y (the sample's front)
# to -Z and +Z to -Y; 90 degrees about Z takes -Y to +X and the lateral X to Y.
ABOUT_X = ((1, 0, 0), (0, 0, -1), (0, 1, 0))
ABOUT_Z = ((0, -1, 0), (1, 0, 0), (0, 0, 1))
TURNS = {"about-x": (ABOUT_X, "0"), "about-z": (ABOUT_Z, "1")}


def turn_mesh(obj, rows):
    """Rotates the mesh data itself, every shape key with it."""
    matrix = Matrix([(*row, 0) for row in rows] + [(0, 0, 0, 1)])
    obj.data.transform(matrix, shape_keys=True)
    obj.data.update()


def pack(obj, **settings):
    make_active(obj)
    for key, value in settings.items():
        setattr(obj.shapesmith.pack, key, value)
    assert bpy.ops.shapesmith.pack_expressions() == {"FINISHED"}
    result = obj.shapesmith.pack.result
    expressions = [sorted(m.name for m in e.members) for e in result.expressions]
    conflicts = sorted((tuple(sorted((c.first, c.second))), c.reasons) for c in result.conflicts)
    return expressions, conflicts, json.loads(result.params_json)


@pytest.fixture(scope="module")
def as_stored(sample_path, shapesmith):
    """The sample's packing as it is stored (facing -Y, Z up)."""
    bpy.ops.wm.open_mainfile(filepath=sample_path)
    return pack(bpy.data.objects["Template"])


def test_the_sample_is_found_facing_minus_y_with_z_up(as_stored):
    expressions, conflicts, params = as_stored
    assert params["front"] == [0.0, -1.0, 0.0] and params["up"] == [0.0, 0.0, 1.0]
    assert params["front_source"] == "found" and params["camera_direction"] == [0.0, -1.0, 0.0]
    assert any("occlusion" in reasons for _, reasons in conflicts)  # the front matters


@pytest.mark.parametrize("turn", TURNS, ids=list(TURNS))
def test_a_turned_mesh_packs_as_the_stored_one(sample, as_stored, turn):
    rows, lateral = TURNS[turn]
    template = bpy.data.objects["Template"]
    turn_mesh(template, rows)
    bpy.context.scene.shapesmith.symmetry_axis = lateral  # the face's left-right is now this axis
    expressions, conflicts, params = pack(template)
    turned = np.array(rows, dtype=np.float64)
    assert np.allclose(params["front"], turned @ [0, -1, 0], atol=1e-9)
    assert np.allclose(params["up"], turned @ [0, 0, 1], atol=1e-9)
    assert expressions == as_stored[0]
    assert conflicts == as_stored[1]


def test_an_object_rotation_changes_nothing(sample, as_stored):
    """The tools read the mesh's own coordinates: turning the object only moves it in the scene."""
    template = bpy.data.objects["Template"]
    template.rotation_euler = (1.2, 0.3, 2.0)
    template.scale = (2.0, 2.0, 2.0)
    bpy.context.view_layer.update()
    assert pack(template) == as_stored


def test_a_turned_mesh_without_its_symmetry_axis_is_told_which_it_is(sample, shapesmith):
    """Symmetry settings left at X on a face whose left-right is now Y: the front is still
    found (every coordinate plane is tried) and the user is told which axis to set."""
    packing = shapesmith.blender.packing
    template = bpy.data.objects["Template"]
    turn_mesh(template, ABOUT_Z)
    report = packing.pack_object(template, **packing.packing_options(template, axis=0))
    assert report["front"] == [1.0, 0.0, 0.0] and report["up"] == [0.0, 0.0, 1.0]
    assert any("mirror-symmetric across Y = 0, not X = 0" in w for w in report["warnings"]), report["warnings"]


def test_a_picked_camera_is_the_front(sample, as_stored):
    template = bpy.data.objects["Template"]
    camera = bpy.data.objects.new("Side Camera", bpy.data.cameras.new("Side Camera"))
    bpy.context.scene.collection.objects.link(camera)
    # At +X looking along -X, its up along +Z: the face seen from its side.
    camera.location = (5.0, 0.0, 0.0)
    camera.rotation_euler = (np.pi / 2, 0.0, np.pi / 2)
    bpy.context.view_layer.update()
    expressions, conflicts, params = pack(template, front_camera=camera)
    assert params["front_source"] == "camera" and params["front_camera"] == "Side Camera"
    assert np.allclose(params["front"], [1, 0, 0], atol=1e-6) and np.allclose(params["up"], [0, 0, 1], atol=1e-6)
    assert np.allclose(params["camera_direction"], [1, 0, 0], atol=1e-6)  # what the occlusion test used
    assert conflicts != as_stored[1]  # seen from the side, other shapes hide each other
    # A camera in front of the face gives the found front's conflicts back.
    camera.location, camera.rotation_euler = (0.0, -5.0, 0.0), (np.pi / 2, 0.0, 0.0)
    bpy.context.view_layer.update()
    expressions, conflicts, params = pack(template, front_camera=camera)
    assert np.allclose(params["camera_direction"], [0, -1, 0], atol=1e-6)
    assert (expressions, conflicts) == as_stored[:2]


def sheet_pixels(obj, path):
    make_active(obj)
    assert bpy.ops.shapesmith.render_reference_sheet(filepath=path, tile_width=48, tile_height=60) == {"FINISHED"}
    image = bpy.data.images.load(path)
    pixels = np.empty(image.size[0] * image.size[1] * 4, np.float32)
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    return pixels


def test_the_reference_sheet_is_the_same_whichever_way_the_mesh_is_stored(sample, tmp_path):
    template = bpy.data.objects["Template"]
    pack(template)
    stored = sheet_pixels(template, str(tmp_path / "stored.png"))
    turn_mesh(template, ABOUT_X)
    template.rotation_euler = (0.0, 0.0, 1.0)
    pack(template)
    turned = sheet_pixels(template, str(tmp_path / "turned.png"))
    assert stored.shape == turned.shape
    assert np.abs(stored - turned).max() < 0.02


def test_batch_pack_takes_a_camera_and_reports_the_front(sample, tmp_path):
    camera = bpy.data.objects.new("Front Camera", bpy.data.cameras.new("Front Camera"))
    bpy.context.scene.collection.objects.link(camera)
    camera.location, camera.rotation_euler = (0.0, -5.0, 0.0), (np.pi / 2, 0.0, 0.0)
    path = str(tmp_path / "with-camera.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path, copy=True)
    digest = file_digest(path)
    found = tmp_path / "found.json"
    run_batch("pack", "--input", path, "--object", "Template", "--json", str(found), check=True)
    report = json.loads(found.read_text())
    assert (report["front"], report["up"], report["front_source"]) == ([0.0, -1.0, 0.0], [0.0, 0.0, 1.0], "found")
    picked = tmp_path / "camera.json"
    run_batch("pack", "--input", path, "--object", "Template", "--camera", "Front Camera", "--json", str(picked), check=True)
    report = json.loads(picked.read_text())
    assert report["front_source"] == "camera" and report["front_camera"] == "Front Camera"
    assert np.allclose(report["front"], [0, -1, 0], atol=1e-6) and np.allclose(report["up"], [0, 0, 1], atol=1e-6)
    wrong = run_batch("pack", "--input", path, "--object", "Template", "--camera", "Template")
    assert wrong.returncode == 2 and wrong.stderr.strip().splitlines() == ["shapesmith: error: 'Template' is a mesh, not a camera"]
    assert file_digest(path) == digest
