"""Transfer Shape Keys: the template's 52 keys land on each Target_* with the template's key
settings; the template onto a copy of itself reproduces its keys; personalisation moves the
shapes towards training expressions; every bad input is refused with the target unchanged."""

import json

import bmesh
import bpy
import numpy as np
import pytest

from conftest import file_digest, make_active, run_batch

TARGETS = ("Target_OldMan", "Target_YoungWoman", "Target_Boy")


def settings():
    return bpy.context.scene.shapesmith.transfer


def key_positions(obj, name):
    block = obj.data.shape_keys.key_blocks[name]
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    block.data.foreach_get("co", co)
    return co.reshape(-1, 3)


def rest(obj):
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def diagonal(obj):
    points = rest(obj)
    return float(np.linalg.norm(points.max(0) - points.min(0)))


def template_names():
    return [kb.name for kb in bpy.data.objects["Template"].data.shape_keys.key_blocks[1:]]


def copy_of(obj, name, keep_keys=False):
    copy = obj.copy()
    copy.data = obj.data.copy()
    copy.name = copy.data.name = name
    if not keep_keys:
        copy.shape_key_clear()
    bpy.context.scene.collection.objects.link(copy)
    return copy


def transfer_onto(target, source="Template", operator="transfer_shape_keys", **options):
    s = settings()
    s.source = bpy.data.objects[source]
    for key, value in options.items():
        setattr(s, key, value)
    make_active(target)
    return getattr(bpy.ops.shapesmith, operator)()


def snapshot(obj):
    """Everything a failed transfer must leave alone."""
    keys = obj.data.shape_keys
    blocks = [(kb.name, key_positions(obj, kb.name).tobytes()) for kb in keys.key_blocks] if keys else None
    return rest(obj).tobytes(), blocks, obj.shapesmith.transfer.done, len(bpy.data.objects)


# --- what a rigger gets ------------------------------------------------------------------


def test_undo_removes_the_transferred_keys(sample):
    target = bpy.data.objects["Target_Boy"]
    bpy.ops.ed.undo_push(message="before transfer")
    assert transfer_onto(target) == {"FINISHED"}
    bpy.ops.ed.undo_push(message="after transfer")
    assert len(bpy.data.objects["Target_Boy"].data.shape_keys.key_blocks) == 53
    bpy.ops.ed.undo()
    assert bpy.data.objects["Target_Boy"].data.shape_keys is None


@pytest.mark.parametrize("target_name", TARGETS)
def test_transfer_writes_the_templates_52_keys_with_their_settings(sample, target_name):
    template = bpy.data.objects["Template"]
    blocks = template.data.shape_keys.key_blocks
    template.vertex_groups.new(name="mouth")
    bpy.data.objects[target_name].vertex_groups.new(name="mouth")
    blocks["jawOpen"].slider_min, blocks["jawOpen"].slider_max = -0.5, 1.5
    blocks["eyeBlinkLeft"].mute = True
    blocks["mouthClose"].relative_key = blocks["jawOpen"]
    blocks["mouthFunnel"].vertex_group = "mouth"
    target = bpy.data.objects[target_name]
    assert transfer_onto(target) == {"FINISHED"}

    keys = target.data.shape_keys.key_blocks
    assert keys[0].name == "Basis" and [kb.name for kb in keys[1:]] == template_names()
    assert len(keys) == 53
    assert (keys["jawOpen"].slider_min, keys["jawOpen"].slider_max) == (-0.5, 1.5)
    assert keys["eyeBlinkLeft"].mute and not keys["eyeBlinkRight"].mute
    assert keys["mouthClose"].relative_key == keys["jawOpen"]
    assert keys["jawLeft"].relative_key == keys["Basis"]
    assert keys["mouthFunnel"].vertex_group == "mouth"
    assert all(kb.value == 0.0 for kb in keys)
    np.testing.assert_array_equal(key_positions(target, "Basis"), rest(target))
    # every shape moves the target where the template moves, and nowhere it does not
    for name in ("jawOpen", "eyeBlinkLeft", "mouthSmileRight"):
        source_moved = np.linalg.norm(key_positions(template, name) - rest(template), axis=1) > 0
        target_moved = np.linalg.norm(key_positions(target, name) - rest(target), axis=1) > 0
        assert target_moved.any() and not (target_moved & ~source_moved).any(), name
    result = target.shapesmith.transfer
    assert result.done and result.written == 52 and result.source == "Template" and len(result.shapes) == 52
    assert result.virtual_edges > 0


@pytest.mark.parametrize("virtual_edges", (False, True))
def test_the_template_onto_a_copy_of_itself_reproduces_its_keys(sample, virtual_edges):
    template = bpy.data.objects["Template"]
    twin = copy_of(template, "Twin")
    # Keeping surfaces apart too: the template onto itself comes back as it is.
    assert transfer_onto(twin, virtual_edges=virtual_edges, contact=True) == {"FINISHED"}
    assert twin.shapesmith.transfer.contact and twin.shapesmith.transfer.contact_resolved == 0
    tolerance = 1e-5 * diagonal(template)
    for name in template_names():
        error = np.abs(key_positions(twin, name) - key_positions(template, name)).max()
        assert error < tolerance, f"{name}: {error} >= {tolerance}"


# --- keeping surfaces apart (the contact solve) --------------------------------------------


def transfer_module(shapesmith):
    import importlib

    return importlib.import_module(shapesmith.__name__ + ".blender.transfer")


CONTACT_KEYS = ["mouthClose", "mouthPucker", "mouthRollUpper", "mouthSmileLeft", "cheekPuff"]


def test_keeping_surfaces_apart_is_off_by_default_and_when_ticked_leaves_no_added_crossing(sample, shapesmith):
    s = settings()
    assert not s.contact and s.contact_distance == pytest.approx(0.25)
    transfer = transfer_module(shapesmith)
    template, target = bpy.data.objects["Template"], bpy.data.objects["Target_OldMan"]
    tool = shapesmith.blender.settings
    off = transfer.transfer_object(template, target, tool.TransferSettings(), keys=CONTACT_KEYS)
    chosen = tool.TransferSettings(transfer=tool.DeformationSettings(contact=tool.ContactSettings()))
    on = transfer.transfer_object(template, target, chosen, keys=CONTACT_KEYS)
    assert "before_contact_length" not in off.report["penetration"][0]
    applied = [row["contact"]["applied"] for row in on.report["penetration"]]
    touched = [k for k, a in enumerate(applied) if a]
    assert touched, "some of these shapes add crossings on a MakeHuman identity"
    for k, row in enumerate(on.report["penetration"]):
        if not applied[k]:
            # a shape adding no crossing is written bit for bit as without contact
            np.testing.assert_array_equal(on.deltas[k], off.deltas[k])
            continue
        assert np.abs(on.deltas[k] - off.deltas[k]).max() > 0
        # the numbers before the solve are those of the transfer without it, and no crossing
        # it added is left
        assert row["before_contact_length"] == pytest.approx(off.report["penetration"][k]["length"], abs=1e-9)
        assert row["contact"]["added_pairs"] > 0 and row["contact"]["remaining_pairs"] == 0


def test_a_bad_contact_distance_is_refused_and_the_target_left_alone(sample, shapesmith):
    transfer = transfer_module(shapesmith)
    target = bpy.data.objects["Target_Boy"]
    before = snapshot(target)
    tool = shapesmith.blender.settings
    for distance in (-0.5, float("nan"), 10.0):
        chosen = tool.TransferSettings(transfer=tool.DeformationSettings(contact=tool.ContactSettings(distance=distance)))
        with pytest.raises(ValueError, match="contact.distance"):
            transfer.transfer_object(bpy.data.objects["Template"], target, chosen)
    assert snapshot(target) == before
    settings().contact_distance = 10.0  # the panel's field clamps to what the core accepts
    assert settings().contact_distance == pytest.approx(2.0)


def test_existing_keys_are_skipped_unless_overwrite(sample):
    target = bpy.data.objects["Target_Boy"]
    target.shape_key_add(name="Basis", from_mix=False)
    mine = target.shape_key_add(name="jawOpen", from_mix=False)
    mine.value = 0.5
    extra = target.shape_key_add(name="myCustomShape", from_mix=False)
    extra.data[0].co.z += 1.0
    kept = key_positions(target, "jawOpen").copy()

    assert transfer_onto(target, overwrite=False) == {"FINISHED"}
    keys = target.data.shape_keys.key_blocks
    assert len(keys) == 54  # Basis, jawOpen, myCustomShape + 51 new
    np.testing.assert_array_equal(key_positions(target, "jawOpen"), kept)
    assert target.shapesmith.transfer.written == 51 and target.shapesmith.transfer.skipped == "jawOpen"
    assert keys["myCustomShape"].data[0].co.z == pytest.approx(rest(target)[0, 2] + 1.0)

    assert transfer_onto(target, overwrite=True) == {"FINISHED"}
    assert len(target.data.shape_keys.key_blocks) == 54
    assert np.abs(key_positions(target, "jawOpen") - kept).max() > 1e-3
    assert keys["jawOpen"].value == 0.5  # an overwritten key keeps the user's slider value
    assert target.shapesmith.transfer.written == 52 and target.shapesmith.transfer.skipped == ""


def test_drivers_are_recreated_and_retargeted_when_asked(sample):
    template = bpy.data.objects["Template"]
    keys = template.data.shape_keys
    fcurve = keys.key_blocks["eyeBlinkRight"].driver_add("value")
    fcurve.driver.type = "SCRIPTED"
    fcurve.driver.expression = "blink * 0.5"
    variable = fcurve.driver.variables.new()
    variable.name = "blink"
    variable.targets[0].id_type = "KEY"
    variable.targets[0].id = keys
    variable.targets[0].data_path = 'key_blocks["eyeBlinkLeft"].value'
    location = fcurve.driver.variables.new()
    location.name = "lx"
    location.type = "TRANSFORMS"
    location.targets[0].id = template
    target = bpy.data.objects["Target_OldMan"]

    assert transfer_onto(target, copy_drivers=False) == {"FINISHED"}
    assert target.data.shape_keys.animation_data is None or not target.data.shape_keys.animation_data.drivers

    assert transfer_onto(target, copy_drivers=True, overwrite=True) == {"FINISHED"}
    drivers = target.data.shape_keys.animation_data.drivers
    assert [d.data_path for d in drivers] == ['key_blocks["eyeBlinkRight"].value']
    copied = drivers[0].driver
    assert copied.expression == "blink * 0.5"
    assert copied.variables["blink"].targets[0].id == target.data.shape_keys
    assert copied.variables["blink"].targets[0].data_path == 'key_blocks["eyeBlinkLeft"].value'
    assert copied.variables["lx"].targets[0].id == target
    target.data.shape_keys.key_blocks["eyeBlinkLeft"].value = 0.8
    bpy.context.view_layer.update()
    bpy.context.evaluated_depsgraph_get().update()
    assert target.data.shape_keys.key_blocks["eyeBlinkRight"].value == pytest.approx(0.4)


def test_preview_virtual_edges_draws_a_parented_edge_mesh_and_replaces_it(sample):
    target = make_active(bpy.data.objects["Target_YoungWoman"])
    assert bpy.ops.shapesmith.preview_virtual_edges() == {"FINISHED"}
    preview = bpy.data.objects["Target_YoungWoman_VirtualEdges"]
    assert preview.parent == target and len(preview.data.polygons) == 0
    edges = len(preview.data.edges)
    assert edges > 0 and len(preview.data.vertices) == len(target.data.vertices)
    # each virtual edge is short in space (< tau_d of the diagonal) but joins no mesh edge
    points = rest(target)
    pairs = np.array([e.vertices[:] for e in preview.data.edges])
    lengths = np.linalg.norm(points[pairs[:, 0]] - points[pairs[:, 1]], axis=1)
    assert lengths.max() < settings().tau_d * diagonal(target)
    mesh_edges = {frozenset(e.vertices) for e in target.data.edges}
    assert not any(frozenset(p) in mesh_edges for p in pairs.tolist())
    # the edges sit on the face's openings: both lips and eyelids (vertices on both sides of x = 0)
    assert (points[pairs[:, 0], 0] < 0).any() and (points[pairs[:, 0], 0] > 0).any()

    count = len(bpy.data.objects)
    settings().tau_d = 0.005
    make_active(target)
    assert bpy.ops.shapesmith.preview_virtual_edges() == {"FINISHED"}
    assert len(bpy.data.objects) == count and len(preview.data.edges) < edges
    assert preview.matrix_world == target.matrix_world


def test_results_survive_save_and_reload(sample, tmp_path):
    assert transfer_onto(bpy.data.objects["Target_Boy"]) == {"FINISHED"}
    path = str(tmp_path / "saved.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    bpy.ops.wm.open_mainfile(filepath=path)
    target = bpy.data.objects["Target_Boy"]
    assert len(target.data.shape_keys.key_blocks) == 53 and target.shapesmith.transfer.written == 52
    assert bpy.context.scene.shapesmith.transfer.source == bpy.data.objects["Template"]


# --- personalisation ---------------------------------------------------------------------


def training_collection(objects):
    collection = bpy.data.collections.new("Training")
    bpy.context.scene.collection.children.link(collection)
    for obj in objects:
        for user in obj.users_collection:
            user.objects.unlink(obj)
        collection.objects.link(obj)
    settings().training = collection
    return collection


def posed_copy(obj, name, positions):
    copy = copy_of(obj, name)
    copy.data.vertices.foreach_set("co", positions.astype(np.float32).ravel())
    copy.data.update()
    return copy


def test_personalise_moves_the_shapes_towards_the_training_expressions(sample):
    target = bpy.data.objects["Target_OldMan"]
    assert transfer_onto(target) == {"FINISHED"}
    plain = {name: key_positions(target, name) - rest(target) for name in ("jawOpen", "mouthSmileLeft")}
    # the scans show a wider jaw opening and a stronger smile
    wanted = {"jawOpen": 1.3 * plain["jawOpen"], "mouthSmileLeft": 1.3 * plain["mouthSmileLeft"]}
    training_collection([posed_copy(target, f"OldMan_{name}", rest(target) + delta) for name, delta in wanted.items()])
    settings().overwrite = True
    make_active(target)
    assert bpy.ops.shapesmith.personalise_shape_keys() == {"FINISHED"}
    assert target.shapesmith.transfer.examples == 2
    for name, delta in wanted.items():
        personalised = key_positions(target, name) - rest(target)
        before = np.linalg.norm(plain[name] - delta)
        after = np.linalg.norm(personalised - delta)
        assert after < 0.8 * before, f"{name}: {after} vs plain {before}"


def test_training_expressions_named_ref_need_a_packed_template(sample):
    target = bpy.data.objects["Target_OldMan"]
    training_collection([posed_copy(target, "REF_01", rest(target))])
    refused(target, "REF_01.*Pack Expressions", operator="personalise_shape_keys")


def test_training_expressions_of_another_topology_are_refused(sample):
    target = bpy.data.objects["Target_OldMan"]
    scan = posed_copy(target, "OldMan_jawOpen", rest(target))
    drop_a_vertex(scan)
    training_collection([scan])
    n = len(target.data.vertices)
    refused(target, f"training expression 'OldMan_jawOpen' has {n - 1} vertices.* {n}", operator="personalise_shape_keys")


def test_unnamed_training_expressions_are_refused(sample):
    target = bpy.data.objects["Target_OldMan"]
    training_collection([posed_copy(target, "Scan42", rest(target))])
    refused(target, "'Scan42' matches no packed expression", operator="personalise_shape_keys")


# --- bad input: a clear error and the target unchanged ------------------------------------


def drop_a_vertex(obj):
    mesh = bmesh.new()
    mesh.from_mesh(obj.data)
    mesh.verts.ensure_lookup_table()
    bmesh.ops.delete(mesh, geom=[mesh.verts[0]], context="VERTS")
    mesh.to_mesh(obj.data)
    mesh.free()


def refused(target, pattern, source="Template", operator="transfer_shape_keys"):
    before = snapshot(target)
    with pytest.raises(RuntimeError, match=pattern):
        transfer_onto(target, source=source, operator=operator)
    assert snapshot(target) == before


def test_a_target_with_another_vertex_count_is_refused(sample):
    target = bpy.data.objects["Target_Boy"]
    drop_a_vertex(target)
    n = len(bpy.data.objects["Template"].data.vertices)
    refused(target, f"'Target_Boy' has {n - 1} vertices but template 'Template' has {n}")


def test_a_target_with_other_faces_is_refused(sample):
    target = bpy.data.objects["Target_Boy"]
    mesh = bmesh.new()
    mesh.from_mesh(target.data)
    mesh.faces.ensure_lookup_table()
    bmesh.ops.reverse_faces(mesh, faces=[mesh.faces[10]])
    mesh.to_mesh(target.data)
    mesh.free()
    refused(target, "other faces .*face 10")


def test_the_template_as_its_own_target_is_refused(sample):
    refused(bpy.data.objects["Template"], "is the template itself")


def test_a_source_without_shape_keys_is_refused(sample):
    # the Template picker only lists meshes with keys; a script can still set one without
    settings().source = bpy.data.objects["Target_YoungWoman"]
    target = make_active(bpy.data.objects["Target_Boy"])
    before = snapshot(target)
    with pytest.raises(RuntimeError, match="'Target_YoungWoman' has no shape keys"):
        bpy.ops.shapesmith.transfer_shape_keys()
    assert snapshot(target) == before


def test_nan_on_the_target_is_refused(sample):
    target = bpy.data.objects["Target_Boy"]
    target.data.vertices[12].co.y = float("nan")
    refused(target, "vertex 12")


def test_nan_in_a_template_key_is_refused(sample):
    bpy.data.objects["Template"].data.shape_keys.key_blocks["jawOpen"].data[7].co.x = float("nan")
    refused(bpy.data.objects["Target_Boy"], "jawOpen.*vertex 7")


def test_a_face_flattened_on_the_target_is_left_out_and_named(sample, shapesmith):
    """The target's shape flattens a face the template has: that face is left out of both (one
    topology, one surface), the keys are written, and the target's report line names it."""
    target = bpy.data.objects["Target_Boy"]
    first = target.data.polygons[0].vertices
    for v in first[1:]:
        target.data.vertices[v].co = target.data.vertices[first[0]].co
    # The quad and, of each of its four neighbours, the triangle on the edge it collapsed.
    assert shapesmith.blender.mesh_arrays.fault_note(target) == "left out: 5 zero-area faces"
    assert transfer_onto(target) == {"FINISHED"}
    written = [kb.name for kb in target.data.shape_keys.key_blocks[1:]]
    assert len(written) == len(bpy.data.objects["Template"].data.shape_keys.key_blocks) - 1
    assert all(np.isfinite(key_positions(target, name)).all() for name in written)


# --- progress ----------------------------------------------------------------------------


def test_progress_reaches_the_caller_on_its_thread_and_can_stop_the_work(sample, shapesmith):
    """The operators drive Blender's progress cursor through this callback; it must run on the
    calling (main) thread, only advance, reach 1, and stop the work when it answers False."""
    import importlib
    import threading

    transfer = importlib.import_module(shapesmith.__name__ + ".blender.transfer")
    template, target = bpy.data.objects["Template"], bpy.data.objects["Target_Boy"]
    seen, threads = [], set()

    def record(fraction):
        seen.append(fraction)
        threads.add(threading.get_ident())

    result = transfer.transfer_object(template, target, progress=record)
    assert len(seen) >= 20 and seen == sorted(set(seen)) and 0.0 <= seen[0] and seen[-1] == 1.0
    assert threads == {threading.get_ident()}
    assert result.deltas.shape == (52, len(target.data.vertices), 3)
    before = snapshot(target)
    with pytest.raises(shapesmith.native.module().CancelledError):
        transfer.transfer_object(template, target, progress=lambda fraction: fraction < 0.5)

    class Stop(Exception):
        pass

    def interrupt(fraction):
        raise Stop

    with pytest.raises(Stop):
        transfer.transfer_object(template, target, progress=interrupt)
    assert snapshot(target) == before
    # The progress cursor does not change what the operator writes.
    assert transfer_onto(target) == {"FINISHED"}
    written = np.stack([key_positions(target, name) - rest(target) for name in template_names()])
    assert np.abs(written - result.deltas).max() < 1e-6


# --- batch -------------------------------------------------------------------------------


def test_batch_transfers_onto_every_target_and_reports(sample_path, tmp_path):
    out_json, out_blend = tmp_path / "transfer.json", tmp_path / "out.blend"
    digest = file_digest(sample_path)
    run_batch(
        "transfer", "--input", sample_path, "--source", "Template", "--targets", "Target_*",
        "--json", str(out_json), "--output", str(out_blend), check=True,
    )
    assert file_digest(sample_path) == digest
    report = json.loads(out_json.read_text())
    assert [t["target"] for t in report["targets"]] == sorted(TARGETS)
    assert {"io", "factorisation", "virtual_edges", "solves", "contact", "template_penetration", "total"} <= set(
        report["seconds"]
    )
    assert report["params"]["transfer"]["contact"] is None  # keeping surfaces apart is opt-in
    template_lengths = None
    for target in report["targets"]:
        assert len(target["shapes"]) == 52 and target["virtual_edges"] > 0
        assert {"io", "factorisation", "virtual_edges", "solves", "contact", "penetration"} <= set(target["seconds"])
        row = target["penetrations"][0]
        assert {"name", "length", "pairs", "template_length", "template_pairs"} <= set(row)
        # the plain comparison and the contact solve are opt-in
        assert "plain_length" not in row and target["plain_worse_than_template"] is None
        assert "before_contact_length" not in row and target["worse_before_contact"] is None
        assert set(target["worse_than_template"]) <= set(target["penetrations"][k]["name"] for k in range(52))
        # the template's own numbers are measured once and are the same for every target
        lengths = [r["template_length"] for r in target["penetrations"]]
        assert template_lengths is None or lengths == template_lengths
        template_lengths = lengths
        # The curve is split by place; the MakeHuman heads' eyeballs and lashes are separate
        # pieces crossing the skin at rest.
        for row in target["penetrations"]:
            assert 0.0 <= row["between_pieces"] <= row["length"] + 1e-9
            assert 0.0 <= row["template_between_pieces"] <= row["template_length"] + 1e-9
        assert 0.0 < target["neutral_penetration"]["between_pieces"] <= target["neutral_penetration"]["length"]
        # The template's curve the wrap judges its carried keys by, per part, at the target's
        # size; and the criterion the add-on reads (`excess`: the curve of the pairs the shape
        # crosses that neither the target's neutral nor the template's shape crosses), part by
        # part no more than the shape's own curve.
        template_rest = target["template_neutral_penetration"]
        for row in target["penetrations"]:
            template_between = row["template_between_pieces"] - template_rest["between_pieces"]
            template_inside = row["template_length"] - template_rest["length"] - template_between
            assert row["template_added"] == pytest.approx({"inside": template_inside, "between": template_between}, abs=1e-9)
            crossing = row["template_crossing"]
            assert crossing["between"] == pytest.approx(row["template_between_pieces"], abs=1e-9)
            assert crossing["inside"] == pytest.approx(row["template_length"] - row["template_between_pieces"], abs=1e-9)
            excess = row["excess"]
            assert 0.0 <= excess["inside"] <= row["length"] - row["between_pieces"] + 1e-9
            assert 0.0 <= excess["between"] <= row["between_pieces"] + 1e-9
        excess = {row["name"]: sum(row["excess"].values()) for row in target["penetrations"]}
        assert all(excess[name] > 0.0 for name in target["worse_than_template"])
    bpy.ops.wm.open_mainfile(filepath=str(out_blend))
    for name in TARGETS:
        assert len(bpy.data.objects[name].data.shape_keys.key_blocks) == 53


def test_batch_personalises_with_packed_expressions_from_a_pack_json(sample, tmp_path):
    target = bpy.data.objects["Target_Boy"]
    assert transfer_onto(target) == {"FINISHED"}
    members = ("jawOpen", "eyeBlinkLeft")
    scan = sum(1.2 * (key_positions(target, m) - rest(target)) for m in members) + rest(target)
    target.shape_key_clear()
    posed_copy(target, "Boy_REF_01", scan)
    path = str(tmp_path / "with_scan.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path)
    pack = tmp_path / "pack.json"
    pack.write_text(json.dumps({"expressions": [{"label": "REF_01", "shapes": list(members)}]}))
    out = tmp_path / "transfer.json"
    run_batch(
        "transfer", "--input", path, "--source", "Template", "--target", "Target_Boy",
        "--examples", "Boy_REF_01", "--pack-json", str(pack), "--json", str(out), "--refine-weights", check=True,
    )
    report = json.loads(out.read_text())["targets"][0]
    row = report["training"]["Boy_REF_01"]
    names = template_names()
    assert [names[k] for k, w in enumerate(row) if w == 1.0] == sorted(members, key=names.index) and sum(row) == 2
    assert report["seconds"]["personalisation"] > 0 and len(report["shapes"]) == 52
    # Refined against the transferred shapes: the scan poses them at 1.2, clamped to 1; the
    # shapes not in the expression stay out. The scan is exact where neither shape moves.
    (refined,) = report["weights"]
    assert [w for w, given in zip(refined, row) if given] == [1.0, 1.0] and sum(refined) == 2.0
    assert len(report["example_noise"]) == 1 and report["example_noise"][0] < 1e-6


def test_batch_contact_flags(sample_path, tmp_path):
    out = tmp_path / "transfer.json"
    run_batch(
        "transfer", "--input", sample_path, "--source", "Template", "--target", "Target_Boy", "--no-contact",
        "--compare-plain", "--json", str(out), check=True,
    )
    report = json.loads(out.read_text())
    assert report["params"]["transfer"]["contact"] is None
    target = report["targets"][0]
    assert target["worse_before_contact"] is None and isinstance(target["plain_worse_than_template"], list)
    assert "before_contact_length" not in target["penetrations"][0] and "plain_length" in target["penetrations"][0]
    run_batch(
        "transfer", "--input", sample_path, "--source", "Template", "--target", "Target_Boy",
        "--contact", "--contact-distance", "0.5", "--keys", "mouthClose,cheekPuff", "--json", str(out), check=True,
    )
    report = json.loads(out.read_text())
    assert report["params"]["transfer"]["contact"]["distance"] == 0.5
    target = report["targets"][0]
    row = target["penetrations"][0]
    assert {"before_contact_length", "before_contact_pairs", "contact"} <= set(row)
    # Virtual edges alone pass the mouth through the teeth and the lips through each other
    # where the template's shapes do not; the contact solve takes every such pair apart, so
    # the judge finds nothing after it.
    assert sorted(target["worse_before_contact"]) == ["cheekPuff", "mouthClose"]
    assert target["worse_than_template"] == []


@pytest.mark.parametrize(
    "args, message",
    [
        (("--target", "Target_Boy", "--contact", "--contact-distance", "-1"), "contact distance must lie in"),
        (("--target", "Target_Nobody"), "no object named 'Target_Nobody'"),
        (("--target", "Template"), "is the template itself"),
        (("--targets", "Nope_*"), "matches no object"),
        (("--target", "Target_Boy", "--examples", "REF_01"), "no object named 'REF_01'"),
    ],
)
def test_batch_bad_input_exits_2_with_one_line(sample_path, tmp_path, args, message):
    digest = file_digest(sample_path)
    proc = run_batch("transfer", "--input", sample_path, "--source", "Template", *args, "--output", str(tmp_path / "o.blend"))
    assert proc.returncode == 2, proc.stderr
    lines = proc.stderr.strip().splitlines()
    assert len(lines) == 1 and message in lines[0], proc.stderr
    assert file_digest(sample_path) == digest and not (tmp_path / "o.blend").exists()
