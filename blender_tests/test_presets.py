"""The Rig presets shipped for common rigs: listed in the Rig panel's preset menu beside the
user's own and never deleted with them; each fills Shape Key Names so that a rig named in its
convention is read as the ARKit shapes (Import Capture's matching of the 52 ARKit columns,
which a wrong, missing or extra row changes); `--name-map` takes a preset's name in batch."""

import csv
import json
import os
from importlib import import_module

import bpy
import pytest

from conftest import run_batch

ARKIT = """browDownLeft browDownRight browInnerUp browOuterUpLeft browOuterUpRight cheekPuff cheekSquintLeft
cheekSquintRight eyeBlinkLeft eyeBlinkRight eyeLookDownLeft eyeLookDownRight eyeLookInLeft eyeLookInRight
eyeLookOutLeft eyeLookOutRight eyeLookUpLeft eyeLookUpRight eyeSquintLeft eyeSquintRight eyeWideLeft eyeWideRight
jawForward jawLeft jawOpen jawRight mouthClose mouthDimpleLeft mouthDimpleRight mouthFrownLeft mouthFrownRight
mouthFunnel mouthLeft mouthLowerDownLeft mouthLowerDownRight mouthPressLeft mouthPressRight mouthPucker mouthRight
mouthRollLower mouthRollUpper mouthShrugLower mouthShrugUpper mouthSmileLeft mouthSmileRight mouthStretchLeft
mouthStretchRight mouthUpperUpLeft mouthUpperUpRight noseSneerLeft noseSneerRight tongueOut""".split()

# Each convention's names for the ARKit shapes (one line: the ARKit shape, then the rig's
# names for it, several when the convention splits it in parts), as Character Creator 4,
# Daz Genesis 8.1's FACS morphs and VRCFaceTracking's ARKit comparison name them.
CHARACTER_CREATOR = """
browDownLeft Brow_Drop_L | browDownRight Brow_Drop_R | browInnerUp Brow_Raise_Inner_L Brow_Raise_Inner_R
browOuterUpLeft Brow_Raise_Outer_L | browOuterUpRight Brow_Raise_Outer_R | cheekPuff Cheek_Puff_L Cheek_Puff_R
cheekSquintLeft Cheek_Raise_L | cheekSquintRight Cheek_Raise_R | eyeBlinkLeft Eye_Blink_L | eyeBlinkRight Eye_Blink_R
eyeLookDownLeft Eye_L_Look_Down | eyeLookDownRight Eye_R_Look_Down | eyeLookInLeft Eye_L_Look_R
eyeLookInRight Eye_R_Look_L | eyeLookOutLeft Eye_L_Look_L | eyeLookOutRight Eye_R_Look_R | eyeLookUpLeft Eye_L_Look_Up
eyeLookUpRight Eye_R_Look_Up | eyeSquintLeft Eye_Squint_L | eyeSquintRight Eye_Squint_R | eyeWideLeft Eye_Wide_L
eyeWideRight Eye_Wide_R | jawForward Jaw_Forward | jawLeft Jaw_L | jawOpen Jaw_Open | jawRight Jaw_R
mouthClose Mouth_Close | mouthDimpleLeft Mouth_Dimple_L | mouthDimpleRight Mouth_Dimple_R | mouthFrownLeft Mouth_Frown_L
mouthFrownRight Mouth_Frown_R | mouthFunnel Mouth_Funnel_Up_L Mouth_Funnel_Up_R | mouthLeft Mouth_L
mouthLowerDownLeft Mouth_Down_Lower_L | mouthLowerDownRight Mouth_Down_Lower_R | mouthPressLeft Mouth_Press_L
mouthPressRight Mouth_Press_R | mouthPucker Mouth_Pucker_Up_L Mouth_Pucker_Up_R Mouth_Pucker_Down_L Mouth_Pucker_Down_R
mouthRight Mouth_R | mouthRollLower Mouth_Roll_In_Lower_L Mouth_Roll_In_Lower_R
mouthRollUpper Mouth_Roll_In_Upper_L Mouth_Roll_In_Upper_R | mouthShrugLower Mouth_Shrug_Lower
mouthShrugUpper Mouth_Shrug_Upper | mouthSmileLeft Mouth_Smile_L | mouthSmileRight Mouth_Smile_R
mouthStretchLeft Mouth_Stretch_L | mouthStretchRight Mouth_Stretch_R | mouthUpperUpLeft Mouth_Up_Upper_L
mouthUpperUpRight Mouth_Up_Upper_R | noseSneerLeft Nose_Sneer_L | noseSneerRight Nose_Sneer_R | tongueOut Tongue_Out
"""
DAZ = """
eyeBlinkLeft facs_jnt_EyeBlinkLeft | eyeBlinkRight facs_jnt_EyeBlinkRight | eyeSquintLeft facs_bs_EyeSquintLeft_div2
eyeSquintRight facs_bs_EyeSquintRight_div2 | browInnerUp facs_ctrl_BrowInnerUp | cheekPuff facs_ctrl_CheekPuff
cheekSquintLeft facs_bs_CheekSquintLeft_div2 | cheekSquintRight facs_bs_CheekSquintRight_div2
noseSneerLeft facs_bs_NoseSneerLeft_div2 | noseSneerRight facs_bs_NoseSneerRight_div2 | jawForward facs_jnt_JawForward
jawLeft facs_jnt_JawLeft | jawOpen facs_jnt_JawOpen | jawRight facs_jnt_JawRight | mouthClose facs_bs_MouthClose_div2
mouthFunnel facs_bs_MouthFunnel_div2 | mouthPucker facs_bs_MouthPucker_div2 | mouthLeft facs_bs_MouthLeft_div2
mouthRight facs_bs_MouthRight_div2 | mouthRollLower facs_bs_MouthRollLower_div2
mouthRollUpper facs_bs_MouthRollUpper_div2
mouthShrugLower facs_bs_MouthShrugLower_div2 | mouthShrugUpper facs_bs_MouthShrugUpper_div2
mouthDimpleLeft facs_bs_MouthDimpleLeft_div2 | mouthDimpleRight facs_bs_MouthDimpleRight_div2
mouthFrownLeft facs_bs_MouthFrownLeft_div2 | mouthFrownRight facs_bs_MouthFrownRight_div2
mouthLowerDownLeft facs_bs_MouthLowerDownLeft_div2 | mouthLowerDownRight facs_bs_MouthLowerDownRight_div2
mouthPressLeft facs_bs_MouthPressLeft_div2 | mouthPressRight facs_bs_MouthPressRight_div2
mouthSmileLeft facs_bs_MouthSmileLeft_div2 | mouthSmileRight facs_bs_MouthSmileRight_div2
mouthStretchLeft facs_bs_MouthStretchLeft_div2 | mouthStretchRight facs_bs_MouthStretchRight_div2
mouthUpperUpLeft facs_bs_MouthUpperUpLeft_div2 | mouthUpperUpRight facs_bs_MouthUpperUpRight_div2
tongueOut facs_bs_TongueOut
"""
UNIFIED = """
eyeLookUpRight EyeLookUpRight | eyeLookDownRight EyeLookDownRight | eyeLookInRight EyeLookInRight
eyeLookOutRight EyeLookOutRight | eyeLookUpLeft EyeLookUpLeft | eyeLookDownLeft EyeLookDownLeft
eyeLookInLeft EyeLookInLeft | eyeLookOutLeft EyeLookOutLeft | eyeBlinkRight EyeClosedRight | eyeBlinkLeft EyeClosedLeft
eyeSquintRight EyeSquintRight | eyeSquintLeft EyeSquintLeft | eyeWideRight EyeWideRight | eyeWideLeft EyeWideLeft
browDownRight BrowDownRight | browDownLeft BrowDownLeft | browInnerUp BrowInnerUp | browOuterUpRight BrowOuterUpRight
browOuterUpLeft BrowOuterUpLeft | noseSneerRight NoseSneerRight | noseSneerLeft NoseSneerLeft
cheekSquintRight CheekSquintRight | cheekSquintLeft CheekSquintLeft | cheekPuff CheekPuff | jawOpen JawOpen
mouthClose MouthClosed | jawRight JawRight | jawLeft JawLeft | jawForward JawForward | mouthRollUpper LipSuckUpper
mouthRollLower LipSuckLower | mouthFunnel LipFunnel | mouthPucker LipPucker | mouthUpperUpRight MouthUpperUpRight
mouthUpperUpLeft MouthUpperUpLeft | mouthLowerDownRight MouthLowerDownRight | mouthLowerDownLeft MouthLowerDownLeft
mouthSmileRight MouthSmileRight | mouthSmileLeft MouthSmileLeft | mouthFrownRight MouthFrownRight
mouthFrownLeft MouthFrownLeft | mouthStretchRight MouthStretchRight | mouthStretchLeft MouthStretchLeft
mouthDimpleRight MouthDimpleRight | mouthDimpleLeft MouthDimpleLeft | mouthShrugUpper MouthRaiserUpper
mouthShrugLower MouthRaiserLower | mouthPressRight MouthPressRight | mouthPressLeft MouthPressLeft | tongueOut TongueOut
"""


def parsed(text):
    rows = [entry.split() for line in text.strip().splitlines() for entry in line.split("|")]
    return {row[0]: row[1:] for row in rows}


def suffixed(separator):
    """ARKit's names with the side as a suffix (`eyeBlink_L`); jawLeft/mouthLeft name a direction."""
    convention = {}
    for name in ARKIT:
        side = next((s for s in ("Left", "Right") if name.endswith(s)), None)
        keep = side is None or name in ("jawLeft", "jawRight", "mouthLeft", "mouthRight")
        convention[name] = [name if keep else name[: -len(side)] + separator + side[0]]
    return convention


# Menu name: (the convention's names, the ARKit shapes it has no row for).
SHIPPED = {
    "ARKit": ({name: [name] for name in ARKIT}, []),
    "Suffix L R (underscore)": (suffixed("_"), []),
    "Suffix .L .R": (suffixed("."), []),
    "Character Creator": (parsed(CHARACTER_CREATOR), []),
    "Daz Genesis 8.1": (parsed(DAZ), ["browDownLeft", "browDownRight", "browOuterUpLeft", "browOuterUpRight",
                                      "eyeLookDownLeft", "eyeLookDownRight", "eyeLookInLeft", "eyeLookInRight",
                                      "eyeLookOutLeft", "eyeLookOutRight", "eyeLookUpLeft", "eyeLookUpRight",
                                      "eyeWideLeft", "eyeWideRight"]),
    "Unified Expressions": (parsed(UNIFIED), ["mouthLeft", "mouthRight"]),
}


def module(shapesmith, name):
    return import_module(f"{shapesmith.__name__}.{name}")


def test_the_tables_in_this_test_name_each_arkit_shape_once():
    for menu_name, (convention, left_out) in SHIPPED.items():
        assert sorted(list(convention) + left_out) == sorted(ARKIT), menu_name
        names = [name for names in convention.values() for name in names]
        assert len(names) == len(set(names)), menu_name


def test_the_rig_menu_lists_the_shipped_presets_beside_the_users_and_keeps_them(shapesmith):
    settings = bpy.context.scene.shapesmith
    settings.name_map.clear()
    assert bpy.ops.shapesmith.add_rig_preset(name="Our Studio") == {"FINISHED"}
    calls = []

    class Layout:
        def __getattr__(self, method):
            def record(*args, **kwargs):
                calls.append((method, kwargs.get("text")))
                return self

            return record

    menu = bpy.types.SHAPESMITH_PT_rig_presets
    members = {k: getattr(menu, k) for k in ("preset_subdir", "preset_operator", "preset_add_operator")}
    drawn = type("Menu", (), {"layout": Layout(), "bl_idname": menu.__name__, "path_menu": bpy.types.Menu.path_menu,
                              **members})
    bpy.types.Menu.draw_preset(drawn(), bpy.context)
    listed = [text for method, text in calls if method == "operator" and text]
    assert set(SHIPPED) | {"Our Studio"} <= set(listed), listed

    shipped = bpy.utils.preset_find("Character Creator", "shapesmith/rig", display_name=True)
    assert bpy.ops.shapesmith.add_rig_preset(name="Character Creator", remove_name=True) == {"CANCELLED"}
    assert os.path.isfile(shipped)
    assert bpy.ops.shapesmith.add_rig_preset(name="Our Studio", remove_name=True) == {"FINISHED"}
    assert "Our Studio" not in module(shapesmith, "ui.presets").preset_names("rig")


@pytest.mark.parametrize("menu_name", list(SHIPPED))
def test_a_shipped_preset_reads_its_conventions_rig_as_the_arkit_shapes(shapesmith, menu_name):
    """Picked as the menu picks it, over a table left from another rig; the rig has every name
    of the convention, and the capture's 52 ARKit columns must drive exactly the keys meaning
    them (a shape in parts: all its parts)."""
    convention, left_out = SHIPPED[menu_name]
    settings = bpy.context.scene.shapesmith
    settings.pair_by_name = False
    settings.name_map.clear()
    row = settings.name_map.add()
    row.theirs, row.standard = "eyeBlinkLeft", "jawOpen"
    assert module(shapesmith, "ui.presets").apply_preset("rig", menu_name)
    assert settings.pair_by_name
    table = module(shapesmith, "blender.names").scene_name_map(bpy.context.scene)
    # A row for every name the convention spells otherwise than ARKit, and no other.
    assert set(table) == {name for arkit, names in convention.items() for name in names if name != arkit}, menu_name

    rig = [name for names in convention.values() for name in names]
    matched, unmatched, undriven = module(shapesmith, "blender.capture").match_columns(ARKIT, rig, name_map=table)
    assert {column: sorted(keys) for column, keys in matched.items()} == \
        {arkit: sorted(names) for arkit, names in convention.items()}
    assert sorted(unmatched) == sorted(left_out) and undriven == []


def write_capture(path, columns):
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["Timecode", "BlendShapeCount", *columns])
        for f in range(3):
            writer.writerow([f"00:00:01:{f:02d}.000", len(columns), *([0.1 * f] * len(columns))])


def test_batch_name_map_takes_a_shipped_or_saved_presets_name(sample, shapesmith, tmp_path):
    """Character Creator's parts of mouthFunnel and mouthPucker are those shapes only through
    the preset's table; a preset saved by the user works alike; an unknown name exits 2."""
    keys = bpy.data.objects["Template"].data.shape_keys.key_blocks
    renamed = {"eyeLookInLeft": "Eye_L_Look_R", "mouthFunnel": "Mouth_Funnel_Up_L",
               "mouthPucker": "Mouth_Pucker_Down_R", "jawOpen": "myJaw"}
    for arkit, theirs in renamed.items():
        keys[arkit].name = theirs
    settings = bpy.context.scene.shapesmith
    settings.name_map.clear()
    row = settings.name_map.add()
    row.theirs, row.standard = "myJaw", "jawOpen"
    assert bpy.ops.shapesmith.add_rig_preset(name="Our Studio") == {"FINISHED"}
    settings.name_map.clear()
    take = str(tmp_path / "take.csv")
    write_capture(take, list(renamed))
    blend, out, report = str(tmp_path / "in.blend"), str(tmp_path / "out.blend"), str(tmp_path / "capture.json")
    bpy.ops.wm.save_as_mainfile(filepath=blend, copy=True)

    def used(*flags):
        run_batch("import-capture", "--input", blend, "--object", "Template", "--capture", take, "--output", out,
                  "--json", report, *flags, check=True)
        return json.load(open(report))["columns_used"]

    assert used("--name-map", "Character Creator") == {"eyeLookInLeft": ["Eye_L_Look_R"],
                                                      "mouthFunnel": ["Mouth_Funnel_Up_L"],
                                                      "mouthPucker": ["Mouth_Pucker_Down_R"]}
    bpy.ops.wm.open_mainfile(filepath=out)  # the saved copy keeps the table, as picking the preset does
    assert module(shapesmith, "blender.names").scene_name_map(bpy.context.scene)["Mouth_Funnel_Up_L"] == "mouthFunnel_L"
    assert used() == {"eyeLookInLeft": ["Eye_L_Look_R"]}
    assert used("--name-map", "Our Studio") == {"eyeLookInLeft": ["Eye_L_Look_R"], "jawOpen": ["myJaw"]}
    bad = run_batch("import-capture", "--input", blend, "--object", "Template", "--capture", take, "--output", out,
                    "--name-map", "Genesis 12")
    assert bad.returncode == 2 and "name map not found" in bad.stderr and "Character Creator" in bad.stderr, bad.stderr
    assert bpy.ops.shapesmith.add_rig_preset(name="Our Studio", remove_name=True) == {"FINISHED"}
