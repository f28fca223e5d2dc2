"""`batch.py -- crossings`: the faces each key pushes through the mesh, as the transfer panel's
Show Crossings arrows select them.

    python scripts/batch.py -- crossings --input F.blend --object NAME [--shapes A,B] [--select SHAPE --output OUT.blend]
                                         [--json REPORT.json]"""

import os

from batch_common import BatchError, find_object, load_shapesmith, open_blend, save_copy, write_json


def add_crossings_args(parser, settings):
    parser.add_argument("--input", required=True, help=".blend file to read")
    parser.add_argument("--object", required=True, help="mesh object with shape keys (e.g. a transferred target)")
    parser.add_argument("--shapes", help="comma-separated keys to check (default: every key but the reference key)")
    parser.add_argument(
        "--select", metavar="SHAPE",
        help="with --output: save a copy showing this key alone with its crossing faces selected, as Show Crossings does",
    )
    parser.add_argument("--json", help="write the report here")
    parser.add_argument("--output", help="save the --select result to this .blend (the input is never written)")


def run_crossings(args):
    """The faces each key pushes through the mesh (pairs of triangles crossing in the key and
    not at rest): the batch counterpart of the transfer panel's Show Crossings arrows."""
    from importlib import import_module

    import numpy as np

    if bool(args.select) != bool(args.output):
        raise BatchError("--select SHAPE and --output OUT.blend go together")
    shapesmith = load_shapesmith()
    open_blend(args.input)
    crossings = import_module(shapesmith.__name__ + ".blender.crossings")
    obj = find_object(args.object)
    keys = obj.data.shape_keys if obj.type == "MESH" else None
    if keys is None:
        raise BatchError(f"'{args.object}' is not a mesh with shape keys")
    names = args.shapes.split(",") if args.shapes else [k.name for k in keys.key_blocks if k != keys.reference_key]
    for name in names + ([args.select] if args.select else []):
        if keys.key_blocks.get(name) is None:
            raise BatchError(f"'{args.object}' has no shape key '{name}'")
    shapes = {}
    for name in names:
        faces = np.flatnonzero(crossings.crossing_faces(obj, name))
        shapes[name] = {"count": len(faces), "faces": faces.tolist()}
        if len(faces):
            print(f"{name}: {len(faces)} faces pass through the mesh")
    print(f"{sum(1 for s in shapes.values() if s['count'])} of {len(shapes)} keys add crossings on '{args.object}'")
    if args.select:
        crossings.show_crossings(obj, args.select)
        save_copy(args.output)
    write_json(args.json, {
        "input": os.path.abspath(args.input), "object": args.object, "faces_total": len(obj.data.polygons),
        "shapes": shapes,
    })
