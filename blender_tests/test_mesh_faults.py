"""Faults of real-world meshes, each made on the sample here: refused with a message naming
the first offender and the mesh left as it was, or handled as documented (loose edges are
ignored, a key relative to another key is read as its delta from that key, a head
posed by an Armature modifier is read at its Basis, a wrap character is only a surface)."""

import bmesh
import bpy
import numpy as np
import pytest

from conftest import file_digest, make_active, run_batch


def edit(obj, change):
    """Applies `change(bm)` to the mesh through bmesh (shape keys kept)."""
    bm = bmesh.new()
    bm.from_mesh(obj.data)
    bm.verts.ensure_lookup_table()
    bm.edges.ensure_lookup_table()
    bm.faces.ensure_lookup_table()
    change(bm)
    bm.to_mesh(obj.data)
    bm.free()
    obj.data.update()


def add_fin(bm):
    """A new triangle on an edge that already has two faces."""
    edge = next(e for e in bm.edges if len(e.link_faces) == 2)
    a, b = edge.verts
    tip = bm.verts.new((a.co + b.co) / 2 + (a.co - b.co).orthogonal())
    bm.faces.new((a, b, tip))


def add_loose_vertex(bm):
    bm.verts.new((0.0, 0.0, 0.0))


def add_zero_area_face(bm):
    corners = [bm.verts.new((0.01, 0.02, 0.03)) for _ in range(3)]
    bm.faces.new(corners)


def duplicate_first_face(obj):
    """Face 0 listed a second time (bmesh refuses to make one, and adding loops one by one
    crashes Blender 5.x): the mesh rebuilt with `from_pydata`, which does not validate, and
    its shape keys copied onto it."""
    mesh = obj.data
    count = len(mesh.vertices)
    keys = []
    for block in mesh.shape_keys.key_blocks:
        co = np.empty(count * 3, np.float32)
        block.data.foreach_get("co", co)
        keys.append((block.name, block.value, co))
    faces = [list(polygon.vertices) for polygon in mesh.polygons]
    rebuilt = bpy.data.meshes.new(mesh.name)
    rebuilt.from_pydata([vertex.co.copy() for vertex in mesh.vertices], [], faces + [faces[0]])
    obj.data = rebuilt
    for name, value, co in keys:
        block = obj.shape_key_add(name=name, from_mix=False)
        block.data.foreach_set("co", co)
        block.value = value


def state(obj):
    """What a refused tool must leave as it was."""
    mesh = obj.data
    co = np.empty(len(mesh.vertices) * 3, np.float32)
    mesh.vertices.foreach_get("co", co)
    return len(mesh.vertices), len(mesh.polygons), co.tobytes(), len(mesh.shape_keys.key_blocks), obj.shapesmith.pack.result.done


FAULTS = {
    "non-manifold-edge": (lambda obj: edit(obj, add_fin), r"edge\(s\) shared by three or more faces \(e\.g\. the edge between vertices \d+ and \d+\)"),
    "loose-vertex": (lambda obj: edit(obj, add_loose_vertex), r"1 loose vertices in no face \(e\.g\. vertex \d+\).*Delete Loose"),
    "zero-area-face": (lambda obj: edit(obj, add_zero_area_face), r"degenerate faces of zero area \(1 triangle\(s\); e\.g\. face \d+\)"),
    "duplicate-face": (duplicate_first_face, r"faces listed twice .*e\.g\. face \d+ repeats face 0"),
}


@pytest.mark.parametrize("fault", FAULTS, ids=list(FAULTS))
def test_a_faulty_mesh_is_refused_by_every_tool_and_left_unchanged(sample, fault):
    make_fault, message = FAULTS[fault]
    template = make_active(bpy.data.objects["Template"])
    make_fault(template)
    before = state(template)
    for operator in (bpy.ops.shapesmith.analyze_rig, bpy.ops.shapesmith.pack_expressions, bpy.ops.shapesmith.place_landmarks):
        with pytest.raises(RuntimeError, match=message):
            operator()
        assert state(template) == before


def test_the_named_offender_is_the_fault(sample, shapesmith):
    """The vertex and the edge the messages name are the ones the fault made."""
    template = bpy.data.objects["Template"]
    count = len(template.data.vertices)
    edit(template, add_loose_vertex)
    with pytest.raises(ValueError, match=f"vertex {count}\\)"):
        shapesmith.blender.mesh_arrays.check_mesh(template)


def test_batch_refuses_a_faulty_file_with_one_line_and_leaves_it_unchanged(sample, tmp_path):
    template = bpy.data.objects["Template"]
    edit(template, add_fin)
    path = str(tmp_path / "fin.blend")
    bpy.ops.wm.save_as_mainfile(filepath=path, copy=True)
    digest = file_digest(path)
    proc = run_batch("pack", "--input", path, "--object", "Template")
    lines = proc.stderr.strip().splitlines()
    assert proc.returncode == 2 and len(lines) == 1 and lines[0].startswith("shapesmith: error: 'Template' has 1 edge(s)"), proc.stderr
    assert file_digest(path) == digest


def test_a_wrap_character_with_a_loose_vertex_is_fitted_and_gets_keys(sample, shapesmith):
    """A character is a surface to fit: a loose vertex (a cut or an import can leave one) is
    not refused, and the carry gives it the delta at its closest point on the wrapped
    template (it made the carry's system singular: a SolverError after the work)."""
    wrap, shape_keys = shapesmith.blender.wrap, shapesmith.blender.shape_keys
    template, character = bpy.data.objects["Template"], bpy.data.objects["Character_YoungWoman"]
    count = len(character.data.vertices)
    edit(character, add_loose_vertex)
    assert len(character.data.vertices) == count + 1
    template_points, character_points = wrap.stored_pairs(character, template)
    wrapped = wrap.wrap_object(template, character, template_points, character_points)
    result = wrap.carry_onto_character(template, character, wrap.show_wrapped(wrapped))
    written, _, _ = shape_keys.write_transferred_keys(result)
    assert len(written) == 52 and np.isfinite(result.deltas).all()


def packed(obj):
    make_active(obj)
    assert bpy.ops.shapesmith.pack_expressions() == {"FINISHED"}
    result = obj.shapesmith.pack.result
    return [[m.name for m in e.members] for e in result.expressions], [(c.first, c.second, c.reasons) for c in result.conflicts]


def test_a_loose_edge_is_ignored(sample):
    template = bpy.data.objects["Template"]
    clean = packed(template)
    template.shapesmith.pack.result.done = False

    def add_loose_edge(bm):
        a = bm.verts[0]
        neighbours = {e.other_vert(a).index for e in a.link_edges} | {a.index}
        b = next(v for v in bm.verts if v.index not in neighbours and v.link_faces)
        bm.edges.new((a, b))

    edit(template, add_loose_edge)
    bm = bmesh.new()
    bm.from_mesh(template.data)
    assert sum(not e.link_faces for e in bm.edges) == 1
    bm.free()
    assert packed(template) == clean


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
