"""Pack Expressions as plain functions: the operators and `scripts/batch.py pack` both call
them. `pack_object` reads and solves without writing anything; `store_packing` is the one
place that writes the result onto the object."""

import csv
import hashlib
import json
import time

import numpy as np

from .. import native
from .face_parts import face_objects, face_of, face_summary, pair_parts, read_face_rest, read_face_rig
from .front import front_summary, rig_front
from .mesh_arrays import MeshDataError
from .settings import PackSettings, pack_settings

# The collision and occlusion results of the last packing, on the object (saved with the file,
# undone with it; the leading underscore keeps it out of the Custom Properties panel).
CONFLICTS_PROPERTY = "_shapesmith_pack_conflicts"

# What the poseability results depend on besides the rig (method, section 1): the other
# options change which pairs are tested, never a pair's answer.
CONFLICT_SETTINGS = ("mu", "collision_tolerance", "occlusion_keep", "camera_direction")


def conflicts_key(rig, params):
    """A hash of the rig's arrays and names and the settings the poseability results depend
    on: stored results are reused only under the same key."""
    # SHA-256 over the arrays' own buffers (no copy): on a 26k-vertex head with 52 shapes
    # (16 MB) it is about twice as fast as BLAKE2b here, which has no hardware support.
    digest = hashlib.sha256()
    for array in (rig.neutral, rig.deltas, rig.triangles):
        digest.update(memoryview(np.ascontiguousarray(array)).cast("B"))
    digest.update(json.dumps([rig.names, [params.get(name) for name in CONFLICT_SETTINGS]]).encode())
    return digest.hexdigest()


def cached_conflicts(obj, key):
    """The poseability results stored on `obj` under `key` (a JSON string for the native
    `known`), or None."""
    try:
        stored = json.loads(obj.get(CONFLICTS_PROPERTY, ""))
    except (TypeError, ValueError):
        return None
    return stored.get("known") if isinstance(stored, dict) and stored.get("key") == key else None


def packing_options(obj, axis=0, time_limit=None):
    """The arguments of `pack_object` stored on `obj`: its Pack panel's settings
    (`settings.pack_settings`), refinements, target and front camera, and the symmetric pairs
    of Analyze Rig (as the user left them) when the rig was analysed; otherwise the native
    call finds the pairs itself."""
    props = obj.shapesmith.pack
    options = dict(
        settings=pack_settings(props, axis=axis, time_limit=time_limit),
        target=props.target,
        pin_together=[(p.first, p.second) for p in props.pin_together],
        keep_apart=[(p.first, p.second) for p in props.keep_apart],
        exclude=[e.name for e in props.exclude],
        pairs=None,
        camera=props.front_camera,
    )
    if obj.shapesmith.analysis.done:
        options["pairs"] = [(p.first, p.second) for p in obj.shapesmith.pairs]
    return options


def _check_named_pairs(pairs, what):
    for index, (first, second) in enumerate(pairs):
        if not first or not second:
            raise MeshDataError(f"{what}: entry {index + 1} is missing a shape key name: fill it in or remove it")


def pack_object(
    obj,
    settings=None,
    *,
    target=None,
    pairs=None,
    pin_together=(),
    keep_apart=(),
    exclude=(),
    camera=None,
    parts=None,
    target_parts=None,
    progress=None,
    reuse_conflicts=True,
):
    """Reads the rig (`read_rig` leaves out the keys a previous Bake wrote), runs the native packer with
    `settings` (a `settings.PackSettings`; None: the defaults) and returns its report with
    timings and shape-key warnings added. Writes nothing.

    With `reuse_conflicts`, the collision and occlusion results an earlier packing stored on
    the object (`store_packing`) are reused when the rig and their settings are unchanged
    (`conflicts_key`): only pairs they did not decide are tested. The report's
    `conflicts_cache` is what `store_packing` stores next.

    `pairs` (symmetric pairs, used with the settings' `symmetric`), `pin_together`,
    `keep_apart` (pairs of shape names) and `exclude` (names) are the refinements. The
    occlusion test looks from the rig's front (`rig_front`: `camera` when given, else found
    from the rig; it replaces the settings' `camera_direction`), which the report gives as
    `front`, `up` and `front_source`. `progress(fraction)`, when given, is called on this
    thread as the work advances (False cancels). `parts`, `target_parts`: the face parts of
    `obj` and `target` (default: the lists stored on them), packed as one rig with the head,
    so that a key moving only a part (tongueOut in the teeth) is tested against the head's.
    Raises MeshDataError (or the core's InvalidInputError) for anything the user has to fix."""
    settings = settings or PackSettings()
    max_expressions = settings.max_expressions
    started = time.perf_counter()
    if max_expressions is not None and max_expressions < 1:
        raise MeshDataError(f"the maximum number of expressions must be at least 1 (got {max_expressions})")
    rig, face = read_face_rig(face_objects(obj, parts))
    names, deltas = rig.names, rig.deltas
    target_neutral = None
    if target is not None:
        targets = pair_parts(face.objects, face_objects(target, target_parts))
        for other, own in zip(targets, face.objects):
            if len(other.data.vertices) != len(own.data.vertices):
                raise MeshDataError(
                    f"target '{other.name}' has {len(other.data.vertices)} vertices but '{own.name}' has "
                    f"{len(own.data.vertices)}: the target must share the rig's topology"
                )
        target_neutral = read_face_rest(face_of(targets))
    _check_named_pairs(pin_together, "pin together")
    _check_named_pairs(keep_apart, "keep apart")
    if settings.symmetric and pairs is not None:
        _check_named_pairs(pairs, "symmetric pairs")
    front = rig_front(obj, rig, axis=settings.axis, camera=camera)
    native_settings = dict(settings.as_native(), camera_direction=list(front["front"]))
    read = time.perf_counter()
    key = conflicts_key(rig, native_settings)
    known = cached_conflicts(obj, key) if reuse_conflicts else None
    hashed = time.perf_counter()
    report = native.module().pack_expressions(
        rig.neutral,
        deltas,
        rig.triangles,
        names,
        native_settings,
        target_neutral=target_neutral,
        pairs=pairs if settings.symmetric else None,
        pin_together=list(pin_together),
        keep_apart=list(keep_apart),
        exclude=list(exclude),
        known=known,
        progress=progress,
    )
    solved = time.perf_counter()
    report["conflicts_cache"] = {"key": key, "known": report["poseability"].pop("known")}
    if not report["expressions"] and not report["unplaced"]:
        raise MeshDataError(
            f"nothing to pack on '{obj.name}': every shape key is inert or excluded "
            f"(inert: {', '.join(report['inert']) or 'none'}; excluded: {', '.join(report['excluded']) or 'none'})"
        )
    report["names"] = names
    report["objects"] = face_summary(face)
    report["target"] = target.name if target is not None else None
    report["warnings"] = rig.warnings + front["warnings"]
    report.update({key: front[key] for key in ("front", "up", "front_source", "front_camera")})
    report["seconds"] = {"read": read - started, "cache_key": hashed - read, "native": solved - hashed}
    return report


def expression_label(index):
    """`REF_01`-style name of expression `index` (0-based)."""
    return f"REF_{index + 1:02d}"


def store_packing(obj, report):
    """Replaces the result stored on `obj` by `report` (a `pack_object` report)."""
    result = obj.shapesmith.pack.result
    result.expressions.clear()
    result.shapes.clear()
    for collection in (result.inert, result.excluded, result.unplaced, result.pairs, result.antagonists, result.conflicts):
        collection.clear()
    member_of = {}
    for j, expression in enumerate(report["expressions"]):
        item = result.expressions.add()
        item.name = expression_label(j)
        for name in expression["shapes"]:
            item.members.add().name = name
            member_of[name] = j
        item.importance = expression["importance"]
        item.vertices = expression["vertices"]
        item.optimal = expression["optimal"]
        item.status = str(expression["status"] or "")
    for name in report["names"]:
        shape = result.shapes.add()
        shape.name = name
        shape.importance = report["importance"][name]
        shape.expression = member_of.get(name, -1)
    for key in ("inert", "excluded", "unplaced"):
        for name in report[key]:
            getattr(result, key).add().name = name
    for key in ("pairs", "antagonists"):
        for first, second in report[key]:
            pair = getattr(result, key).add()
            pair.first, pair.second = first, second
            pair.source = "GEOMETRY"
    for conflict in report["conflicts"]:
        item = result.conflicts.add()
        (item.first, item.second), item.reasons = conflict["shapes"], " ".join(conflict["reasons"])
    fewest = report.get("fewest")
    result.fewest = fewest["count"] if fewest else 0
    result.fewest_optimal = bool(fewest and fewest["optimal"])
    front = {key: report.get(key) for key in ("front", "up", "front_source", "front_camera")}
    result.params_json = json.dumps(dict(report["params"], target=report.get("target"), **front))
    result.regions_json = json.dumps(report["regions"], separators=(",", ":"))
    result.done = True
    obj[CONFLICTS_PROPERTY] = json.dumps(report["conflicts_cache"], separators=(",", ":"))
    obj.shapesmith.pack.active_expression = 0


def stored_weights(obj):
    """(names, weights): the shape keys in the packed order and the J x K 0/1 matrix whose
    row j poses expression j, from the result stored on `obj` (for the Transfer tool)."""
    result = obj.shapesmith.pack.result
    names = [shape.name for shape in result.shapes]
    weights = np.zeros((len(result.expressions), len(names)), dtype=np.uint8)
    for k, shape in enumerate(result.shapes):
        if shape.expression >= 0:
            weights[shape.expression, k] = 1
    return names, weights


def stored_report(obj):
    """The stored result as the JSON shot list (the keys of the native report)."""
    result = obj.shapesmith.pack.result
    if not result.done:
        raise MeshDataError(f"'{obj.name}' has no packed expressions: run Pack Expressions first")
    names, weights = stored_weights(obj)
    fewest = {"count": result.fewest, "optimal": result.fewest_optimal} if result.fewest else None
    return {
        "object": obj.name,
        "expressions": [
            {
                "label": e.name,
                "shapes": [m.name for m in e.members],
                "importance": e.importance,
                "vertices": e.vertices,
                "status": e.status or None,
                "optimal": e.optimal,
            }
            for e in result.expressions
        ],
        "importance": {s.name: s.importance for s in result.shapes},
        "inert": [s.name for s in result.inert],
        "excluded": [s.name for s in result.excluded],
        "unplaced": [s.name for s in result.unplaced],
        "pairs": [[p.first, p.second] for p in result.pairs],
        "antagonists": [[p.first, p.second] for p in result.antagonists],
        "conflicts": [{"shapes": [c.first, c.second], "reasons": c.reasons.split()} for c in result.conflicts],
        "names": names,
        "weights": weights.tolist(),
        "fewest": fewest,
        "params": json.loads(result.params_json),
    }


def write_shot_list_json(path, report):
    with open(path, "w") as f:
        json.dump(report, f, indent=2)


def write_shot_list_csv(path, report, explain=False):
    """One row per expression, for a capture session's shot list; with `explain`, then a blank
    row and one row per pair of shapes kept apart, with the reasons (overlap, antagonist,
    collision, occlusion, user) and the expressions that pose each."""
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(["expression", "label", "shapes", "importance", "vertices", "optimal"])
        for j, expression in enumerate(report["expressions"]):
            writer.writerow(
                [
                    j + 1,
                    expression_label(j),
                    " ".join(expression["shapes"]),
                    f"{expression['importance']:.4f}",
                    expression["vertices"],
                    "yes" if expression["optimal"] else "no",
                ]
            )
        if explain:
            posed_in = {name: j + 1 for j, e in enumerate(report["expressions"]) for name in e["shapes"]}
            writer.writerow([])
            writer.writerow(["kept apart", "second", "reasons", "first in", "second in"])
            for conflict in report["conflicts"]:
                first, second = conflict["shapes"]
                writer.writerow([first, second, " ".join(conflict["reasons"]), posed_in.get(first, ""), posed_in.get(second, "")])


def _shape_keys(obj):
    keys = obj.data.shape_keys
    if keys is None:
        raise MeshDataError(f"'{obj.name}' has no shape keys")
    return [kb for kb in keys.key_blocks if kb != keys.reference_key]


def _posed_objects(obj):
    """The head and those of its face parts that have shape keys: what an expression poses."""
    return [o for o in face_objects(obj) if o == obj or o.data.shape_keys is not None]


def _expression_members(obj, index):
    result = obj.shapesmith.pack.result
    if not result.done or not 0 <= index < len(result.expressions):
        raise MeshDataError(f"'{obj.name}' has no packed expression {index + 1}: run Pack Expressions first")
    members = {m.name for m in result.expressions[index].members}
    missing = members - {kb.name for o in _posed_objects(obj) for kb in _shape_keys(o)}
    if missing:
        raise MeshDataError(f"shape key(s) {', '.join(sorted(missing))} no longer exist: pack again")
    return members


def preview_expression(obj, index):
    """Poses expression `index` on the head and its face parts: its member keys at 1, every
    other key at 0."""
    members = _expression_members(obj, index)
    for posed in _posed_objects(obj):
        for block in _shape_keys(posed):
            block.value = 1.0 if block.name in members else 0.0


def animate_expressions(obj, scene):
    """Keyframes one expression per frame from frame 1 on the head and its face parts
    (constant interpolation, so every frame is exactly one expression) and sets the scene's
    frame range to them; returns J."""
    result = obj.shapesmith.pack.result
    posed = [_expression_members(obj, j) for j in range(len(result.expressions))]
    for animated in _posed_objects(obj):
        blocks = _shape_keys(animated)
        for frame, members in enumerate(posed, start=1):
            for block in blocks:
                block.value = 1.0 if block.name in members else 0.0
                block.keyframe_insert("value", frame=frame)
        action = animated.data.shape_keys.animation_data.action
        for fcurve in _fcurves(action):
            for point in fcurve.keyframe_points:
                if 1 <= point.co.x <= len(posed):
                    point.interpolation = "CONSTANT"
    scene.frame_start, scene.frame_end = 1, max(len(posed), 1)
    scene.frame_set(1)
    return len(posed)


def _fcurves(action):
    """F-curves of an action in Blender 4.x (flat) and 5.x (layered, channelbags)."""
    if hasattr(action, "fcurves"):
        return list(action.fcurves)
    return [fc for layer in action.layers for strip in layer.strips for bag in strip.channelbags for fc in bag.fcurves]


def _baked_shapes(obj, posed):
    """(label, positions) of each expression on one object: its Basis plus its own members'
    deltas (keys of an earlier bake left out)."""
    keys = obj.data.shape_keys
    n = len(obj.data.vertices)
    neutral = np.empty(n * 3, dtype=np.float32)
    keys.reference_key.points.foreach_get("co", neutral)
    previous = {b.name for b in obj.shapesmith.pack.baked}
    sources = {kb.name: kb for kb in _shape_keys(obj) if kb.name not in previous}
    buffer = np.empty(n * 3, dtype=np.float32)
    shapes = []
    for j, members in enumerate(posed):
        mixed = neutral.copy()
        for name in members & sources.keys():
            sources[name].points.foreach_get("co", buffer)
            mixed += buffer - neutral
        shapes.append((expression_label(j), mixed))
    taken = sorted(label for label, _ in shapes if label not in previous and label in keys.key_blocks)
    if taken:
        raise MeshDataError(f"shape key(s) {', '.join(taken)} of '{obj.name}' exist and were not made by Bake: rename them first")
    return shapes


def bake_expressions(obj):
    """Writes one `REF_01`-style shape key per expression (Basis plus its members' deltas, value
    0) on the head and on each of its face parts that has shape keys; keys of an earlier bake
    are replaced and leftovers removed. Everything is checked before the first write. Returns
    the key names."""
    result = obj.shapesmith.pack.result
    posed = [_expression_members(obj, j) for j in range(len(result.expressions))]
    planned = [(baked_on, _baked_shapes(baked_on, posed)) for baked_on in _posed_objects(obj)]
    for baked_on, shapes in planned:
        keys = baked_on.data.shape_keys
        baked = baked_on.shapesmith.pack.baked
        previous = {b.name for b in baked}
        labels = {label for label, _ in shapes}
        for name in previous - labels:
            block = keys.key_blocks.get(name)
            if block is not None:
                baked_on.shape_key_remove(block)
        baked.clear()
        for label, mixed in shapes:
            block = keys.key_blocks.get(label) or baked_on.shape_key_add(name=label, from_mix=False)
            block.points.foreach_set("co", mixed)
            block.value = 0.0  # shape_key_add defaults to 1.0 in Blender 5.x
            baked.add().name = label
        baked_on.data.update()
    return [label for label, _ in planned[0][1]]


def summary_lines(report):
    """The expressions, numbered with their members, and what was left out (batch, demo)."""
    fewest = report.get("fewest")
    beside = f" (fewest possible: {fewest['count']}{'' if fewest['optimal'] else ', not proven'})" if fewest else ""
    lines = [f"{len(report['expressions'])} expressions{beside}"]
    for j, expression in enumerate(report["expressions"]):
        flag = "" if expression["optimal"] else "  [not proven optimal]"
        lines.append(f"{j + 1:3d}. {', '.join(expression['shapes'])}{flag}")
    for key in ("inert", "excluded", "unplaced"):
        if report[key]:
            lines.append(f"{key}: {', '.join(report[key])}")
    lines.append("antagonists kept apart: " + (", ".join(f"{a}/{b}" for a, b in report["antagonists"]) or "none"))
    lines.append("collisions kept apart: " + (", ".join("/".join(c["shapes"]) for c in report["collisions"]) or "none"))
    occlusions = [f"{o['hidden']} hidden by {o['by']}" for o in report["occlusions"]]
    lines.append("occlusions kept apart: " + (", ".join(occlusions) or "none"))
    if front_summary(report):
        lines.append(f"front: {front_summary(report)}")
    reused = report.get("poseability", {}).get("pairs_reused", 0)
    if reused:
        lines.append(f"collision and occlusion tests: {reused} pairs reused from the results stored on the object")
    return lines + [f"warning: {w}" for w in report.get("warnings", ())]
