"""Personalisation benchmark on the warp ground truth (method, section 4), run with the bpy Python:

    python scripts/bench_personalise.py [-- --json OUT.json] [--heads bundled,4x]

The target is W(V0) for a known smooth map W (non-uniform scale (1.0, 1.25, 0.85) and a bend),
so the true shapes are W(V0 + D_k) - W(V0) and a training expression posing weights w is
W(V0 + sum_k w_k D_k). Mean vertex error on each shape's active vertices (moving at least 0.3
of its largest displacement), relative to the bounding-box diagonal, for: the naive additive
copy, plain deformation transfer, with virtual edges, personalised with the J packed
expressions (`shapesmith_native.pack_expressions` on the warped target), with J random single
shapes (the control; mean over 5 seeds), with the first 5 packed expressions only (J_max = 5,
the shapes in no expression stay transferred); each personalised row also with scan noise
(Gaussian, 0.1% of the diagonal per coordinate, on the training expressions); and with slightly
wrong weights (each member posed at a weight drawn in [0.75, 1], the fit told 1), without and
with weight refinement. On the bundled head and on its 4x subdivision (every edge cut once;
shape keys subdivided with it).
"""

import argparse
import os
import sys
import time

import bpy
import numpy as np

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
import batch  # noqa: E402
from bench_transfer import batch_cache, subdivided  # noqa: E402

SCALE = np.array([1.0, 1.25, 0.85])
BEND = 0.03  # the bend moves the face's sides back by this fraction of the diagonal
ACTIVE = 0.3  # the method's (section 1) mu: a vertex is active in a shape moving >= 0.3 of its maximum
CONTROL_SEEDS = 5
FEW = 5  # J_max of the few-examples row
NOISE = 1e-3  # scan noise: standard deviation per coordinate, fraction of the diagonal
POSE_LOW = 0.75  # slightly wrong weights: members posed at a weight in [POSE_LOW, 1]


def warp(points, centre, half_width, diagonal):
    """W: scale about the centre, then bend the sides back (y grows with x^2)."""
    p = (points - centre) * SCALE + centre
    p[..., 1] += BEND * diagonal * ((points[..., 0] - centre[0]) / half_width) ** 2
    return p.astype(np.float32)


def mean_active_error(predicted, truth, diagonal):
    """Mean over shapes of the mean error on the shape's active vertices, / diagonal."""
    errors = []
    for k in range(len(truth)):
        size = np.linalg.norm(truth[k], axis=1)
        if size.max() == 0:
            continue
        active = size >= ACTIVE * size.max()
        errors.append(np.linalg.norm(predicted[k] - truth[k], axis=1)[active].mean() / diagonal)
    return float(np.mean(errors))


def packed_expressions(nat, rig, target_neutral, max_expressions=None):
    report = nat.pack_expressions(
        rig.neutral, rig.deltas, rig.triangles, rig.names, {"max_expressions": max_expressions}, target_neutral=target_neutral
    )
    return [e["shapes"] for e in report["expressions"]]


class WarpGroundTruth:
    """The warped target of one rig, its true shapes, and the training expressions it poses."""

    def __init__(self, nat, rig, personalise_options):
        self.nat, self.rig = nat, rig
        self.personalise_options = personalise_options
        self.points = rig.neutral.astype(np.float64)
        low, high = self.points.min(0), self.points.max(0)
        self.source_diagonal = float(np.linalg.norm(high - low))
        self.centre, self.half_width = (low + high) / 2, (high[0] - low[0]) / 2
        self.target = self.warp(self.points)
        self.truth = np.stack([self.warp(self.points + d) - self.target for d in rig.deltas])
        self.diagonal = float(np.linalg.norm(self.target.max(0) - self.target.min(0)))
        self.index = {name: k for k, name in enumerate(rig.names)}

    def warp(self, p):
        return warp(p, self.centre, self.half_width, self.source_diagonal)

    def error(self, deltas):
        return mean_active_error(deltas, self.truth, self.diagonal)

    def transfer(self, examples=None, weights=None, **options):
        """(error, native report) of one transfer; `examples` J x N x 3, `weights` J x K."""
        arguments = {}
        if examples is not None:
            arguments = dict(examples=np.ascontiguousarray(examples, dtype=np.float32), example_weights=weights.tolist())
            options.update(self.personalise_options)
        # `virtual_edges` on or off; the other options are the personalisation's settings.
        settings = {
            "transfer": {} if options.pop("virtual_edges", True) else {"virtual_edges": None},
            "personalise": options,
            "measure_penetration": False,
        }
        deltas, report = self.nat.transfer_shapes(
            self.rig.neutral, self.rig.deltas, self.target, self.rig.triangles, self.rig.names, settings, **arguments,
        )
        return self.error(deltas), report

    def weights_of(self, expressions):
        weights = np.zeros((len(expressions), len(self.rig.names)))
        for row, members in enumerate(expressions):
            weights[row, [self.index[m] for m in members]] = 1.0
        return weights

    def pose(self, weights):
        """The training expressions posing `weights` (J x K) on the warped target."""
        return np.stack([self.warp(self.points + np.tensordot(row, self.rig.deltas, 1)) for row in weights])

    def noisy(self, examples, seed):
        rng = np.random.default_rng(seed)
        return examples + rng.normal(0.0, NOISE * self.diagonal, examples.shape)


def personalised_rows(gt, label, weights, seeds=(0,), **options):
    """Mean error over `seeds` of personalising with the expressions posing `weights` (a
    function of the seed), without and with scan noise."""
    clean, noisy, seconds = [], [], []
    for seed in seeds:
        w = weights(seed)
        examples = gt.pose(w)
        started = time.perf_counter()
        error, _ = gt.transfer(examples, w, **options)
        seconds.append(time.perf_counter() - started)
        clean.append(error)
        noisy.append(gt.transfer(gt.noisy(examples, seed), w, **options)[0])
    return {
        label: float(np.mean(clean)),
        f"{label}, scan noise": float(np.mean(noisy)),
    }, float(np.mean(seconds))


def warp_benchmark(nat, rig, **personalise_options):
    """The table for one rig; `personalise_options` go to every personalised transfer."""
    gt = WarpGroundTruth(nat, rig, personalise_options)
    rows = {"additive copy": gt.error(rig.deltas)}
    rows["plain transfer"], _ = gt.transfer(virtual_edges=False)
    rows["virtual edges"], _ = gt.transfer(virtual_edges=True)
    expressions = packed_expressions(nat, rig, gt.target)
    j = len(expressions)
    result = {"diagonal": gt.diagonal, "vertices": len(rig.neutral), "shapes": len(rig.names), "expressions": expressions}
    packed = gt.weights_of(expressions)
    new, result["personalise_seconds"] = personalised_rows(gt, f"personalised, {j} packed expressions", lambda s: packed)
    rows.update(new)
    moving = [k for k in range(len(rig.names)) if np.abs(rig.deltas[k]).max() > 0]

    def singles(seed):
        chosen = np.random.default_rng(seed).choice(moving, size=min(j, len(moving)), replace=False)
        w = np.zeros((len(chosen), len(rig.names)))
        w[np.arange(len(chosen)), chosen] = 1.0
        return w

    new, _ = personalised_rows(gt, f"personalised, {j} random single shapes ({CONTROL_SEEDS} seeds)", singles, range(CONTROL_SEEDS))
    rows.update(new)
    few = gt.weights_of(packed_expressions(nat, rig, gt.target, max_expressions=FEW))
    new, _ = personalised_rows(gt, f"personalised, J_max = {FEW} packed expressions", lambda s: few)
    rows.update(new)
    posed = packed * np.random.default_rng(7).uniform(POSE_LOW, 1.0, packed.shape)
    examples = gt.pose(posed)
    rows[f"packed, posed at weights in [{POSE_LOW}, 1], told 1"], _ = gt.transfer(examples, packed)
    rows[f"packed, posed at weights in [{POSE_LOW}, 1], told 1, refined"], report = gt.transfer(
        examples, packed, refine_weights=True
    )
    refined = np.array(report["weights"])
    result["refined_weight_error"] = {
        "told": float(np.abs(packed - posed)[packed > 0].mean()),
        "refined": float(np.abs(refined - posed)[packed > 0].mean()),
    }
    result["mean_active_error"] = rows
    return result


def print_report(result):
    for head, warp_result in result.items():
        print(
            f"\n== {head}: {warp_result['vertices']} vertices, {warp_result['shapes']} shapes; warp ground truth "
            "(mean error on active vertices / bbox diagonal)"
        )
        for name, value in warp_result["mean_active_error"].items():
            print(f"  {name:60s} {value:.2e}")
        w = warp_result["refined_weight_error"]
        print(f"  mean weight error of the posed members: told {w['told']:.3f}, refined {w['refined']:.3f}")
        print(f"  personalise with the packed expressions: {warp_result['personalise_seconds']:.2f} s")


def main():
    argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
    parser = argparse.ArgumentParser(prog="bench_personalise.py --")
    parser.add_argument("--json", default=os.path.join(batch_cache(), "bench", "personalise.json"))
    parser.add_argument("--heads", default="bundled,4x", help="comma separated: bundled, 4x")
    parser.add_argument("--beta-reg", type=float, help="the personalisation's beta (default: the library's)")
    parser.add_argument("--no-virtual-edges", action="store_true", help="personalise without virtual edges")
    args = parser.parse_args(argv)
    options = {} if args.beta_reg is None else {"beta_reg": args.beta_reg}
    if args.no_virtual_edges:
        options["virtual_edges"] = False
    heads = args.heads.split(",")
    shapesmith = batch.load_shapesmith()
    from importlib import import_module

    mesh_arrays = import_module(shapesmith.__name__ + ".blender.mesh_arrays")
    nat = shapesmith.native.module()
    bpy.ops.wm.open_mainfile(filepath=batch.cached_sample())
    template = bpy.data.objects["Template"]
    result = {}
    if "bundled" in heads:
        result["bundled"] = warp_benchmark(nat, mesh_arrays.read_rig(template), **options)
    if "4x" in heads:
        result["4x"] = warp_benchmark(nat, mesh_arrays.read_rig(subdivided(template, "TemplateDense")), **options)
    print_report(result)
    batch.write_json(args.json, result)
    print(f"\nwrote {args.json}")


if __name__ == "__main__":
    main()
