"""Bench heads resembling production rigs, made from the arrays that
scripts/save_contact_arrays.py writes (plain numpy, no Blender):

    python scripts/production_heads.py DIR [HEAD ...]

For each HEAD (default: every DIR/Target_* head) it writes, beside it:

- DIR/many_<HEAD>/: template and target with many pieces crossing the skin at rest, as the
  pieces of a production head do (eyeballs through the lids, lashes through the lids, gums and
  teeth through the inner lip). Every helper piece (the sample's eyes, teeth, tongue and
  lashes) is grown by `GROW` about its centre and moved `FORWARD` of its size to the front;
  each piece smaller than `SMALL` vertices (lashes) gets `COPIES` copies, each shifted a
  little further through the skin, moving with it in every shape. Same edit on both neutrals.
- DIR/many_self/: the many-piece template onto itself (from the first HEAD's template).
- DIR/lips_<HEAD>/: a template whose neutral's lips cross (the lower lip pushed `LIP_PUSH`
  into the upper one; its shapes keep that crossing, as their deltas are unchanged) onto the
  head's clean target.

Then `cargo run --release --example contact_counts -- DIR/<head> DIR/names.txt` on each.
"""

import glob
import os
import sys

import numpy as np

GROW = 1.04
FORWARD = 0.04
SMALL = 400
COPIES = 8
COPY_SHIFT = 0.0006  # metres, each copy further back (into the skin) than the one before
LIP_PUSH = 0.0025  # metres


def read_points(path):
    return np.fromfile(path, dtype="<f4").reshape(-1, 3).astype(np.float64)


def read_head(folder):
    return {
        "source": read_points(os.path.join(folder, "source.f32")),
        "target": read_points(os.path.join(folder, "target.f32")),
        "deltas": read_points(os.path.join(folder, "deltas.f32")),
        "triangles": np.fromfile(os.path.join(folder, "triangles.u32"), dtype="<u4").reshape(-1, 3).astype(np.int64),
    }


def write_head(head, folder):
    os.makedirs(folder, exist_ok=True)
    for key in ("source", "target", "deltas"):
        np.ascontiguousarray(head[key], dtype="<f4").tofile(os.path.join(folder, key + ".f32"))
    np.ascontiguousarray(head["triangles"], dtype="<u4").tofile(os.path.join(folder, "triangles.u32"))


def pieces(n, triangles):
    """The connected piece of each vertex (union-find over the triangles' edges)."""
    parent = np.arange(n)

    def root(v):
        while parent[v] != v:
            parent[v] = parent[parent[v]]
            v = parent[v]
        return v

    for a, b in np.concatenate([triangles[:, [0, 1]], triangles[:, [1, 2]]]):
        ra, rb = root(a), root(b)
        if ra != rb:
            parent[max(ra, rb)] = min(ra, rb)
    roots = np.array([root(v) for v in range(n)])
    return np.unique(roots, return_inverse=True)[1]


def many_pieces(head):
    """The head with its helper pieces grown, moved to the front and the small ones copied
    (module docs)."""
    n = len(head["source"])
    label = pieces(n, head["triangles"])
    skin = np.argmax(np.bincount(label))
    k = len(head["deltas"]) // n
    deltas = head["deltas"].reshape(k, n, 3).copy()
    source, target = head["source"].copy(), head["target"].copy()
    extra_points = {"source": [], "target": []}
    extra_deltas, extra_triangles = [], []
    added = n
    for piece in range(label.max() + 1):
        if piece == skin:
            continue
        members = np.flatnonzero(label == piece)
        for name, points in (("source", source), ("target", target)):
            centre = points[members].mean(0)
            size = np.linalg.norm(points[members].max(0) - points[members].min(0))
            # Grown about its centre and moved to the front (-Y): through the lids and lips.
            points[members] = centre + GROW * (points[members] - centre) + [0.0, -FORWARD * size, 0.0]
        deltas[:, members] *= GROW
        if len(members) >= SMALL:
            continue
        index = np.full(n, -1)
        index[members] = np.arange(len(members))
        faces = head["triangles"][np.all(np.isin(head["triangles"], members), axis=1)]
        for copy in range(1, COPIES + 1):
            for name, points in (("source", source), ("target", target)):
                extra_points[name].append(points[members] + [0.0, COPY_SHIFT * copy, -0.5 * COPY_SHIFT * copy])
            extra_deltas.append(deltas[:, members])
            extra_triangles.append(index[faces] + added)
            added += len(members)
    return {
        "source": np.concatenate([source, *extra_points["source"]]),
        "target": np.concatenate([target, *extra_points["target"]]),
        "deltas": np.concatenate([deltas, *extra_deltas], axis=1).reshape(-1, 3),
        "triangles": np.concatenate([head["triangles"], *extra_triangles]),
    }


def crossing_lips(head, names):
    """The template's neutral with its lower lip pushed up into the upper one: the skin
    vertices that jawOpen moves most (the lower lip and chin) and that lie within a few
    millimetres of skin it barely moves (the upper lip) are the contact; skin around it that
    jawOpen moves is pushed up by `LIP_PUSH`, fading with the distance to the contact."""
    n = len(head["source"])
    label = pieces(n, head["triangles"])
    skin = label == np.argmax(np.bincount(label))
    jaw = head["deltas"].reshape(-1, n, 3)[names.index("jawOpen")]
    moved = np.linalg.norm(jaw, axis=1)
    lower = skin & (moved > 0.5 * moved.max())
    upper = skin & (moved < 0.1 * moved.max())
    source = head["source"]
    upper_points = source[upper]
    near = np.array([np.min(np.linalg.norm(upper_points - p, axis=1)) for p in source[lower]])
    contact = source[lower][near < 0.004]
    if len(contact) == 0:
        raise SystemExit("no lower-lip vertex lies within 4 mm of the upper lip")
    distance = np.array([np.min(np.linalg.norm(contact - p, axis=1)) for p in source])
    push = np.where(skin & (moved > 0.2 * moved.max()), LIP_PUSH * np.exp(-((distance / 0.006) ** 2)), 0.0)
    pushed = source.copy()
    pushed[:, 2] += push
    return {**head, "source": pushed}


def main():
    if len(sys.argv) < 2:
        raise SystemExit("usage: production_heads.py DIR [HEAD ...]")
    out = sys.argv[1]
    heads = sys.argv[2:] or sorted(os.path.basename(p) for p in glob.glob(os.path.join(out, "Target_*")))
    with open(os.path.join(out, "names.txt")) as f:
        names = f.read().splitlines()
    for index, name in enumerate(heads):
        head = read_head(os.path.join(out, name))
        many = many_pieces(head)
        write_head(many, os.path.join(out, "many_" + name))
        if index == 0:
            write_head({**many, "target": many["source"]}, os.path.join(out, "many_self"))
        write_head(crossing_lips(head, names), os.path.join(out, "lips_" + name))
        print(f"{name}: many pieces {len(many['source'])} vertices, lips crossing")


if __name__ == "__main__":
    main()
