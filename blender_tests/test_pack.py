"""Pack Expressions on the MakeHuman Template: poseable expressions (no antagonists together,
partners together, active regions disjoint, checked here from the shape keys themselves),
the result stored on the object, what the rigger does with it, bad input, and batch."""

import csv
import json
import math
from dataclasses import replace

import bpy
import numpy as np
import pytest

from conftest import file_digest, make_active, run_batch

ANTAGONISTS = [("jawLeft", "jawRight"), ("mouthLeft", "mouthRight")]


def shape_deltas(obj):
    """{name: (N, 3) delta} read here, independently of the add-on."""
    keys = obj.data.shape_keys
    n = len(obj.data.vertices)
    basis = np.empty(n * 3, np.float32)
    keys.reference_key.data.foreach_get("co", basis)
    deltas = {}
    for block in keys.key_blocks[1:]:
        co = np.empty(n * 3, np.float32)
        block.data.foreach_get("co", co)
        deltas[block.name] = (co - basis).reshape(n, 3).astype(np.float64)
    return deltas


def binary_blendshapes(deltas, mu):
    """b_k[n] = |D_k[n]| >= mu * max |D_k| (method, section 1), as vertex sets."""
    sets = {}
    for name, delta in deltas.items():
        length = np.linalg.norm(delta, axis=1)
        sets[name] = set(np.flatnonzero(length >= mu * length.max()).tolist()) if length.max() > 0 else set()
    return sets


def check_poseable(expressions, pairs, deltas, mu):
    """Every expression: no antagonists, partners together, active sets pairwise disjoint
    (partners excepted); every moving shape placed exactly once."""
    active = binary_blendshapes(deltas, mu)
    partners = {frozenset(p) for p in pairs}
    where = {}
    for j, members in enumerate(expressions):
        for name in members:
            assert name not in where, f"{name} in expressions {where[name] + 1} and {j + 1}"
            where[name] = j
        for first, second in ANTAGONISTS:
            assert not (first in members and second in members), f"expression {j + 1} poses {first} with {second}"
        for i, first in enumerate(members):
            for second in members[i + 1 :]:
                if frozenset((first, second)) in partners:
                    continue
                overlap = active[first] & active[second]
                assert not overlap, f"expression {j + 1}: {first} and {second} share vertex {min(overlap)}"
    for first, second in pairs:
        assert where.get(first) == where.get(second), f"{first} and {second} are apart"
    return where


def pack(obj, **settings):
    make_active(obj)
    for key, value in settings.items():
        setattr(obj.shapesmith.pack, key, value)
    assert bpy.ops.shapesmith.pack_expressions() == {"FINISHED"}
    return obj.shapesmith.pack.result


def members(result):
    return [[m.name for m in e.members] for e in result.expressions]


@pytest.mark.parametrize("analyzed", [False, True], ids=["pairs-found-by-packing", "pairs-from-analyze-rig"])
def test_template_expressions_are_poseable_optimal_and_complete(sample, analyzed):
    template = make_active(bpy.data.objects["Template"])
    if analyzed:
        assert bpy.ops.shapesmith.analyze_rig() == {"FINISHED"}
    result = pack(template)
    deltas = shape_deltas(template)
    pairs = [(p.first, p.second) for p in result.pairs]
    assert len(pairs) == 18 and not {frozenset(a) for a in ANTAGONISTS} & {frozenset(p) for p in pairs}
    assert {frozenset((p.first, p.second)) for p in result.antagonists} >= {frozenset(a) for a in ANTAGONISTS}
    where = check_poseable(members(result), pairs, deltas, mu=0.3)
    moving = {name for name, delta in deltas.items() if np.abs(delta).max() > 0}
    assert set(where) == moving - {s.name for s in result.inert}
    assert all(e.optimal for e in result.expressions)
    assert 1 < len(result.expressions) < len(moving)
    importance = [e.importance for e in result.expressions]
    assert importance[0] == max(importance)


def together(groups, first, second):
    return any(first in g and second in g for g in groups)


def test_template_expressions_can_be_posed_and_seen(sample):
    """Collision and occlusion conflicts (method, section 1, poseable and observable): the tongue
    never goes out through closed lips, an eye never turns under its own closed lid; with
    both switched off the first expression asks for exactly that."""
    template = bpy.data.objects["Template"]
    result = pack(template)
    groups = members(result)
    assert not together(groups, "tongueOut", "mouthClose")
    for side in ("Left", "Right"):
        for look in ("In", "Out", "Up", "Down"):
            assert not together(groups, f"eyeLook{look}{side}", f"eyeBlink{side}"), f"eyeLook{look}{side}"
    reasons = {frozenset((c.first, c.second)): set(c.reasons.split()) for c in result.conflicts}
    assert "collision" in reasons[frozenset(("tongueOut", "mouthClose"))]
    assert "occlusion" in reasons[frozenset(("eyeLookInLeft", "eyeBlinkLeft"))]
    assert set().union(*reasons.values()) <= {"overlap", "antagonist", "collision", "occlusion", "user"}
    assert all(e.optimal for e in result.expressions)

    off = members(pack(template, collision_conflicts=False, occlusion_conflicts=False))
    assert {"tongueOut", "mouthClose", "eyeLookInLeft", "eyeBlinkLeft"} <= set(off[0])
    assert not any("collision" in c.reasons or "occlusion" in c.reasons for c in template.shapesmith.pack.result.conflicts)


def test_stored_weights_match_the_members_and_survive_save_and_reload(sample, shapesmith, tmp_path):
    template = bpy.data.objects["Template"]
    result = pack(template, fewest=True)
    before = members(result)
    assert 1 <= result.fewest <= len(before) and result.fewest_optimal
    path = str(tmp_path / "packed.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    template = bpy.data.objects["Template"]
    assert members(template.shapesmith.pack.result) == before
    names, weights = shapesmith.blender.packing.stored_weights(template)
    assert names == [kb.name for kb in template.data.shape_keys.key_blocks[1:]]
    assert weights.shape == (len(before), len(names)) and set(np.unique(weights)) <= {0, 1}
    for row, group in zip(weights, before):
        assert sorted(names[k] for k in np.flatnonzero(row)) == sorted(group)
    report = shapesmith.blender.packing.stored_report(template)
    assert report["fewest"]["count"] == template.shapesmith.pack.result.fewest
    assert report["params"]["mu"] == pytest.approx(0.3)


def test_export_shot_list_writes_json_and_csv_from_the_stored_result(sample, tmp_path):
    template = bpy.data.objects["Template"]
    groups = members(pack(template))
    path = tmp_path / "shots.json"
    assert bpy.ops.shapesmith.export_shot_list(filepath=str(path)) == {"FINISHED"}
    report = json.loads(path.read_text())
    assert [e["shapes"] for e in report["expressions"]] == groups
    assert {frozenset(a) for a in report["antagonists"]} >= {frozenset(a) for a in ANTAGONISTS}
    assert len(report["weights"]) == len(groups) and all(sum(row) == len(g) for row, g in zip(report["weights"], groups))
    rows = list(csv.DictReader(open(tmp_path / "shots.csv")))
    assert [r["label"] for r in rows] == [f"REF_{j + 1:02d}" for j in range(len(groups))]
    assert [r["shapes"].split() for r in rows] == groups
    assert {frozenset(c["shapes"]): c["reasons"] for c in report["conflicts"]}[frozenset(("tongueOut", "mouthClose"))]

    bpy.context.active_object.shapesmith.pack.explain = True
    assert bpy.ops.shapesmith.export_shot_list(filepath=str(path)) == {"FINISHED"}
    expressions, kept_apart = read_shot_list(tmp_path / "shots.csv")
    assert [r["shapes"].split() for r in expressions] == groups
    check_kept_apart(kept_apart, groups)


def read_shot_list(path):
    """(expression rows, kept-apart rows) of a CSV shot list, the second empty without Explain."""
    lines = open(path, newline="").read().splitlines()
    blank = lines.index("") if "" in lines else len(lines)
    return list(csv.DictReader(lines[:blank])), list(csv.DictReader(lines[blank + 1 :]))


def check_kept_apart(rows, groups):
    """Every pair the Explain rows list is posed in different expressions, with its reasons."""
    assert rows
    where = {name: j + 1 for j, g in enumerate(groups) for name in g}
    for row in rows:
        assert row["reasons"].split() and set(row["reasons"].split()) <= {"overlap", "antagonist", "collision", "occlusion", "user"}
        assert int(row["first in"]) == where[row["kept apart"]] != where[row["second"]] == int(row["second in"])
    by_pair = {frozenset((r["kept apart"], r["second"])): r["reasons"] for r in rows}
    assert "collision" in by_pair[frozenset(("tongueOut", "mouthClose"))]


def test_export_to_an_unwritable_place_is_reported(sample, tmp_path):
    pack(bpy.data.objects["Template"])
    path = tmp_path / "missing folder" / "shots.json"
    with pytest.raises(RuntimeError, match="No such file"):
        bpy.ops.shapesmith.export_shot_list(filepath=str(path))
    assert not path.parent.exists()


def test_a_higher_threshold_packs_into_no_more_expressions(sample):
    template = bpy.data.objects["Template"]
    loose = len(pack(template, mu=0.2).expressions)
    strict = pack(template, mu=0.5)
    check_poseable(members(strict), [(p.first, p.second) for p in strict.pairs], shape_deltas(template), mu=0.5)
    assert len(strict.expressions) <= loose


def test_refinements_are_honoured(sample):
    template = bpy.data.objects["Template"]
    settings = template.shapesmith.pack
    plain = members(pack(template))
    together = next(g for g in plain if "eyeBlinkLeft" in g)
    assert "eyeBlinkRight" in together
    bpy.ops.shapesmith.add_pack_refinement(kind="APART")
    bpy.ops.shapesmith.add_pack_refinement(kind="EXCLUDE")
    settings.keep_apart[0].first, settings.keep_apart[0].second = "eyeBlinkLeft", "eyeBlinkRight"
    settings.exclude[0].name = "jawOpen"
    bpy.ops.shapesmith.add_pack_refinement(kind="PIN")
    settings.pin_together[0].first, settings.pin_together[0].second = "browInnerUp", "mouthPucker"
    result = pack(template)
    groups = members(result)
    where = {name: j for j, g in enumerate(groups) for name in g}
    assert where["eyeBlinkLeft"] != where["eyeBlinkRight"]
    assert "jawOpen" not in where and [s.name for s in result.excluded] == ["jawOpen"]
    assert where["browInnerUp"] == where["mouthPucker"]
    assert bpy.ops.shapesmith.remove_pack_refinement(kind="EXCLUDE") == {"FINISHED"}
    assert len(settings.exclude) == 0


def test_symmetry_off_lets_partners_part(sample):
    template = bpy.data.objects["Template"]
    result = pack(template, symmetric=False)
    assert len(result.pairs) == 0
    check_poseable(members(result), [], shape_deltas(template), mu=0.3)


def test_max_expressions_leaves_the_rest_unplaced(sample):
    template = bpy.data.objects["Template"]
    result = pack(template, limit_expressions=True, max_expressions=2)
    assert len(result.expressions) == 2 and len(result.unplaced) > 0
    placed = {name for g in members(result) for name in g}
    assert placed.isdisjoint(s.name for s in result.unplaced)


def test_preview_animate_and_bake(sample):
    template = bpy.data.objects["Template"]
    result = pack(template)
    groups = members(result)
    blocks = template.data.shape_keys.key_blocks
    assert bpy.ops.shapesmith.preview_expression(index=1) == {"FINISHED"}
    assert {kb.name for kb in blocks[1:] if kb.value == 1.0} == set(groups[1])
    assert all(kb.value == 0.0 for kb in blocks[1:] if kb.name not in groups[1])

    assert bpy.ops.shapesmith.animate_expressions() == {"FINISHED"}
    scene = bpy.context.scene
    assert (scene.frame_start, scene.frame_end) == (1, len(groups))
    for frame in (1, len(groups) // 2 + 1, len(groups)):
        scene.frame_set(frame)
        assert {kb.name for kb in blocks[1:] if kb.value > 0.5} == set(groups[frame - 1])

    assert bpy.ops.shapesmith.bake_expressions() == {"FINISHED"}
    deltas = shape_deltas(template)
    for j, group in enumerate(groups):
        baked = deltas[f"REF_{j + 1:02d}"]
        assert np.allclose(baked, sum(deltas[name] for name in group), atol=1e-5)
        assert blocks[f"REF_{j + 1:02d}"].value == 0.0
    # Baked keys are never packed themselves (nor analysed, laid out or transferred: the rig
    # read for every tool leaves them out), and baking again replaces them.
    assert members(pack(template)) == groups
    assert bpy.ops.shapesmith.analyze_rig() == {"FINISHED"} and template.shapesmith.analysis.shapes == 52
    assert bpy.ops.shapesmith.bake_expressions() == {"FINISHED"}
    assert sum(kb.name.startswith("REF_") for kb in blocks) == len(groups)


def test_undo_restores_the_previous_result(sample):
    template = bpy.data.objects["Template"]
    first = members(pack(template))
    bpy.ops.ed.undo_push(message="first pack")
    pack(template, mu=0.5)
    bpy.ops.ed.undo_push(message="second pack")
    assert members(bpy.data.objects["Template"].shapesmith.pack.result) != first
    bpy.ops.ed.undo()
    assert members(bpy.data.objects["Template"].shapesmith.pack.result) == first


def test_reference_sheet_has_one_labelled_tile_per_expression(sample, tmp_path):
    template = bpy.data.objects["Template"]
    groups = members(pack(template))
    template.data.shape_keys.key_blocks["jawOpen"].value = 0.4
    scenes, objects = len(bpy.data.scenes), len(bpy.data.objects)
    counts = {kind: len(getattr(bpy.data, kind)) for kind in ("meshes", "materials", "curves", "cameras", "shape_keys")}
    materials = list(template.data.materials)
    path = str(tmp_path / "sheet.png")
    assert bpy.ops.shapesmith.render_reference_sheet(filepath=path, tile_width=96, tile_height=120) == {"FINISHED"}
    image = bpy.data.images.load(path)
    columns = math.ceil(math.sqrt(len(groups)))
    assert tuple(image.size) == (2 * 96 * columns, 120 * math.ceil(len(groups) / columns))
    pixels = np.empty(image.size[0] * image.size[1] * 4, np.float32)
    image.pixels.foreach_get(pixels)
    tiles = pixels.reshape(image.size[1], image.size[0], 4)[:, :, :3]
    front, side = tiles[-120:, :96], tiles[-120:, 96:192]
    assert front.min() < 0.4 and front.max() > 0.9  # dark label and head shading on white
    assert not np.allclose(front, side)  # the three-quarter view beside the front one
    assert not np.allclose(tiles[-120:, :192], tiles[-120:, 192:384])  # expressions differ
    # Members' regions are tinted: strongly coloured pixels in both views (the rig is grey).
    for view in (front, side):
        assert (view.max(axis=2) - view.min(axis=2)).max() > 0.3
    assert len(bpy.data.scenes) == scenes and len(bpy.data.objects) == objects
    assert {kind: len(getattr(bpy.data, kind)) for kind in counts} == counts
    assert template.data.shape_keys.key_blocks["jawOpen"].value == pytest.approx(0.4)
    assert list(template.data.materials) == materials  # tinted through a copy, never the rig


# --- bad input: a clear error and nothing changed ------------------------------------------


def assert_refused(obj, message):
    make_active(obj)
    with pytest.raises(RuntimeError, match=message):
        bpy.ops.shapesmith.pack_expressions()
    assert not obj.shapesmith.pack.result.done


def test_a_mesh_without_shape_keys_is_refused(sample):
    target = bpy.data.objects["Target_OldMan"]
    assert_refused(target, "no shape keys")
    assert target.data.shape_keys is None


def test_a_single_shape_is_one_expression(sample):
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=4, y_subdivisions=4)
    grid = make_active(bpy.context.active_object)
    grid.shape_key_add(name="Basis", from_mix=False)
    key = grid.shape_key_add(name="bump", from_mix=False)
    key.value = 0.0
    key.data[5].co.z += 0.3
    result = pack(grid)
    assert members(result) == [["bump"]] and result.expressions[0].optimal


def test_all_inert_shapes_are_refused(sample):
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=4, y_subdivisions=4)
    grid = make_active(bpy.context.active_object)
    grid.shape_key_add(name="Basis", from_mix=False)
    for name in ("still", "unmoved"):
        grid.shape_key_add(name=name, from_mix=False).value = 0.0
    assert_refused(grid, "inert")


def test_a_target_with_another_vertex_count_is_refused(sample):
    template = bpy.data.objects["Template"]
    bpy.ops.mesh.primitive_cube_add()
    template.shapesmith.pack.target = bpy.context.active_object
    assert_refused(template, "target 'Cube' has 8 vertices")


def test_nan_coordinates_are_refused(sample):
    template = bpy.data.objects["Template"]
    template.data.shape_keys.key_blocks["mouthSmileLeft"].data[11].co.y = float("nan")
    assert_refused(template, "mouthSmileLeft.*vertex 11")


def test_zero_expressions_are_refused(sample, shapesmith):
    template = bpy.data.objects["Template"]
    with pytest.raises(ValueError, match="at least 1"):
        shapesmith.blender.packing.pack_object(template, shapesmith.blender.settings.PackSettings(max_expressions=0))
    assert not template.shapesmith.pack.result.done


def test_a_failed_pack_keeps_the_earlier_result(sample):
    template = bpy.data.objects["Template"]
    before = members(pack(template))
    bpy.ops.shapesmith.add_pack_refinement(kind="EXCLUDE")
    template.shapesmith.pack.exclude[0].name = "noSuchShape"
    with pytest.raises(RuntimeError, match="noSuchShape"):
        bpy.ops.shapesmith.pack_expressions()
    assert members(template.shapesmith.pack.result) == before


# --- batch --------------------------------------------------------------------------------


def test_batch_pack_writes_json_csv_sheet_and_a_packed_copy(sample_path, tmp_path):
    out = {name: str(tmp_path / name) for name in ("pack.json", "pack.csv", "sheet.png", "packed.blend")}
    digest = file_digest(sample_path)
    proc = run_batch(
        "pack", "--input", sample_path, "--object", "Template", "--fewest", "--bake", "--json", out["pack.json"],
        "--csv", out["pack.csv"], "--explain", "--sheet", out["sheet.png"], "--output", out["packed.blend"], check=True,
    )
    assert file_digest(sample_path) == digest
    report = json.loads(open(out["pack.json"]).read())
    for key in ("expressions", "inert", "pairs", "antagonists", "params", "seconds", "weights", "fewest"):
        assert key in report
    assert set(report["seconds"]) == {"read", "cache_key", "native", "write"}
    assert "conflicts_cache" not in report and report["poseability"]["pairs_reused"] == 0
    assert report["params"]["mu"] == pytest.approx(0.3) and report["params"]["symmetric"] is True
    groups = [e["shapes"] for e in report["expressions"]]
    assert all(e["optimal"] for e in report["expressions"])
    assert report["fewest"]["count"] <= len(groups)
    assert f"1. {', '.join(groups[0])}" in proc.stdout
    rows, kept_apart = read_shot_list(out["pack.csv"])
    assert [r["shapes"].split() for r in rows] == groups
    check_kept_apart(kept_apart, groups)
    assert "collisions kept apart:" in proc.stdout and "tongueOut" in proc.stdout.split("collisions kept apart:")[1]

    bpy.ops.wm.open_mainfile(filepath=out["packed.blend"])
    template = bpy.data.objects["Template"]
    check_poseable(groups, report["pairs"], {k: v for k, v in shape_deltas(template).items() if not k.startswith("REF_")}, 0.3)
    assert members(template.shapesmith.pack.result) == groups
    assert [kb.name for kb in template.data.shape_keys.key_blocks if kb.name.startswith("REF_")] == [
        f"REF_{j + 1:02d}" for j in range(len(groups))
    ]
    image = bpy.data.images.load(out["sheet.png"])
    assert image.size[0] > 0 and image.size[1] > 0

    # The packed copy carries the collision and occlusion results: packing it again reuses them.
    again = run_batch("pack", "--input", out["packed.blend"], "--object", "Template", "--fewest", "--json", out["pack.json"], check=True)
    second = json.loads(open(out["pack.json"]).read())
    assert second["poseability"]["pairs_reused"] > 500 and second["poseability"]["collision_pairs_tested"] == 0
    assert [e["shapes"] for e in second["expressions"]] == groups and second["conflicts"] == report["conflicts"]
    assert "pairs reused from the results stored on the object" in again.stdout


def test_batch_pack_flags_change_the_result(sample_path, tmp_path):
    out = str(tmp_path / "pack.json")
    run_batch("pack", "--input", sample_path, "--object", "Template", "--no-symmetry", "--mu", "0.4",
              "--max-expressions", "3", "--json", out, check=True)
    report = json.loads(open(out).read())
    assert report["pairs"] == [] and len(report["expressions"]) == 3 and report["unplaced"]
    assert report["params"]["mu"] == pytest.approx(0.4) and report["params"]["max_expressions"] == 3
    assert report["collisions"] and report["occlusions"]

    run_batch("pack", "--input", sample_path, "--object", "Template", "--no-collision-conflicts",
              "--no-occlusion-conflicts", "--json", out, check=True)
    report = json.loads(open(out).read())
    assert report["params"]["collision_conflicts"] is False and report["params"]["occlusion_conflicts"] is False
    assert report["collisions"] == [] and report["occlusions"] == []
    assert together([e["shapes"] for e in report["expressions"]], "tongueOut", "mouthClose")
    run_batch("pack", "--input", sample_path, "--object", "Template", "--collision-tolerance", "0.5",
              "--occlusion-keep", "0.2", "--json", out, check=True)
    report = json.loads(open(out).read())
    assert report["params"]["collision_tolerance"] == pytest.approx(0.5) and report["params"]["occlusion_keep"] == pytest.approx(0.2)
    assert all(c["between_pieces"] > 0.5 for c in report["collisions"]) and all(o["kept"] < 0.2 for o in report["occlusions"])


@pytest.mark.parametrize(
    "args, message",
    [
        (["--object", "Target_OldMan"], "no shape keys"),
        (["--object", "Template", "--max-expressions", "0"], "at least 1"),
        (["--object", "Template", "--target", "Nobody"], "no object named 'Nobody'"),
        (["--object", "Template", "--target", "Camera"], "not a mesh"),
        (["--object", "Template", "--explain"], "give --csv too"),
        (["--object", "Template", "--collision-tolerance", "0"], "collision_tolerance must be a positive number"),
        (["--object", "Template", "--occlusion-keep", "1.5"], "occlusion_keep must be in (0, 1]"),
    ],
)
def test_batch_pack_bad_input_exits_with_one_line(sample_path, tmp_path, args, message):
    path = str(tmp_path / "input.blend")
    bpy.ops.wm.open_mainfile(filepath=sample_path)
    bpy.data.objects.new("Camera", bpy.data.cameras.new("Camera"))
    bpy.context.scene.collection.objects.link(bpy.data.objects["Camera"])
    bpy.ops.wm.save_as_mainfile(filepath=path)
    digest = file_digest(path)
    output = tmp_path / "out.blend"
    proc = run_batch("pack", "--input", path, *args, "--output", str(output))
    assert proc.returncode == 2
    lines = proc.stderr.strip().splitlines()
    assert lines and message in lines[-1] and lines[-1].startswith("shapesmith: error:")
    assert file_digest(path) == digest and not output.exists()


def test_progress_reaches_the_caller_and_stopping_keeps_the_previous_result(sample, shapesmith):
    """Packing with the collision and occlusion tests takes seconds on a dense head: the
    operator shows it in the progress cursor, and False from the callback stops it."""
    template = make_active(bpy.data.objects["Template"])
    assert bpy.ops.shapesmith.pack_expressions() == {"FINISHED"}
    first = shapesmith.blender.packing.stored_report(template)
    seen = []
    report = shapesmith.blender.packing.pack_object(template, progress=seen.append)
    assert len(seen) >= 5 and seen == sorted(seen) and seen[0] == 0.0 and seen[-1] == 1.0, seen
    # Stages in between: the poseability tests end at 80%, the programs fill the rest.
    assert any(0.0 < f <= 0.8 for f in seen) and any(0.8 < f < 1.0 for f in seen), seen
    without = shapesmith.blender.packing.pack_object(template)
    assert [e["shapes"] for e in report["expressions"]] == [e["shapes"] for e in without["expressions"]]
    with pytest.raises(shapesmith.native.module().CancelledError):
        shapesmith.blender.packing.pack_object(template, progress=lambda fraction: fraction < 0.5)
    assert shapesmith.blender.packing.stored_report(template) == first


def test_conflicts_are_reused_until_the_rig_or_their_settings_change(sample, shapesmith):
    """The collision and occlusion results are stored on the object and reused by the next
    packing of the same rig with the same mu, tolerance and keep share: the same conflicts
    and expressions with no pair tested again; other options reuse them too; a changed shape
    key or tolerance tests again."""
    packing = shapesmith.blender.packing
    template = make_active(bpy.data.objects["Template"])
    assert packing.CONFLICTS_PROPERTY not in template
    cold = pack(template)
    cold_report = packing.stored_report(template)
    assert packing.CONFLICTS_PROPERTY in template
    options = packing.packing_options(template)
    warm = packing.pack_object(template, **options)
    assert warm["poseability"]["collision_pairs_tested"] == 0
    assert warm["poseability"]["occlusion_directions_tested"] == 0 and warm["poseability"]["pairs_reused"] > 500
    fresh = packing.pack_object(template, reuse_conflicts=False, **options)
    assert fresh["poseability"]["collision_pairs_tested"] > 500 and fresh["poseability"]["pairs_reused"] == 0
    for key in ("collisions", "occlusions", "conflicts"):
        assert warm[key] == fresh[key], key
    assert [e["shapes"] for e in warm["expressions"]] == [e["shapes"] for e in cold_report["expressions"]] == members(cold)

    # Options the tests do not depend on: the stored results still serve, and the answer is
    # the one a cold packing gives.
    excluded = dict(options, exclude=["mouthClose"], settings=replace(options["settings"], antagonist_cosine=-0.9))
    warm = packing.pack_object(template, **excluded)
    fresh = packing.pack_object(template, reuse_conflicts=False, **excluded)
    assert warm["poseability"]["pairs_reused"] > 0
    assert warm["collisions"] == fresh["collisions"] and warm["occlusions"] == fresh["occlusions"]
    assert [e["shapes"] for e in warm["expressions"]] == [e["shapes"] for e in fresh["expressions"]]

    # A new tolerance, or an edited shape key, tests every pair again.
    changed = packing.pack_object(template, **dict(options, settings=replace(options["settings"], collision_tolerance=0.2)))
    assert changed["poseability"]["pairs_reused"] == 0 and changed["poseability"]["collision_pairs_tested"] > 500
    key = template.data.shape_keys.key_blocks["jawOpen"]
    key.data[0].co.z += 0.01
    edited = packing.pack_object(template, **options)
    assert edited["poseability"]["pairs_reused"] == 0
