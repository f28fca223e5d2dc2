"""Generate ARKit Keys: the wrap's whole chain in one call on a character as it comes. The
template (the chosen one, else the bundled ARKit template, added), point pairs (the stored
ones, else proposed), the wrap, the transfer onto the wrapped template and the carry onto the
character, then the keys written; the operator and `scripts/batch.py generate` both call
`generate_keys`.

A character that is more than a head (a full body) is wrapped on its head region only: the
user's vertex group, else the part above the neck (`head_region`). The chain then runs on a
temporary copy of the region's faces in the character's space, and the carried keys go back
onto the character's own vertices, every vertex outside the region unmoved. Teeth, eyes and
tongue in objects of their own are taken as face parts by their place (`parts_by_place`) when
the character lists none.

Nothing is kept unless everything succeeded: what the chain made on the way (the template it
added, the region's copy, a new wrapped template) is removed and what it replaced put back
on any error or cancel (`blender.jobs`).
"""

from dataclasses import dataclass, field

import numpy as np

from . import bundled_template
from .face_parts import face_objects, stored_parts, store_parts
from .mesh_arrays import MeshDataError, group_weights, read_triangles, rest_positions
from .shape_keys import write_transferred_keys
from .transfer import face_corners, store_transfer
from .wrap import (
    carry_onto_character, propose_pairs, remove_object, show_wrapped, store_proposed_pairs, store_symmetry, store_wrap,
    stored_pairs, wrap_object, wrapped_name,
)

# Horizontal sections of the character (world Z up) for finding its neck: enough for a neck
# to span several on a full body, few enough that each holds many vertices.
SECTIONS = 64
# A section is the neck's only when it is this much narrower than the head above it.
NECK_NARROWING = 0.8
# Progress: the proposal, the wrap and the transfer with the carry, as shares of the bar.
STAGES = {"propose": (0.0, 0.1), "wrap": (0.1, 0.3), "carry": (0.4, 0.6)}


@dataclass
class Generated:
    template: object
    character: object
    written: list
    skipped: list
    warnings: list
    wrap_report: dict
    transfer_report: dict
    proposal: dict = None
    region: str = "whole mesh"
    region_vertices: int = 0
    parts_found: list = field(default_factory=list)
    template_added: bool = False


def world_rest(obj):
    positions = rest_positions(obj).astype(np.float64)
    matrix = np.array(obj.matrix_world, dtype=np.float64)
    return positions @ matrix[:3, :3].T + matrix[:3, 3]


def head_region(character):
    """The vertices of the character's head (bool (N,)), or None when the whole mesh is a head.

    The head is what lies above the neck, and the neck is the narrowest horizontal section
    (world Z up, `SECTIONS` of the height) that is narrower than the head above it by
    `NECK_NARROWING` with something wider than that head below it (the shoulders). A head or
    a bust has no such section: nothing below its neck is wider than the head."""
    points = world_rest(character)
    z = points[:, 2]
    top, height = z.max(), max(float(np.ptp(z)), 1e-30)
    triangles = read_triangles(character)
    edges = np.unique(np.sort(np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]], triangles[:, [2, 0]]]), axis=1), axis=0)
    a, b = points[edges[:, 0]], points[edges[:, 1]]
    width = np.zeros(SECTIONS)
    for k in range(SECTIONS):
        # The surface's section by the plane through the middle of slice k: where its edges cross it.
        level = top - (k + 0.5) * height / SECTIONS
        crossing = (a[:, 2] - level) * (b[:, 2] - level) < 0.0
        if crossing.any():
            t = (level - a[crossing, 2]) / (b[crossing, 2] - a[crossing, 2])
            cut = a[crossing, :2] + t[:, None] * (b[crossing, :2] - a[crossing, :2])
            width[k] = np.sqrt(np.prod(np.ptp(cut, axis=0)))  # side of the section's box, as a square
    above = np.maximum.accumulate(width)
    below = np.maximum.accumulate(width[::-1])[::-1]
    candidates = [k for k in range(1, SECTIONS - 1)
                  if width[k] > 0.0 and width[k] < NECK_NARROWING * above[k - 1] and below[k + 1] > above[k - 1]]
    if not candidates:
        return None
    neck = min(candidates, key=lambda k: width[k])
    return z > top - (neck + 0.5) * height / SECTIONS


def region_of(character, group):
    """(vertices in the region (bool (N,)), its description), from the vertex group `group`
    when given (weight above 0), else `head_region`."""
    if group:
        if group not in character.vertex_groups:
            names = ", ".join(g.name for g in character.vertex_groups) or "none"
            raise MeshDataError(f"'{character.name}' has no vertex group '{group}' (its groups: {names})")
        inside = group_weights(character, [group])[group] > 0.0
        if not inside.any():
            raise MeshDataError(f"the vertex group '{group}' of '{character.name}' holds no vertex")
        return inside, f"vertex group '{group}'"
    inside = head_region(character)
    return inside, "whole mesh" if inside is None else "head (above the neck)"


def parts_by_place(character, inside, exclude):
    """Mesh objects lying within the head region's box (world space, with 5% of its diagonal
    to spare): the character's teeth, eyes and tongue in objects of their own."""
    import bpy
    from mathutils import Vector

    points = world_rest(character)
    if inside is not None:
        points = points[inside]
    low, high = points.min(axis=0), points.max(axis=0)
    spare = 0.05 * float(np.linalg.norm(high - low))
    found = []
    for obj in bpy.context.scene.objects:
        if obj.type != "MESH" or obj in exclude or obj.data == character.data or not len(obj.data.vertices):
            continue
        if bundled_template.PROPERTY in obj.keys() or obj.name.startswith(f"{character.name}_Wrapped_"):
            continue
        corners = np.array([obj.matrix_world @ Vector(corner) for corner in obj.bound_box])
        if np.all(corners >= low - spare) and np.all(corners <= high + spare):
            found.append(obj)
    return sorted(found, key=lambda o: o.name)


def region_copy(character, inside):
    """A temporary object with the faces of `character` whose corners all lie in the region,
    in the character's space and with its face parts. Returns (object, the character's
    vertex of each of its vertices)."""
    import bpy

    sizes, corners = face_corners(character)
    starts = np.concatenate(([0], np.cumsum(sizes)[:-1]))
    kept = np.logical_and.reduceat(inside[corners], starts)
    if not kept.any():
        raise MeshDataError(f"the head region of '{character.name}' holds no whole face")
    faces = [corners[a:a + n] for a, n, keep in zip(starts, sizes, kept) if keep]
    used = np.unique(np.concatenate(faces))
    local = np.full(len(inside), -1)
    local[used] = np.arange(len(used))
    mesh = bpy.data.meshes.new(f"{character.name} head region")
    mesh.from_pydata(rest_positions(character)[used].tolist(), [], [local[f].tolist() for f in faces])
    copy = bpy.data.objects.new(mesh.name, mesh)
    bpy.context.scene.collection.objects.link(copy)
    copy.matrix_world = character.matrix_world.copy()
    store_parts(copy, stored_parts(character))
    return copy, used


def onto_character(result, character, used):
    """The carried keys of the region's copy put on the character's own vertices (zero outside
    the region), the face parts' after them as they were."""
    copy_count = len(used)
    count = len(character.data.vertices)
    deltas = np.zeros((len(result.names), count + result.deltas.shape[1] - copy_count, 3), dtype=np.float32)
    deltas[:, used] = result.deltas[:, :copy_count]
    deltas[:, count:] = result.deltas[:, copy_count:]
    groups = {}
    for name, weights in result.vertex_groups.items():
        full = np.zeros(deltas.shape[1], dtype=np.float32)
        full[used], full[count:] = weights[:copy_count], weights[copy_count:]
        groups[name] = full[:count] if len(weights) == copy_count else full
    result.target, result.deltas, result.vertex_groups = character, deltas, groups
    result.target_neutral = rest_positions(character)
    from .wrap import character_pieces

    result.pieces = character_pieces(result)
    return result


def _staged(progress, stage):
    if progress is None:
        return None
    start, span = STAGES[stage]
    return lambda fraction: progress(start + span * fraction)


def generate_keys(character, template=None, *, region=None, transfer_settings=None, keep_sculpted=False, progress=None,
                  location=(0.0, 0.0, 0.0)):
    """The 52 keys (the template's) on `character`; see the module's doc. `progress(fraction)`
    is the native callback (False stops: the native `CancelledError`, the file as it was).
    Returns a `Generated`."""
    import bpy

    if character is None or character.type != "MESH":
        raise MeshDataError("select the character (a mesh)")
    added = template is None
    if added:
        template = bundled_template.add_template(bpy.context.scene, location)
    if character == template or character.data == template.data:
        raise MeshDataError(f"the character '{character.name}' is the template itself: select the character")
    made, restore = [], []
    listed = stored_parts(character)
    try:
        face_objects(character, topology=False)
        inside, described = region_of(character, region)
        template_objects = face_objects(template)
        found = [] if listed else parts_by_place(character, inside, {character, *template_objects})
        if found:
            store_parts(character, found)
            restore.append(lambda: store_parts(character, []))
        work, used = character, None
        if inside is not None and not inside.all():
            work, used = region_copy(character, inside)
            made.append(work)
        template_points, character_points = stored_pairs(character, template)
        proposal = None
        if not len(template_points):
            proposal = propose_pairs(template, work, _staged(progress, "propose"))
            if len(proposal["pairs"]) >= 4:
                if work is character:
                    restore.append(character.shapesmith_wrap.pairs.clear)
                store_proposed_pairs(work, template, proposal)
                template_points, character_points = stored_pairs(work, template)
            else:
                proposal["warnings"].append(f"only {len(proposal['pairs'])} pairs found on both heads: none used")
        wrapped = wrap_object(template, work, template_points, character_points, progress=_staged(progress, "wrap"))
        name = wrapped_name(template, character)
        previous = bpy.data.objects.get(name)
        if previous is not None:
            previous.name = f"{name} (previous)"
            restore.append(lambda: setattr(previous, "name", name))
        shown = character.shapesmith_wrap.wrapped
        restore.append(lambda: setattr(character.shapesmith_wrap, "wrapped", shown))
        wrapped_object = show_wrapped(wrapped)
        made.append(wrapped_object)
        result = carry_onto_character(template, work, wrapped_object, transfer_settings, progress=_staged(progress, "carry"))
        if used is not None:
            result = onto_character(result, character, used)
        written, skipped, warnings = write_transferred_keys(result, overwrite=True, keep_sculpted=keep_sculpted)
    except BaseException:
        for obj in reversed(made):
            remove_object(obj)
        for undo in reversed(restore):
            undo()
        if added:
            bundled_template.remove_template(template)
        raise
    # Everything succeeded: the pairs, the fit and the wrapped template stay with the character.
    if work is not character:
        if proposal is not None and len(proposal["pairs"]) >= 4:
            store_proposed_pairs(character, template, region_pairs(proposal, used, len(work.data.vertices), len(character.data.vertices)))
        remove_object(work)
    if previous is not None:
        remove_object(previous)
    wrapped_object.name = name
    try:
        wrapped_object.hide_set(True)  # kept for Transfer onto Character and a look at the fit
    except RuntimeError:  # not in the view layer
        pass
    wrapped.character = character
    store_wrap(wrapped, "WRAP")
    character.shapesmith_wrap.wrapped = wrapped_object
    character.shapesmith_wrap.written = len(written)
    store_symmetry(character, result.report["symmetry"])
    store_transfer(result, written, skipped)
    return Generated(
        template, character, written, skipped, list(result.warnings) + warnings + wrapped.report["warnings"]
        + (proposal or {}).get("warnings", []), wrapped.report, result.report, proposal, described,
        int(len(character.data.vertices) if used is None else len(used)), [o.name for o in found], added,
    )


def region_pairs(proposal, used, copy_count, count):
    """The proposal made on the region's copy, its character ends renumbered as the
    character's own vertices (a face part's vertex after the character's)."""
    pairs = []
    for pair in proposal["pairs"]:
        index = int(pair["character_vertex"])
        index = int(used[index]) if index < copy_count else count + index - copy_count
        pairs.append({**pair, "character_vertex": index})
    return {**proposal, "pairs": pairs}


def report_lines(generated):
    """What the operator and batch print: the outcome, the region, the parts and the fit."""
    fit = generated.wrap_report
    lines = [
        f"{len(generated.written)} ARKit keys written onto '{generated.character.name}' from '{generated.template.name}'"
        + (" (the bundled template, added to the scene)" if generated.template_added else ""),
        f"region: {generated.region} ({generated.region_vertices} vertices); the others unmoved",
        f"fit: mean distance {100 * fit['mean_distance']:.3f}% of the diagonal, max {100 * fit['max_distance']:.2f}%",
    ]
    if generated.parts_found:
        lines.append(f"face parts found by their place: {', '.join(generated.parts_found)}")
    if generated.proposal is not None:
        lines.append(f"point pairs proposed: {len(generated.proposal['pairs'])} (move any that are off and generate again)")
    return lines
