"""Add-on preferences: limits that apply to every tool."""

import bpy


class SHAPESMITH_AP_preferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    solver_time_limit: bpy.props.FloatProperty(
        name="Solver Time Limit",
        description="Seconds each 0/1 program of Pack Expressions and Place Landmarks may take (0: solve to "
        "proven optimality, however long); a result stopped by the limit is the best found, reported as not "
        "proven optimal",
        default=120.0,
        min=0.0,
        unit="TIME_ABSOLUTE",
    )

    def draw(self, context):
        self.layout.prop(self, "solver_time_limit")


def get(context=None):
    """The preferences, or None when the add-on is loaded without its preferences (tests)."""
    context = context or bpy.context
    addon = context.preferences.addons.get(__package__)
    return addon.preferences if addon else None


register, unregister = bpy.utils.register_classes_factory((SHAPESMITH_AP_preferences,))
