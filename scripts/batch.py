"""Shapesmith batch entry point, for pipelines over many characters.

    blender -b [FILE.blend] -P scripts/batch.py -- COMMAND [FLAGS]
    python scripts/batch.py -- COMMAND [FLAGS]          (with the `bpy` wheel)

Commands: sample, analyze, pack, landmarks, transfer, wrap, generate, crossings, solve, import-capture (see
`-- COMMAND --help`). Every command
but `sample` needs the
Shapesmith extension installed in this Blender. Bad input exits with status 2 and one line
on stderr; input files are never written (results go to --output/--json).
"""

import argparse
import json
import os
import sys

import bpy

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
# cached_sample and cached_sample_path are re-exported: the tests, benches and renders call them here.
from sample_blend import build_sample, cached_sample, cached_sample_path  # noqa: E402,F401
from batch_generate import add_generate_args, run_generate  # noqa: E402
from batch_crossings import add_crossings_args, run_crossings  # noqa: E402


# The shared parts are re-exported: the tests, benches and renders call them here.
from batch_common import (  # noqa: E402,F401
    NAME_MAP_HELP,
    BatchError,
    driver_map,
    find_face,
    find_object,
    load_shapesmith,
    name_map,
    open_blend,
    print_looks,
    save_copy,
    template_or_bundled,
    tool_settings,
    write_json,
)


# --- commands ---------------------------------------------------------------------------


def add_sample_args(parser, settings):
    parser.add_argument("--output", required=True, help="where to write sample.blend")


def run_sample(args):
    try:
        build_sample(args.output)
    except FileNotFoundError as error:
        raise BatchError(str(error))


FACE_HELP = (
    "mesh object with shape keys; a face in several objects as the head, then its parts, comma separated "
    "(Head,Teeth,EyeLeft,EyeRight); the head alone uses the Face Parts list stored on it"
)


def add_analyze_args(parser, settings):
    parser.add_argument("--input", required=True, help=".blend file to read")
    parser.add_argument("--object", required=True, help=FACE_HELP)
    default = settings.AnalyzeSettings()
    parser.add_argument("--axis", choices="XYZ", default="XYZ"[default.axis], help="symmetry axis (default %(default)s)")
    parser.add_argument("--name-pairs", action=argparse.BooleanOptionalAction, default=default.symmetry.use_names,
                        help="pair shapes by Left/Right names where geometry finds no mirror partner (--no-name-pairs: do not)")
    parser.add_argument("--name-map", help=NAME_MAP_HELP)
    parser.add_argument("--json", help="write the report here")


def analyze_settings(args, settings):
    """The analysis' settings from the flags (`settings`: the extension's settings module)."""
    return settings.AnalyzeSettings(axis="XYZ".index(args.axis), symmetry=settings.SymmetrySettings(use_names=args.name_pairs))


def run_analyze(args):
    shapesmith = load_shapesmith()
    open_blend(args.input)
    from importlib import import_module

    analysis = import_module(shapesmith.__name__ + ".blender.analysis")
    obj = find_face(args.object, shapesmith)
    report = analysis.analyze_object(obj, analyze_settings(args, tool_settings()), name_map=name_map(args, shapesmith))
    for line in analysis.summary_lines(report):
        print(line)
    report["pair_details"] = report["symmetric_pairs"]
    report["symmetric_pairs"] = [[p["first"], p["second"]] for p in report["symmetric_pairs"]]
    report["antagonist_details"] = report["antagonists"]
    report["antagonists"] = [[p["first"], p["second"]] for p in report["antagonists"]]
    report.update(input=os.path.abspath(args.input), object=obj.name)
    write_json(args.json, report)


def add_pack_args(parser, settings):
    parser.add_argument("--input", required=True, help=".blend file to read")
    parser.add_argument("--object", required=True, help=FACE_HELP)
    parser.add_argument("--target", help="target head of the same topology (importance by its distortion); with "
                        "face parts, the head then its parts, comma separated")
    # Unset flags keep the settings stored on the object, whose own defaults are these.
    default = settings.PackSettings()
    parser.add_argument("--mu", type=float, help=f"the panel's Moving Region: share of a shape's largest motion (default: the object's; {default.mu})")
    parser.add_argument("--a", type=float, help=f"the panel's Strong Motion First: strength vs distortion (default: the object's; {default.a})")
    parser.add_argument("--beta", type=float, help=f"the panel's Unlike Shapes First (default: the object's; {default.beta})")
    parser.add_argument("--max-expressions", type=int, help="J max: stop after this many expressions")
    parser.add_argument("--fewest", action="store_true", help="also prove the fewest expressions possible")
    parser.add_argument("--no-symmetry", action="store_true", help="do not force symmetric partners together")
    parser.add_argument("--no-collision-conflicts", action="store_true",
                        help="allow shapes that pass through each other when mixed in one expression")
    parser.add_argument("--collision-tolerance", type=float,
                        help="intersection curve between pieces a mix may add, as a fraction of the head's diagonal "
                        f"(default: the object's; {default.collision_tolerance})")
    parser.add_argument("--no-occlusion-conflicts", action="store_true",
                        help="allow a shape with one that hides its motion from the front camera")
    parser.add_argument("--occlusion-keep", type=float,
                        help=f"share of a shape's visible moving vertices that must stay in sight (default: the object's; {default.occlusion_keep})")
    parser.add_argument("--camera", help="camera object whose view is the face's front (default: the object's "
                        "Front Camera, else the front found from the rig)")
    parser.add_argument("--json", help="write the report (expressions, pairs, antagonists, conflicts with their "
                        "reasons, params, seconds) here")
    parser.add_argument("--csv", help="write the shot list here")
    parser.add_argument("--explain", action="store_true",
                        help="add to the CSV every pair of shapes kept apart and why")
    parser.add_argument("--sheet", help="render the reference sheet (PNG) here")
    parser.add_argument("--tile-width", type=int, default=320, help="sheet tile width in pixels (default 320)")
    parser.add_argument("--tile-height", type=int, default=400, help="sheet tile height in pixels (default 400)")
    parser.add_argument("--bake", action="store_true", help="bake REF_01.. shape keys (saved with --output)")
    parser.add_argument("--output", help="save a copy of the file with the result stored on the object")


def pack_settings(args, stored):
    """The pack settings: those `stored` on the object (a `PackSettings`), with the flags given
    in their place."""
    from dataclasses import replace

    overrides = {"mu": args.mu, "a": args.a, "beta": args.beta, "max_expressions": args.max_expressions,
                 "collision_tolerance": args.collision_tolerance, "occlusion_keep": args.occlusion_keep}
    return replace(
        stored,
        **{key: value for key, value in overrides.items() if value is not None},
        fewest=args.fewest or stored.fewest,
        symmetric=not args.no_symmetry and stored.symmetric,
        collision_conflicts=not args.no_collision_conflicts and stored.collision_conflicts,
        occlusion_conflicts=not args.no_occlusion_conflicts and stored.occlusion_conflicts,
    )


def run_pack(args):
    """Settings and refinements stored on the object apply; flags override them."""
    import time
    from importlib import import_module

    if args.explain and not args.csv:
        raise BatchError("--explain adds the reasons to the CSV shot list: give --csv too")

    shapesmith = load_shapesmith()
    open_blend(args.input)
    packing = import_module(shapesmith.__name__ + ".blender.packing")
    obj = find_face(args.object, shapesmith)
    options = packing.packing_options(obj, axis=int(bpy.context.scene.shapesmith.symmetry_axis))
    options["settings"] = pack_settings(args, options["settings"])
    if args.target:
        options["target"] = find_face(args.target, shapesmith)
    if args.camera:
        options["camera"] = find_object(args.camera)
        if options["camera"].type != "CAMERA":
            raise BatchError(f"'{args.camera}' is a {options['camera'].type.lower()}, not a camera")
    report = packing.pack_object(obj, **options)
    started = time.perf_counter()
    packing.store_packing(obj, report)
    for line in packing.summary_lines(report):
        print(line)
    if args.bake:
        packing.bake_expressions(obj)
    if args.sheet:
        reference_sheet = import_module(shapesmith.__name__ + ".blender.reference_sheet")
        reference_sheet.render_reference_sheet(obj, args.sheet, args.tile_width, args.tile_height)
        print(f"wrote {args.sheet}")
    if args.csv:
        packing.write_shot_list_csv(args.csv, report, explain=args.explain)
    if args.output:
        save_copy(args.output)
    report.update(input=os.path.abspath(args.input), object=obj.name)
    report.pop("conflicts_cache")  # stored on the object (and in --output); opaque to readers
    report["seconds"]["write"] = time.perf_counter() - started
    write_json(args.json, report)


def add_landmarks_args(parser, settings):
    parser.add_argument("--input", required=True, help=".blend file to read")
    parser.add_argument("--object", required=True, help=FACE_HELP)
    parser.add_argument(
        "--landmark-parts",
        help="face parts landmarks may go on, comma separated (default: the parts ticked in the stored list; none: the head only)",
    )
    default = settings.LandmarkSettings()
    parser.add_argument("--epsilon", type=float, default=default.epsilon, help="the panel's Strong Motion, in (0, 1] (default %(default)s)")
    parser.add_argument("--alpha", type=float, default=default.alpha, help="the panel's Visible over Moving (default %(default)s)")
    parser.add_argument("--gamma", type=float, default=default.gamma,
                        help="the panel's Quality: quality against count; 0 = fewest (default %(default)s)")
    parser.add_argument("--rays", type=int, default=default.rays, help="visibility rays per vertex and pose (default %(default)s)")
    parser.add_argument("--symmetric", action=argparse.BooleanOptionalAction, default=default.symmetric,
                        help="mirror-symmetric layout")
    parser.add_argument("--axis", choices="XYZ", default="XYZ"[default.axis], help="symmetry axis (default %(default)s)")
    parser.add_argument("--max-per-shape", type=int, default=default.max_per_shape, help="multi-cover rounds (default %(default)s)")
    parser.add_argument("--radius", type=float, default=default.radius,
                        help="exclusion radius / bbox diagonal (default %(default)s)")
    cameras = parser.add_mutually_exclusive_group()
    cameras.add_argument("--scene-cameras", action="store_true", help="visibility from the scene's cameras")
    cameras.add_argument("--camera-collection", help="visibility from the cameras in this collection")
    design = parser.add_argument_group("landmarks added for reconstruction after the cover")
    design.add_argument("--landmarks", type=int, metavar="M", default=default.landmarks,
                        help="add landmarks until the layout has M in all")
    design.add_argument("--target-error", type=float, metavar="E", default=default.target_error,
                        help="add landmarks until the predicted error is E (fraction of the bbox diagonal)")
    design.add_argument("--criterion", choices=("a", "d"), default=default.criterion,
                        help="a: the predicted error (default); d: the log-determinant of the information")
    design.add_argument("--curve", metavar="PNG", help="plot the predicted error per landmark count to this PNG")
    parser.add_argument("--score-group", help="also score the layout of this vertex group, and compare with it")
    parser.add_argument("--json", help="write the report here")
    parser.add_argument("--csv", help="write one row per landmark here")
    parser.add_argument("--picture", help="render a front view with the landmarks to this PNG")
    parser.add_argument("--output", help="save the file with the layout (empties, vertex group) here")


def landmark_settings(args, settings):
    """The layout's settings from the flags (`settings`: the extension's settings module)."""
    return settings.LandmarkSettings(
        epsilon=args.epsilon, alpha=args.alpha, gamma=args.gamma, rays=args.rays, symmetric=args.symmetric,
        axis="XYZ".index(args.axis), max_per_shape=args.max_per_shape, radius=args.radius, landmarks=args.landmarks,
        target_error=args.target_error, criterion=args.criterion,
    )


def run_landmarks(args):
    shapesmith = load_shapesmith()
    open_blend(args.input)
    from importlib import import_module

    landmarks = import_module(shapesmith.__name__ + ".blender.landmarks")
    obj = find_face(args.object, shapesmith)
    allowed_parts = None
    if args.landmark_parts is not None:
        allowed_parts = [find_object(name.strip()) for name in args.landmark_parts.split(",") if name.strip()]
    scene = bpy.context.scene
    source = "SCENE" if args.scene_cameras else "COLLECTION" if args.camera_collection else "HEMISPHERE"
    collection = None
    if args.camera_collection:
        collection = bpy.data.collections.get(args.camera_collection)
        if collection is None:
            raise BatchError(f"no collection named '{args.camera_collection}' in the file")
    if args.landmarks is not None and args.landmarks < 1:
        raise BatchError(f"--landmarks must be at least 1, got {args.landmarks}")
    if args.target_error is not None and not args.target_error > 0:
        raise BatchError(f"--target-error must be a positive fraction of the bbox diagonal, got {args.target_error}")
    if args.curve and args.landmarks is None and args.target_error is None:
        raise BatchError("--curve plots the landmarks added after the cover: give --landmarks or --target-error")
    cameras = landmarks.camera_positions(obj, source, scene, collection)
    score = landmarks.score_group(obj, args.score_group) if args.score_group else None
    document = landmarks.place_landmarks(
        obj, landmark_settings(args, tool_settings()), cameras=cameras, allowed_parts=allowed_parts
    )
    if score is not None:
        document["comparison"] = score
    landmarks.build_layout(obj, document, scene)
    for line in landmarks.summary_lines(document):
        print(line)
    if score is not None:
        document["score"] = score
        print(f"score of '{args.score_group}' ({score['landmarks']} vertices): mean {score['mean']:.2e}, "
              f"max {score['max']:.2e} of the bbox diagonal, predicted {score['predicted']:.2e}")
    document.update(input=os.path.abspath(args.input))
    write_json(args.json, document)
    if args.csv:
        landmarks.write_csv(args.csv, document)
    if args.picture:
        picture = import_module(shapesmith.__name__ + ".blender.landmark_picture")
        picture.render_landmarks(obj, os.path.abspath(args.picture))
    if args.curve:
        import_module(shapesmith.__name__ + ".blender.landmark_curve").write_curve_png(document, os.path.abspath(args.curve))
    if args.output:
        save_copy(args.output)


def add_transfer_settings_args(parser, settings, onto):
    """The flags of the transfer's solve (`settings.TransferSettings`, named as the Transfer
    panel's properties) for `transfer` and for `wrap`'s transfer `onto` the wrapped template;
    returns the defaults."""
    default = settings.TransferSettings()
    edges, contact = default.transfer.virtual_edges, default.transfer.contact
    parser.add_argument(
        "--virtual-edges", action=argparse.BooleanOptionalAction, default=edges is not None,
        help=f"virtual edges against lips and lids passing through each other{onto} (--no-virtual-edges: plain deformation "
        "transfer)",
    )
    parser.add_argument("--tau-d", type=float, default=edges.tau_d,
                        help="the panel's Distance: virtual-edge pairs closer than this fraction of the bbox diagonal (default %(default)s)")
    parser.add_argument("--tau-r", type=float, default=edges.tau_r,
                        help="the panel's Detour: surface-to-straight distance ratio of a virtual edge (default %(default)s)")
    parser.add_argument("--edge-weight", type=float, default=default.transfer.edge_weight,
                        help="weight of each virtual edge (default %(default)s)")
    parser.add_argument(
        "--contact", action=argparse.BooleanOptionalAction, default=contact is not None,
        help="keep lips, lids and skin from passing through each other or through teeth and eyes where the template's "
        "shape does not (off by default: slow on dense heads)",
    )
    parser.add_argument(
        "--contact-distance", type=float, default=settings.ContactSettings().distance,
        help="with --contact: how close two surfaces may come before they push apart, fraction of the local edge length (default %(default)s)",
    )
    return default


def add_transfer_args(parser, settings):
    parser.add_argument("--input", required=True, help=".blend file to read")
    parser.add_argument("--source", required=True, help="the template: " + FACE_HELP)
    parser.add_argument(
        "--target", action="append", default=[],
        help="mesh to receive the keys (repeatable); a face in several objects as the head, then its parts, comma "
        "separated, paired with the template's parts by name after each face's common prefix, else in order",
    )
    parser.add_argument("--targets", help="glob over object names, e.g. 'Target_*'")
    default = add_transfer_settings_args(parser, settings, "")
    parser.add_argument(
        "--compare-plain", action=argparse.BooleanOptionalAction, default=default.compare_plain,
        help="also transfer without virtual edges and contact solve and report its penetration (one more solve)",
    )
    parser.add_argument(
        "--examples",
        help="training expressions to personalise with, comma separated object names (REF_01-style after the "
        "packed expressions, or after shape keys); with several targets use {target} in the names",
    )
    parser.add_argument("--pack-json", help="Pack Expressions JSON report naming the expressions' shapes")
    parser.add_argument(
        "--beta-reg", type=float, default=default.personalise.beta_reg,
        help="the panel's Regularisation: pull towards the transferred shapes against noisy scans (default %(default)s)",
    )
    parser.add_argument(
        "--refine-weights", action=argparse.BooleanOptionalAction, default=default.personalise.refine_weights,
        help="personalisation: refit the weights of each training expression's shapes within [0, 1] first",
    )
    parser.add_argument("--overwrite", action="store_true", help="replace existing keys of the same name")
    parser.add_argument("--keep-sculpted", action="store_true",
                        help="with --overwrite: add back what was sculpted on a key since the last transfer wrote it")
    parser.add_argument("--keys", help='transfer only these template keys, names or patterns, comma separated: "eyeBlink*,jawOpen" '
                        "(the target's other keys stay as they are)")
    parser.add_argument("--copy-drivers", action="store_true", help="recreate the template's key drivers")
    parser.add_argument("--driver-map", help="with --copy-drivers: a file of lines 'template object = target object' for "
                        "drivers reading objects other than the template's own and its armature's")
    parser.add_argument("--name-map", help=NAME_MAP_HELP)
    parser.add_argument("--json", help="write the report here")
    parser.add_argument("--output", help="save the result to this .blend (the input is never written)")


def transfer_targets(args, shapesmith):
    """The target heads named by --target (each a head and its parts, comma separated) and
    --targets (heads with their stored lists), in order, without repeats."""
    import fnmatch

    names = [find_face(value, shapesmith).name for value in args.target]
    if args.targets:
        matched = sorted(o.name for o in bpy.data.objects if fnmatch.fnmatchcase(o.name, args.targets))
        if not matched:
            raise BatchError(f"--targets '{args.targets}' matches no object")
        names += matched
    if not names:
        raise BatchError("give --target NAME (repeatable) or --targets GLOB")
    return [find_object(name) for name in dict.fromkeys(names)]


def run_transfer(args):
    """Validates and solves every target before writing any, then writes and saves."""
    import time
    from importlib import import_module

    shapesmith = load_shapesmith()
    # The flags have the Transfer panel's property names, so the panel's reading serves them.
    settings = tool_settings().transfer_settings(args)
    started = time.perf_counter()
    open_blend(args.input)
    transfer = import_module(shapesmith.__name__ + ".blender.transfer")
    shape_keys = import_module(shapesmith.__name__ + ".blender.shape_keys")
    source = find_face(args.source, shapesmith)
    targets = transfer_targets(args, shapesmith)
    names, drivers = name_map(args, shapesmith), driver_map(args, shapesmith)
    pack_report = None
    if args.pack_json:
        if not os.path.isfile(args.pack_json):
            raise BatchError(f"pack JSON not found: {args.pack_json}")
        with open(args.pack_json) as f:
            pack_report = json.load(f)
    if args.examples and len(targets) > 1 and "{target}" not in args.examples:
        raise BatchError("--examples with several targets must name them per target with {target}")
    opened = time.perf_counter()
    # The template's own intersection per shape is the same for every target: measured once.
    template_penetration = transfer.measure_template_penetration(source)
    measured = time.perf_counter()
    solved = []
    for target in targets:
        examples = [find_object(n.strip().replace("{target}", target.name)) for n in (args.examples or "").split(",") if n.strip()]
        solved.append(
            transfer.transfer_object(
                source,
                target,
                settings,
                training_objects=examples,
                pack_report=pack_report,
                template_penetration=template_penetration,
                keys=args.keys.split(",") if args.keys is not None else None,
            )
        )
    reports = []
    for result in solved:
        write_started = time.perf_counter()
        written, skipped, warnings = shape_keys.write_transferred_keys(
            result, args.overwrite, args.copy_drivers, keep_sculpted=args.keep_sculpted, name_map=names,
            driver_map=drivers)
        transfer.store_transfer(result, written, skipped)
        result.warnings += warnings
        for line in transfer.summary_lines(result, written, skipped):
            print(line)
        seconds = dict(result.report["seconds"])
        seconds["io"] = seconds.pop("read") + time.perf_counter() - write_started
        reports.append(
            {
                "target": result.target.name,
                "objects": result.report["objects"],
                "shapes": written,
                "skipped": skipped,
                # Keys written under the target's own name for the shape (another convention's).
                "written_onto": {name: own for name, own in result.onto.items() if own != name},
                "virtual_edges": result.report["virtual_edges"],
                "penetrations": result.report["penetration"],
                "neutral_penetration": result.report["neutral_penetration"],
                "template_neutral_penetration": result.report["template_neutral_penetration"],
                "training": {name: row.tolist() for name, row in result.training.items()},
                "weights": result.report.get("weights"),
                "example_noise": result.report.get("example_noise"),
                "worse_than_template": transfer.worse_than_template(result.report),
                "worse_before_contact": (
                    transfer.worse_than_template(result.report, key="before_contact_length")
                    if transfer.contact_traced(result.report)
                    else None
                ),
                "plain_worse_than_template": (
                    transfer.worse_than_template(result.report, key="plain_length") if args.compare_plain else None
                ),
                "warnings": result.warnings,
                "seconds": seconds,
            }
        )
    saved = time.perf_counter()
    if args.output:
        save_copy(args.output)
    totals = {key: sum(r["seconds"][key] for r in reports) for key in reports[0]["seconds"]}
    totals["io"] += (opened - started) + (time.perf_counter() - saved)
    totals["template_penetration"] = measured - opened
    totals["total"] = time.perf_counter() - started
    write_json(
        args.json,
        {
            "input": os.path.abspath(args.input),
            "source": source.name,
            "params": solved[0].report["params"],
            "targets": reports,
            "seconds": totals,
        },
    )


def add_wrap_args(parser, settings):
    parser.add_argument("--input", required=True, help=".blend file to read")
    parser.add_argument("--template", help="the template: " + FACE_HELP + " (default: the bundled ARKit template)")
    parser.add_argument(
        "--character", required=True,
        help="the character: a head of any topology; with face parts, the head then its parts, comma separated",
    )
    parser.add_argument(
        "--pairs",
        help="point pairs JSON: [[template_vertex, character_vertex], ...] or [[[x,y,z],[x,y,z]], ...] in each "
        "object's local space (default: the pairs stored on the character; none stored: proposed as --propose-pairs)",
    )
    parser.add_argument(
        "--propose-pairs", action="store_true",
        help="propose the pairs (eye and mouth corners, nose tip and chin found on both heads), store "
        "them on the character, use them, and write them to the JSON (proposed_pairs)",
    )
    parser.add_argument("--no-transfer", action="store_true", help="wrap only: keep the wrapped template, write no keys")
    parser.add_argument("--keep-wrapped", action="store_true", help="keep the wrapped template object in the output")
    default = add_transfer_settings_args(parser, settings, " on the wrapped template")
    # What only the transfer's own command sets: the carried keys are not personalised.
    parser.set_defaults(compare_plain=default.compare_plain, beta_reg=default.personalise.beta_reg,
                        refine_weights=default.personalise.refine_weights)
    parser.add_argument("--overwrite", action="store_true", help="replace existing keys of the same name")
    parser.add_argument("--keep-sculpted", action="store_true",
                        help="with --overwrite: add back what was sculpted on a key since the last transfer wrote it")
    parser.add_argument("--name-map", help=NAME_MAP_HELP)
    parser.add_argument("--copy-drivers", action="store_true", help="recreate the template's key drivers")
    parser.add_argument("--driver-map", help="with --copy-drivers: a file of lines 'template object = target object' for "
                        "drivers reading objects other than the template's own and its armature's")
    parser.add_argument("--json", help="write the report here")
    parser.add_argument("--output", help="save the result to this .blend (the input is never written)")


def run_wrap(args):
    """Wraps the template onto the character, transfers onto the wrapped template, carries the
    keys onto the character's own vertices; writes only when all of it succeeded."""
    import time
    from importlib import import_module

    shapesmith = load_shapesmith()
    started = time.perf_counter()
    open_blend(args.input)
    wrap = import_module(shapesmith.__name__ + ".blender.wrap")
    shape_keys = import_module(shapesmith.__name__ + ".blender.shape_keys")
    transfer = import_module(shapesmith.__name__ + ".blender.transfer")
    template, character = template_or_bundled(args.template, shapesmith), find_face(args.character, shapesmith)
    for obj in (template, character):
        if obj.type != "MESH":
            raise BatchError(f"'{obj.name}' is a {obj.type.lower()}, not a mesh")
    proposal = None
    if args.pairs and args.propose_pairs:
        raise BatchError("give --pairs or --propose-pairs, not both")
    if args.pairs:
        if not os.path.isfile(args.pairs):
            raise BatchError(f"point pairs file not found: {args.pairs}")
        template_points, character_points = wrap.pairs_from_json(args.pairs, template, character)
    else:
        if args.propose_pairs:
            character.shapesmith_wrap.pairs.clear()
            if wrap.PAIRS_PROPERTY in character.keys():
                del character[wrap.PAIRS_PROPERTY]
        template_points, character_points, proposal = wrap.pairs_or_proposed(character, template)
        if proposal is not None:
            print(f"point pairs proposed: {len(proposal['pairs'])}" + (f" (not found: {', '.join(proposal['missing'])})" if proposal["missing"] else ""))
    opened = time.perf_counter()
    wrapped = wrap.wrap_object(template, character, template_points, character_points)
    wrapped.seconds["io"] += opened - started
    wrapped_object = wrap.show_wrapped(wrapped)
    written, skipped, warnings, penetration, worse, symmetry = [], [], [], None, None, None
    seconds, looks = dict(wrapped.seconds), None
    try:
        if not args.no_transfer:
            result = wrap.carry_onto_character(
                template,
                character,
                wrapped_object,
                tool_settings().transfer_settings(args),
                seconds=wrapped.seconds,
            )
            seconds = result.report["stage_seconds"]
            writing = time.perf_counter()
            written, skipped, warnings = shape_keys.write_transferred_keys(
                result, args.overwrite, args.copy_drivers, keep_sculpted=args.keep_sculpted,
                name_map=name_map(args, shapesmith), driver_map=driver_map(args, shapesmith))
            seconds["io"] += time.perf_counter() - writing
            penetration = {"neutral": result.report["neutral_penetration"], "shapes": result.report["penetration"]}
            worse = transfer.worse_than_template(result.report)
            symmetry, looks = result.report["symmetry"], result.report["looks"]
            transfer.store_transfer(result, written, skipped)
            warnings = result.warnings + warnings
    finally:
        if not (args.keep_wrapped or args.no_transfer):
            wrap.remove_object(wrapped_object)
    wrap.store_wrap(wrapped, "WRAP")
    character.shapesmith_wrap.written = len(written)
    if symmetry is not None:
        wrap.store_symmetry(character, symmetry)
    for line in wrap.summary_lines(wrapped):
        print(line)
    if symmetry is not None and symmetry["worst"] is not None:
        worst = symmetry["worst"]
        print(f"symmetric carry: worst mirror miss {100 * worst['carried']:.1f}% ({worst['pair']}; {100 * worst['template']:.1f}% on the wrapped template)")
    elif symmetry is not None:
        print(f"carried without symmetry: {symmetry['reason']}")
    if not args.no_transfer:
        print(f"{len(written)} shape keys written onto '{character.name}'" + (f", {len(skipped)} kept" if skipped else ""))
        print(f"adding more intersection on the character than on the template: {len(worse)}" + (f" ({', '.join(worse)})" if worse else ""))
        print_looks(shapesmith, character, looks)
    saving = time.perf_counter()
    if args.output:
        save_copy(args.output)
    seconds["io"] += time.perf_counter() - saving
    seconds["total"] = time.perf_counter() - started
    write_json(
        args.json,
        {
            "input": os.path.abspath(args.input),
            "template": template.name,
            "character": character.name,
            "fit": wrapped.report,
            "proposed_pairs": proposal,
            "shapes": written,
            "skipped": skipped,
            "penetration": penetration,
            "worse_than_template": worse,
            "symmetry": symmetry,
            "looks": looks,
            "warnings": warnings + (proposal or {}).get("warnings", []) + wrapped.report["warnings"],
            "seconds": seconds,
        },
    )


def add_solve_args(parser, settings):
    parser.add_argument("--input", required=True, help=".blend file to read")
    parser.add_argument("--object", required=True, help="the head: mesh with shape keys and a landmark layout")
    source = parser.add_mutually_exclusive_group(required=True)
    source.add_argument("--trajectories", help="3D trajectories: CSV (<landmark>_x,_y,_z columns) or TRC")
    source.add_argument("--clip", help="a Movie Clip in the file whose tracks are named after the landmarks (2D)")
    parser.add_argument("--camera", help="with --clip: the camera object placed for the shot (default: the scene's camera)")
    parser.add_argument("--landmarks", help="collection of landmark empties (default: the head's Place Landmarks layout)")
    parser.add_argument("--scale", type=float, default=1.0, help="trajectories: scene units per file unit (default 1)")
    default = settings.PerformanceSettings()
    parser.add_argument("--smoothing", type=float, default=default.smoothing,
                        help="temporal smoothing lambda >= 0 (default %(default)s)")
    parser.add_argument("--solve-scale", action=argparse.BooleanOptionalAction, default=default.solve_scale,
                        help="3D: solve a uniform head scale per frame")
    parser.add_argument("--target", help="key the pose on this object (an empty) instead of the head")
    parser.add_argument("--plot", metavar="PNG", help="plot the residual and the most active weights to this PNG")
    parser.add_argument("--plot-shapes", help="comma-separated shapes to plot (default: the most active)")
    parser.add_argument("--json", help="write the report here")
    parser.add_argument("--output", help="save the animated file here (the input is never written)")


def run_solve(args):
    """Per frame: the head's pose and the shape weights from tracked landmarks, keyed."""
    import time
    from importlib import import_module

    shapesmith = load_shapesmith()
    started = time.perf_counter()
    open_blend(args.input)
    performance = import_module(shapesmith.__name__ + ".blender.performance")
    obj = find_object(args.object)
    if obj.type != "MESH":
        raise BatchError(f"'{obj.name}' is a {obj.type.lower()}, not a mesh")
    if not (args.smoothing >= 0):
        raise BatchError(f"--smoothing must be >= 0, got {args.smoothing}")
    collection = None
    if args.landmarks:
        collection = bpy.data.collections.get(args.landmarks)
        if collection is None:
            raise BatchError(f"no collection named '{args.landmarks}' in the file")
    target = find_object(args.target) if args.target else None
    names, vertices = performance.layout_landmarks(obj, collection)
    scene = bpy.context.scene
    if args.trajectories:
        tracks = performance.read_trajectories(args.trajectories, names, vertices, scene.frame_start, args.scale)
    else:
        clip = bpy.data.movieclips.get(args.clip)
        if clip is None:
            raise BatchError(f"no movie clip named '{args.clip}' in the file "
                             f"(clips: {', '.join(c.name for c in bpy.data.movieclips) or 'none'})")
        camera = find_object(args.camera) if args.camera else scene.camera
        tracks = performance.clip_tracks(clip, names, vertices, camera)
    read = time.perf_counter()
    # The flags have the Performance panel's property names, so the panel's reading serves them.
    document = performance.solve(obj, tracks, tool_settings().performance_settings(args))
    solved = time.perf_counter()
    performance.write_animation(obj, document, target)
    for line in performance.summary_lines(document):
        print(line)
    if args.plot:
        plot = import_module(shapesmith.__name__ + ".blender.performance_plot")
        shapes = args.plot_shapes.split(",") if args.plot_shapes else None
        plot.write_plot_png(document, os.path.abspath(args.plot), shapes)
    if args.output:
        save_copy(args.output)
    document.update(input=os.path.abspath(args.input), seconds={
        "read": read - started, "solve": solved - read, "per_frame": (solved - read) / max(len(document["frames"]), 1),
        "total": time.perf_counter() - started})
    write_json(args.json, document)


def add_import_capture_args(parser, settings):
    parser.add_argument("--input", required=True, help=".blend file to read")
    parser.add_argument("--object", required=True, help="the head: mesh with (ARKit-named) shape keys")
    parser.add_argument("--capture", required=True, help="Live Link Face CSV or Face Cap TXT")
    parser.add_argument("--mapping", help='JSON file {"column": "shape key" or ["key", ...]} for names that do not match')
    parser.add_argument("--name-map", help=NAME_MAP_HELP)
    parser.add_argument("--capture-fps", type=float, help="Live Link Face: the capture's frame rate (default: from the timecodes)")
    parser.add_argument("--no-head", action="store_true", help="do not key the head rotation onto the object")
    parser.add_argument("--invert-head", default="", help="comma-separated head angles whose sign to change: yaw,pitch,roll")
    parser.add_argument("--json", help="write the report here")
    parser.add_argument("--output", required=True, help="save the animated file here (the input is never written)")


def run_import_capture(args):
    from importlib import import_module

    shapesmith = load_shapesmith()
    open_blend(args.input)
    capture = import_module(shapesmith.__name__ + ".blender.capture")
    obj = find_object(args.object)
    mapping = None
    if args.mapping:
        if not os.path.isfile(args.mapping):
            raise BatchError(f"mapping file not found: {args.mapping}")
        with open(args.mapping) as handle:
            mapping = capture.read_mapping(handle.read())
    invert = {name.strip().upper() for name in args.invert_head.split(",") if name.strip()}
    report = capture.import_capture(obj, args.capture, bpy.context.scene, mapping, args.capture_fps, not args.no_head, invert,
                                    name_map(args, shapesmith))
    print(f"{report['frames']} frames of {report['format']} onto '{obj.name}' (frames {report['first_frame']:g} to "
          f"{report['last_frame']:g}, capture {report['capture_fps']} fps, scene {report['scene_fps']:g} fps); "
          f"{len(report['columns_used'])} columns used, unmatched columns: {', '.join(report['unmatched_columns']) or 'none'}, "
          f"keys not driven: {', '.join(report['unmatched_keys']) or 'none'}; {capture.lost_tracking_line(report)}")
    save_copy(args.output)
    report.update(input=os.path.abspath(args.input))
    write_json(args.json, report)


COMMANDS = {
    "sample": (add_sample_args, run_sample, "build sample.blend from the MakeHuman assets"),
    "analyze": (add_analyze_args, run_analyze, "analyze a rig's shape keys"),
    "pack": (add_pack_args, run_pack, "pack the shape keys into reference expressions"),
    "landmarks": (add_landmarks_args, run_landmarks, "place landmarks, score and export the layout"),
    "transfer": (add_transfer_args, run_transfer, "transfer a template's shape keys onto other heads"),
    "wrap": (add_wrap_args, run_wrap, "wrap the template onto a character of any topology and write its keys there"),
    "generate": (add_generate_args, run_generate, "write the 52 ARKit keys onto a character (its head on a full body)"),
    "crossings": (add_crossings_args, run_crossings, "list the faces each shape key pushes through the mesh"),
    "solve": (add_solve_args, run_solve, "solve shape-key animation and head pose from tracked landmarks"),
    "import-capture": (add_import_capture_args, run_import_capture, "key an ARKit capture (Live Link Face, Face Cap) onto the rig"),
}


def parser_for(argv):
    """The command line's parser, with the flags of the command `argv` names: a tool's take
    their defaults from the installed extension's settings (`tool_settings`), so only that
    command's are built (`sample` needs no extension)."""
    parser = argparse.ArgumentParser(prog="batch.py --", description=__doc__.split("\n\n")[0])
    sub = parser.add_subparsers(dest="command", required=True)
    command = argv[0] if argv else None
    for name, (add_args, _, help_text) in COMMANDS.items():
        command_parser = sub.add_parser(name, help=help_text)
        if name == command:
            add_args(command_parser, None if name == "sample" else tool_settings())
    return parser


def parse(argv):
    return parser_for(argv).parse_args(argv)


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else sys.argv[1:]
    try:
        try:
            args = parse(argv)
        except SystemExit as exit_:
            return exit_.code or 0
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
