"""The foundation: the zip installs, the native core loads, Analyze Rig finds the true
symmetric pairs and antagonists of the MakeHuman rig, and bad input is refused cleanly."""

import glob
import importlib.util
import json
import os

import bpy
import numpy as np
import pytest

from conftest import file_digest, make_active, run_batch

# The MakeHuman face units are ARKit-named: every <name>Left/<name>Right is a symmetric pair
# except the two that move the same region sideways, which are antagonists.
ANTAGONISTS = {frozenset(("jawLeft", "jawRight")), frozenset(("mouthLeft", "mouthRight"))}


def true_pairs(names):
    pairs = {frozenset((n, n[:-4] + "Right")) for n in names if n.endswith("Left") and n[:-4] + "Right" in names}
    return pairs - ANTAGONISTS


def test_native_core_loads_from_the_installed_wheel(shapesmith):
    import shapesmith_native

    assert shapesmith.native.STATUS == f"native core {shapesmith_native.__version__}"
    assert "user_default" in shapesmith_native.__file__ or "extensions" in shapesmith_native.__file__
    assert issubclass(shapesmith_native.InvalidInputError, ValueError)
    assert issubclass(shapesmith_native.SolverError, RuntimeError)


def test_a_wheel_that_cannot_load_is_reported_with_this_and_the_built_platforms(shapesmith):
    # The add-on names this machine as Blender does when it matches wheels and zips to platforms.
    path = glob.glob(os.path.join(bpy.utils.system_resource("SCRIPTS"), "addons_core", "bl_pkg", "cli", "blender_ext.py"))
    spec = importlib.util.spec_from_file_location("blender_ext_for_test", path[0])
    blender_ext = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(blender_ext)
    assert shapesmith.native.this_platform() == blender_ext.platform_from_this_system()
    # The installed zip's manifest says which platforms it was built for.
    assert shapesmith.native.built_platforms() == [shapesmith.native.this_platform()]

    status = shapesmith.native.unavailable_status(
        ImportError("DLL load failed while importing shapesmith_native"), "windows-x64", ["linux-x64"])
    assert "on windows-x64" in status and "built for linux-x64" in status
    assert "install the Shapesmith zip for windows-x64" in status and "DLL load failed" in status
    status = shapesmith.native.unavailable_status(ImportError("broken"), "macos-arm64", ["macos-arm64", "macos-x64"])
    assert "built for macos-arm64, macos-x64 (reinstall the Shapesmith extension)" in status


def test_analyze_rig_finds_the_arkit_pairs_geometrically(sample):
    template = make_active(bpy.data.objects["Template"])
    assert bpy.ops.shapesmith.analyze_rig() == {"FINISHED"}
    props = template.shapesmith
    names = [kb.name for kb in template.data.shape_keys.key_blocks[1:]]
    assert props.analysis.shapes == 52 and props.analysis.vertices == len(template.data.vertices)
    found = {frozenset((p.first, p.second)) for p in props.pairs}
    expected = true_pairs(names)
    assert len(expected) == 18
    assert found == expected, f"missing {expected - found}, wrong {found - expected}"
    assert all(p.source == "GEOMETRY" for p in props.pairs)
    assert {frozenset((p.first, p.second)) for p in props.antagonists} == ANTAGONISTS


def test_pairs_survive_save_and_reload(sample, tmp_path):
    make_active(bpy.data.objects["Template"])
    bpy.ops.shapesmith.analyze_rig()
    before = [(p.first, p.second) for p in bpy.data.objects["Template"].shapesmith.pairs]
    path = str(tmp_path / "saved.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    after = [(p.first, p.second) for p in bpy.data.objects["Template"].shapesmith.pairs]
    assert after == before and len(after) == 18


def test_pairs_can_be_edited_by_hand(sample):
    template = make_active(bpy.data.objects["Template"])
    bpy.ops.shapesmith.analyze_rig()
    assert bpy.ops.shapesmith.add_pair() == {"FINISHED"}
    assert template.shapesmith.pairs[-1].source == "USER"
    assert len(template.shapesmith.pairs) == 19
    assert bpy.ops.shapesmith.remove_pair() == {"FINISHED"}
    assert len(template.shapesmith.pairs) == 18


def test_undo_brings_back_the_pairs_as_edited(sample):
    """Analyze Rig replaces the pair list, hand edits included; the list lives in the file's
    data (not in Python state), so undoing the step brings the edited list back."""
    template = make_active(bpy.data.objects["Template"])
    bpy.ops.shapesmith.analyze_rig()
    assert bpy.ops.shapesmith.remove_pair() == {"FINISHED"}
    edited = [(p.first, p.second) for p in template.shapesmith.pairs]
    bpy.ops.ed.undo_push(message="pairs edited")
    assert bpy.ops.shapesmith.analyze_rig() == {"FINISHED"}
    assert len(bpy.data.objects["Template"].shapesmith.pairs) == 18
    bpy.ops.ed.undo_push(message="analysed again")
    bpy.ops.ed.undo()
    assert [(p.first, p.second) for p in bpy.data.objects["Template"].shapesmith.pairs] == edited
    assert len(edited) == 17


def test_a_mesh_without_shape_keys_is_refused_and_left_unchanged(sample):
    target = make_active(bpy.data.objects["Target_OldMan"])
    with pytest.raises(RuntimeError, match="no shape keys"):
        bpy.ops.shapesmith.analyze_rig()
    assert not target.shapesmith.analysis.done and target.data.shape_keys is None


def test_nan_coordinates_are_refused_and_the_mesh_left_unchanged(sample):
    template = make_active(bpy.data.objects["Template"])
    key = template.data.shape_keys.key_blocks["jawOpen"]
    key.data[7].co.x = float("nan")
    with pytest.raises(RuntimeError, match="jawOpen.*vertex 7"):
        bpy.ops.shapesmith.analyze_rig()
    assert not template.shapesmith.analysis.done and len(template.shapesmith.pairs) == 0


def test_a_mesh_in_edit_mode_is_refused(sample, shapesmith):
    template = make_active(bpy.data.objects["Template"])
    bpy.ops.object.mode_set(mode="EDIT")
    try:
        with pytest.raises(RuntimeError, match="Object Mode"):
            bpy.ops.shapesmith.analyze_rig()
        with pytest.raises(ValueError, match="Edit Mode"):
            shapesmith.blender.analysis.analyze_object(template)
    finally:
        bpy.ops.object.mode_set(mode="OBJECT")
    assert not template.shapesmith.analysis.done


def test_ngons_are_read_as_blender_draws_them(sample, shapesmith):
    bpy.ops.mesh.primitive_cylinder_add(vertices=8)  # its caps are 8-gons
    cylinder = make_active(bpy.context.active_object)
    cylinder.shape_key_add(name="Basis", from_mix=False)
    bulge = cylinder.shape_key_add(name="bulge", from_mix=False)
    bulge.data[0].co.z += 0.5
    assert bpy.ops.shapesmith.analyze_rig() == {"FINISHED"}
    report = shapesmith.blender.analysis.analyze_object(cylinder)
    assert report["triangles"] == 2 * 8 + 2 * 6 and report["warnings"] == ["triangulated: 2 n-gons"]


def test_native_errors_name_the_offender(shapesmith):
    native = shapesmith.native.module()
    neutral = np.zeros((4, 3), np.float32)
    neutral[1, 0] = neutral[2, 1] = 1.0
    deltas = np.zeros((1, 4, 3), np.float32)
    with pytest.raises(native.InvalidInputError, match="vertex 9"):
        native.analyze_rig(neutral, deltas, np.array([[0, 1, 9]], np.int32), ["a"])
    with pytest.raises(ValueError, match=r"\(K, 4, 3\)"):
        native.analyze_rig(neutral, np.zeros((1, 3, 3), np.float32), np.array([[0, 1, 2]], np.int32), ["a"])
    with pytest.raises(ValueError, match="C-contiguous"):
        native.analyze_rig(np.asfortranarray(np.zeros((4, 3), np.float32)), deltas, np.array([[0, 1, 2]], np.int32), ["a"])


# --- batch -----------------------------------------------------------------------------


def test_batch_analyze_writes_name_pairs(sample_path, tmp_path):
    out = tmp_path / "analyze.json"
    digest = file_digest(sample_path)
    proc = run_batch("analyze", "--input", sample_path, "--object", "Template", "--json", str(out), check=True)
    report = json.loads(out.read_text())
    pairs = {frozenset(p) for p in report["symmetric_pairs"]}
    assert all(isinstance(p, list) and len(p) == 2 for p in report["symmetric_pairs"] + report["antagonists"])
    assert pairs == true_pairs(report_names(sample_path))
    assert {frozenset(p) for p in report["antagonists"]} == ANTAGONISTS
    assert "symmetric pairs (18)" in proc.stdout
    assert file_digest(sample_path) == digest


def report_names(path):
    bpy.ops.wm.open_mainfile(filepath=path)
    return [kb.name for kb in bpy.data.objects["Template"].data.shape_keys.key_blocks[1:]]


@pytest.mark.parametrize(
    "args, message",
    [
        (["--input", "/nonexistent/file.blend", "--object", "Template"], "input file not found"),
        (["--object", "Nobody"], "no object named 'Nobody'"),
        (["--object", "Target_OldMan"], "no shape keys"),
        (["--object", "Camera"], "not a mesh"),
    ],
)
def test_batch_bad_input_exits_with_one_line(sample_path, tmp_path, args, message):
    path = str(tmp_path / "input.blend")
    bpy.ops.wm.open_mainfile(filepath=sample_path)
    bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    bpy.context.scene.collection.objects.link(bpy.data.objects["Camera"])
    bpy.ops.wm.save_as_mainfile(filepath=path)
    digest = file_digest(path)
    if "--input" not in args:
        args = ["--input", path] + args
    proc = run_batch("analyze", *args)
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0] and lines[0].startswith("shapesmith: error:")
    assert file_digest(path) == digest
