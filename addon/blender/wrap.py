"""Wrap as plain functions: the operators and `scripts/batch.py wrap` both call them.

The chain: point pairs -> `native.wrap_template` (similarity, then non-rigid fit) -> a
wrapped template object (template topology, the character's shape) -> the same-topology
transfer onto it (`transfer.transfer_object`) -> `native.carry_shapes` onto the character's
own vertices -> `shape_keys.write_transferred_keys` (nothing is written before everything
has succeeded)."""

import json
import time
from dataclasses import dataclass, field

import numpy as np

from .. import native
from .face_parts import face_objects, face_of, read_face_rest, read_face_rig, read_face_triangles
from .mesh_arrays import MeshDataError, fault_notes, read_triangles, show_mesh
from .settings import CarrySettings, TransferSettings, WrapSettings
from .transfer import Transfer, joined_face_corners, rest_positions, transfer_object

# A custom property holding point pairs in the JSON form of `batch.py wrap --pairs`.
PAIRS_PROPERTY = "shapesmith_wrap_pairs"
# The distance (relative to the character's bbox diagonal) drawn fully red on the wrapped template.
HEAT_RANGE = 0.01


@dataclass
class Wrapped:
    """A solved wrap: the wrapped template's positions (template topology, character space)
    and the native fit report."""

    template: object
    character: object
    positions: np.ndarray
    report: dict
    seconds: dict = field(default_factory=dict)


def read_surface(obj, what):
    """(rest positions (N, 3), triangles (T, 3)) of a mesh and its face parts (one mesh in the
    head's space, head first: the wrap fits each part as a piece), or MeshDataError naming
    `what`."""
    if obj is None:
        raise MeshDataError(f"no {what} chosen")
    # The character is only a surface to fit (closest points): loose vertices or extra faces
    # on an edge of a scan change nothing there, so only the template's topology is checked.
    face = face_of(face_objects(obj, topology=what != "character"))
    return read_face_rest(face), read_face_triangles(face)


def _as_points(obj, positions, values, what, index):
    """A pair entry as a local point: a vertex index in range, or three finite numbers."""
    if isinstance(values, bool):
        raise MeshDataError(f"pair {index + 1}: the {what} entry must be a vertex index or [x, y, z], got {values!r}")
    if isinstance(values, int):
        if not 0 <= values < len(positions):
            raise MeshDataError(
                f"pair {index + 1}: vertex {values} is out of range for '{obj.name}' ({len(positions)} vertices)"
            )
        return positions[values]
    try:
        point = np.asarray(values, dtype=np.float64)
    except (TypeError, ValueError):
        point = None
    if point is None or point.shape != (3,):
        raise MeshDataError(f"pair {index + 1}: the {what} entry must be a vertex index or [x, y, z], got {values!r}")
    if not np.all(np.isfinite(point)):
        raise MeshDataError(f"pair {index + 1}: the {what} point {values!r} is not finite")
    return point


def pairs_from_list(entries, template, character):
    """Point pairs (template (P, 3), character (P, 3), float32 local points) from
    `[[template_vertex, character_vertex], ...]` or `[[[x, y, z], [x, y, z]], ...]`."""
    if not isinstance(entries, list) or any(not isinstance(e, (list, tuple)) or len(e) != 2 for e in entries):
        raise MeshDataError("point pairs must be a list of [template, character] entries (vertex indices or [x, y, z])")
    template_positions, character_positions = rest_positions(template), rest_positions(character)
    template_points = [_as_points(template, template_positions, e[0], "template", i) for i, e in enumerate(entries)]
    character_points = [_as_points(character, character_positions, e[1], "character", i) for i, e in enumerate(entries)]
    shape = (len(entries), 3)
    return (
        np.ascontiguousarray(np.reshape(template_points, shape), dtype=np.float32),
        np.ascontiguousarray(np.reshape(character_points, shape), dtype=np.float32),
    )


def pairs_from_json(path, template, character):
    try:
        with open(path) as f:
            entries = json.load(f)
    except OSError as error:
        raise MeshDataError(f"cannot read the point pairs file {path}: {error.strerror}")
    except json.JSONDecodeError as error:
        raise MeshDataError(f"the point pairs file {path} is not JSON: {error}")
    return pairs_from_list(entries, template, character)


def import_script_pairs(character, template):
    """Pairs given as the custom property `shapesmith_wrap_pairs` (the `--pairs` JSON form, as
    scripts write them) join the character's list when the list is empty."""
    if not len(character.shapesmith_wrap.pairs) and PAIRS_PROPERTY in character.keys():
        try:
            entries = json.loads(character[PAIRS_PROPERTY])
        except (TypeError, json.JSONDecodeError) as error:
            raise MeshDataError(f"the custom property '{PAIRS_PROPERTY}' of '{character.name}' is not JSON: {error}")
        store_pairs(character, entries, template)


def stored_pairs(character, template):
    """The pairs stored on the character (`shapesmith_wrap.pairs`, after `import_script_pairs`)
    as two (P, 3) arrays."""
    import_script_pairs(character, template)
    pairs = character.shapesmith_wrap.pairs
    template_points = np.array([p.template_co for p in pairs], dtype=np.float32).reshape(-1, 3)
    character_points = np.array([p.character_co for p in pairs], dtype=np.float32).reshape(-1, 3)
    return template_points, character_points


def store_pairs(character, entries, template, names=None):
    """Replaces the character's stored pairs with `entries` (the JSON forms); vertex entries
    keep their index."""
    template_points, character_points = pairs_from_list(entries, template, character)
    pairs = character.shapesmith_wrap.pairs
    pairs.clear()
    for i, (entry, p, q) in enumerate(zip(entries, template_points, character_points)):
        pair = pairs.add()
        pair.name = names[i] if names else f"Pair {i + 1}"
        pair.template_vertex = entry[0] if isinstance(entry[0], int) else -1
        pair.character_vertex = entry[1] if isinstance(entry[1], int) else -1
        pair.template_co, pair.character_co = p.tolist(), q.tolist()
    character.shapesmith_wrap.active_pair = max(len(pairs) - 1, 0)


def propose_pairs(template, character, progress=None):
    """The native proposal (`propose_pairs`: the same named features found on the template's
    face, from its keys and geometry, and on the character's, from its geometry alone) for
    the template and its face parts onto the character and its parts. Writes nothing."""
    if character is None or template is None:
        raise MeshDataError("pick a template and make the character the active mesh")
    if character == template or character.data == template.data:
        raise MeshDataError(f"the character '{character.name}' is the template itself: pick another mesh")
    rig, _ = read_face_rig(face_objects(template))
    character_neutral, character_triangles = read_surface(character, "character")
    return native.module().propose_pairs(
        rig.neutral, rig.deltas, rig.triangles, rig.names, character_neutral, character_triangles, progress=progress
    )


def store_proposed_pairs(character, template, proposal):
    """Replaces the character's pairs with the proposal's, named after their features, each
    end a vertex of its object (a part's vertex stays a point: the pair's index is the
    head's). Returns how many."""
    head_vertices = (len(template.data.vertices), len(character.data.vertices))
    entries, names = [], []
    for pair in proposal["pairs"]:
        ends = []
        for index, point, count in ((pair["template_vertex"], pair["template"], head_vertices[0]),
                                    (pair["character_vertex"], pair["character"], head_vertices[1])):
            ends.append(int(index) if index < count else [float(x) for x in point])
        entries.append(ends)
        names.append(pair["name"])
    store_pairs(character, entries, template, names)
    return len(entries)


def pairs_or_proposed(character, template, progress=None):
    """(template points, character points, proposal): the pairs stored on the character with
    proposal None, or, with none stored, the proposed pairs (stored on the character for the
    rigger to review) and the proposal. A proposal of fewer than 4 pairs is not stored: the
    wrap then aligns by the principal axes, and the proposal's warnings say why."""
    template_points, character_points = stored_pairs(character, template)
    if len(template_points):
        return template_points, character_points, None
    proposal = propose_pairs(template, character, progress)
    if len(proposal["pairs"]) < 4:
        proposal["warnings"].append(f"only {len(proposal['pairs'])} pairs found on both heads: none used")
        return template_points, character_points, proposal
    store_proposed_pairs(character, template, proposal)
    template_points, character_points = stored_pairs(character, template)
    return template_points, character_points, proposal


def marker_collection_name(character):
    return f"{character.name} Point Pairs"


def refresh_markers(character, template):
    """Rebuilds the collection `<character> Point Pairs`: for each stored pair a sphere empty
    on the template and one on the character, each parented to its object at the pair's local
    point and named after the pair. Removed (with its empties) when the character's
    `show_markers` is off or there is no template."""
    import bpy

    settings = character.shapesmith_wrap
    shown = settings.show_markers and template is not None and template != character
    if shown:
        import_script_pairs(character, template)  # before the markers are cleared and rebuilt
    name = marker_collection_name(character)
    collection = bpy.data.collections.get(name)
    if collection is not None:
        for marker in list(collection.objects):
            bpy.data.objects.remove(marker)
    if not shown:
        if collection is not None:
            bpy.data.collections.remove(collection)
        return
    if collection is None:
        collection = bpy.data.collections.new(name)
        bpy.context.scene.collection.children.link(collection)
    for side, obj, colour in (("template", template, (0.2, 0.5, 1.0, 1.0)), ("character", character, (1.0, 0.45, 0.1, 1.0))):
        # 0.5% of the object's world-space diagonal, in its local units (markers are parented).
        size = 0.005 * float(np.linalg.norm(obj.dimensions)) / max(max(abs(x) for x in obj.scale), 1e-12)
        for pair in settings.pairs:
            marker = bpy.data.objects.new(f"{pair.name} ({side})", None)
            marker.empty_display_type = "SPHERE"
            marker.empty_display_size = size or 0.01
            marker.show_name = True
            marker.show_in_front = True
            marker.color = colour
            collection.objects.link(marker)
            marker.parent = obj
            marker.matrix_parent_inverse.identity()
            marker.location = getattr(pair, f"{side}_co")


def wrap_object(template, character, template_points, character_points, settings=None, *, progress=None):
    """Validates and runs the native wrap with `settings` (a `settings.WrapSettings`; None:
    the defaults; its `ignore_symmetry` fits as if the meshes were not mirror-symmetric, which
    scripts/bench_wrap.py compares); returns a `Wrapped`. Writes nothing."""
    settings = settings or WrapSettings()
    started = time.perf_counter()
    if character is None or template is None:
        raise MeshDataError("pick a template and make the character the active mesh")
    if character == template or character.data == template.data:
        raise MeshDataError(f"the character '{character.name}' is the template itself: pick another mesh")
    template_neutral, template_triangles = read_surface(template, "template")
    character_neutral, character_triangles = read_surface(character, "character")
    read = time.perf_counter()
    positions, report = native.module().wrap_template(
        template_neutral,
        template_triangles,
        character_neutral,
        character_triangles,
        np.ascontiguousarray(template_points, dtype=np.float32).reshape(-1, 3),
        np.ascontiguousarray(character_points, dtype=np.float32).reshape(-1, 3),
        settings.as_native(),
        progress=progress,
    )
    seconds = {"io": read - started, "align": report["align_seconds"], "wrap": report["fit_seconds"]}
    report["warnings"] = fault_notes(face_objects(template) + face_objects(character, topology=False)) + report["warnings"]
    name_matches(report, template, character)
    return Wrapped(template, character, positions, report, seconds)


def _piece_namer(obj):
    """vertex (the face's numbering) -> the name of the face object holding it, or, for a
    face in one mesh, 'piece at vertex V'."""
    face = face_of(face_objects(obj, topology=False))

    def name(vertex, count):
        if vertex is None:
            return None
        if len(face.objects) == 1:
            return f"{obj.name} piece at vertex {vertex} ({count} vertices)"
        index = int(np.searchsorted(face.offsets, vertex, side="right") - 1)
        return face.objects[index].name

    return name


def name_matches(report, template, character):
    """Names each piece and hole row of the native report by the objects holding them
    (`template_name`, `character_name`): which pieces landed on which, which follow the skin."""
    template_name, character_name = _piece_namer(template), _piece_namer(character)
    for row in report["piece_matches"]:
        row["template_name"] = template_name(row["template_vertex"], row["template_vertices"])
        row["character_name"] = character_name(row["character_vertex"], row["character_vertices"])
    for row in report["hole_matches"]:
        if row["lids"]:
            row["template_name"] = f"{template.name}'s lids (about {template_name(row['template_vertex'], row['template_rim'])})"
            row["character_name"] = f"{character.name}'s lid hole at vertex {row['character_vertex']} ({row['character_rim']} rim vertices)"
        else:
            row["template_name"] = f"{template.name}'s opening at vertex {row['template_vertex']} ({row['template_rim']} rim vertices)"
            row["character_name"] = f"{character.name}'s at vertex {row['character_vertex']} ({row['character_rim']})"


def match_lines(report):
    """One line per template piece (fitted onto which character piece, or following the skin
    and why) and per paired opening."""
    lines = []
    for row in report["piece_matches"]:
        if row["fitted"]:
            lines.append(f"{row['template_name']} fitted onto {row['character_name']}")
        elif row["character_name"]:
            lines.append(f"{row['template_name']} follows the skin: it did not fit {row['character_name']}")
        else:
            lines.append(f"{row['template_name']} follows the skin: no character piece of its place and size")
    for row in report["hole_matches"]:
        lines.append(f"{row['template_name']} landed on {row['character_name']}")
    return lines


def wrapped_name(template, character):
    return f"{character.name}_Wrapped_{template.name}"


def show_wrapped(wrapped):
    """The wrapped template as an object `<character>_Wrapped_<template>` (template faces, no
    shape keys) placed over the character, with its distance to the character as the colour
    attribute `wrap_distance` (blue on the surface, red at 1% of the diagonal or more) and
    the raw distance / diagonal as the float attribute `wrap_distance_value`. An earlier one is
    replaced."""
    import bpy

    template, character = wrapped.template, wrapped.character
    name = wrapped_name(template, character)
    # A new mesh with the template's faces, its face parts' after the head's (same corners,
    # so the transfer sees the same topology), not a copy: a copied mesh would drag along a
    # shape-key block without owner.
    sizes, corners = joined_face_corners(face_objects(template))
    starts = np.concatenate(([0], np.cumsum(sizes)[:-1]))
    mesh = bpy.data.meshes.new(name)
    mesh.from_pydata(wrapped.positions.tolist(), [], [corners[a:a + n].tolist() for a, n in zip(starts, sizes)])
    obj = show_mesh(name, mesh, beside=character)
    character_neutral, character_triangles = read_surface(character, "character")
    _, _, distance = native.module().bind_to_surface(
        np.ascontiguousarray(wrapped.positions, dtype=np.float32), character_neutral, character_triangles
    )
    relative = distance / max(wrapped.report["diagonal"], 1e-30)
    for attribute in ("wrap_distance", "wrap_distance_value"):
        if attribute in mesh.attributes:
            mesh.attributes.remove(mesh.attributes[attribute])
    values = mesh.attributes.new("wrap_distance_value", "FLOAT", "POINT")
    values.data.foreach_set("value", relative.astype(np.float32))
    colours = mesh.color_attributes.new("wrap_distance", "FLOAT_COLOR", "POINT")
    colours.data.foreach_set("color", heat_colours(relative / HEAT_RANGE).ravel())
    mesh.color_attributes.active_color = colours
    mesh.update()
    obj.matrix_world = character.matrix_world.copy()
    obj.show_in_front = False
    character.shapesmith_wrap.wrapped = obj
    return obj


def heat_colours(t):
    """RGBA (N, 4) float32 from blue (0) through green and yellow to red (>= 1)."""
    t = np.clip(np.asarray(t, dtype=np.float64), 0.0, 1.0)
    stops = np.array([[0.05, 0.15, 0.9], [0.1, 0.8, 0.3], [0.95, 0.85, 0.1], [0.9, 0.1, 0.05]])
    position = t * (len(stops) - 1)
    lower = np.minimum(position.astype(int), len(stops) - 2)
    fraction = (position - lower)[:, None]
    rgb = stops[lower] * (1 - fraction) + stops[lower + 1] * fraction
    return np.concatenate([rgb, np.ones((len(t), 1))], axis=1).astype(np.float32)


def store_wrap(wrapped, stage):
    """Keeps the fit's summary on the character (the panel shows it)."""
    result = wrapped.character.shapesmith_wrap
    report = wrapped.report
    result.done = True
    result.stage = stage
    result.template = wrapped.template.name
    result.alignment = report["alignment"]
    result.mean_distance = report["mean_distance"]
    result.max_distance = report["max_distance"]
    result.max_pair_residual = max(report["pair_residuals"], default=0.0)
    result.symmetric = report["symmetry"]["symmetric"]
    result.symmetry_note = report["symmetry"]["reason"]
    result.worst_mirror_miss = -1.0
    result.pieces = f"{report['pieces_fitted']} of {report['pieces']} fitted, openings landed: {report['holes_paired']}"
    result.matches = "\n".join(match_lines(report))
    result.seconds = sum(wrapped.seconds.values())


def named_symmetry(symmetry, names):
    """The carry's symmetry report with each mirror pair of shapes named (`names`: the keys'),
    and the worst miss of the carried pairs (`worst`: name and miss, or None)."""
    shapes = [
        {**row, "first_name": names[row["first"]], "second_name": names[row["second"]]} for row in symmetry.get("shapes", [])
    ]
    worst = max(shapes, key=lambda row: row["carried"], default=None)
    return {**symmetry, "shapes": shapes, "worst": None if worst is None else {
        "pair": f"{worst['first_name']}/{worst['second_name']}" if worst["first"] != worst["second"] else worst["first_name"],
        "carried": worst["carried"],
        "template": worst["template"],
    }}


def store_symmetry(character, symmetry):
    """Keeps the carry's symmetry summary on the character (the panel shows it)."""
    settings = character.shapesmith_wrap
    settings.symmetric = symmetry["symmetric"]
    settings.symmetry_note = symmetry["reason"]
    worst = symmetry["worst"]
    settings.worst_mirror_miss = -1.0 if worst is None else worst["carried"]
    settings.worst_mirror_pair = "" if worst is None else worst["pair"]


def template_curve(report):
    """Per shape of the transfer report, the curve the template's own shape adds to the
    template's neutral and its whole curve (inside, between) in the character's units, as the
    native report gives them (`template_added`, `template_crossing`): the criterion's two
    allowances the carried keys are judged by, as `carry_shapes`' keyword arguments (float64
    (K, 2) each)."""
    def parts(key):
        rows = [[row[key]["inside"], row[key]["between"]] for row in report["penetration"]]
        return np.asarray(rows, dtype=np.float64).reshape(-1, 2)

    return {"template_added": parts("template_added"), "template_crossing": parts("template_crossing")}


def character_rows(report, character_penetration):
    """The transfer report's per-shape penetration rows, for the keys carried onto the
    character: its own curve lengths, the template's beside them, and the criterion of method, section 3 as
    the native carry judged it on the character's mesh (`excess`, per part). What the
    contact solve did on the wrapped template stays with each row (`contact`), what the
    carry's did on the character beside it (`carry_collisions`, when it ran)."""
    carry_collisions = report.get("carry", {}).get("collisions") or []
    rows = []
    for k, (wrapped_row, measured, excess, allowed) in enumerate(
        zip(
            report["penetration"],
            character_penetration["shapes"],
            character_penetration["excess"],
            character_penetration["allowed"],
        )
    ):
        rows.append(
            {
                "name": wrapped_row["name"],
                "length": measured["length"],
                "pairs": measured["pairs"],
                "between_pieces": measured["between_pieces"],
                "template_length": wrapped_row["template_length"],
                "template_pairs": wrapped_row["template_pairs"],
                "template_between_pieces": wrapped_row["template_between_pieces"],
                "template_added": wrapped_row["template_added"],
                "template_crossing": wrapped_row["template_crossing"],
                "contact": wrapped_row.get("contact"),
                "carry_collisions": carry_collisions[k] if k < len(carry_collisions) else None,
                "allowed": allowed,
                "excess": excess,
            }
        )
    return rows


def carry_onto_character(template, character, wrapped_object, transfer_settings=None, *, seconds=None, symmetric=True,
                         collision_pass=True, progress=None, truth=None):
    """Transfers the template's keys onto the wrapped template object (same topology, with
    `transfer_settings`, a `settings.TransferSettings`; None: the defaults), then carries
    them onto the character's own vertices. Returns a `transfer.Transfer` whose target is the
    character, ready for `shape_keys.write_transferred_keys`, with `report["stage_seconds"]`;
    writes nothing. `symmetric=False` carries as if the meshes were not mirror-symmetric (the
    report's `symmetry` still has the mirror misses); `collision_pass=False` carries without
    the carry's collision pass (a benchmark's carry alone). `report["looks"]` has where riggers look
    first per key (`looks.look_lines` words it); with `truth` (the same-topology keys on the
    character, float (K, Nc, 3), a benchmark's) each key's roughness beside the truth's."""
    started = time.perf_counter()
    transfer_settings = transfer_settings or TransferSettings()
    # One bar over both solves: the transfer its first half, the carry the second.
    halves = (None, None) if progress is None else (lambda f: progress(0.5 * f), lambda f: progress(0.5 + 0.5 * f))
    onto_wrapped = transfer_object(template, wrapped_object, transfer_settings, joined_target=True, progress=halves[0])
    transferred = time.perf_counter()
    character_neutral, character_triangles = read_surface(character, "character")
    wrapped_neutral, wrapped_triangles = rest_positions(wrapped_object), read_triangles(wrapped_object)
    # The carried keys are judged on the character's own mesh by the criterion the transfer
    # used, and the carry's collision pass holds them to it (its margin the contact distance
    # when the transfer keeps surfaces apart). Without it an eyeball carried onto the template
    # itself turns through its lid (eyeLookUpLeft); with it the carry is further from the
    # same-topology truth (1.39e-3 of the diagonal against 1.18e-3 on the decimated identity).
    contact = transfer_settings.transfer.contact
    carry = CarrySettings(collision_pass=collision_pass, symmetrize=symmetric)
    # The template's rest gives the carry its mirror map: with a symmetric character each
    # carried shape is averaged with the mirror of its partner's; its own keys give each
    # matched piece its motion (an eyeball turns as the template's does).
    template_rig, _ = read_face_rig(face_objects(template))
    template_neutral = template_rig.neutral  # the reference keys in the head's space, as read_surface reads them
    row = {name: k for k, name in enumerate(template_rig.names)}
    template_shapes = template_rig.deltas[[row[name] for name in onto_wrapped.names]]
    if contact is not None:
        carry.collision_margin = contact.distance
    deltas, carry_report = native.module().carry_shapes(
        np.ascontiguousarray(wrapped_neutral),
        wrapped_triangles,
        np.ascontiguousarray(onto_wrapped.deltas, dtype=np.float32),
        character_neutral,
        character_triangles,
        carry.as_native(),
        template_neutral=np.ascontiguousarray(template_neutral, dtype=np.float32),
        template_shapes=np.ascontiguousarray(template_shapes, dtype=np.float32),
        progress=halves[1],
        **template_curve(onto_wrapped.report),
    )
    carried = time.perf_counter()
    report = dict(onto_wrapped.report)
    report["carry"] = carry_report
    # Where riggers look first (eyes closing, the mouth opening, smooth lines and keys), per
    # key; with `truth` (the same-topology keys on the character, a bench's) its roughness too.
    looking = time.perf_counter()
    report["looks"] = native.module().look_at_keys(
        np.ascontiguousarray(template_neutral, dtype=np.float32),
        np.ascontiguousarray(template_shapes, dtype=np.float32),
        wrapped_triangles,
        list(onto_wrapped.names),
        np.ascontiguousarray(wrapped_neutral),
        np.ascontiguousarray(onto_wrapped.deltas, dtype=np.float32),
        character_neutral,
        character_triangles,
        deltas,
        None if truth is None else np.ascontiguousarray(truth, dtype=np.float32),
    )
    looked = time.perf_counter()
    report["diagonal"] = float(np.linalg.norm(character_neutral.max(0) - character_neutral.min(0)))
    # The keys as the rigger gets them: judged on the character's own mesh, not on the
    # wrapped template the transfer (and its collision pass) worked on.
    report["wrapped_penetration"] = report["penetration"]
    character_penetration = carry_report.pop("penetration")
    report["penetration"] = character_rows(report, character_penetration)
    report["neutral_penetration"] = character_penetration["neutral"]
    report["symmetry"] = named_symmetry(carry_report.pop("symmetry"), onto_wrapped.names)
    stage_seconds = dict(seconds or {})
    stage_seconds["io"] = stage_seconds.get("io", 0.0) + onto_wrapped.report["seconds"]["read"]
    stage_seconds["transfer"] = transferred - started - onto_wrapped.report["seconds"]["read"]
    stage_seconds["carry"] = carried - transferred
    stage_seconds["looks"] = looked - looking
    stage_seconds["penetration"] = time.perf_counter() - carried - stage_seconds["looks"]
    report["stage_seconds"] = stage_seconds
    groups = carried_vertex_groups(template, onto_wrapped.names, (wrapped_neutral, wrapped_triangles), character_neutral)
    result = Transfer(
        template, character, onto_wrapped.names, character_neutral, deltas, report, {}, list(onto_wrapped.warnings), groups
    )
    result.pieces = character_pieces(result)
    return result


def character_pieces(result):
    """The carried keys for writing, one piece per object of a character with face parts: the
    head takes every key, each part the keys that move it; each key its settings from the
    template object that has it (the head's first). None for a character alone."""
    # The character was read as a surface (`read_surface`): its topology is not checked here
    # either (a loose vertex moves with the surface point nearest it, as in every tool).
    character_face = face_of(face_objects(result.target, topology=False))
    if len(character_face.objects) == 1:
        return []
    origin = {}
    for source in face_objects(result.source):
        keys = source.data.shape_keys
        for name in keys.key_blocks.keys() if keys is not None else ():
            origin.setdefault(name, source)
    pieces = []
    for index, obj in enumerate(character_face.objects):
        own = result.deltas[:, character_face.vertices(index)]
        rows = [k for k in range(len(result.names)) if index == 0 or np.any(own[k] != 0.0)]
        names = [result.names[k] for k in rows]
        piece = Transfer(
            result.source, obj, names, rest_positions(obj), np.ascontiguousarray(character_face.to_local_deltas(index, own[rows])), {},
            vertex_groups={name: weights[character_face.vertices(index)] for name, weights in result.vertex_groups.items()},
        )
        piece.key_sources = {name: origin[name] for name in names}
        pieces.append(piece)
    return pieces


def carried_vertex_groups(template, names, wrapped_surface, character_neutral):
    """The template's vertex groups that the keys `names` are masked by, carried onto the
    character (name -> float32 weights (Nc,)): each character vertex (`character_neutral`)
    takes the weights at its closest point on the wrapped template (`wrapped_surface`:
    positions, triangles), mixed barycentrically (the binding of `bind_to_surface`)."""
    objects = face_objects(template)
    face = face_of(objects)
    wanted = sorted(
        {
            block.vertex_group
            for obj in objects
            if obj.data.shape_keys is not None
            for block in obj.data.shape_keys.key_blocks
            if block.name in names and block.vertex_group in obj.vertex_groups
        }
    )
    if not wanted:
        return {}
    weights = np.zeros((len(wanted), int(face.offsets[-1])), dtype=np.float32)
    for index, obj in enumerate(objects):
        row = {obj.vertex_groups[name].index: k for k, name in enumerate(wanted) if name in obj.vertex_groups}
        start = int(face.offsets[index])
        for vertex in obj.data.vertices:
            for membership in vertex.groups:
                if membership.group in row:
                    weights[row[membership.group], start + vertex.index] = membership.weight
    positions, triangles = wrapped_surface
    triangle, barycentric, _ = native.module().bind_to_surface(character_neutral, positions, triangles)
    carried = np.einsum("vc,gvc->gv", barycentric, weights[:, triangles[triangle]])
    return {name: carried[k].astype(np.float32) for k, name in enumerate(wanted)}


def remove_object(obj):
    import bpy

    mesh = obj.data
    bpy.data.objects.remove(obj)
    if mesh.users == 0:
        bpy.data.meshes.remove(mesh)


def summary_lines(wrapped):
    report = wrapped.report
    lines = [
        f"'{wrapped.template.name}' wrapped onto '{wrapped.character.name}' ({report['alignment']}, {report['pairs']} pairs): "
        f"mean distance {100 * report['mean_distance']:.3f}% of the diagonal, max {100 * report['max_distance']:.2f}%",
    ]
    similarity = report["similarity"]
    lines.append(f"similarity: scale {similarity['scale']:.4g}, translation {[round(x, 4) for x in similarity['translation']]}")
    if report["pair_residuals"]:
        lines.append(f"pair residuals: max {100 * max(report['pair_residuals']):.3f}% of the diagonal")
    if report["pieces"]:
        lines.append(
            f"pieces (eyes, teeth, ...): {report['pieces_fitted']} of {report['pieces']} fitted onto the character's own, "
            "the others follow the skin"
        )
    lines.append(f"openings (ear canals, lid holes, open lips) landed on the character's: {report['holes_paired']}")
    symmetry = report["symmetry"]
    if symmetry["symmetric"]:
        lines.append(
            f"symmetric fit: {100 * symmetry['character_coverage']:.0f}% of the character's skin mirrors onto it, "
            f"{symmetry['mirrored_pairs']} mirrored point pairs added"
        )
    else:
        lines.append(f"fitted without symmetry: {symmetry['reason']}")
    lines += ["  " + line for line in match_lines(report)]
    return lines + [f"warning: {w}" for w in report["warnings"]]
