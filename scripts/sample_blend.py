"""The sample rig, built from the CC0 MakeHuman assets (`makehuman.py`) into a .blend:
`batch.py -- sample` writes it, and the tests, benches and render scripts share one cached
copy per Blender version (`cached_sample`)."""

import json
import os
import sys

import bpy

SCRIPTS = os.path.dirname(os.path.abspath(__file__))


def cached_sample_path():
    """Where the sample.blend for this Blender (major.minor) and this scripts/makehuman.py is
    cached: tests, benches and renders share it, keyed by the script's digest so that a
    changed sample never reuses an older file."""
    sys.path.insert(0, SCRIPTS)
    import makehuman

    return os.path.join(makehuman.cache_dir(), "sample-%d.%d-%s.blend" % (*bpy.app.version[:2], makehuman.sample_version()))


def cached_sample():
    """The cached sample.blend (`cached_sample_path`), built when missing. Building it resets
    Blender to factory settings, which disables add-ons: an enabled Shapesmith is enabled again
    so that a bench run on a fresh cache finds its properties."""
    import addon_utils

    path = cached_sample_path()
    if not os.path.isfile(path):
        enabled = [m.__name__ for m in addon_utils.modules(refresh=False)
                   if m.__name__.rsplit(".", 1)[-1] == "shapesmith" and addon_utils.check(m.__name__)[1]]
        build_sample(path)
        for name in enabled:
            addon_utils.enable(name, default_set=True)
    return path


def build_sample(output):
    """Writes `output`: Template (MakeHuman head + 52 ARKit face units), Target_* identity
    heads and Character_* heads of other topology. FileNotFoundError when the MakeHuman
    assets are missing."""
    sys.path.insert(0, SCRIPTS)
    import makehuman
    import numpy as np

    head = makehuman.build_head()
    bpy.ops.wm.read_factory_settings(use_empty=True)

    def mesh_object(name, positions, location_x):
        mesh = bpy.data.meshes.new(name)
        mesh.from_pydata(positions.tolist(), [], head["faces"].tolist())
        mesh.shade_smooth()
        obj = bpy.data.objects.new(name, mesh)
        obj.location.x = location_x
        bpy.context.scene.collection.objects.link(obj)
        return obj

    template = mesh_object("Template", head["neutral"], 0.0)
    template.shape_key_add(name="Basis", from_mix=False)
    for name, delta in zip(head["shape_names"], head["deltas"]):
        key = template.shape_key_add(name=name, from_mix=False)
        key.data.foreach_set("co", (head["neutral"] + delta).astype(np.float32).ravel())
        key.value = 0.0  # shape_key_add defaults to 1.0 in Blender 5.x
    for i, (name, positions) in enumerate(head["targets"].items()):
        mesh_object(name, positions, 0.25 * (i + 1))
    for i, (name, spec) in enumerate(makehuman.CHARACTERS.items()):
        add_character(name, spec, head, mesh_object("_identity", head["targets"][spec["identity"]], 0.0), 0.25 * (i + 4))
    os.makedirs(os.path.dirname(os.path.abspath(output)), exist_ok=True)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.abspath(output))
    print(f"wrote {output}: Template with {len(head['shape_names'])} shape keys, "
          f"{len(head['neutral'])} vertices; targets {', '.join(head['targets'])}; "
          f"characters {', '.join(makehuman.CHARACTERS)}")


def add_character(name, spec, head, identity, location_x):
    """A character of other topology from an identity head: collapse-decimated, in
    centimetres and Y-up axes (the object turned and scaled back to stand beside the others),
    with point pairs known by construction stored on it (template vertex -> the identity's
    same vertex in the character's space)."""
    import makehuman
    import numpy as np

    decimate = identity.modifiers.new("Decimate", "DECIMATE")
    decimate.ratio = spec["ratio"]
    evaluated = identity.evaluated_get(bpy.context.evaluated_depsgraph_get())
    mesh = bpy.data.meshes.new_from_object(evaluated)
    mesh.name = name
    identity_positions = head["targets"][spec["identity"]]
    bpy.data.objects.remove(identity)
    co = np.empty(len(mesh.vertices) * 3, dtype=np.float32)
    mesh.vertices.foreach_get("co", co)
    mesh.vertices.foreach_set("co", makehuman.character_frame(co.reshape(-1, 3), spec["scale"]).astype(np.float32).ravel())
    mesh.shade_smooth()
    obj = bpy.data.objects.new(name, mesh)
    bpy.context.scene.collection.objects.link(obj)
    obj.rotation_euler.x = np.pi / 2  # Y up in the mesh, Z up in the scene
    obj.scale = (1.0 / spec["scale"],) * 3
    obj.location.x = location_x
    vertices = makehuman.pair_vertices(head["neutral"], head["skin_vertices"])
    targets = makehuman.character_frame(identity_positions[vertices], spec["scale"])
    # A custom property in the `--pairs` JSON form, which the Wrap tool imports into the
    # character's point pairs (the extension need not be installed to build the sample).
    obj["shapesmith_wrap_pairs"] = json.dumps([[int(v), [float(x) for x in q]] for v, q in zip(vertices, targets)])
    return obj
