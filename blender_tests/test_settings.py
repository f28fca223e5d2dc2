"""One settings object per tool: the add-on's dataclasses, the core's defaults
(`default_settings`), the panel's property defaults and batch's flag defaults are the same;
a misspelt or ill-typed option is refused naming it; a changed option reaches the core from
the panel and from batch."""

import dataclasses
import json
import os
import sys

import bpy
import numpy as np
import pytest

from conftest import ROOT, make_active, run_batch

sys.path.insert(0, os.path.join(ROOT, "scripts"))
import batch  # noqa: E402  (scripts/ on the path)


def tools(shapesmith):
    return shapesmith.blender.settings


def plain(value):
    """The settings as JSON gives them back (tuples as lists)."""
    return json.loads(json.dumps(value))


def same_in_float32(panel, expected, path="settings"):
    """Whether `panel` (read from Blender properties, whose floats are single precision)
    equals `expected` once each float is rounded to float32; raises naming the first
    difference."""
    if isinstance(expected, dict):
        assert panel.keys() == expected.keys(), path
        for key in expected:
            same_in_float32(panel[key], expected[key], f"{path}.{key}")
    elif isinstance(expected, list):
        assert len(panel) == len(expected), path
        for index, (a, b) in enumerate(zip(panel, expected)):
            same_in_float32(a, b, f"{path}.{index}")
    elif isinstance(expected, float):
        assert isinstance(panel, float) and np.float32(panel) == np.float32(expected), (path, panel, expected)
    else:
        assert type(panel) is type(expected) and panel == expected, (path, panel, expected)
    return True


@pytest.mark.parametrize("tool", ["analyze", "pack", "landmarks", "score", "transfer", "virtual_edges", "wrap", "carry",
                                  "performance"])
def test_each_dataclass_has_the_cores_keys_and_defaults(shapesmith, tool):
    native = shapesmith.native.module()
    dataclass = tools(shapesmith).TOOLS[tool]
    assert plain(dataclass().as_native()) == native.default_settings(tool)


def test_the_core_names_its_tools_and_refuses_another(shapesmith):
    native = shapesmith.native.module()
    assert set(tools(shapesmith).TOOLS) == {"analyze", "pack", "landmarks", "score", "transfer", "virtual_edges", "wrap",
                                            "carry", "performance"}
    with pytest.raises(native.InvalidInputError, match="no tool named 'packing'.*pack"):
        native.default_settings("packing")


def fresh_scene_and_object():
    """A new scene and mesh object: their Shapesmith properties hold the registered defaults
    (the sample's own may have been edited by other tests)."""
    scene = bpy.data.scenes.new("SettingsDefaults")
    obj = bpy.data.objects.new("SettingsDefaults", bpy.data.meshes.new("SettingsDefaults"))
    return scene, obj


def test_the_panels_defaults_are_the_dataclasses(shapesmith):
    settings = tools(shapesmith)
    scene, obj = fresh_scene_and_object()
    panels = {
        "analyze": settings.analyze_settings(scene),
        "pack": settings.pack_settings(obj.shapesmith.pack),
        "landmarks": settings.landmark_settings(scene.shapesmith.landmarks),
        "transfer": settings.transfer_settings(scene.shapesmith.transfer),
        "performance": settings.performance_settings(scene.shapesmith_performance),
    }
    for tool, read in panels.items():
        same_in_float32(plain(read.as_native()), plain(settings.TOOLS[tool]().as_native()), tool)
    # The properties whose default is the dataclass's own, read off the registered types.
    transfer_type = type(scene.shapesmith.transfer).bl_rna.properties
    assert transfer_type["virtual_edges"].default and not transfer_type["contact"].default
    assert np.float32(transfer_type["tau_d"].default) == np.float32(settings.VirtualEdgeSettings().tau_d)
    assert np.float32(transfer_type["contact_distance"].default) == np.float32(settings.ContactSettings().distance)
    pack_type = type(obj.shapesmith.pack).bl_rna.properties
    assert np.float32(pack_type["collision_tolerance"].default) == np.float32(settings.PackSettings().collision_tolerance)
    assert not pack_type["limit_expressions"].default and settings.PackSettings().max_expressions is None


def parsed(*argv):
    return batch.parse(list(argv))


def test_batchs_flag_defaults_are_the_dataclasses(shapesmith):
    settings = tools(shapesmith)
    transfer = parsed("transfer", "--input", "in.blend", "--source", "Template")
    assert settings.transfer_settings(transfer) == settings.TransferSettings()
    wrap = parsed("wrap", "--input", "in.blend", "--template", "Template", "--character", "Character")
    assert settings.transfer_settings(wrap) == settings.TransferSettings()
    landmarks = parsed("landmarks", "--input", "in.blend", "--object", "Template")
    assert batch.landmark_settings(landmarks, settings) == settings.LandmarkSettings()
    analyze = parsed("analyze", "--input", "in.blend", "--object", "Template")
    assert batch.analyze_settings(analyze, settings) == settings.AnalyzeSettings()
    solve = parsed("solve", "--input", "in.blend", "--object", "Template", "--trajectories", "t.csv")
    assert settings.performance_settings(solve) == settings.PerformanceSettings()
    # pack's flags default to the settings stored on the object, which it keeps unchanged
    pack = parsed("pack", "--input", "in.blend", "--object", "Template")
    assert batch.pack_settings(pack, settings.PackSettings()) == settings.PackSettings()
    stored = settings.PackSettings(mu=0.4, symmetric=False, collision_conflicts=False)
    assert batch.pack_settings(pack, stored) == stored
    # and a flag reaches the settings under the core's key
    flagged = parsed("transfer", "--input", "in.blend", "--source", "T", "--no-virtual-edges", "--contact", "--contact-distance", "0.5")
    chosen = settings.transfer_settings(flagged)
    assert chosen.transfer.virtual_edges is None and chosen.transfer.contact.distance == 0.5


def tiny_rig():
    """A tetrahedron with one shape: enough for every entry point to read its settings."""
    neutral = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], dtype=np.float32)
    deltas = np.zeros((1, 4, 3), dtype=np.float32)
    deltas[0, 3, 2] = 0.1
    triangles = np.array([[0, 2, 1], [0, 1, 3], [0, 3, 2], [1, 2, 3]], dtype=np.int32)
    return neutral, deltas, triangles, ["lift"]


def calls(native):
    """Each tool's native entry point, called with `settings` on the tiny rig (the settings
    are read before the arrays)."""
    neutral, deltas, triangles, names = tiny_rig()
    pairs = np.zeros((0, 3), dtype=np.float32)
    tracks = np.zeros((2, 1, 3))
    return {
        "analyze": lambda s: native.analyze_rig(neutral, deltas, triangles, names, s),
        "pack": lambda s: native.pack_expressions(neutral, deltas, triangles, names, s),
        "landmarks": lambda s: native.place_landmarks(neutral, deltas, triangles, names, s),
        "score": lambda s: native.score_layout(neutral, deltas, triangles, names, [3], s),
        "transfer": lambda s: native.transfer_shapes(neutral, deltas, neutral, triangles, names, s),
        "virtual_edges": lambda s: native.find_virtual_edges(neutral, triangles, s),
        "wrap": lambda s: native.wrap_template(neutral, triangles, neutral, triangles, pairs, pairs, s),
        "carry": lambda s: native.carry_shapes(neutral, triangles, deltas, neutral, triangles, s),
        "performance": lambda s: native.solve_performance(neutral, deltas, triangles, names, [3], tracks, s),
    }


@pytest.mark.parametrize("tool", ["analyze", "pack", "landmarks", "score", "transfer", "virtual_edges", "wrap", "carry",
                                  "performance"])
def test_an_unknown_or_ill_typed_option_is_refused_naming_it(shapesmith, tool):
    native = shapesmith.native.module()
    call = calls(native)[tool]
    defaults = native.default_settings(tool)
    misspelt = dict(defaults, smothing=1.0)
    with pytest.raises(native.InvalidInputError, match=f"^{tool} settings: `smothing`: unknown field `smothing`"):
        call(misspelt)
    # a nested or top-level option of the wrong type, or not finite, is named with its path
    path, value = next((key, inner) for key, inner in defaults.items() if not isinstance(inner, (dict, list, type(None))))
    with pytest.raises(native.InvalidInputError, match=f"^{tool} settings: `{path}`: invalid type"):
        call({path: "high"} if not isinstance(value, str) else {path: 7})
    nested = next(((key, inner) for key, inner in defaults.items() if isinstance(inner, dict)), None)
    if nested is not None:
        key, inner = nested
        leaf = next(k for k, v in inner.items() if isinstance(v, float))
        with pytest.raises(native.InvalidInputError, match=f"`{key}.{leaf}` must be a finite number, got NaN"):
            call({key: dict(inner, **{leaf: float("nan")})})


def test_the_transfer_panels_settings_reach_the_core(sample, shapesmith):
    panel = bpy.context.scene.shapesmith.transfer
    panel.source = bpy.data.objects["Template"]
    panel.virtual_edges = False
    panel.contact, panel.contact_distance = True, 0.5
    # two keys: the contact solve is the slow part of a transfer
    assert bpy.ops.shapesmith.list_template_keys(tick="NONE") == {"FINISHED"}
    for item in panel.key_choice:
        item.chosen = item.name in ("mouthClose", "cheekPuff")
    panel.only_ticked = True
    target = make_active(bpy.data.objects["Target_Boy"])
    assert bpy.ops.shapesmith.transfer_shape_keys() == {"FINISHED"}
    panel.only_ticked, panel.contact = False, False
    result = target.shapesmith.transfer
    # the core's report: no virtual edges, and the contact distance as the core used it
    assert result.virtual_edges == 0 and result.contact
    assert result.contact_distance == pytest.approx(0.5)


def test_batchs_transfer_flags_reach_the_core(sample, tmp_path):
    report = tmp_path / "transfer.json"
    run_batch("transfer", "--input", sample, "--source", "Template", "--target", "Target_Boy", "--tau-d", "0.02",
              "--edge-weight", "2", "--no-contact", "--json", str(report), check=True)
    params = json.loads(report.read_text())["params"]
    assert params["transfer"]["virtual_edges"]["tau_d"] == 0.02 and params["transfer"]["edge_weight"] == 2.0
    assert params["transfer"]["contact"] is None and params["measure_penetration"] is True


def test_the_landmark_panels_settings_reach_the_core(sample, shapesmith):
    panel = bpy.context.scene.shapesmith.landmarks
    panel.rays = 8
    panel.design, panel.landmarks = "COUNT", 30
    template = make_active(bpy.data.objects["Template"])
    assert bpy.ops.shapesmith.place_landmarks() == {"FINISHED"}
    echoed = json.loads(template.shapesmith.landmarks.document)["params"]
    assert echoed["rays"] == 8 and echoed["landmarks"] == 30 and echoed["epsilon"] == pytest.approx(0.5)
    assert dataclasses.asdict(tools(shapesmith).landmark_settings(panel))["landmarks"] == 30
