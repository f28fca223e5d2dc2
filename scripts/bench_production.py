"""Production-size benchmark, run with the bpy Python:

    python scripts/bench_production.py [-- --json OUT.json] [--sizes L:K ...] [--tools ...]

A rig the size studios use: the bundled head subdivided 0, 1 or 2 times (4.9k, 19k, 77k
vertices) with 52, 100 or 150 shape keys: the 52 ARKit units, MakeHuman's 34 expression units
(`makehuman.expression_units`) and combination shapes (sums of two ARKit units) up to the
count. Each size is built once by code and cached outside git
(`$SHAPESMITH_CACHE/production/`), with a transfer target (Target_OldMan subdivided alike)
and a wrap character of other topology (Target_YoungWoman subdivided alike, decimated to
45% of its faces, in centimetres and Y up, with 10 point pairs known by construction).

Each size runs in a process of its own (so its peak memory is its own) through every tool
as the panel and `scripts/batch.py` run them: Analyze, Pack (cold), Place Landmarks,
Transfer (template -> target with the default settings, keys written) and Wrap (fit,
transfer onto the wrapped template, carry, keys written); beside them the C++ Eigen reference
deformation transfer of `bench_reference_transfer.py` (pmp-library's: each shape's system
factorised afresh, single-threaded) on the same template, target and keys, its own seconds
(reading and writing excluded), and each tool's ratio to it against the goals. Per tool: wall seconds, the native calls'
seconds, the process's peak resident memory during the tool and the native calls' own peak
above the memory they started from (VmHWM, reset through /proc/self/clear_refs before each),
and how often the progress advanced (native reports, keys read, keys written). Blender-side costs apart: reading every key
(`read_rig`, foreach_get), writing every key (the transfer's `write_transferred_keys`,
foreach_set) and the memory the undo step of the transfer's written keys holds; the CPU
seconds and the load average beside the wall seconds, as the machine may be shared. The
growth of each cost with vertices (at the largest key count) and with keys (at the largest head) is fitted as
the exponent of a power law between the sizes (1: linear, 2: quadratic).
"""

import argparse
import json
import os
import resource
import subprocess
import sys
import tempfile
import time

import bpy
import numpy as np

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
import batch  # noqa: E402
import bench_reference_transfer  # noqa: E402
import makehuman  # noqa: E402
import production_heads  # noqa: E402
from production_rig import TARGET, build_rig, cached_rig_path  # noqa: E402

# Vertices at 1x, 4x and 16x (0, 1, 2 subdivisions) with the most keys; keys at the largest head.
SIZES = ("0:150", "1:150", "2:150", "2:52", "2:100")
TOOLS = ("analyze", "pack", "landmarks", "transfer", "reference", "wrap")
GOALS = {"transfer": 10.0, "pack": 3.0, "landmarks": 20.0}  # seconds on 2 cores, 150 keys
# Each tool's wall seconds over the reference transfer's at most this (Transfer: at least
# twice as fast, Pack in half its time, Landmarks in its time, Wrap in twice it).
REFERENCE_GOALS = {"transfer": 0.5, "pack": 0.5, "landmarks": 1.0, "wrap": 2.0}
MEMORY_GOAL = 4 * 1024**3


# ---- memory ---------------------------------------------------------------------------


def _status(field):
    with open("/proc/self/status") as f:
        for line in f:
            if line.startswith(field + ":"):
                return int(line.split()[1]) * 1024
    raise RuntimeError(f"no {field} in /proc/self/status")


def resident():
    return _status("VmRSS")


def reset_peak():
    """Sets the peak resident size (VmHWM) back to the current one (Linux's clear_refs 5)."""
    with open("/proc/self/clear_refs", "w") as f:
        f.write("5")


class Meter:
    """Peak memory and seconds of one tool, with its native calls measured apart: every
    public function of the native module is wrapped to reset the peak before the call and to
    read it after (so the tool's own peak is the largest over the segments)."""

    def __init__(self):
        self.tool_peak = 0
        self.native_seconds = 0.0
        self.native_peak_above_start = 0
        self.native_calls = {}

    def start(self):
        self.__init__()
        reset_peak()

    def _segment_peak(self):
        self.tool_peak = max(self.tool_peak, _status("VmHWM"))

    def wrap(self, name, function):
        def measured(*args, **kwargs):
            self._segment_peak()
            reset_peak()
            before = resident()
            started = time.perf_counter()
            try:
                return function(*args, **kwargs)
            finally:
                seconds = time.perf_counter() - started
                peak = _status("VmHWM")
                self.native_seconds += seconds
                self.native_peak_above_start = max(self.native_peak_above_start, peak - before)
                self.native_calls[name] = self.native_calls.get(name, 0.0) + seconds
                self._segment_peak()

        return measured

    def finish(self):
        self._segment_peak()
        return {
            "peak_bytes": self.tool_peak,
            "native_seconds": self.native_seconds,
            "native_peak_above_start_bytes": self.native_peak_above_start,
            "native_calls": self.native_calls,
        }


def cpu_seconds():
    """User and system seconds of this process's threads: beside the wall seconds, since on a
    machine shared with other work the wall time also counts the waits for a core."""
    usage = resource.getrusage(resource.RUSAGE_SELF)
    return usage.ru_utime + usage.ru_stime


def load_average():
    return os.getloadavg()[0]


def measure_native(nat, meter):
    for name in dir(nat):
        value = getattr(nat, name)
        if not name.startswith("_") and callable(value) and not isinstance(value, type):
            setattr(nat, name, meter.wrap(name, value))


# ---- one size through every tool --------------------------------------------------------


def run_tools(shapesmith, path, tools):
    from importlib import import_module

    def addon(name):
        return import_module(shapesmith.__name__ + ".blender." + name)

    analysis, packing, landmarks = addon("analysis"), addon("packing"), addon("landmarks")
    transfer, wrap, shape_keys, mesh_arrays = addon("transfer"), addon("wrap"), addon("shape_keys"), addon("mesh_arrays")
    bpy.ops.wm.open_mainfile(filepath=path)
    template, target, character = bpy.data.objects["Template"], bpy.data.objects[TARGET], bpy.data.objects["Character"]
    meter = Meter()
    measure_native(shapesmith.native.module(), meter)
    updates = [0, 0, 0]  # native progress reports, keys read, keys written

    def progress(fraction):
        updates[0] += 1
        return True

    def key_progress(done, total, writing):
        updates[2 if writing else 1] += 1

    mesh_arrays.key_progress.set(key_progress)

    result = {
        "vertices": len(template.data.vertices),
        "triangles": len(mesh_arrays.read_triangles(template)),
        "keys": len(template.data.shape_keys.key_blocks) - 1,
        "target_vertices": len(target.data.vertices),
        "character_vertices": len(character.data.vertices),
        "resident_after_open_bytes": resident(),
        "load_average_at_start": load_average(),
        "tools": {},
    }

    def measured(name, run):
        updates[:] = [0, 0, 0]
        meter.start()
        cpu, started = cpu_seconds(), time.perf_counter()
        extra = run() or {}
        row = {"seconds": time.perf_counter() - started, "cpu_seconds": cpu_seconds() - cpu, **meter.finish(),
               "progress_updates": updates[0],
               "keys_read": updates[1], "keys_written": updates[2], **extra}
        row["python_seconds"] = row["seconds"] - row["native_seconds"]
        result["tools"][name] = row
        print(f"  {name}: {row['seconds']:.2f} s (native {row['native_seconds']:.2f} s, cpu {row['cpu_seconds']:.2f} s), "
              f"peak {row['peak_bytes'] / 2**20:.0f} MiB", flush=True)

    def read_keys():
        rig = mesh_arrays.read_rig(template)
        return {"bytes": int(rig.deltas.nbytes)}

    measured("read keys", read_keys)
    if "analyze" in tools:
        measured("analyze", lambda: {"pairs": len(analysis.analyze_object(template)["symmetric_pairs"])})
    if "pack" in tools:
        def pack():
            options = packing.packing_options(template, axis=0)
            report = packing.pack_object(template, progress=progress, reuse_conflicts=False, **options)
            packing.store_packing(template, report)
            tests = report["poseability"]
            return {
                "expressions": len(report["expressions"]), "stages": {**report["seconds"], **tests["seconds"]},
                "collision_pairs_tested": tests["collision_pairs_tested"],
                "occlusion_directions_tested": tests["occlusion_directions_tested"],
            }

        measured("pack", pack)
    if "landmarks" in tools:
        def place():
            cameras = landmarks.camera_positions(template, "HEMISPHERE", bpy.context.scene)
            # The panel's defaults (`settings.LandmarkSettings`).
            document = landmarks.place_landmarks(template, addon("settings").LandmarkSettings(), cameras=cameras, progress=progress)
            landmarks.build_layout(template, document, bpy.context.scene)
            return {"landmarks": len(document["landmarks"]), "stages": document["seconds"]}

        measured("landmarks", place)
    if "transfer" in tools:
        def transfer_keys():
            solved = transfer.transfer_object(template, target, progress=progress)
            writing = time.perf_counter()
            written, _, _ = shape_keys.write_transferred_keys(solved)
            write_seconds = time.perf_counter() - writing
            transfer.store_transfer(solved, written, [])
            return {
                "written": len(written), "write_seconds": write_seconds,
                "worse_than_template": len(transfer.worse_than_template(solved.report)),
                "stages": solved.report["seconds"],
            }

        undo_push()  # the step before the transfer: what it holds is the file so far
        measured("transfer", transfer_keys)
        result["undo_step_bytes"] = undo_push()
    if "reference" in tools:
        binary = bench_reference_transfer.build_reference(os.path.join(makehuman.cache_dir(), "reference_transfer"))

        def reference():
            rig = mesh_arrays.read_rig(template)
            head = {"source": rig.neutral, "target": mesh_arrays.rest_positions(target),
                    "deltas": rig.deltas.reshape(-1, 3), "triangles": rig.triangles}
            with tempfile.TemporaryDirectory(prefix="shapesmith-reference-") as folder:
                production_heads.write_head(head, folder)
                seconds, _ = bench_reference_transfer.run_reference(binary, folder, 1)
            return {"reference_seconds": seconds["seconds"], "reference_cpu_seconds": seconds["cpu"],
                    "stages": {"setup": seconds["setup"]}}

        measured("reference", reference)
    if "wrap" in tools:
        def wrap_keys():
            template_points, character_points = wrap.stored_pairs(character, template)
            wrapped = wrap.wrap_object(template, character, template_points, character_points, progress=progress)
            wrapped_object = wrap.show_wrapped(wrapped)
            carried = wrap.carry_onto_character(template, character, wrapped_object, seconds=wrapped.seconds, progress=progress)
            writing = time.perf_counter()
            written, _, _ = shape_keys.write_transferred_keys(carried)
            seconds = dict(carried.report["stage_seconds"], write=time.perf_counter() - writing)
            return {"written": len(written), "mean_distance": wrapped.report["mean_distance"], "stages": seconds}

        measured("wrap", wrap_keys)
    result["load_average_at_end"] = load_average()
    result["peak_bytes"] = max(r["peak_bytes"] for r in result["tools"].values())
    return result


def undo_push():
    """Resident memory an undo step adds (None where Blender keeps no undo stack)."""
    if not bpy.ops.ed.undo_push.poll():
        return None
    before = resident()
    bpy.ops.ed.undo_push(message="bench")
    return resident() - before


# ---- growth and the table ---------------------------------------------------------------


def exponent(xs, ys):
    """Least-squares slope of log y against log x: the power of the growth."""
    xs, ys = np.log(np.asarray(xs, dtype=float)), np.log(np.maximum(np.asarray(ys, dtype=float), 1e-6))
    return float(np.polyfit(xs, ys, 1)[0]) if len(set(xs)) > 1 else None


def growth(runs, by, fixed):
    """Exponent per tool (wall, native and peak memory above the opened file) along `by`
    ('vertices' or 'keys') among the runs that share the largest `fixed`."""
    largest = max(r[fixed] for r in runs)
    chosen = sorted((r for r in runs if r[fixed] == largest), key=lambda r: r[by])
    if len({r[by] for r in chosen}) < 2:
        return {}
    out = {}
    for tool in chosen[0]["tools"]:
        rows = [r for r in chosen if tool in r["tools"]]
        xs = [r[by] for r in rows]
        out[tool] = {
            "seconds": exponent(xs, [r["tools"][tool]["seconds"] for r in rows]),
            "cpu_seconds": exponent(xs, [r["tools"][tool]["cpu_seconds"] for r in rows]),
            "native_seconds": exponent(xs, [r["tools"][tool]["native_seconds"] for r in rows]),
            "python_seconds": exponent(xs, [r["tools"][tool]["python_seconds"] for r in rows]),
            "memory": exponent(xs, [r["tools"][tool]["peak_bytes"] - r["resident_after_open_bytes"] for r in rows]),
            "sizes": xs,
        }
    return out


def print_report(result):
    runs = result["runs"]
    tools = list(runs[0]["tools"])
    print(f"\n== Seconds per tool: wall (CPU of both cores), then the native calls' wall; load average "
          f"{min(r['load_average_at_start'] for r in runs):.1f}-{max(r['load_average_at_end'] for r in runs):.1f}")
    print("  vertices  keys  " + "  ".join(f"{t:>22s}" for t in tools) + "  peak MiB")
    for run in runs:
        cells = [
            f"{r['seconds']:6.2f} ({r['cpu_seconds']:6.2f}) {r['native_seconds']:6.2f}" if (r := run["tools"].get(t)) else ""
            for t in tools
        ]
        print(f"  {run['vertices']:8d}  {run['keys']:4d}  " + "  ".join(f"{c:>22s}" for c in cells) + f"  {run['peak_bytes'] / 2**20:8.0f}")
    for run in runs:
        stages = "; ".join(
            f"{t}: " + ", ".join(f"{k} {v:.2f}" for k, v in r["stages"].items() if isinstance(v, float) and v >= 0.01)
            for t, r in run["tools"].items() if r.get("stages")
        )
        written = run["tools"].get("transfer", {}).get("write_seconds")
        print(f"  {run['vertices']} vertices, {run['keys']} keys: {stages}"
              + (f"; writing the transfer's keys {written:.2f}" if written is not None else ""))
    print("\n== Peak resident memory per tool (MiB; the native calls' own peak above where they started in brackets)")
    for run in runs:
        print(f"  {run['vertices']} vertices, {run['keys']} keys: " + "; ".join(
            f"{t} {r['peak_bytes'] / 2**20:.0f} ({r['native_peak_above_start_bytes'] / 2**20:.0f})" for t, r in run["tools"].items()))
        if run.get("undo_step_bytes") is not None:
            print(f"    an undo step after the transfer's keys: {run['undo_step_bytes'] / 2**20:.0f} MiB")
    for by, label in (("vertices", "vertices (at the most keys)"), ("keys", "keys (at the largest head)")):
        print(f"\n== Growth with {label}: exponent of a power law (1 linear, 2 quadratic): "
              "wall / CPU / native wall / python wall / memory")
        for tool, g in result["growth"][by].items():
            cells = [f"{g[k]:.2f}" if g[k] is not None else "-"
                     for k in ("seconds", "cpu_seconds", "native_seconds", "python_seconds", "memory")]
            print(f"  {tool:10s} {' / '.join(cells)}  over {g['sizes']}")
    largest = max(runs, key=lambda r: (r["vertices"], r["keys"]))
    print(f"\n== Goals at {largest['vertices']} vertices, {largest['keys']} keys")
    for tool, goal in GOALS.items():
        if tool in largest["tools"]:
            seconds = largest["tools"][tool]["seconds"]
            print(f"  {tool}: {seconds:.2f} s against {goal:.0f} s: {'met' if seconds < goal else 'NOT met'}")
    print(f"  peak memory: {largest['peak_bytes'] / 2**30:.2f} GiB against 4 GiB: "
          f"{'met' if largest['peak_bytes'] < MEMORY_GOAL else 'NOT met'}")
    for run in runs:
        reference = run["tools"].get("reference")
        if reference is None:
            continue
        seconds = reference["reference_seconds"]
        print(f"\n== Against the C++ reference transfer at {run['vertices']} vertices, {run['keys']} keys: "
              f"{seconds:.2f} s ({reference['reference_cpu_seconds']:.2f} CPU, one thread; reading and writing excluded)")
        for tool, goal in REFERENCE_GOALS.items():
            if tool in run["tools"]:
                row = run["tools"][tool]
                ratio, native = row["seconds"] / seconds, row["native_seconds"] / seconds
                print(f"  {tool}: {ratio:.2f}x the reference's time (native calls {native:.2f}x) against at most {goal:g}x: "
                      f"{'met' if ratio <= goal else 'NOT met'}")


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="bench_production.py --")
    parser.add_argument("--json", default=os.path.join(makehuman.cache_dir(), "bench", "bench_production.json"))
    parser.add_argument("--sizes", nargs="+", default=list(SIZES), metavar="LEVELS:KEYS",
                        help="subdivisions and key counts to run (default: %(default)s)")
    parser.add_argument("--tools", nargs="+", choices=TOOLS, default=list(TOOLS))
    parser.add_argument("--one", metavar="LEVELS:KEYS", help=argparse.SUPPRESS)  # a child process: one size
    parser.add_argument("--build", metavar="LEVELS:KEYS", help=argparse.SUPPRESS)  # a child process: build one size
    parser.add_argument("--report", metavar="JSON", help="print the tables of an earlier run's JSON and stop")
    args = parser.parse_args(argv)
    if args.report:
        with open(args.report) as f:
            result = json.load(f)
        result["growth"] = {"vertices": growth(result["runs"], "vertices", "keys"), "keys": growth(result["runs"], "keys", "vertices")}
        print_report(result)
        return
    if args.build:
        level, keys = map(int, args.build.split(":"))
        build_rig(level, keys, cached_rig_path(level, keys))
        return
    if args.one:
        level, keys = map(int, args.one.split(":"))
        shapesmith = batch.load_shapesmith()
        print(f"{args.one}: {cached_rig_path(level, keys)}", flush=True)
        result = run_tools(shapesmith, cached_rig_path(level, keys), args.tools)
        batch.write_json(args.json, result)
        return
    runs = []
    for size in args.sizes:
        level, keys = map(int, size.split(":"))
        me = [sys.executable, os.path.abspath(__file__), "--"]
        if not os.path.isfile(cached_rig_path(level, keys)):
            started = time.perf_counter()
            subprocess.run(me + ["--build", size], check=True)
            print(f"built {cached_rig_path(level, keys)} in {time.perf_counter() - started:.0f} s", flush=True)
        partial = args.json + f".{level}-{keys}.partial"
        subprocess.run(me + ["--one", size, "--json", partial, "--tools", *args.tools], check=True)
        with open(partial) as f:
            runs.append(json.load(f))
        os.remove(partial)
    result = {"runs": runs, "growth": {"vertices": growth(runs, "vertices", "keys"), "keys": growth(runs, "keys", "vertices")}}
    print_report(result)
    batch.write_json(args.json, result)
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
