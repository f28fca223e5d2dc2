"""`batch.py -- generate`: Generate ARKit Keys on a character, as the panel's button does.

    python scripts/batch.py -- generate --input F.blend --character C [--template T] [--region GROUP]
                                        [--output OUT.blend] [--json REPORT.json]

The template defaults to the bundled ARKit template (added to the output); the region to the
whole mesh, or on a full body the head found above the neck."""

import os

from batch_common import BatchError, find_face, find_object, load_shapesmith, open_blend, save_copy, write_json


def add_generate_args(parser, settings):
    parser.add_argument("--input", required=True, help=".blend file to read")
    parser.add_argument(
        "--character", required=True,
        help="the character: a head or a full body of any topology; with face parts, the mesh then its parts, comma "
        "separated (none listed: objects within its head are taken by their place)",
    )
    parser.add_argument("--template", help="the template (default: the bundled ARKit template, added to the output)")
    parser.add_argument("--region", metavar="GROUP",
                        help="write keys on this vertex group of the character only (default: the whole mesh, or on a "
                        "full body the head, above the neck)")
    parser.add_argument("--keep-sculpted", action="store_true",
                        help="keys generated before keep what was sculpted on them since")
    parser.add_argument("--json", help="write the report here")
    parser.add_argument("--output", help="save the result to this .blend (the input is never written)")


def run_generate(args):
    """The 52 keys on the character; nothing is written unless all of it succeeded."""
    import time
    from importlib import import_module

    import bpy

    shapesmith = load_shapesmith()
    started = time.perf_counter()
    open_blend(args.input)
    generate = import_module(shapesmith.__name__ + ".blender.generate")
    character = find_face(args.character, shapesmith)
    template = find_object(args.template) if args.template else None
    for obj in (character, template):
        if obj is not None and obj.type != "MESH":
            raise BatchError(f"'{obj.name}' is a {obj.type.lower()}, not a mesh")
    generated = generate.generate_keys(character, template, region=args.region, keep_sculpted=args.keep_sculpted)
    if generated.template_added:
        bpy.context.scene.shapesmith.transfer.source = generated.template
    for line in generate.report_lines(generated):
        print(line)
    for warning in generated.warnings:
        print(f"warning: {warning}")
    if args.output:
        save_copy(args.output)
    write_json(args.json, {
        "input": os.path.abspath(args.input),
        "character": character.name,
        "template": generated.template.name,
        "template_added": generated.template_added,
        "region": generated.region,
        "region_vertices": generated.region_vertices,
        "face_parts_found": generated.parts_found,
        "shapes": generated.written,
        "skipped": generated.skipped,
        "fit": generated.wrap_report,
        "proposed_pairs": generated.proposal,
        "symmetry": generated.transfer_report["symmetry"],
        "warnings": generated.warnings,
        "seconds": {**generated.transfer_report["stage_seconds"], "total": time.perf_counter() - started},
    })
