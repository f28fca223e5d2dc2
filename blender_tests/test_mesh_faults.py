"""Faults of real-world meshes, made on the sample here. What makes an answer meaningless is
refused with a message saying why and the mesh left as it was (no faces, a non-finite
coordinate). The rest is left out of the computation and named in one report line: the
sample head with two zero-area faces, two faces listed twice (their edges then shared by
three faces), three loose vertices (one moved by a key), two loose edges and two n-gons runs
through every tool from its button and from batch, with the clean head's results on the
shared vertices (the clean head has the same n-gons, which every tool reads as Blender draws
them), and its loose vertices move with the surface under them. Also handled as documented: a
key relative to another key is read as its delta from that key, and a head posed by an
Armature modifier is read at its Basis."""

import json

import bpy
import numpy as np
import pytest

from conftest import file_digest, make_active, run_batch

# Five loose vertices for the tools: the three in no face and the two halfway points, whose
# only faces are the flat ones left out.
FAULT_WORDS = ["2 zero-area faces", "2 faces listed twice", "5 loose vertices", "2 loose edges", "triangulated: 2 n-gons"]


def positions(obj, key=None):
    data = obj.data.shape_keys.key_blocks[key].data if key else obj.data.vertices
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    data.foreach_get("co", co)
    return co.reshape(-1, 3)


def diagonal(obj):
    points = positions(obj)
    return float(np.linalg.norm(points.max(0) - points.min(0)))


def faces_of(mesh):
    return [list(polygon.vertices) for polygon in mesh.polygons]


def merged(first, second):
    """The n-gon of two faces that share one edge: `first` from the edge's far end round to
    its near end, then `second` between them."""
    shared = set(first) & set(second)
    i = next(i for i in range(len(first)) if first[i] in shared and first[(i + 1) % len(first)] in shared)
    start = first[(i + 1) % len(first)]
    ring = first[first.index(start):] + first[:first.index(start)]
    j = second.index(ring[-1])
    other = second[j:] + second[:j]
    return ring + other[1:-1]


def ngon_plan(obj):
    """Two pairs of neighbouring quads, one on each side of the head, each merged into a
    hexagon; the face list with the pairs replaced by their hexagons."""
    faces = faces_of(obj.data)
    centres = np.array([positions(obj)[f].mean(0) for f in faces])
    quads = [i for i, f in enumerate(faces) if len(f) == 4]
    by_edge = {}
    for i in quads:
        for a, b in zip(faces[i], faces[i][1:] + faces[i][:1]):
            by_edge.setdefault(frozenset((a, b)), []).append(i)
    pairs = []
    for side in (1, -1):
        pairs.append(next(tuple(p) for p in by_edge.values() if len(p) == 2 and all(side * centres[i][0] > 0.3 * np.abs(centres[:, 0]).max() for i in p)))
    gone = {i for p in pairs for i in p}
    return [f for i, f in enumerate(faces) if i not in gone] + [merged(faces[a], faces[b]) for a, b in pairs]


def rebuilt(obj, name, faces, extra_points=(), edges=(), moves=None):
    """A copy of `obj` named `name` (linked to the scene) with `faces`, `extra_points` after
    its own vertices and `edges`, built with `from_pydata` (which validates nothing, so faces
    listed twice stay); its shape keys, vertex groups and key settings copied, the extra
    points resting in every key except where `moves` ({key: (vertex, offset)}) moves them."""
    n = len(obj.data.vertices)
    points = np.concatenate([positions(obj), np.asarray(extra_points, dtype=np.float32).reshape(-1, 3)])
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(points.tolist(), list(edges), faces)
    mesh.update()
    copy = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(copy)
    copy.matrix_world = obj.matrix_world
    for group in obj.vertex_groups:
        new = copy.vertex_groups.new(name=group.name)
        for vertex in obj.data.vertices:
            for membership in vertex.groups:
                if membership.group == group.index:
                    new.add([vertex.index], membership.weight, "REPLACE")
    keys = obj.data.shape_keys
    if keys is None:
        return copy
    for block in keys.key_blocks:
        co = np.concatenate([positions(obj, block.name), points[n:]])
        if moves and block.name in moves:
            vertex, offset = moves[block.name]
            co[vertex] += offset
        new = copy.shape_key_add(name=block.name, from_mix=False)
        new.data.foreach_set("co", co.reshape(-1))
        new.value, new.vertex_group = block.value, block.vertex_group
    for block in keys.key_blocks:
        copy.data.shape_keys.key_blocks[block.name].relative_key = copy.data.shape_keys.key_blocks[block.relative_key.name]
    return copy


def with_faults(obj, name, faces):
    """(`obj` rebuilt with `faces` and, after them, the faults; its own vertex count N). The
    faults: three loose vertices (N: hovering just over a face, N + 1 and N + 2 inside the
    head), two zero-area faces (triangles on an edge's ends and a new vertex halfway along it,
    N + 3 and N + 4), the first two faces listed again (the second wound the other way), a
    loose edge between two new loose vertices and one between two far surface vertices."""
    n = len(obj.data.vertices)
    rest = positions(obj)
    centre = rest.mean(0)
    hovering_face = faces[len(faces) // 3]
    normal = np.cross(rest[hovering_face[1]] - rest[hovering_face[0]], rest[hovering_face[2]] - rest[hovering_face[0]])
    hovering = rest[hovering_face].mean(0) + 0.002 * diagonal(obj) * normal / np.linalg.norm(normal)
    edges = [(faces[7][0], faces[7][1]), (faces[90][0], faces[90][1])]
    halfway = [0.5 * (rest[a] + rest[b]) for a, b in edges]
    extra = [hovering, centre, centre + 0.01 * diagonal(obj), *halfway]
    flat = [[a, b, n + 3 + i] for i, (a, b) in enumerate(edges)]
    twice = [faces[0], faces[1][::-1]]
    far = (faces[0][0], faces[len(faces) // 2][0])
    return rebuilt(obj, name, faces + flat + twice, extra, edges=[(n + 1, n + 2), far]), n


def assert_carried(obj, faces, n, key, tolerance):
    """The loose vertices move with the surface: a halfway point as the middle of its edge,
    the hovering one within the motion of the face under it (its corners' range)."""
    delta = positions(obj, key) - positions(obj)
    for i, (a, b) in enumerate([(faces[7][0], faces[7][1]), (faces[90][0], faces[90][1])]):
        assert np.abs(delta[n + 3 + i] - 0.5 * (delta[a] + delta[b])).max() <= tolerance, key
    corners = delta[faces[len(faces) // 3]]
    assert np.all(delta[n] >= corners.min(0) - tolerance) and np.all(delta[n] <= corners.max(0) + tolerance), key


def fault_lines(lines):
    return [line for line in lines if "left out" in line]


@pytest.fixture
def heads(sample):
    """(clean head, faulty head, clean target, faulty target, N): the Template and Target_Boy
    with the same two n-gons, and each with the faults too."""
    template, boy = bpy.data.objects["Template"], bpy.data.objects["Target_Boy"]
    faces = ngon_plan(template)
    clean, clean_boy = rebuilt(template, "Clean", faces), rebuilt(boy, "CleanBoy", faces)
    faulty, n = with_faults(template, "Faulty", faces)
    faulty_boy, _ = with_faults(boy, "FaultyBoy", faces)
    # A stray key motion on the hovering loose vertex: the tools must not read it.
    block = faulty.data.shape_keys.key_blocks["jawOpen"]
    co = positions(faulty, "jawOpen")
    co[n] += (0.0, 0.0, 0.05 * diagonal(faulty))
    block.data.foreach_set("co", co.reshape(-1))
    faulty.data.update()
    return clean, faulty, clean_boy, faulty_boy, n


def test_the_report_names_each_fault_and_reading_leaves_the_mesh_as_it_was(heads, shapesmith):
    clean, faulty, _, _, n = heads
    mesh_arrays = shapesmith.blender.mesh_arrays
    before = positions(faulty).tobytes(), len(faulty.data.polygons), len(faulty.data.edges)
    note = mesh_arrays.fault_note(faulty)
    for words in FAULT_WORDS:
        assert words in note, note
    assert "3 edges shared by three or more faces" not in note, "faces listed twice are left out, not a fin"
    assert mesh_arrays.fault_note(clean) == "triangulated: 2 n-gons"
    rig = mesh_arrays.read_rig(faulty)
    assert rig.warnings == [note] and len(rig.neutral) == n + 5
    assert (positions(faulty).tobytes(), len(faulty.data.polygons), len(faulty.data.edges)) == before


def test_every_tool_from_its_button_gives_the_clean_heads_answers(heads, shapesmith):
    clean, faulty, _, _, n = heads
    blender = shapesmith.blender
    answers = {}
    for obj in (clean, faulty):
        make_active(obj)
        assert bpy.ops.shapesmith.analyze_rig() == {"FINISHED"}
        pairs = [(p.first, p.second) for p in obj.shapesmith.pairs]
        assert bpy.ops.shapesmith.pack_expressions() == {"FINISHED"}
        packed = [[m.name for m in e.members] for e in obj.shapesmith.pack.result.expressions]
        assert bpy.ops.shapesmith.place_landmarks() == {"FINISHED"}
        layout = blender.landmarks.stored_document(obj)
        vertices = [lm["vertex"] for lm in layout["landmarks"]]
        group = obj.vertex_groups.new(name="Tracked")
        group.add(vertices[::2], 1.0, "REPLACE")
        assert bpy.ops.shapesmith.score_layout(group="Tracked") == {"FINISHED"}
        score = obj.shapesmith.landmark_score
        analysis = blender.analysis.analyze_object(obj)
        answers[obj.name] = (pairs, packed, vertices, (score.mean_error, score.max_error), analysis, layout)
    (pairs, packed, vertices, score, analysis, layout) = answers["Clean"]
    (f_pairs, f_packed, f_vertices, f_score, f_analysis, f_layout) = answers["Faulty"]
    assert (f_pairs, f_packed, f_vertices) == (pairs, packed, vertices) and pairs and packed and vertices
    assert np.allclose(f_score, score, rtol=0, atol=1e-6), (f_score, score)
    assert all(v < n for v in f_vertices)
    for report in (f_analysis, f_layout):
        assert len(fault_lines(report["warnings"])) == 1, report["warnings"]
    assert not fault_lines(analysis["warnings"]) and not fault_lines(layout["warnings"])


def test_performance_solves_the_clean_heads_weights(heads, shapesmith, tmp_path):
    clean, faulty, _, _, n = heads
    performance = shapesmith.blender.performance
    rig = shapesmith.blender.mesh_arrays.read_rig(clean)
    vertices = list(range(0, n, max(1, n // 80)))
    frames = 6
    weights = np.random.default_rng(4).random((frames, len(rig.names))) * 0.6
    tracks = rig.neutral[vertices][None] + np.einsum("tk,kvc->tvc", weights, rig.deltas[:, vertices])
    names = [f"L{v}" for v in vertices]
    path = tmp_path / "tracks.csv"
    path.write_text(
        "frame," + ",".join(f"{name}_{a}" for name in names for a in "xyz") + "\n"
        + "".join(f"{t + 1}," + ",".join(f"{x:.9g}" for x in frame.reshape(-1)) + "\n" for t, frame in enumerate(tracks))
    )
    solved = {}
    for obj in (clean, faulty):
        read = performance.read_trajectories(str(path), names, vertices, 1)
        solved[obj.name] = performance.solve(obj, read)
    assert np.allclose(solved["Faulty"]["weights"], solved["Clean"]["weights"], rtol=0, atol=1e-6)
    assert len(fault_lines(solved["Faulty"]["warnings"])) == 1


def transfer(source, target):
    bpy.context.scene.shapesmith.transfer.source = source
    make_active(target)
    assert bpy.ops.shapesmith.transfer_shape_keys() == {"FINISHED"}


def test_transfer_gives_the_clean_keys_and_carries_the_loose_vertices(heads):
    clean, faulty, clean_boy, faulty_boy, n = heads
    transfer(clean, clean_boy)
    transfer(faulty, faulty_boy)
    tolerance = 1e-6 * diagonal(clean_boy)
    rest, faulty_rest = positions(clean_boy), positions(faulty_boy)
    for block in clean.data.shape_keys.key_blocks[1:]:
        expected = positions(clean_boy, block.name) - rest
        got = positions(faulty_boy, block.name) - faulty_rest
        error = float(np.abs(got[:n] - expected).max())
        assert error <= tolerance, f"{block.name}: {error} from the clean transfer (tolerance {tolerance})"
    # Not the stray motion the template's jawOpen gave the hovering vertex: the surface's.
    faces = faces_of(clean.data)
    for block in clean.data.shape_keys.key_blocks[1:]:
        assert_carried(faulty_boy, faces, n, block.name, tolerance)


def test_wrap_and_carry_onto_a_faulty_character_give_the_clean_keys(sample, shapesmith):
    template, character = bpy.data.objects["Template"], bpy.data.objects["Character_YoungWoman"]
    faces = faces_of(character.data)
    clean = rebuilt(character, "CleanCharacter", faces)
    faulty, n = with_faults(character, "FaultyCharacter", faces)
    bpy.context.scene.shapesmith.transfer.source = template
    keys = {}
    for obj in (clean, faulty):
        make_active(obj)
        assert bpy.ops.shapesmith.align_template() == {"FINISHED"}
        assert bpy.ops.shapesmith.wrap_template() == {"FINISHED"}
        assert bpy.ops.shapesmith.transfer_onto_character() == {"FINISHED"}
        rest = positions(obj)
        keys[obj.name] = {b.name: positions(obj, b.name) - rest for b in obj.data.shape_keys.key_blocks[1:]}
    tolerance = 1e-6 * diagonal(clean)
    assert keys["FaultyCharacter"].keys() == keys["CleanCharacter"].keys() and len(keys["CleanCharacter"]) == 52
    for name, expected in keys["CleanCharacter"].items():
        error = float(np.abs(keys["FaultyCharacter"][name][:n] - expected).max())
        assert error <= tolerance, f"{name}: {error} from the clean character's (tolerance {tolerance})"
    for name in ("jawOpen", "mouthSmileLeft", "eyeBlinkLeft"):
        assert_carried(faulty, faces, n, name, tolerance)


def test_batch_runs_every_tool_on_the_faulty_head_and_names_the_faults(heads, tmp_path):
    _, _, _, _, _ = heads
    path = str(tmp_path / "faulty.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path, copy=True)
    digest = file_digest(path)
    runs = {
        "analyze": ("analyze", "--input", path, "--object", "Faulty"),
        "pack": ("pack", "--input", path, "--object", "Faulty"),
        "landmarks": ("landmarks", "--input", path, "--object", "Faulty"),
        "transfer": ("transfer", "--input", path, "--source", "Faulty", "--target", "FaultyBoy", "--output", str(tmp_path / "t.blend")),
    }
    for tool, args in runs.items():
        out = tmp_path / f"{tool}.json"
        proc = run_batch(*args, "--json", str(out))
        assert proc.returncode == 0, f"{tool}: {proc.stderr}"
        text = out.read_text()
        for words in FAULT_WORDS:
            assert words in text, f"{tool}: {words!r} missing"
        json.loads(text)
    assert file_digest(path) == digest


@pytest.mark.parametrize("fault", ["no-faces", "non-finite"])
def test_what_makes_the_answer_meaningless_is_refused_and_the_mesh_left_unchanged(sample, fault):
    template = make_active(bpy.data.objects["Template"])
    if fault == "no-faces":
        template.data = bpy.data.meshes.new("Points")
        template.data.from_pydata([(0, 0, 0), (1, 0, 0), (0, 1, 0)], [], [])
        message = "has no faces: there is no surface"
    else:
        co = positions(template)
        co[5] = (np.nan, 0.0, 0.0)
        template.data.vertices.foreach_set("co", co.reshape(-1))
        template.data.shape_keys.reference_key.data.foreach_set("co", co.reshape(-1))
        message = r"1 vertices with a non-finite coordinate \(e\.g\. vertex 5\)"
    before = positions(template).tobytes(), len(template.data.polygons)
    for operator in (bpy.ops.shapesmith.analyze_rig, bpy.ops.shapesmith.pack_expressions, bpy.ops.shapesmith.place_landmarks):
        with pytest.raises(RuntimeError, match=message):
            operator()
        assert (positions(template).tobytes(), len(template.data.polygons)) == before


def packed(obj):
    make_active(obj)
    assert bpy.ops.shapesmith.pack_expressions() == {"FINISHED"}
    result = obj.shapesmith.pack.result
    return [[m.name for m in e.members] for e in result.expressions], [(c.first, c.second, c.reasons) for c in result.conflicts]


def test_a_key_relative_to_another_key_is_read_as_its_delta_from_that_key(sample, shapesmith):
    template = bpy.data.objects["Template"]
    keys = template.data.shape_keys
    smile = keys.key_blocks["mouthSmileLeft"]
    smile.relative_key = keys.key_blocks["jawOpen"]
    rig = shapesmith.blender.mesh_arrays.read_rig(template)
    n = len(template.data.vertices)
    co, base = np.empty(n * 3, np.float32), np.empty(n * 3, np.float32)
    smile.data.foreach_get("co", co)
    keys.key_blocks["jawOpen"].data.foreach_get("co", base)
    assert np.array_equal(rig.deltas[rig.names.index("mouthSmileLeft")], (co - base).reshape(n, 3))
    assert rig.warnings == []
    assert smile.relative_key.name == "jawOpen"


def test_a_head_posed_by_an_armature_is_read_at_its_basis(sample):
    template = bpy.data.objects["Template"]
    clean = packed(template)
    template.shapesmith.pack.result.done = False
    armature = bpy.data.objects.new("Rig", bpy.data.armatures.new("Rig"))
    bpy.context.scene.collection.objects.link(armature)
    make_active(armature)
    bpy.ops.object.mode_set(mode="EDIT")
    bone = armature.data.edit_bones.new("head")
    bone.head, bone.tail = (0.0, 0.0, 0.0), (0.0, 0.0, 0.1)
    bpy.ops.object.mode_set(mode="OBJECT")
    group = template.vertex_groups.new(name="head")
    group.add(list(range(len(template.data.vertices))), 1.0, "REPLACE")
    modifier = template.modifiers.new("Armature", "ARMATURE")
    modifier.object = armature
    armature.pose.bones["head"].rotation_mode = "XYZ"
    armature.pose.bones["head"].rotation_euler = (0.6, 0.0, 0.4)
    bpy.context.view_layer.update()
    evaluated = template.evaluated_get(bpy.context.evaluated_depsgraph_get()).data
    assert abs(evaluated.vertices[0].co.z - template.data.vertices[0].co.z) + abs(evaluated.vertices[0].co.y - template.data.vertices[0].co.y) > 1e-4
    assert packed(template) == clean
