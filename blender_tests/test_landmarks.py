"""Place Landmarks on the sample rig: every shape covered by a candidate vertex, the layout
proven optimal, empties that follow the face, symmetric layouts that are mirror images, the
score of a tracked group, exports, the picture, batch, and bad input leaving files unchanged."""

import csv
import json
import os

import bpy
import numpy as np
import pytest

from conftest import file_digest, make_active, run_batch


def rig_arrays(obj):
    """Neutral (N, 3) and deltas {name: (N, 3)} read straight from the shape keys."""
    blocks = obj.data.shape_keys.key_blocks
    basis = np.array([v.co[:] for v in blocks[0].data])
    return basis, {kb.name: np.array([v.co[:] for v in kb.data]) - basis for kb in blocks[1:]}


def place(**settings):
    scene_settings = bpy.context.scene.shapesmith.landmarks
    for name, value in settings.items():
        setattr(scene_settings, name, value)
    assert bpy.ops.shapesmith.place_landmarks() == {"FINISHED"}
    return json.loads(bpy.context.active_object.shapesmith.landmarks.document)


def layout_empties(obj):
    return list(obj.shapesmith.landmarks.collection.objects)


def test_every_shape_gets_a_strongly_moving_landmark_and_the_layout_is_optimal(sample):
    template = make_active(bpy.data.objects["Template"])
    document = place(epsilon=0.5)
    assert document["optimal"] and document["uncovered"] == [] and document["inert"] == []
    _, deltas = rig_arrays(template)
    vertices = np.array([lm["vertex"] for lm in document["landmarks"]])
    for name, delta in deltas.items():
        moves = np.linalg.norm(delta, axis=1)
        # An independent check of coverage: some landmark moves at least eps of the shape's maximum.
        assert (moves[vertices] >= 0.5 * moves.max() - 1e-7).any(), f"{name} has no landmark"
        assert any(name in lm["shapes"] for lm in document["landmarks"])
    assert len(vertices) == len(set(vertices.tolist())) < len(deltas)
    rec = document["reconstruction"]
    assert 0 < rec["mean"] <= rec["max"] < 0.1 and rec["poses"] >= len(deltas)


def test_the_layout_is_built_as_empties_on_vertices_and_a_vertex_group(sample):
    template = make_active(bpy.data.objects["Template"])
    document = place()
    empties = layout_empties(template)
    assert template.shapesmith.landmarks.collection.name == "Landmarks"
    assert len(empties) == len(document["landmarks"]) == template.shapesmith.landmarks.count
    by_vertex = {lm["vertex"]: lm for lm in document["landmarks"]}
    for empty in empties:
        landmark = by_vertex[empty["vertex"]]
        assert empty.type == "EMPTY" and empty.parent == template and empty.parent_type == "VERTEX"
        assert tuple(empty.parent_vertices) == (landmark["vertex"],) * 3
        assert empty.name == f"LM_{landmark['strongest']}_{landmark['vertex']}"
        assert list(empty["shapes"]) == landmark["shapes"] and landmark["strongest"] in landmark["shapes"]
    group = template.vertex_groups["Landmarks"]
    members = {v.index for v in template.data.vertices if any(g.group == group.index for g in v.groups)}
    assert members == set(by_vertex)
    diagonal = np.linalg.norm(np.ptp(np.array([c[:] for c in template.bound_box]), axis=0))
    assert empties[0].empty_display_size == pytest.approx(0.012 * diagonal, rel=1e-3)


def test_empties_sit_on_their_vertices_and_follow_a_shape_key(sample):
    template = make_active(bpy.data.objects["Template"])
    template.location = (0.3, -0.1, 0.2)
    template.rotation_euler = (0.2, 0.0, 0.5)
    template.scale = (1.5, 1.5, 1.5)
    place()

    def positions():
        depsgraph = bpy.context.evaluated_depsgraph_get()
        depsgraph.update()
        evaluated = template.evaluated_get(depsgraph)
        mesh = evaluated.to_mesh()
        world = {e["vertex"]: evaluated.matrix_world @ mesh.vertices[e["vertex"]].co for e in layout_empties(template)}
        empties = {e["vertex"]: e.evaluated_get(depsgraph).matrix_world.translation.copy() for e in layout_empties(template)}
        evaluated.to_mesh_clear()
        return world, empties

    rest_mesh, rest_empties = positions()
    for v in rest_mesh:
        assert (rest_empties[v] - rest_mesh[v]).length < 1e-5
    template.data.shape_keys.key_blocks["jawOpen"].value = 1.0
    posed_mesh, posed_empties = positions()
    moved = [v for v in posed_mesh if (posed_empties[v] - rest_empties[v]).length > 1e-3]
    assert moved, "no landmark moved with jawOpen"
    for v in posed_mesh:
        assert (posed_empties[v] - posed_mesh[v]).length < 1e-5


def test_a_symmetric_layout_is_its_own_mirror_image(sample):
    template = make_active(bpy.data.objects["Template"])
    document = place(symmetric=True)
    assert document["optimal"] and document["uncovered"] == [] and document["params"]["symmetric"]
    positions = np.array([lm["position"] for lm in document["landmarks"]])
    mirrored = positions * np.array([-1.0, 1.0, 1.0])
    diagonal = np.linalg.norm(np.ptp(rig_arrays(template)[0], axis=0))
    gaps = np.linalg.norm(mirrored[:, None, :] - positions[None, :, :], axis=2).min(axis=1)
    assert gaps.max() < 1e-3 * diagonal
    assert np.any(np.abs(positions[:, 0]) > 0.01 * diagonal), "a layout on the midline alone proves nothing"


def test_running_again_replaces_the_previous_layout(sample):
    template = make_active(bpy.data.objects["Template"])
    place(max_per_shape=2)
    objects_before = len(bpy.data.objects)
    first_count = template.shapesmith.landmarks.count
    document = place(max_per_shape=1)
    assert len(document["landmarks"]) <= first_count
    assert [c.name for c in bpy.data.collections if c.name.startswith("Landmarks")] == ["Landmarks"]
    assert len(bpy.data.objects) == objects_before - first_count + len(document["landmarks"])
    assert len([g for g in template.vertex_groups if g.name.startswith("Landmarks")]) == 1


def test_undo_restores_the_previous_layout(sample):
    make_active(bpy.data.objects["Template"])
    first = sorted(lm["vertex"] for lm in place(max_per_shape=2)["landmarks"])
    bpy.ops.ed.undo_push(message="first layout")
    second = sorted(lm["vertex"] for lm in place(max_per_shape=1)["landmarks"])
    bpy.ops.ed.undo_push(message="second layout")
    assert second != first
    bpy.ops.ed.undo()
    template = bpy.data.objects["Template"]
    assert sorted(lm["vertex"] for lm in json.loads(template.shapesmith.landmarks.document)["landmarks"]) == first
    assert sorted(e.parent_vertices[0] for e in layout_empties(template)) == first


def test_progress_reaches_the_caller_and_stopping_keeps_the_previous_layout(sample, shapesmith):
    import importlib

    landmarks = importlib.import_module(shapesmith.__name__ + ".blender.landmarks")
    template = make_active(bpy.data.objects["Template"])
    first = place(epsilon=0.5)
    seen = []
    settings = shapesmith.blender.settings.LandmarkSettings(epsilon=0.5)
    document = landmarks.place_landmarks(template, settings, progress=seen.append)
    assert len(seen) > 10 and seen == sorted(set(seen)) and 0.0 <= seen[0] and seen[-1] == 1.0
    without = landmarks.place_landmarks(template, settings)
    assert [lm["vertex"] for lm in document["landmarks"]] == [lm["vertex"] for lm in without["landmarks"]]
    with pytest.raises(shapesmith.native.module().CancelledError):
        landmarks.place_landmarks(template, settings, progress=lambda fraction: fraction < 0.3)
    assert json.loads(template.shapesmith.landmarks.document) == first
    assert len(layout_empties(template)) == len(first["landmarks"])


def test_the_layout_survives_save_and_reload(sample, tmp_path):
    template = make_active(bpy.data.objects["Template"])
    document = place()
    path = str(tmp_path / "saved.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    template = bpy.data.objects["Template"]
    assert json.loads(template.shapesmith.landmarks.document) == document
    assert len(layout_empties(template)) == len(document["landmarks"])


def test_score_layout_of_a_tracked_group_matches_the_layout_and_ranks_layouts(sample):
    template = make_active(bpy.data.objects["Template"])
    document = place()
    tracked = template.vertex_groups.new(name="Tracked")
    tracked.add([lm["vertex"] for lm in document["landmarks"]], 1.0, "REPLACE")
    assert bpy.ops.shapesmith.score_layout(group="Tracked") == {"FINISHED"}
    score = template.shapesmith.landmark_score
    assert score.landmarks == len(document["landmarks"])
    assert score.mean_error == pytest.approx(document["reconstruction"]["mean"], rel=1e-5)
    # A single nose-tip vertex cannot tell the shapes apart: it must score clearly worse.
    neutral, _ = rig_arrays(template)
    one = template.vertex_groups.new(name="NoseTip")
    one.add([int(np.argmin(neutral[:, 1]))], 1.0, "REPLACE")
    assert bpy.ops.shapesmith.score_layout(group="NoseTip") == {"FINISHED"}
    assert score.group == "NoseTip" and score.mean_error > 2 * document["reconstruction"]["mean"]


def test_packed_expressions_stored_on_the_rig_join_the_test_poses(sample):
    template = make_active(bpy.data.objects["Template"])
    without = place()["reconstruction"]
    assert without["packed_expressions"] == 0
    assert bpy.ops.shapesmith.pack_expressions() == {"FINISHED"}
    expressions = len(template.shapesmith.pack.result.expressions)
    with_packed = place()["reconstruction"]
    assert expressions > 0 and with_packed["packed_expressions"] == expressions
    assert with_packed["poses"] == without["poses"] + expressions


def test_export_writes_the_layout_as_json_and_csv(sample, tmp_path):
    make_active(bpy.data.objects["Template"])
    document = place()
    json_path, csv_path = str(tmp_path / "layout.json"), str(tmp_path / "layout.csv")
    assert bpy.ops.shapesmith.export_landmarks(filepath=json_path, file_format="JSON") == {"FINISHED"}
    assert bpy.ops.shapesmith.export_landmarks(filepath=csv_path, file_format="CSV") == {"FINISHED"}
    with open(json_path) as f:
        assert json.load(f) == document
    with open(csv_path) as f:
        rows = list(csv.DictReader(f))
    assert [int(r["vertex"]) for r in rows] == [lm["vertex"] for lm in document["landmarks"]]
    assert [r["shapes"].split() for r in rows] == [lm["shapes"] for lm in document["landmarks"]]


def test_known_cameras_are_taken_in_the_mesh_local_space(sample, shapesmith):
    template = make_active(bpy.data.objects["Template"])
    template.location = (1.0, 0.0, 0.0)
    template.scale = (2.0, 2.0, 2.0)
    camera = bpy.data.objects.new("Front", bpy.data.cameras.new("Front"))
    bpy.context.scene.collection.objects.link(camera)
    camera.location = (1.0, -1.0, 1.4)
    bpy.context.view_layer.update()
    local = shapesmith.blender.landmarks.camera_positions(template, "SCENE", bpy.context.scene)
    assert local.shape == (1, 3) and np.allclose(local[0], (0.0, -0.5, 0.7))
    document = place(camera_source="SCENE")
    assert document["params"]["cameras"] == 1 and document["optimal"] and document["uncovered"] == []
    # Seen from one camera in front, the back of the head is hidden: visibilities are 0 or 1.
    assert {lm["visibility"] for lm in document["landmarks"]} <= {0.0, 1.0}


def test_the_picture_is_rendered_without_changing_the_file(sample, tmp_path):
    make_active(bpy.data.objects["Template"])
    place()
    counts = (len(bpy.data.objects), len(bpy.data.scenes), len(bpy.data.meshes), len(bpy.data.cameras))
    path = str(tmp_path / "front.png")
    assert bpy.ops.shapesmith.render_landmarks(filepath=path, resolution=512) == {"FINISHED"}
    assert counts == (len(bpy.data.objects), len(bpy.data.scenes), len(bpy.data.meshes), len(bpy.data.cameras))
    image = bpy.data.images.load(path)
    pixels = np.array(image.pixels[:]).reshape(-1, 4)
    bpy.data.images.remove(image)
    red = (pixels[:, 0] > 0.6) & (pixels[:, 1] < 0.2) & (pixels[:, 2] < 0.2)
    skin = (np.abs(pixels[:, 0] - pixels[:, 1]) < 0.15) & (pixels[:, 0] > 0.3)
    assert red.sum() > 50 and skin.sum() > 0.1 * len(pixels)


def test_the_mesh_report_explains_loose_parts_and_holes(sample):
    template = make_active(bpy.data.objects["Template"])
    document = place()
    assert document["mesh"]["loose_parts"] == 10 and document["mesh"]["boundary_edges"] > 0
    assert "10 loose part(s)" in template.shapesmith.landmarks.mesh_note


# --- bad input --------------------------------------------------------------------------


def assert_no_layout(obj):
    assert not obj.shapesmith.landmarks.done and "Landmarks" not in bpy.data.collections
    assert "Landmarks" not in obj.vertex_groups
    assert not [o for o in bpy.data.objects if o.name.startswith("LM_")]


def test_a_mesh_without_shape_keys_is_refused_and_left_unchanged(sample):
    target = make_active(bpy.data.objects["Target_OldMan"])
    with pytest.raises(RuntimeError, match="no shape keys"):
        bpy.ops.shapesmith.place_landmarks()
    assert_no_layout(target)


def test_shape_keys_that_move_nothing_are_explained_and_nothing_is_built(sample):
    target = make_active(bpy.data.objects["Target_Boy"])
    target.shape_key_add(name="Basis", from_mix=False)
    target.shape_key_add(name="still", from_mix=False).value = 0.0
    with pytest.raises(RuntimeError, match="nothing to place landmarks for"):
        bpy.ops.shapesmith.place_landmarks()
    assert_no_layout(target)


def test_a_bad_epsilon_is_refused_with_the_previous_layout_kept(sample, shapesmith):
    template = make_active(bpy.data.objects["Template"])
    document = place()
    for bad in (0.0, 1.5):
        with pytest.raises(ValueError, match="epsilon must be in"):
            shapesmith.blender.landmarks.place_landmarks(template, shapesmith.blender.settings.LandmarkSettings(epsilon=bad))
    with pytest.raises(ValueError, match="rays must be at least 1"):
        shapesmith.blender.landmarks.place_landmarks(template, shapesmith.blender.settings.LandmarkSettings(rays=0))
    assert json.loads(template.shapesmith.landmarks.document) == document
    assert len(layout_empties(template)) == len(document["landmarks"])


def test_an_open_sheet_with_one_moving_shape_gets_an_explained_layout(sample):
    bpy.ops.mesh.primitive_grid_add(x_subdivisions=6, y_subdivisions=6, size=1.0)
    sheet = make_active(bpy.context.active_object)
    sheet.shape_key_add(name="Basis", from_mix=False)
    bump = sheet.shape_key_add(name="bump", from_mix=False)
    bump.value = 0.0
    bump.data[17].co.z += 0.1
    document = place()
    assert [lm["vertex"] for lm in document["landmarks"]] == [17]
    assert document["mesh"]["loose_parts"] == 1 and document["mesh"]["boundary_edges"] > 0
    assert "open boundary" in document["mesh"]["note"]


def test_scoring_a_missing_or_empty_group_is_refused(sample):
    template = make_active(bpy.data.objects["Template"])
    template.vertex_groups.new(name="Empty")
    with pytest.raises(RuntimeError, match="no vertex group 'Nope'"):
        bpy.ops.shapesmith.score_layout(group="Nope")
    with pytest.raises(RuntimeError, match="'Empty' is empty"):
        bpy.ops.shapesmith.score_layout(group="Empty")
    assert not template.shapesmith.landmark_score.done


def test_a_conditioned_layout_keeps_the_cover_and_adds_up_to_the_count(sample):
    template = make_active(bpy.data.objects["Template"])
    cover = place(design="NONE", max_per_shape=1)
    assert cover["design_stop"] is None and cover["curve"] == [] and cover["predicted_error"] > 0
    m = len(cover["landmarks"]) + 10
    document = place(design="COUNT", landmarks=m, max_per_shape=1)
    assert document["design_stop"] == "count" and m - 1 <= len(document["landmarks"]) <= m
    by_vertex = {lm["vertex"]: lm for lm in document["landmarks"]}
    for landmark in cover["landmarks"]:
        # Every covered shape keeps its landmark.
        assert by_vertex[landmark["vertex"]] == dict(landmark, added=None)
    added = [lm for lm in document["landmarks"] if lm["added"] is not None]
    assert len(added) == len(document["landmarks"]) - len(cover["landmarks"]) == template.shapesmith.landmarks.added
    # Measured and predicted error both fall with the added landmarks.
    assert document["predicted_error"] < cover["predicted_error"]
    assert document["reconstruction"]["mean"] < cover["reconstruction"]["mean"]
    curve = document["curve"]
    assert curve[0]["landmarks"] == len(cover["landmarks"]) and curve[0]["predicted_error"] == pytest.approx(cover["predicted_error"])
    assert all(b["predicted_error"] <= a["predicted_error"] for a, b in zip(curve, curve[1:]))
    assert curve[-1]["landmarks"] >= 68
    assert template.shapesmith.landmarks.predicted_error == pytest.approx(document["predicted_error"], rel=1e-5)
    assert len(layout_empties(template)) == len(document["landmarks"])


def test_a_symmetric_conditioned_layout_is_its_own_mirror_image(sample):
    template = make_active(bpy.data.objects["Template"])
    document = place(design="COUNT", landmarks=30, max_per_shape=1, symmetric=True)
    neutral, _ = rig_arrays(template)
    chosen = neutral[[lm["vertex"] for lm in document["landmarks"]]]
    mirrored = chosen * np.array([-1.0, 1.0, 1.0])
    gaps = np.linalg.norm(mirrored[:, None, :] - chosen[None, :, :], axis=2).min(axis=1)
    assert gaps.max() < 1e-4, gaps.max()
    assert any(lm["added"] for lm in document["landmarks"])


def test_a_target_error_stops_where_the_curve_reaches_it(sample):
    make_active(bpy.data.objects["Template"])
    probe = place(design="COUNT", landmarks=40, max_per_shape=1)
    # Between the sixth and seventh points (the setting is a 32-bit float).
    target = 0.5 * (probe["curve"][5]["predicted_error"] + probe["curve"][6]["predicted_error"])
    document = place(design="TARGET", target_error=target, max_per_shape=1)
    assert document["design_stop"] == "target" and document["predicted_error"] <= target
    assert len(document["landmarks"]) == probe["curve"][6]["landmarks"]


def test_the_score_compares_with_a_tracked_group_and_the_panel_draws(sample):
    template = make_active(bpy.data.objects["Template"])
    tracked = template.vertex_groups.new(name="Tracked")
    tracked.add(list(range(0, len(template.data.vertices), 70)), 1.0, "REPLACE")
    settings = bpy.context.scene.shapesmith.landmarks
    settings.score_group = "Tracked"
    assert bpy.ops.shapesmith.score_layout() == {"FINISHED"}
    score = template.shapesmith.landmark_score
    document = place(design="COUNT", landmarks=30, max_per_shape=1)
    comparison = document["comparison"]
    assert comparison["group"] == "Tracked" and comparison["mean"] == pytest.approx(score.mean_error, rel=1e-5)
    assert comparison["predicted"] == pytest.approx(score.predicted_error, rel=1e-5)
    # The panel's draw reads the stored result (no error on a headless UI layout stand-in).
    lines = []

    class Recorder:
        def __getattr__(self, name):
            return lambda *args, **kwargs: (lines.append(kwargs.get("text", "")), self)[1]

    panel = bpy.types.SHAPESMITH_PT_landmarks
    panel.draw(type("P", (), {"layout": Recorder()})(), bpy.context)
    assert any("vs 'Tracked'" in line for line in lines), lines
    assert any("chosen" in line for line in lines), lines


def test_the_curve_picture_is_saved_without_changing_the_file(sample, tmp_path):
    make_active(bpy.data.objects["Template"])
    place(design="NONE")
    path = str(tmp_path / "curve.png")
    with pytest.raises(RuntimeError, match="no predicted-error curve"):
        bpy.ops.shapesmith.render_landmark_curve(filepath=path)
    place(design="COUNT", landmarks=30, max_per_shape=1)
    images = len(bpy.data.images)
    assert bpy.ops.shapesmith.render_landmark_curve(filepath=path) == {"FINISHED"}
    assert len(bpy.data.images) == images
    picture = bpy.data.images.load(path)
    try:
        assert tuple(picture.size) == (720, 420)
        pixels = np.array(picture.pixels[:]).reshape(420, 720, 4)
        # The orange curve and the blue chosen marker are drawn.
        assert ((pixels[:, :, 0] > 0.8) & (pixels[:, :, 2] < 0.1)).sum() > 100
        assert ((pixels[:, :, 2] > 0.8) & (pixels[:, :, 0] < 0.1)).sum() > 50
    finally:
        bpy.data.images.remove(picture)


@pytest.mark.parametrize(
    "design, value, message",
    [
        ("COUNT", 0, "at least 1"),
        ("COUNT", -5, "at least 1"),
        ("COUNT", 3, "the cover alone needs"),
        ("COUNT", 10**7, "more than the mesh's"),
        ("TARGET", -0.001, "positive fraction"),
        ("TARGET", 0.0, "positive fraction"),
    ],
)
def test_a_bad_count_or_target_is_refused_with_the_previous_layout_kept(sample, design, value, message):
    template = make_active(bpy.data.objects["Template"])
    document = place()
    settings = bpy.context.scene.shapesmith.landmarks
    settings.design = design
    setattr(settings, "landmarks" if design == "COUNT" else "target_error", value)
    with pytest.raises(RuntimeError, match=message):
        bpy.ops.shapesmith.place_landmarks()
    assert json.loads(template.shapesmith.landmarks.document) == document
    assert len(layout_empties(template)) == len(document["landmarks"])


# --- batch --------------------------------------------------------------------------------


def test_batch_places_scores_exports_renders_and_saves_a_copy(sample, tmp_path):
    template = bpy.data.objects["Template"]
    tracked_vertices = list(range(0, len(template.data.vertices), 50))
    template.vertex_groups.new(name="Tracked").add(tracked_vertices, 1.0, "REPLACE")
    source = str(tmp_path / "in.blend")
    bpy.ops.wm.save_as_mainfile(filepath=source, copy=True)
    digest = file_digest(source)
    out = {name: str(tmp_path / name) for name in ("out.json", "out.csv", "out.png", "out.blend")}
    proc = run_batch("landmarks", "--input", source, "--object", "Template", "--symmetric", "--score-group", "Tracked",
                     "--json", out["out.json"], "--csv", out["out.csv"], "--picture", out["out.png"],
                     "--output", out["out.blend"], check=True)
    assert "landmarks in" in proc.stdout
    assert file_digest(source) == digest
    with open(out["out.json"]) as f:
        report = json.load(f)
    for key in ("landmarks", "optimal", "uncovered", "reconstruction", "params", "seconds", "score", "mesh"):
        assert key in report
    assert set(report["seconds"]) >= {"io", "visibility", "solve"}
    assert set(report["landmarks"][0]) >= {"vertex", "position", "shapes", "visibility"}
    assert report["optimal"] and report["params"]["symmetric"] and report["score"]["group"] == "Tracked"
    assert report["score"]["landmarks"] == len(tracked_vertices)
    assert os.path.getsize(out["out.png"]) > 1000
    with open(out["out.csv"]) as f:
        assert len(list(csv.DictReader(f))) == len(report["landmarks"])
    bpy.ops.wm.open_mainfile(filepath=out["out.blend"])
    saved = bpy.data.objects["Template"]
    assert len(saved.shapesmith.landmarks.collection.objects) == len(report["landmarks"])


def test_batch_adds_landmarks_compares_and_plots_the_curve(sample, tmp_path):
    template = bpy.data.objects["Template"]
    template.vertex_groups.new(name="Tracked").add(list(range(0, len(template.data.vertices), 70)), 1.0, "REPLACE")
    source = str(tmp_path / "in.blend")
    bpy.ops.wm.save_as_mainfile(filepath=source, copy=True)
    digest = file_digest(source)
    report_path, curve_path = str(tmp_path / "out.json"), str(tmp_path / "curve.png")
    proc = run_batch("landmarks", "--input", source, "--object", "Template", "--max-per-shape", "1",
                     "--landmarks", "28", "--score-group", "Tracked", "--json", report_path, "--curve", curve_path,
                     check=True)
    assert "added" in proc.stdout and "<- chosen" in proc.stdout and "against 'Tracked'" in proc.stdout
    assert file_digest(source) == digest
    with open(report_path) as f:
        report = json.load(f)
    assert report["design_stop"] == "count" and len(report["landmarks"]) in (27, 28)
    assert report["params"]["landmarks"] == 28 and report["params"]["criterion"] == "a"
    assert [p["landmarks"] for p in report["curve"]] == sorted({p["landmarks"] for p in report["curve"]})
    assert report["comparison"]["group"] == "Tracked" and report["comparison"]["predicted"] > 0
    assert os.path.getsize(curve_path) > 1000


@pytest.mark.parametrize(
    "flags, message",
    [
        (["--landmarks", "0"], "--landmarks must be at least 1"),
        (["--landmarks", "2"], "the cover alone needs"),
        (["--target-error", "-0.01"], "--target-error must be a positive"),
        (["--target-error", "nan"], "--target-error must be a positive"),
        (["--curve", "x.png"], "--curve plots the landmarks added"),
        (["--epsilon", "0"], "epsilon must be in"),
        (["--epsilon", "1.5"], "epsilon must be in"),
        (["--rays", "0"], "rays must be at least 1"),
        (["--score-group", "Nope"], "no vertex group 'Nope'"),
        (["--camera-collection", "Nope"], "no collection named 'Nope'"),
        (["--scene-cameras"], "no camera objects"),
    ],
)
def test_batch_bad_input_exits_2_with_one_line_and_writes_nothing(sample_path, shapesmith, tmp_path, flags, message):
    digest = file_digest(sample_path)
    out = tmp_path / "out.json"
    proc = run_batch("landmarks", "--input", sample_path, "--object", "Template", "--json", str(out),
                     "--output", str(tmp_path / "out.blend"), *flags)
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len([line for line in lines if line.startswith("shapesmith: error:")]) == 1 and message in lines[-1]
    assert file_digest(sample_path) == digest and not out.exists() and not (tmp_path / "out.blend").exists()


def test_batch_refuses_a_mesh_without_shape_keys(sample_path, shapesmith):
    proc = run_batch("landmarks", "--input", sample_path, "--object", "Target_OldMan")
    assert proc.returncode == 2 and "no shape keys" in proc.stderr.strip().splitlines()[-1]
