"""A face in several objects: the sample Template's loose pieces split into objects as a Ready
Player Me export has them (the head with its lashes, the teeth with the tongue, each eye), each
part with only the keys that move it, listed on the head as its Face Parts. Every tool must
read them as the one joined mesh they came from: the same collisions across objects, the same
packing, the same transferred keys (each part receiving its own), and the same results after a
round trip through Blender's glTF and FBX exporters and importers."""

import importlib
import json

import bmesh
import bpy
import numpy as np
import pytest

from conftest import file_digest, make_active, run_batch

OBJECTS = ("Head", "Teeth", "EyeLeft", "EyeRight")


def module(shapesmith, name):
    return importlib.import_module(f"{shapesmith.__name__}.blender.{name}")


def positions(obj, key=None):
    mesh = obj.data
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    (mesh.shape_keys.key_blocks[key].data if key else mesh.vertices).foreach_get("co", co)
    return co.reshape(-1, 3)


def template_arrays(triangulated=False):
    """The Template's rest positions, faces (as corner lists; its triangles when
    `triangulated`) and {key: positions}."""
    template = bpy.data.objects["Template"]
    template.data.calc_loop_triangles()
    polygons = template.data.loop_triangles if triangulated else template.data.polygons
    faces = [list(p.vertices) for p in polygons]
    blocks = template.data.shape_keys.key_blocks
    return positions(template), faces, {kb.name: positions(template, kb.name) for kb in blocks[1:]}


def pieces(shapesmith, neutral, faces, keys):
    """{object name: Template vertices (ascending)}: each loose piece of the Template grouped
    by what moves it (the largest piece and the lashes, which blinks move: the head; pieces
    the eye looks turn: the eyes; the rest, tongue and teeth: the teeth)."""
    triangles = np.array([[f[0], f[i], f[i + 1]] for f in faces for i in range(1, len(f) - 1)], dtype=np.int32)
    labels, count, _ = shapesmith.native.module().mesh_parts(len(neutral), triangles)
    labels = np.asarray(labels)
    sizes = np.bincount(labels)
    groups = {name: [] for name in OBJECTS}
    for piece in range(count):
        vertices = np.flatnonzero(labels == piece)
        moved = {name for name, key in keys.items() if np.any(key[vertices] != neutral[vertices])}
        if sizes[piece] == sizes.max() or {"eyeBlinkLeft", "eyeBlinkRight"} & moved:
            groups["Head"].append(vertices)
        elif "eyeLookUpLeft" in moved:
            groups["EyeLeft"].append(vertices)
        elif "eyeLookUpRight" in moved:
            groups["EyeRight"].append(vertices)
        else:
            groups["Teeth"].append(vertices)
    return {name: np.sort(np.concatenate(v)) for name, v in groups.items()}


def mesh_object(name, rest, faces, keys=(), location=0.0):
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(rest.tolist(), [], faces)
    mesh.shade_smooth()  # as the sample's: glTF splits a vertex per normal
    obj = bpy.data.objects.new(name, mesh)
    obj.location.x = location
    bpy.context.scene.collection.objects.link(obj)
    if keys:
        obj.shape_key_add(name="Basis", from_mix=False).value = 0.0
        for key, co in keys:
            block = obj.shape_key_add(name=key, from_mix=False)
            block.data.foreach_set("co", co.ravel())
            block.value = 0.0
    return obj


def split(shapesmith, prefix, rest, faces, keys, groups, location):
    """The face as objects `<prefix>Head`, `<prefix>Teeth`, ... (each with the keys that move
    it, when `keys`), the parts listed on the head; and `<prefix>Joined`, the same vertices and
    faces in one object in the parts' order, with the union of their keys in the order the
    tools read them. Returns (head, joined)."""
    owner = np.empty(len(rest), dtype=np.int64)
    for index, name in enumerate(OBJECTS):
        owner[groups[name]] = index
    face_owner = owner[[f[0] for f in faces]]
    objects, order, names = [], [], []
    for index, name in enumerate(OBJECTS):
        vertices = groups[name]
        new_index = np.full(len(rest), -1)
        new_index[vertices] = np.arange(len(vertices))
        own = [new_index[f].tolist() for f, o in zip(faces, face_owner) if o == index]
        moving = [(k, co[vertices]) for k, co in keys.items() if np.any(co[vertices] != rest[vertices])]
        objects.append(mesh_object(prefix + name, rest[vertices], own, moving, location))
        order.append(vertices)
        names += [k for k, _ in moving if k not in names]
    head = objects[0]
    module(shapesmith, "face_parts").store_parts(head, objects[1:])
    order = np.concatenate(order)
    new_index = np.empty(len(rest), dtype=np.int64)
    new_index[order] = np.arange(len(order))
    joined_faces = [new_index[faces[f]].tolist() for f in np.argsort(face_owner, kind="stable")]
    joined = mesh_object(prefix + "Joined", rest[order], joined_faces, [(k, keys[k][order]) for k in names] if keys else (),
                         location + 0.12)
    bpy.context.view_layer.update()
    return head, joined


def split_sample(shapesmith, triangulated=False):
    rest, faces, keys = template_arrays(triangulated)
    groups = pieces(shapesmith, rest, faces, keys)
    template, joined = split(shapesmith, "Tpl_", rest, faces, keys, groups, 2.0)
    target_rest = positions(bpy.data.objects["Target_OldMan"])
    target, target_joined = split(shapesmith, "Old_", target_rest, faces, {}, groups, 2.5)
    return {"template": template, "joined": joined, "target": target, "target_joined": target_joined}


@pytest.fixture
def face(sample, shapesmith):
    """{"template": Tpl_Head, "joined": Tpl_Joined, "target": Old_Head, "target_joined":
    Old_Joined}: the split Template with its keys and the split Target_OldMan without."""
    return split_sample(shapesmith)


@pytest.fixture
def triangulated_face(sample, shapesmith):
    """`face` with the Template's triangles for faces on every object, as glTF carries them
    (its exporter splits each quad along the diagonal the quad's own shape picks, so that a
    template and a target of one quad topology would come back as two topologies)."""
    return split_sample(shapesmith, triangulated=True)


def parts(head):
    return [item.object for item in head.shapesmith.face_parts]


def face_positions(head, key=None):
    """Positions of a key over the head and its parts, concatenated (head first); an object
    without the key at rest."""
    def own(obj):
        keys = obj.data.shape_keys
        return positions(obj, key) if key and keys is not None and key in keys.key_blocks else positions(obj)

    return np.concatenate([own(o) for o in [head, *parts(head)]])


def diagonal(points):
    return float(np.linalg.norm(points.max(0) - points.min(0)))


def transfer(source, target, **options):
    settings = bpy.context.scene.shapesmith.transfer
    settings.source = source
    for key, value in options.items():
        setattr(settings, key, value)
    make_active(target)
    return bpy.ops.shapesmith.transfer_shape_keys()


# --- the list on the head ----------------------------------------------------------------


def test_the_face_parts_list_is_edited_by_its_buttons_each_one_undo_step(face):
    head = face["target"]
    head.shapesmith.face_parts.clear()
    make_active(head)
    for name in ("Old_Teeth", "Old_EyeLeft"):
        bpy.data.objects[name].select_set(True)
    bpy.ops.ed.undo_push(message="before")
    assert bpy.ops.shapesmith.add_face_parts() == {"FINISHED"}
    bpy.ops.ed.undo_push(message="added")
    assert [o.name for o in parts(bpy.data.objects["Old_Head"])] == ["Old_EyeLeft", "Old_Teeth"]
    assert bpy.ops.shapesmith.add_face_parts() == {"FINISHED"}  # listed once
    head = bpy.data.objects["Old_Head"]
    head.shapesmith.active_face_part = 1
    assert bpy.ops.shapesmith.move_face_part(direction="UP") == {"FINISHED"}
    assert [o.name for o in parts(head)] == ["Old_Teeth", "Old_EyeLeft"] and head.shapesmith.active_face_part == 0
    bpy.ops.ed.undo_push(message="moved")
    assert bpy.ops.shapesmith.remove_face_part() == {"FINISHED"}
    bpy.ops.ed.undo_push(message="removed")
    assert [o.name for o in parts(bpy.data.objects["Old_Head"])] == ["Old_EyeLeft"]
    bpy.ops.ed.undo()
    assert [o.name for o in parts(bpy.data.objects["Old_Head"])] == ["Old_Teeth", "Old_EyeLeft"]
    bpy.ops.ed.undo()
    bpy.ops.ed.undo()
    assert parts(bpy.data.objects["Old_Head"]) == []


def test_a_part_listed_twice_or_sharing_a_mesh_is_refused(face, shapesmith):
    face_parts = module(shapesmith, "face_parts")
    head = face["template"]
    teeth = parts(head)[0]
    with pytest.raises(ValueError, match="'Tpl_Teeth' is listed twice"):
        face_parts.face_objects(head, [teeth, teeth])
    with pytest.raises(ValueError, match="uses the mesh of 'Tpl_Head'"):
        twin = head.copy()
        bpy.context.scene.collection.objects.link(twin)
        face_parts.face_objects(head, [twin])


# --- every tool reads the parts with the head ---------------------------------------------


def test_tongue_out_in_the_teeth_collides_with_mouth_close_across_objects(face, shapesmith):
    head = face["template"]
    assert "tongueOut" not in head.data.shape_keys.key_blocks and "tongueOut" in parts(head)[0].data.shape_keys.key_blocks
    report = module(shapesmith, "analysis").analyze_object(head)
    assert [o["object"] for o in report["objects"]] == ["Tpl_" + n for n in OBJECTS]
    assert report["shapes"] == 52 and "tongueOut" not in report["inert"]
    packed = module(shapesmith, "packing").pack_object(head)
    collisions = {frozenset(c["shapes"]) for c in packed["collisions"]}
    assert frozenset(("tongueOut", "mouthClose")) in collisions
    assert not any("tongueOut" in e["shapes"] and "mouthClose" in e["shapes"] for e in packed["expressions"])
    # The head alone never sees the tongue: the key does not exist for it.
    alone = module(shapesmith, "packing").pack_object(head, parts=[])
    assert "tongueOut" not in alone["names"]


def test_packing_the_split_face_equals_packing_the_joined_one(face, shapesmith):
    packing = module(shapesmith, "packing")
    split_report, joined_report = packing.pack_object(face["template"]), packing.pack_object(face["joined"])
    assert split_report["names"] == joined_report["names"]
    for key in ("expressions", "conflicts", "inert", "pairs", "antagonists", "collisions", "occlusions"):
        assert split_report[key] == joined_report[key], key
    assert [p["object"] for p in split_report["objects"]] == ["Tpl_" + n for n in OBJECTS]


def test_transfer_of_the_split_face_equals_the_joined_transfer_and_every_part_gets_its_keys(face):
    template, target = face["template"], face["target"]
    teeth = parts(template)[0]
    teeth.data.shape_keys.key_blocks["tongueOut"].slider_max = 2.0
    bpy.ops.ed.undo_push(message="before transfer")
    assert transfer(template, target) == {"FINISHED"}
    bpy.ops.ed.undo_push(message="after transfer")
    assert transfer(face["joined"], face["target_joined"]) == {"FINISHED"}

    target, template = bpy.data.objects["Old_Head"], bpy.data.objects["Tpl_Head"]
    joined = bpy.data.objects["Old_Joined"]
    tolerance = 1e-6 * diagonal(positions(joined))
    offset = 0
    for source_part, target_part in zip([template, *parts(template)], [target, *parts(target)]):
        own = [kb.name for kb in source_part.data.shape_keys.key_blocks]
        assert [kb.name for kb in target_part.data.shape_keys.key_blocks] == own, target_part.name
        n = len(target_part.data.vertices)
        for name in own[1:]:
            error = np.abs(positions(target_part, name) - positions(joined, name)[offset : offset + n]).max()
            assert error <= tolerance, f"{target_part.name} {name}: {error} > {tolerance}"
        offset += n
    assert parts(target)[0].data.shape_keys.key_blocks["tongueOut"].slider_max == 2.0
    assert target.shapesmith.transfer.done and target.shapesmith.transfer.written == 52

    bpy.ops.ed.undo()  # one step takes the keys off every object of the face
    assert all(bpy.data.objects["Old_" + name].data.shape_keys is None for name in OBJECTS)


def test_after_transfer_no_skin_of_the_head_is_inside_the_teeth(face, shapesmith):
    """The collision pass sees the teeth of another object: in no key do more head triangles
    pass through the teeth than in the joined transfer's."""
    assert transfer(face["template"], face["target"]) == {"FINISHED"}
    assert transfer(face["joined"], face["target_joined"]) == {"FINISHED"}
    intersecting = shapesmith.native.module().intersecting_triangles
    read_triangles = module(shapesmith, "mesh_arrays").read_triangles
    target, joined = face["target"], face["target_joined"]
    head, teeth = len(target.data.vertices), len(parts(target)[0].data.vertices)
    triangles = read_triangles(joined)
    head_and_teeth = triangles[np.all(triangles < head + teeth, axis=1)]
    head_only = triangles[np.all(triangles < head, axis=1)]

    def through_teeth(posed):
        """Head triangles that cross something only once the teeth are there."""
        rest = positions(joined)[: head + teeth]
        with_teeth = np.asarray(intersecting(posed[: head + teeth], head_and_teeth, rest=rest), dtype=bool)
        alone = np.asarray(intersecting(posed[:head], head_only, rest=rest[:head]), dtype=bool)
        return int(np.sum(with_teeth[: len(head_only)] & ~alone))

    for name in [kb.name for kb in joined.data.shape_keys.key_blocks[1:]]:
        split_count, joined_count = through_teeth(face_positions(target, name)), through_teeth(positions(joined, name))
        assert split_count <= joined_count, f"{name}: {split_count} head triangles through the teeth, joined {joined_count}"


def test_landmarks_go_on_the_head_unless_a_part_is_allowed(face, shapesmith):
    landmarks = module(shapesmith, "landmarks")
    head = face["template"]
    settings = module(shapesmith, "settings").LandmarkSettings(rays=16, max_per_shape=1)
    document = landmarks.place_landmarks(head, settings)
    assert {l["object"] for l in document["landmarks"]} == {"Tpl_Head"}
    assert "tongueOut" in document["uncovered"]  # it moves only the teeth, where no landmark may go
    teeth = parts(head)[0]
    allowed = landmarks.place_landmarks(head, settings, allowed_parts=[teeth])
    on_teeth = [l for l in allowed["landmarks"] if l["object"] == "Tpl_Teeth"]
    assert on_teeth and "tongueOut" not in allowed["uncovered"]
    assert {l["object"] for l in allowed["landmarks"]} <= {"Tpl_Head", "Tpl_Teeth"}
    landmarks.build_layout(head, allowed, bpy.context.scene)
    empties = head.shapesmith.landmarks.collection.objects
    on_part = [e for e in empties if e.parent == teeth]
    assert len(on_part) == len(on_teeth) and all(e.parent_vertices[0] < len(teeth.data.vertices) for e in on_part)
    bpy.context.view_layer.update()
    for landmark in allowed["landmarks"]:  # each empty sits on its landmark, wherever the part is
        empty = next(e for e in empties if e["vertex"] == landmark["vertex"])
        owner = bpy.data.objects[landmark["object"]]
        local = owner.matrix_world.inverted() @ empty.matrix_world.translation
        assert np.allclose(local[:], landmark["position"], atol=1e-5)
    grouped = {v.index for v in teeth.data.vertices if any(g.group == teeth.vertex_groups["Landmarks"].index for g in v.groups)}
    assert grouped == {l["object_vertex"] for l in on_teeth}


# --- what is refused, and leaves every object as it was ---------------------------------


def snapshot():
    """Every mesh's vertices and keys, and every object's transfer result."""
    state = {}
    for obj in bpy.data.objects:
        if obj.type == "MESH":
            keys = obj.data.shape_keys
            blocks = [(kb.name, positions(obj, kb.name).tobytes()) for kb in keys.key_blocks] if keys else None
            state[obj.name] = (positions(obj).tobytes(), blocks, obj.shapesmith.transfer.done)
    return state


def test_a_part_with_another_vertex_count_is_refused_naming_both(face):
    teeth = parts(face["target"])[0]
    mesh = bmesh.new()
    mesh.from_mesh(teeth.data)
    mesh.verts.ensure_lookup_table()
    bmesh.ops.delete(mesh, geom=[mesh.verts[0]], context="VERTS")
    mesh.to_mesh(teeth.data)
    mesh.free()
    before = snapshot()
    with pytest.raises(RuntimeError) as error:
        transfer(face["template"], face["target"])
    message = str(error.value)
    assert "'Old_Teeth'" in message and "'Tpl_Teeth'" in message and "vertices" in message
    assert snapshot() == before


def test_parts_that_do_not_pair_are_refused(face):
    target = face["target"]
    target.shapesmith.face_parts.remove(2)
    before = snapshot()
    with pytest.raises(RuntimeError, match="3 face part.*but target 'Old_Head' has 2"):
        transfer(face["template"], target)
    assert snapshot() == before


def test_parts_pair_by_name_after_the_prefix_whatever_their_order(face, shapesmith):
    face_parts = module(shapesmith, "face_parts")
    template_objects = face_parts.face_objects(face["template"])
    shuffled = [face["target"], *reversed(parts(face["target"]))]
    paired = face_parts.pair_parts(template_objects, shuffled)
    assert [o.name for o in paired] == ["Old_" + n for n in OBJECTS]
    # Names that do not match after the prefix pair in list order.
    renamed = parts(face["target"])[0]
    renamed.name = "Old_Mouth"
    assert [o.name for o in face_parts.pair_parts(template_objects, shuffled)] == [o.name for o in shuffled]


def test_transformed_parts_are_read_in_the_heads_space(face, shapesmith):
    """A part moved and turned with its vertices moved back reads as before; its keys are
    written back in its own space."""
    from mathutils import Matrix

    face_parts = module(shapesmith, "face_parts")
    before, _ = face_parts.read_face_rig(face_parts.face_objects(face["template"]))
    teeth = parts(face["template"])[0]
    turn = Matrix.Translation((0.01, 0.02, -0.03)) @ Matrix.Rotation(0.3, 4, "Z")
    teeth.data.transform(turn.inverted(), shape_keys=True)
    teeth.matrix_world = teeth.matrix_world @ turn
    bpy.context.view_layer.update()
    after, face_read = face_parts.read_face_rig(face_parts.face_objects(face["template"]))
    assert face_read.to_head[1] is not None
    assert np.abs(after.neutral - before.neutral).max() < 1e-6 and np.abs(after.deltas - before.deltas).max() < 1e-6


# --- batch ------------------------------------------------------------------------------


def test_batch_takes_comma_lists_or_the_stored_list(face, shapesmith, tmp_path):
    for head in (face["template"], face["target"]):
        head.shapesmith.face_parts.clear()
    listed = tmp_path / "listed.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(listed), copy=True)
    for head in ("Tpl_Head", "Old_Head"):
        module(shapesmith, "face_parts").store_parts(bpy.data.objects[head], [bpy.data.objects[head[:4] + n] for n in OBJECTS[1:]])
    stored = tmp_path / "stored.blend"
    bpy.ops.wm.save_as_mainfile(filepath=str(stored), copy=True)
    digest = file_digest(listed)

    comma = ",".join("Tpl_" + n for n in OBJECTS), ",".join("Old_" + n for n in OBJECTS)
    outputs = {}
    for label, path, source, target in (("comma", listed, *comma), ("stored", stored, "Tpl_Head", "Old_Head")):
        out, report = tmp_path / f"{label}.blend", tmp_path / f"{label}.json"
        run_batch("transfer", "--input", str(path), "--source", source, "--target", target,
                  "--output", str(out), "--json", str(report), check=True)
        result = json.loads(report.read_text())["targets"][0]
        assert result["objects"] == [["Tpl_" + n, "Old_" + n] for n in OBJECTS] and len(result["shapes"]) == 52
        outputs[label] = out
    assert file_digest(listed) == digest
    keys = {}
    for label, out in outputs.items():
        bpy.ops.wm.open_mainfile(filepath=str(out))
        keys[label] = {(o, kb.name): positions(bpy.data.objects[o], kb.name).tobytes()
                       for o in ("Old_" + n for n in OBJECTS) for kb in bpy.data.objects[o].data.shape_keys.key_blocks}
        assert [p.object.name for p in bpy.data.objects["Old_Head"].shapesmith.face_parts] == ["Old_" + n for n in OBJECTS[1:]]
    assert keys["comma"] == keys["stored"]
    assert ("Old_Teeth", "tongueOut") in keys["comma"] and ("Old_Head", "tongueOut") not in keys["comma"]

    proc = run_batch("pack", "--input", str(listed), "--object", comma[0], "--json", str(tmp_path / "pack.json"))
    assert proc.returncode == 0, proc.stderr
    collisions = {frozenset(c["shapes"]) for c in json.loads((tmp_path / "pack.json").read_text())["collisions"]}
    assert frozenset(("tongueOut", "mouthClose")) in collisions
    proc = run_batch("transfer", "--input", str(listed), "--source", comma[0], "--target", "Old_Head,Old_Teeth,Nowhere")
    assert proc.returncode == 2 and proc.stderr.count("\n") == 1 and "no object named 'Nowhere'" in proc.stderr


# --- Blender's own exporters and importers ------------------------------------------------


def world(obj, key=None):
    matrix = np.array(obj.matrix_world)
    return positions(obj, key) @ matrix[:3, :3].T + matrix[:3, 3]


def export(path, names, file_format):
    bpy.ops.object.select_all(action="DESELECT")
    for name in names:
        bpy.data.objects[name].select_set(True)
    bpy.context.view_layer.objects.active = bpy.data.objects[names[0]]
    if file_format == "GLTF":
        bpy.ops.export_scene.gltf(filepath=str(path), export_format="GLB", use_selection=True, export_morph=True,
                                  export_morph_normal=False, export_apply=False, export_animations=False)
    else:
        bpy.ops.export_scene.fbx(filepath=str(path), use_selection=True, object_types={"MESH"}, bake_anim=False)


def import_only(path, file_format):
    """The file's meshes alone in the scene, as a user starting from an export has them."""
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj)
    for mesh in list(bpy.data.meshes):
        bpy.data.meshes.remove(mesh)
    if file_format == "GLTF":
        # Unmerged, as the importer's default: merging orders each mesh's vertices by position,
        # so that template and target would no longer share a topology. The comparisons below
        # are by position, whatever the order.
        bpy.ops.import_scene.gltf(filepath=str(path), merge_vertices=False)
    else:
        bpy.ops.import_scene.fbx(filepath=str(path))
    bpy.context.view_layer.update()


def results(shapesmith, template, target):
    """What the tools give on a face: the packed expressions, the landmarks' world positions,
    and the transferred keys in world space ({(object, key): (N, 3)}), with the rest shapes."""
    expressions = [sorted(e["shapes"]) for e in module(shapesmith, "packing").pack_object(template)["expressions"]]
    document = module(shapesmith, "landmarks").place_landmarks(
        template, module(shapesmith, "settings").LandmarkSettings(rays=16, max_per_shape=1)
    )
    matrix = np.array(template.matrix_world)
    landmarks = np.array([l["position"] for l in document["landmarks"]]) @ matrix[:3, :3].T + matrix[:3, 3]
    assert transfer(template, target) == {"FINISHED"}
    keys = {}
    for obj in [target, *parts(target)]:
        keys[(obj.name, "rest")] = world(obj)
        for block in obj.data.shape_keys.key_blocks[1:]:
            keys[(obj.name, block.name)] = world(obj, block.name)
    return expressions, landmarks, keys


def nearest(points, to):
    """For each of `points`, the index of the nearest of `to`, and the largest distance."""
    from mathutils.kdtree import KDTree

    tree = KDTree(len(to))
    for i, p in enumerate(to):
        tree.insert(p, i)
    tree.balance()
    found = [tree.find(p) for p in points]
    return np.array([f[1] for f in found]), max(f[2] for f in found)


@pytest.mark.parametrize("file_format", ("GLTF", "FBX"))
def test_a_round_trip_through_blenders_exporter_and_importer_gives_the_same_results(
    triangulated_face, shapesmith, tmp_path, file_format
):
    face = triangulated_face
    names = [f"{prefix}{n}" for prefix in ("Tpl_", "Old_") for n in OBJECTS]
    path = tmp_path / ("face.glb" if file_format == "GLTF" else "face.fbx")
    export(path, names, file_format)
    expressions, landmarks, keys = results(shapesmith, face["template"], face["target"])

    import_only(path, file_format)
    assert {o.name for o in bpy.data.objects if o.type == "MESH"} == set(names)
    face_parts = module(shapesmith, "face_parts")
    for prefix in ("Tpl_", "Old_"):
        face_parts.store_parts(bpy.data.objects[prefix + "Head"], [bpy.data.objects[prefix + n] for n in OBJECTS[1:]])
    template, target = bpy.data.objects["Tpl_Head"], bpy.data.objects["Old_Head"]
    assert "tongueOut" in bpy.data.objects["Tpl_Teeth"].data.shape_keys.key_blocks
    imported_expressions, imported_landmarks, imported_keys = results(shapesmith, template, target)

    assert imported_expressions == expressions
    diagonal_ = diagonal(np.concatenate([v for (o, k), v in keys.items() if k == "rest"]))
    _, distance = nearest(imported_landmarks, landmarks)
    assert len(imported_landmarks) == len(landmarks) and distance <= 1e-6 * diagonal_ + 1e-7
    for obj in ("Old_" + n for n in OBJECTS):
        order, distance = nearest(imported_keys[(obj, "rest")], keys[(obj, "rest")])
        assert distance <= 1e-6 * diagonal_
        own = sorted(k for o, k in keys if o == obj)
        assert sorted(k for o, k in imported_keys if o == obj) == own, obj
        for key in own:
            error = np.abs(imported_keys[(obj, key)] - keys[(obj, key)][order]).max()
            assert error <= 1e-6 * diagonal_, f"{file_format} {obj} {key}: {error / diagonal_:.2e} of the diagonal"


def test_transferred_keys_exported_to_gltf_come_back_as_named_morph_targets(face, tmp_path):
    assert transfer(face["template"], face["target"]) == {"FINISHED"}
    targets = ["Old_" + n for n in OBJECTS]
    written = {name: [kb.name for kb in bpy.data.objects[name].data.shape_keys.key_blocks[1:]] for name in targets}
    path = tmp_path / "transferred.glb"
    export(path, targets, "GLTF")
    import_only(path, "GLTF")
    for name in targets:
        keys = bpy.data.objects[name].data.shape_keys
        assert keys is not None and [kb.name for kb in keys.key_blocks[1:]] == written[name], name
    assert "tongueOut" in written["Old_Teeth"] and len(written["Old_Head"]) == 51


def add_seam_uvs(template_objects, target_objects):
    """A cylindrical UV map around the head's vertical axis on every object, cut at the back
    (the faces across the cut take u + 1 on one side, so the vertices there have two UVs): the
    same per face corner on template and target, so that glTF splits both alike."""
    for source, target in zip(template_objects, target_objects):
        mesh = source.data
        co = positions(source)
        corners = np.empty(len(mesh.loops), dtype=np.int32)
        mesh.loops.foreach_get("vertex_index", corners)
        u = (np.arctan2(co[:, 0], -co[:, 1]) / (2 * np.pi) + 0.5)[corners]
        v = co[corners, 2]
        sizes = np.empty(len(mesh.polygons), dtype=np.int32)
        mesh.polygons.foreach_get("loop_total", sizes)
        face_of_corner = np.repeat(np.arange(len(sizes)), sizes)
        spread = np.zeros(len(sizes))
        np.maximum.at(spread, face_of_corner, u)
        low = np.full(len(sizes), 2.0)
        np.minimum.at(low, face_of_corner, u)
        across = (spread - low)[face_of_corner] > 0.5
        u = np.where(across & (u < 0.5), u + 1.0, u)
        uv = np.stack([u, v], axis=1).astype(np.float32).ravel()
        for obj in (source, target):
            obj.data.uv_layers.new(name="UVMap").data.foreach_set("uv", uv)


def test_a_seam_split_gltf_round_trip_gives_the_same_transfer(triangulated_face, shapesmith, tmp_path):
    face = triangulated_face
    templates, targets = [face["template"], *parts(face["template"])], [face["target"], *parts(face["target"])]
    add_seam_uvs(templates, targets)
    names = [o.name for o in templates + targets]
    path = tmp_path / "seams.glb"
    export(path, names, "GLTF")
    assert transfer(face["template"], face["target"]) == {"FINISHED"}
    original = {(o.name, k.name): world(o, k.name) for o in targets for k in o.data.shape_keys.key_blocks}
    counts = {o.name: len(o.data.vertices) for o in targets}

    import_only(path, "GLTF")
    assert len(bpy.data.objects["Old_Head"].data.vertices) > counts["Old_Head"]  # split along the seam
    face_parts = module(shapesmith, "face_parts")
    for prefix in ("Tpl_", "Old_"):
        face_parts.store_parts(bpy.data.objects[prefix + "Head"], [bpy.data.objects[prefix + n] for n in OBJECTS[1:]])
    assert transfer(bpy.data.objects["Tpl_Head"], bpy.data.objects["Old_Head"]) == {"FINISHED"}
    diagonal_ = diagonal(np.concatenate([v for (o, k), v in original.items() if k == "Basis"]))
    for name in counts:
        obj = bpy.data.objects[name]
        order, distance = nearest(world(obj), original[(name, "Basis")])
        assert distance <= 1e-6 * diagonal_
        for block in obj.data.shape_keys.key_blocks[1:]:
            error = np.abs(world(obj, block.name) - original[(name, block.name)][order]).max()
            assert error <= 1e-6 * diagonal_, f"{name} {block.name}: {error / diagonal_:.2e} of the diagonal"


def test_the_wrap_takes_the_templates_parts_as_its_pieces(face, shapesmith):
    """The split template wrapped onto the sample character and its keys carried there give
    the joined template's wrap and keys."""
    wrap = module(shapesmith, "wrap")
    character = bpy.data.objects["Character_YoungWoman"]
    entries = json.loads(character["shapesmith_wrap_pairs"])
    rest, _, _ = template_arrays()
    head = positions(face["template"])
    index_in_head = {tuple(p): i for i, p in enumerate(head)}
    template_points = np.array([head[index_in_head[tuple(rest[v])]] for v, _ in entries], dtype=np.float32)
    character_points = np.array([q for _, q in entries], dtype=np.float32)
    carried = {}
    for label in ("template", "joined"):
        template = face[label]
        wrapped = wrap.wrap_object(template, character, template_points, character_points)
        wrapped_object = wrap.show_wrapped(wrapped)
        result = wrap.carry_onto_character(template, character, wrapped_object)
        carried[label] = (wrapped.positions, dict(zip(result.names, result.deltas)))
        assert not result.pieces  # the character is one mesh
        wrap.remove_object(wrapped_object)
    tolerance = 1e-6 * diagonal(positions(character))
    assert np.abs(carried["template"][0] - carried["joined"][0]).max() <= 1e-6 * diagonal(head)
    assert carried["template"][1].keys() == carried["joined"][1].keys()
    for name, deltas in carried["template"][1].items():
        assert np.abs(deltas - carried["joined"][1][name]).max() <= tolerance, name


def test_keys_carried_onto_a_character_with_parts_land_on_each_of_its_objects(sample, shapesmith):
    """The sample character with its inner pieces (eyes, teeth, tongue) split off as one part
    object: each object receives the keys the character in one piece receives, on its own
    vertices (the head every key, the part the keys that move it)."""
    wrap, shape_keys = module(shapesmith, "wrap"), module(shapesmith, "shape_keys")
    character = bpy.data.objects["Character_YoungWoman"]
    template = bpy.data.objects["Template"]
    template_points, character_points = wrap.stored_pairs(character, template)
    rest = positions(character)
    faces = [list(p.vertices) for p in character.data.polygons]
    triangles = np.array([[f[0], f[i], f[i + 1]] for f in faces for i in range(1, len(f) - 1)], dtype=np.int32)
    labels = np.asarray(shapesmith.native.module().mesh_parts(len(rest), triangles)[0])
    head_vertices = np.flatnonzero(labels == np.bincount(labels).argmax())
    inner_vertices = np.flatnonzero(labels != np.bincount(labels).argmax())
    objects = []
    for name, vertices in (("Character_Head", head_vertices), ("Character_Inner", inner_vertices)):
        new_index = np.full(len(rest), -1)
        new_index[vertices] = np.arange(len(vertices))
        obj = mesh_object(name, rest[vertices], [[int(new_index[v]) for v in f] for f in faces if new_index[f[0]] >= 0])
        obj.matrix_world = character.matrix_world
        objects.append(obj)
    module(shapesmith, "face_parts").store_parts(objects[0], objects[1:])
    bpy.context.view_layer.update()

    carried = {}
    for label, obj in (("one", character), ("parts", objects[0])):
        wrapped = wrap.wrap_object(template, obj, template_points, character_points)
        wrapped_object = wrap.show_wrapped(wrapped)
        result = wrap.carry_onto_character(template, obj, wrapped_object)
        shape_keys.write_transferred_keys(result)
        wrap.remove_object(wrapped_object)
        carried[label] = result
    one = character.data.shape_keys.key_blocks
    tolerance = 1e-6 * diagonal(rest)
    head, inner = objects
    assert [kb.name for kb in head.data.shape_keys.key_blocks] == [kb.name for kb in one]
    inner_keys = [kb.name for kb in inner.data.shape_keys.key_blocks[1:]]
    assert "tongueOut" in inner_keys and "jawOpen" in inner_keys and len(inner_keys) < 52
    for obj, vertices in ((head, head_vertices), (inner, inner_vertices)):
        for block in obj.data.shape_keys.key_blocks[1:]:
            expected = positions(character, block.name)[vertices]
            error = np.abs(positions(obj, block.name) - expected).max()
            assert error <= tolerance, f"{obj.name} {block.name}: {error / diagonal(rest):.2e} of the diagonal"
        missing = [kb.name for kb in one[1:] if kb.name not in obj.data.shape_keys.key_blocks]
        for name in missing:  # a key left off a part moves nothing there
            assert np.array_equal(positions(character, name)[vertices], rest[vertices]), name
