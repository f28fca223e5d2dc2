"""The predicted-error curve of a conditioned layout as a PNG: predicted reconstruction error
against the number of landmarks, one point per landmark added after the cover, so that a
rigger can see where more landmarks stop paying and pick M.

Drawn with numpy into an RGB array (a 3 x 5 pixel font for the axis labels) and saved through
Blender's image API; the temporary image is removed again, so the .blend is not changed.
"""

import bpy
import numpy as np

from .mesh_arrays import MeshDataError

WIDTH, HEIGHT = 720, 420
LEFT, RIGHT, TOP, BOTTOM = 92, 24, 36, 56
BACKGROUND = (1.0, 1.0, 1.0)
INK = (0.15, 0.15, 0.15)
GRID = (0.88, 0.88, 0.88)
CURVE = (0.85, 0.33, 0.05)
COVER = (0.85, 0.05, 0.05)
CHOSEN = (0.05, 0.35, 0.85)
REFERENCE = (0.1, 0.55, 0.2)

# 3 x 5 glyphs, rows top to bottom, '#' = ink.
GLYPHS = {
    "0": "###,#.#,#.#,#.#,###", "1": ".#.,##.,.#.,.#.,###", "2": "###,..#,###,#..,###",
    "3": "###,..#,.##,..#,###", "4": "#.#,#.#,###,..#,..#", "5": "###,#..,###,..#,###",
    "6": "###,#..,###,#.#,###", "7": "###,..#,.#.,.#.,.#.", "8": "###,#.#,###,#.#,###",
    "9": "###,#.#,###,..#,###", ".": "...,...,...,...,.#.", "-": "...,...,###,...,...",
    "+": "...,.#.,###,.#.,...", "=": "...,###,...,###,...", "(": ".#.,#..,#..,#..,.#.",
    ")": ".#.,..#,..#,..#,.#.", ":": "...,.#.,...,.#.,...", " ": "...,...,...,...,...",
    "%": "#.#,..#,.#.,#..,#.#", "_": "...,...,...,...,###", ",": "...,...,...,.#.,#..",
    "/": "..#,..#,.#.,#..,#..",
    "A": ".#.,#.#,###,#.#,#.#", "B": "##.,#.#,##.,#.#,##.", "C": "###,#..,#..,#..,###",
    "D": "##.,#.#,#.#,#.#,##.", "E": "###,#..,##.,#..,###", "F": "###,#..,##.,#..,#..",
    "G": "###,#..,#.#,#.#,###", "H": "#.#,#.#,###,#.#,#.#", "I": "###,.#.,.#.,.#.,###",
    "J": "..#,..#,..#,#.#,###",
    "K": "#.#,#.#,##.,#.#,#.#", "L": "#..,#..,#..,#..,###", "M": "#.#,###,###,#.#,#.#",
    "N": "##.,#.#,#.#,#.#,#.#", "O": "###,#.#,#.#,#.#,###", "P": "###,#.#,###,#..,#..",
    "Q": "###,#.#,#.#,###,..#",
    "R": "##.,#.#,##.,#.#,#.#", "S": "###,#..,###,..#,###", "T": "###,.#.,.#.,.#.,.#.",
    "U": "#.#,#.#,#.#,#.#,###", "V": "#.#,#.#,#.#,#.#,.#.", "W": "#.#,#.#,###,###,#.#",
    "X": "#.#,#.#,.#.,#.#,#.#", "Y": "#.#,#.#,.#.,.#.,.#.", "Z": "###,..#,.#.,#..,###",
}


class Canvas:
    """An RGB float image, row 0 at the top (flipped when saved: Blender's rows go up)."""

    def __init__(self, width, height):
        self.pixels = np.empty((height, width, 3), dtype=np.float32)
        self.pixels[:] = BACKGROUND

    def rect(self, x0, y0, x1, y1, colour):
        h, w, _ = self.pixels.shape
        x0, x1 = sorted((int(round(x0)), int(round(x1))))
        y0, y1 = sorted((int(round(y0)), int(round(y1))))
        self.pixels[max(y0, 0):min(y1 + 1, h), max(x0, 0):min(x1 + 1, w)] = colour

    def line(self, x0, y0, x1, y1, colour, width=1):
        steps = int(max(abs(x1 - x0), abs(y1 - y0))) + 1
        for t in np.linspace(0.0, 1.0, steps + 1):
            x, y = x0 + t * (x1 - x0), y0 + t * (y1 - y0)
            self.rect(x - width // 2, y - width // 2, x + (width - 1) // 2, y + (width - 1) // 2, colour)

    def text(self, x, y, string, colour=INK, scale=2, anchor="left"):
        """Draws `string` (upper-cased) with its top at `y`; `anchor` left, right or centre."""
        string = string.upper()
        width = len(string) * 4 * scale - scale
        x = x - width if anchor == "right" else x - width / 2 if anchor == "centre" else x
        for i, char in enumerate(string):
            rows = GLYPHS.get(char, GLYPHS[" "]).split(",")
            for r, row in enumerate(rows):
                for c, cell in enumerate(row):
                    if cell == "#":
                        left = x + (4 * i + c) * scale
                        self.rect(left, y + r * scale, left + scale - 1, y + r * scale + scale - 1, colour)


def nice_ticks(low, high, count=5):
    """Round tick values covering [low, high]."""
    span = max(high - low, 1e-300)
    raw = span / count
    magnitude = 10 ** np.floor(np.log10(raw))
    step = magnitude * min((1, 2, 2.5, 5, 10), key=lambda m: abs(m * magnitude - raw))
    first = np.ceil(low / step) * step
    return [first + i * step for i in range(int(np.floor((high - first) / step + 1e-9)) + 1)]


def curve_picture(document):
    """The curve as an (H, W, 3) float array. Needs a layout with a design curve."""
    curve = document.get("curve") or []
    if not curve:
        raise MeshDataError(
            "the layout has no predicted-error curve: choose Up to Count or Up to Error under "
            "Add for Reconstruction and place landmarks again"
        )
    counts = np.array([point["landmarks"] for point in curve], dtype=float)
    errors = np.array([point["predicted_error"] for point in curve], dtype=float)
    chosen = len(document["landmarks"])
    reference = document.get("comparison")
    ceiling = errors.max() if reference is None else max(errors.max(), reference.get("predicted") or 0.0)
    y_ticks = nice_ticks(0.0, 1.05 * ceiling)
    y_top = max(y_ticks[-1], 1.05 * ceiling)
    x_low, x_high = counts.min(), max(counts.max(), counts.min() + 1)
    x_ticks = [t for t in nice_ticks(x_low, x_high, 8) if t == int(t)]
    plot_w, plot_h = WIDTH - LEFT - RIGHT, HEIGHT - TOP - BOTTOM
    to_x = lambda m: LEFT + (m - x_low) / (x_high - x_low) * plot_w  # noqa: E731
    to_y = lambda e: TOP + plot_h - e / y_top * plot_h  # noqa: E731

    canvas = Canvas(WIDTH, HEIGHT)
    for value in y_ticks:
        canvas.line(LEFT, to_y(value), LEFT + plot_w, to_y(value), GRID)
        canvas.text(LEFT - 8, to_y(value) - 5, f"{value * 100:.3g}", anchor="right")
    for value in x_ticks:
        canvas.line(to_x(value), TOP, to_x(value), TOP + plot_h, GRID)
        canvas.text(to_x(value), TOP + plot_h + 8, f"{int(value)}", anchor="centre")
    canvas.line(LEFT, TOP, LEFT, TOP + plot_h, INK, 2)
    canvas.line(LEFT, TOP + plot_h, LEFT + plot_w, TOP + plot_h, INK, 2)
    canvas.text(LEFT + plot_w / 2, HEIGHT - 22, "LANDMARKS", anchor="centre")
    canvas.text(LEFT, 10, "PREDICTED ERROR (% OF DIAGONAL)")
    if reference is not None and reference.get("predicted"):
        y = to_y(reference["predicted"])
        for x in range(LEFT, LEFT + plot_w, 12):
            canvas.line(x, y, min(x + 6, LEFT + plot_w), y, REFERENCE, 2)
        canvas.text(LEFT + plot_w - 4, y - 14, f"{reference['group']} ({reference['landmarks']})", REFERENCE, anchor="right")
    points = [(to_x(m), to_y(e)) for m, e in zip(counts, errors)]
    for (x0, y0), (x1, y1) in zip(points, points[1:]):
        canvas.line(x0, y0, x1, y1, CURVE, 2)
    for (x, y), m in zip(points, counts):
        colour = COVER if m == counts[0] else CHOSEN if m == chosen else CURVE
        size = 4 if colour is CURVE else 6
        canvas.rect(x - size, y - size, x + size, y + size, colour)
    canvas.text(points[0][0] + 8, points[0][1] - 16, "COVER", COVER)
    index = int(np.flatnonzero(counts == chosen)[0]) if chosen in counts else None
    if index is not None and index > 0:
        canvas.text(points[index][0] + 8, points[index][1] - 16, f"M={chosen}", CHOSEN)
    return canvas.pixels


def write_curve_png(document, path):
    """Writes the curve picture to `path` (PNG) through a temporary Blender image."""
    return save_png(curve_picture(document), path, "Shapesmith Landmark Curve")


def save_png(pixels, path, name):
    """Writes an (H, W, 3) Canvas picture (row 0 at the top) to `path` as PNG through a
    temporary Blender image called `name`."""
    height, width, _ = pixels.shape
    rgba = np.ones((height, width, 4), dtype=np.float32)
    rgba[:, :, :3] = pixels[::-1]
    image = bpy.data.images.new(name, width, height, alpha=False)
    try:
        image.pixels.foreach_set(rgba.ravel())
        image.filepath_raw = path
        image.file_format = "PNG"
        image.save()
    finally:
        bpy.data.images.remove(image)
    return path
