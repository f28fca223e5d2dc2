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


class SHAPESMITH_PG_landmark_layout(bpy.types.PropertyGroup):
    """The last Place Landmarks result on this mesh (Run again replaces it)."""

    done: bpy.props.BoolProperty(default=False)
    collection: bpy.props.PointerProperty(type=bpy.types.Collection, description="The layout's empties")
    count: bpy.props.IntProperty(name="Landmarks")
    optimal: bpy.props.BoolProperty(name="Optimal")
    rounds: bpy.props.IntProperty(name="Rounds")
    uncovered: bpy.props.StringProperty(description="Shapes with no candidate vertex, comma separated")
    inert: bpy.props.StringProperty(description="Shapes that move nothing, comma separated")
    mean_error: bpy.props.FloatProperty(name="Mean Error", description="Mean reconstruction error / bbox diagonal")
    max_error: bpy.props.FloatProperty(name="Max Error", description="Largest reconstruction error / bbox diagonal")
    mesh_note: bpy.props.StringProperty(description="Loose parts and holes of the mesh, and how they were used")
    document: bpy.props.StringProperty(description="The full layout report as JSON (what Export writes)")


class SHAPESMITH_PG_layout_score(bpy.types.PropertyGroup):
    """The last Score Layout result on this mesh."""

    done: bpy.props.BoolProperty(default=False)
    group: bpy.props.StringProperty(name="Vertex Group")
    landmarks: bpy.props.IntProperty(name="Landmarks")
    mean_error: bpy.props.FloatProperty(name="Mean Error", description="Mean reconstruction error / bbox diagonal")
    max_error: bpy.props.FloatProperty(name="Max Error", description="Largest reconstruction error / bbox diagonal")


class SHAPESMITH_PG_object(bpy.types.PropertyGroup):
    analysis: bpy.props.PointerProperty(type=SHAPESMITH_PG_analysis)
    landmarks: bpy.props.PointerProperty(type=SHAPESMITH_PG_landmark_layout)
    landmark_score: bpy.props.PointerProperty(type=SHAPESMITH_PG_layout_score)
    pairs: bpy.props.CollectionProperty(type=SHAPESMITH_PG_shape_pair)
    active_pair: bpy.props.IntProperty(name="Active Pair")
    antagonists: bpy.props.CollectionProperty(type=SHAPESMITH_PG_shape_pair)


class SHAPESMITH_PG_landmark_settings(bpy.types.PropertyGroup):
    """Place Landmarks knobs (SPEC section 2); defaults are the paper's."""

    epsilon: bpy.props.FloatProperty(
        name="Epsilon", description="A vertex is a candidate for a shape when it moves at least this fraction of the "
        "shape's largest displacement (0.3 to 0.8 is useful)", default=0.5, min=0.01, max=1.0, soft_min=0.3, soft_max=0.8)
    alpha: bpy.props.FloatProperty(
        name="Alpha", description="Weight of visibility against displacement when choosing among candidates",
        default=0.5, min=0.0, max=1.0)
    gamma: bpy.props.FloatProperty(
        name="Gamma", description="Weight of quality against count (0 places the fewest landmarks, ignoring quality)",
        default=0.5, min=0.0, soft_max=2.0)
    rays: bpy.props.IntProperty(
        name="Rays", description="Visibility rays per vertex and pose (hemisphere mode)", default=64, min=1, soft_max=512)
    symmetric: bpy.props.BoolProperty(
        name="Symmetric", description="Mirror-symmetric layout across the Rig panel's symmetry axis", default=False)
    max_per_shape: bpy.props.IntProperty(
        name="Max per Shape", description="Rounds of the multi-cover: up to this many landmarks per shape",
        default=2, min=1, max=8)
    radius: bpy.props.FloatProperty(
        name="Radius", description="Later rounds keep this far from earlier landmarks (fraction of the bbox diagonal)",
        default=0.03, min=0.0, max=0.5, precision=3)
    camera_source: bpy.props.EnumProperty(
        name="Visibility",
        description="What a landmark must be visible from",
        items=(
            ("HEMISPHERE", "Hemisphere", "Any direction around the surface normal (ambient-occlusion style)"),
            ("SCENE", "Scene Cameras", "Every camera object in the scene"),
            ("COLLECTION", "Camera Collection", "The camera objects of a collection"),
        ),
        default="HEMISPHERE",
    )
    camera_collection: bpy.props.PointerProperty(type=bpy.types.Collection, name="Cameras")
    score_group: bpy.props.StringProperty(name="Vertex Group", description="A vertex group whose vertices you track")


class SHAPESMITH_PG_scene(bpy.types.PropertyGroup):
    landmarks: bpy.props.PointerProperty(type=SHAPESMITH_PG_landmark_settings)
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
    SHAPESMITH_PG_landmark_layout,
    SHAPESMITH_PG_layout_score,
    SHAPESMITH_PG_object,
    SHAPESMITH_PG_landmark_settings,
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
