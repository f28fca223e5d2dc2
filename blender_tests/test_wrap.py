"""Wrap: the template onto a character of another topology (a decimated identity head in
other units and axes, its correspondence with the template known by construction). The keys
written on the character match the same-topology transfer onto the undecimated head,
sampled at the character's vertices; another motion of the character gives the same keys
moved; bad input is refused with the character as it was."""

import importlib
import json
import os
import sys

import bpy
import numpy as np
import pytest

from conftest import file_digest, make_active, run_batch

sys.path.insert(0, os.path.join(os.path.dirname(os.path.dirname(os.path.abspath(__file__))), "scripts"))
from wrap_copies import barycentric_copy, moving_error, nearest_vertex_copy  # noqa: E402

IDENTITY = "Target_OldMan"
# Each test character: the identity's vertices moved by x -> SCALE * R x + SHIFT (local data).
MOTIONS = {
    "cm_y_up": (100.0, (np.pi / 2, 0.3, -0.2), (5.0, 160.0, -3.0)),
    "mm_turned": (1000.0, (-0.4, 2.5, 1.1), (-200.0, 30.0, 900.0)),
}


def rotation(angles):
    a, b, c = angles
    rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    rz = np.array([[np.cos(c), -np.sin(c), 0], [np.sin(c), np.cos(c), 0], [0, 0, 1]])
    return rz @ ry @ rx


def apply(motion, points):
    scale, angles, shift = motion
    return scale * np.asarray(points, dtype=np.float64) @ rotation(angles).T + np.array(shift)


def positions(obj):
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", co)
    return co.reshape(-1, 3).astype(np.float64)


def key_deltas(obj, names):
    rest = positions(obj)
    out = []
    for name in names:
        co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
        obj.data.shape_keys.key_blocks[name].data.foreach_get("co", co)
        out.append(co.reshape(-1, 3) - rest)
    return np.array(out)


def module(shapesmith, name):
    return importlib.import_module(f"{shapesmith.__name__}.{name}")


def decimated_copy(source, name, ratio=0.5):
    """`source` collapse-decimated into a new object without shape keys (other vertices,
    other faces)."""
    copy = source.copy()
    copy.data = source.data.copy()
    copy.name = name
    bpy.context.scene.collection.objects.link(copy)
    if copy.data.shape_keys is not None:
        copy.shape_key_clear()
    copy.modifiers.new("Decimate", "DECIMATE").ratio = ratio
    mesh = bpy.data.meshes.new_from_object(copy.evaluated_get(bpy.context.evaluated_depsgraph_get()))
    copy.modifiers.clear()
    copy.data = mesh
    return copy


def skin_vertices(obj):
    """The vertices of the mesh's largest piece (what the wrap fits)."""
    import makehuman  # scripts/ is on the path (conftest)

    return makehuman.largest_piece(len(obj.data.vertices), [tuple(p.vertices) for p in obj.data.polygons])


def character(motion, name="Character_Test"):
    """A decimated identity head moved by `motion`, and its point pairs (template vertex ->
    the identity's same vertex moved, a point on or near the decimated surface)."""
    import makehuman  # scripts/ is on the path (conftest)

    template, identity = bpy.data.objects["Template"], bpy.data.objects[IDENTITY]
    obj = decimated_copy(identity, name)
    obj.data.vertices.foreach_set("co", apply(motion, positions(obj)).astype(np.float32).ravel())
    obj.data.update()
    vertices = makehuman.pair_vertices(positions(template), skin_vertices(template))
    targets = apply(motion, positions(identity)[vertices])
    return obj, [[int(v), [float(x) for x in q]] for v, q in zip(vertices, targets)]


def without_collision_pass(shapesmith):
    """Transfer settings with surfaces not kept apart (the carry's collision pass is its own
    switch: `carry_onto_character(..., collision_pass=False)`)."""
    tool = module(shapesmith, "blender.settings")
    return tool.TransferSettings(transfer=tool.DeformationSettings(contact=None))


def wrap_and_carry(shapesmith, obj, entries, transfer_settings=None):
    """The whole chain through the plain functions: keys written on `obj`; returns (names,
    the Wrapped, the carried Transfer)."""
    wrap = module(shapesmith, "blender.wrap")
    shape_keys = module(shapesmith, "blender.shape_keys")
    template = bpy.data.objects["Template"]
    template_points, character_points = wrap.pairs_from_list(entries, template, obj)
    wrapped = wrap.wrap_object(template, obj, template_points, character_points)
    wrapped_object = wrap.show_wrapped(wrapped)
    result = wrap.carry_onto_character(template, obj, wrapped_object, transfer_settings)
    written, _, _ = shape_keys.write_transferred_keys(result)
    return written, wrapped, result


@pytest.fixture
def truth(sample, shapesmith):
    """The same-topology transfer onto the undecimated identity head: (names, deltas)."""
    transfer = module(shapesmith, "blender.transfer")
    result = transfer.transfer_object(bpy.data.objects["Template"], bpy.data.objects[IDENTITY])
    return result.names, result.deltas.astype(np.float64)


def sampled_truth(shapesmith, motion, obj, deltas):
    """The same-topology result sampled at the character's vertices (closest point on the
    undecimated head, barycentric), in the character's space."""
    native = module(shapesmith, "native").module()
    identity = bpy.data.objects[IDENTITY]
    scale, angles, shift = motion
    back = ((positions(obj) - np.array(shift)) @ rotation(angles)) / scale
    triangles = module(shapesmith, "blender.mesh_arrays").read_triangles(identity)
    sampled = barycentric_copy(native, back, positions(identity), triangles, deltas)
    return scale * sampled @ rotation(angles).T


def test_keys_on_a_decimated_moved_identity_match_the_same_topology_transfer(sample, shapesmith, truth):
    names, truth_deltas = truth
    motion = MOTIONS["cm_y_up"]
    obj, entries = character(motion)
    written, wrapped, result = wrap_and_carry(shapesmith, obj, entries)
    assert written == names and len(obj.data.shape_keys.key_blocks) == len(names) + 1
    diagonal = wrapped.report["diagonal"]
    assert wrapped.report["mean_distance"] < 2e-3, wrapped.report
    carried = key_deltas(obj, names)
    reference = sampled_truth(shapesmith, motion, obj, truth_deltas)
    carry_error = moving_error(carried, reference, diagonal)
    wrapped_object = obj.shapesmith_wrap.wrapped
    wrapped_deltas = module(shapesmith, "blender.transfer").transfer_object(bpy.data.objects["Template"], wrapped_object).deltas
    nearest_error = moving_error(nearest_vertex_copy(positions(wrapped_object), wrapped_deltas, positions(obj)), reference, diagonal)
    triangles = module(shapesmith, "blender.mesh_arrays").read_triangles(wrapped_object)
    native = module(shapesmith, "native").module()
    barycentric = barycentric_copy(native, positions(obj), positions(wrapped_object), triangles, wrapped_deltas)
    barycentric_error = moving_error(barycentric, reference, diagonal)
    # The same chain and truth without the carry's collision pass measure the wrap and the
    # carry alone: the pass decides per shape which vertices to hold, and the wrapped template
    # (a slightly slid mouth) gets some decisions the true head does not.
    transfer = module(shapesmith, "blender.transfer")
    plain_truth = transfer.transfer_object(bpy.data.objects["Template"], bpy.data.objects[IDENTITY], without_collision_pass(shapesmith))
    plain_reference = sampled_truth(shapesmith, motion, obj, plain_truth.deltas.astype(np.float64))
    plain_result = module(shapesmith, "blender.wrap").carry_onto_character(
        bpy.data.objects["Template"], obj, wrapped_object, without_collision_pass(shapesmith), collision_pass=False
    )
    plain_carried = plain_result.deltas
    plain_carry_error = moving_error(plain_carried, plain_reference, diagonal)
    # Without the pass the carried keys are still judged on the character's own mesh: each
    # row's excess is the curve its key adds to the character's neutral beyond what the
    # template's shape allows (in the character's units), per part, from a full sweep of the
    # written key: the more of the curve it adds to its neutral and its own curve beyond the
    # character's rest.
    character_triangles = module(shapesmith, "blender.mesh_arrays").read_triangles(obj)
    measured = native.measure_penetration(positions(obj).astype(np.float32), plain_carried, character_triangles)
    inside = lambda p: p["length"] - p["between_pieces"]  # noqa: E731
    rest = measured["neutral"]
    for row, shape in zip(plain_result.report["penetration"], measured["shapes"], strict=True):
        assert (row["length"], row["pairs"]) == (shape["length"], shape["pairs"]), row["name"]
        added, crossing = row["template_added"], row["template_crossing"]
        allowed = {
            "inside": max(0.0, added["inside"], crossing["inside"] - inside(rest)),
            "between": max(0.0, added["between"], crossing["between"] - rest["between_pieces"]),
        }
        expected = {
            "inside": max(0.0, inside(shape) - inside(rest) - allowed["inside"]),
            "between": max(0.0, shape["between_pieces"] - rest["between_pieces"] - allowed["between"]),
        }
        assert row["excess"] == pytest.approx(expected, abs=1e-9 * diagonal), row["name"]
    print(f"carry {carry_error:.2e}, nearest vertex {nearest_error:.2e}, barycentric {barycentric_error:.2e} of the diagonal; "
          f"without the collision pass, carry {plain_carry_error:.2e}")
    # Measured: carry 1.39e-3, nearest vertex 1.43e-3, barycentric 1.34e-3; without the
    # carry's collision pass, carry 1.18e-3. The copies have no pass: the carry alone is
    # compared with them, and the pass (which holds eyeballs behind the lids, at a cost where
    # its holds on the wrapped template differ from the true head's) has its own bound. The
    # rest is the skin fit's slide along the surface between the pairs, a floor every copy
    # shares: with the true correspondence in place of the fit, the carry is 4.1e-4 from the
    # truth (docs/wrap.md, Limits).
    assert plain_carry_error < 1.3e-3, plain_carry_error
    assert carry_error < 1.6e-3, carry_error
    assert plain_carry_error < nearest_error and plain_carry_error < barycentric_error, (plain_carry_error, nearest_error, barycentric_error)


def test_another_motion_of_the_character_gives_the_same_keys_moved(sample, shapesmith):
    first, first_entries = character(MOTIONS["cm_y_up"], "Character_A")
    second, second_entries = character(MOTIONS["mm_turned"], "Character_B")
    # Without the transfer's collision pass: its decisions (which shapes it re-solves, which
    # round it keeps) flip under the rounding of another frame, and where they do a shape
    # differs locally (measured with the pass: largest 1.8e-2 of the diagonal, 3e-2 to 4e-2
    # with an earlier pass, in eyeBlinkRight, mouthLeft, mouthClose). This test is about the wrap.
    names, _, _ = wrap_and_carry(shapesmith, first, first_entries, without_collision_pass(shapesmith))
    wrap_and_carry(shapesmith, second, second_entries, without_collision_pass(shapesmith))
    # Second = T(first) for the similarity T taking the first motion to the second.
    s1, a1, t1 = MOTIONS["cm_y_up"]
    s2, a2, _ = MOTIONS["mm_turned"]
    linear = (s2 / s1) * rotation(a2) @ rotation(a1).T
    assert np.allclose(positions(first) @ linear.T + (positions(second) - positions(first) @ linear.T)[0], positions(second), atol=1e-2)
    moved = key_deltas(first, names) @ linear.T
    diagonal = np.linalg.norm(positions(second).max(0) - positions(second).min(0))
    error = np.linalg.norm(key_deltas(second, names) - moved, axis=2) / diagonal
    print(f"invariance: mean {error.mean():.2e}, max {error.max():.2e}")
    # Measured: mean 1.9e-5, max 3.6e-3 (a few vertices where a closest-point tie breaks the
    # other way in the fit).
    assert error.mean() < 1e-4 and error.max() < 2e-2, (error.mean(), error.max())


def refused(shapesmith, obj, entries, pattern):
    """The chain raises a clear error and the character keeps no key."""
    wrap = module(shapesmith, "blender.wrap")
    errors = (wrap.MeshDataError,) + module(shapesmith, "native").error_types()
    template = bpy.data.objects["Template"]
    with pytest.raises(errors, match=pattern):
        template_points, character_points = wrap.pairs_from_list(entries, template, obj)
        wrap.wrap_object(template, obj, template_points, character_points)
    assert obj.data.shape_keys is None


def test_bad_input_is_refused_with_nothing_written(sample, shapesmith):
    obj, entries = character(MOTIONS["cm_y_up"])
    refused(shapesmith, obj, entries[:3], "at least 4")
    refused(shapesmith, obj, [[10**7, entries[0][1]]] + entries[1:], "out of range")
    refused(shapesmith, obj, [[entries[0][0], [float("nan"), 0.0, 0.0]]] + entries[1:], "not finite")
    refused(shapesmith, obj, [[entries[0][0], [1e4, 0.0, 0.0]]] + entries[1:], "placed on another object")
    empty = bpy.data.objects.new("Character_Empty", bpy.data.meshes.new("Character_Empty"))
    bpy.context.scene.collection.objects.link(empty)
    empty.data.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0), (0, 0, 1)], [], [])
    refused(shapesmith, empty, [[e[0], 0] for e in entries], "no faces")


def test_buttons_align_wrap_and_transfer_onto_the_character_with_undo(sample, shapesmith):
    obj = bpy.data.objects["Character_YoungWoman"]
    bpy.context.scene.shapesmith.transfer.source = bpy.data.objects["Template"]
    make_active(obj)
    assert bpy.ops.shapesmith.align_template() == {"FINISHED"}
    assert obj.shapesmith_wrap.stage == "ALIGN" and len(obj.shapesmith_wrap.pairs) == 10
    assert bpy.ops.shapesmith.wrap_template() == {"FINISHED"}
    wrapped = obj.shapesmith_wrap.wrapped
    assert wrapped is not None and "wrap_distance" in wrapped.data.color_attributes
    assert obj.shapesmith_wrap.mean_distance < 2e-3, obj.shapesmith_wrap.mean_distance
    bpy.ops.ed.undo_push(message="before transfer")
    assert bpy.ops.shapesmith.transfer_onto_character() == {"FINISHED"}
    bpy.ops.ed.undo_push(message="after transfer")
    assert len(bpy.data.objects["Character_YoungWoman"].data.shape_keys.key_blocks) == 53
    # The Transfer panel lists, for the character, the shapes judged on its own mesh.
    result = bpy.data.objects["Character_YoungWoman"].shapesmith.transfer
    assert result.done and result.carried and result.source == "Template" and len(result.shapes) == 52
    assert result.worse_before_contact == -1
    bpy.ops.ed.undo()
    assert bpy.data.objects["Character_YoungWoman"].data.shape_keys is None


def test_keys_carried_onto_the_template_in_centimetres_add_the_templates_own_intersection(sample, shapesmith):
    """The template wrapped onto a copy of itself in centimetres, turned and moved: the keys
    carried onto the copy are the template's own made symmetric, moved, so each adds to the copy's neutral
    exactly the template shape's intersection curve, x100. The criterion, judged on the
    character's own mesh in its own units, lists none of them (read in metres, the
    template's allowance would be 100 times too small and the collision pass on the wrapped
    template would pull the lips the artist pressed together apart)."""
    transfer = module(shapesmith, "blender.transfer")
    template = bpy.data.objects["Template"]
    motion = MOTIONS["cm_y_up"]
    obj = decimated_copy(template, "Character_Self", ratio=1.0)
    assert len(obj.data.vertices) == len(template.data.vertices)
    obj.data.vertices.foreach_set("co", apply(motion, positions(template)).astype(np.float32).ravel())
    obj.data.update()
    import makehuman  # scripts/ is on the path (conftest)

    vertices = makehuman.pair_vertices(positions(template), skin_vertices(template))
    entries = [[int(v), int(v)] for v in vertices]
    names, _, result = wrap_and_carry(shapesmith, obj, entries)
    report = result.report
    assert report["template_to_target"] == pytest.approx(100.0, rel=1e-4)
    diagonal = report["diagonal"]
    # The copy is symmetric, so each carried key is the template's averaged with the mirror
    # of its partner's (a self-symmetric key with its own).
    own = key_deltas(template, names)
    partner, flip = template_partner(template), np.array([-1.0, 1.0, 1.0])
    symmetric = own.copy()
    for row in report["symmetry"]["shapes"]:
        i, j = names.index(row["first_name"]), names.index(row["second_name"])
        symmetric[i], symmetric[j] = 0.5 * (own[i] + flip * own[j][partner]), 0.5 * (own[j] + flip * own[i][partner])
    expected = motion[0] * symmetric @ rotation(motion[1]).T
    error = np.linalg.norm(key_deltas(obj, names) - expected, axis=2).max()
    assert error < 2e-3 * diagonal, error / diagonal
    assert transfer.worse_than_template(report) == [], [(r["name"], r["excess"]) for r in report["penetration"] if sum(r["excess"].values()) > 1e-3 * diagonal]
    assert not any((row["contact"] or {}).get("applied") for row in report["penetration"])


def test_batch_wraps_the_sample_character_and_reports(sample_path, tmp_path):
    out = tmp_path / "wrap.json"
    proc = run_batch("wrap", "--input", sample_path, "--template", "Template", "--character", "Character_YoungWoman",
                     "--json", str(out), "--output", str(tmp_path / "o.blend"))
    assert proc.returncode == 0, proc.stderr
    report = json.loads(out.read_text())
    assert len(report["shapes"]) == 52 and report["fit"]["alignment"] == "pairs"
    assert report["fit"]["mean_distance"] < 2e-3
    assert {"io", "align", "wrap", "transfer", "carry", "penetration"} <= set(report["seconds"])
    assert (tmp_path / "o.blend").exists()
    # The keys judged on the character's own mesh: one row per shape, the criterion's shapes listed.
    rows = report["penetration"]["shapes"]
    assert [row["name"] for row in rows] == report["shapes"]
    diagonal_margin = [row["name"] for row in rows if row["excess"]["inside"] + row["excess"]["between"] > 0]
    assert set(report["worse_than_template"]) <= set(diagonal_margin)
    assert "adding more intersection on the character than on the template" in proc.stdout


@pytest.mark.parametrize(
    "pairs, message",
    [
        ([[0, 0], [1, 1], [2, 2]], "at least 4"),
        ([[0, 99999999], [1, 1], [2, 2], [3, 3]], "out of range"),
        ("not a list", "list of"),
    ],
)
def test_batch_bad_pairs_exit_2_with_one_line(sample_path, tmp_path, pairs, message):
    digest = file_digest(sample_path)
    path = tmp_path / "pairs.json"
    path.write_text(json.dumps(pairs))
    proc = run_batch("wrap", "--input", sample_path, "--template", "Template", "--character", "Character_YoungWoman",
                     "--pairs", str(path), "--output", str(tmp_path / "o.blend"))
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], proc.stderr
    assert file_digest(sample_path) == digest and not (tmp_path / "o.blend").exists()


def test_point_pairs_are_added_from_a_selected_vertex_and_the_snapped_cursor(sample, shapesmith):
    template, obj = bpy.data.objects["Template"], bpy.data.objects["Character_YoungWoman"]
    bpy.context.scene.shapesmith.transfer.source = template
    for mesh_object, chosen in ((template, 10), (obj, None)):
        selection = np.zeros(len(mesh_object.data.vertices), dtype=bool)
        if chosen is not None:
            selection[chosen] = True
        mesh_object.data.vertices.foreach_set("select", selection)
    # The cursor a little off the character's vertex 5 (world space): snapped back onto its surface.
    vertex = obj.matrix_world @ obj.data.vertices[5].co
    bpy.context.scene.cursor.location = vertex + (vertex - obj.matrix_world.translation).normalized() * 0.002
    make_active(obj)
    count = len(obj.shapesmith_wrap.pairs)
    assert bpy.ops.shapesmith.add_point_pair(name="nose tip") == {"FINISHED"}
    pair = obj.shapesmith_wrap.pairs[-1]
    assert len(obj.shapesmith_wrap.pairs) == count + 1 and pair.name == "nose tip"
    assert pair.template_vertex == 10 and pair.character_vertex == -1
    assert np.allclose(pair.template_co, template.data.vertices[10].co, atol=1e-6)
    # On the surface, near the vertex the cursor was put by (character units: centimetres).
    assert np.linalg.norm(np.array(pair.character_co) - np.array(obj.data.vertices[5].co)) < 0.5
    assert bpy.ops.shapesmith.add_point_pair() == {"FINISHED"}
    assert bpy.ops.shapesmith.remove_point_pair() == {"FINISHED"}
    assert len(obj.shapesmith_wrap.pairs) == count + 1
    assert bpy.ops.shapesmith.clear_point_pairs() == {"FINISHED"}
    assert len(obj.shapesmith_wrap.pairs) == 0


def test_point_pairs_load_from_json_and_a_bad_file_changes_nothing(sample, shapesmith, tmp_path):
    obj = bpy.data.objects["Character_YoungWoman"]
    bpy.context.scene.shapesmith.transfer.source = bpy.data.objects["Template"]
    make_active(obj)
    good, bad = tmp_path / "good.json", tmp_path / "bad.json"
    good.write_text(json.dumps([[0, 0], [1, 1], [2, [1.0, 2.0, 3.0]], [3, 3]]))
    bad.write_text(json.dumps([[0, 0], [1, 10**9]]))
    assert bpy.ops.shapesmith.load_point_pairs(filepath=str(good)) == {"FINISHED"}
    pairs = obj.shapesmith_wrap.pairs
    assert [(p.template_vertex, p.character_vertex) for p in pairs] == [(0, 0), (1, 1), (2, -1), (3, 3)]
    assert tuple(pairs[2].character_co) == (1.0, 2.0, 3.0)
    with pytest.raises(RuntimeError, match="out of range"):
        bpy.ops.shapesmith.load_point_pairs(filepath=str(bad))
    assert len(obj.shapesmith_wrap.pairs) == 4


def world(obj, local):
    """A local point of `obj` in world space (after the depsgraph has placed parented markers)."""
    import mathutils

    bpy.context.view_layer.update()
    return np.array(obj.matrix_world @ mathutils.Vector(local))


def test_a_pair_end_moves_to_a_selected_vertex_and_the_markers_follow_with_undo(sample, shapesmith):
    template, obj = bpy.data.objects["Template"], bpy.data.objects["Character_YoungWoman"]
    bpy.context.scene.shapesmith.transfer.source = template
    make_active(obj)
    settings = obj.shapesmith_wrap
    settings.show_markers = True  # lists the sample's pairs (stored as JSON by the script that built it)
    settings.active_pair = 2
    markers = bpy.data.collections[f"{obj.name} Point Pairs"].objects
    assert len(markers) == 2 * len(settings.pairs) == 20
    pair = settings.pairs[2]
    marker = markers[f"{pair.name} (character)"]
    expected = world(obj, pair.character_co)
    assert marker.parent == obj and np.allclose(marker.matrix_world.translation, expected, atol=1e-3)
    before = (pair.character_vertex, tuple(pair.character_co))
    selection = np.zeros(len(obj.data.vertices), dtype=bool)
    selection[7] = True
    obj.data.vertices.foreach_set("select", selection)
    bpy.ops.ed.undo_push(message="before moves")
    assert bpy.ops.shapesmith.move_point_pair(side="CHARACTER") == {"FINISHED"}
    pair = obj.shapesmith_wrap.pairs[2]
    assert pair.character_vertex == 7 and np.allclose(pair.character_co, obj.data.vertices[7].co)
    marker = bpy.data.collections[f"{obj.name} Point Pairs"].objects[f"{pair.name} (character)"]
    expected = world(obj, obj.data.vertices[7].co)
    assert np.allclose(marker.matrix_world.translation, expected, atol=1e-3)
    # The template end, with nothing selected there: the 3D cursor snapped onto the template.
    template.data.vertices.foreach_set("select", np.zeros(len(template.data.vertices), dtype=bool))
    bpy.context.scene.cursor.location = template.matrix_world @ template.data.vertices[20].co
    assert bpy.ops.shapesmith.move_point_pair(side="TEMPLATE") == {"FINISHED"}
    assert pair.template_vertex == -1 and np.linalg.norm(np.subtract(pair.template_co, template.data.vertices[20].co)) < 1e-4
    bpy.ops.ed.undo_push(message="after moves")
    bpy.ops.ed.undo()
    obj = bpy.data.objects["Character_YoungWoman"]
    assert (obj.shapesmith_wrap.pairs[2].character_vertex, tuple(obj.shapesmith_wrap.pairs[2].character_co)) == before
    obj.shapesmith_wrap.show_markers = False
    assert f"{obj.name} Point Pairs" not in bpy.data.collections


def group_weights(obj, name):
    group, weights = obj.vertex_groups[name], np.zeros(len(obj.data.vertices))
    for vertex in obj.data.vertices:
        for membership in vertex.groups:
            if membership.group == group.index:
                weights[vertex.index] = membership.weight
    return weights


def test_the_vertex_group_masking_a_key_is_carried_by_the_binding(sample, shapesmith):
    """A ramp over the lower face (0 to 1 across 10% of the diagonal) masks jawOpen; the
    character gets the group, sampled where its vertices correspond to the template's."""
    template, identity = bpy.data.objects["Template"], bpy.data.objects[IDENTITY]
    rest = positions(template)
    diagonal = np.linalg.norm(rest.max(0) - rest.min(0))
    ramp = np.clip((rest[:, 2].mean() - rest[:, 2]) / (0.1 * diagonal) + 0.5, 0.0, 1.0)
    group = template.vertex_groups.new(name="LowerFace")
    for vertex in np.flatnonzero(ramp > 0):
        group.add([int(vertex)], float(ramp[vertex]), "REPLACE")
    template.data.shape_keys.key_blocks["jawOpen"].vertex_group = "LowerFace"
    motion = MOTIONS["cm_y_up"]
    obj, entries = character(motion)
    written, _, result = wrap_and_carry(shapesmith, obj, entries)
    assert "jawOpen" in written and set(result.vertex_groups) == {"LowerFace"}
    assert obj.data.shape_keys.key_blocks["jawOpen"].vertex_group == "LowerFace"
    carried = group_weights(obj, "LowerFace")
    # The truth: the ramp on the identity (same vertices as the template), sampled at the
    # character's vertices moved back into the identity's space.
    scale, angles, shift = motion
    back = ((positions(obj) - np.array(shift)) @ rotation(angles)) / scale
    triangles = module(shapesmith, "blender.mesh_arrays").read_triangles(identity)
    native = module(shapesmith, "native").module()
    triangle, barycentric, _ = native.bind_to_surface(back.astype(np.float32), positions(identity).astype(np.float32), triangles)
    truth = np.einsum("vc,vc->v", barycentric, ramp[triangles[triangle]])
    error = np.abs(carried - truth)
    print(f"vertex group: mean error {error.mean():.3f}, 99th percentile {np.percentile(error, 99):.3f}, mean weight {truth.mean():.3f}")
    assert carried.min() >= 0.0 and carried.max() <= 1.0 + 1e-6
    assert error.mean() < 0.1 * truth.mean(), (error.mean(), truth.mean())


def test_a_denser_character_gets_keys_as_smooth_as_the_same_topology_result(sample, shapesmith, truth):
    """The identity head subdivided twice (16x the faces): the carried keys have no stair
    steps: their roughness (mean uniform Laplacian on moving vertices) stays near that of the
    same-topology result sampled on the dense mesh, far below the nearest-vertex copy's."""
    names, truth_deltas = truth
    identity = bpy.data.objects[IDENTITY]
    obj = identity.copy()
    obj.data = identity.data.copy()
    obj.name = "Character_Dense"
    bpy.context.scene.collection.objects.link(obj)
    obj.shape_key_clear()
    modifier = obj.modifiers.new("Subdivide", "SUBSURF")
    modifier.subdivision_type, modifier.levels = "SIMPLE", 2
    obj.data = bpy.data.meshes.new_from_object(obj.evaluated_get(bpy.context.evaluated_depsgraph_get()))
    obj.modifiers.clear()
    assert len(obj.data.vertices) > 10 * len(identity.data.vertices)
    import makehuman

    template = bpy.data.objects["Template"]
    vertices = makehuman.pair_vertices(positions(template), skin_vertices(template))
    entries = [[int(v), [float(x) for x in positions(identity)[v]]] for v in vertices]
    written, wrapped, result = wrap_and_carry(shapesmith, obj, entries)
    chosen = [names.index(n) for n in ("jawOpen", "mouthSmileLeft", "eyeBlinkLeft", "browInnerUp")]
    dense = positions(obj)
    diagonal = wrapped.report["diagonal"]
    triangles = module(shapesmith, "blender.mesh_arrays").read_triangles(identity)
    native = module(shapesmith, "native").module()
    triangle, barycentric, _ = native.bind_to_surface(dense.astype(np.float32), positions(identity).astype(np.float32), triangles)
    reference = np.einsum("vc,kvcx->kvx", barycentric, truth_deltas[chosen][:, triangles[triangle]])
    carried = key_deltas(obj, [names[k] for k in chosen])
    wrapped_object = obj.shapesmith_wrap.wrapped
    wrapped_deltas = module(shapesmith, "blender.transfer").transfer_object(template, wrapped_object).deltas[chosen]
    nearest = nearest_vertex_copy(positions(wrapped_object), wrapped_deltas, dense)
    edges = np.array([e.vertices[:] for e in obj.data.edges])

    def roughness(deltas):
        degree = np.bincount(edges.ravel(), minlength=len(dense)).astype(np.float64)
        values = []
        for est, ref in zip(deltas, reference):
            summed = np.zeros_like(est, dtype=np.float64)
            np.add.at(summed, edges[:, 0], est[edges[:, 1]])
            np.add.at(summed, edges[:, 1], est[edges[:, 0]])
            moving = np.linalg.norm(ref, axis=1) > 1e-3 * diagonal
            values.append(np.linalg.norm((summed / degree[:, None] - est)[moving], axis=1).mean() / diagonal)
        return float(np.mean(values))

    carry, same, stairs = roughness(carried), roughness(reference), roughness(nearest)
    print(f"roughness on {len(dense)} vertices: carry {carry:.2e}, same-topology sampled {same:.2e}, nearest vertex {stairs:.2e}")
    assert carry < 2.0 * same and carry < 0.5 * stairs, (carry, same, stairs)


# The bound on a carried mirror pair's miss: this many times the sum of the template's own
# miss (its keys on its own vertex map) and the measure's floor on the character.
MIRROR_FACTOR = 1.5


def mirror_images(points, triangles, plane_point, plane_normal, native):
    """Each skin vertex's image across the plane, on the skin (triangle corners, barycentric),
    whether that triangle faces the mirrored vertex normal's way (a lip's image is not read on
    the lip it touches) and lies within 0.2% of the diagonal of it, the skin vertices and the
    plane's unit normal: the measure of `mirror_miss`."""
    import makehuman  # scripts/ is on the path (conftest)

    normal = np.asarray(plane_normal, dtype=np.float64) / np.linalg.norm(plane_normal)
    skin = makehuman.largest_piece(len(points), [tuple(t) for t in triangles])
    on_skin = np.zeros(len(points), dtype=bool)
    on_skin[skin] = True
    skin_triangles = triangles[on_skin[triangles[:, 0]]]
    corners = points[skin_triangles]
    face_normals = np.cross(corners[:, 1] - corners[:, 0], corners[:, 2] - corners[:, 0])
    vertex_normals = np.zeros_like(points)
    for k in range(3):
        np.add.at(vertex_normals, skin_triangles[:, k], face_normals)
    unit = lambda v: v / np.maximum(np.linalg.norm(v, axis=-1, keepdims=True), 1e-30)  # noqa: E731
    images = points[skin] - 2.0 * ((points[skin] - np.asarray(plane_point)) @ normal)[:, None] * normal
    triangle, barycentric, distance = native.bind_to_surface(images.astype(np.float32), points.astype(np.float32), skin_triangles)
    mirrored_normals = unit(vertex_normals[skin]) - 2.0 * (unit(vertex_normals[skin]) @ normal)[:, None] * normal
    diagonal = np.linalg.norm(points.max(0) - points.min(0))
    facing = (np.einsum("vx,vx->v", unit(face_normals[triangle]), mirrored_normals) > 0.5) & (distance < 2e-3 * diagonal)
    return skin, skin_triangles[triangle], barycentric, facing, normal


def mirrored(images, field):
    """The field mirrored at every skin vertex (zero elsewhere)."""
    skin, corners, barycentric, _, normal = images
    out = np.zeros_like(field, dtype=np.float64)
    values = np.einsum("vc,vcx->vx", barycentric, field[corners])
    out[skin] = values - 2.0 * (values @ normal)[:, None] * normal
    return out


def mirror_miss(images, first, second):
    """The worst measured vertex's miss between the mirror of the field `first` and the field
    `second`, relative to the larger largest motion on the skin (0 when neither moves it),
    and the measure's floor for them: the worst miss of either field against its mirror
    mirrored (an image interpolated twice across the character's triangles)."""
    skin, _, _, facing, _ = images
    measured = skin[facing]
    largest = max(np.linalg.norm(first[skin], axis=1).max(), np.linalg.norm(second[skin], axis=1).max())
    if largest == 0.0:
        return 0.0, 0.0
    worst = lambda a, b: np.linalg.norm(a[measured] - b[measured], axis=1).max() / largest  # noqa: E731
    floor = max(worst(mirrored(images, mirrored(images, f)), f) for f in (first, second))
    return worst(mirrored(images, first), second), floor


def template_partner(template):
    """Each template vertex's nearest vertex to its image across x = 0 (brute force)."""
    rest = positions(template)
    images = rest * np.array([-1.0, 1.0, 1.0])
    return np.concatenate([np.argmin(((chunk[:, None] - rest[None]) ** 2).sum(-1), axis=1) for chunk in np.array_split(images, 40)])


def template_mirror_miss(template, first, second):
    """The template's own miss for two of its key fields: the worst vertex's distance between
    the mirror of `first` (across x = 0, each vertex's nearest vertex to its image, brute
    force) and `second`, relative to the larger largest motion."""
    partner = template_partner(template)
    largest = max(np.linalg.norm(first, axis=1).max(), np.linalg.norm(second, axis=1).max())
    return np.linalg.norm(first[partner] * np.array([-1.0, 1.0, 1.0]) - second, axis=1).max() / max(largest, 1e-30)


def template_copy_y_up(name):
    """The Template collapse-decimated to half its faces, rescaled by 1.3, turned a quarter
    about X (Y up, still metres) and by 0.4 rad about its new up axis, and moved; with its
    motion (scale, rotation, shift) and its point pairs (template vertex -> the same point moved)."""
    import makehuman  # scripts/ is on the path (conftest)

    template = bpy.data.objects["Template"]
    obj = decimated_copy(template, name)
    turn = rotation((0.0, 0.4, 0.0)) @ rotation((-np.pi / 2, 0.0, 0.0))
    motion = (1.3, turn, np.array([0.2, 1.1, -0.3]))
    move = lambda p: motion[0] * np.asarray(p) @ motion[1].T + motion[2]  # noqa: E731
    obj.data.vertices.foreach_set("co", move(positions(obj)).astype(np.float32).ravel())
    obj.data.update()
    vertices = makehuman.pair_vertices(positions(template), skin_vertices(template))
    return obj, move, [[int(v), [float(x) for x in q]] for v, q in zip(vertices, move(positions(template)[vertices]))]


def test_a_symmetric_template_on_symmetric_characters_carries_mirrored_pairs(sample, shapesmith):
    """The template onto two mirror-symmetric characters whose triangles are not mirrored:
    Character_YoungWoman (another identity, centimetres, Y up) and the template decimated,
    rescaled, turned (Y up, metres). Fit and carry report symmetric; each carried Left/Right
    pair and each self-symmetric key mirrors within MIRROR_FACTOR times the template's own
    miss (its keys on its vertex map) plus the measure's floor on the character (what
    interpolating an image twice across the character's triangles costs the same keys), a
    bound the chain without symmetry breaks, the pairs the collision pass held apart
    differently included. No key carried onto Character_YoungWoman is worse than the
    template, and onto the copy no more than without symmetry."""
    native = module(shapesmith, "native").module()
    triangles_of = module(shapesmith, "blender.mesh_arrays").read_triangles
    template = bpy.data.objects["Template"]
    copy, move, copy_entries = template_copy_y_up("Character_TemplateCopy")
    young = bpy.data.objects["Character_YoungWoman"]
    young_entries = json.loads(young["shapesmith_wrap_pairs"])
    names = [block.name for block in template.data.shape_keys.key_blocks[1:]]
    own_keys = key_deltas(template, names)
    for obj, entries, plane in (
        (young, young_entries, ((0.0, 0.0, 0.0), (1.0, 0.0, 0.0))),
        (copy, copy_entries, (move(np.zeros((1, 3)))[0], np.array([1.0, 0.0, 0.0]) @ copy_motion_linear(move).T)),
    ):
        written, wrapped, result = wrap_and_carry(shapesmith, obj, entries)
        fit_symmetry, carry_symmetry = wrapped.report["symmetry"], result.report["symmetry"]
        assert fit_symmetry["symmetric"] and carry_symmetry["symmetric"], (fit_symmetry, carry_symmetry["reason"])
        pairs = [(row["first_name"], row["second_name"]) for row in carry_symmetry["shapes"]]
        assert ("eyeBlinkLeft", "eyeBlinkRight") in pairs and ("jawLeft", "jawRight") in pairs and ("jawOpen", "jawOpen") in pairs, pairs
        assert len(pairs) >= 28, pairs
        images = mirror_images(positions(obj), triangles_of(obj), *plane, native)
        assert images[3].mean() > 0.8, images[3].mean()
        carried = key_deltas(obj, written)
        # The same chain fitted and carried as if nothing were symmetric, measured alike: the
        # bound must be one it breaks.
        wrap = module(shapesmith, "blender.wrap")
        template_points, character_points = wrap.pairs_from_list(entries, template, obj)
        unsymmetric = wrap.wrap_object(template, obj, template_points, character_points,
                                       module(shapesmith, "blender.settings").WrapSettings(ignore_symmetry=True))
        plain_result = wrap.carry_onto_character(template, obj, wrap.show_wrapped(unsymmetric), symmetric=False)
        plain = plain_result.deltas
        rows = []
        for first, second in pairs:
            miss, floor = mirror_miss(images, carried[written.index(first)], carried[written.index(second)])
            plain_miss, _ = mirror_miss(images, plain[written.index(first)], plain[written.index(second)])
            own = template_mirror_miss(template, own_keys[names.index(first)], own_keys[names.index(second)])
            rows.append((first, second, miss, plain_miss, own, floor))
        print(obj.name + ": " + ", ".join(f"{a}/{b} {100 * m:.1f}% (without symmetry {100 * p:.1f}%, template {100 * t:.1f}%, floor {100 * f:.1f}%)" for a, b, m, p, t, f in rows))
        broken = [row[:2] for row in rows if row[3] > MIRROR_FACTOR * (row[4] + row[5])]
        assert len(broken) >= 5, rows
        # A pair the collision pass held apart differently, with no mirrored version meeting the
        # criterion, is re-solved from its average (the report says which): at most one here,
        # and it too within the bound.
        held_apart = {(row["first_name"], row["second_name"]) for row in carry_symmetry["shapes"] if row["held_apart"]}
        assert len(held_apart) <= 1, held_apart
        for first, second, miss, _, own, floor in rows:
            assert miss <= MIRROR_FACTOR * (own + floor), (obj.name, first, second, miss, own, floor)
        worse_than_template = module(shapesmith, "blender.transfer").worse_than_template
        worse, plain_worse = worse_than_template(result.report), worse_than_template(plain_result.report)
        print(f"{obj.name}: worse than the template {worse}, without symmetry {plain_worse}")
        # Measured: Character_YoungWoman none (one without symmetry); the half-decimated copy's
        # coarse lips keep mouthClose, mouthLeft/Right, mouthPucker and mouthRollUpper.
        assert worse == [] if obj == young else len(worse) <= len(plain_worse), (worse, plain_worse)


def copy_motion_linear(move):
    """The linear part of an affine `move` (points (N, 3) -> (N, 3))."""
    origin = move(np.zeros((1, 3)))[0]
    return np.stack([move(np.eye(3)[k][None])[0] - origin for k in range(3)], axis=1)


def test_an_asymmetric_character_is_wrapped_without_symmetry_and_says_why(sample, shapesmith):
    """Character_YoungWoman with its left half widened by 8%: no longer mirror-symmetric, it is
    fitted and carried as without symmetry, every key written, and the report says why."""
    obj = bpy.data.objects["Character_YoungWoman"]
    entries = json.loads(obj["shapesmith_wrap_pairs"])
    points = positions(obj)
    points[:, 0] = np.where(points[:, 0] > 0.0, 1.08 * points[:, 0], points[:, 0])
    obj.data.vertices.foreach_set("co", points.astype(np.float32).ravel())
    obj.data.update()
    written, wrapped, result = wrap_and_carry(shapesmith, obj, entries)
    assert len(written) == 52 and wrapped.report["mean_distance"] < 2e-3
    fit, carry = wrapped.report["symmetry"], result.report["symmetry"]
    assert not fit["symmetric"] and "character is not mirror-symmetric" in fit["reason"], fit
    assert not carry["symmetric"] and carry["shapes"] == [] and carry["worst"] is None, carry
    wrap = module(shapesmith, "blender.wrap")
    assert any("fitted without symmetry" in line for line in wrap.summary_lines(wrapped))
