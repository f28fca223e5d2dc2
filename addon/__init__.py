"""Shapesmith: expression packing, landmark layouts and shape-key transfer for face rigs.

Each module registers itself; this list is the order (properties before the UI that draws them).
"""

import importlib

_MODULE_NAMES = (
    "preferences",
    "properties",
    "wrap_properties",
    "performance_properties",
    "operators.face_parts",
    "operators.analyze_rig",
    "operators.symmetry_pairs",
    "operators.name_map_rows",
    "operators.list_template_keys",
    "operators.pack_expressions",
    "operators.pack_refinements",
    "operators.pose_expressions",
    "operators.export_expressions",
    "operators.place_landmarks",
    "operators.score_layout",
    "operators.export_landmarks",
    "operators.render_landmarks",
    "operators.render_landmark_curve",
    "operators.preview_virtual_edges",
    "operators.transfer_shape_keys",
    "operators.show_crossings",
    "operators.wrap_pairs",
    "operators.propose_pairs",
    "operators.wrap_template",
    "operators.job_operator",
    "operators.arkit_template",
    "operators.transfer_onto_character",
    "operators.solve_performance",
    "operators.cancel_performance_solve",
    "operators.import_capture",
    "operators.save_performance_report",
    "ui.presets",
    "ui.panels",
    "ui.names_panel",
    "ui.pack_panel",
    "ui.transfer_panel",
    "ui.wrap_panel",
    "ui.performance_panel",
)

_modules = []


def register():
    _modules.clear()
    for name in _MODULE_NAMES:
        module = importlib.import_module(f"{__package__}.{name}")
        module.register()
        _modules.append(module)


def unregister():
    for module in reversed(_modules):
        module.unregister()
    _modules.clear()
