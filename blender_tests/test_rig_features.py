"""What riggers build their rigs with: keys masked by vertex groups (a Left/Right split done
with groups), read as Blender shows them by every tool and carried onto a transfer's target."""

import importlib

import bpy
import numpy as np
import pytest

from conftest import make_active


def module(shapesmith, name):
    return importlib.import_module(f"{shapesmith.__name__}.blender.{name}")


def positions(obj, name):
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.shape_keys.key_blocks[name].data.foreach_get("co", co)
    return co.reshape(-1, 3)


def copy_of(obj, name):
    copy = obj.copy()
    copy.data = obj.data.copy()
    copy.name = copy.data.name = name
    bpy.context.scene.collection.objects.link(copy)
    return copy


def group_weights_of(obj, name):
    index = obj.vertex_groups[name].index
    weights = np.zeros(len(obj.data.vertices))
    for vertex in obj.data.vertices:
        for membership in vertex.groups:
            if membership.group == index:
                weights[vertex.index] = membership.weight
    return weights


def side_weights(obj):
    """Left and right weights with a soft midline: 1 on one side, 0 on the other, a ramp
    over the middle fifth of the head's width."""
    x = np.array([v.co.x for v in obj.data.vertices])
    ramp = np.clip(0.5 + x / (0.2 * (x.max() - x.min())), 0.0, 1.0)
    return ramp, 1.0 - ramp


def split_by_groups(obj, shape, weights):
    """Replaces `shape` by halves: keys `<shape>SideA/B` holding the whole shape, each masked
    by a vertex group of `weights`."""
    keys = obj.data.shape_keys.key_blocks
    whole = positions(obj, shape)
    for side, w in zip("AB", weights):
        group = obj.vertex_groups.new(name=f"side{side}")
        for v in np.flatnonzero(w > 0):
            group.add([int(v)], float(w[v]), "REPLACE")
        block = obj.shape_key_add(name=f"{shape}Side{side}", from_mix=False)
        block.data.foreach_set("co", whole.ravel())
        block.vertex_group = group.name
    obj.shape_key_remove(keys[shape])


def split_explicitly(obj, shape, weights):
    """The same halves written out: each key holds the shape's delta times the weight."""
    keys = obj.data.shape_keys.key_blocks
    basis, whole = positions(obj, keys[0].name), positions(obj, shape)
    for side, w in zip("AB", weights):
        block = obj.shape_key_add(name=f"{shape}Side{side}", from_mix=False)
        block.data.foreach_set("co", (basis + (whole - basis) * w[:, None].astype(np.float32)).ravel())
    obj.shape_key_remove(keys[shape])


def masked_and_split(shape="browInnerUp"):
    template = bpy.data.objects["Template"]
    weights = side_weights(template)
    masked, split = copy_of(template, "Masked"), copy_of(template, "Split")
    split_by_groups(masked, shape, weights)
    split_explicitly(split, shape, weights)
    return masked, split, weights


def test_a_split_done_with_groups_pairs_and_packs_like_split_keys(sample, shapesmith):
    masked, split, _ = masked_and_split()
    read_rig = module(shapesmith, "mesh_arrays").read_rig
    masked_rig, split_rig = read_rig(masked), read_rig(split)
    assert masked_rig.names == split_rig.names
    np.testing.assert_allclose(masked_rig.deltas, split_rig.deltas, atol=1e-6)
    pairs = {}
    for obj in (masked, split):
        make_active(obj)
        assert bpy.ops.shapesmith.analyze_rig() == {"FINISHED"}
        pairs[obj.name] = sorted(tuple(sorted((p.first, p.second))) for p in obj.shapesmith.pairs)
    assert ("browInnerUpSideA", "browInnerUpSideB") in pairs["Masked"]
    assert pairs["Masked"] == pairs["Split"]
    packed = {}
    for obj in (masked, split):
        make_active(obj)
        assert bpy.ops.shapesmith.pack_expressions() == {"FINISHED"}
        packed[obj.name] = [sorted(m.name for m in e.members) for e in obj.shapesmith.pack.result.expressions]
    assert packed["Masked"] == packed["Split"]


def test_a_transfer_creates_the_masking_group_and_shows_the_masked_shape(sample):
    masked, split, weights = masked_and_split()
    target = bpy.data.objects["Target_Boy"]
    twin = copy_of(target, "Target_Boy_Split")
    for source, onto in ((masked, target), (split, twin)):
        bpy.context.scene.shapesmith.transfer.source = source
        make_active(onto)
        assert bpy.ops.shapesmith.transfer_shape_keys() == {"FINISHED"}
    keys = target.data.shape_keys.key_blocks
    basis = positions(target, "Basis")
    for side, w in zip("AB", weights):
        name = f"browInnerUpSide{side}"
        assert keys[name].vertex_group == f"side{side}"
        np.testing.assert_allclose(group_weights_of(target, f"side{side}"), w, atol=1e-6)
        # What Blender shows (the stored delta times the group's weight) is the transfer of the
        # explicitly split key.
        shown = (positions(target, name) - basis) * w[:, None]
        expected = positions(twin, name) - positions(twin, "Basis")
        assert np.abs(expected).max() > 1e-4
        np.testing.assert_allclose(shown, expected, atol=1e-5 * np.abs(basis).max())


# --- names in any convention ---------------------------------------------------------------

CONVENTIONS = {
    "eyeBlinkLeft": ["eyeBlink_L", "eyeBlink.L", "eyeBlink.L.001", "L_eyeBlink", "EYEBLINK_LEFT", "eyeBlink_l",
                     "blendShape2.eyeBlinkLeft", "head_blendShapes.eyeBlink_L", "Char:eyeBlinkLeft", "Eye_Blink_L",
                     "eCTRLEyesClosedL", "facs_bs_EyeBlinkLeft_div2", "EyeClosedLeft"],
    "mouthRollUpper": ["LipSuckUpper", "Mouth_Roll_In_Upper", "mouth_roll_upper"],
    "eyeLookOutLeft": ["Eye_L_Look_L"],
    "mouthSmileRight": ["MouthCornerPullRight", "Mouth_Smile_R", "R_mouthSmile"],
    "browDownLeft": ["Brow_Drop_L", "BrowLowererLeft"],
    "mouthShrugUpper": ["MouthRaiserUpper", "Mouth_Shrug_Upper"],
    "jawOpen": ["Jaw_Open", "JAWOPEN", "blendShape1.jawOpen"],
}


def test_every_convention_names_the_arkit_shape(shapesmith):
    names = module(shapesmith, "names")
    for arkit, spellings in CONVENTIONS.items():
        for spelling in spellings:
            assert names.shape_key(spelling) == names.shape_key(arkit), (spelling, arkit)
    assert names.shape_key("eyeBlinkLeft") != names.shape_key("eyeBlinkRight")
    assert names.shape_key("mouthLeft") != names.shape_key("mouthRight")
    table = names.read_name_map("blinky_a = eyeBlinkLeft  # mine\nblinky_b, eyeBlinkRight\n")
    assert names.counterpart("eyeBlinkRight", ["blinky_a", "blinky_b"], table) == "blinky_b"
    assert names.read_name_map('{"x": "jawOpen"}') == {"x": "jawOpen"}


def test_pairing_by_name_reads_every_convention(sample):
    """Halved right shapes (mirror error 0.5, beyond the geometric test) pair by name alone."""
    template = bpy.data.objects["Template"]
    renamed = {
        ("eyeBlinkLeft", "eyeBlinkRight"): ("EyesClosedL", "EyesClosedR"),
        ("browDownLeft", "browDownRight"): ("L_browDown", "R_browDown"),
        ("cheekSquintLeft", "cheekSquintRight"): ("CHEEKSQUINT_LEFT", "CHEEKSQUINT_RIGHT"),
        ("noseSneerLeft", "noseSneerRight"): ("noseSneer.L.001", "noseSneer.R.001"),
    }
    keys = template.data.shape_keys.key_blocks
    basis = positions(template, "Basis")
    for (left, right), (new_left, new_right) in renamed.items():
        halved = basis + 0.5 * (positions(template, right) - basis)
        keys[right].data.foreach_set("co", halved.ravel())
        keys[left].name, keys[right].name = new_left, new_right
    make_active(template)
    bpy.context.scene.shapesmith.pair_by_name = True
    assert bpy.ops.shapesmith.analyze_rig() == {"FINISHED"}
    found = {tuple(sorted((p.first, p.second))): p.source for p in template.shapesmith.pairs}
    for left, right in renamed.values():
        assert found.get(tuple(sorted((left, right)))) == "NAME", (left, right, found)


def test_transfer_writes_onto_the_targets_own_names_and_the_users_table(sample):
    target = bpy.data.objects["Target_Boy"]
    target.shape_key_add(name="Basis", from_mix=False)
    for name in ("Eye_Blink_L", "blinky_b"):
        target.shape_key_add(name=name, from_mix=False).value = 0.0
    scene = bpy.context.scene
    for _ in range(2):
        assert bpy.ops.shapesmith.add_name_row() == {"FINISHED"}
    assert bpy.ops.shapesmith.remove_name_row() == {"FINISHED"}
    row = scene.shapesmith.name_map[0]
    row.theirs, row.standard = "blinky_b", "eyeBlinkRight"
    scene.shapesmith.transfer.source = bpy.data.objects["Template"]
    scene.shapesmith.transfer.overwrite = True
    make_active(target)
    assert bpy.ops.shapesmith.transfer_shape_keys() == {"FINISHED"}
    keys = target.data.shape_keys.key_blocks
    assert "eyeBlinkLeft" not in keys and "eyeBlinkRight" not in keys
    assert len(keys) == 53
    basis = positions(target, "Basis")
    for name in ("Eye_Blink_L", "blinky_b"):
        assert np.abs(positions(target, name) - basis).max() > 1e-3, name


def test_a_capture_in_other_conventions_drives_the_arkit_keys(sample, shapesmith, tmp_path):
    import csv

    from conftest import run_batch

    columns = ["EyeClosedLeft", "LipSuckUpper", "Mouth_Smile_R", "myJaw"]
    path = str(tmp_path / "take.csv")
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["Timecode", "BlendShapeCount", *columns])
        for f in range(4):
            writer.writerow([f"00:00:01:{f:02d}.000", 4, 0.1 * f, 0.2, 0.3, 0.4])
    name_map = tmp_path / "names.txt"
    name_map.write_text("myJaw = jawOpen\n")
    blend, out, report = str(tmp_path / "in.blend"), str(tmp_path / "out.blend"), str(tmp_path / "capture.json")
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    run_batch("import-capture", "--input", blend, "--object", "Template", "--capture", path, "--output", out,
              "--json", report, "--name-map", str(name_map), check=True)
    import json

    used = json.load(open(report))["columns_used"]
    assert used == {"EyeClosedLeft": ["eyeBlinkLeft"], "LipSuckUpper": ["mouthRollUpper"],
                    "Mouth_Smile_R": ["mouthSmileRight"], "myJaw": ["jawOpen"]}
    bad = run_batch("import-capture", "--input", blend, "--object", "Template", "--capture", path, "--output", out,
                    "--name-map", str(tmp_path / "missing.txt"))
    assert bad.returncode == 2 and "name map not found" in bad.stderr


# --- subsets, re-runs and sculpted fixes ----------------------------------------------------


def transfer(target, **options):
    settings = bpy.context.scene.shapesmith.transfer
    settings.source = options.pop("source", bpy.data.objects["Template"])
    for key, value in options.items():
        setattr(settings, key, value)
    make_active(target)
    return bpy.ops.shapesmith.transfer_shape_keys()


def test_only_ticked_keys_are_written_and_a_rerun_keeps_the_others(sample):
    target = bpy.data.objects["Target_Boy"]
    settings = bpy.context.scene.shapesmith.transfer
    settings.source = bpy.data.objects["Template"]
    assert bpy.ops.shapesmith.list_template_keys(tick="NONE") == {"FINISHED"}
    assert len(settings.key_choice) == 52 and not any(item.chosen for item in settings.key_choice)
    for item in settings.key_choice:
        item.chosen = item.name.startswith("eyeBlink") or item.name == "jawOpen"
    assert transfer(target, only_ticked=True) == {"FINISHED"}
    keys = target.data.shape_keys.key_blocks
    assert sorted(kb.name for kb in keys[1:]) == ["eyeBlinkLeft", "eyeBlinkRight", "jawOpen"]
    blink = positions(target, "eyeBlinkLeft").copy()
    for item in settings.key_choice:
        item.chosen = item.name == "mouthClose"
    assert transfer(target, only_ticked=True, overwrite=True) == {"FINISHED"}
    assert sorted(kb.name for kb in keys[1:]) == ["eyeBlinkLeft", "eyeBlinkRight", "jawOpen", "mouthClose"]
    np.testing.assert_array_equal(positions(target, "eyeBlinkLeft"), blink)
    for item in settings.key_choice:
        item.chosen = False
    with pytest.raises(RuntimeError, match="no shape keys chosen"):
        transfer(target, only_ticked=True)


def test_keep_sculpted_changes_adds_the_users_edits_onto_the_new_result(sample):
    template = bpy.data.objects["Template"]
    target = bpy.data.objects["Target_Boy"]
    twin = copy_of(target, "Target_Boy_Fresh")
    assert transfer(target) == {"FINISHED"}
    # The rigger fixes jawOpen by hand on the target.
    edit = np.zeros((len(target.data.vertices), 3), dtype=np.float32)
    edit[::50, 2] = 0.01
    fixed = positions(target, "jawOpen") + edit
    target.data.shape_keys.key_blocks["jawOpen"].data.foreach_set("co", fixed.ravel())
    # The template's jawOpen changes; the transfer runs again.
    basis = positions(template, "Basis")
    stronger = basis + 1.2 * (positions(template, "jawOpen") - basis)
    template.data.shape_keys.key_blocks["jawOpen"].data.foreach_set("co", stronger.ravel())
    assert transfer(target, overwrite=True, keep_sculpted=True) == {"FINISHED"}
    assert transfer(twin, overwrite=True, keep_sculpted=False) == {"FINISHED"}
    fresh = positions(twin, "jawOpen") - positions(twin, "Basis")
    np.testing.assert_allclose(positions(target, "jawOpen") - positions(target, "Basis"), fresh + edit, atol=1e-6)
    # Keys the rigger did not touch are the fresh result; without Keep Sculpted Changes the
    # edit is gone.
    np.testing.assert_allclose(positions(target, "mouthClose"), positions(twin, "mouthClose"), atol=1e-6)
    assert transfer(target, overwrite=True, keep_sculpted=False) == {"FINISHED"}
    np.testing.assert_allclose(positions(target, "jawOpen") - positions(target, "Basis"), fresh, atol=1e-6)


def test_analyze_rig_keeps_edited_pairs_unless_reset(sample):
    template = bpy.data.objects["Template"]
    make_active(template)
    assert bpy.ops.shapesmith.analyze_rig() == {"FINISHED"}
    pairs = template.shapesmith.pairs
    found = len(pairs)
    blink = next(p for p in pairs if "eyeBlinkLeft" in (p.first, p.second))
    blink.first, blink.second = "eyeBlinkLeft", "eyeSquintRight"
    assert blink.source == "USER"
    assert bpy.ops.shapesmith.analyze_rig() == {"FINISHED"}
    names = {(p.first, p.second): p.source for p in pairs}
    assert names[("eyeBlinkLeft", "eyeSquintRight")] == "USER"
    # Found pairs with a shape of the user's pair make way for it.
    assert not any(p.source != "USER" and {p.first, p.second} & {"eyeBlinkLeft", "eyeSquintRight"} for p in pairs)
    assert bpy.ops.shapesmith.analyze_rig(reset_pairs=True) == {"FINISHED"}
    assert len(pairs) == found and all(p.source != "USER" for p in pairs)


def test_batch_transfers_the_keys_given_and_refuses_a_pattern_matching_none(sample, tmp_path):
    from conftest import run_batch

    blend, out = str(tmp_path / "in.blend"), str(tmp_path / "out.blend")
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    run_batch("transfer", "--input", blend, "--source", "Template", "--target", "Target_Boy", "--keys", "eyeBlink*,jawOpen",
              "--output", out, check=True)
    bpy.ops.wm.open_mainfile(filepath=out)
    keys = bpy.data.objects["Target_Boy"].data.shape_keys.key_blocks
    assert sorted(kb.name for kb in keys[1:]) == ["eyeBlinkLeft", "eyeBlinkRight", "jawOpen"]
    # A re-run with the user's names writes onto the target's own keys and says so.
    keys["eyeBlinkLeft"].name = "blinky"
    names = tmp_path / "names.txt"
    names.write_text("blinky = eyeBlinkLeft\n")
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)
    report = str(tmp_path / "transfer.json")
    run_batch("transfer", "--input", blend, "--source", "Template", "--target", "Target_Boy", "--keys", "eyeBlinkLeft",
              "--overwrite", "--name-map", str(names), "--json", report, "--output", out, check=True)
    import json

    assert json.load(open(report))["targets"][0]["written_onto"] == {"eyeBlinkLeft": "blinky"}
    bad = run_batch("transfer", "--input", blend, "--source", "Template", "--target", "Target_Boy", "--keys", "nose*,eyeBlonk*",
                    "--output", out)
    assert bad.returncode == 2 and "'eyeBlonk*' matches no shape key" in bad.stderr


# --- correctives ---------------------------------------------------------------------------


def test_a_corrective_is_transferred_on_top_of_its_base(sample, shapesmith):
    template = bpy.data.objects["Template"]
    keys = template.data.shape_keys.key_blocks
    basis = positions(template, "Basis")
    smile = positions(template, "mouthSmileLeft") - basis
    # mouthSmileLeft becomes a corrective on jawOpen adding the same smile.
    keys["mouthSmileLeft"].data.foreach_set("co", (positions(template, "jawOpen") + smile).ravel())
    keys["mouthSmileLeft"].relative_key = keys["jawOpen"]
    # Every tool sees what the corrective adds to its base.
    rig = module(shapesmith, "mesh_arrays").read_rig(template)
    np.testing.assert_allclose(rig.deltas[rig.names.index("mouthSmileLeft")], smile, atol=1e-6)
    plain = copy_of(template, "Plain")
    plain_keys = plain.data.shape_keys.key_blocks
    plain_keys["mouthSmileLeft"].relative_key = plain_keys["Basis"]
    plain_keys["mouthSmileLeft"].data.foreach_set("co", (basis + smile).ravel())
    target = bpy.data.objects["Target_Boy"]
    twin = copy_of(target, "Target_Boy_Plain")
    assert transfer(target) == {"FINISHED"}
    assert transfer(twin, source=plain) == {"FINISHED"}
    written = target.data.shape_keys.key_blocks
    assert written["mouthSmileLeft"].relative_key == written["jawOpen"]
    added = positions(target, "mouthSmileLeft") - positions(target, "jawOpen")
    expected = positions(twin, "mouthSmileLeft") - positions(twin, "Basis")
    assert np.abs(expected).max() > 1e-3
    np.testing.assert_allclose(added, expected, atol=1e-6)
    np.testing.assert_allclose(positions(target, "jawOpen"), positions(twin, "jawOpen"), atol=1e-6)


# --- drivers onto the target's rig -----------------------------------------------------------


def rig_for(obj, name):
    """An armature with a `jaw` bone deforming `obj`."""
    armature = bpy.data.armatures.new(name)
    rig = bpy.data.objects.new(name, armature)
    bpy.context.scene.collection.objects.link(rig)
    make_active(rig)
    bpy.ops.object.mode_set(mode="EDIT")
    bone = armature.edit_bones.new("jaw")
    bone.head, bone.tail = (0, 0, 0), (0, 0.1, 0)
    bpy.ops.object.mode_set(mode="OBJECT")
    obj.modifiers.new("Armature", "ARMATURE").object = rig
    return rig


def drive(keys, name, target_id, variable_type="TRANSFORMS", bone=""):
    fcurve = keys.key_blocks[name].driver_add("value")
    fcurve.driver.type = "SCRIPTED"
    fcurve.driver.expression = "v"
    variable = fcurve.driver.variables.new()
    variable.name, variable.type = "v", variable_type
    variable.targets[0].id = target_id
    variable.targets[0].bone_target = bone
    variable.targets[0].transform_type = "ROT_X"
    return fcurve


def test_copy_drivers_points_them_at_the_targets_rig(sample, shapesmith):
    template, target = bpy.data.objects["Template"], bpy.data.objects["Target_Boy"]
    template_rig, target_rig = rig_for(template, "Template_Rig"), rig_for(target, "BoyArmature")
    empties = {}
    for name in ("Template_Controls", "Target_Boy_Controls", "Slider", "Slider_Boy", "Elsewhere"):
        empties[name] = bpy.data.objects.new(name, None)
        bpy.context.scene.collection.objects.link(empties[name])
    keys = template.data.shape_keys
    drive(keys, "jawOpen", template_rig, bone="jaw")
    drive(keys, "eyeBlinkLeft", empties["Template_Controls"])
    drive(keys, "mouthClose", empties["Slider"])
    drive(keys, "mouthFunnel", empties["Elsewhere"])
    transfer_module, shape_keys = module(shapesmith, "transfer"), module(shapesmith, "shape_keys")
    result = transfer_module.transfer_object(template, target, keys=["jawOpen", "eyeBlinkLeft", "mouthClose", "mouthFunnel"])
    _, _, warnings = shape_keys.write_transferred_keys(result, copy_drivers=True, driver_map={"Slider": "Slider_Boy"})
    drivers = {d.data_path: d.driver.variables["v"].targets[0] for d in target.data.shape_keys.animation_data.drivers}
    assert drivers['key_blocks["jawOpen"].value'].id == target_rig
    assert drivers['key_blocks["jawOpen"].value'].bone_target == "jaw"
    assert drivers['key_blocks["eyeBlinkLeft"].value'].id == empties["Target_Boy_Controls"]
    assert drivers['key_blocks["mouthClose"].value'].id == empties["Slider_Boy"]
    assert drivers['key_blocks["mouthFunnel"].value'].id == empties["Elsewhere"]
    assert [w for w in warnings if "still points at" in w] == [
        "driver on key_blocks[\"mouthFunnel\"].value: variable 'v' still points at 'Elsewhere' "
        "(no counterpart found: add it to the driver map)"]
    # The target's armature without the bone: said, not hidden.
    target_rig.data.bones["jaw"].name = "chin"
    _, _, warnings = shape_keys.write_transferred_keys(result, overwrite=True, copy_drivers=True)
    assert any("reads bone 'jaw', which 'BoyArmature' does not have" in w for w in warnings), warnings
    with pytest.raises(ValueError, match="'Nowhere'"):
        shape_keys.write_transferred_keys(result, overwrite=True, copy_drivers=True, driver_map={"Slider": "Nowhere"})
