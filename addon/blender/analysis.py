"""Analyze Rig as a plain function: the operator and `scripts/batch.py analyze` both call it."""

import time

from .. import native
from .face_parts import face_objects, face_summary, read_face_rig
from .names import pairing_name
from .settings import AnalyzeSettings


def analyze_object(obj, settings=None, parts=None, name_map=None):
    """Reads the rig (with its face parts: `parts`, else the list stored on `obj`), runs the
    native analysis with `settings` (a `settings.AnalyzeSettings`; None: the defaults),
    returns its report (a dict) with the face's objects, the shape-key
    warnings and timings added. Writes nothing. Pairing by name sees every name in one
    spelling (`names.pairing_name`, `name_map` the user's table), so `eyeBlink_L`,
    `L_eyeBlink`, `EyesClosedL` and `eyeBlink.L.001` find their partners as `eyeBlinkLeft` does;
    the report gives the rig's own names."""
    started = time.perf_counter()
    rig, face = read_face_rig(face_objects(obj, parts))
    read = time.perf_counter()
    settings = settings or AnalyzeSettings()
    spelled = [pairing_name(name, name_map) for name in rig.names]
    # A spelling two keys share (eyeBlink_L beside eyeBlinkLeft) keeps the keys' own names.
    spelled = [s if spelled.count(s) == 1 and s not in rig.names[:k] + rig.names[k + 1:] else name
               for k, (s, name) in enumerate(zip(spelled, rig.names))]
    own = dict(zip(spelled, rig.names))
    try:
        report = native.module().analyze_rig(rig.neutral, rig.deltas, rig.triangles, spelled, settings.as_native())
    except ValueError as error:
        # The native message names a key by its pairing spelling; the user knows it by its own.
        raise type(error)(_own_names_in(str(error), own)) from None
    _rename(report, own)
    report["warnings"] = rig.warnings
    report["objects"] = face_summary(face)
    report["seconds"] = {"read": read - started, "native": time.perf_counter() - read}
    return report


def _own_names_in(message, names):
    """`message` with each quoted spelled shape name (`'jawopen'`) given as the rig's own."""
    for spelled, name in names.items():
        message = message.replace(f"'{spelled}'", f"'{name}'")
    return message


def _rename(report, names):
    """The native report's shape names back to the rig's own (`names`: spelled -> own)."""
    for key in ("inert", "self_symmetric"):
        report[key] = [names[n] for n in report[key]]
    for key in ("symmetric_pairs", "antagonists"):
        for pair in report[key]:
            pair["first"], pair["second"] = names[pair["first"]], names[pair["second"]]
    report["name_conflicts"] = [[names[a], names[b]] for a, b in report["name_conflicts"]]


def store_analysis(obj, report, keep_edited=True):
    """Keeps the summary and the pairs on the object, where the user reviews and edits them
    (replacing any earlier analysis). With `keep_edited`, the pairs the user added or edited
    stay, and found pairs with a shape of theirs are left out."""
    props = obj.shapesmith
    summary = props.analysis
    summary.done = True
    summary.vertices = report["vertices"]
    summary.triangles = report["triangles"]
    summary.shapes = report["shapes"]
    summary.unmatched_vertices = len(report["unmatched_vertices"])
    summary.degenerate_triangles = len(report["degenerate_triangles"])
    summary.seam_vertices = report["seam_vertices"]
    summary.seam_groups = report["seam_groups"]
    summary.inert = ", ".join(report["inert"])
    summary.self_symmetric = ", ".join(report["self_symmetric"])
    edited = [(p.first, p.second) for p in props.pairs if p.source == "USER"] if keep_edited else []
    taken = {name for pair in edited for name in pair}
    props.pairs.clear()
    for first, second in edited:
        item = props.pairs.add()
        item.first, item.second = first, second
        item.source = "USER"
    for pair in report["symmetric_pairs"]:
        if pair["first"] in taken or pair["second"] in taken:
            continue
        item = props.pairs.add()
        item.first, item.second = pair["first"], pair["second"]
        item.source = pair["source"].upper()
        item.mirror_error = pair["mirror_error"]
    props.active_pair = 0
    props.antagonists.clear()
    for pair in report["antagonists"]:
        item = props.antagonists.add()
        item.first, item.second = pair["first"], pair["second"]
        item.source = "GEOMETRY"


def seam_note(report):
    """What the weld did, in one line: split vertices are one surface point for every tool."""
    if not report["seam_vertices"]:
        return "seams: none (no vertices split along UV seams)"
    return (
        f"seams: {report['seam_vertices']} vertices split along UV seams welded into "
        f"{report['seam_groups']} points for the computation (the mesh keeps its vertices)"
    )


def summary_lines(report):
    """A short human-readable summary (for the batch log and the demo)."""
    objects = report.get("objects") or []
    lines = [
        f"{report['vertices']} vertices, {report['triangles']} triangles, {report['shapes']} shape keys",
        *([f"face parts: {', '.join(o['object'] for o in objects[1:])}"] if len(objects) > 1 else []),
        f"inert shapes: {', '.join(report['inert']) or 'none'}",
        f"unmatched mirror vertices: {len(report['unmatched_vertices'])}",
        f"degenerate triangles: {len(report['degenerate_triangles'])}",
        seam_note(report),
        f"symmetric pairs ({len(report['symmetric_pairs'])}): "
        + ", ".join(f"{p['first']}/{p['second']}" for p in report["symmetric_pairs"]),
        "antagonists: " + (", ".join(f"{p['first']}/{p['second']}" for p in report["antagonists"]) or "none"),
    ]
    return lines + [f"warning: {w}" for w in report["warnings"]]
