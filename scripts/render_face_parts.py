"""Renders the README's picture of a face in several objects (Rig > Face Parts), headless (bpy
Python or Blender):

    python scripts/render_face_parts.py [-- --target Target_OldMan --tiles jawOpen,tongueOut
                                            --output docs/face_parts.png]
    blender -b -P scripts/render_face_parts.py -- [--target ...] [--tiles ...] [--output ...]

The sample's Template and a Target_* head are each split into four objects as a Ready Player
Me export has them (`<name>_Head` with the lashes, `<name>_Teeth` with the tongue,
`<name>_EyeLeft`, `<name>_EyeRight`), the loose pieces grouped by what moves them as
blender_tests/test_face_parts.py groups them; each template object keeps only the keys that
move it and the target objects have none. The parts are listed on each head as its Face
Parts, and the template face's keys are transferred onto the target face by the add-on's
`transfer_object` (as `batch.py -- transfer` calls it), each target part receiving its own.
The target face is rendered (Workbench, orthographic, from the front, each object in its own
flat colour, framed on the region the keys move) at its neutral, then once per --tiles entry
with its keys (joined by `+`) at 1, side by side.
"""

import argparse
import os
import sys
from importlib import import_module

import bpy
import bmesh  # after bpy: the bpy wheel provides it once bpy is imported
import numpy as np
from mathutils import Vector

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
import batch  # noqa: E402
import pictures  # noqa: E402
from bench_transfer import batch_cache  # noqa: E402

OBJECTS = ("Head", "Teeth", "EyeLeft", "EyeRight")
# flat colours (Workbench 'OBJECT'): skin, teeth and tongue, one eye, the other
COLOURS = {
    "Head": (0.80, 0.66, 0.56, 1.0),
    "Teeth": (0.85, 0.22, 0.30, 1.0),
    "EyeLeft": (0.20, 0.45, 0.90, 1.0),
    "EyeRight": (0.20, 0.70, 0.35, 1.0),
}
SIZE = (400, 440)


def groups_of(modules, template):
    """{object name: Template vertices (ascending)}: each loose piece of the Template grouped
    by what moves it, as the tests split it (the largest piece and the lashes, which blinks
    move: the head; the pieces the eye looks turn: the eyes; the rest, tongue and teeth: the
    teeth)."""
    rig = modules["mesh_arrays"].read_rig(template)
    parts = modules["landmarks"].mesh_parts(template, rig.triangles, rig.neutral)
    labels = np.asarray(parts["part_of_vertex"])
    sizes = np.bincount(labels)
    moving = {name: np.any(delta != 0.0, axis=1) for name, delta in zip(rig.names, rig.deltas)}
    groups = {name: [] for name in OBJECTS}
    for piece in range(parts["loose_parts"]):
        vertices = np.flatnonzero(labels == piece)
        moved = {name for name, rows in moving.items() if rows[vertices].any()}
        if sizes[piece] == sizes.max() or {"eyeBlinkLeft", "eyeBlinkRight"} & moved:
            groups["Head"].append(vertices)
        elif "eyeLookUpLeft" in moved:
            groups["EyeLeft"].append(vertices)
        elif "eyeLookUpRight" in moved:
            groups["EyeRight"].append(vertices)
        else:
            groups["Teeth"].append(vertices)
    return {name: np.sort(np.concatenate(v)) for name, v in groups.items()}


def split(modules, source, prefix, groups):
    """The objects `<prefix>Head`, `<prefix>Teeth`, ...: copies of `source` with only their
    group's vertices (in the source's order, its keys and transform kept), each keeping the
    keys that move it; the parts listed on the head. Returns [head, *parts]."""
    objects = []
    for name in OBJECTS:
        obj = source.copy()
        obj.data = source.data.copy()
        obj.name = obj.data.name = prefix + name
        bpy.context.scene.collection.objects.link(obj)
        keep = np.zeros(len(obj.data.vertices), dtype=bool)
        keep[groups[name]] = True
        bm = bmesh.new()
        bm.from_mesh(obj.data)
        bm.verts.ensure_lookup_table()
        bmesh.ops.delete(bm, geom=[v for v, kept in zip(bm.verts, keep) if not kept], context="VERTS")
        bm.to_mesh(obj.data)
        bm.free()
        keys = obj.data.shape_keys
        if keys is not None:
            rest = modules["mesh_arrays"].rest_positions(obj)
            co = np.empty(rest.size, dtype=np.float32)
            for block in list(keys.key_blocks[1:]):
                block.data.foreach_get("co", co)
                if np.array_equal(co.reshape(-1, 3), rest):
                    obj.shape_key_remove(block)
        obj.color = COLOURS[name]
        objects.append(obj)
    modules["face_parts"].store_parts(objects[0], objects[1:])
    bpy.context.view_layer.update()
    return objects


def transfer_face(modules, template_head, target_head):
    """Transfers the template face's keys onto the target face (the parts listed on each
    head) and writes them, each target object its own; returns the `Transfer`."""
    result = modules["transfer"].transfer_object(template_head, target_head)
    written, skipped, warnings = modules["shape_keys"].write_transferred_keys(result)
    for line in modules["transfer"].summary_lines(result, written, skipped) + list(warnings):
        print(line)
    return result


def frame(result, shown):
    """Centre (world) and orthographic scale framing, from the front, the target face's
    vertices that the keys move (by a fifth of the largest move or more), at rest and posed at
    each tile's keys."""
    neutral, deltas = result.target_neutral, result.deltas
    reach = np.linalg.norm(deltas, axis=2).max(axis=0)
    moved = reach > 0.2 * reach.max()
    points = [neutral[moved]] + [
        neutral[moved] + sum(deltas[result.names.index(n)][moved] for n in keys) for keys in shown
    ]
    matrix = np.array(result.target.matrix_world)
    points = np.concatenate(points) @ matrix[:3, :3].T + matrix[:3, 3]
    low, high = points.min(0), points.max(0)
    # ortho_scale spans the longer (vertical) side of the portrait tile
    extent = 1.2 * float(max(high[2] - low[2], (high[0] - low[0]) * SIZE[1] / SIZE[0]))
    return Vector((low + high) / 2), extent, float(high[1] - low[1] + extent)


def pose(objects, shapes):
    for obj in objects:
        keys = obj.data.shape_keys
        for block in keys.key_blocks[1:] if keys is not None else ():
            block.value = 1.0 if block.name in shapes else 0.0


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="render_face_parts.py --")
    parser.add_argument("--target", default="Target_OldMan")
    parser.add_argument(
        "--tiles", default="jawOpen,tongueOut",
        help="the tiles beside the neutral, comma-separated, each its transferred keys joined by +",
    )
    parser.add_argument("--output", default=os.path.join(SCRIPTS, "..", "docs", "face_parts.png"))
    args = parser.parse_args(argv)
    output = os.path.abspath(args.output)
    tiles = [[k for k in tile.split("+") if k] for tile in args.tiles.split(",") if tile.strip("+")]
    sample = batch.cached_sample()  # first: building it resets Blender to factory settings
    shapesmith = batch.load_shapesmith()
    modules = {
        name: import_module(f"{shapesmith.__name__}.blender.{name}")
        for name in ("transfer", "shape_keys", "mesh_arrays", "landmarks", "face_parts")
    }
    bpy.ops.wm.open_mainfile(filepath=sample)
    template, target = bpy.data.objects["Template"], bpy.data.objects[args.target]
    groups = groups_of(modules, template)
    template_face = split(modules, template, "Template_", groups)
    target_face = split(modules, target, f"{args.target}_", groups)
    for face in (template_face, target_face):
        print(f"{face[0].name}: face parts " + ", ".join(f"{o.name} ({len(o.data.vertices)} vertices)" for o in face[1:]))
    result = transfer_face(modules, template_face[0], target_face[0])
    missing = [k for keys in tiles for k in keys if k not in result.names]
    if missing:
        raise SystemExit(f"render_face_parts.py: no transferred shape {', '.join(missing)}")
    for obj in target_face:
        keys = obj.data.shape_keys
        print(f"  {obj.name}: {len(keys.key_blocks) - 1 if keys else 0} keys")

    shading = bpy.context.scene.display.shading
    shading.light = "STUDIO"
    shading.show_cavity = False
    shading.color_type = "OBJECT"
    # the objects' own colours, not the default view transform's desaturated ones
    bpy.context.scene.view_settings.view_transform = "Standard"
    centre, extent, distance = frame(result, tiles)
    front = Vector((0.0, -1.0, 0.0))
    scratch = os.path.join(batch_cache(), "render", "face_parts")
    os.makedirs(scratch, exist_ok=True)
    os.makedirs(os.path.dirname(output), exist_ok=True)
    paths = []
    for keys in [[]] + tiles:
        pose(target_face, set(keys))
        path = os.path.join(scratch, f"{'+'.join(keys) or 'neutral'}.png")
        pictures.render_alone(target_face, centre + distance * front, -front, extent, SIZE, path, clip_end=10 * distance)
        paths.append(path)
    pictures.tiled(paths, output)
    print(f"wrote {output}")


if __name__ == "__main__":
    main()
