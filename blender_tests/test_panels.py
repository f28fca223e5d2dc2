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
    return [getattr(bpy.types, name) for name in dir(bpy.types) if name.startswith("SHAPESMITH_PT_")]


def test_every_panel_draws_before_and_after_results(sample):
    make_active(bpy.data.objects["Template"])
    panels = shapesmith_panels()
    assert len(panels) >= 8
    for panel in panels:
        draw(panel)
    assert bpy.ops.shapesmith.pack_expressions() == {"FINISHED"}
    for panel in panels:
        draw(panel)


@pytest.mark.parametrize("panel, button", [("SHAPESMITH_PT_pack", "shapesmith.pack_expressions"),
                                           ("SHAPESMITH_PT_landmarks", "shapesmith.place_landmarks")])
def test_the_main_button_comes_first(sample, panel, button):
    make_active(bpy.data.objects["Template"])
    calls = draw(getattr(bpy.types, panel))
    first_widget = next(call for call in calls if call[0] in ("operator", "prop"))
    assert first_widget[:2] == ("operator", button), calls[:5]


def test_no_setting_a_rigger_sees_is_named_by_a_paper_symbol(sample):
    symbols = ("(mu)", "(a)", "(beta)", "Epsilon", "Alpha", "Gamma", "J max", "tau", "Cosine")
    template = make_active(bpy.data.objects["Template"])
    groups = [template.shapesmith.pack, bpy.context.scene.shapesmith.landmarks]
    names = [prop.name for group in groups for prop in group.bl_rna.properties]
    assert "Moving Region" in names and "Strong Motion" in names
    offending = [name for name in names if any(symbol in name for symbol in symbols)]
    assert not offending
