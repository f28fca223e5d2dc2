"""Stylised characters by code, with a known answer: the sample's template (the CC0 MakeHuman
head of scripts/makehuman.py, its 52 ARKit units) warped to cartoon proportions by one smooth
map of space (large eyes, a short nose, a wide mouth, a long muzzle), and its keys warped by
the same map (`W(p + d) - W(p)`: the same-topology truth, a lid that closes on the template
closes on the warp, since both lids land on one point of space). Copies of other topology
(collapse-decimated; subdivided then decimated), in other units and axes, are the characters
the wrap is judged on (scripts/bench_looks.py, blender_tests/test_wrap_looks.py).

Run with the bpy Python (Blender's own modifiers make the copies); the map itself is numpy.
"""

import bpy
import bmesh  # noqa: I001  (bmesh loads only after bpy)
import numpy as np

import makehuman

# The cartoon's proportions, about the template's own features (sizes in its eye radii).
EYE_SCALE = 1.6          # eyes (and the lids around them) this much larger
EYE_REACH = 2.2          # ... falling off over this many eyeball radii
NOSE_SCALE = 0.55        # the nose's protrusion kept
NOSE_REACH = 2.5
MOUTH_SCALE = 1.35       # the mouth this much wider
MOUTH_REACH = 3.0
MUZZLE = 2.0             # the mouth and chin pushed forward this many eyeball radii


def features(neutral, faces, keys):
    """The template's eyeball centres and radius, mouth centre and nose tip (Blender frame:
    Z up, the face towards -Y, X = 0 its midline). `keys`: name -> (N, 3) deltas."""
    labels = makehuman.vertex_pieces(len(neutral), faces)
    balls = []
    for piece in np.unique(labels):
        members = neutral[labels == piece]
        distance = np.linalg.norm(members - members.mean(0), axis=1)
        if len(members) >= 8 and distance.std() < 0.15 * distance.mean():
            balls.append((members.mean(0), distance.mean()))
    eyes = sorted(balls, key=lambda b: -b[1])[:2]
    weights = np.linalg.norm(keys["mouthPucker"], axis=1)
    mouth = (weights[:, None] * neutral).sum(0) / weights.sum()
    skin = np.flatnonzero(labels == np.bincount(labels).argmax())
    eye_height = np.mean([e[0][2] for e in eyes])
    band = skin[(np.abs(neutral[skin, 0]) < 0.005) & (neutral[skin, 2] > mouth[2]) & (neutral[skin, 2] < eye_height)]
    nose = neutral[band[np.argmin(neutral[band, 1])]]
    return {"eyes": [e[0] for e in eyes], "radius": float(np.mean([e[1] for e in eyes])), "mouth": mouth, "nose": nose}


def cartoon_map(feature):
    """The warp W: (M, 3) -> (M, 3), a sum of smooth bumps about the features (Gaussian
    falloff), each monotone along its own direction so that W stays one to one."""
    r = feature["radius"]
    front = np.array([0.0, -1.0, 0.0])
    across = np.array([1.0, 0.0, 0.0])

    def bump(p, centre, reach):
        return np.exp(-(np.linalg.norm(p - centre, axis=1) / (reach * r)) ** 2)[:, None]

    def warp(p):
        p = np.asarray(p, dtype=np.float64)
        out = p.copy()
        for eye in feature["eyes"]:
            out += (EYE_SCALE - 1.0) * (p - eye) * bump(p, eye, EYE_REACH)
        nose, mouth = feature["nose"], feature["mouth"]
        depth = (p - nose) @ front
        out += (NOSE_SCALE - 1.0) * np.maximum(depth + 2.0 * r, 0.0)[:, None] * front * bump(p, nose, NOSE_REACH)
        out += (MOUTH_SCALE - 1.0) * ((p - mouth) @ across)[:, None] * across * bump(p, mouth, MOUTH_REACH)
        # The muzzle: the lower face ahead of the ears pushed forward, most at the mouth.
        below = np.clip((nose[2] - p[:, 2]) / (6.0 * r) + 0.5, 0.0, 1.0)
        ahead = np.clip(((p - mouth) @ front) / (4.0 * r) + 1.0, 0.0, 1.0)
        side = np.exp(-(p[:, 0] / (4.0 * r)) ** 2)
        out += MUZZLE * r * (below * ahead * side)[:, None] * front
        return out

    return warp


def stylised_head(template):
    """The template warped (rest and keys), as a new object `Stylised` of the template's
    topology with its keys: the same-topology character and its truth."""
    rest = positions(template)
    names = [block.name for block in template.data.shape_keys.key_blocks[1:]]
    keys = {name: block_positions(template, name) - rest for name in names}
    faces = [tuple(p.vertices) for p in template.data.polygons]
    warp = cartoon_map(features(rest, faces, keys))
    warped = warp(rest)
    obj = template.copy()
    obj.data = template.data.copy()
    obj.name = obj.data.name = "Stylised"
    bpy.context.scene.collection.objects.link(obj)
    obj.data.vertices.foreach_set("co", warped.astype(np.float32).ravel())
    for name in names:
        obj.data.shape_keys.key_blocks[name].data.foreach_set("co", warp(rest + keys[name]).astype(np.float32).ravel())
    obj.data.shape_keys.key_blocks[0].data.foreach_set("co", warped.astype(np.float32).ravel())
    obj.data.update()
    return obj, names, np.stack([warp(rest + keys[n]) - warped for n in names])


# The stylised characters: other topology, units and axes. `frame(points)` takes the warped
# head's Blender-frame points (metres, Z up) to the character's own.
FRAMES = {
    "centimetres, Y up": lambda p: makehuman.character_frame(p, 100.0) + np.array([5.0, 160.0, -3.0]),
    "metres, facing +X": lambda p: np.stack([-p[:, 1], p[:, 0], p[:, 2]], axis=1) + np.array([0.0, 0.0, 1.5]),
    "millimetres, Z up": lambda p: 1000.0 * p,
}
COPIES = {
    "decimated to half": {"subdivide": False, "ratio": 0.5},
    "subdivided and decimated": {"subdivide": True, "ratio": 1.4},
}


def stylised_character(stylised, name, copy, frame):
    """`stylised`'s mesh (no keys) copied with `COPIES[copy]` (collapse decimation to `ratio`
    of its faces, after one subdivision when `subdivide`, `ratio` then of the original's
    vertices), its points taken through `FRAMES[frame]`."""
    recipe = COPIES[copy]
    mesh = bmesh.new()
    mesh.from_mesh(stylised.data)
    for layer in list(mesh.verts.layers.shape):
        mesh.verts.layers.shape.remove(layer)
    target = len(mesh.verts)
    if recipe["subdivide"]:
        bmesh.ops.subdivide_edges(mesh, edges=mesh.edges[:], cuts=1, use_grid_fill=True)
    data = bpy.data.meshes.new(name)
    mesh.to_mesh(data)
    mesh.free()
    obj = bpy.data.objects.new(name, data)
    bpy.context.scene.collection.objects.link(obj)
    ratio = recipe["ratio"] * target / len(data.vertices) if recipe["subdivide"] else recipe["ratio"]
    obj.modifiers.new("Decimate", "DECIMATE").ratio = min(ratio, 1.0)
    decimated = bpy.data.meshes.new_from_object(obj.evaluated_get(bpy.context.evaluated_depsgraph_get()))
    obj.modifiers.clear()
    obj.data = decimated
    obj.data.vertices.foreach_set("co", FRAMES[frame](positions(obj)).astype(np.float32).ravel())
    obj.data.update()
    return obj


def positions(obj):
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.vertices.foreach_get("co", co)
    return co.reshape(-1, 3).astype(np.float64)


def block_positions(obj, name):
    co = np.empty(len(obj.data.vertices) * 3, dtype=np.float32)
    obj.data.shape_keys.key_blocks[name].data.foreach_get("co", co)
    return co.reshape(-1, 3).astype(np.float64)
