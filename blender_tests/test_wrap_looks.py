"""Where riggers look first, measured on the carried keys: the template's keys read on the
template itself give the template's own answers (eyes that close, a mouth that opens), keys
that do not move read as eyes left open, and the wrap onto a stylised character (the template
warped to cartoon proportions, decimated, in centimetres with Y up) closes both eyes, opens
the mouth as far as the template's for its face and says so in the Wrap panel."""

import importlib
import os
import sys

import bpy
import numpy as np
import pytest

from conftest import make_active

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "scripts"))
import makehuman  # noqa: E402
import stylised  # noqa: E402

# The bounds: an eye is closed when its blink leaves at most 5% of the open eye;
# jawOpen opens the mouth as far as the template's does for the face's size.
CLOSED = 0.05


def module(shapesmith, name):
    return importlib.import_module(f"{shapesmith.__name__}.{name}")


def template_arrays(shapesmith):
    """The template's rest, triangles, key names and keys (K, N, 3), float32."""
    template = bpy.data.objects["Template"]
    triangles = module(shapesmith, "blender.mesh_arrays").read_triangles(template)
    rest = stylised.positions(template).astype(np.float32)
    names = [block.name for block in template.data.shape_keys.key_blocks[1:]]
    keys = np.stack([stylised.block_positions(template, n) for n in names]).astype(np.float32) - rest
    return rest, triangles, names, keys


def looks_on_itself(shapesmith, character_keys):
    """The template's keys measured with the template as its own wrap and character, the
    character's keys `character_keys`."""
    rest, triangles, names, keys = template_arrays(shapesmith)
    native = module(shapesmith, "native").module()
    looks = native.look_at_keys(rest, keys, triangles, names, rest, keys, rest, triangles,
                                np.ascontiguousarray(character_keys, dtype=np.float32), keys)
    return {s["name"]: s for s in looks["shapes"]}, looks


def test_the_templates_keys_on_itself_read_the_templates_own_answers(sample, shapesmith):
    _, _, names, keys = template_arrays(shapesmith)
    shapes, looks = looks_on_itself(shapesmith, keys)
    assert [name for name, _ in looks["openings"]["eyes"]] == ["eyeBlinkLeft", "eyeBlinkRight"]
    assert looks["openings"]["mouth"] is not None and looks["openings"]["face_size"] > 0.0
    for name in ("eyeBlinkLeft", "eyeBlinkRight"):
        shape = shapes[name]
        # Read on itself, every measure is the template's own, exactly.
        assert abs(shape["eye_gap"] - shape["template_eye_gap"]) < 1e-6, shape
        assert abs(shape["lid_turning"] - shape["template_lid_turning"]) < 1e-6 * shape["template_lid_turning"]
        assert shape["eye_gap"] <= CLOSED and shape["eyes_close"], shape
    jaw = shapes["jawOpen"]
    assert abs(jaw["mouth_opening"] - jaw["template_mouth_opening"]) < 1e-6 and jaw["mouth_opening"] > 0.05, jaw
    close = shapes["mouthClose"]
    assert abs(close["mouth_closing"] - close["template_mouth_closing"]) < 1e-6, close
    rest, triangles, _, _ = template_arrays(shapesmith)
    for name, shape in shapes.items():
        # Brute force: a triangle is turned over when its normal's dot with its rest normal is negative.
        posed = rest + keys[names.index(name)]
        normal = lambda p: np.cross(p[triangles[:, 1]] - p[triangles[:, 0]], p[triangles[:, 2]] - p[triangles[:, 0]])  # noqa: E731
        assert shape["turned_over"] == int(((normal(rest) * normal(posed)).sum(1) < 0).sum()), name
        assert abs(shape["roughness"] - shape["truth_roughness"]) <= 1e-9 + 1e-6 * shape["truth_roughness"]
        assert abs(shape["copy_roughness"] - shape["roughness"]) <= 1e-9 + 1e-3 * shape["roughness"], shape["name"]


def test_a_blink_that_does_not_move_leaves_the_eyes_open_and_says_so(sample, shapesmith):
    _, _, names, keys = template_arrays(shapesmith)
    still = keys.copy()
    still[names.index("eyeBlinkLeft")] = 0.0
    # Half the blink: the eye half closed.
    still[names.index("eyeBlinkRight")] *= 0.5
    shapes, looks = looks_on_itself(shapesmith, still)
    assert abs(shapes["eyeBlinkLeft"]["eye_gap"] - 1.0) < 1e-9 and shapes["eyeBlinkLeft"]["eyes_close"] is False
    half = shapes["eyeBlinkRight"]["eye_gap"]
    # Brute force at the eye's middle: the rest opening's share the half blink leaves (the
    # template's blink presses the upper lid past the lower, so half of it leaves under half).
    rest, _, _, _ = template_arrays(shapesmith)
    upper, lower = dict(looks["openings"]["eyes"])["eyeBlinkRight"]["middle"]
    opening = (rest[upper] - rest[lower]).astype(np.float64)
    moved = opening + still[names.index("eyeBlinkRight")][upper] - still[names.index("eyeBlinkRight")][lower]
    expected = max(0.0, float(moved @ opening)) / float(opening @ opening)
    assert abs(half - expected) < 1e-5 and 0.05 < half < 0.6 and shapes["eyeBlinkRight"]["eyes_close"] is False, (half, expected)
    lines = [line for line, good in module(shapesmith, "blender.looks").look_lines(looks) if not good]
    assert any(line.startswith("eyeBlinkLeft: eyes close: no, gap 100%") for line in lines), lines


@pytest.mark.xfail(strict=True, reason="the carry's collision pass reopens the blink 28-30% of the open eye on the stylised characters "
                   "(the truth closes it, gap 0%, yet the pass's curve judge calls the truth's blink worse) and the halved copy's jawOpen opens 1.27x the template's (truth 1.06x): "
                   "docs/wrap.md, 'Where riggers look first'")
def test_the_wrap_onto_a_stylised_character_closes_the_eyes_and_opens_the_mouth(sample, shapesmith):
    template = bpy.data.objects["Template"]
    head, _, _ = stylised.stylised_head(template)
    frame = "centimetres, Y up"
    character = stylised.stylised_character(head, "Cartoon", "decimated to half", frame)
    skin = makehuman.largest_piece(len(template.data.vertices), [tuple(p.vertices) for p in template.data.polygons])
    vertices = makehuman.pair_vertices(stylised.positions(template), skin)
    entries = [[int(v), [float(x) for x in q]] for v, q in zip(vertices, stylised.FRAMES[frame](stylised.positions(head)[vertices]))]
    module(shapesmith, "blender.wrap").store_pairs(character, entries, template)
    bpy.context.scene.shapesmith.transfer.source = template
    make_active(character)
    assert bpy.ops.shapesmith.align_template() == {"FINISHED"}
    assert bpy.ops.shapesmith.wrap_template() == {"FINISHED"}
    assert bpy.ops.shapesmith.transfer_onto_character() == {"FINISHED"}
    lines = character.shapesmith_wrap.looks.splitlines()
    for name in ("eyeBlinkLeft", "eyeBlinkRight"):
        line = next(line for line in lines if line[2:].startswith(f"{name}: eyes close:"))
        assert line.startswith(f"+ {name}: eyes close: yes"), lines
    # The panel's lines name every finding, the eyes first.
    assert lines[0][2:].startswith("eyeBlinkLeft: eyes close:") and lines[1][2:].startswith("eyeBlinkRight: eyes close:"), lines
    jaw = next(line for line in lines if line[2:].startswith("jawOpen: mouth opens"))
    opens = float(jaw.split("mouth opens ")[1].split("%")[0]) / 100.0
    assert 0.8 <= opens <= 1.25, lines
