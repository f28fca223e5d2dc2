"""Writes transferred shape keys (and their drivers) onto a target: the only place Transfer
changes a mesh. Everything that can be refused is checked by `plan_keys` before the first
write."""

import zlib

import numpy as np

from .drivers import copy_driver, driver_targets, key_drivers
from .mesh_arrays import MeshDataError, group_weights, report_key
from .names import counterpart


def plan_keys(target, names, overwrite, name_map=None):
    """(written, skipped, onto): the template keys to write in order, those kept because the
    target already has that key and `overwrite` is off, and the target's name for each
    template key: its own key meaning the same shape in another convention
    (`names.counterpart`: `eyeBlinkLeft` onto an existing `EyeBlink_L`), else the
    template's name."""
    keys = target.data.shape_keys
    existing = list(keys.key_blocks.keys()) if keys is not None else []
    onto, claimed = {}, set()
    for name in names:
        found = counterpart(name, existing, name_map)
        onto[name] = found if found is not None and found not in claimed else name
        claimed.add(onto[name])
    if overwrite and keys is not None and keys.reference_key.name in onto.values():
        raise MeshDataError(
            f"the template has a shape key named '{keys.reference_key.name}', the name of the target's reference key: "
            "rename one of them (overwriting the reference key would move the whole head)"
        )
    written = [n for n in names if overwrite or onto[n] not in existing]
    skipped = [n for n in names if not overwrite and onto[n] in existing]
    return written, skipped, onto


def _copy_key_settings(block, source_block, keys, source_keys, onto):
    block.slider_min = -10.0  # the lowest allowed, so any slider_max can be set first
    block.slider_max = source_block.slider_max
    block.slider_min = source_block.slider_min
    block.vertex_group = source_block.vertex_group
    block.mute = source_block.mute
    block.interpolation = source_block.interpolation
    relative = source_block.relative_key
    mapped = keys.key_blocks.get(onto.get(relative.name, relative.name)) if relative != source_keys.reference_key else None
    block.relative_key = mapped if mapped is not None and mapped != block else keys.reference_key


def write_vertex_groups(target, groups, overwrite):
    """Writes each group of `groups` (name -> weights (N,)) on `target`: vertices of weight 0
    are left out of it. A group the target already has is kept as it is unless `overwrite`
    (then its weights are replaced). Returns the warnings."""
    warnings = []
    for name, weights in groups.items():
        group = target.vertex_groups.get(name)
        if group is not None and not overwrite:
            warnings.append(f"vertex group '{name}' was already on '{target.name}': kept as it was (overwrite replaces it)")
            continue
        if group is None:
            group = target.vertex_groups.new(name=name)
        else:
            group.remove(list(range(len(target.data.vertices))))
        for vertex in np.flatnonzero(weights > 0.0):
            group.add([int(vertex)], float(weights[vertex]), "REPLACE")
    return warnings


def unmasked(delta, weights):
    """The delta to store on a key its vertex group masks so that Blender shows `delta`: the
    tools read and transfer the masked shape (delta times weight), and Blender multiplies the
    stored key by the weight again, so the stored key is `delta / weight` where the weight is
    not 0 (where it is 0 Blender shows nothing whatever is stored)."""
    if weights is None:
        return delta
    scale = np.ones_like(weights)
    np.divide(1.0, weights, out=scale, where=weights > 0.0)
    return delta * scale[:, None]


def write_transferred_keys(transfer, overwrite=False, copy_drivers=False, *, keep_sculpted=False, name_map=None,
                           driver_map=None):
    """Writes `transfer` (a solved `transfer.Transfer`) onto its target: a Basis first when
    the target has no shape keys; then each template key with the template's name (or the
    target's own name for that shape, `plan_keys`), slider range, vertex group, mute,
    interpolation and relative key (mapped by name, else the reference key); new keys at
    value 0. Vertex groups the transfer carries are written first. Existing keys and groups
    are kept unless `overwrite`; with `keep_sculpted`, an overwritten key keeps the user's
    edits since the last transfer wrote it (`sculpted_changes`). A corrective (a key relative
    to another) is written on top of its base on the target. A face in several objects is
    written piece by piece (`Transfer.pieces`), each object its own keys, once every piece
    has been checked. Drivers go to the target's rig (`drivers.driver_targets`, `driver_map`
    the user's {template object: target object}). Returns (written, skipped, warnings), names
    over all objects in the transfer's order; `transfer.onto` gets the target's name of each
    key written."""
    pieces = transfer.pieces or [transfer]
    plans = [plan_keys(piece.target, piece.names, overwrite, name_map) for piece in pieces]
    # Drivers re-targeted from every template object (and its mesh, keys and rig) to its counterpart.
    mapping = driver_targets([(piece.source, piece.target) for piece in pieces], driver_map) if copy_drivers else {}
    written, skipped, warnings = set(), set(), []
    transfer.onto = {}
    for piece, plan in zip(pieces, plans):
        warnings += _write_piece(piece, plan, copy_drivers, mapping, overwrite, keep_sculpted)
        written.update(plan[0])
        skipped.update(plan[1])
        transfer.onto.update({n: plan[2][n] for n in plan[0]})
    return [n for n in transfer.names if n in written], [n for n in transfer.names if n in skipped], warnings


# The hidden point attribute holding a key's delta as Transfer last wrote it (a key's name
# can be as long as an attribute's may be, so the attribute is named by its checksum).
def _last_written_attribute(name):
    return f".shapesmith transferred {zlib.crc32(name.encode()):08x}"


def key_delta(keys, block):
    """A key's stored delta from its relative key, float32 (N, 3)."""
    n = len(block.points)
    co, base = np.empty(n * 3, dtype=np.float32), np.empty(n * 3, dtype=np.float32)
    block.points.foreach_get("co", co)
    relative = block.relative_key if block.relative_key != block else keys.reference_key
    relative.points.foreach_get("co", base)
    return (co - base).reshape(n, 3)


def sculpted_changes(mesh, block):
    """The user's edits of `block` since Transfer last wrote it: its stored delta minus the
    one Transfer wrote (kept in a hidden attribute), or None when Transfer never wrote it."""
    attribute = mesh.attributes.get(_last_written_attribute(block.name))
    if attribute is None or attribute.domain != "POINT" or attribute.data_type != "FLOAT_VECTOR":
        return None
    last = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    attribute.data.foreach_get("vector", last)
    return key_delta(mesh.shape_keys, block) - last.reshape(-1, 3)


def remember_written(mesh, name, delta):
    """Keeps the delta Transfer wrote on key `name`, for Keep Sculpted Changes next time."""
    attribute = mesh.attributes.get(_last_written_attribute(name))
    if attribute is None:
        attribute = mesh.attributes.new(_last_written_attribute(name), "FLOAT_VECTOR", "POINT")
    attribute.data.foreach_set("vector", np.ascontiguousarray(delta, dtype=np.float32).ravel())


def _base_first(names, source_blocks):
    """`names` with each corrective after the key it is relative to."""
    placed, ordered = set(), []
    pending = list(names)
    while pending:
        ready = [n for n in pending if source_blocks[n].relative_key.name not in pending or source_blocks[n].relative_key.name == n]
        ready = ready or pending[:1]  # a cycle of Relative To keys: Blender cannot show it either
        ordered += ready
        placed.update(ready)
        pending = [n for n in pending if n not in placed]
    return ordered


def _write_piece(transfer, plan, copy_drivers, mapping, overwrite, keep_sculpted):
    written, skipped, onto = plan
    target = transfer.target
    # Each key takes its settings from the template object that has it (a character's part
    # may take keys of several template objects).
    origin = {name: transfer.key_sources.get(name, transfer.source) for name in written}
    drivers = {}
    if copy_drivers:
        for source in dict.fromkeys(origin.values()):
            drivers.update(key_drivers(source, [n for n in written if origin[n] == source]))
    source_blocks = {name: origin[name].data.shape_keys.key_blocks[name] for name in written}
    warnings = write_vertex_groups(target, transfer.vertex_groups, overwrite)
    warnings += [
        f"vertex group '{source_blocks[n].vertex_group}' of shape key '{n}' is not on '{target.name}'"
        for n in written
        if source_blocks[n].vertex_group and source_blocks[n].vertex_group not in target.vertex_groups
    ]
    if not written and not skipped:
        return warnings  # a part without keys of its own (an eye that never moves)
    if target.data.shape_keys is None:
        target.shape_key_add(name="Basis", from_mix=False).value = 0.0
    keys = target.data.shape_keys
    created = set()
    for name in written:  # all keys first, so relative keys can name keys later in the list
        if onto[name] not in keys.key_blocks:
            target.shape_key_add(name=onto[name], from_mix=False)
            created.add(name)
    order = {name: k for k, name in enumerate(transfer.names)}
    masks = group_weights(target, [source_blocks[n].vertex_group for n in written if source_blocks[n].vertex_group])
    edits = {}
    if keep_sculpted:
        for name in written:
            if name not in created:
                edits[name] = sculpted_changes(target.data, keys.key_blocks[onto[name]])
        unknown = [onto[n] for n, change in edits.items() if change is None]
        if unknown:
            warnings.append(f"no transfer wrote {', '.join(unknown)} before: replaced as a whole (no sculpted changes known)")
    n = len(target.data.vertices)
    base = np.empty(n * 3, dtype=np.float32)
    for done, name in enumerate(_base_first(written, source_blocks), start=1):
        block = keys.key_blocks[onto[name]]
        _copy_key_settings(block, source_blocks[name], keys, source_blocks[name].id_data, onto)
        delta = unmasked(transfer.deltas[order[name]], masks.get(source_blocks[name].vertex_group))
        if edits.get(name) is not None:
            delta = delta + edits[name]
        # A corrective goes on top of its base as the target has it (method, section 0: its delta from its base).
        relative = block.relative_key if block.relative_key != block else keys.reference_key
        if relative == keys.reference_key:
            base[:] = transfer.target_neutral.ravel()
        else:
            relative.points.foreach_get("co", base)
        block.points.foreach_set("co", (base.reshape(n, 3) + delta).ravel())
        remember_written(target.data, block.name, delta - (edits.get(name) if edits.get(name) is not None else 0.0))
        if name in created:
            block.value = 0.0  # shape_key_add defaults to 1.0 in Blender 5.x
        report_key(done, len(written), writing=True)
    mapping = {**mapping, **{o.data.shape_keys: keys for o in set(origin.values())}}
    for fcurve in drivers.values():
        warnings += copy_driver(fcurve, keys, mapping, onto)
    target.data.update()
    return warnings
