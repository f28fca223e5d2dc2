"""Renders the README's picture of the performance loop, headless (bpy Python):

    python scripts/render_performance_loop.py [-- --output docs/performance_loop.png]

The known performance of `known_performance.py` on the bundled Template (100 frames, tracker
noise 0.1% of the diagonal), in its three steps:

1. the head with the 68 landmarks Place Landmarks chose (a cover of every shape, then the ones
   Add for Reconstruction adds), as dots on a front render;
2. the tracks: each landmark's noisy 3D trajectory over the 15 frames before TRACK_FRAME,
   drawn over a render of the true performance at that frame (the take's image);
3. the solve (3D trajectories, smoothing 1): the head driven by the solved weights and pose at
   TRACK_FRAME beside it, then at SOLVED_FRAMES, above the Performance panel's plot of the
   residual and four weights, those frames marked.

Workbench renders through an orthographic camera in front of the head (-Y, up +Z), so a point's
place in the picture is its (x, z) scaled; dots and trajectories are drawn onto the renders.
"""

import argparse
import os
import sys
from importlib import import_module

import bpy
import numpy as np
from mathutils import Matrix, Vector

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
import batch  # noqa: E402
import known_performance as known  # noqa: E402
import pictures  # noqa: E402
from bench_transfer import batch_cache  # noqa: E402

FRAMES = 100
TRACK_FRAME = 40
TRAIL = 15
SOLVED_FRAMES = (12, 55, 70, 90)
PLOT_SHAPES = ["jawOpen", "mouthSmileLeft", "eyeBlinkLeft", "browInnerUp"]
WIDTH = 900
TILE = (296, 330)
SMALL = (219, 250)
GAP, LABEL = 6, 26
SKIN = (0.82, 0.68, 0.6)
DOT = (0.05, 0.35, 0.85)
TRACK = (0.85, 0.33, 0.05)
MARK = (0.6, 0.6, 0.6)


class Stage:
    """The orthographic front camera: centred on the posed head (its neutral's box centre
    moved by the pose: the mesh's origin is far below the head, so a small turn moves the head
    much), the head's extent across the picture's longer side."""

    def __init__(self, rig):
        low, high = rig.neutral.min(0).astype(np.float64), rig.neutral.max(0).astype(np.float64)
        self.rest_centre = (low + high) / 2
        self.extent = 1.08 * float(max(high[0] - low[0], high[2] - low[2]))
        self.centre = self.rest_centre

    def place(self, rotation, translation):
        self.centre = np.asarray(rotation) @ self.rest_centre + np.asarray(translation)

    def render(self, obj, size, path):
        location = Vector(self.centre) + Vector((0.0, -1.0, 0.0))
        pictures.render_alone(obj, location, Vector((0.0, 1.0, 0.0)), self.extent, size, path)
        return load_over_white(path)

    def to_pixels(self, points, size):
        """(x, y) picture coordinates (row 0 at the top) of world points."""
        width, height = size
        scale = max(width, height) / self.extent
        x = width / 2 + (points[..., 0] - self.centre[0]) * scale
        y = height / 2 - (points[..., 2] - self.centre[2]) * scale
        return np.stack([x, y], axis=-1)


def load_over_white(path):
    """A rendered PNG as an (H, W, 3) array, row 0 at the top, its transparent film on white."""
    image = bpy.data.images.load(path, check_existing=False)
    width, height = image.size
    rgba = np.array(image.pixels[:], dtype=np.float32).reshape(height, width, 4)[::-1]
    bpy.data.images.remove(image)
    alpha = rgba[..., 3:]
    return rgba[..., :3] * alpha + (1.0 - alpha)


def pose(obj, weights, rotation, translation):
    """Poses the head: the shape keys at `weights`, its world matrix from the pose."""
    keys = obj.data.shape_keys.key_blocks
    for name, weight in zip(known_names(obj), weights):
        keys[name].value = float(weight)
    matrix = Matrix(np.asarray(rotation).tolist()).to_4x4()
    matrix.translation = Vector(translation)
    obj.matrix_world = matrix


def known_names(obj):
    keys = obj.data.shape_keys
    return [block.name for block in keys.key_blocks if block != keys.reference_key]


def dot(canvas, x, y, colour, radius=2):
    canvas.rect(x - radius, y - radius, x + radius, y + radius, colour)


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="render_performance_loop.py --")
    parser.add_argument("--output", default=os.path.join(SCRIPTS, "..", "docs", "performance_loop.png"))
    args = parser.parse_args(argv)
    output = os.path.abspath(args.output)
    shapesmith = batch.load_shapesmith()
    modules = {name: import_module(f"{shapesmith.__name__}.blender.{name}")
               for name in ("landmarks", "mesh_arrays", "performance_plot", "landmark_curve")}
    native = import_module(shapesmith.__name__ + ".native").module()
    Canvas = modules["landmark_curve"].Canvas
    bpy.ops.wm.open_mainfile(filepath=batch.cached_sample())
    template = bpy.data.objects["Template"]
    rig = modules["mesh_arrays"].read_rig(template)
    assert known_names(template) == rig.names

    vertices = known.designed_layout(modules["landmarks"], template)
    weights, rotations, translations = known.truth(len(rig.names), FRAMES)
    _, noisy, _ = known.tracks(rig, vertices, FRAMES, "3d")
    _, rms, _, solved = known.solve(native, rig, vertices, FRAMES, "3d")
    print(f"{len(vertices)} landmarks; solved weight RMS {rms:.4f}")

    scene = bpy.context.scene
    scene.render.film_transparent = True
    shading = scene.display.shading
    shading.light, shading.color_type, shading.single_color = "STUDIO", "SINGLE", SKIN
    shading.show_cavity = True
    stage = Stage(rig)
    work = os.path.join(batch_cache(), "render")
    os.makedirs(work, exist_ok=True)
    tiles = {}

    # 1. The landmarks on the neutral, at rest.
    pose(template, np.zeros(len(rig.names)), np.eye(3), np.zeros(3))
    canvas = Canvas(*TILE)
    canvas.pixels[:] = stage.render(template, TILE, os.path.join(work, "loop_landmarks.png"))
    for x, y in stage.to_pixels(rig.neutral[vertices].astype(np.float64), TILE):
        dot(canvas, x, y, DOT, 3)
    tiles["landmarks"] = canvas.pixels

    # 2. The tracks over the true frame.
    f = TRACK_FRAME
    pose(template, weights[f], rotations[f], translations[f])
    stage.place(rotations[f], translations[f])
    canvas = Canvas(*TILE)
    canvas.pixels[:] = 0.35 + 0.65 * stage.render(template, TILE, os.path.join(work, "loop_truth.png"))
    trails = stage.to_pixels(noisy[f - TRAIL:f + 1], TILE)
    for landmark in range(len(vertices)):
        path = trails[:, landmark]
        for (x0, y0), (x1, y1) in zip(path, path[1:]):
            canvas.line(x0, y0, x1, y1, TRACK)
        dot(canvas, *path[-1], TRACK, 2)
    tiles["tracks"] = canvas.pixels

    # 3. The driven head at the same frame, then at the strip's frames.
    def solved_render(frame, size, name):
        pose(template, solved["weights"][frame], solved["rotations"][frame], solved["translations"][frame])
        stage.place(solved["rotations"][frame], solved["translations"][frame])
        return stage.render(template, size, os.path.join(work, name))

    tiles["solved"] = solved_render(f, TILE, "loop_solved.png")
    strip = [solved_render(frame, SMALL, f"loop_solved_{frame}.png") for frame in SOLVED_FRAMES]

    document = {"frames": list(range(FRAMES)), "residuals": solved["residuals"], "weights": solved["weights"],
                "shapes": rig.names, "kind": "3d"}
    plot = modules["performance_plot"].plot_picture(document, PLOT_SHAPES)
    mark_frames(modules["performance_plot"], plot, SOLVED_FRAMES + (TRACK_FRAME,))

    height = 3 * LABEL + TILE[1] + SMALL[1] + plot.shape[0] + 2 * GAP
    sheet = Canvas(WIDTH, height)
    top = LABEL
    labels = ("1 PLACE LANDMARKS (68)", f"2 TRACK (FRAMES {TRACK_FRAME - TRAIL}-{TRACK_FRAME})",
              f"3 SOLVE: FRAME {TRACK_FRAME}")
    for i, (key, label) in enumerate(zip(("landmarks", "tracks", "solved"), labels)):
        left = i * (TILE[0] + GAP)
        sheet.text(left + 4, top - 18, label)
        sheet.pixels[top:top + TILE[1], left:left + TILE[0]] = tiles[key]
    top += TILE[1] + GAP + LABEL
    sheet.text(4, top - 18, "SOLVED FRAMES " + ", ".join(str(frame) for frame in SOLVED_FRAMES))
    for i, picture in enumerate(strip):
        left = i * (SMALL[0] + GAP)
        sheet.pixels[top:top + SMALL[1], left:left + SMALL[0]] = picture
        sheet.text(left + 6, top + 6, str(SOLVED_FRAMES[i]), MARK)
    top += SMALL[1] + GAP + LABEL
    sheet.text(4, top - 18, f"RESIDUAL AND WEIGHTS PER FRAME (WEIGHT RMS {rms:.3f} FROM THE TRUTH)")
    sheet.pixels[top:top + plot.shape[0], :plot.shape[1]] = plot
    modules["landmark_curve"].save_png(sheet.pixels, output, "Shapesmith Performance Loop")
    print(f"wrote {output}")


def mark_frames(plot_module, pixels, frames):
    """Grey vertical lines at `frames` across the plot's panels (its x axis: frames 0 to FRAMES - 1)."""
    plot_width = plot_module.WIDTH - plot_module.LEFT - plot_module.RIGHT
    bottom = plot_module.HEIGHT - plot_module.BOTTOM
    for frame in frames:
        x = int(round(plot_module.LEFT + frame / (FRAMES - 1) * plot_width))
        column = pixels[plot_module.TOP:bottom, x]
        white = (column > 0.97).all(axis=1)
        column[white] = MARK


if __name__ == "__main__":
    main()
