"""A face in several objects: a head and its face parts (teeth, tongue, eyes, lashes, brows as
separate meshes whose shape keys match the head's by name). Every tool reads them as one mesh,
the head's vertices and triangles first and then each part's, in the head's object space (the
native core already treats a mesh's loose pieces as separate surfaces: the collision pass keeps
skin off the teeth, visibility rays stop at the eyes); results go back to each object as its
slice of the vertices, in its own object space. A head without parts reads exactly as
`read_rig` reads it."""

import os
from dataclasses import dataclass

import numpy as np

from .mesh_arrays import MeshDataError, Rig, check_mesh, fault_note, read_rig, read_triangles, rest_positions


@dataclass
class Face:
    """The objects of a face, head first; `offsets[i]` is where object i's vertices start in
    the concatenated arrays (one entry more than objects); `to_head[i]` is object i's 4x4
    matrix into the head's object space, None when it has the head's own transform."""

    objects: list
    offsets: np.ndarray
    to_head: list

    @property
    def head(self):
        return self.objects[0]

    @property
    def parts(self):
        return self.objects[1:]

    def vertices(self, index):
        """The slice of the concatenated vertices that belongs to object `index`."""
        return slice(int(self.offsets[index]), int(self.offsets[index + 1]))

    def locate(self, vertex):
        """(object index, the object's own vertex index) of a concatenated vertex."""
        index = int(np.searchsorted(self.offsets, vertex, side="right")) - 1
        return index, int(vertex - self.offsets[index])

    def to_local_deltas(self, index, deltas):
        """Displacements (..., n, 3) of object `index` from the head's space into its own."""
        matrix = self.to_head[index]
        if matrix is None:
            return deltas
        return (deltas @ np.linalg.inv(matrix[:3, :3]).T).astype(np.float32)


def stored_parts(head):
    """The face parts listed on the head (the Rig panel's Face Parts list), in list order."""
    return [item.object for item in head.shapesmith.face_parts if item.object is not None]


def landmark_parts(head):
    """The listed parts Place Landmarks may put landmarks on (the list's Landmarks ticks)."""
    return [item.object for item in head.shapesmith.face_parts if item.object is not None and item.landmarks]


def face_objects(head, parts=None, topology=True):
    """[head, *parts]: `parts` when given (batch's comma lists), else the list stored on the
    head. Each must be a usable mesh (`check_mesh`), and each its own: a part listed twice, the head listed as its own part, or two
    objects sharing one mesh are refused by name."""
    if head is None:
        raise MeshDataError("no object given: select a mesh")
    objects = [head, *(stored_parts(head) if parts is None else parts)]
    owner = {}
    for obj in objects:
        check_mesh(obj, need_shape_keys=False, topology=topology)
        if obj.data in owner:
            first = owner[obj.data]
            raise MeshDataError(
                f"'{obj.name}' is listed twice among the face parts of '{head.name}'"
                if first == obj
                else f"face part '{obj.name}' uses the mesh of '{first.name}': every part must be a mesh of its own"
            )
        owner[obj.data] = obj
    return objects


def _to_head(head, obj):
    if obj == head or obj.matrix_world == head.matrix_world:
        return None
    matrix = np.array(head.matrix_world.inverted_safe() @ obj.matrix_world, dtype=np.float64)
    if abs(np.linalg.det(matrix[:3, :3])) < 1e-12:
        raise MeshDataError(f"face part '{obj.name}' is scaled to zero: give it a non-zero scale")
    return matrix


def face_of(objects):
    """The `Face` (offsets and transforms into the head's space) of [head, *parts]."""
    counts = [len(obj.data.vertices) for obj in objects]
    offsets = np.concatenate(([0], np.cumsum(counts))).astype(np.int64)
    return Face(list(objects), offsets, [_to_head(objects[0], obj) for obj in objects])


def _into_head(matrix, points, linear_only=False):
    if matrix is None:
        return points
    moved = points @ matrix[:3, :3].T
    return (moved if linear_only else moved + matrix[:3, 3]).astype(np.float32)


def _part_rig(part, baked):
    """A part's rest positions and its shape keys by name (keys Bake wrote left out): its rig
    when it has keys of its own, else its rest shape alone (a part that never moves)."""
    keys = part.data.shape_keys
    own = [] if keys is None else [kb for kb in keys.key_blocks if kb != keys.reference_key and kb.name not in baked]
    if not own:
        note = fault_note(part)
        return rest_positions(part), {}, read_triangles(part), [note] if note else []
    rig = read_rig(part)
    return rig.neutral, dict(zip(rig.names, rig.deltas)), rig.triangles, rig.warnings


def read_face_rig(objects):
    """(rig, face) of [head, *parts]: one `Rig` over all their vertices in the head's object
    space, the keys being the union of their names (the head's in its order, then any a part
    alone has, such as tongueOut in the teeth), with a zero delta where an object lacks a
    key. Bake's keys of any object are left out of every object."""
    head = objects[0]
    face = face_of(objects)
    head_rig = read_rig(head)
    if len(objects) == 1:
        return head_rig, face
    baked = {b.name for obj in objects for b in obj.shapesmith.pack.baked}
    pieces = [(head_rig.neutral, dict(zip(head_rig.names, head_rig.deltas)), head_rig.triangles)]
    warnings = list(head_rig.warnings)
    for index, part in enumerate(objects[1:], start=1):
        neutral, deltas, triangles, part_warnings = _part_rig(part, baked)
        matrix = face.to_head[index]
        pieces.append((_into_head(matrix, neutral), {n: _into_head(matrix, d, True) for n, d in deltas.items()}, triangles))
        warnings += [f"'{part.name}': {w}" for w in part_warnings]
    names = list(dict.fromkeys(name for _, deltas, _ in pieces for name in deltas if name not in baked))
    row = {name: k for k, name in enumerate(names)}
    all_deltas = np.zeros((len(names), int(face.offsets[-1]), 3), dtype=np.float32)
    for index, (_, deltas, _) in enumerate(pieces):
        for name, delta in deltas.items():
            if name in row:
                all_deltas[row[name], face.vertices(index)] = delta
    neutral = np.ascontiguousarray(np.concatenate([p[0] for p in pieces]), dtype=np.float32)
    triangles = np.ascontiguousarray(
        np.concatenate([p[2] + face.offsets[i] for i, p in enumerate(pieces)]), dtype=np.int32
    )
    return Rig(neutral, all_deltas, triangles, names, warnings), face


def read_face_rest(face):
    """The rest shapes of the face's objects, concatenated in the head's space, float32 (N, 3)."""
    return np.ascontiguousarray(
        np.concatenate([_into_head(m, rest_positions(o)) for o, m in zip(face.objects, face.to_head)]), dtype=np.float32
    )


def read_face_triangles(face):
    """The triangles of the face's objects, in the concatenated vertex numbering."""
    return np.ascontiguousarray(
        np.concatenate([read_triangles(o) + face.offsets[i] for i, o in enumerate(face.objects)]), dtype=np.int32
    )


def _stem(name):
    """An object's name without Blender's duplicate suffix (`Teeth.001` -> `Teeth`)."""
    head, dot, tail = name.rpartition(".")
    return head if dot and tail.isdigit() and len(tail) == 3 else name


def _after_prefix(objects):
    """The parts' names after the prefix all the face's objects share (`Wolf3D_Teeth` ->
    `Teeth` in a face named `Wolf3D_*`)."""
    names = [_stem(o.name) for o in objects]
    prefix = os.path.commonprefix(names) if len(names) > 1 else ""
    return [name[len(prefix):] for name in names[1:]]


def pair_parts(template_objects, target_objects):
    """The target's objects in the order of the template's, so that object i of one is object
    i of the other: head with head; parts by their names after each face's common prefix when
    those names match one to one (`Wolf3D_Teeth` with `Avatar_Teeth`), else by list order.
    Lists of different lengths are refused, naming both."""
    if len(template_objects) != len(target_objects):
        raise MeshDataError(
            f"template '{template_objects[0].name}' has {len(template_objects) - 1} face part(s) "
            f"({', '.join(o.name for o in template_objects[1:]) or 'none'}) but target '{target_objects[0].name}' has "
            f"{len(target_objects) - 1} ({', '.join(o.name for o in target_objects[1:]) or 'none'}): list the same parts on both"
        )
    template_names, target_names = _after_prefix(template_objects), _after_prefix(target_objects)
    if len(set(template_names)) == len(template_names) and sorted(template_names) == sorted(target_names):
        by_name = dict(zip(target_names, target_objects[1:]))
        return [target_objects[0], *(by_name[name] for name in template_names)]
    return list(target_objects)


def face_summary(face):
    """The face's objects and their vertex counts, for reports: [{object, vertices}, ...]."""
    return [
        {"object": obj.name, "vertices": int(face.offsets[i + 1] - face.offsets[i])} for i, obj in enumerate(face.objects)
    ]


def store_parts(head, parts):
    """Replaces the Face Parts list stored on `head` by `parts` (batch's comma lists, so that
    a saved copy keeps the face together); the Landmarks ticks of parts still listed are kept."""
    ticked = set(landmark_parts(head))
    head.shapesmith.face_parts.clear()
    for part in parts:
        item = head.shapesmith.face_parts.add()
        item.object, item.landmarks = part, part in ticked
    head.shapesmith.active_face_part = max(len(parts) - 1, 0)
