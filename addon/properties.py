"""Shapesmith data stored in the .blend: per-object results (so they survive save/reload and
undo restores them) and per-scene tool settings."""

import bpy


class SHAPESMITH_PG_shape_pair(bpy.types.PropertyGroup):
    first: bpy.props.StringProperty(name="First", description="Shape key name")
    second: bpy.props.StringProperty(name="Second", description="Shape key name")
    source: bpy.props.EnumProperty(
        name="Source",
        items=(
            ("GEOMETRY", "Geometry", "Found by mirroring the shape's displacement field"),
            ("NAME", "Name", "Found by the Left/Right naming convention"),
            ("USER", "User", "Added or edited by hand"),
        ),
        default="USER",
    )
    mirror_error: bpy.props.FloatProperty(name="Mirror Error", description="||M(D_i) - D_j|| / max(||D_i||, ||D_j||)")


class SHAPESMITH_PG_analysis(bpy.types.PropertyGroup):
    done: bpy.props.BoolProperty(default=False)
    vertices: bpy.props.IntProperty()
    triangles: bpy.props.IntProperty()
    shapes: bpy.props.IntProperty()
    unmatched_vertices: bpy.props.IntProperty()
    degenerate_triangles: bpy.props.IntProperty()
    inert: bpy.props.StringProperty(description="Inert shape keys, comma separated")
    self_symmetric: bpy.props.StringProperty(description="Shapes that are their own mirror image")


class SHAPESMITH_PG_object(bpy.types.PropertyGroup):
    analysis: bpy.props.PointerProperty(type=SHAPESMITH_PG_analysis)
    pairs: bpy.props.CollectionProperty(type=SHAPESMITH_PG_shape_pair)
    active_pair: bpy.props.IntProperty(name="Active Pair")
    antagonists: bpy.props.CollectionProperty(type=SHAPESMITH_PG_shape_pair)


class SHAPESMITH_PG_scene(bpy.types.PropertyGroup):
    symmetry_axis: bpy.props.EnumProperty(
        name="Symmetry Axis",
        description="Local axis across whose zero plane the face is mirrored",
        items=(("0", "X", ""), ("1", "Y", ""), ("2", "Z", "")),
        default="0",
    )
    pair_by_name: bpy.props.BoolProperty(
        name="Pair by Name",
        description="Pair shapes by Left/Right, _L/_R, .L/.R names where geometry finds no mirror partner",
        default=True,
    )


_CLASSES = (
    SHAPESMITH_PG_shape_pair,
    SHAPESMITH_PG_analysis,
    SHAPESMITH_PG_object,
    SHAPESMITH_PG_scene,
)


def register():
    for cls in _CLASSES:
        bpy.utils.register_class(cls)
    bpy.types.Object.shapesmith = bpy.props.PointerProperty(type=SHAPESMITH_PG_object)
    bpy.types.Scene.shapesmith = bpy.props.PointerProperty(type=SHAPESMITH_PG_scene)


def unregister():
    del bpy.types.Scene.shapesmith
    del bpy.types.Object.shapesmith
    for cls in reversed(_CLASSES):
        bpy.utils.unregister_class(cls)
