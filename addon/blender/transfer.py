"""Transfer Shape Keys as plain functions: the operators and `scripts/batch.py transfer` both
call them. `transfer_object` validates and solves without writing anything; writing the keys
is `shape_keys.write_transferred_keys`, run only once everything here has succeeded."""

import re
import time
from dataclasses import dataclass, field

import numpy as np

from .. import native
from .mesh_arrays import MeshDataError, check_mesh, read_rig, read_triangles, show_mesh

# A training object named `REF_03`, `OldMan_REF_03` or `REF_03.001` poses packed expression 3.
_EXPRESSION_NAME = re.compile(r"(?:^|[_.\- ])REF_(\d+)$")
# Blender's duplicate suffix, ignored when matching names.
_DUPLICATE_SUFFIX = re.compile(r"\.\d{3}$")


@dataclass
class Transfer:
    """A solved transfer, not yet written: the target deltas (K, N, 3) in the template's key
    order, the native report, the training expressions used (object name -> weight row) and,
    for a wrap, the template's vertex groups carried onto the target (name -> weights (N,))."""

    source: object
    target: object
    names: list
    target_neutral: np.ndarray
    deltas: np.ndarray
    report: dict
    training: dict = field(default_factory=dict)
    warnings: list = field(default_factory=list)
    vertex_groups: dict = field(default_factory=dict)


def rest_positions(obj):
    """The mesh's rest shape, float32 (N, 3): its reference key when it has shape keys (the
    vertex array can lag behind a reference key written by script), else its vertices."""
    mesh = obj.data
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    if mesh.shape_keys is not None:
        mesh.shape_keys.reference_key.data.foreach_get("co", co)
    else:
        mesh.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


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


def _read_pair(source, target):
    if source is None:
        raise MeshDataError("no template chosen: pick the mesh whose shape keys are transferred")
    if target is None:
        raise MeshDataError("no target: make the new head the active object")
    if target == source or target.data == source.data:
        raise MeshDataError(f"the target '{target.name}' is the template itself: pick another mesh as target")
    rig = read_rig(source)
    check_same_topology(target, source)
    return rig, rest_positions(target)


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
    *,
    virtual_edges=True,
    tau_d=0.015,
    tau_r=4.0,
    edge_weight=3.0,
    training_objects=(),
    pack_report=None,
    beta_reg=1.0,
    refine_weights=False,
    compare_plain=False,
    collisions=True,
    collision_margin=0.25,
    template_penetration=None,
    progress=None,
):
    """Validates the pair (and the training expressions when given), runs the native
    transfer and returns a `Transfer`. Writes nothing; raises MeshDataError (or the core's
    InvalidInputError) for anything the user has to fix. `progress(fraction)`, when given, is
    called as the work advances and stops it by returning False (CancelledError).
    `template_penetration` is `measure_template_penetration(source)` when the caller already
    has it (a batch over many targets measures it once)."""
    started = time.perf_counter()
    rig, target_neutral = _read_pair(source, target)
    examples = example_weights = None
    training = {}
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
        virtual_edges=virtual_edges,
        tau_d=tau_d,
        tau_r=tau_r,
        edge_weight=edge_weight,
        examples=examples,
        example_weights=None if example_weights is None else example_weights.tolist(),
        beta_reg=beta_reg,
        refine_weights=refine_weights,
        compare_plain=compare_plain,
        measure_penetration=True,
        collisions=collisions,
        collision_margin=collision_margin,
        template_penetration=template_penetration,
        progress=progress,
    )
    report["diagonal"] = float(np.linalg.norm(target_neutral.max(0) - target_neutral.min(0)))
    report["seconds"]["read"] = read - started
    return Transfer(source, target, rig.names, target_neutral, deltas, report, training, list(rig.warnings))


def measure_template_penetration(source):
    """The template's own intersection curve, at rest and per shape at weight 1: the same for
    every target, so a batch measures it once and passes it to each `transfer_object`."""
    rig = read_rig(source)
    return native.module().measure_penetration(rig.neutral, rig.deltas, rig.triangles)


def find_virtual_edges(target, tau_d=0.015, tau_r=4.0):
    """The target's virtual edges (E, 2) and its rest positions."""
    check_mesh(target, need_shape_keys=False)
    positions = rest_positions(target)
    return native.module().find_virtual_edges(positions, read_triangles(target), tau_d=tau_d, tau_r=tau_r), positions


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
    collisions = report["params"]["transfer"]["collisions"]
    result.collisions = collisions is not None
    result.collision_margin = collisions["margin"] if collisions else 0.0
    rows = report["penetration"]
    traced = collision_traced(report)
    result.worse_before_collisions = len(worse_than_template(report, key="before_collisions_length")) if traced else -1
    result.carried = "carry" in report
    result.collision_resolved = sum(1 for row in rows if (row.get("collisions") or {}).get("applied", False))
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
        item.before_length = row.get("before_collisions_length", row["length"])
        item.collision_solves = (row.get("collisions") or {}).get("solves", 0)
    result.done = True


def collision_traced(report):
    """Whether the report has each shape's numbers before the collision pass (the pass was on
    and the shapes were transferred, not personalised)."""
    rows = report["penetration"]
    return bool(rows) and all("before_collisions_length" in row for row in rows)


def added_beyond_template(report, row, key="length"):
    """How much more intersection curve the shape adds to the target's neutral than the
    template's shape allows, split into (inside one piece: lips or lids through each other,
    between pieces: skin through a separate eyeball, lashes or teeth), each part zero or more:
    SPEC 3's criterion, as the native report computes it (`excess`: per part, the shape may
    add what the template's adds to its neutral, a removal allowing none, or cross as much as
    the template's shape does, `template_added` and `template_crossing`; removing in one part
    does not pay for adding in the other). `key="plain_length"` reads plain transfer's,
    `key="before_collisions_length"` the result's before the collision pass."""
    excess = row[key.replace("length", "excess")]
    return excess["inside"], excess["between"]


def worse_than_template(report, key="length", tolerance=1e-3):
    """Names of shapes that add more intersection curve to the target's neutral than they add
    to the template's (`added_beyond_template`, both parts together beyond `tolerance` x the
    bbox diagonal); `key="plain_length"` judges plain transfer, `key="before_collisions_length"`
    the result before the collision pass."""
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
    collision_line = []
    if collision_traced(report):
        resolved = sum(1 for row in report["penetration"] if (row.get("collisions") or {}).get("applied", False))
        collision_line = [
            f"collision pass: {resolved} shapes re-solved; shapes adding more intersection than on the template "
            f"{len(worse_than_template(report, key='before_collisions_length'))} before the pass, {len(worse)} after"
        ]
    lines = [
        f"'{transfer.source.name}' -> '{transfer.target.name}': {len(written)} shape keys written"
        + (f", {len(skipped)} kept ({', '.join(skipped)})" if skipped else ""),
        f"virtual edges: {report['virtual_edges']}"
        + (f"; personalised with {len(transfer.training)} training expressions" if transfer.training else ""),
        "seconds: " + ", ".join(f"{k} {v:.3f}" for k, v in seconds.items()),
        *collision_line,
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
