"""The production-size rig of `bench_production.py`, built by code from the sample: the
bundled head subdivided `level` times (4.9k, 19k, 77k vertices) with `keys` shape keys: the 52
ARKit units, MakeHuman's 34 expression units (`makehuman.expression_units`) and combination
shapes (sums of two ARKit units) up to the count; beside it the transfer target (Target_OldMan
subdivided alike) and a wrap character of other topology (Target_YoungWoman subdivided alike,
collapse-decimated to 45% of its faces, in centimetres and Y up, with 10 point pairs known by
construction, as the sample's character). Cached outside git under
`$SHAPESMITH_CACHE/production/`, keyed by this file's and the sample's digests."""

import hashlib
import os
import sys

import bpy
import bmesh  # noqa: I001  (bmesh loads only after bpy)
import numpy as np

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
import makehuman  # noqa: E402
import sample_blend  # noqa: E402

TARGET, CHARACTER_IDENTITY = "Target_OldMan", "Target_YoungWoman"
CHARACTER = {"ratio": 0.45, "scale": 100.0, "location": (0.0, 0.0, 0.0)}
# The combination shapes: ARKit unit i with unit i + 17, then with unit i + 13 (mod 52).
COMBINATION_OFFSETS = (17, 13)


def rig_version():
    """Digest of this file and of the sample's: a changed rig or sample never reuses an older
    cached file."""
    with open(os.path.abspath(__file__), "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()[:8] + "-" + makehuman.sample_version()


def cached_rig_path(level, keys):
    return os.path.join(makehuman.cache_dir(), "production", f"head-{level}x-{keys}keys-{rig_version()}.blend")


def combination_pairs(count, units=52):
    pairs = []
    for offset in COMBINATION_OFFSETS:
        pairs += [(i, (i + offset) % units) for i in range(units)]
    return pairs[:count]


def add_keys(obj, names, positions):
    for name, co in zip(names, positions):
        key = obj.shape_key_add(name=name, from_mix=False)
        key.points.foreach_set("co", np.ascontiguousarray(co, dtype=np.float32).ravel())
        key.value = 0.0  # shape_key_add defaults to 1.0 in Blender 5.x


def subdivide(obj, levels):
    """Every edge cut once per level (bmesh, grid fill, as bench_transfer's denser heads);
    shape keys are bmesh layers, so each is subdivided as the basis is. The original vertices
    keep their indices (new ones are appended), which the point pairs rely on."""
    if not levels:
        return
    mesh = bmesh.new()
    mesh.from_mesh(obj.data)
    for _ in range(levels):
        bmesh.ops.subdivide_edges(mesh, edges=mesh.edges[:], cuts=1, use_grid_fill=True)
    mesh.to_mesh(obj.data)
    mesh.free()
    obj.data.update()


def positions(obj):
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", co)
    return co.reshape(-1, 3)


def build_rig(level, keys, path):
    """Writes `path`: Template (`keys` shape keys, `level` subdivisions), the transfer target
    and the wrap character."""
    head = makehuman.build_head()
    bpy.ops.wm.open_mainfile(filepath=sample_blend.cached_sample())
    template = bpy.data.objects["Template"]
    arkit = list(head["shape_names"])
    extra = max(0, keys - len(arkit))
    unit_names, unit_deltas = makehuman.expression_units(head)
    units = min(extra, len(unit_names))
    add_keys(template, unit_names[:units], head["neutral"] + unit_deltas[:units])
    pairs = combination_pairs(extra - units, len(arkit))
    add_keys(
        template, [f"{arkit[a]}+{arkit[b]}" for a, b in pairs], [head["neutral"] + head["deltas"][a] + head["deltas"][b] for a, b in pairs]
    )
    blocks = template.data.shape_keys.key_blocks
    for block in list(blocks)[keys + 1:]:  # fewer than the 52 ARKit units asked for
        template.shape_key_remove(block)
    original = positions(template).copy()
    for obj in list(bpy.data.objects):
        if obj.name not in ("Template", TARGET, CHARACTER_IDENTITY):
            bpy.data.objects.remove(obj)
    for obj in bpy.data.objects:
        subdivide(obj, level)
    if not np.allclose(positions(template)[: len(original)], original):
        raise RuntimeError("subdivision renumbered the original vertices: the point pairs would be wrong")
    identity = bpy.data.objects[CHARACTER_IDENTITY]
    character_head = {"neutral": positions(template), "skin_vertices": head["skin_vertices"],
                      "targets": {CHARACTER_IDENTITY: positions(identity)}}
    sample_blend.add_character("Character", {**CHARACTER, "identity": CHARACTER_IDENTITY}, character_head, identity, 0.5)
    for block in template.data.shape_keys.key_blocks:
        block.value = 0.0
    os.makedirs(os.path.dirname(path), exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=path + ".partial.blend")
    os.replace(path + ".partial.blend", path)
