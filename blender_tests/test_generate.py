"""Generate ARKit Keys with the bundled template alone, on characters as they come: a cartoon
head (the MakeHuman identity warped to large eyes and a wide mouth, decimated, with n-gons,
Y up in centimetres); a full body (a head joined to a body), whose body keeps still; Cancel
during a wrap, a transfer onto a character, Pack, Place Landmarks and Transfer Shape Keys,
leaving the file as it was; and the zip installed in a fresh
user directory giving a character its 52 keys."""

import importlib
import os
import subprocess
import sys
import tempfile
import threading

import bmesh
import bpy
import numpy as np
import pytest
from mathutils import Vector

from conftest import ROOT, extension_zip, make_active

IDENTITY = "Target_YoungWoman"


def module(shapesmith, name):
    return importlib.import_module(f"{shapesmith.__name__}.{name}")


def positions(obj):
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", co)
    return co.reshape(-1, 3).astype(np.float64)


def key_delta(obj, name):
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.shape_keys.key_blocks[name].data.foreach_get("co", co)
    return co.reshape(-1, 3) - positions(obj)


def face_sizes(obj):
    sizes = np.empty(len(obj.data.polygons), dtype=np.int32)
    obj.data.polygons.foreach_get("loop_total", sizes)
    return sizes


def only(*keep):
    """Removes every object but `keep` (the sample's template among them: only the bundled
    one is left to wrap from)."""
    for obj in list(bpy.data.objects):
        if obj.name not in keep:
            bpy.data.objects.remove(obj)
    bpy.context.view_layer.update()


def bulge(points, centre, radius, factor, axes=(1.0, 1.0, 1.0)):
    """Points scaled about `centre` by up to `factor` (per axis weights `axes`), fading out at `radius`."""
    offset = points - centre
    weight = np.clip(1.0 - np.linalg.norm(offset, axis=1) / radius, 0.0, 1.0) ** 2
    return points + offset * (factor - 1.0) * weight[:, None] * np.asarray(axes)


def cartoon(shapesmith, name="Cartoon"):
    """The identity head warped to large eyes and a wide mouth, collapse-decimated, a strip of
    faces at the back dissolved into n-gons, then Y up in centimetres (the object turned and
    scaled back into the scene)."""
    template = module(shapesmith, "blender.bundled_template").load()
    parts = {name: i for i, name in enumerate(template["part_names"])}
    neutral = template["neutral"]

    def centre(part, side=0):
        used = np.unique(template["faces"][template["face_part"] == parts[part]])
        points = neutral[used]
        return points[points[:, 0] * side > 0].mean(axis=0) if side else points.mean(axis=0)

    identity = bpy.data.objects[IDENTITY]
    points = positions(identity)
    for side in (1, -1):
        points = bulge(points, centre("Eyes", side), 0.035, 1.35)
    points = bulge(points, centre("Teeth"), 0.05, 1.3, axes=(1.0, 0.3, 0.3))
    mesh = identity.data.copy()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    mesh.vertices.foreach_set("co", points.astype(np.float32).ravel())
    obj.modifiers.new("Decimate", "DECIMATE").ratio = 0.5
    decimated = bpy.data.meshes.new_from_object(obj.evaluated_get(bpy.context.evaluated_depsgraph_get()))
    obj.modifiers.clear()
    obj.data = decimated
    bm = bmesh.new()
    bm.from_mesh(decimated)
    back = max(v.co.y for v in bm.verts) - 0.04
    edges = [e for e in bm.edges if all(v.co.y > back for v in e.verts) and len(e.link_faces) == 2][::3]
    bmesh.ops.dissolve_edges(bm, edges=edges)
    bm.to_mesh(decimated)
    bm.free()
    points = positions(obj)
    cm_y_up = 100.0 * np.stack([points[:, 0], points[:, 2], -points[:, 1]], axis=1)
    decimated.vertices.foreach_set("co", cm_y_up.astype(np.float32).ravel())
    decimated.update()
    obj.rotation_euler.x = np.pi / 2
    obj.scale = (0.01,) * 3
    assert (face_sizes(obj) > 4).sum() >= 3, "the cartoon should have n-gons"
    return obj


def template_motion(name):
    """The bundled template's largest vertex motion in `name`, metres."""
    head = bpy.data.objects["ARKit Template"]
    return float(np.linalg.norm(key_delta(head, name), axis=1).max())


def check_blink(character, name, side, scale):
    """The key closes the lid on its side: its largest motion at least 60% of the template's
    (in the character's units, `scale` per metre), on that side of the face, downward
    (local Y up)."""
    delta = key_delta(character, name)
    motion = np.linalg.norm(delta, axis=1)
    assert motion.max() >= 0.6 * scale * template_motion(name), (name, motion.max(), scale * template_motion(name))
    moving = motion > 0.5 * motion.max()
    assert np.mean(np.sign(positions(character)[moving, 0]) == side) >= 0.9, name
    assert delta[moving, 1].mean() < 0.0, f"{name} does not move the lid down"


def blink_side(name):
    """+1 or -1: the side of X the bundled template's key moves."""
    head = bpy.data.objects["ARKit Template"]
    motion = np.linalg.norm(key_delta(head, name), axis=1)
    return float(np.sign(positions(head)[motion > 0.5 * motion.max(), 0].mean()))


def test_add_arkit_template_adds_the_head_its_keys_and_face_parts(sample, shapesmith):
    assert bpy.ops.shapesmith.add_arkit_template() == {"FINISHED"}
    head = bpy.data.objects["ARKit Template"]
    assert bpy.context.scene.shapesmith.transfer.source == head
    keys = [k.name for k in head.data.shape_keys.key_blocks[1:]]
    assert len(keys) == 52 and "eyeBlinkLeft" in keys and "jawOpen" in keys and "tongueOut" in keys
    parts = [item.object.name for item in head.shapesmith.face_parts]
    assert parts == [f"ARKit Template {p}" for p in ("Eyes", "Teeth", "Tongue", "Lashes")]
    assert "CC0" in head["shapesmith_bundled_template"] and "MakeHuman" in head["shapesmith_bundled_template"]
    # The sample's template is the same face in one mesh: the bundled keys are its keys, to
    # float32, each part's taking its own.
    sample_template = bpy.data.objects["Template"]
    bundled = [head, *(item.object for item in head.shapesmith.face_parts)]
    for name in ("eyeBlinkLeft", "jawOpen", "tongueOut"):
        own = max(float(np.linalg.norm(key_delta(o, name), axis=1).max()) for o in bundled if name in o.data.shape_keys.key_blocks)
        assert abs(own - float(np.linalg.norm(key_delta(sample_template, name), axis=1).max())) < 1e-6, name
    teeth = bpy.data.objects["ARKit Template Teeth"]
    assert "jawOpen" in teeth.data.shape_keys.key_blocks and "eyeBlinkLeft" not in teeth.data.shape_keys.key_blocks


def test_generate_on_a_cartoon_with_ngons_in_centimetres_closes_both_eyes(sample, shapesmith):
    character = cartoon(shapesmith)
    sizes = face_sizes(character)
    only(character.name)
    make_active(character)
    assert bpy.ops.shapesmith.generate_arkit_keys() == {"FINISHED"}
    keys = character.data.shape_keys.key_blocks
    assert len(keys) == 53
    assert np.array_equal(face_sizes(character), sizes), "the user's faces are untouched"
    # The cartoon's eyes are 1.35 times the template's: the lid travels at least as far.
    for name in ("eyeBlinkLeft", "eyeBlinkRight"):
        check_blink(character, name, blink_side(name), 100.0)
    assert len(character.shapesmith_wrap.pairs) >= 4, "the proposed pairs are kept for the rigger to move"
    jaw = np.linalg.norm(key_delta(character, "jawOpen"), axis=1).max()
    assert jaw >= 0.6 * 100.0 * template_motion("jawOpen")


def full_body(shapesmith, name="Body"):
    """The identity head joined to a body below its neck (a box, shoulders wider than the
    head); returns (object, the head's vertex count: the body's vertices follow)."""
    identity = bpy.data.objects[IDENTITY]
    mesh = identity.data.copy()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    if mesh.shape_keys is not None:
        obj.shape_key_clear()
    head_count = len(mesh.vertices)
    points = positions(obj)
    bm = bmesh.new()
    bm.from_mesh(mesh)
    neck = points[:, 2].min()
    body = bmesh.ops.create_cube(bm, size=1.0)["verts"]
    bmesh.ops.scale(bm, vec=(0.45, 0.25, 0.6), verts=body)
    bmesh.ops.translate(bm, vec=(0.0, points[:, 1].mean(), neck - 0.31), verts=body)
    # More vertices than the head: a wrap of the whole mesh would fit its largest piece, the body.
    bmesh.ops.subdivide_edges(bm, edges=list({e for v in body for e in v.link_edges}), cuts=32, use_grid_fill=True)
    bm.to_mesh(mesh)
    bm.free()
    return obj, head_count


def test_generate_on_a_full_body_keys_the_head_and_leaves_the_body_still(sample, shapesmith, capfd):
    character, head_count = full_body(shapesmith)
    assert len(character.data.vertices) > 2 * head_count
    only(character.name)
    make_active(character)
    assert bpy.ops.shapesmith.generate_arkit_keys() == {"FINISHED"}
    region = [line for line in capfd.readouterr().out.splitlines() if "region:" in line]
    assert len(region) == 1 and "head (above the neck)" in region[0], region
    keys = character.data.shape_keys.key_blocks
    assert len(keys) == 53
    for key in keys[1:]:
        delta = key_delta(character, key.name)
        assert not np.any(delta[head_count:]), f"{key.name} moves the body"
    for name in ("eyeBlinkLeft", "eyeBlinkRight"):
        check_blink_z_up(character, name, blink_side(name))


def check_blink_z_up(character, name, side):
    delta = key_delta(character, name)
    motion = np.linalg.norm(delta, axis=1)
    assert motion.max() >= 0.6 * template_motion(name), (name, motion.max(), template_motion(name))
    moving = motion > 0.5 * motion.max()
    assert np.mean(np.sign(positions(character)[moving, 0]) == side) >= 0.9, name
    assert delta[moving, 2].mean() < 0.0, f"{name} does not move the lid down"


def state(character):
    """What a cancelled tool must leave as it was."""
    keys = character.data.shape_keys
    return (
        sorted(o.name for o in bpy.data.objects), sorted(m.name for m in bpy.data.meshes),
        None if keys is None else [k.name for k in keys.key_blocks], len(character.shapesmith_wrap.pairs),
        bpy.context.scene.shapesmith.transfer.source, character.shapesmith_wrap.done, character.shapesmith_wrap.written,
    )


@pytest.fixture
def cancel_midway(shapesmith, monkeypatch):
    """The user's Cancel, pressed once the native work has started: the stop flag set from
    another thread at the first progress report past 5%."""
    jobs = module(shapesmith, "blender.jobs")
    original = jobs.keep_going

    def keep_going(callback=None):
        inner = original(callback)

        def progress(fraction):
            if fraction > 0.05 and not jobs.cancelling():
                presser = threading.Thread(target=jobs.cancel)
                presser.start()
                presser.join()
            return inner(fraction)

        return progress

    monkeypatch.setattr(jobs, "keep_going", keep_going)
    return jobs


def cancelled_once(capfd, label):
    lines = [line for line in capfd.readouterr().out.splitlines() if "cancelled" in line.lower()]
    assert lines == [f"Warning: {label} cancelled: nothing was changed"], lines


def test_cancel_during_a_wrap_and_a_transfer_leaves_the_file_as_it_was(sample, shapesmith, cancel_midway, capfd):
    character = bpy.data.objects["Character_YoungWoman"]
    del character["shapesmith_wrap_pairs"]
    make_active(character)
    bpy.context.scene.shapesmith.transfer.source = None
    before = state(character)
    capfd.readouterr()
    assert bpy.ops.shapesmith.wrap_template() == {"CANCELLED"}
    assert state(character) == before
    cancelled_once(capfd, "Wrap")

    # The threaded path the panel runs (stepped here as its timer would): cancelled the same way.
    jobs = cancel_midway
    wrap_operator = importlib.import_module(f"{shapesmith.__name__}.operators.wrap_template")
    job = jobs.ThreadedJob("Wrap", wrap_operator.wrap_onto, character, None, False, bpy.context.scene)
    while job.step():
        if job.fraction > 0.05 and not jobs.cancelling():
            threading.Thread(target=jobs.cancel).start()
    job.wait()
    assert job.state == "cancelled" and state(character) == before

    template = bpy.data.objects["Template"]
    bpy.context.scene.shapesmith.transfer.source = template
    wrapped = wrap_operator.wrap_onto(lambda fraction: True, character, template, False, bpy.context.scene)
    assert wrapped[0].report["mean_distance"] < 0.01
    before = state(character)
    capfd.readouterr()
    assert bpy.ops.shapesmith.transfer_onto_character() == {"CANCELLED"}
    assert state(character) == before and character.data.shape_keys is None
    cancelled_once(capfd, "Transfer onto Character")


def test_the_zip_alone_in_a_fresh_user_directory_gives_a_character_its_52_keys(sample, shapesmith, tmp_path):
    character, head_count = full_body(shapesmith, "Avatar")
    character.vertex_groups.new(name="Head").add(list(range(head_count)), 1.0, "REPLACE")
    only(character.name)
    source = str(tmp_path / "avatar.blend")
    bpy.ops.wm.save_as_mainfile(filepath=source, copy=True)
    output = str(tmp_path / "avatar_keys.blend")
    script = (
        "import bpy, runpy, sys\n"
        f"assert bpy.ops.extensions.package_install_files(filepath={extension_zip()!r}, repo='user_default', "
        "enable_on_install=True) == {'FINISHED'}\n"
        f"sys.argv = ['batch.py', '--', 'generate', '--input', {source!r}, '--character', 'Avatar', '--region', 'Head', "
        f"'--output', {output!r}]\n"
        f"runpy.run_path({os.path.join(ROOT, 'scripts', 'batch.py')!r}, run_name='__main__')\n"
    )
    env = dict(os.environ, BLENDER_USER_RESOURCES=tempfile.mkdtemp(prefix="shapesmith-fresh-user-"), SHAPESMITH_CACHE=str(tmp_path / "no-cache"))
    proc = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, env=env)
    assert proc.returncode == 0, proc.stderr[-3000:]
    assert "52 ARKit keys written onto 'Avatar'" in proc.stdout
    bpy.ops.wm.open_mainfile(filepath=output)
    avatar = bpy.data.objects["Avatar"]
    assert len(avatar.data.shape_keys.key_blocks) == 53
    for key in avatar.data.shape_keys.key_blocks[1:]:
        assert not np.any(key_delta(avatar, key.name)[head_count:]), f"{key.name} moves outside the Head group"
    assert np.linalg.norm(key_delta(avatar, "eyeBlinkLeft"), axis=1).max() > 0.003


def test_cancel_during_pack_and_place_landmarks_leaves_the_rig_as_it_was(sample, shapesmith, cancel_midway, capfd):
    template = make_active(bpy.data.objects["Template"])
    before = state(template), template.shapesmith.pack.result.done, template.shapesmith.landmarks.done
    capfd.readouterr()
    assert bpy.ops.shapesmith.pack_expressions() == {"CANCELLED"}
    cancelled_once(capfd, "Pack Expressions")
    assert bpy.ops.shapesmith.place_landmarks() == {"CANCELLED"}
    cancelled_once(capfd, "Place Landmarks")
    assert (state(template), template.shapesmith.pack.result.done, template.shapesmith.landmarks.done) == before


def test_cancel_during_transfer_shape_keys_leaves_the_target_and_its_sculpted_key_as_they_were(sample, shapesmith, cancel_midway, capfd):
    target = make_active(bpy.data.objects["Target_Boy"])
    target.shape_key_add(name="Basis")
    sculpted = target.shape_key_add(name="jawOpen", from_mix=False)
    co = positions(target)
    co[:, 2] -= 0.01
    sculpted.data.foreach_set("co", co.astype(np.float32).ravel())
    settings = bpy.context.scene.shapesmith.transfer
    settings.source, settings.overwrite = bpy.data.objects["Template"], True

    def target_state():
        return state(target), key_delta(target, "jawOpen").tobytes(), target.shapesmith.transfer.done

    before = target_state()
    capfd.readouterr()
    assert bpy.ops.shapesmith.transfer_shape_keys() == {"CANCELLED"}
    assert target_state() == before
    cancelled_once(capfd, "Transfer Shape Keys")

    # The threaded path the panel runs, stepped as its timer would: cancelled the same way.
    jobs = cancel_midway
    operator = module(shapesmith, "operators.transfer_shape_keys")
    job = jobs.ThreadedJob("Transfer Shape Keys", operator.transfer_and_write, settings.source, target, settings, (), {}, {})
    while job.step():
        if job.fraction > 0.05 and not jobs.cancelling():
            threading.Thread(target=jobs.cancel).start()
    job.wait()
    assert job.state == "cancelled" and target_state() == before

    # Not cancelled, the same job writes the 52 keys over the sculpted one.
    job = jobs.ThreadedJob("Transfer Shape Keys", operator.transfer_and_write, settings.source, target, settings, (), {}, {})
    job.wait()
    assert job.state == "finished" and len(target.data.shape_keys.key_blocks) == 53
    assert np.abs(key_delta(target, "jawOpen")[:, 2] + 0.01).max() > 1e-3


def test_objects_within_the_head_are_its_face_parts_by_their_place(sample, shapesmith):
    generate = module(shapesmith, "blender.generate")
    character = bpy.data.objects["Character_YoungWoman"]
    corners = np.array([character.matrix_world @ Vector(v) for v in character.bound_box])
    low, high = corners.min(axis=0), corners.max(axis=0)
    centre, size = (low + high) / 2, float(np.linalg.norm(high - low))

    def cube(name, location):
        mesh = bpy.data.meshes.new(name)
        bm = bmesh.new()
        bmesh.ops.create_cube(bm, size=0.05 * size)
        bm.to_mesh(mesh)
        bm.free()
        obj = bpy.data.objects.new(name, mesh)
        bpy.context.scene.collection.objects.link(obj)
        obj.location = location
        return obj

    inside = cube("Teeth_Inside", centre)
    cube("Prop_Outside", centre + np.array([size, 0.0, 0.0]))
    bpy.context.view_layer.update()
    found = generate.parts_by_place(character, None, {character})
    assert inside in found and all(o.name != "Prop_Outside" for o in found)
    # The sample's other heads stand beside the character, not within it.
    assert not any(o.name.startswith(("Target_", "Template")) for o in found)
