"""Solve Performance benchmark (never asserted): seconds per frame and the known-answer
weight errors on the bundled Template and on its 25k-vertex subdivision, and the time Import
Capture takes on a long take.

    python scripts/bench_performance.py -- [--json OUT.json] [--frames 100] [--plot OUT.png]

The known performance (`known_performance.py`): random smooth weights and a rigid head motion;
the landmarks' positions with Gaussian noise of 0.1% of the head's diagonal, as 3D
trajectories and as pixels through a distorting camera. Layouts: Place Landmarks' cover with
landmarks added for reconstruction up to 68, and the conventional 68-point layout of
`bench_landmarks.py`, at the same noise. Import Capture: a 10-minute Live Link Face take at
60 fps (36,000 rows, every ARKit column and the head's angles), written and imported.
"""

import argparse
import csv
import os
import sys
import tempfile
import time

import bpy
import numpy as np

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
import batch  # noqa: E402
import known_performance as known  # noqa: E402

# The plot's shapes: one each of the jaw, the mouth corners, the lids and the brows.
PLOT_SHAPES = ["jawOpen", "mouthSmileLeft", "eyeBlinkLeft", "browInnerUp"]
CAPTURE_MINUTES, CAPTURE_FPS = 10, 60


def live_link_take(path, names, minutes=CAPTURE_MINUTES, fps=CAPTURE_FPS):
    """Writes a Live Link Face CSV of random weights on `names` (ARKit spelling) and small
    head angles; returns its row count."""
    rows = minutes * 60 * fps
    rng = np.random.default_rng(11)
    values = rng.random((rows, len(names)))
    head = 0.2 * np.sin(np.arange(rows)[:, None] * np.array([0.01, 0.013, 0.007]))
    with open(path, "w", newline="") as handle:
        writer = csv.writer(handle)
        writer.writerow(["Timecode", "BlendShapeCount", *names, "HeadYaw", "HeadPitch", "HeadRoll"])
        for f in range(rows):
            seconds, frame = divmod(f, fps)
            code = f"{10 + seconds // 3600:02d}:{seconds // 60 % 60:02d}:{seconds % 60:02d}:{frame:02d}.000"
            writer.writerow([code, len(names) + 3, *(f"{v:.6f}" for v in values[f]), *(f"{a:.6f}" for a in head[f])])
    return rows


def capture_benchmark(capture, template):
    """Seconds to import a long Live Link Face take onto the Template (read, match and key)."""
    names = [block.name[0].upper() + block.name[1:] for block in template.data.shape_keys.key_blocks[1:]]
    with tempfile.TemporaryDirectory() as directory:
        path = os.path.join(directory, "take.csv")
        rows = live_link_take(path, names)
        started = time.perf_counter()
        report = capture.import_capture(template, path, bpy.context.scene, fps=CAPTURE_FPS)
        seconds = time.perf_counter() - started
    template.animation_data_clear()
    template.data.shape_keys.animation_data_clear()
    return {"rows": rows, "columns": len(report["columns_used"]), "seconds": seconds, "ms_per_row": 1000 * seconds / rows}


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="bench_performance.py --")
    cache = os.environ.get("SHAPESMITH_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "shapesmith"))
    parser.add_argument("--json", default=os.path.join(cache, "bench", "performance.json"))
    parser.add_argument("--frames", type=int, default=100)
    parser.add_argument("--plot", help="also write the Performance panel's plot of the 3D solve with the designed layout (PNG)")
    args = parser.parse_args(argv)

    shapesmith = batch.load_shapesmith()
    from importlib import import_module

    landmarks = import_module(shapesmith.__name__ + ".blender.landmarks")
    mesh_arrays = import_module(shapesmith.__name__ + ".blender.mesh_arrays")
    capture = import_module(shapesmith.__name__ + ".blender.capture")
    native = import_module(shapesmith.__name__ + ".native").module()

    batch.open_blend(batch.cached_sample())
    template = bpy.data.objects["Template"]
    rig = mesh_arrays.read_rig(template)
    conventional = known.conventional_layout(landmarks, template)
    designed = known.designed_layout(landmarks, template)
    results = {"frames": args.frames, "noise": known.NOISE, "layouts": {}, "speed": {}}
    known.solve(native, rig, designed, 10, "3d")  # warm-up: the first call starts the thread pool
    print(f"Known answer, {args.frames} frames, noise {known.NOISE:.1%} of the diagonal, smoothing 1")
    print(f"{'head, layout':<36}{'N':>7}{'L':>4}{'kind':>6}{'s/frame':>10}{'w rms':>9}{'w max':>8}")

    def row(label, head_rig, vertices, kind):
        seconds, rms, worst, solved = known.solve(native, head_rig, vertices, args.frames, kind)
        per_frame = seconds / args.frames
        print(f"{label:<36}{len(head_rig.neutral):>7}{len(vertices):>4}{kind:>6}{per_frame:>10.4f}{rms:>9.4f}{worst:>8.3f}")
        return {"vertices": len(head_rig.neutral), "seconds_per_frame": per_frame, "ms_per_frame": 1000 * per_frame,
                "weight_rms": rms, "weight_max": worst}, solved

    for name, vertices in (("added for reconstruction", designed), ("conventional 68", conventional)):
        for kind in ("3d", "2d"):
            result, solved = row(f"Template, {name}", rig, vertices, kind)
            if args.plot and kind == "3d" and name == "added for reconstruction":
                plot = import_module(shapesmith.__name__ + ".blender.performance_plot")
                document = {"frames": list(range(1, args.frames + 1)), "residuals": solved["residuals"],
                            "weights": solved["weights"], "shapes": rig.names, "kind": "3d"}
                plot.write_plot_png(document, args.plot, PLOT_SHAPES)
            results["layouts"].setdefault(name, {"landmarks": len(vertices)})[kind] = result
    import bench_transfer

    dense = bench_transfer.subdivided(template, "Template_25k", bench_transfer.FACE_EDGES)
    dense_rig = mesh_arrays.read_rig(dense)
    for kind in ("3d", "2d"):
        # Subdivision keeps the original vertices first: the same landmarks on the denser head.
        results["speed"][f"25k_{kind}"], _ = row("25k head, added for reconstruction", dense_rig, designed, kind)
    results["capture"] = capture_benchmark(capture, template)
    c = results["capture"]
    print(f"\nImport Capture: {c['rows']} rows ({CAPTURE_MINUTES} minutes at {CAPTURE_FPS} fps), {c['columns']} columns "
          f"keyed in {c['seconds']:.2f} s ({c['ms_per_row']:.3f} ms a row)")
    batch.write_json(args.json, results)
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
