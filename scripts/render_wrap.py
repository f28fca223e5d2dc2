"""Renders docs/wrap.md's pictures of Wrap, headless (bpy Python or Blender):

    python scripts/render_wrap.py [-- --shapes jawOpen,eyeBlinkLeft --out docs/]
    blender -b -P scripts/render_wrap.py -- [--shapes ...] [--out ...]

Template is wrapped onto Character_YoungWoman of the sample (other topology, centimetres,
Y up) with the pairs stored on it, its keys transferred onto the wrapped template and carried
onto the character, through the add-on's plain functions as `batch.py -- wrap` calls them.
Two pictures (Workbench, orthographic, from the front):
- `wrap_character.png`: the character at its neutral, then at each of --shapes at 1;
- `wrap_fit.png`: the wrapped template coloured by its `wrap_distance` attribute (blue on the
  character's surface, red at 1% of the bounding-box diagonal or more), front and side.
With the bpy wheel the extension is taken from scripts/demo's user directory unless
BLENDER_USER_RESOURCES is set (a Blender binary uses its own user directory).
"""

import os

os.environ.setdefault(
    "BLENDER_USER_RESOURCES",
    os.path.join(
        os.environ.get("SHAPESMITH_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "shapesmith")),
        "blender-user-demo",
    ),
)

import argparse  # noqa: E402
import hashlib  # noqa: E402
import sys  # noqa: E402
from importlib import import_module  # noqa: E402

import bpy  # noqa: E402
import numpy as np  # noqa: E402
from mathutils import Vector  # noqa: E402

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
import batch  # noqa: E402
import pictures  # noqa: E402
from bench_transfer import batch_cache  # noqa: E402

TEMPLATE, CHARACTER = "Template", "Character_YoungWoman"
SIZE = (400, 500)


def sample_path():
    """The demo's sample.blend, else the cached one keyed as scripts/demo keys it, built if missing."""
    demo = os.path.join(batch_cache(), "demo", "sample.blend")
    if os.path.isfile(demo):
        return demo
    with open(os.path.join(SCRIPTS, "makehuman.py"), "rb") as f:
        key = hashlib.sha256(f.read()).hexdigest()[:12]
    sample = os.path.join(batch_cache(), f"sample-{key}.blend")
    if not os.path.isfile(sample):
        batch.run_sample(argparse.Namespace(output=sample))
    return sample


def wrap_and_carry(shapesmith):
    """The wrapped template object and the character with the carried keys written."""
    try:
        wrap = import_module(shapesmith.__name__ + ".blender.wrap")
    except ImportError:
        raise SystemExit(
            "render_wrap.py: the installed Shapesmith has no Wrap: run scripts/demo again, or set "
            "BLENDER_USER_RESOURCES to a user directory with the current extension"
        ) from None
    shape_keys = import_module(shapesmith.__name__ + ".blender.shape_keys")
    template, character = bpy.data.objects[TEMPLATE], bpy.data.objects[CHARACTER]
    template_points, character_points = wrap.stored_pairs(character, template)
    wrapped = wrap.wrap_object(template, character, template_points, character_points)
    wrapped_object = wrap.show_wrapped(wrapped)
    result = wrap.carry_onto_character(template, character, wrapped_object)
    written, _, warnings = shape_keys.write_transferred_keys(result, True, False)
    for line in wrap.summary_lines(wrapped) + list(warnings):
        print(line)
    print(f"{len(written)} shape keys written onto '{character.name}'")
    return wrapped_object, character


def world_positions(obj):
    """Evaluated (posed) vertex positions in world space."""
    evaluated = obj.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = evaluated.to_mesh()
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float64)
    mesh.vertices.foreach_get("co", co)
    evaluated.to_mesh_clear()
    matrix = np.array(obj.matrix_world)
    return co.reshape(-1, 3) @ matrix[:3, :3].T + matrix[:3, 3]


def frame(obj):
    """Centre and orthographic scale framing the object's neutral from the front (-Y)."""
    points = world_positions(obj)
    low, high = points.min(0), points.max(0)
    # the portrait tile is 4:5; ortho_scale spans the longer (vertical) side
    extent = 1.08 * float(max(high[2] - low[2], (high[0] - low[0]) * SIZE[1] / SIZE[0]))
    return Vector((low + high) / 2), extent, float(high[1] - low[1] + extent)


def render(obj, centre, extent, distance, path, *, side=False, attribute=False):
    shading = bpy.context.scene.display.shading
    shading.light = "STUDIO"
    shading.show_cavity = not attribute
    shading.color_type = "VERTEX" if attribute else "MATERIAL"
    # the front is -Y; the side view looks from the character's left (+X)
    direction = Vector((1.0, 0.0, 0.0)) if side else Vector((0.0, -1.0, 0.0))
    pictures.render_alone(obj, centre + distance * direction, -direction, extent, SIZE, path, clip_end=10 * distance)


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="render_wrap.py --")
    parser.add_argument("--shapes", default="jawOpen,eyeBlinkLeft", help="carried shapes shown beside the neutral")
    parser.add_argument("--out", default=os.path.join(SCRIPTS, "..", "docs"), help="folder for the two PNGs")
    args = parser.parse_args(argv)
    out = os.path.abspath(args.out)
    shapes = [s for s in args.shapes.split(",") if s]
    sample = sample_path()  # first: building it resets Blender to factory settings
    shapesmith = batch.load_shapesmith()
    bpy.ops.wm.open_mainfile(filepath=sample)
    wrapped_object, character = wrap_and_carry(shapesmith)
    blocks = character.data.shape_keys.key_blocks
    missing = [s for s in shapes if s not in blocks]
    if missing:
        raise SystemExit(f"render_wrap.py: no carried shape {', '.join(missing)} on {CHARACTER}")

    scratch = os.path.join(batch_cache(), "render", "wrap")
    os.makedirs(scratch, exist_ok=True)
    os.makedirs(out, exist_ok=True)
    centre, extent, distance = frame(character)
    paths = []
    for shape in [None] + shapes:
        for block in blocks[1:]:
            block.value = 1.0 if block.name == shape else 0.0
        path = os.path.join(scratch, f"character_{shape or 'neutral'}.png")
        render(character, centre, extent, distance, path)
        paths.append(path)
    pictures.tiled(paths, os.path.join(out, "wrap_character.png"))

    # smooth shading for the picture only: the colour, not the facets, should show
    wrapped_object.data.shade_smooth()
    paths = []
    for side in (False, True):
        path = os.path.join(scratch, f"fit_{'side' if side else 'front'}.png")
        render(wrapped_object, centre, extent, distance, path, side=side, attribute=True)
        paths.append(path)
    pictures.tiled(paths, os.path.join(out, "wrap_fit.png"))
    print(f"wrote {os.path.join(out, 'wrap_character.png')} and {os.path.join(out, 'wrap_fit.png')}")


if __name__ == "__main__":
    main()
