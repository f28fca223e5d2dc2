"""The solve's plot as a PNG: the per-frame residual on top, the weights of chosen shapes
below, against the scene frame. Drawn with numpy (the landmark curve's canvas and font) and
saved through a temporary Blender image, so the .blend is not changed."""

import numpy as np

from .landmark_curve import GRID, INK, Canvas, nice_ticks, save_png

WIDTH, HEIGHT = 900, 560
LEFT, RIGHT, TOP, GAP, BOTTOM = 80, 170, 30, 50, 40
RESIDUAL = (0.85, 0.33, 0.05)
KEPT = (0.85, 0.05, 0.05)
COLOURS = [(0.05, 0.35, 0.85), (0.1, 0.55, 0.2), (0.6, 0.1, 0.6), (0.85, 0.6, 0.0), (0.0, 0.6, 0.65), (0.45, 0.3, 0.15)]
# With no shapes chosen, the ones that move most over the take.
DEFAULT_SHAPES = 4


def chosen_shapes(document, names=None):
    """The shapes to plot: `names` (those the solve knows), else the most active ones."""
    shapes = document["shapes"]
    if names:
        return [name for name in names if name in shapes][: len(COLOURS)]
    weights = np.asarray(document["weights"])
    order = np.argsort(-weights.std(axis=0))
    return [shapes[k] for k in order[:DEFAULT_SHAPES] if weights[:, k].std() > 0]


def plot_picture(document, names=None):
    """The plot as an (H, W, 3) float array."""
    frames = np.asarray(document["frames"], dtype=float)
    residuals = np.array([np.nan if r is None else r for r in document["residuals"]], dtype=float)
    weights = np.asarray(document["weights"], dtype=float)
    shapes = chosen_shapes(document, names)
    canvas = Canvas(WIDTH, HEIGHT)
    plot_w = WIDTH - LEFT - RIGHT
    panel_h = (HEIGHT - TOP - GAP - BOTTOM) // 2
    x_low, x_high = frames.min(), max(frames.max(), frames.min() + 1)
    to_x = lambda f: LEFT + (f - x_low) / (x_high - x_low) * plot_w  # noqa: E731

    def panel(top, ceiling, label):
        to_y = lambda v: top + panel_h - v / ceiling * panel_h  # noqa: E731
        for value in nice_ticks(0.0, ceiling):
            canvas.line(LEFT, to_y(value), LEFT + plot_w, to_y(value), GRID)
            canvas.text(LEFT - 8, to_y(value) - 5, f"{value:.3g}", anchor="right")
        canvas.line(LEFT, top, LEFT, top + panel_h, INK, 2)
        canvas.line(LEFT, top + panel_h, LEFT + plot_w, top + panel_h, INK, 2)
        canvas.text(LEFT, top - 18, label)
        return to_y

    finite = residuals[np.isfinite(residuals)]
    ceiling = float(finite.max()) * 1.05 if len(finite) and finite.max() > 0 else 1.0
    unit = "PX" if document["kind"] == "2d" else "UNITS"
    to_y = panel(TOP, ceiling, f"RESIDUAL PER FRAME (RMS, {unit})")
    for f0, f1, r0, r1 in zip(frames, frames[1:], residuals, residuals[1:]):
        if np.isfinite(r0) and np.isfinite(r1):
            canvas.line(to_x(f0), to_y(r0), to_x(f1), to_y(r1), RESIDUAL, 2)
    for frame, r in zip(frames, residuals):
        if not np.isfinite(r):
            canvas.rect(to_x(frame) - 2, TOP + panel_h - 8, to_x(frame) + 2, TOP + panel_h, KEPT)
    bottom_top = TOP + panel_h + GAP
    to_y = panel(bottom_top, 1.0, "WEIGHTS")
    for value in nice_ticks(x_low, x_high, 8):
        canvas.text(to_x(value), bottom_top + panel_h + 8, f"{int(value)}", anchor="centre")
    for i, name in enumerate(shapes):
        column = weights[:, document["shapes"].index(name)]
        colour = COLOURS[i % len(COLOURS)]
        for f0, f1, w0, w1 in zip(frames, frames[1:], column, column[1:]):
            canvas.line(to_x(f0), to_y(w0), to_x(f1), to_y(w1), colour, 2)
        canvas.rect(WIDTH - RIGHT + 12, bottom_top + 16 * i + 2, WIDTH - RIGHT + 22, bottom_top + 16 * i + 10, colour)
        canvas.text(WIDTH - RIGHT + 28, bottom_top + 16 * i, name[:22], colour, scale=1)
    return canvas.pixels


def write_plot_png(document, path, names=None):
    """Writes the plot to `path` (PNG) through a temporary Blender image."""
    return save_png(plot_picture(document, names), path, "Shapesmith Performance Plot")
