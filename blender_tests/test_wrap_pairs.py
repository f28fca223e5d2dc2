"""Point pairs proposed, not clicked: on characters whose correspondence with the template is
known by construction (the sample's decimated identity, also with its lids open as an
avatar's, a decimated identity in centimetres with Y up, a decimated Template turned and
rescaled), every proposed character point lies near where the template point's feature truly
is, the keys from the proposed pairs are as good as those from the hand pairs, and the button,
Wrap with no pairs and the batch all propose."""

import json

import bpy
import numpy as np
import pytest

from conftest import make_active, run_batch
from test_wrap import (
    IDENTITY,
    MOTIONS,
    apply,
    character,
    decimated_copy,
    key_deltas,
    module,
    positions,
    sampled_truth,
    wrap_and_carry,
)

from wrap_copies import moving_error  # noqa: E402  (scripts/ is on the path: test_wrap)

# Each proposed character point lies within this fraction of the character's diagonal of the
# template point's true place (measured: on the sample character median 0.5%, the largest
# 1.4%, the nose tip of a decimated nose; on the turned decimated Template median 0.07%, the
# largest 0.34%, the chin).
PAIR_TOLERANCE = 0.03
MEDIAN_TOLERANCE = 0.008
# On a coarse avatar with lids open the holes' outer ends lie farther from the lids' corners
# and the chin is found on a section of few edges (measured 3.1% and 3.3%).
COARSE_HOLE_TOLERANCE = 0.035


def proposal_errors(proposal, truth_of_template_vertex, diagonal):
    """{pair name: distance of its character point from the true place of its template vertex,
    / diagonal}."""
    return {
        p["name"]: float(np.linalg.norm(np.array(p["character"]) - truth_of_template_vertex(p["template_vertex"])) / diagonal)
        for p in proposal["pairs"]
    }


FEATURES = [
    "eye corner inner left", "eye corner outer left", "eye corner inner right", "eye corner outer right",
    "mouth corner left", "mouth corner right", "nose tip", "chin",
]


def proposed_on_open_lids(shapesmith, wrap, obj):
    """The pairs proposed on the character `obj` with its lids opened, its points, and each
    feature's distance from its true place (of the diagonal)."""
    import makehuman  # scripts/ is on the path (conftest)
    from bench_wrap import open_lids

    assert open_lids(shapesmith, obj) > 50
    identity = positions(bpy.data.objects["Target_YoungWoman"])
    proposal = wrap.propose_pairs(bpy.data.objects["Template"], obj)
    points = positions(obj)
    diagonal = float(np.linalg.norm(points.max(0) - points.min(0)))
    scale = makehuman.CHARACTERS["Character_YoungWoman"]["scale"]
    errors = proposal_errors(proposal, lambda v: makehuman.character_frame(identity[[v]], scale)[0], diagonal)
    return proposal, points, errors


def check_proposal(errors, proposal):
    assert sorted(errors) == sorted(FEATURES), proposal["missing"]
    worst = max(errors, key=errors.get)
    assert errors[worst] < PAIR_TOLERANCE, (worst, errors)
    assert np.median(list(errors.values())) < MEDIAN_TOLERANCE, errors


def test_pairs_proposed_on_the_sample_character_lie_on_the_template_points_features(sample, shapesmith):
    import makehuman  # scripts/ is on the path (conftest)

    wrap = module(shapesmith, "blender.wrap")
    obj = bpy.data.objects["Character_YoungWoman"]
    identity = positions(bpy.data.objects["Target_YoungWoman"])
    proposal = wrap.propose_pairs(bpy.data.objects["Template"], obj)
    spec = makehuman.CHARACTERS["Character_YoungWoman"]
    points = positions(obj)
    diagonal = float(np.linalg.norm(points.max(0) - points.min(0)))
    errors = proposal_errors(proposal, lambda v: makehuman.character_frame(identity[[v]], spec["scale"])[0], diagonal)
    print({k: round(100 * e, 2) for k, e in errors.items()})
    check_proposal(errors, proposal)
    # Seen from the character's own front: +Z, up +Y (the sample character's mesh is Y up).
    assert np.dot(proposal["character_front"], [0, 0, 1]) > 0.98 and np.dot(proposal["character_up"], [0, 1, 0]) > 0.98


@pytest.mark.parametrize("ratio", [None, 0.45])
def test_pairs_proposed_on_the_sample_character_with_its_lids_open(sample, shapesmith, ratio):
    """An avatar's eye sockets are open at the lids: its eye corners are where the holes end,
    and the mouth and chin are still found where they are (with the lids open, the hollow
    under the lower lip seen from the front runs wider than the closed mouth: the mouth
    corners were proposed 10-11% of the diagonal off, the chin 19%); also on a coarser copy
    (1.1k vertices), which the alignment's screening of 4 steps a turn left face down."""
    from bench_wrap import decimate

    wrap = module(shapesmith, "blender.wrap")
    obj = bpy.data.objects["Character_YoungWoman"]
    if ratio is not None:
        decimate(obj, ratio)
    proposal, _, errors = proposed_on_open_lids(shapesmith, wrap, obj)
    print({k: round(100 * e, 2) for k, e in errors.items()})
    # The holes are cut rounder than lids: their outer ends lie up to 2.2% from the lids'
    # corners (measured), so the median is not the uncut character's; every pair is still
    # within the tolerance, and the mouth's corners as close as on the uncut character.
    assert sorted(errors) == sorted(FEATURES), proposal["missing"]
    assert max(errors.values()) < (COARSE_HOLE_TOLERANCE if ratio else PAIR_TOLERANCE), errors
    assert max(errors["mouth corner left"], errors["mouth corner right"]) < MEDIAN_TOLERANCE, errors


def jittered(obj, seed):
    """`obj`'s vertices moved by a random 1e-4 of its diagonal: a different collapse order."""
    rest = positions(obj)
    rng = np.random.default_rng(seed)
    rest += rng.normal(scale=1e-4 * np.linalg.norm(rest.max(0) - rest.min(0)), size=rest.shape)
    obj.data.vertices.foreach_set("co", rest.astype(np.float32).ravel())
    obj.data.update()


def unsubdivided(obj):
    modifier = obj.modifiers.new("Decimate", "DECIMATE")
    modifier.decimate_type, modifier.iterations = "UNSUBDIV", 1
    obj.data = bpy.data.meshes.new_from_object(obj.evaluated_get(bpy.context.evaluated_depsgraph_get()))
    obj.modifiers.clear()


@pytest.mark.parametrize("remake", ["ratio 0.3", "ratio 0.6", "ratio 0.8", "seed 1, ratio 0.45", "seed 2, ratio 0.45", "unsubdivided"])
def test_the_proposal_does_not_hang_on_the_vertex_layout(sample, shapesmith, remake):
    """The lids-open sample character decimated by Blender's Decimate (collapse at several
    ratios, also after its vertices were jittered by 1e-4 of the diagonal, which changes the
    collapse order; un-subdivide): every feature is proposed within the coarse tolerance
    (measured on bpy 4.2 and 4.5: the largest 3.25%, an outer eye corner at a lid hole; the chin
    at most 3.24%). The chin was missed at ratios 0.3 and 0.45 before it was read from the
    profile's front outline."""
    from bench_wrap import decimate

    wrap = module(shapesmith, "blender.wrap")
    obj = bpy.data.objects["Character_YoungWoman"]
    words = remake.replace(",", "").split()
    if "seed" in words:
        jittered(obj, int(words[words.index("seed") + 1]))
    if "ratio" in words:
        decimate(obj, float(words[words.index("ratio") + 1]))
    if "unsubdivided" in words:
        unsubdivided(obj)
    proposal, points, errors = proposed_on_open_lids(shapesmith, wrap, obj)
    print(remake, len(points), {k: round(100 * e, 2) for k, e in errors.items()})
    assert sorted(errors) == sorted(FEATURES), proposal["missing"]
    assert max(errors.values()) < COARSE_HOLE_TOLERANCE, errors


def test_pairs_proposed_on_a_decimated_turned_rescaled_template(sample, shapesmith):
    """The Template decimated, turned off every axis and in millimetres: each template point's
    true place is the template vertex moved."""
    wrap = module(shapesmith, "blender.wrap")
    template = bpy.data.objects["Template"]
    obj = decimated_copy(template, "Character_Template", ratio=0.4)
    motion = MOTIONS["mm_turned"]
    obj.data.vertices.foreach_set("co", apply(motion, positions(obj)).astype(np.float32).ravel())
    obj.data.update()
    proposal = wrap.propose_pairs(template, obj)
    points = positions(obj)
    diagonal = float(np.linalg.norm(points.max(0) - points.min(0)))
    rest = positions(template)
    errors = proposal_errors(proposal, lambda v: apply(motion, rest[[v]])[0], diagonal)
    print({k: round(100 * e, 2) for k, e in errors.items()})
    check_proposal(errors, proposal)


def test_keys_from_proposed_pairs_are_as_close_to_the_truth_as_from_hand_pairs(sample, shapesmith):
    """The decimated identity in centimetres with Y up of test_wrap, once with its hand pairs
    (exact by construction) and once with pairs proposed: the keys' error against the
    same-topology transfer, within 15% of the hand pairs' (measured 1.58e-3 proposed against
    1.39e-3 hand, 13.2% more; with the surfaces kept apart in the transfers 1.70e-3 against
    1.52e-3, 12.2%)."""
    wrap = module(shapesmith, "blender.wrap")
    transfer = module(shapesmith, "blender.transfer")
    template = bpy.data.objects["Template"]
    truth = transfer.transfer_object(template, bpy.data.objects[IDENTITY]).deltas.astype(np.float64)
    motion = MOTIONS["cm_y_up"]
    errors = {}
    for label in ("hand", "proposed"):
        obj, entries = character(motion, f"Character_{label}")
        if label == "proposed":
            proposal = wrap.propose_pairs(template, obj)
            entries = [[p["template_vertex"], p["character_vertex"]] for p in proposal["pairs"]]
        names, wrapped, _ = wrap_and_carry(shapesmith, obj, entries)
        reference = sampled_truth(shapesmith, motion, obj, truth)
        errors[label] = moving_error(key_deltas(obj, names), reference, wrapped.report["diagonal"])
    print(errors)
    assert errors["proposed"] <= 1.15 * errors["hand"], errors


def test_the_button_fills_the_pairs_list_in_one_undo_step_and_wrap_proposes_when_there_are_none(sample, shapesmith):
    obj = bpy.data.objects["Character_YoungWoman"]
    del obj["shapesmith_wrap_pairs"]  # the sample's script pairs: a character starting from nothing
    bpy.context.scene.shapesmith.transfer.source = bpy.data.objects["Template"]
    make_active(obj)
    bpy.ops.ed.undo_push(message="before")
    assert bpy.ops.shapesmith.propose_point_pairs() == {"FINISHED"}
    pairs = bpy.data.objects["Character_YoungWoman"].shapesmith_wrap.pairs
    names = [p.name for p in pairs]
    assert sorted(names) == sorted(FEATURES) and all(p.template_vertex >= 0 and p.character_vertex >= 0 for p in pairs)
    bpy.ops.ed.undo_push(message="proposed")
    bpy.ops.ed.undo()
    obj = bpy.data.objects["Character_YoungWoman"]
    assert len(obj.shapesmith_wrap.pairs) == 0
    make_active(obj)
    assert bpy.ops.shapesmith.wrap_template() == {"FINISHED"}
    assert len(obj.shapesmith_wrap.pairs) == len(FEATURES) and obj.shapesmith_wrap.alignment == "pairs"
    assert obj.shapesmith_wrap.mean_distance < 2e-3, obj.shapesmith_wrap.mean_distance


def test_batch_proposes_the_pairs_writes_them_to_the_json_and_uses_them(sample_path, tmp_path):
    out = tmp_path / "wrap.json"
    proc = run_batch("wrap", "--input", sample_path, "--template", "Template", "--character", "Character_YoungWoman",
                     "--propose-pairs", "--no-transfer", "--json", str(out))
    assert proc.returncode == 0, proc.stderr
    report = json.loads(out.read_text())
    proposed = report["proposed_pairs"]["pairs"]
    assert len(proposed) == len(FEATURES) and report["fit"]["pairs"] == len(proposed) and report["fit"]["alignment"] == "pairs"
    assert "point pairs proposed" in proc.stdout
    proc = run_batch("wrap", "--input", sample_path, "--template", "Template", "--character", "Character_YoungWoman",
                     "--propose-pairs", "--pairs", str(out))
    assert proc.returncode == 2 and "not both" in proc.stderr


def components(obj):
    """Per vertex, its connected piece's label (its lowest vertex's index)."""
    faces = [tuple(p.vertices) for p in obj.data.polygons]
    labels = np.full(len(obj.data.vertices), -1)
    adjacency = {}
    for face in faces:
        for a in face:
            adjacency.setdefault(a, set()).update(face)
    for start in range(len(labels)):
        if labels[start] >= 0:
            continue
        labels[start] = start
        stack = [start]
        while stack:
            for w in adjacency.get(stack.pop(), ()):
                if labels[w] < 0:
                    labels[w] = start
                    stack.append(w)
    return labels


def test_the_templates_pieces_land_on_the_characters_and_a_character_without_teeth_says_so(sample, shapesmith):
    """With the sample character's hand pairs, each template piece fitted onto a character piece
    has its centre within 10% of its size (root-mean-square radius) of where its vertices truly
    are, the identity's same vertices (measured: at most 7.5%, a 226-vertex piece 2.1 cm in
    radius, 1.6 mm off); with the character's teeth and tongue removed, the template's follow the skin
    and the report says so, the other pieces still fitted."""
    import bmesh
    import makehuman  # scripts/ is on the path (conftest)

    wrap = module(shapesmith, "blender.wrap")
    template, obj = bpy.data.objects["Template"], bpy.data.objects["Character_YoungWoman"]
    identity = positions(bpy.data.objects["Target_YoungWoman"])
    scale = makehuman.CHARACTERS["Character_YoungWoman"]["scale"]
    template_points, character_points = wrap.stored_pairs(obj, template)
    wrapped = wrap.wrap_object(template, obj, template_points, character_points)
    labels = components(template)
    rest = positions(template)
    eye_motion = np.abs(key_deltas(template, ["eyeBlinkLeft", "eyeBlinkRight", "eyeLookUpLeft", "eyeLookUpRight"])).sum(axis=(0, 2))
    skin_label = np.bincount(labels).argmax()
    fitted_rows = [row for row in wrapped.report["piece_matches"] if row["fitted"]]
    assert len(fitted_rows) >= 7, wrap.match_lines(wrapped.report)
    for row in fitted_rows:
        piece = np.flatnonzero(labels == labels[row["template_vertex"]])
        truth = makehuman.character_frame(identity[piece], scale)
        size = np.sqrt(((truth - truth.mean(0)) ** 2).sum(1).mean())
        offset = np.linalg.norm(wrapped.positions[piece].mean(0) - truth.mean(0))
        assert offset < 0.1 * size, (row["template_name"], offset / size)
    # The template's teeth and tongue: the pieces no blink or eye look moves (as test_face_parts
    # splits them). Their character matches go.
    pieces = set(labels) - {skin_label}
    teeth = {label for label in pieces if not eye_motion[labels == label].any()}
    assert len(teeth) == 3, len(teeth)
    character_labels = components(obj)
    doomed = set()
    for row in wrapped.report["piece_matches"]:
        if labels[row["template_vertex"]] in teeth and row["character_vertex"] is not None:
            doomed.add(character_labels[row["character_vertex"]])
    assert doomed
    mesh = bmesh.new()
    mesh.from_mesh(obj.data)
    mesh.verts.ensure_lookup_table()
    bmesh.ops.delete(mesh, geom=[v for v in mesh.verts if character_labels[v.index] in doomed], context="VERTS")
    mesh.to_mesh(obj.data)
    mesh.free()
    obj.data.update()
    without = wrap.wrap_object(template, obj, template_points, character_points).report
    lines = wrap.match_lines(without)
    for row in without["piece_matches"]:
        if labels[row["template_vertex"]] in teeth:
            assert not row["fitted"] and row["character_vertex"] is None, row
            assert any(line.startswith(row["template_name"]) and "follows the skin" in line for line in lines), lines
    assert without["pieces_fitted"] == wrapped.report["pieces_fitted"] - sum(
        1 for row in wrapped.report["piece_matches"] if row["fitted"] and labels[row["template_vertex"]] in teeth
    ), lines


def test_the_templates_lids_land_on_an_avatars_lid_holes_and_its_blink_closes_them(sample, shapesmith):
    """The sample character with its lids cut open (an avatar's lid holes; its eye sockets
    still paired with the template's), wrapped with exact pairs: both lid holes are reported
    landed, and the carried blinks move the holes' rims as far as the same-topology blink
    sampled there (before the lids landed: 60% as far, the template's lids 1.1% of the
    diagonal off; measured now 97%)."""
    import makehuman  # scripts/ is on the path (conftest)
    from bench_wrap import open_lids, young_reference

    transfer = module(shapesmith, "blender.transfer")
    template, obj = bpy.data.objects["Template"], bpy.data.objects["Character_YoungWoman"]
    assert open_lids(shapesmith, obj) > 50
    truth = transfer.transfer_object(template, bpy.data.objects["Target_YoungWoman"])
    identity = positions(bpy.data.objects["Target_YoungWoman"])
    scale = makehuman.CHARACTERS["Character_YoungWoman"]["scale"]
    rest = positions(template)
    skin = makehuman.largest_piece(len(rest), [tuple(p.vertices) for p in template.data.polygons])
    entries = [[int(v), [float(x) for x in makehuman.character_frame(identity[[v]], scale)[0]]] for v in makehuman.pair_vertices(rest, skin)]
    names, wrapped, _ = wrap_and_carry(shapesmith, obj, entries)
    lid_rows = [row for row in wrapped.report["hole_matches"] if row["lids"]]
    assert len(lid_rows) == 2 and all("lid hole" in row["character_name"] for row in lid_rows), wrapped.report["hole_matches"]
    reference = young_reference(shapesmith, obj, truth.deltas.astype(np.float64))
    for name in ("eyeBlinkLeft", "eyeBlinkRight"):
        carried = np.linalg.norm(key_deltas(obj, [name])[0], axis=1).max()
        true = np.linalg.norm(reference[list(truth.names).index(name)], axis=1).max()
        print(f"{name}: largest motion {carried:.4f} against {true:.4f}")
        assert 0.9 * true < carried < 1.1 * true, (name, carried, true)
