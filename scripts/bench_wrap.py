"""Wrap benchmark (method, section 5), run with the bpy Python:

    python scripts/bench_wrap.py [-- --json OUT.json] [--proposals-only]

Characters of other topology with a known answer: the identity head Target_OldMan subdivided
and collapse-decimated to about 10k and 25k vertices, in centimetres with Y up, paired with
the template at 10 vertices known by construction. For each: seconds per stage of the whole
chain (io, align, wrap, transfer onto the wrapped template, carry onto the character), the
fit (mean and max distance to the character, / bbox diagonal), and the error of the keys
against the same-topology transfer onto the undecimated head sampled at the character's
vertices (mean over shapes of the mean error on vertices moving more than 1e-3 of the
diagonal, / diagonal), beside the nearest-vertex and plain barycentric copies of the
wrapped template's keys measured in the same run, and the fit's floor (the same-topology
keys copied from where the fit put each template vertex, as if the transfer onto the wrapped
template were exact: the error the fit's slide along the surface alone causes); and the
keys' roughness (mean norm of the uniform Laplacian of the deltas on moving vertices, /
diagonal); and the shapes of the carried keys that add more intersection curve to the
character's neutral than the template's shape allows (the criterion of method, section 3, excess over 1e-3
of the diagonal), with the carry's collision pass (the chain's default) and
without it (the plain carry of the same wrapped keys, timed in the same run).

Symmetry (the identity is mirror-symmetric across x = 0, so the characters are across the
image of that plane): per mirror pair of shapes (as the carry paired them), the worst vertex's
miss between the mirror of one carried key and the other, in % of the larger one's largest
motion, each vertex's image at its closest point on the character's skin facing its mirrored
normal's way (`mirror_misses`), beside the same measure of the barycentric copy of the
wrapped template's keys (what it reads for keys as symmetric as the wrapped template's on a
mesh whose triangles are not mirrored), and of the chain fitted and carried as if nothing
were symmetric (`ignore_symmetry`), with its shapes worse and its error.

Perfect alignment (`run_perfect`): the template collapse-decimated to half its faces, in the
character frame, the template itself placed exactly on it as the wrapped template and its own
keys carried: the carry's error against the template's keys sampled at the character's
vertices, beside the nearest-vertex copy's (no fit error in either).

Proposals (`run_proposals`; `-- --proposals-only` runs them alone): point pairs proposed (no
click) on the sample character and on a glTF avatar copy of it (metres, each piece an
object), each also with its eye sockets cut open at the lids as an avatar's are (and the
first also decimated to about 1.1k vertices): each proposed point's distance from where its
template point truly lies, the pieces and openings matched, and the keys' error from proposed
against hand pairs.
"""

import argparse
import os
import sys
import time

import bpy
import bmesh  # noqa: I001  (bmesh loads only after bpy)
import numpy as np

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
import batch  # noqa: E402
import makehuman  # noqa: E402
from wrap_copies import barycentric_copy, moving_error, nearest_vertex_copy  # noqa: E402

IDENTITY = "Target_OldMan"
SIZES = {"10k": 10_000, "25k": 25_000}
SCALE, SHIFT = 100.0, np.array([5.0, 160.0, -3.0])  # centimetres, Y up, moved
# An avatar's lid holes: the skin within this many eyeball radii of each eyeball cut away.
LID_HOLE_RADII = 1.15
# A coarser avatar: the sample character decimated to this share of its faces.
COARSE_RATIO = 0.45


def to_character(points):
    return makehuman.character_frame(points, SCALE) + SHIFT


def positions(obj):
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", co)
    return co.reshape(-1, 3).astype(np.float64)


def build_character(identity, name, vertices):
    """The identity subdivided (bmesh, one cut per edge, grid fill) until it has more than
    `vertices`, then collapse-decimated to about that many, moved into the character frame."""
    mesh = bmesh.new()
    mesh.from_mesh(identity.data)
    while len(mesh.verts) < vertices:
        bmesh.ops.subdivide_edges(mesh, edges=mesh.edges[:], cuts=1, use_grid_fill=True)
    data = bpy.data.meshes.new(name)
    mesh.to_mesh(data)
    mesh.free()
    obj = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(obj)
    decimate(obj, vertices / len(data.vertices))
    obj.data.vertices.foreach_set("co", to_character(positions(obj)).astype(np.float32).ravel())
    obj.data.update()
    return obj


def decimate(obj, ratio):
    """`obj`'s mesh collapse-decimated to `ratio` of its faces (Blender's Decimate modifier,
    applied)."""
    obj.modifiers.new("Decimate", "DECIMATE").ratio = ratio
    decimated = bpy.data.meshes.new_from_object(obj.evaluated_get(bpy.context.evaluated_depsgraph_get()))
    obj.modifiers.clear()
    obj.data = decimated


def roughness(deltas, edges, reference, diagonal):
    """Mean norm of the uniform Laplacian of the deltas on moving vertices, / diagonal."""
    n = deltas.shape[1]
    degree = np.bincount(edges.ravel(), minlength=n).astype(np.float64)
    values = []
    for est, ref in zip(deltas, reference):
        summed = np.zeros((n, 3))
        np.add.at(summed, edges[:, 0], est[edges[:, 1]])
        np.add.at(summed, edges[:, 1], est[edges[:, 0]])
        laplacian = summed / np.maximum(degree, 1)[:, None] - est
        moving = np.linalg.norm(ref, axis=1) > 1e-3 * diagonal
        if moving.any():
            values.append(np.linalg.norm(laplacian[moving], axis=1).mean() / diagonal)
    return float(np.mean(values))


def vertex_normals(points, triangles):
    """Area-weighted vertex normals, unit length."""
    face = np.cross(points[triangles[:, 1]] - points[triangles[:, 0]], points[triangles[:, 2]] - points[triangles[:, 0]])
    normals = np.zeros_like(points)
    for corner in range(3):
        np.add.at(normals, triangles[:, corner], face)
    return normals / np.maximum(np.linalg.norm(normals, axis=1), 1e-30)[:, None]


def mirror_misses(nat, points, triangles, keys, names, pairs):
    """Per pair (first, second) of `names`, the worst skin vertex's miss between the mirror of
    key `first` and key `second` (`keys`: (K, N, 3) on `points`), / the larger largest motion
    on the skin; mirrored across the character frame's image of x = 0, each skin vertex's image
    at its closest point on the skin facing the mirrored normal's way (barycentric; the skin
    only, so that a lid's image never lands on an eyeball, and facing, so that an upper lip's
    image at the lips' contact never lands on the lower lip)."""
    normal = np.array([1.0, 0.0, 0.0])
    skin = makehuman.largest_piece(len(points), [tuple(t) for t in triangles])
    on_skin = np.zeros(len(points), dtype=bool)
    on_skin[skin] = True
    skin_triangles = triangles[on_skin[triangles[:, 0]]]
    reflect = lambda v: v - 2.0 * (v @ normal)[:, None] * normal  # noqa: E731
    images = reflect(points[skin] - SHIFT) + SHIFT
    image_normals = reflect(vertex_normals(points, triangles)[skin])
    triangle, barycentric, _ = nat.bind_to_surface(
        np.ascontiguousarray(images, dtype=np.float32), np.ascontiguousarray(points, dtype=np.float32), skin_triangles,
        normals=np.ascontiguousarray(image_normals, dtype=np.float32),
    )
    misses = {}
    for first, second in pairs:
        a, b = keys[names.index(first)], keys[names.index(second)]
        mirrored = reflect(np.einsum("vc,vcx->vx", barycentric, a[skin_triangles[triangle]]))
        largest = max(np.linalg.norm(a[skin], axis=1).max(), np.linalg.norm(b[skin], axis=1).max())
        misses[first if first == second else f"{first}/{second}"] = float(np.linalg.norm(mirrored - b[skin], axis=1).max() / max(largest, 1e-30))
    return misses


def run_size(shapesmith, label, vertices, truth):
    from importlib import import_module

    wrap = import_module(shapesmith.__name__ + ".blender.wrap")
    mesh_arrays = import_module(shapesmith.__name__ + ".blender.mesh_arrays")
    transfer = import_module(shapesmith.__name__ + ".blender.transfer")
    settings = import_module(shapesmith.__name__ + ".blender.settings")
    nat = shapesmith.native.module()
    template, identity = bpy.data.objects["Template"], bpy.data.objects[IDENTITY]
    character = build_character(identity, f"Character_{label}", vertices)
    skin = makehuman.largest_piece(len(template.data.vertices), [tuple(p.vertices) for p in template.data.polygons])
    pair_vertices = makehuman.pair_vertices(positions(template), skin)
    entries = [[int(v), [float(x) for x in q]] for v, q in zip(pair_vertices, to_character(positions(identity)[pair_vertices]))]
    started = time.perf_counter()
    template_points, character_points = wrap.pairs_from_list(entries, template, character)
    wrapped = wrap.wrap_object(template, character, template_points, character_points)
    wrapped_object = wrap.show_wrapped(wrapped)
    shown = time.perf_counter()
    result = wrap.carry_onto_character(template, character, wrapped_object, seconds=wrapped.seconds)
    total = time.perf_counter() - started
    seconds = dict(result.report["stage_seconds"])
    seconds["picture"] = shown - started - sum(wrapped.seconds.values())
    seconds["total"] = total
    diagonal = wrapped.report["diagonal"]
    # The same-topology result sampled at the character's vertices (back in the identity's frame).
    points = positions(character)
    identity_frame = (points - SHIFT) / SCALE
    identity_frame = np.stack([identity_frame[:, 0], -identity_frame[:, 2], identity_frame[:, 1]], axis=1)
    identity_triangles = mesh_arrays.read_triangles(identity)
    reference = barycentric_copy(nat, identity_frame, positions(identity), identity_triangles, truth)
    reference = np.stack([makehuman.character_frame(r, SCALE) for r in reference])
    wrapped_positions = positions(wrapped_object)
    wrapped_deltas = transfer.transfer_object(template, wrapped_object).deltas.astype(np.float64)
    # The same keys carried without the collision pass, judged on the character as the pass
    # judges (so both times include the sweep of every shape).
    plain_report = {k: v for k, v in result.report.items() if k != "carry"}
    plain_report["penetration"] = result.report["wrapped_penetration"]
    plain_started = time.perf_counter()
    plain, plain_carry = nat.carry_shapes(
        np.ascontiguousarray(wrapped_positions, dtype=np.float32),
        mesh_arrays.read_triangles(wrapped_object),
        np.ascontiguousarray(wrapped_deltas, dtype=np.float32),
        np.ascontiguousarray(points, dtype=np.float32),
        mesh_arrays.read_triangles(character),
        {"collision_pass": False},
        **wrap.template_curve(plain_report),
    )
    plain_seconds = time.perf_counter() - plain_started
    copies = {
        "carry": result.deltas.astype(np.float64),
        "plain carry": plain.astype(np.float64),
        "nearest vertex": nearest_vertex_copy(wrapped_positions, wrapped_deltas, points),
        "barycentric": barycentric_copy(nat, points, wrapped_positions, mesh_arrays.read_triangles(wrapped_object), wrapped_deltas),
    }
    # The fit's floor: the same-topology keys themselves (template vertex order) copied from
    # where the fit put each template vertex, as if the transfer onto the wrapped template
    # were exact; what is left is where the fit slid the template along the surface.
    true_keys = np.stack([makehuman.character_frame(r, SCALE) for r in truth])
    fit_floor = barycentric_copy(nat, points, wrapped_positions, mesh_arrays.read_triangles(wrapped_object), true_keys)
    edges = np.array([tuple(e.vertices) for e in character.data.edges])
    row = {
        "vertices": len(points),
        "template_vertices": len(wrapped_positions),
        "seconds": seconds,
        "fit": {k: wrapped.report[k] for k in ("mean_distance", "max_distance", "pair_residuals", "fit")},
        "error": {name: moving_error(d, reference, diagonal) for name, d in copies.items()},
        "fit_floor": moving_error(fit_floor, reference, diagonal),
        "roughness": {name: roughness(d, edges, reference, diagonal) for name, d in copies.items()},
    }
    row["roughness"]["same-topology (sampled)"] = roughness(reference, edges, reference, diagonal)
    plain_rows = wrap.character_rows(plain_report, plain_carry["penetration"])
    row["worse"] = {name: worse_than_template(rows, diagonal) for name, rows in (("carry", result.report["penetration"]), ("plain carry", plain_rows))}
    row["carry_seconds"] = {"carry": seconds["carry"], "plain carry": plain_seconds}
    # Symmetry: the chain's keys and the barycentric copy, then the chain as if nothing were
    # symmetric, each measured alike.
    names = list(result.names)
    symmetry = result.report["symmetry"]
    pairs = [(r["first_name"], r["second_name"]) for r in symmetry["shapes"]]
    triangles = mesh_arrays.read_triangles(character)
    misses = {
        "carry": mirror_misses(nat, points, triangles, copies["carry"], names, pairs),
        "barycentric": mirror_misses(nat, points, triangles, copies["barycentric"], names, pairs),
    }
    wrap.remove_object(wrapped_object)
    unsymmetric = wrap.wrap_object(template, character, template_points, character_points,
                                   settings.WrapSettings(ignore_symmetry=True))
    unsymmetric_object = wrap.show_wrapped(unsymmetric)
    unsymmetric_result = wrap.carry_onto_character(template, character, unsymmetric_object, symmetric=False)
    misses["carry without symmetry"] = mirror_misses(nat, points, triangles, unsymmetric_result.deltas.astype(np.float64), names, pairs)
    row["symmetry"] = {
        "fit": wrapped.report["symmetry"],
        "carry": symmetry,
        "misses": misses,
        "worse without symmetry": worse_than_template(unsymmetric_result.report["penetration"], diagonal),
        "error without symmetry": moving_error(unsymmetric_result.deltas.astype(np.float64), reference, diagonal),
    }
    wrapped_object = unsymmetric_object
    # What the carry's collision pass did to each shape it acted on.
    names = [r["name"] for r in result.report["penetration"]]
    row["carry_collisions"] = {n: c for n, c in zip(names, result.report["carry"].get("collisions", [])) if c["plain_excess"] > 0}
    wrap.remove_object(wrapped_object)
    return row


def run_sample(shapesmith):
    """The sample's Character_YoungWoman (Target_YoungWoman decimated to 45%, centimetres, Y
    up, its stored pairs): shapes worse with the chain's defaults, without the carry's pass and
    without symmetry; the mirror misses as the carry reports them; the keys' error against the
    same-topology transfer onto Target_YoungWoman sampled at its vertices."""
    from importlib import import_module

    wrap = import_module(shapesmith.__name__ + ".blender.wrap")
    mesh_arrays = import_module(shapesmith.__name__ + ".blender.mesh_arrays")
    transfer = import_module(shapesmith.__name__ + ".blender.transfer")
    settings = import_module(shapesmith.__name__ + ".blender.settings")
    nat = shapesmith.native.module()
    template, character, identity = (bpy.data.objects[n] for n in ("Template", "Character_YoungWoman", "Target_YoungWoman"))
    truth = transfer.transfer_object(template, identity).deltas.astype(np.float64)
    points = positions(character)
    back = points / 100.0
    back = np.stack([back[:, 0], -back[:, 2], back[:, 1]], axis=1)
    reference = barycentric_copy(nat, back, positions(identity), mesh_arrays.read_triangles(identity), truth)
    reference = np.stack([makehuman.character_frame(r, 100.0) for r in reference])
    row = {}
    for label, symmetric in (("symmetric", True), ("without symmetry", False)):
        template_points, character_points = wrap.stored_pairs(character, template)
        wrapped = wrap.wrap_object(template, character, template_points, character_points,
                                   settings.WrapSettings(ignore_symmetry=not symmetric))
        wrapped_object = wrap.show_wrapped(wrapped)
        result = wrap.carry_onto_character(template, character, wrapped_object, symmetric=symmetric)
        diagonal = wrapped.report["diagonal"]
        row[label] = {
            "worse": worse_than_template(result.report["penetration"], diagonal),
            "error": moving_error(result.deltas.astype(np.float64), reference, diagonal),
            "nearest vertex error": moving_error(
                nearest_vertex_copy(positions(wrapped_object), transfer.transfer_object(template, wrapped_object).deltas, points), reference, diagonal
            ),
            "symmetry": result.report["symmetry"],
        }
        wrap.remove_object(wrapped_object)
    return row


def key_error(shapesmith, character, entries, reference):
    """The whole chain with point pairs `entries`: (error of the carried keys against
    `reference` (K, N, 3) on moving vertices / diagonal, the fit report)."""
    from importlib import import_module

    wrap = import_module(shapesmith.__name__ + ".blender.wrap")
    template = bpy.data.objects["Template"]
    template_points, character_points = wrap.pairs_from_list(entries, template, character)
    wrapped = wrap.wrap_object(template, character, template_points, character_points)
    wrapped_object = wrap.show_wrapped(wrapped)
    result = wrap.carry_onto_character(template, character, wrapped_object)
    wrap.remove_object(wrapped_object)
    return moving_error(result.deltas.astype(np.float64), reference, wrapped.report["diagonal"]), wrapped.report


def proposal_row(shapesmith, character, true_point, reference=None):
    """Pairs proposed on `character` against the truth: per pair the distance of its character
    point from `true_point(template vertex)` (the template point's true place, character
    space) / diagonal; the pieces and openings the wrap matched with the hand pairs (exact by
    construction: template vertex -> its true place) and with the proposed ones; with
    `reference` (the same-topology keys sampled at the character's vertices), the keys' error
    from each."""
    from importlib import import_module

    wrap = import_module(shapesmith.__name__ + ".blender.wrap")
    template = bpy.data.objects["Template"]
    started = time.perf_counter()
    proposal = wrap.propose_pairs(template, character)
    seconds = time.perf_counter() - started
    points = positions(character)
    diagonal = float(np.linalg.norm(points.max(0) - points.min(0)))
    distances = {p["name"]: float(np.linalg.norm(np.array(p["character"]) - true_point(p["template_vertex"])) / diagonal) for p in proposal["pairs"]}
    skin = makehuman.largest_piece(len(template.data.vertices), [tuple(p.vertices) for p in template.data.polygons])
    hand = [[int(v), [float(x) for x in true_point(v)]] for v in makehuman.pair_vertices(positions(template), skin)]
    proposed = [[p["template_vertex"], p["character_vertex"]] for p in proposal["pairs"]]
    row = {"seconds": seconds, "pairs": len(proposed), "missing": proposal["missing"], "distances": distances,
           "median_distance": float(np.median(list(distances.values()))), "max_distance": max(distances.values())}
    for label, entries in (("hand", hand), ("proposed", proposed)):
        if reference is not None:
            error, report = key_error(shapesmith, character, entries, reference)
            row[f"{label}_key_error"] = error
        else:
            template_points, character_points = wrap.pairs_from_list(entries, template, character)
            report = wrap.wrap_object(template, character, template_points, character_points).report
        row[f"{label}_matches"] = {"pieces": report["pieces"], "pieces_fitted": report["pieces_fitted"],
                                   "holes_paired": report["holes_paired"], "lines": wrap.match_lines(report)}
    return row


def piece_labels(shapesmith, obj):
    """Per vertex of `obj`, the loose piece it belongs to (the add-on's `mesh_parts`)."""
    from importlib import import_module

    landmarks = import_module(shapesmith.__name__ + ".blender.landmarks")
    return np.asarray(landmarks.mesh_parts(obj)["part_of_vertex"])


def gltf_character(shapesmith, source):
    """`source` (one mesh with its pieces) as an avatar export brings it: each piece an object
    of its own, in metres and the scene's axes, through Blender's glTF exporter (Y up in the
    file) and importer, the parts listed on the head. Returns (head, 4x4 matrix taking
    `source`-local points to the head's local space)."""
    from importlib import import_module

    face_parts = import_module(shapesmith.__name__ + ".blender.face_parts")
    rest = positions(source)
    faces = [list(p.vertices) for p in source.data.polygons]
    labels = piece_labels(shapesmith, source)
    order = np.argsort(-np.bincount(labels), kind="stable")
    exported = []
    for rank, piece in enumerate(order):
        vertices = np.flatnonzero(labels == piece)
        index = np.full(len(rest), -1)
        index[vertices] = np.arange(len(vertices))
        mesh = bpy.data.meshes.new(f"Avatar_{rank}")
        mesh.from_pydata(rest[vertices].tolist(), [], [[int(index[v]) for v in f] for f in faces if index[f[0]] >= 0])
        mesh.shade_smooth()
        mesh.transform(source.matrix_world)
        obj = bpy.data.objects.new("Avatar_Head" if rank == 0 else f"Avatar_Piece{rank}", mesh)
        bpy.context.scene.collection.objects.link(obj)
        exported.append(obj)
    bpy.ops.object.select_all(action="DESELECT")
    for obj in exported:
        obj.select_set(True)
    bpy.context.view_layer.objects.active = exported[0]
    path = os.path.join(os.path.dirname(batch.cached_sample_path()), "bench", "avatar.glb")
    os.makedirs(os.path.dirname(path), exist_ok=True)
    bpy.ops.export_scene.gltf(filepath=path, export_format="GLB", use_selection=True, export_animations=False)
    for obj in exported:
        bpy.data.objects.remove(obj)
    bpy.ops.import_scene.gltf(filepath=path)
    imported = [o for o in bpy.context.selected_objects if o.type == "MESH"]
    head = max(imported, key=lambda o: len(o.data.vertices))
    face_parts.store_parts(head, [o for o in imported if o != head])
    bpy.context.view_layer.update()
    return head, np.array(head.matrix_world.inverted()) @ np.array(source.matrix_world)


def open_lids(shapesmith, obj, radii=LID_HOLE_RADII):
    """Cuts `obj`'s eye sockets open at the lids, as an avatar's are (its eyes seen through
    holes in the skin): the skin (its largest piece) within `radii` eyeball radii of each
    eyeball removed, the eyeballs its two largest round pieces (vertices' distances from the
    piece's centre varying by under 15% of their mean). Returns the vertices removed."""
    rest = positions(obj)
    labels = piece_labels(shapesmith, obj)
    skin = np.argmax(np.bincount(labels))
    balls = []
    for piece in set(labels.tolist()) - {skin}:
        members = rest[labels == piece]
        distance = np.linalg.norm(members - members.mean(0), axis=1)
        if len(members) >= 8 and distance.std() < 0.15 * distance.mean():
            balls.append((distance.mean(), members.mean(0)))
    cut = np.zeros(len(rest), dtype=bool)
    for radius, centre in sorted(balls, key=lambda b: -b[0])[:2]:
        cut |= (labels == skin) & (np.linalg.norm(rest - centre, axis=1) < radii * radius)
    mesh = bmesh.new()
    mesh.from_mesh(obj.data)
    mesh.verts.ensure_lookup_table()
    bmesh.ops.delete(mesh, geom=[mesh.verts[int(v)] for v in np.flatnonzero(cut)], context="VERTS")
    mesh.to_mesh(obj.data)
    mesh.free()
    obj.data.update()
    return int(cut.sum())


def young_reference(shapesmith, character, young_truth):
    """The same-topology keys onto Target_YoungWoman sampled at `character`'s vertices (a copy
    of the sample character, in its frame): the truth its carried keys are measured against."""
    from importlib import import_module

    mesh_arrays = import_module(shapesmith.__name__ + ".blender.mesh_arrays")
    identity = bpy.data.objects["Target_YoungWoman"]
    scale = makehuman.CHARACTERS["Character_YoungWoman"]["scale"]
    back = positions(character) / scale
    back = np.stack([back[:, 0], -back[:, 2], back[:, 1]], axis=1)
    reference = barycentric_copy(shapesmith.native.module(), back, positions(identity), mesh_arrays.read_triangles(identity), young_truth)
    return np.stack([makehuman.character_frame(r, scale) for r in reference])


def run_proposals(shapesmith, young_truth):
    """Proposed against hand pairs on the sample character (keys against the same-topology
    transfer onto Target_YoungWoman), on its glTF avatar copy in metres with separate pieces
    (pairs and matches only), and on both with the eye sockets open at the lids (`open_lids`),
    the first also decimated to about half its vertices."""
    character = bpy.data.objects["Character_YoungWoman"]
    identity_points = positions(bpy.data.objects["Target_YoungWoman"])
    scale = makehuman.CHARACTERS["Character_YoungWoman"]["scale"]
    true_point = lambda v: makehuman.character_frame(identity_points[[v]], scale)[0]  # noqa: E731
    opened, coarse = character.copy(), character.copy()
    for obj, name in ((opened, "Character_YoungWoman_LidsOpen"), (coarse, "Character_YoungWoman_Coarse")):
        obj.data = character.data.copy()
        obj.name = name
        bpy.context.scene.collection.objects.link(obj)
    decimate(coarse, COARSE_RATIO)
    for obj in (opened, coarse):
        open_lids(shapesmith, obj)
    rows = {}
    for label, obj in (("Character_YoungWoman", character), (f"the same, lids open ({LID_HOLE_RADII} eyeball radii cut)", opened),
                       (f"the same, lids open, decimated to {len(coarse.data.vertices)} vertices", coarse)):
        rows[label] = proposal_row(shapesmith, obj, true_point, young_reference(shapesmith, obj, young_truth))
    for label, obj in (("glTF avatar (metres, separate pieces)", character), ("glTF avatar, lids open", opened)):
        head, to_head = gltf_character(shapesmith, obj)
        rows[label] = proposal_row(shapesmith, head, lambda v, to_head=to_head: (to_head @ np.append(true_point(v), 1.0))[:3])
    return rows


def run_perfect(shapesmith):
    """The template's own keys carried onto its collapse-decimated copy (half the faces, in the
    character frame) from the template itself placed exactly there: the carry's error against
    the keys sampled at the copy's vertices (barycentric at the closest point), beside the
    nearest-vertex copy's."""
    from importlib import import_module

    mesh_arrays = import_module(shapesmith.__name__ + ".blender.mesh_arrays")
    nat = shapesmith.native.module()
    template = bpy.data.objects["Template"]
    rest = positions(template)
    names = [block.name for block in template.data.shape_keys.key_blocks[1:]]
    keys = np.stack([makehuman.character_frame(block_positions(template, name) - rest, SCALE) for name in names])
    copy = template.copy()
    copy.data = template.data.copy()
    bpy.context.scene.collection.objects.link(copy)
    copy.shape_key_clear()
    copy.modifiers.new("Decimate", "DECIMATE").ratio = 0.5
    decimated = bpy.data.meshes.new_from_object(copy.evaluated_get(bpy.context.evaluated_depsgraph_get()))
    copy.modifiers.clear()
    copy.data = decimated
    points = to_character(positions(copy))
    placed = to_character(rest)
    triangles, copy_triangles = mesh_arrays.read_triangles(template), mesh_arrays.read_triangles(copy)
    diagonal = float(np.linalg.norm(points.max(0) - points.min(0)))
    carried, _ = nat.carry_shapes(
        np.ascontiguousarray(placed, dtype=np.float32), triangles, np.ascontiguousarray(keys, dtype=np.float32),
        np.ascontiguousarray(points, dtype=np.float32), copy_triangles,
    )
    reference = barycentric_copy(nat, points, placed, triangles, keys)
    copies = {"carry": carried.astype(np.float64), "nearest vertex": nearest_vertex_copy(placed, keys, points)}
    return {"vertices": len(points), "error": {name: moving_error(d, reference, diagonal) for name, d in copies.items()}}


def block_positions(obj, name):
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.shape_keys.key_blocks[name].data.foreach_get("co", co)
    return co.reshape(-1, 3).astype(np.float64)


def worse_than_template(rows, diagonal):
    """The shapes whose excess over the template (both parts, the criterion of method, section 3) is over
    1e-3 of the diagonal, name -> excess / diagonal."""
    excess = {row["name"]: (row["excess"]["inside"] + row["excess"]["between"]) / diagonal for row in rows}
    return {name: e for name, e in excess.items() if e > 1e-3}


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="bench_wrap.py --")
    cache = os.environ.get("SHAPESMITH_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "shapesmith"))
    parser.add_argument("--json", default=os.path.join(cache, "bench", "bench_wrap.json"))
    parser.add_argument("--proposals-only", action="store_true", help="only the proposed-pairs comparison")
    args = parser.parse_args(argv)
    shapesmith = batch.load_shapesmith()
    from importlib import import_module

    transfer = import_module(shapesmith.__name__ + ".blender.transfer")
    bpy.ops.wm.open_mainfile(filepath=batch.cached_sample())
    result = {}
    if not args.proposals_only:
        truth = transfer.transfer_object(bpy.data.objects["Template"], bpy.data.objects[IDENTITY]).deltas.astype(np.float64)
        result = {label: run_size(shapesmith, label, vertices, truth) for label, vertices in SIZES.items()}
        perfect = run_perfect(shapesmith)
        sample = run_sample(shapesmith)
    young_truth = transfer.transfer_object(bpy.data.objects["Template"], bpy.data.objects["Target_YoungWoman"]).deltas.astype(np.float64)
    proposals = run_proposals(shapesmith, young_truth)
    print("\n== Wrap + transfer + carry onto a character of other topology (seconds, one run, 2 cores)")
    for label, row in result.items():
        s = row["seconds"]
        print(
            f"  {label}: {row['vertices']} character vertices ({row['template_vertices']} template): "
            + ", ".join(f"{k} {v:.3f}" for k, v in s.items())
        )
        fit = row["fit"]
        print(
            f"    fit: mean {100 * fit['mean_distance']:.3f}% / max {100 * fit['max_distance']:.2f}% of the diagonal; "
            f"largest pair residual {100 * max(fit['pair_residuals']):.3f}%"
        )
        print("    error vs same-topology transfer: " + ", ".join(f"{k} {v:.2e}" for k, v in row["error"].items()))
        print(f"    the fit's floor (same-topology keys copied from the wrapped template, no transfer): {row['fit_floor']:.2e}")
        print("    roughness (Laplacian of deltas): " + ", ".join(f"{k} {v:.2e}" for k, v in row["roughness"].items()))
        for name, worse in row["worse"].items():
            print(
                f"    {name}: {len(worse)} shapes worse than the template, excess {sum(worse.values()):.4f} of the diagonal, "
                f"{row['carry_seconds'][name]:.3f} s: " + ", ".join(f"{k} {v:.4f}" for k, v in sorted(worse.items()))
            )
        misses = row["symmetry"]["misses"]
        print(f"    symmetry: fit {row['symmetry']['fit']['symmetric']}, carry {row['symmetry']['carry']['symmetric']}; "
              "worst-vertex mirror miss, % of the largest motion (carry / barycentric copy / carry without symmetry):")
        for pair in misses["carry"]:
            print(f"      {pair}: " + " / ".join(f"{100 * misses[k][pair]:.1f}" for k in ("carry", "barycentric", "carry without symmetry")))
        print(f"    without symmetry: {len(row['symmetry']['worse without symmetry'])} shapes worse "
              f"({', '.join(sorted(row['symmetry']['worse without symmetry']))}), error {row['symmetry']['error without symmetry']:.2e}")
    if not args.proposals_only:
        print(f"\n== Perfect alignment: the template's keys carried onto its decimated copy ({perfect['vertices']} vertices)")
        print("  error vs the template's keys sampled there: " + ", ".join(f"{k} {v:.2e}" for k, v in perfect["error"].items()))
        result["perfect alignment"] = perfect
        print("\n== Character_YoungWoman (the sample)")
        for label, row in sample.items():
            print(f"  {label}: {len(row['worse'])} shapes worse ({', '.join(sorted(row['worse']))}), error {row['error']:.2e} "
                  f"(nearest vertex {row['nearest vertex error']:.2e}); symmetric {row['symmetry']['symmetric']}")
            for miss in row["symmetry"].get("shapes", []):
                print(f"    {miss['first_name']}/{miss['second_name']}: worst-vertex mirror miss {100 * miss['carried']:.1f}% "
                      f"(plain {100 * miss['plain']:.1f}%, barycentric copy {100 * miss['copied']:.1f}%, wrapped template {100 * miss['template']:.1f}%)"
                      + (" held apart" if miss["held_apart"] else ""))
        result["Character_YoungWoman"] = sample
    print("\n== Point pairs proposed, against hand pairs (distances from the template point's true place, / diagonal)")
    for label, row in proposals.items():
        print(f"  {label}: {row['pairs']} pairs in {row['seconds']:.2f} s, median {100 * row['median_distance']:.2f}%, "
              f"largest {100 * row['max_distance']:.2f}% ({max(row['distances'], key=row['distances'].get)})"
              + (f"; not found: {', '.join(row['missing'])}" if row["missing"] else ""))
        for pairs in ("hand", "proposed"):
            matches = row[f"{pairs}_matches"]
            error = f", keys {row[pairs + '_key_error']:.2e}" if pairs + "_key_error" in row else ""
            print(f"    {pairs} pairs: pieces fitted {matches['pieces_fitted']} of {matches['pieces']}, "
                  f"openings landed {matches['holes_paired']}{error}")
    result["proposals"] = proposals
    batch.write_json(args.json, result)
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
