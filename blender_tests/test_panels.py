"""The sidebar as a rigger meets it: every Shapesmith panel and sub-panel draws on a fresh file
and after results exist, each tool's main button comes before its settings, and no setting a
rigger sees is named by a paper's symbol."""

import bpy
import pytest

from conftest import make_active


class Recorder:
    """A stand-in for a panel's layout that records each call: (method, first argument, text)."""

    def __init__(self, calls):
        self.calls = calls

    def __getattr__(self, name):
        def record(*args, **kwargs):
            self.calls.append((name, args[1] if name == "prop" and len(args) > 1 else (args[0] if args else None),
                               kwargs.get("text", "")))
            return self

        return record


def draw(panel_type):
    calls = []
    if hasattr(panel_type, "poll") and not panel_type.poll(bpy.context):
        return None
    # The panel's own methods on a plain object: Blender makes panel instances itself.
    members = {}
    for cls in reversed(panel_type.__mro__):
        if cls.__module__.startswith("bpy") or cls is object:
            continue
        members.update({k: v for k, v in vars(cls).items() if not k.startswith("__")})
    members["layout"] = Recorder(calls)
    panel_type.draw(type("P", (), members)(), bpy.context)
    return calls


def shapesmith_panels():
    """The sidebar's panels (the header's preset popovers are Blender's own preset lists)."""
    return [getattr(bpy.types, name) for name in dir(bpy.types)
            if name.startswith("SHAPESMITH_PT_") and not name.endswith("_presets")]


def test_every_panel_draws_before_and_after_results(sample):
    make_active(bpy.data.objects["Template"])
    panels = shapesmith_panels()
    assert len(panels) >= 8
    for panel in panels:
        draw(panel)
    assert bpy.ops.shapesmith.pack_expressions() == {"FINISHED"}
    for panel in panels:
        draw(panel)


@pytest.mark.parametrize("panel, button", [("SHAPESMITH_PT_rig", "shapesmith.analyze_rig"),
                                           ("SHAPESMITH_PT_pack", "shapesmith.pack_expressions"),
                                           ("SHAPESMITH_PT_landmarks", "shapesmith.place_landmarks"),
                                           ("SHAPESMITH_PT_transfer", "shapesmith.transfer_shape_keys"),
                                           ("SHAPESMITH_PT_transfer_personalise", "shapesmith.personalise_shape_keys"),
                                           ("SHAPESMITH_PT_wrap", "shapesmith.generate_arkit_keys"),
                                           ("SHAPESMITH_PT_wrap_pairs", "shapesmith.propose_point_pairs")])
def test_the_main_button_comes_first(sample, panel, button):
    make_active(bpy.data.objects["Template"])
    calls = draw(getattr(bpy.types, panel))
    first_widget = next(call for call in calls if call[0] in ("operator", "prop"))
    assert first_widget[:2] == ("operator", button), calls[:5]


def test_no_setting_a_rigger_sees_is_named_by_a_paper_symbol(sample):
    symbols = ("(mu)", "(a)", "(beta)", "Epsilon", "Alpha", "Gamma", "J max", "tau", "Cosine", "(d)", "(r)")
    template = make_active(bpy.data.objects["Template"])
    scene = bpy.context.scene
    groups = [template.shapesmith.pack, scene.shapesmith.landmarks, scene.shapesmith.transfer, template.shapesmith_wrap]
    names = [prop.name for group in groups for prop in group.bl_rna.properties]
    assert "Moving Region" in names and "Strong Motion" in names and "Distance" in names and "Detour" in names
    offending = [name for name in names if any(symbol in name for symbol in symbols)]
    assert not offending


def labels(calls):
    return [text for method, _, text in calls if method == "label" and text]


def test_result_lines_speak_a_riggers_words(sample):
    """After a transfer: the crossings in the scene's units with where they lie in words, never
    a bare number against 'the template's allows'; the wrap's pairs show no vertex index."""
    target = make_active(bpy.data.objects["Target_OldMan"])
    settings = bpy.context.scene.shapesmith.transfer
    settings.source, settings.contact, settings.virtual_edges = bpy.data.objects["Template"], False, False
    assert bpy.ops.shapesmith.transfer_shape_keys() == {"FINISHED"}
    worse = [shape for shape in target.shapesmith.transfer.shapes if shape.worse]
    assert worse, "plain transfer onto OldMan adds crossings the template does not have"
    lines = labels(draw(bpy.types.SHAPESMITH_PT_transfer))
    assert any(line.startswith(f"Passing through more than the template's: {len(worse)}") for line in lines), lines
    biggest = max(worse, key=lambda shape: shape.added)
    row = next(line for line in lines if line.strip().startswith(biggest.name + ":"))
    assert row.endswith(", lips or lids") or row.endswith(", through eyes, teeth or lashes"), row
    assert " m" in row or "cm" in row or "mm" in row, row  # the sample is in metres: a unit is shown
    assert not any("allows" in line or "between pieces" in line for line in lines), lines


def test_a_saved_preset_brings_back_a_panels_settings_and_the_name_table(sample):
    """Rig and Transfer presets: saved, the settings changed, the preset picked: the saved
    values are back (the Shape Key Names rows too), and the picked template is not touched."""
    scene = bpy.context.scene
    rig, transfer = scene.shapesmith, scene.shapesmith.transfer
    rig.symmetry_axis, rig.pair_by_name = "1", False
    rig.name_map.clear()
    row = rig.name_map.add()
    row.theirs, row.standard = "Blink_Left_Eye", "eyeBlinkLeft"
    transfer.tau_d, transfer.overwrite = 0.02, True
    assert bpy.ops.shapesmith.add_rig_preset(name="Studio Heads") == {"FINISHED"}
    assert bpy.ops.shapesmith.add_transfer_preset(name="Studio Heads") == {"FINISHED"}

    rig.symmetry_axis, rig.pair_by_name = "0", True
    rig.name_map.clear()
    transfer.tau_d, transfer.overwrite = 0.015, False
    transfer.source = bpy.data.objects["Template"]
    for panel in ("rig", "transfer"):
        path = bpy.utils.preset_find("Studio_Heads", f"shapesmith/{panel}")
        assert path, panel
        assert bpy.ops.script.execute_preset(filepath=path, menu_idname=f"SHAPESMITH_PT_{panel}_presets") == {"FINISHED"}
    assert (rig.symmetry_axis, rig.pair_by_name) == ("1", False)
    assert [(r.theirs, r.standard) for r in rig.name_map] == [("Blink_Left_Eye", "eyeBlinkLeft")]
    assert transfer.tau_d == pytest.approx(0.02) and transfer.overwrite
    assert transfer.source == bpy.data.objects["Template"]
