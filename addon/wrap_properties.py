"""Wrap data stored on the character object (`Object.shapesmith_wrap`): its point pairs with
the template, and the last fit's summary. Kept apart from `properties.py` so the Wrap tool
registers and evolves on its own."""

import bpy


def _refresh_markers(owner, context):
    """Markers follow the pairs: rebuilt when shown, hidden or edited by hand (`id_data` is
    the character that stores them; with markers off this only finds none to remove)."""
    from .blender.wrap import refresh_markers

    refresh_markers(owner.id_data, context.scene.shapesmith.transfer.source)


class SHAPESMITH_PG_point_pair(bpy.types.PropertyGroup):
    """One pair: a point on the template and the same feature on the character, each in its
    object's local space (the vertex index too when the point is a vertex, else -1)."""

    # `name` (built in) labels the pair: "nose tip", "mouth corner L".
    template_vertex: bpy.props.IntProperty(name="Template Vertex", default=-1, min=-1)
    character_vertex: bpy.props.IntProperty(name="Character Vertex", default=-1, min=-1)
    template_co: bpy.props.FloatVectorProperty(name="On Template", size=3, subtype="XYZ", update=_refresh_markers)
    character_co: bpy.props.FloatVectorProperty(name="On Character", size=3, subtype="XYZ", update=_refresh_markers)


class SHAPESMITH_PG_wrap(bpy.types.PropertyGroup):
    pairs: bpy.props.CollectionProperty(type=SHAPESMITH_PG_point_pair)
    active_pair: bpy.props.IntProperty(name="Active Pair", default=0)
    show_markers: bpy.props.BoolProperty(
        name="Show Markers",
        description="Show each pair as two labelled empties, one on the template and one on the character",
        default=False,
        update=_refresh_markers,
    )
    region: bpy.props.StringProperty(
        name="Head Region",
        description="Generate ARKit Keys writes keys on this vertex group only (empty: the whole mesh, or on a full "
        "body the head, found above the neck)",
    )
    # The last Align or Wrap on this character.
    done: bpy.props.BoolProperty(default=False)
    stage: bpy.props.StringProperty(description="ALIGN or WRAP")
    template: bpy.props.StringProperty(description="The template that was wrapped")
    alignment: bpy.props.StringProperty(description="pairs or principal axes")
    mean_distance: bpy.props.FloatProperty(description="Mean distance to the character / bbox diagonal")
    max_distance: bpy.props.FloatProperty(description="Largest distance to the character / bbox diagonal")
    max_pair_residual: bpy.props.FloatProperty(description="Largest pair residual / bbox diagonal")
    symmetric: bpy.props.BoolProperty(description="Whether the fit and the carry were made mirror-symmetric")
    symmetry_note: bpy.props.StringProperty(description="Why the wrap is not symmetric (empty when it is)")
    worst_mirror_miss: bpy.props.FloatProperty(
        default=-1.0, description="Largest mirror miss of a carried Left/Right pair at its worst vertex / its largest motion (-1: not measured)"
    )
    worst_mirror_pair: bpy.props.StringProperty(description="The pair with the largest mirror miss")
    pieces: bpy.props.StringProperty(description="How many template pieces were fitted onto the character's, openings landed")
    matches: bpy.props.StringProperty(description="Per template piece and opening, what it landed on (one per line)")
    wrapped: bpy.props.PointerProperty(type=bpy.types.Object, description="The wrapped template object")
    written: bpy.props.IntProperty(description="Shape keys written by the last Transfer onto Character")
    looks: bpy.props.StringProperty(
        description="Where riggers look first, per key of the last Transfer onto Character: eyes closing, the mouth, "
        "smooth lines and keys (one per line, '+' fine, '!' look at it)"
    )
    seconds: bpy.props.FloatProperty()


_register_classes, _unregister_classes = bpy.utils.register_classes_factory((SHAPESMITH_PG_point_pair, SHAPESMITH_PG_wrap))


def register():
    _register_classes()
    bpy.types.Object.shapesmith_wrap = bpy.props.PointerProperty(type=SHAPESMITH_PG_wrap)


def unregister():
    del bpy.types.Object.shapesmith_wrap
    _unregister_classes()
