"""Place Landmarks and Score Layout as plain functions: the operators and
`scripts/batch.py landmarks` both call them (method, section 2).

`place_landmarks` reads the rig and returns a JSON-ready layout document without writing
anything; `build_layout` then replaces the object's previous layout (empties parented to their
vertices in a `Landmarks` collection, and a `Landmarks` vertex group) in one go.
"""

import csv
import json
import time

import bpy
import numpy as np
from mathutils import Matrix

from .. import native
from .face_parts import face_objects, face_summary, landmark_parts, read_face_rig, stored_parts
from .mesh_arrays import MeshDataError, read_positions, read_triangles
from .packing import stored_weights
from .settings import LandmarkSettings, ScoreSettings

COLLECTION_NAME = "Landmarks"
VERTEX_GROUP_NAME = "Landmarks"
# An empty's display size as a fraction of the head's bounding-box diagonal: visible, yet
# small enough that neighbouring landmarks (a few % of the diagonal apart) do not merge.
EMPTY_SIZE = 0.012


def camera_positions(obj, source, scene=None, collection=None):
    """World positions of the chosen camera objects in `obj`'s local space (the rig's frame),
    float32 (C, 3); None for hemisphere visibility. Raises MeshDataError when none is found."""
    if source == "HEMISPHERE":
        return None
    if source == "SCENE":
        cameras, where = [o for o in scene.objects if o.type == "CAMERA"], f"scene '{scene.name}'"
    elif collection is None:
        raise MeshDataError("choose a camera collection, or use hemisphere visibility")
    else:
        cameras, where = [o for o in collection.all_objects if o.type == "CAMERA"], f"collection '{collection.name}'"
    if not cameras:
        raise MeshDataError(f"no camera objects in {where}: add cameras or use hemisphere visibility")
    to_local = obj.matrix_world.inverted_safe()
    return np.array([(to_local @ cam.matrix_world.translation)[:] for cam in cameras], dtype=np.float32)


def mesh_parts(obj, triangles=None, neutral=None):
    """Loose parts and open boundary edges of the welded surface (vertices split along UV
    seams are one point: a seam is neither a cut nor a hole). Both are normal on a head
    (eyeballs, teeth and lashes are loose parts; eye sockets and the neck are open), so they
    are reported, not refused. `triangles`, `neutral`: the mesh's, when already read
    (`read_rig`; a face in several objects counts all of them)."""
    if triangles is None:
        triangles = read_triangles(obj)
    if neutral is None:
        neutral = read_positions(obj)
    labels, count, boundary = native.module().mesh_parts(len(neutral), triangles, neutral)
    return {"loose_parts": count, "boundary_edges": boundary, "part_of_vertex": labels}


def mesh_note(parts, landmark_vertices):
    """One sentence explaining the mesh's loose parts and holes and how the layout used them."""
    if parts["loose_parts"] == 1 and parts["boundary_edges"] == 0:
        return "closed mesh in one piece"
    used = len({int(parts["part_of_vertex"][v]) for v in landmark_vertices})
    return (
        f"{parts['loose_parts']} loose part(s) and {parts['boundary_edges']} open boundary edge(s): "
        f"every part hides what is behind it and may carry landmarks (here {used} part(s) do); "
        "holes let visibility rays through"
    )


def packed_poses(obj, names):
    """The expressions of a Pack Expressions result stored on `obj` as extra test poses
    (J, K) float32 in the rig's shape order (the method: the packed expressions are test poses), or
    None when the object carries no pack result."""
    if not obj.shapesmith.pack.result.done:
        return None
    packed_names, weights = stored_weights(obj)
    column = {name: k for k, name in enumerate(names)}
    poses = np.zeros((len(weights), len(names)), dtype=np.float32)
    for j, name in enumerate(packed_names):
        if name in column:
            poses[:, column[name]] = weights[:, j]
    return poses


def score_vertices(obj, rig, vertices, progress=None):
    """Noisy reconstruction score of a layout (method, section 2), with the packed expressions
    among the test poses when the object has them; `progress(fraction)` as the poses are
    scored (seconds on a 100k-vertex head with 150 keys)."""
    poses = packed_poses(obj, rig.names)
    settings = ScoreSettings()
    score = native.module().score_layout(
        rig.neutral, rig.deltas, rig.triangles, rig.names, vertices, settings.as_native(), extra_poses=poses,
        progress=progress,
    )
    return dict(score, noise=settings.noise, packed_expressions=0 if poses is None else len(poses))


def check_design(settings):
    """Refuses a bad count or target before any work (the core checks them again)."""
    landmarks, target_error = settings.landmarks, settings.target_error
    if landmarks is not None and landmarks < 1:
        raise MeshDataError(f"the landmark count must be at least 1, got {landmarks}")
    if target_error is not None and not (target_error > 0 and np.isfinite(target_error)):
        raise MeshDataError(f"the target error must be a positive fraction of the diagonal, got {target_error}")


def allowed_vertices(face, allowed_parts):
    """The vertices of `face` a landmark may go on, as a list of bools: the head's and those
    of the parts in `allowed_parts`; None when the face is the head alone."""
    if len(face.objects) == 1:
        return None
    allowed = np.zeros(int(face.offsets[-1]), dtype=bool)
    for index, obj in enumerate(face.objects):
        if index == 0 or obj in allowed_parts:
            allowed[face.vertices(index)] = True
    return allowed.tolist()


def place_landmarks(
    obj, settings=None, *, cameras=None, progress=None, compare_group=None, parts=None, allowed_parts=None
):
    """Runs the layout on `obj` with `settings` (a `settings.LandmarkSettings`; None: the
    defaults) and scores it; returns the layout document (a dict). Writes nothing.
    `cameras`: (C, 3) camera positions in the mesh's space (None: the hemisphere);
    `progress(fraction)`, when
    given, is called as the work advances and stops it by returning False (CancelledError).
    With `compare_group`, that vertex group's layout (e.g. a conventional one the user
    tracks) is scored too, as `comparison`. `parts`: the head's face parts (default: its
    stored list), all traced for visibility and moving in every pose; landmarks go on the
    head and on `allowed_parts` only (default: the parts ticked in the list). Raises
    MeshDataError or the core's errors on bad input."""
    settings = settings or LandmarkSettings()
    check_design(settings)
    started = time.perf_counter()
    rig, face = read_face_rig(face_objects(obj, parts))
    if allowed_parts is None:
        allowed_parts = landmark_parts(obj)
    stray = [o.name for o in allowed_parts if o not in face.parts]
    if stray:
        raise MeshDataError(f"landmarks may go only on face parts of '{obj.name}', and {', '.join(stray)} is not one")
    parts_of_mesh = mesh_parts(obj, rig.triangles, rig.neutral)
    comparison = score_group(obj, compare_group) if compare_group else None
    read = time.perf_counter()
    # One bar over both native calls: the layout 90% of it, its score (a tenth of the time on
    # a 77k-vertex head with 150 keys) the rest.
    placing, scoring = (None, None) if progress is None else (lambda f: progress(0.9 * f), lambda f: progress(0.9 + 0.1 * f))
    layout = native.module().place_landmarks(
        rig.neutral, rig.deltas, rig.triangles, rig.names, settings.as_native(), cameras=cameras, progress=placing,
        allowed=allowed_vertices(face, allowed_parts),
    )
    vertices = [landmark["vertex"] for landmark in layout["landmarks"]]
    if not vertices:
        raise MeshDataError(
            f"'{obj.name}': no shape key moves any vertex (inert: {', '.join(layout['inert'])}); "
            "there is nothing to place landmarks for"
        )
    placed = time.perf_counter()
    layout["reconstruction"] = score_vertices(obj, rig, vertices, progress=scoring)
    scored = time.perf_counter()
    if comparison is not None:
        layout["comparison"] = comparison
    layout["mesh"] = {
        "vertices": len(rig.neutral),
        "loose_parts": parts_of_mesh["loose_parts"],
        "boundary_edges": parts_of_mesh["boundary_edges"],
        "note": mesh_note(parts_of_mesh, vertices),
    }
    for landmark in layout["landmarks"]:
        index, own = face.locate(landmark["vertex"])
        landmark["object"], landmark["object_vertex"] = face.objects[index].name, own
    layout["object"] = obj.name
    layout["objects"] = face_summary(face)
    layout["warnings"] = rig.warnings
    layout["seconds"] = {
        "io": read - started,
        "visibility": layout["seconds"]["visibility"],
        "solve": layout["seconds"]["solve"],
        "design": layout["seconds"]["design"],
        "score": scored - placed,
    }
    return layout


def remove_layout(obj):
    """Deletes the object's previous layout: its empties, their collection, and the
    `Landmarks` vertex group."""
    collection = obj.shapesmith.landmarks.collection
    if collection is not None:
        for empty in list(collection.objects):
            bpy.data.objects.remove(empty, do_unlink=True)
        bpy.data.collections.remove(collection)
    for owner in [obj, *stored_parts(obj)]:
        group = owner.vertex_groups.get(VERTEX_GROUP_NAME)
        if group is not None:
            owner.vertex_groups.remove(group)
    obj.shapesmith.landmarks.done = False


def bbox_diagonal(obj):
    corners = np.array([corner[:] for corner in obj.bound_box])
    return float(np.linalg.norm(corners.max(axis=0) - corners.min(axis=0)))


def build_layout(obj, document, scene):
    """Replaces the object's layout with the document's: one empty per landmark, parented to
    its vertex (so it follows shape keys), named after the strongest shape it serves, with the
    covered shapes as the custom property `shapes`; a `Landmarks` collection in `scene`; a
    `Landmarks` vertex group. A landmark on a face part is parented to, and grouped on, that
    part (the document names it: `object`, `object_vertex`). Returns the collection."""
    remove_layout(obj)
    collection = bpy.data.collections.new(COLLECTION_NAME)
    scene.collection.children.link(collection)
    size = EMPTY_SIZE * bbox_diagonal(obj)
    on = {}
    for landmark in document["landmarks"]:
        vertex = landmark["vertex"]
        owner = bpy.data.objects.get(landmark.get("object", obj.name)) or obj
        own = landmark.get("object_vertex", vertex)
        on.setdefault(owner, []).append(own)
        empty = bpy.data.objects.new(f"LM_{landmark['strongest']}_{vertex}", None)
        empty.empty_display_type = "SPHERE"
        empty.empty_display_size = size
        empty.parent = owner
        empty.parent_type = "VERTEX"
        empty.parent_vertices = (own, own, own)
        # The vertex itself is the origin: no offset, whatever the parent's transform.
        empty.matrix_parent_inverse = Matrix.Identity(4)
        empty.location = (0.0, 0.0, 0.0)
        empty["shapes"] = list(landmark["shapes"])
        empty["vertex"] = vertex
        empty["visibility"] = landmark["visibility"]
        empty["round"] = landmark["round"]
        collection.objects.link(empty)
    for owner in [obj, *(o for o in on if o != obj)]:
        owner.vertex_groups.new(name=VERTEX_GROUP_NAME).add(on.get(owner, []), 1.0, "REPLACE")
    store_layout(obj, document, collection)
    return collection


def store_layout(obj, document, collection):
    result = obj.shapesmith.landmarks
    result.done = True
    result.collection = collection
    result.count = len(document["landmarks"])
    result.optimal = document["optimal"]
    result.rounds = document["rounds"]
    result.uncovered = ", ".join(document["uncovered"])
    result.inert = ", ".join(document["inert"])
    result.mean_error = document["reconstruction"]["mean"]
    result.max_error = document["reconstruction"]["max"]
    result.predicted_error = document["predicted_error"]
    result.added = sum(1 for landmark in document["landmarks"] if landmark.get("added") is not None)
    result.design_stop = document.get("design_stop") or ""
    result.mesh_note = document["mesh"]["note"]
    result.document = json.dumps(document)


def group_vertices(obj, name):
    """Indices of the vertices with a non-zero weight in vertex group `name`."""
    group = obj.vertex_groups.get(name)
    if group is None:
        names = ", ".join(g.name for g in obj.vertex_groups) or "none"
        raise MeshDataError(f"'{obj.name}' has no vertex group '{name}' (groups: {names})")
    index = group.index
    vertices = [v.index for v in obj.data.vertices if any(g.group == index and g.weight > 0 for g in v.groups)]
    if not vertices:
        raise MeshDataError(f"vertex group '{name}' is empty: assign the vertices you track to it")
    return vertices


def comparison_group(obj, name):
    """The vertex group to compare a new layout with: the panel's scored group when the
    object has it, never the layout's own `Landmarks` group (the run replaces it)."""
    if name and name != VERTEX_GROUP_NAME and obj.vertex_groups.get(name) is not None:
        return name
    return None


def score_group(obj, name, progress=None):
    """Reconstruction error of the layout a vertex group describes (same poses and noise as
    Place Landmarks' own score), relative to the bbox diagonal. Writes nothing."""
    vertices = group_vertices(obj, name)
    return dict(score_vertices(obj, read_face_rig(face_objects(obj))[0], vertices, progress=progress), group=name)


def store_score(obj, score):
    result = obj.shapesmith.landmark_score
    result.done = True
    result.group = score["group"]
    result.landmarks = score["landmarks"]
    result.mean_error = score["mean"]
    result.max_error = score["max"]
    result.predicted_error = score.get("predicted") or 0.0


def stored_document(obj):
    """The object's last layout document, or MeshDataError when it has none."""
    result = obj.shapesmith.landmarks
    if not result.done or not result.document:
        raise MeshDataError(f"'{obj.name}' has no landmark layout yet: run Place Landmarks first")
    return json.loads(result.document)


def write_json(path, document):
    with open(path, "w") as f:
        json.dump(document, f, indent=2)


CSV_COLUMNS = ("vertex", "x", "y", "z", "strongest", "shapes", "visibility", "round", "added")


def write_csv(path, document):
    """One row per landmark; `shapes` separated by spaces (shape key names have none in
    practice, and a second delimiter keeps the file one table)."""
    with open(path, "w", newline="") as f:
        writer = csv.writer(f)
        writer.writerow(CSV_COLUMNS)
        for landmark in document["landmarks"]:
            x, y, z = landmark["position"]
            writer.writerow(
                (landmark["vertex"], x, y, z, landmark["strongest"], " ".join(landmark["shapes"]),
                 landmark["visibility"], landmark["round"], "" if landmark.get("added") is None else landmark["added"])
            )


STOP_REASONS = {
    "count": "reached the requested count",
    "target": "reached the target error",
    "pool_exhausted": "no visible vertex outside the radius was left to add",
}


def curve_lines(document, every=4):
    """The predicted-error curve as text rows (cover, every `every`-th step, the chosen
    layout, the end), for the panel's report and the batch log."""
    curve = document.get("curve") or []
    chosen = len(document["landmarks"])
    keep = [i for i, point in enumerate(curve)
            if i == 0 or i == len(curve) - 1 or i % every == 0 or point["landmarks"] == chosen]
    return [
        f"{curve[i]['landmarks']:>4} landmarks: predicted {curve[i]['predicted_error']:.2e}"
        + ("  (cover)" if i == 0 else "  <- chosen" if curve[i]["landmarks"] == chosen else "")
        for i in keep
    ]


def comparison_line(document):
    """The layout's error beside a tracked layout's, or None when there is none to compare."""
    other = document.get("comparison")
    if other is None:
        return None
    mean = document["reconstruction"]["mean"]
    change = mean / other["mean"] - 1.0
    return (
        f"{len(document['landmarks'])} landmarks: mean {mean:.2e} against '{other['group']}' "
        f"({other['landmarks']} vertices): mean {other['mean']:.2e} ({change:+.0%})"
    )


def summary_lines(document):
    """A short human-readable summary (for the batch log and the demo)."""
    rec = document["reconstruction"]
    seconds = document["seconds"]
    added = sum(1 for landmark in document["landmarks"] if landmark.get("added") is not None)
    lines = [
        f"{len(document['landmarks'])} landmarks in {document['rounds']} round(s), "
        f"{'proven optimal' if document['optimal'] else 'NOT proven optimal'}",
        f"uncovered shapes: {', '.join(document['uncovered']) or 'none'}; inert: {', '.join(document['inert']) or 'none'}",
        f"reconstruction error (noise {rec['noise']:.1%} of the diagonal, {rec['poses']} poses, "
        f"{rec['packed_expressions']} of them packed expressions): "
        f"mean {rec['mean']:.2e}, max {rec['max']:.2e} of the bbox diagonal; "
        f"predicted {document['predicted_error']:.2e} (RMS, design model)",
        f"mesh: {document['mesh']['note']}",
        f"seconds: I/O {seconds['io']:.2f}, visibility {seconds['visibility']:.2f} "
        f"({document['rays_per_second']:.3g} rays/s, {document['rays_cast']} rays), solve {seconds['solve']:.2f}, "
        f"design {seconds['design']:.2f}, score {seconds['score']:.2f}",
    ]
    if document.get("design_stop"):
        lines.append(f"added {added} landmark(s) for reconstruction after the cover: "
                     f"{STOP_REASONS[document['design_stop']]}")
        lines += ["  " + line for line in curve_lines(document)]
    if document.get("comparison"):
        lines.append(comparison_line(document))
    return lines + [f"warning: {w}" for w in document["warnings"]]
