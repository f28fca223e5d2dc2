"""Writes the arrays `native/examples/carry_counts.rs` reads, run with the bpy Python:

    python scripts/save_wrap_arrays.py -- DIR

DIR/10k/, DIR/25k/ (scripts/bench_wrap.py's characters and pairs) and DIR/young/ (the sample's
Character_YoungWoman, its stored pairs): each the wrapped template and the template's keys
transferred onto it, the character, the template's rest and own keys and the template's
curve per shape (what the chain hands `carry_shapes`), so that the carry and its collision
pass can be run and measured outside Blender:

    cargo run --release --example carry_counts -- DIR/25k
"""

import os
import sys
from importlib import import_module

import bpy
import numpy as np

SCRIPTS = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, SCRIPTS)
import batch  # noqa: E402
import bench_wrap  # noqa: E402
import makehuman  # noqa: E402

argv = sys.argv[sys.argv.index("--") + 1:] if "--" in sys.argv else []
if len(argv) != 1:
    raise SystemExit("usage: save_wrap_arrays.py -- DIR")
out = argv[0]
shapesmith = batch.load_shapesmith()
wrap = import_module(shapesmith.__name__ + ".blender.wrap")
mesh_arrays = import_module(shapesmith.__name__ + ".blender.mesh_arrays")
transfer = import_module(shapesmith.__name__ + ".blender.transfer")
face_parts = import_module(shapesmith.__name__ + ".blender.face_parts")
bpy.ops.wm.open_mainfile(filepath=batch.cached_sample())
template = bpy.data.objects["Template"]

def dump(name, character, template_points, character_points):
    d = os.path.join(out, name)
    os.makedirs(d, exist_ok=True)
    wrapped = wrap.wrap_object(template, character, template_points, character_points)
    wobj = wrap.show_wrapped(wrapped)
    onto = transfer.transfer_object(template, wobj, joined_target=True)
    cn, ct = wrap.read_surface(character, "character")
    wn, wt = transfer.rest_positions(wobj), mesh_arrays.read_triangles(wobj)
    tn, _ = wrap.read_surface(template, "template")
    rig, _ = face_parts.read_face_rig(face_parts.face_objects(template))
    row = {n: k for k, n in enumerate(rig.names)}
    curve = wrap.template_curve(onto.report)
    np.ascontiguousarray(wn, dtype=np.float32).tofile(f"{d}/wrapped.f32")
    np.ascontiguousarray(wt, dtype=np.uint32).tofile(f"{d}/wrapped.u32")
    np.ascontiguousarray(onto.deltas, dtype=np.float32).tofile(f"{d}/deltas.f32")
    np.ascontiguousarray(cn, dtype=np.float32).tofile(f"{d}/character.f32")
    np.ascontiguousarray(ct, dtype=np.uint32).tofile(f"{d}/character.u32")
    np.ascontiguousarray(tn, dtype=np.float32).tofile(f"{d}/template.f32")
    np.ascontiguousarray(rig.deltas[[row[n] for n in onto.names]], dtype=np.float32).tofile(f"{d}/template_deltas.f32")
    np.ascontiguousarray(curve["template_added"], dtype=np.float64).tofile(f"{d}/added.f64")
    np.ascontiguousarray(curve["template_crossing"], dtype=np.float64).tofile(f"{d}/crossing.f64")
    open(f"{d}/names.txt", "w").write("\n".join(onto.names) + "\n")
    print(f"{d}: {len(cn)} character vertices, {len(wn)} template vertices, {len(onto.names)} shapes", flush=True)
    wrap.remove_object(wobj)

identity = bpy.data.objects[bench_wrap.IDENTITY]
skin = makehuman.largest_piece(len(template.data.vertices), [tuple(p.vertices) for p in template.data.polygons])
pv = makehuman.pair_vertices(bench_wrap.positions(template), skin)
for label, n in bench_wrap.SIZES.items():
    character = bench_wrap.build_character(identity, f"Character_{label}", n)
    entries = [[int(v), [float(x) for x in q]] for v, q in zip(pv, bench_wrap.to_character(bench_wrap.positions(identity)[pv]))]
    tp, cp = wrap.pairs_from_list(entries, template, character)
    dump(label, character, tp, cp)
yw = bpy.data.objects["Character_YoungWoman"]
tp, cp = wrap.stored_pairs(yw, template)
dump("young", yw, tp, cp)
