"""What riggers build their rigs with: keys masked by vertex groups (a Left/Right split done
with groups), read as Blender shows them by every tool and carried onto a transfer's target."""

import importlib

import bpy
import numpy as np

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
    row = scene.shapesmith.name_map.add()
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
