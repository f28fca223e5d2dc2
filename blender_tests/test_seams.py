"""Rigs split along UV seams, as Blender's glTF and FBX importers leave them: the bundled
Template and Target_Boy split by code along island boundaries (bmesh `split_edges`, which keeps
the shape keys; the copies sit exactly on top of each other). Every tool reads the welded
surface: transferred keys move every copy of a seam vertex alike, to the bit, and equal the
welded sample's; packing, landmarks and Analyze Rig give the welded sample's answers, and
Analyze Rig reports the seams it welded."""

import json

import bmesh
import bpy
import numpy as np
import pytest

from conftest import make_active, run_batch

ORIGINAL = "original_vertex"


def islands(obj):
    """Four islands, as a UV layout cuts a head: the faces left and right of the midline,
    above and below the height of the vertices' mean; the island of each face."""
    centres = np.empty(len(obj.data.polygons) * 3, dtype=np.float32)
    obj.data.polygons.foreach_get("center", centres)
    centres = centres.reshape(-1, 3)
    return (centres[:, 0] > 0) + 2 * (centres[:, 2] > rest_height(obj))


def rest_height(obj):
    return float(positions(obj)[:, 2].mean())


def islands_split(obj, name, island):
    """A copy of `obj` (with its shape keys) split along the boundaries of the faces'
    `island`s. Each vertex remembers its welded vertex in the integer attribute
    `original_vertex`."""
    copy = obj.copy()
    copy.data = obj.data.copy()
    copy.name = copy.data.name = name
    bpy.context.scene.collection.objects.link(copy)
    bm = bmesh.new()
    bm.from_mesh(copy.data)
    layer = bm.verts.layers.int.new(ORIGINAL)
    for v in bm.verts:
        v[layer] = v.index
    bm.faces.ensure_lookup_table()
    seams = [e for e in bm.edges if len(e.link_faces) == 2 and island[e.link_faces[0].index] != island[e.link_faces[1].index]]
    bmesh.ops.split_edges(bm, edges=seams)
    bm.to_mesh(copy.data)
    bm.free()
    copy.data.update()
    return copy


def original_vertex(obj):
    values = np.empty(len(obj.data.vertices), dtype=np.int32)
    obj.data.attributes[ORIGINAL].data.foreach_get("value", values)
    return values


def positions(obj, key=None):
    data = obj.data.shape_keys.key_blocks[key].data if key else obj.data.vertices
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    data.foreach_get("co", co)
    return co.reshape(-1, 3)


def diagonal(obj):
    points = positions(obj)
    return float(np.linalg.norm(points.max(0) - points.min(0)))


def transfer(source, target):
    settings = bpy.context.scene.shapesmith.transfer
    settings.source = source
    make_active(target)
    assert bpy.ops.shapesmith.transfer_shape_keys() == {"FINISHED"}


@pytest.fixture
def split_sample(sample):
    template, boy = bpy.data.objects["Template"], bpy.data.objects["Target_Boy"]
    # One cut on both heads (they share their topology), drawn on the template.
    island = islands(template)
    split_template, split_boy = islands_split(template, "TemplateSplit", island), islands_split(boy, "BoySplit", island)
    original = original_vertex(split_template)
    assert len(original) > len(template.data.vertices) + 100, "the islands should cut the head"
    np.testing.assert_array_equal(original, original_vertex(split_boy))
    # The copies sit on their vertex, in the neutral and in every key.
    for name in ("Basis", "jawOpen"):
        np.testing.assert_array_equal(positions(split_template, name), positions(template, name)[original])
    return template, boy, split_template, split_boy, original


def test_transferred_keys_close_every_seam_and_equal_the_welded_transfer(split_sample):
    template, boy, split_template, split_boy, original = split_sample
    transfer(template, boy)
    transfer(split_template, split_boy)
    tolerance = 1e-6 * diagonal(boy)
    names = [kb.name for kb in template.data.shape_keys.key_blocks[1:]]
    # Copies of one vertex, grouped: every copy's delta equal to the first copy's, bit for bit.
    order = np.argsort(original, kind="stable")
    first = order[np.searchsorted(original[order], original)]
    assert (first != np.arange(len(original))).sum() > 100
    rest, welded_rest = positions(split_boy), positions(boy)
    for name in names:
        delta = positions(split_boy, name) - rest
        np.testing.assert_array_equal(delta, delta[first], err_msg=f"{name}: a seam opened")
        welded = (positions(boy, name) - welded_rest)[original]
        error = float(np.abs(delta - welded).max())
        assert error <= tolerance, f"{name}: {error} from the welded transfer (tolerance {tolerance})"


def test_analyze_reports_the_seams_and_finds_the_welded_pairs(split_sample, tmp_path):
    template, _, split_template, _, original = split_sample
    seam_vertices = int(sum(np.bincount(original)[np.bincount(original) > 1]))
    groups = int((np.bincount(original) > 1).sum())
    path = str(tmp_path / "split.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path, copy=True)
    reports = {}
    for name in ("Template", "TemplateSplit"):
        out = tmp_path / f"{name}.json"
        run_batch("analyze", "--input", path, "--object", name, "--json", str(out), check=True)
        reports[name] = json.loads(out.read_text())
    assert (reports["TemplateSplit"]["seam_vertices"], reports["TemplateSplit"]["seam_groups"]) == (seam_vertices, groups)
    assert (reports["Template"]["seam_vertices"], reports["Template"]["seam_groups"]) == (0, 0)
    assert reports["TemplateSplit"]["symmetric_pairs"] == reports["Template"]["symmetric_pairs"]
    assert reports["TemplateSplit"]["antagonists"] == reports["Template"]["antagonists"]
    # The panel's summary and the operator's message say so too.
    make_active(split_template)
    assert bpy.ops.shapesmith.analyze_rig() == {"FINISHED"}
    summary = split_template.shapesmith.analysis
    assert (summary.seam_vertices, summary.seam_groups) == (seam_vertices, groups)


def test_packing_and_landmarks_on_the_split_head_give_the_welded_answers(split_sample, shapesmith):
    import importlib

    packing = importlib.import_module(shapesmith.__name__ + ".blender.packing")
    landmarks = importlib.import_module(shapesmith.__name__ + ".blender.landmarks")
    template, _, split_template, _, original = split_sample

    def expressions(obj):
        report = packing.pack_object(obj, **packing.packing_options(obj))
        return [sorted(e["shapes"]) for e in report["expressions"]]

    assert expressions(split_template) == expressions(template)
    welded = landmarks.place_landmarks(template)
    split = landmarks.place_landmarks(split_template)
    # A landmark is one welded point: its vertex is the lowest of the point's copies.
    welded_points = [lm["vertex"] for lm in welded["landmarks"]]
    split_points = [int(original[lm["vertex"]]) for lm in split["landmarks"]]
    assert split_points == welded_points
    lowest = {int(o): v for v, o in reversed(list(enumerate(original)))}
    assert all(lm["vertex"] == lowest[int(original[lm["vertex"]])] for lm in split["landmarks"])
    assert split["mesh"]["loose_parts"] == welded["mesh"]["loose_parts"]
