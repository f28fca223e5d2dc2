"""Renders the README's before/after picture of Transfer Shape Keys, headless (bpy Python):

    python scripts/render_transfer.py [-- --target Target_Boy --shape mouthLeft --output docs/transfer_mouthLeft.png]

The template's keys are transferred onto three copies of the target: plain deformation
transfer, with virtual edges (the default), and with virtual edges and Keep Surfaces Apart;
each is posed at the shape and rendered (Workbench, orthographic close-up of the region the
shape moves, the skin half transparent) side by side in that order, every triangle that passes
through another one (and did not at rest) painted red, so what each variant pushes through
lips, teeth or eyes shows even inside the mouth. The intersection-curve lengths are printed for the caption.
"""

import argparse
import os
import sys
from importlib import import_module

import bpy
import numpy as np
from mathutils import Vector

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
import batch  # noqa: E402
import pictures  # noqa: E402
from bench_transfer import batch_cache  # noqa: E402

SIZE = (360, 300)


def transferred_copy(modules, template, target, name, virtual_edges, collisions):
    copy = target.copy()
    copy.data = target.data.copy()
    copy.name = name
    bpy.context.scene.collection.objects.link(copy)
    settings = modules["settings"]
    chosen = settings.TransferSettings(transfer=settings.DeformationSettings(
        virtual_edges=settings.VirtualEdgeSettings() if virtual_edges else None,
        contact=settings.ContactSettings() if collisions else None,
    ))
    transfer = modules["transfer"].transfer_object(template, copy, chosen)
    modules["shape_keys"].write_transferred_keys(transfer)
    return copy, transfer


def paint_crossings(obj, shape, crossings):
    """Paints red the faces that pass through the mesh when `obj` is posed at `shape` and did
    not at rest (the neutral's own crossings at the lashes stay grey); returns their count."""
    mesh = obj.data
    faces = crossings.crossing_faces(obj, shape)
    crossed_loop = crossings.face_corners(mesh, faces)
    colours = np.where(crossed_loop[:, None], (1.0, 0.0, 0.0, 1.0), (0.75, 0.75, 0.75, 1.0)).astype(np.float32)
    attribute = mesh.color_attributes.new("crossings", "FLOAT_COLOR", "CORNER")
    attribute.data.foreach_set("color", colours.ravel())
    mesh.color_attributes.active_color = attribute
    return int(faces.sum())


def render(obj, shape, centre, extent, path):
    obj.data.shape_keys.key_blocks[shape].value = 1.0
    shading = bpy.context.scene.display.shading
    shading.light = "STUDIO"
    shading.show_cavity = True
    shading.color_type = "VERTEX"
    # half-transparent skin: the teeth and the far lip, where most crossings hide, show through
    shading.show_xray = True
    shading.xray_alpha = 0.55
    # from the front (-Y), a little from below, where lips and lids show their overlap
    world_centre = obj.matrix_world @ Vector(centre)
    pictures.render_alone(obj, world_centre + Vector((0.0, -1.0, -0.25)), Vector((0.0, 1.0, 0.25)), extent, SIZE, path)


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="render_transfer.py --")
    parser.add_argument("--target", default="Target_OldMan")
    parser.add_argument("--shape", default="mouthPucker")
    parser.add_argument("--output", help="default: docs/transfer_<shape>.png")
    args = parser.parse_args(argv)
    output = os.path.abspath(args.output or os.path.join(SCRIPTS, "..", "docs", f"transfer_{args.shape}.png"))
    shapesmith = batch.load_shapesmith()
    modules = {name: import_module(f"{shapesmith.__name__}.blender.{name}") for name in ("transfer", "shape_keys", "mesh_arrays", "crossings", "settings")}
    bpy.ops.wm.open_mainfile(filepath=batch.cached_sample())
    template, target = bpy.data.objects["Template"], bpy.data.objects[args.target]

    rig = modules["mesh_arrays"].read_rig(template)
    moved = np.linalg.norm(rig.deltas[rig.names.index(args.shape)], axis=1)
    region = modules["transfer"].rest_positions(target)[moved > 0.2 * moved.max()]
    centre = (region.min(0) + region.max(0)) / 2
    extent = 1.5 * float(max(np.ptp(region[:, 0]), np.ptp(region[:, 2])))

    os.makedirs(os.path.dirname(output), exist_ok=True)
    paths = []
    for label, virtual_edges, collisions in (("plain", False, False), ("virtual_edges", True, False), ("collision_pass", True, True)):
        copy, transfer = transferred_copy(modules, template, target, f"{args.target}_{label}", virtual_edges, collisions)
        row = next(r for r in transfer.report["penetration"] if r["name"] == args.shape)
        print(
            f"{args.shape} on {args.target}, {label}: intersection curve {row['length']:.4f} ({row['pairs']} pairs); "
            f"template {row['template_length']:.4f} ({row['template_pairs']} pairs)"
        )
        print(f"  {paint_crossings(copy, args.shape, modules['crossings'])} faces painted red")
        path = os.path.join(batch_cache(), "render", f"{label}.png")
        render(copy, args.shape, centre, extent, path)
        paths.append(path)
    pictures.tiled(paths, output)
    print(f"wrote {output}")


if __name__ == "__main__":
    main()
