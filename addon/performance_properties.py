"""Performance settings and the last solve's summary, on the scene
(`Scene.shapesmith_performance`). Kept apart from `properties.py` so the tool registers on
its own."""

import bpy


def _is_camera(_settings, obj):
    return obj.type == "CAMERA"


class SHAPESMITH_PG_performance(bpy.types.PropertyGroup):
    source: bpy.props.EnumProperty(
        name="Source",
        items=(
            ("TRAJECTORIES", "Trajectories", "3D marker trajectories: a CSV (<landmark>_x, _y, _z columns) or TRC file"),
            ("CLIP", "Movie Clip", "2D tracks named after the landmarks, through the clip's tracking camera"),
            ("CAPTURE", "ARKit Capture", "ARKit weights: a Live Link Face CSV or a Face Cap TXT"),
        ),
        default="TRAJECTORIES",
    )
    trajectories: bpy.props.StringProperty(name="Trajectories", subtype="FILE_PATH")
    scale: bpy.props.FloatProperty(
        name="Scale", description="Scene units per unit of the trajectories file (TRC files' own units are applied first)",
        default=1.0, min=1e-6)
    clip: bpy.props.PointerProperty(name="Clip", type=bpy.types.MovieClip)
    camera: bpy.props.PointerProperty(
        name="Camera", type=bpy.types.Object, poll=_is_camera,
        description="The camera placed where the footage was filmed from (empty: the scene's camera)")
    landmarks: bpy.props.PointerProperty(
        name="Landmarks", type=bpy.types.Collection,
        description="The landmark empties the tracks follow (empty: the head's Place Landmarks layout)")
    smoothing: bpy.props.FloatProperty(
        name="Smoothing", default=1.0, min=0.0, soft_max=100.0,
        description="Penalty on a weight's change between frames, against residuals in units of the tracker's noise "
                    "(0: every frame on its own)")
    solve_scale: bpy.props.BoolProperty(
        name="Solve Scale", default=False, description="3D only: solve a uniform scale of the head per frame")
    target: bpy.props.PointerProperty(
        name="Pose Onto", type=bpy.types.Object,
        description="Key the head's pose on this object (e.g. an empty the head is parented to; empty: the head itself)")
    plot_shapes: bpy.props.StringProperty(
        name="Plot Shapes", description="Comma-separated shapes to plot (empty: the most active)")
    capture: bpy.props.StringProperty(name="Capture", subtype="FILE_PATH")
    mapping: bpy.props.PointerProperty(
        name="Mapping", type=bpy.types.Text,
        description='A text block with a JSON mapping {"column": "shape key"} for names that do not match')
    capture_fps: bpy.props.FloatProperty(
        name="Capture FPS", default=0.0, min=0.0,
        description="Live Link Face: the capture's frame rate (0: read from the timecodes)")
    capture_head: bpy.props.BoolProperty(name="Head Rotation", default=True, description="Key the captured head rotation")
    capture_head_invert: bpy.props.EnumProperty(
        name="Invert", options={"ENUM_FLAG"}, default=set(),
        items=(("YAW", "Yaw", "Turn the other way (Live Link Face: the phone held the other way round)"),
               ("PITCH", "Pitch", "Nod the other way (Live Link Face: the phone held the other way round)"),
               ("ROLL", "Roll", "Tilt the other way")),
        description="Captured head angles whose sign to change")
    # The last solve or import.
    done: bpy.props.BoolProperty(default=False)
    summary: bpy.props.StringProperty(description="The last result's summary, one line per row")
    document: bpy.props.StringProperty(description="The last solve's report as JSON (what Save Report writes)")


_register_classes, _unregister_classes = bpy.utils.register_classes_factory((SHAPESMITH_PG_performance,))


def register():
    _register_classes()
    bpy.types.Scene.shapesmith_performance = bpy.props.PointerProperty(type=SHAPESMITH_PG_performance)


def unregister():
    del bpy.types.Scene.shapesmith_performance
    _unregister_classes()
