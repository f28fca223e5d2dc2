import bpy, numpy as np
from test_wrap import IDENTITY, MOTIONS, apply, character, module, positions
from test_wrap_pairs import proposal_errors

def test_probe(sample, shapesmith):
    wrap = module(shapesmith, "blender.wrap")
    motion = MOTIONS["cm_y_up"]
    obj, entries = character(motion, "Character_probe")
    print("hand pairs", len(entries))
    proposal = wrap.propose_pairs(bpy.data.objects["Template"], obj)
    identity = positions(bpy.data.objects[IDENTITY])
    pts = positions(obj)
    diag = float(np.linalg.norm(pts.max(0) - pts.min(0)))
    errs = proposal_errors(proposal, lambda v: apply(motion, identity[[v]])[0], diag)
    print({k: round(100 * e, 2) for k, e in errs.items()})
