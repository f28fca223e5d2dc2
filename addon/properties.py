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


# --- Transfer Shape Keys: scene settings and the last transfer's report on the target ---


def _has_shape_keys(settings, obj):
    """Transfer sources: meshes with shape keys beyond the Basis."""
    keys = obj.data.shape_keys if obj.type == "MESH" else None
    return keys is not None and len(keys.key_blocks) > 1


class SHAPESMITH_PG_transfer_settings(bpy.types.PropertyGroup):
    source: bpy.props.PointerProperty(
        name="Template",
        type=bpy.types.Object,
        poll=_has_shape_keys,
        description="Mesh whose shape keys are transferred onto the active object (same topology)",
    )
    virtual_edges: bpy.props.BoolProperty(
        name="Virtual Edges",
        description="Keep opposite lips, eyelids and nostril walls from passing through each other",
        default=True,
    )
    tau_d: bpy.props.FloatProperty(
        name="Distance (tau_d)",
        description="Vertex pairs closer than this fraction of the bounding-box diagonal are candidates",
        default=0.015,
        min=0.0001,
        max=0.2,
        precision=4,
    )
    tau_r: bpy.props.FloatProperty(
        name="Detour (tau_r)",
        description="A candidate pair becomes a virtual edge when its path along the surface is this many "
        "times longer than the straight distance",
        default=4.0,
        min=1.0,
        soft_max=20.0,
    )
    edge_weight: bpy.props.FloatProperty(
        name="Weight", description="Weight of each virtual edge against the shape-following energy", default=1.0, min=0.0, soft_max=100.0
    )
    overwrite: bpy.props.BoolProperty(
        name="Overwrite Existing Keys",
        description="Replace the target's shape keys that have a template key's name (otherwise they are skipped)",
        default=False,
    )
    copy_drivers: bpy.props.BoolProperty(
        name="Copy Drivers",
        description="Recreate the drivers on the template's key values, re-targeted from the template to the target",
        default=False,
    )
    compare_plain: bpy.props.BoolProperty(
        name="Compare Without Virtual Edges",
        description="Also measure the penetration of plain transfer (one more solve)",
        default=False,
    )
    training: bpy.props.PointerProperty(
        name="Training",
        type=bpy.types.Collection,
        description="Meshes of the target's topology posing expressions: named REF_01... after the template's "
        "packed expressions, or after a shape key",
    )
    beta_reg: bpy.props.FloatProperty(
        name="Regularisation",
        description="How strongly personalised shapes stay close to the transferred ones",
        default=0.1,
        min=0.0,
        soft_max=10.0,
    )
    refine_weights: bpy.props.BoolProperty(
        name="Refine Weights", description="Also refit each training expression's weights within [0, 1]", default=False
    )


class SHAPESMITH_PG_transfer_shape(bpy.types.PropertyGroup):
    """Intersection curve of one transferred shape beside the template's own for that shape
    (lips or lids passing through each other; the neutral's own intersection included)."""

    name: bpy.props.StringProperty(name="Shape")
    length: bpy.props.FloatProperty(name="Curve Length", subtype="DISTANCE")
    pairs: bpy.props.IntProperty(name="Pairs")
    template_length: bpy.props.FloatProperty(name="Template Curve Length", subtype="DISTANCE")
    template_pairs: bpy.props.IntProperty(name="Template Pairs")
    worse: bpy.props.BoolProperty(
        name="Worse", description="Adds more intersection to the target's neutral than to the template's"
    )


class SHAPESMITH_PG_transfer_result(bpy.types.PropertyGroup):
    done: bpy.props.BoolProperty(default=False)
    source: bpy.props.StringProperty(name="Template")
    written: bpy.props.IntProperty(name="Written")
    skipped: bpy.props.StringProperty(description="Keys kept because they existed, comma separated")
    virtual_edges: bpy.props.IntProperty(name="Virtual Edges")
    examples: bpy.props.IntProperty(name="Training Expressions")
    seconds: bpy.props.FloatProperty(name="Seconds")
    neutral_length: bpy.props.FloatProperty(name="Target Neutral Curve Length", subtype="DISTANCE")
    template_neutral_length: bpy.props.FloatProperty(name="Template Neutral Curve Length", subtype="DISTANCE")
    shapes: bpy.props.CollectionProperty(type=SHAPESMITH_PG_transfer_shape)


class SHAPESMITH_PG_object(bpy.types.PropertyGroup):
    analysis: bpy.props.PointerProperty(type=SHAPESMITH_PG_analysis)
    pairs: bpy.props.CollectionProperty(type=SHAPESMITH_PG_shape_pair)
    active_pair: bpy.props.IntProperty(name="Active Pair")
    antagonists: bpy.props.CollectionProperty(type=SHAPESMITH_PG_shape_pair)
    transfer: bpy.props.PointerProperty(type=SHAPESMITH_PG_transfer_result)


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
    transfer: bpy.props.PointerProperty(type=SHAPESMITH_PG_transfer_settings)


_CLASSES = (
    SHAPESMITH_PG_shape_pair,
    SHAPESMITH_PG_analysis,
    SHAPESMITH_PG_transfer_settings,
    SHAPESMITH_PG_transfer_shape,
    SHAPESMITH_PG_transfer_result,
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
