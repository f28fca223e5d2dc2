"""Shapesmith batch entry point, for pipelines over many characters.

    blender -b [FILE.blend] -P scripts/batch.py -- COMMAND [FLAGS]
    python scripts/batch.py -- COMMAND [FLAGS]          (with the `bpy` wheel)

Commands: sample, analyze, landmarks (see `-- COMMAND --help`). Every command but `sample` needs the
Shapesmith extension installed in this Blender. Bad input exits with status 2 and one line
on stderr; input files are never written (results go to --output/--json).
"""

import argparse
import json
import os
import sys

import bpy

SCRIPTS = os.path.dirname(os.path.abspath(__file__))


class BatchError(Exception):
    """Bad input: reported as one line on stderr, exit status 2."""


def load_shapesmith():
    """The installed Shapesmith extension's package, enabled."""
    import addon_utils
    import importlib

    names = [m.__name__ for m in addon_utils.modules(refresh=False) if m.__name__.rsplit(".", 1)[-1] == "shapesmith"]
    if not names:
        raise BatchError(
            "the Shapesmith extension is not installed in this Blender: build it with scripts/build and "
            "install dist/shapesmith-*.zip (Preferences > Get Extensions > Install from Disk)"
        )
    addon_utils.enable(names[0], default_set=True)
    return importlib.import_module(names[0])


def open_blend(path):
    if not path or not os.path.isfile(path):
        raise BatchError(f"input file not found: {path}")
    bpy.ops.wm.open_mainfile(filepath=os.path.abspath(path))


def find_object(name):
    obj = bpy.data.objects.get(name)
    if obj is None:
        meshes = ", ".join(o.name for o in bpy.data.objects if o.type == "MESH") or "none"
        raise BatchError(f"no object named '{name}' in the file (meshes: {meshes})")
    return obj


def write_json(path, data):
    if path:
        with open(path, "w") as f:
            json.dump(data, f, indent=2)


def save_copy(path):
    """Saves the result to a new file; the input file is left as it was."""
    bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(path), copy=True)


# --- commands ---------------------------------------------------------------------------


def add_sample_args(parser):
    parser.add_argument("--output", required=True, help="where to write sample.blend")


def run_sample(args):
    """Template (MakeHuman head + 52 ARKit face units) and Target_* identity heads."""
    sys.path.insert(0, SCRIPTS)
    import makehuman
    import numpy as np

    try:
        head = makehuman.build_head()
    except FileNotFoundError as error:
        raise BatchError(str(error))
    bpy.ops.wm.read_factory_settings(use_empty=True)

    def mesh_object(name, positions, location_x):
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata(positions.tolist(), [], head["faces"].tolist())
        mesh.shade_smooth()
        obj = bpy.data.objects.new(name, mesh)
        obj.location.x = location_x
        bpy.context.scene.collection.objects.link(obj)
        return obj

    template = mesh_object("Template", head["neutral"], 0.0)
    template.shape_key_add(name="Basis", from_mix=False)
    for name, delta in zip(head["shape_names"], head["deltas"]):
        key = template.shape_key_add(name=name, from_mix=False)
        key.data.foreach_set("co", (head["neutral"] + delta).astype(np.float32).ravel())
        key.value = 0.0  # shape_key_add defaults to 1.0 in Blender 5.x
    for i, (name, positions) in enumerate(head["targets"].items()):
        mesh_object(name, positions, 0.25 * (i + 1))
    os.makedirs(os.path.dirname(os.path.abspath(args.output)), exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(args.output))
    print(f"wrote {args.output}: Template with {len(head['shape_names'])} shape keys, "
          f"{len(head['neutral'])} vertices; targets {', '.join(head['targets'])}")


def add_analyze_args(parser):
    parser.add_argument("--input", required=True, help=".blend file to read")
    parser.add_argument("--object", required=True, help="mesh object with shape keys")
    parser.add_argument("--axis", choices="XYZ", default="X", help="symmetry axis (default X)")
    parser.add_argument("--no-name-pairs", action="store_true", help="do not pair shapes by Left/Right names")
    parser.add_argument("--json", help="write the report here")


def run_analyze(args):
    shapesmith = load_shapesmith()
    open_blend(args.input)
    from importlib import import_module

    analysis = import_module(shapesmith.__name__ + ".blender.analysis")
    report = analysis.analyze_object(find_object(args.object), axis="XYZ".index(args.axis), pair_by_name=not args.no_name_pairs)
    for line in analysis.summary_lines(report):
        print(line)
    report["pair_details"] = report["symmetric_pairs"]
    report["symmetric_pairs"] = [[p["first"], p["second"]] for p in report["symmetric_pairs"]]
    report["antagonist_details"] = report["antagonists"]
    report["antagonists"] = [[p["first"], p["second"]] for p in report["antagonists"]]
    report.update(input=os.path.abspath(args.input), object=args.object)
    write_json(args.json, report)


def add_landmarks_args(parser):
    parser.add_argument("--input", required=True, help=".blend file to read")
    parser.add_argument("--object", required=True, help="mesh object with shape keys")
    parser.add_argument("--epsilon", type=float, default=0.5, help="candidate threshold in (0, 1] (default 0.5)")
    parser.add_argument("--alpha", type=float, default=0.5, help="visibility against displacement (default 0.5)")
    parser.add_argument("--gamma", type=float, default=0.5, help="quality against count; 0 = fewest (default 0.5)")
    parser.add_argument("--rays", type=int, default=64, help="visibility rays per vertex and pose (default 64)")
    parser.add_argument("--symmetric", action="store_true", help="mirror-symmetric layout")
    parser.add_argument("--axis", choices="XYZ", default="X", help="symmetry axis (default X)")
    parser.add_argument("--max-per-shape", type=int, default=2, help="multi-cover rounds (default 2)")
    parser.add_argument("--radius", type=float, default=0.03, help="exclusion radius / bbox diagonal (default 0.03)")
    cameras = parser.add_mutually_exclusive_group()
    cameras.add_argument("--scene-cameras", action="store_true", help="visibility from the scene's cameras")
    cameras.add_argument("--camera-collection", help="visibility from the cameras in this collection")
    parser.add_argument("--score-group", help="also score the layout of this vertex group")
    parser.add_argument("--json", help="write the report here")
    parser.add_argument("--csv", help="write one row per landmark here")
    parser.add_argument("--picture", help="render a front view with the landmarks to this PNG")
    parser.add_argument("--output", help="save the file with the layout (empties, vertex group) here")


def run_landmarks(args):
    shapesmith = load_shapesmith()
    open_blend(args.input)
    from importlib import import_module

    landmarks = import_module(shapesmith.__name__ + ".blender.landmarks")
    obj = find_object(args.object)
    scene = bpy.context.scene
    source = "SCENE" if args.scene_cameras else "COLLECTION" if args.camera_collection else "HEMISPHERE"
    collection = None
    if args.camera_collection:
        collection = bpy.data.collections.get(args.camera_collection)
        if collection is None:
            raise BatchError(f"no collection named '{args.camera_collection}' in the file")
    cameras = landmarks.camera_positions(obj, source, scene, collection)
    params = dict(epsilon=args.epsilon, alpha=args.alpha, gamma=args.gamma, rays=args.rays, symmetric=args.symmetric,
                  max_per_shape=args.max_per_shape, radius=args.radius)
    score = landmarks.score_group(obj, args.score_group) if args.score_group else None
    document = landmarks.place_landmarks(obj, cameras=cameras, axis="XYZ".index(args.axis), **params)
    landmarks.build_layout(obj, document, scene)
    for line in landmarks.summary_lines(document):
        print(line)
    if score is not None:
        document["score"] = score
        print(f"score of '{args.score_group}' ({score['landmarks']} vertices): mean {score['mean']:.2e}, "
              f"max {score['max']:.2e} of the bbox diagonal")
    document.update(input=os.path.abspath(args.input))
    write_json(args.json, document)
    if args.csv:
        landmarks.write_csv(args.csv, document)
    if args.picture:
        picture = import_module(shapesmith.__name__ + ".blender.landmark_picture")
        picture.render_landmarks(obj, os.path.abspath(args.picture))
    if args.output:
        save_copy(args.output)


COMMANDS = {
    "sample": (add_sample_args, run_sample, "build sample.blend from the MakeHuman assets"),
    "analyze": (add_analyze_args, run_analyze, "analyze a rig's shape keys"),
    "landmarks": (add_landmarks_args, run_landmarks, "place landmarks, score and export the layout"),
}


def parse(argv):
    parser = argparse.ArgumentParser(prog="batch.py --", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    for name, (add_args, _, help_text) in COMMANDS.items():
        add_args(sub.add_parser(name, help=help_text))
    return parser.parse_args(argv)


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    try:
        args = parse(argv)
    except SystemExit as exit_:
        return exit_.code or 0
    try:
        COMMANDS[args.command][1](args)
    except (BatchError, ValueError) as error:
        # ValueError covers MeshDataError and the core's InvalidInputError and InfeasibleError.
        print(f"shapesmith: error: {error}", file=sys.stderr)
        return 2
    except RuntimeError as error:
        # The core's SolverError, or a native module that cannot load.
        print(f"shapesmith: failed: {error}", file=sys.stderr)
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
