"""Shapesmith data stored in the .blend: per-object results (so they survive save/reload and
undo restores them) and per-scene tool settings."""

import bpy

from .blender.settings import AnalyzeSettings, ContactSettings, LandmarkSettings, PackSettings, TransferSettings

# The defaults of every tool option below: the core's, through the add-on's dataclasses.
_PACK = PackSettings()
_LANDMARKS = LandmarkSettings()
_TRANSFER = TransferSettings()
_ANALYZE = AnalyzeSettings()


def _edited_by_hand(pair, _context):
    pair.source = "USER"  # Analyze Rig keeps the pairs the rigger set


class SHAPESMITH_PG_shape_pair(bpy.types.PropertyGroup):
    first: bpy.props.StringProperty(name="First", description="Shape key name", update=_edited_by_hand)
    second: bpy.props.StringProperty(name="Second", description="Shape key name", update=_edited_by_hand)
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
    seam_vertices: bpy.props.IntProperty(description="Vertices split along UV seams or hard edges, welded for the computation")
    seam_groups: bpy.props.IntProperty(description="Welded points the seam vertices make")
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
    predicted_error: bpy.props.FloatProperty(
        name="Predicted Error", description="Predicted RMS reconstruction error / bbox diagonal (the design model)")
    added: bpy.props.IntProperty(name="Added", description="Landmarks added after the cover for reconstruction")
    design_stop: bpy.props.StringProperty(description="Why the added landmarks stopped (count, target, pool_exhausted)")
    document: bpy.props.StringProperty(description="The full layout report as JSON (what Export writes)")


class SHAPESMITH_PG_layout_score(bpy.types.PropertyGroup):
    """The last Score Layout result on this mesh."""

    done: bpy.props.BoolProperty(default=False)
    group: bpy.props.StringProperty(name="Vertex Group")
    landmarks: bpy.props.IntProperty(name="Landmarks")
    mean_error: bpy.props.FloatProperty(name="Mean Error", description="Mean reconstruction error / bbox diagonal")
    max_error: bpy.props.FloatProperty(name="Max Error", description="Largest reconstruction error / bbox diagonal")
    predicted_error: bpy.props.FloatProperty(
        name="Predicted Error", description="Predicted RMS reconstruction error / bbox diagonal (the design model)")


# --- Pack Expressions: settings, refinements and the last result (read by Transfer) ---


def _is_other_mesh(settings, obj):
    """Target candidates: meshes other than the rig that owns the settings."""
    return obj.type == "MESH" and obj != settings.id_data


class SHAPESMITH_PG_shape_name(bpy.types.PropertyGroup):
    name: bpy.props.StringProperty(name="Shape", description="Shape key name")


class SHAPESMITH_PG_packed_shape(bpy.types.PropertyGroup):
    """One shape key of the packed rig, in the rig's order: column k of the J x K weights."""

    name: bpy.props.StringProperty(name="Shape")
    importance: bpy.props.FloatProperty(name="Importance", description="Eq. (4) in the first iteration; 0 when inert")
    expression: bpy.props.IntProperty(
        name="Expression", description="Index of the expression that poses this shape (-1: none)", default=-1
    )


class SHAPESMITH_PG_expression(bpy.types.PropertyGroup):
    """One reference expression: its member shapes are posed at 1 together."""

    name: bpy.props.StringProperty(name="Label")
    members: bpy.props.CollectionProperty(type=SHAPESMITH_PG_shape_name)
    importance: bpy.props.FloatProperty(name="Importance")
    vertices: bpy.props.IntProperty(name="Vertices", description="Vertices the expression moves strongly")
    optimal: bpy.props.BoolProperty(name="Optimal", description="Proven the most important expression left")
    status: bpy.props.StringProperty(name="Solver Status")


class SHAPESMITH_PG_conflict(bpy.types.PropertyGroup):
    """Two shapes the packing kept apart, and why (overlap, antagonist, collision, occlusion, user)."""

    first: bpy.props.StringProperty(name="First")
    second: bpy.props.StringProperty(name="Second")
    reasons: bpy.props.StringProperty(name="Reasons", description="Space-separated reasons")


class SHAPESMITH_PG_pack_result(bpy.types.PropertyGroup):
    done: bpy.props.BoolProperty(default=False)
    conflicts: bpy.props.CollectionProperty(type=SHAPESMITH_PG_conflict)
    expressions: bpy.props.CollectionProperty(type=SHAPESMITH_PG_expression)
    shapes: bpy.props.CollectionProperty(type=SHAPESMITH_PG_packed_shape)
    inert: bpy.props.CollectionProperty(type=SHAPESMITH_PG_shape_name)
    excluded: bpy.props.CollectionProperty(type=SHAPESMITH_PG_shape_name)
    unplaced: bpy.props.CollectionProperty(type=SHAPESMITH_PG_shape_name)
    pairs: bpy.props.CollectionProperty(type=SHAPESMITH_PG_shape_pair)
    antagonists: bpy.props.CollectionProperty(type=SHAPESMITH_PG_shape_pair)
    fewest: bpy.props.IntProperty(name="Fewest Possible", description="0: not asked for")
    fewest_optimal: bpy.props.BoolProperty()
    params_json: bpy.props.StringProperty(description="The parameters of the native call, as JSON")
    regions_json: bpy.props.StringProperty(
        description="Each placed shape's strongly moving vertices, as JSON (the reference sheet tints them)")


class SHAPESMITH_PG_pack(bpy.types.PropertyGroup):
    mu: bpy.props.FloatProperty(
        name="Moving Region",
        description="A vertex belongs to a shape's moving region when it moves at least this fraction of the "
        "shape's largest motion; two shapes whose regions share a vertex go in different expressions (the "
        "paper's mu; 0.25 to 0.4)",
        default=_PACK.mu,
        min=0.01,
        max=1.0,
    )
    a: bpy.props.FloatProperty(
        name="Strong Motion First",
        description="How much a shape's strength of motion decides its importance; the rest goes to how much it "
        "distorts the Target head (the paper's a)",
        default=_PACK.a,
        min=0.0,
        max=1.0,
    )
    beta: bpy.props.FloatProperty(
        name="Unlike Shapes First",
        description="Importance bonus for shapes unlike those already placed (0: off; the paper's beta)",
        default=_PACK.beta,
        min=0.0,
        soft_max=2.0,
    )
    target: bpy.props.PointerProperty(
        name="Target",
        type=bpy.types.Object,
        poll=_is_other_mesh,
        description="Optional new head of the same topology: shapes that distort it most are packed first",
    )
    limit_expressions: bpy.props.BoolProperty(
        name="At Most",
        description="Stop after this many expressions (the paper's J max)",
        default=_PACK.max_expressions is not None,
    )
    max_expressions: bpy.props.IntProperty(name="Expressions", description="Most expressions to pack", default=10, min=1)
    symmetric: bpy.props.BoolProperty(
        name="Symmetric Pairs Together",
        description="Pose left/right partners in the same expression",
        default=_PACK.symmetric,
    )
    antagonist_cosine: bpy.props.FloatProperty(
        name="Opposites",
        description="Two shapes that move the face in opposite directions (the cosine of their motions below "
        "this: jawLeft and jawRight) are never posed together",
        default=_PACK.antagonist_cosine,
        min=-1.0,
        max=0.0,
    )
    fewest: bpy.props.BoolProperty(
        name="Fewest Possible",
        description="Also prove the fewest expressions the conflicts allow (shown beside the count)",
        default=_PACK.fewest,
    )
    collision_conflicts: bpy.props.BoolProperty(
        name="Collisions",
        description="Never pose together two shapes that pass through each other when mixed (tongue out through "
        "closed lips)",
        default=_PACK.collision_conflicts,
    )
    collision_tolerance: bpy.props.FloatProperty(
        name="Collision Tolerance",
        description="Intersection curve between separate pieces (tongue and lips, eyeball and lids) a mix may "
        "add beyond its shapes alone, as a fraction of the head's bounding-box diagonal",
        default=_PACK.collision_tolerance,
        min=1e-6,
        soft_max=0.5,
        precision=3,
    )
    occlusion_conflicts: bpy.props.BoolProperty(
        name="Occlusions",
        description="Never pose a shape with one that hides its motion from the front camera (an eye turning "
        "under a closed lid)",
        default=_PACK.occlusion_conflicts,
    )
    occlusion_keep: bpy.props.FloatProperty(
        name="Keep Visible",
        description="Share of a shape's visible moving vertices that must stay in sight of the front camera when "
        "posed with another",
        default=_PACK.occlusion_keep,
        min=0.01,
        max=1.0,
    )
    front_camera: bpy.props.PointerProperty(
        name="Front Camera",
        type=bpy.types.Object,
        poll=lambda settings, obj: obj.type == "CAMERA",
        description="Camera whose view is the face's front for occlusions and the reference sheet (its up is "
        "the face's up); empty: the front is found from the rig",
    )
    explain: bpy.props.BoolProperty(
        name="Explain in Shot List",
        description="Add to the CSV shot list every pair of shapes kept apart and why",
        default=False,
    )
    pin_together: bpy.props.CollectionProperty(type=SHAPESMITH_PG_shape_pair)
    active_pin: bpy.props.IntProperty()
    keep_apart: bpy.props.CollectionProperty(type=SHAPESMITH_PG_shape_pair)
    active_apart: bpy.props.IntProperty()
    exclude: bpy.props.CollectionProperty(type=SHAPESMITH_PG_shape_name)
    active_exclude: bpy.props.IntProperty()
    result: bpy.props.PointerProperty(type=SHAPESMITH_PG_pack_result)
    active_expression: bpy.props.IntProperty(name="Expression")
    baked: bpy.props.CollectionProperty(
        type=SHAPESMITH_PG_shape_name, description="Shape keys written by Bake: never packed themselves"
    )


# --- Transfer Shape Keys: scene settings and the last transfer's report on the target ---


def _has_shape_keys(settings, obj):
    """Transfer sources: meshes with shape keys beyond the Basis."""
    keys = obj.data.shape_keys if obj.type == "MESH" else None
    return keys is not None and len(keys.key_blocks) > 1


class SHAPESMITH_PG_key_choice(bpy.types.PropertyGroup):
    """A template key in the Transfer panel's list, ticked to be transferred."""

    chosen: bpy.props.BoolProperty(name="Transfer", default=True, description="Transfer this key")


class SHAPESMITH_PG_name_row(bpy.types.PropertyGroup):
    """One row of the user's name table: a name in their rig's convention and the name it
    stands for (ARKit's or the template's)."""

    theirs: bpy.props.StringProperty(name="Name", description="A shape key or capture column name as your rig spells it")
    standard: bpy.props.StringProperty(name="Means", description="The name it stands for, e.g. ARKit's eyeBlinkLeft")


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
        default=_TRANSFER.transfer.virtual_edges is not None,
    )
    tau_d: bpy.props.FloatProperty(
        name="Distance",
        description="Vertex pairs closer than this fraction of the head's size (bounding-box diagonal) may get a "
        "virtual edge (the paper's tau_d)",
        default=_TRANSFER.transfer.virtual_edges.tau_d,
        min=0.0001,
        max=0.2,
        precision=4,
    )
    tau_r: bpy.props.FloatProperty(
        name="Detour",
        description="A close pair becomes a virtual edge when its path along the surface is this many "
        "times longer than the straight distance: across a lip or lid gap, not along the skin (the paper's tau_r)",
        default=_TRANSFER.transfer.virtual_edges.tau_r,
        min=1.0,
        soft_max=20.0,
    )
    edge_weight: bpy.props.FloatProperty(
        name="Weight", description="Weight of each virtual edge against the shape-following energy",
        default=_TRANSFER.transfer.edge_weight, min=0.0, soft_max=100.0
    )
    contact: bpy.props.BoolProperty(
        name="Keep Surfaces Apart",
        description="After each shape is solved, keep lips, lids and skin from passing through each other or through teeth, "
        "eyes and lashes where the template's shape does not (shapes that add no crossing come out unchanged)",
        default=_TRANSFER.transfer.contact is not None,
    )
    contact_distance: bpy.props.FloatProperty(
        name="Contact Distance",
        description="How close two surfaces may come before they push each other apart, as a fraction of the local edge "
        "length (d_hat of Incremental Potential Contact); smaller lets pressed lips meet more tightly",
        default=ContactSettings().distance,
        min=0.01,
        max=2.0,
        precision=3,
    )
    overwrite: bpy.props.BoolProperty(
        name="Overwrite Existing Keys",
        description="Replace the target's shape keys that have a template key's name (otherwise they are skipped)",
        default=False,
    )
    keep_sculpted: bpy.props.BoolProperty(
        name="Keep Sculpted Changes",
        description="When overwriting, add back what you sculpted on a key since the last transfer wrote it "
        "(the last transferred version is kept on the mesh)",
        default=False,
    )
    only_ticked: bpy.props.BoolProperty(
        name="Only Ticked Keys",
        description="Transfer only the keys ticked in the list (List Template Keys fills it); the target's other keys stay",
        default=False,
    )
    key_choice: bpy.props.CollectionProperty(type=SHAPESMITH_PG_key_choice)
    active_key_choice: bpy.props.IntProperty()
    copy_drivers: bpy.props.BoolProperty(
        name="Copy Drivers",
        description="Recreate the drivers on the template's key values, re-targeted from the template to the target",
        default=False,
    )
    driver_map: bpy.props.PointerProperty(
        name="Driver Map",
        type=bpy.types.Text,
        description="A text of lines 'template object = target object' for drivers reading objects that Copy Drivers "
        "cannot pair by itself (the template's armature and objects named after the template it pairs by itself)",
    )
    compare_plain: bpy.props.BoolProperty(
        name="Compare Without Virtual Edges",
        description="Also measure the penetration of plain transfer (one more solve)",
        default=_TRANSFER.compare_plain,
    )
    training: bpy.props.PointerProperty(
        name="Training",
        type=bpy.types.Collection,
        description="Meshes of the target's topology posing expressions: named REF_01... after the template's "
        "packed expressions, or after a shape key",
    )
    beta_reg: bpy.props.FloatProperty(
        name="Regularisation",
        description="How strongly personalised shapes stay close to the transferred ones where the training "
        "expressions are noisy (their noise is estimated from the vertices they do not move); exact scans are "
        "followed wherever a shape moves (the paper's beta)",
        default=_TRANSFER.personalise.beta_reg,
        min=0.01,
        soft_max=10.0,
    )
    refine_weights: bpy.props.BoolProperty(
        name="Refine Weights",
        description="Refit the weights of each training expression's shapes within [0, 1] against the transferred "
        "shapes first (for scans not posed at full strength); shapes not in the expression stay out",
        default=_TRANSFER.personalise.refine_weights,
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
        name="Worse", description="Adds more intersection to the target's neutral than the template's shape allows"
    )
    added: bpy.props.FloatProperty(
        name="Added Beyond Template",
        subtype="DISTANCE",
        description="Intersection curve the shape adds to the target's neutral beyond what the template's shape allows",
    )
    allowed: bpy.props.FloatProperty(
        name="Allowed",
        subtype="DISTANCE",
        description="Intersection curve the shape may add to the target's neutral: per part (inside one piece, "
        "between pieces) what the template's shape adds to its neutral, or as much as the template's shape "
        "crosses, whichever is more",
    )
    before_length: bpy.props.FloatProperty(
        name="Curve Length Before Keeping Surfaces Apart", subtype="DISTANCE"
    )
    contact_iterations: bpy.props.IntProperty(name="Contact Solve Iterations")
    where: bpy.props.StringProperty(
        name="Where",
        description="Where most of the extra intersection lies: inside one piece (lips, lids) or between pieces "
        "(skin through a separate eyeball, lashes or teeth)",
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
    contact: bpy.props.BoolProperty(name="Keep Surfaces Apart")
    contact_distance: bpy.props.FloatProperty(name="Contact Distance")
    worse_before_contact: bpy.props.IntProperty(
        name="Worse Before Keeping Surfaces Apart",
        description="Shapes adding more intersection than on the template before the pass (-1: not measured, as for keys "
        "carried onto a character of other topology, where the pass ran on the wrapped template)",
    )
    carried: bpy.props.BoolProperty(
        name="Carried", description="The keys were carried onto this mesh from a wrapped template (Wrap), not transferred onto it"
    )
    contact_resolved: bpy.props.IntProperty(name="Shapes Kept Apart")
    template_neutral_length: bpy.props.FloatProperty(name="Template Neutral Curve Length", subtype="DISTANCE")
    shapes: bpy.props.CollectionProperty(type=SHAPESMITH_PG_transfer_shape)


def _is_mesh(item, obj):
    return obj.type == "MESH"


class SHAPESMITH_PG_face_part(bpy.types.PropertyGroup):
    """One face part of a head: a separate mesh (teeth, tongue, eyes, lashes, brows) whose
    shape keys match the head's by name; every tool reads it together with the head."""

    object: bpy.props.PointerProperty(name="Part", type=bpy.types.Object, poll=_is_mesh)
    landmarks: bpy.props.BoolProperty(
        name="Landmarks",
        description="Place Landmarks may put landmarks on this part (the head always may; parts are only traced "
        "for visibility otherwise)",
        default=False,
    )


class SHAPESMITH_PG_object(bpy.types.PropertyGroup):
    analysis: bpy.props.PointerProperty(type=SHAPESMITH_PG_analysis)
    landmarks: bpy.props.PointerProperty(type=SHAPESMITH_PG_landmark_layout)
    landmark_score: bpy.props.PointerProperty(type=SHAPESMITH_PG_layout_score)
    pairs: bpy.props.CollectionProperty(type=SHAPESMITH_PG_shape_pair)
    active_pair: bpy.props.IntProperty(name="Active Pair")
    antagonists: bpy.props.CollectionProperty(type=SHAPESMITH_PG_shape_pair)
    pack: bpy.props.PointerProperty(type=SHAPESMITH_PG_pack)
    transfer: bpy.props.PointerProperty(type=SHAPESMITH_PG_transfer_result)
    face_parts: bpy.props.CollectionProperty(
        type=SHAPESMITH_PG_face_part, description="Separate meshes every tool reads together with this head"
    )
    active_face_part: bpy.props.IntProperty(name="Active Face Part")


class SHAPESMITH_PG_landmark_settings(bpy.types.PropertyGroup):
    """Place Landmarks knobs (method, section 2); defaults are the paper's."""

    epsilon: bpy.props.FloatProperty(
        name="Strong Motion", description="A vertex can track a shape when it moves at least this fraction of the "
        "shape's largest motion (the paper's epsilon; 0.3 to 0.8 is useful)", default=_LANDMARKS.epsilon, min=0.01, max=1.0, soft_min=0.3, soft_max=0.8)
    alpha: bpy.props.FloatProperty(
        name="Visible over Moving", description="Among equally good vertices, how much being visible counts against "
        "moving strongly (the paper's alpha)",
        default=_LANDMARKS.alpha, min=0.0, max=1.0)
    gamma: bpy.props.FloatProperty(
        name="Quality", description="How much the landmarks' quality counts against their number (0 places the fewest, "
        "ignoring quality; the paper's gamma)",
        default=_LANDMARKS.gamma, min=0.0, soft_max=2.0)
    rays: bpy.props.IntProperty(
        name="Rays", description="Visibility rays per vertex and pose (hemisphere mode)", default=_LANDMARKS.rays, min=1, soft_max=512)
    symmetric: bpy.props.BoolProperty(
        name="Symmetric", description="Mirror-symmetric layout across the Rig panel's symmetry axis",
        default=_LANDMARKS.symmetric)
    max_per_shape: bpy.props.IntProperty(
        name="Landmarks per Shape", description="Up to this many landmarks track each shape (rounds of the multi-cover)",
        default=_LANDMARKS.max_per_shape, min=1, max=8)
    radius: bpy.props.FloatProperty(
        name="Spacing", description="Landmarks of later rounds keep this far from earlier ones (fraction of the head's "
        "size, its bounding-box diagonal)",
        default=_LANDMARKS.radius, min=0.0, max=0.5, precision=3)
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
    # No hard limits on the two targets: a typed-in bad value is refused with a clear message
    # and the previous layout kept, rather than silently clamped.
    design: bpy.props.EnumProperty(
        name="Add for Reconstruction",
        description="After the cover, add the landmarks that most lower the predicted reconstruction error under "
        "tracker noise (the cover still gives every shape its own landmark)",
        items=(
            ("NONE", "Cover Only", "The cover (and its multi-cover rounds) alone"),
            ("COUNT", "Up to Count", "Add landmarks until the layout has this many"),
            ("TARGET", "Up to Error", "Add landmarks until the predicted error is this low"),
        ),
        default="NONE",
    )
    landmarks: bpy.props.IntProperty(
        name="Landmarks", description="Landmarks in all, cover included (mirror pairs count two)",
        default=34, soft_min=1, soft_max=200)
    target_error: bpy.props.FloatProperty(
        name="Target Error", description="Predicted RMS reconstruction error to reach, as a fraction of the bbox diagonal",
        default=0.001, soft_min=1e-5, soft_max=0.01, precision=5, step=0.01)
    score_group: bpy.props.StringProperty(name="Vertex Group", description="A vertex group whose vertices you track")


class SHAPESMITH_PG_scene(bpy.types.PropertyGroup):
    landmarks: bpy.props.PointerProperty(type=SHAPESMITH_PG_landmark_settings)
    symmetry_axis: bpy.props.EnumProperty(
        name="Symmetry Axis",
        description="Local axis across whose zero plane the face is mirrored",
        items=(("0", "X", ""), ("1", "Y", ""), ("2", "Z", "")),
        default=str(_ANALYZE.axis),
    )
    pair_by_name: bpy.props.BoolProperty(
        name="Pair by Name",
        description="Pair shapes by Left/Right, _L/_R, .L/.R names where geometry finds no mirror partner",
        default=_ANALYZE.symmetry.use_names,
    )
    transfer: bpy.props.PointerProperty(type=SHAPESMITH_PG_transfer_settings)
    name_map: bpy.props.CollectionProperty(type=SHAPESMITH_PG_name_row)
    active_name_row: bpy.props.IntProperty()


_CLASSES = (
    SHAPESMITH_PG_shape_pair,
    SHAPESMITH_PG_analysis,
    SHAPESMITH_PG_landmark_layout,
    SHAPESMITH_PG_layout_score,
    SHAPESMITH_PG_shape_name,
    SHAPESMITH_PG_packed_shape,
    SHAPESMITH_PG_expression,
    SHAPESMITH_PG_conflict,
    SHAPESMITH_PG_pack_result,
    SHAPESMITH_PG_pack,
    SHAPESMITH_PG_key_choice,
    SHAPESMITH_PG_name_row,
    SHAPESMITH_PG_transfer_settings,
    SHAPESMITH_PG_transfer_shape,
    SHAPESMITH_PG_transfer_result,
    SHAPESMITH_PG_face_part,
    SHAPESMITH_PG_object,
    SHAPESMITH_PG_landmark_settings,
    SHAPESMITH_PG_scene,
)


_register_classes, _unregister_classes = bpy.utils.register_classes_factory(_CLASSES)


def register():
    _register_classes()
    bpy.types.Object.shapesmith = bpy.props.PointerProperty(type=SHAPESMITH_PG_object)
    bpy.types.Scene.shapesmith = bpy.props.PointerProperty(type=SHAPESMITH_PG_scene)


def unregister():
    del bpy.types.Scene.shapesmith
    del bpy.types.Object.shapesmith
    _unregister_classes()
