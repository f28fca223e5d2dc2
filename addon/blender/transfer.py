"""Transfer Shape Keys as plain functions: the operators and `scripts/batch.py transfer` both
call them. `transfer_object` validates and solves without writing anything; writing the keys
is `shape_keys.write_transferred_keys`, run only once everything here has succeeded."""

import fnmatch
import re
import time
from dataclasses import dataclass, field

import numpy as np

from .. import native
from .face_parts import face_objects, face_of, pair_parts, read_face_rest, read_face_rig
from .mesh_arrays import MeshDataError, check_mesh, fault_notes, group_weights, read_triangles, rest_positions, show_mesh
from .settings import TransferSettings, VirtualEdgeSettings

# A training object named `REF_03`, `OldMan_REF_03` or `REF_03.001` poses packed expression 3.
_EXPRESSION_NAME = re.compile(r"(?:^|[_.\- ])REF_(\d+)$")
# Blender's duplicate suffix, ignored when matching names.
_DUPLICATE_SUFFIX = re.compile(r"\.\d{3}$")


@dataclass
class Transfer:
    """A solved transfer, not yet written: the target deltas (K, N, 3) in the template's key
    order, the native report, the training expressions used (object name -> weight row) and,
    for a wrap, the template's vertex groups carried onto the target (name -> weights (N,)).
    With face parts, `names` and `deltas` span every object (head first, in the head's
    space)."""

    source: object
    target: object
    names: list
    target_neutral: np.ndarray
    deltas: np.ndarray
    report: dict
    training: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    vertex_groups: dict = field(default_factory=dict)
    # A face in several objects: one `Transfer` per object (head first), each with its own
    # keys and vertices, written in place of this one (`split_transfer`).
    pieces: list = field(default_factory=list)
    # Template object of each key whose settings a piece takes, when not `source` alone.
    key_sources: dict = field(default_factory=dict)
    # After writing: the target's key name for each template key written (its own name for
    # that shape in another convention, else the template's).
    onto: dict = field(default_factory=dict)


def face_corners(obj):
    """(corners per face, vertex of each corner): the mesh's faces, independent of positions
    (unlike `loop_triangles`, whose split of a quad follows its shape)."""
    mesh = obj.data
    sizes = np.empty(len(mesh.polygons), dtype=np.int32)
    mesh.polygons.foreach_get("loop_total", sizes)
    corners = np.empty(len(mesh.loops), dtype=np.int32)
    mesh.loops.foreach_get("vertex_index", corners)
    return sizes, corners


def check_same_topology(obj, template, what="target"):
    """Raises MeshDataError unless `obj` has the template's vertices and faces (same counts,
    same corners), naming both counts. The template's triangles then serve both meshes."""
    check_mesh(obj, need_shape_keys=False)
    (sizes, corners), (template_sizes, template_corners) = face_corners(obj), face_corners(template)
    counts = [
        (len(mesh.vertices), len(face_sizes), int(np.sum(face_sizes - 2)))
        for mesh, face_sizes in ((obj.data, sizes), (template.data, template_sizes))
    ]
    for index, unit in enumerate(("vertices", "faces", "triangles")):
        if counts[0][index] != counts[1][index]:
            raise MeshDataError(
                f"{what} '{obj.name}' has {counts[0][index]} {unit} but template '{template.name}' has "
                f"{counts[1][index]}: transfer needs the same topology"
            )
    starts = np.concatenate(([0], np.cumsum(sizes)[:-1]))
    differs = np.flatnonzero(
        (sizes != template_sizes) | np.logical_or.reduceat(corners != template_corners, starts)
    )
    if len(differs):
        f = differs[0]
        raise MeshDataError(
            f"{what} '{obj.name}' has the template's counts but other faces ({len(differs)} faces differ, "
            f"e.g. face {f}: vertices {tuple(obj.data.polygons[f].vertices)} vs "
            f"{tuple(template.data.polygons[f].vertices)}): transfer needs the same topology"
        )


def joined_face_corners(objects):
    """`face_corners` of several meshes as one mesh: their faces in order, each object's
    vertex indices after those of the objects before it."""
    sizes, corners, offset = [], [], 0
    for obj in objects:
        own_sizes, own_corners = face_corners(obj)
        sizes.append(own_sizes)
        corners.append(own_corners + offset)
        offset += len(obj.data.vertices)
    return np.concatenate(sizes), np.concatenate(corners)


def check_joined_topology(obj, objects):
    """Raises MeshDataError unless `obj` has the faces of `objects` joined into one mesh (a
    wrapped template made from a face in several objects)."""
    check_mesh(obj, need_shape_keys=False)
    (sizes, corners), (joined_sizes, joined_corners) = face_corners(obj), joined_face_corners(objects)
    if not (np.array_equal(sizes, joined_sizes) and np.array_equal(corners, joined_corners)):
        raise MeshDataError(
            f"'{obj.name}' does not have the faces of '{objects[0].name}' and its face parts "
            f"({', '.join(o.name for o in objects[1:])}) joined in that order: wrap the template again"
        )


def _read_pair(source, target, source_parts=None, target_parts=None, joined_target=False):
    """(rig, template face, target face, target rest positions): the template's face and the
    target's, object i of one paired with object i of the other (`face_parts.pair_parts`) and
    each pair checked for the same topology. With `joined_target`, the target is one mesh
    with the faces of the template's objects joined (`check_joined_topology`)."""
    if source is None:
        raise MeshDataError("no template chosen: pick the mesh whose shape keys are transferred")
    if target is None:
        raise MeshDataError("no target: make the new head the active object")
    sources = face_objects(source, source_parts)
    if joined_target and len(sources) > 1:
        check_joined_topology(target, sources)
        rig, face = read_face_rig(sources)
        target_face = face_of([target])
        return rig, face, target_face, read_face_rest(target_face)
    targets = pair_parts(sources, face_objects(target, target_parts))
    for obj in targets:
        template = next((s for s in sources if obj == s or obj.data == s.data), None)
        if template is not None:
            if obj == target:
                raise MeshDataError(f"the target '{obj.name}' is the template itself: pick another mesh as target")
            raise MeshDataError(f"the target part '{obj.name}' is the template's '{template.name}' itself: pick another mesh")
    rig, face = read_face_rig(sources)
    for index, (obj, template) in enumerate(zip(targets, sources)):
        check_same_topology(obj, template, what="target" if index == 0 else "target part")
    target_face = face_of(targets)
    return rig, face, target_face, read_face_rest(target_face)


def split_transfer(transfer, face, target_face):
    """The transfer's pieces for writing, one per object of a face in several objects: the
    template object's own keys (in the transfer's order) with their deltas, in the target
    object's own space, onto its own rest shape; none for a head without parts or a joined
    target."""
    if len(face.objects) == 1 or len(target_face.objects) == 1:
        return []
    pieces = []
    for index, (source, target) in enumerate(zip(face.objects, target_face.objects)):
        keys = source.data.shape_keys
        own = set(keys.key_blocks.keys()) if keys is not None else set()
        rows = [k for k, name in enumerate(transfer.names) if name in own]
        deltas = target_face.to_local_deltas(index, transfer.deltas[rows][:, target_face.vertices(index)])
        pieces.append(
            Transfer(source, target, [transfer.names[k] for k in rows], rest_positions(target), np.ascontiguousarray(deltas), {})
        )
    return pieces


def packed_expressions(source, pack_report=None):
    """The template's packed expressions as (label, member shape names) in order: from a
    Pack Expressions JSON report when given, else from the result the pack tool stored on the
    template (`obj.shapesmith.pack.result`), else none."""
    if pack_report is not None:
        return [
            (expression.get("label") or f"REF_{j + 1:02d}", list(expression["shapes"]))
            for j, expression in enumerate(pack_report["expressions"])
        ]
    # Pack Expressions is a separate tool: its settings exist only where it is installed.
    pack = getattr(source.shapesmith, "pack", None)
    if pack is None or not pack.result.done:
        return []
    return [(e.name, [m.name for m in e.members]) for e in pack.result.expressions]


def training_weights(obj_name, names, expressions):
    """The 0/1 weight row (K,) of a training object, matched by its name: `REF_03` (any
    prefix) poses packed expression 3; a name equal to a shape key's, or ending in
    `_<shape key>`, poses that shape alone. Raises MeshDataError when nothing matches."""
    stem = _DUPLICATE_SUFFIX.sub("", obj_name)
    weights = np.zeros(len(names), dtype=np.float32)
    index = {name: k for k, name in enumerate(names)}
    match = _EXPRESSION_NAME.search(stem)
    if match:
        j = int(match.group(1)) - 1
        if not 0 <= j < len(expressions):
            raise MeshDataError(
                f"training object '{obj_name}' names expression {j + 1}, but the template has "
                f"{len(expressions)} packed expression(s): run Pack Expressions on the template first"
            )
        label, members = expressions[j]
        missing = [m for m in members if m not in index]
        if missing:
            raise MeshDataError(
                f"packed expression {label} poses {', '.join(missing)}, which the template no longer has: pack again"
            )
        weights[[index[m] for m in members]] = 1.0
        return weights
    shape = max((n for n in names if stem == n or stem.endswith(("_" + n, "." + n))), key=len, default=None)
    if shape is None:
        raise MeshDataError(
            f"training object '{obj_name}' matches no packed expression (name it like REF_01) and no shape key "
            "(name it after one, e.g. jawOpen or OldMan_jawOpen)"
        )
    weights[index[shape]] = 1.0
    return weights


def read_training(objects, source, target, names, expressions):
    """Training expressions (J, N, 3) and their weights (J, K) from meshes of the target's
    topology; the template and target themselves, and non-meshes, are left out."""
    chosen = [o for o in objects if o.type == "MESH" and o not in (source, target)]
    if not chosen:
        raise MeshDataError("no training expressions: put meshes of the target's topology in the training collection")
    positions, rows = [], {}
    for obj in sorted(chosen, key=lambda o: o.name):
        check_same_topology(obj, source, what="training expression")
        rows[obj.name] = training_weights(obj.name, names, expressions)
        positions.append(rest_positions(obj))
    return np.ascontiguousarray(np.stack(positions)), np.stack(list(rows.values())), rows


def transfer_object(
    source,
    target,
    settings=None,
    *,
    training_objects=(),
    pack_report=None,
    template_penetration=None,
    source_parts=None,
    target_parts=None,
    joined_target=False,
    keys=None,
    progress=None,
):
    """Validates the pair (and the training expressions when given), runs the native
    transfer with `settings` (a `settings.TransferSettings`, None for the defaults) and returns
    a `Transfer`. Writes nothing; raises MeshDataError (or the core's
    InvalidInputError) for anything the user has to fix. `progress(fraction)`, when given, is
    called as the work advances and stops it by returning False (CancelledError).
    `template_penetration` is `measure_template_penetration(source)` when the caller already
    has it (a batch over many targets measures it once). `source_parts`, `target_parts`: the
    face parts of each (`face_parts.face_objects`; default: the lists stored on the heads);
    `joined_target`: the target is one mesh of the template's objects joined (a wrap's).
    `keys`: the template keys to transfer (names or patterns such as `eyeBlink*`,
    `chosen_keys`); None transfers all."""
    started = time.perf_counter()
    settings = settings or TransferSettings()
    if not settings.measure_penetration:
        raise MeshDataError("the add-on's transfer report needs the penetration measured: keep measure_penetration on")
    rig, face, target_face, target_neutral = _read_pair(source, target, source_parts, target_parts, joined_target)
    examples = example_weights = None
    training = {}
    if training_objects and len(face.objects) > 1:
        raise MeshDataError(
            f"personalisation reads training expressions of one mesh, but '{source.name}' has face parts "
            f"({', '.join(o.name for o in face.parts)}): transfer without training expressions"
        )
    if keys is not None:
        if training_objects:
            raise MeshDataError("personalisation fits every key to the training expressions: transfer all keys")
        rows = chosen_keys(rig.names, keys)
        rig.deltas, rig.names = np.ascontiguousarray(rig.deltas[rows]), [rig.names[k] for k in rows]
        if template_penetration is not None:  # measured for every key: the chosen keys' rows
            template_penetration = {**template_penetration, "shapes": [template_penetration["shapes"][k] for k in rows]}
    if training_objects:
        expressions = packed_expressions(source, pack_report)
        examples, example_weights, training = read_training(
            training_objects, source, target, rig.names, expressions
        )
    read = time.perf_counter()
    deltas, report = native.module().transfer_shapes(
        rig.neutral,
        rig.deltas,
        target_neutral,
        rig.triangles,
        rig.names,
        settings.as_native(),
        examples=examples,
        example_weights=None if example_weights is None else example_weights.tolist(),
        template_penetration=template_penetration,
        progress=progress,
    )
    report["diagonal"] = float(np.linalg.norm(target_neutral.max(0) - target_neutral.min(0)))
    report["seconds"]["read"] = read - started
    # Which template object went onto which target object (all onto one for a joined target).
    counterparts = target_face.objects if len(target_face.objects) > 1 else [target] * len(face.objects)
    report["objects"] = [[s.name, t.name] for s, t in zip(face.objects, counterparts)]
    # The target shares the template's faces; where its own shape flattens one, that face is
    # left out of both (one topology, one surface) and the target's line says so.
    own_notes = fault_notes(target_face.objects)
    result = Transfer(source, target, rig.names, target_neutral, deltas, report, training, list(rig.warnings) + own_notes)
    result.pieces = split_transfer(result, face, target_face)
    # Same topology: the groups masking the keys go onto the target with the same weights.
    result.vertex_groups = masking_groups(face.objects, rig.names)
    for piece in result.pieces:
        piece.vertex_groups = masking_groups([piece.source], piece.names)
    return result


def masking_groups(objects, names):
    """{group name: weights over the vertices of `objects` in order}: the vertex groups that
    mask the keys `names` on those objects (a split done with groups), for a target of the
    same vertices."""
    wanted = {
        block.vertex_group
        for obj in objects
        if obj.data.shape_keys is not None
        for block in obj.data.shape_keys.key_blocks
        if block.name in names and block.vertex_group
    }
    per_object = [group_weights(obj, wanted) for obj in objects]
    found = sorted(set().union(*per_object))
    return {
        name: np.concatenate([weights.get(name, np.zeros(len(obj.data.vertices), np.float32))
                              for obj, weights in zip(objects, per_object)])
        for name in found
    }


def chosen_keys(names, chosen):
    """Indices of `names` that the user chose: each of `chosen` is a key's name or a
    pattern (`eyeBlink*`, `mouth?ight`; any letter case). A choice matching no key is refused,
    as is choosing none."""
    chosen = [c.strip() for c in chosen if c.strip()]
    if not chosen:
        raise MeshDataError("no shape keys chosen: tick at least one key (or give --keys)")
    rows = set()
    for choice in chosen:
        found = [k for k, name in enumerate(names) if name == choice or fnmatch.fnmatch(name.lower(), choice.lower())]
        if not found:
            raise MeshDataError(f"'{choice}' matches no shape key of the template (such as {', '.join(names[:3])})")
        rows.update(found)
    return sorted(rows)


def measure_template_penetration(source, parts=None):
    """The template's own intersection curve (its face parts included), at rest and per shape
    at weight 1: the same for every target, so a batch measures it once and passes it to each
    `transfer_object`."""
    rig, _ = read_face_rig(face_objects(source, parts))
    return native.module().measure_penetration(rig.neutral, rig.deltas, rig.triangles)


def find_virtual_edges(target, settings=None):
    """The target's virtual edges (E, 2) and its rest positions; `settings`: a
    `settings.VirtualEdgeSettings` (None: the defaults)."""
    check_mesh(target, need_shape_keys=False)
    positions = rest_positions(target)
    settings = settings or VirtualEdgeSettings()
    return native.module().find_virtual_edges(positions, read_triangles(target), settings.as_native()), positions


def preview_name(target):
    return f"{target.name}_VirtualEdges"


def show_virtual_edges(target, edges, positions):
    """An edge-only mesh `<target>_VirtualEdges` (the target's rest vertices, one edge per
    virtual edge) parented to the target, drawn in front as wire; an earlier one is replaced."""
    import bpy

    name = preview_name(target)
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(positions.tolist(), np.asarray(edges).tolist(), [])
    obj = show_mesh(name, mesh, beside=target)
    obj.parent = target
    obj.matrix_parent_inverse.identity()
    obj.matrix_basis.identity()
    obj.display_type = "WIRE"
    obj.show_in_front = True
    obj.hide_render = True
    return obj


def store_transfer(transfer, written, skipped):
    """Keeps the summary and the per-shape penetration on the target (replacing the last)."""
    result = transfer.target.shapesmith.transfer
    report = transfer.report
    result.source = transfer.source.name
    result.written = len(written)
    result.skipped = ", ".join(skipped)
    result.virtual_edges = report["virtual_edges"]
    result.examples = len(transfer.training)
    result.seconds = sum(report["seconds"].values())
    result.neutral_length = report["neutral_penetration"]["length"]
    result.template_neutral_length = report["template_neutral_penetration"]["length"]
    contact = report["params"]["transfer"]["contact"]
    result.contact = contact is not None
    result.contact_distance = contact["distance"] if contact else 0.0
    rows = report["penetration"]
    traced = contact_traced(report)
    result.worse_before_contact = len(worse_than_template(report, key="before_contact_length")) if traced else -1
    result.carried = "carry" in report
    result.contact_resolved = sum(1 for row in rows if (row.get("contact") or {}).get("applied", False))
    worse = set(worse_than_template(report))
    result.shapes.clear()
    for row in rows:
        item = result.shapes.add()
        item.name = row["name"]
        item.length, item.pairs = row["length"], row["pairs"]
        item.template_length, item.template_pairs = row["template_length"], row["template_pairs"]
        item.worse = row["name"] in worse
        item.added = sum(added_beyond_template(report, row))
        item.allowed = row["allowed"]["inside"] + row["allowed"]["between"]
        item.where = where_added(report, row)
        item.before_length = row.get("before_contact_length", row["length"])
        item.contact_iterations = (row.get("contact") or {}).get("iterations", 0)
    result.done = True


def contact_traced(report):
    """Whether the report has each shape's numbers before the contact solve (it was on and the
    shapes were transferred, not personalised)."""
    rows = report["penetration"]
    return bool(rows) and all("before_contact_length" in row for row in rows)


def added_beyond_template(report, row, key="length"):
    """The intersection curve of what the shape passes through that neither the target's
    neutral nor the template's shape does, split into (inside one piece: lips or lids through
    each other, between pieces: skin through a separate eyeball, lashes or teeth), each zero
    or more, as the native report computes it (`excess`): after a transfer, the crossings
    Keep Surfaces Apart takes apart; after a wrap, the curve its keys add on the character
    beyond what the template's shapes add. `key="plain_length"` reads plain transfer's,
    `key="before_contact_length"` the result's before the contact solve."""
    excess = row[key.replace("length", "excess")]
    return excess["inside"], excess["between"]


def worse_than_template(report, key="length", tolerance=1e-3):
    """Names of shapes that pass through more than the template's (`added_beyond_template`,
    both parts together beyond `tolerance` x the bbox diagonal); `key="plain_length"` judges
    plain transfer, `key="before_contact_length"` the result before the contact solve."""
    margin = tolerance * report["diagonal"]
    return [row["name"] for row in report["penetration"] if sum(added_beyond_template(report, row, key)) > margin]


def where_added(report, row):
    """Where most of a shape's extra intersection lies, for the panel and the summary."""
    within, between = added_beyond_template(report, row)
    return "inside one piece" if within >= between else "between pieces"


def summary_lines(transfer, written, skipped):
    """A short human-readable summary (batch log, demo, operator report)."""
    report = transfer.report
    seconds = report["seconds"]
    worse = worse_than_template(report)
    contact_line = []
    if contact_traced(report):
        resolved = sum(1 for row in report["penetration"] if (row.get("contact") or {}).get("applied", False))
        contact_line = [
            f"surfaces kept apart in {resolved} shapes; shapes adding more intersection than on the template "
            f"{len(worse_than_template(report, key='before_contact_length'))} before, {len(worse)} after"
        ]
    lines = [
        f"'{transfer.source.name}' -> '{transfer.target.name}': {len(written)} shape keys written"
        + (f", {len(skipped)} kept ({', '.join(skipped)})" if skipped else ""),
        f"virtual edges: {report['virtual_edges']}"
        + (f"; personalised with {len(transfer.training)} training expressions" if transfer.training else ""),
        "seconds: " + ", ".join(f"{k} {v:.3f}" for k, v in seconds.items()),
        *contact_line,
        "shapes adding more intersection than on the template: "
        + (
            ", ".join(
                f"{row['name']} (+{sum(added_beyond_template(report, row)):.4f}, {where_added(report, row)})"
                for row in report["penetration"]
                if row["name"] in worse
            )
            or "none"
        ),
    ]
    return lines + [f"warning: {w}" for w in transfer.warnings]
