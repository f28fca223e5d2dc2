"""The progress a long operator shows: Blender's progress cursor and the status text advance
through reading the rig's keys, the native work and writing keys, only forward, and end
cleared; the operators that show it still write what they wrote without it."""

import importlib
from types import SimpleNamespace

import bpy
import numpy as np
from conftest import make_active


class WindowManager:
    """Records what the operator's progress gives Blender's progress cursor."""

    def __init__(self):
        self.calls = []

    def progress_begin(self, low, high):
        self.calls.append(("begin", low, high))

    def progress_update(self, value):
        self.calls.append(("update", value))

    def progress_end(self):
        self.calls.append(("end",))


class Workspace:
    def __init__(self):
        self.texts = []

    def status_text_set(self, text):
        self.texts.append(text)


def addon(shapesmith, name):
    return importlib.import_module(shapesmith.__name__ + name)


def test_transfer_progress_runs_through_reading_solving_and_writing_keys(sample, shapesmith):
    base = addon(shapesmith, ".operators.base")
    transfer = addon(shapesmith, ".blender.transfer")
    shape_keys = addon(shapesmith, ".blender.shape_keys")
    mesh_arrays = addon(shapesmith, ".blender.mesh_arrays")
    template, target = bpy.data.objects["Template"], bpy.data.objects["Target_Boy"]
    keys = len(template.data.shape_keys.key_blocks) - 1
    context = SimpleNamespace(window_manager=WindowManager(), workspace=Workspace())
    with base.progress_cursor(context, "Transfer") as progress:
        solved = transfer.transfer_object(template, target, progress=progress)
        written, _, _ = shape_keys.write_transferred_keys(solved)
    assert len(written) == keys
    calls = context.window_manager.calls
    assert calls[0] == ("begin", 0, 100) and calls[-1] == ("end",)
    values = [c[1] for c in calls[1:-1]]
    assert all(c[0] == "update" for c in calls[1:-1])
    assert values == sorted(values) and values[-1] == 100
    texts = context.workspace.texts
    assert texts[-1] is None  # the status bar is given back
    reading = [t for t in texts[:-1] if "reading shape key" in t]
    computing = [t for t in texts[:-1] if "computing" in t]
    writing = [t for t in texts[:-1] if "writing shape key" in t]
    # Every key read (the template's, once) and written advances the text; reading comes
    # first, then the native work, then writing.
    assert f"Transfer: reading shape key {keys} of {keys}, 10%" in reading
    assert f"Transfer: writing shape key {keys} of {keys}, 100%" in writing
    assert len(writing) == keys and len(computing) >= 20
    order = [texts.index(reading[-1]), texts.index(computing[0]), texts.index(computing[-1]), texts.index(writing[0])]
    assert order == sorted(order)
    # Outside an operator nothing listens.
    assert mesh_arrays.key_progress.get() is None
    # What was written (through ShapeKey.points) is what ShapeKey.data reads back.
    for k, name in enumerate(solved.names):
        co = np.empty(len(target.data.vertices) * 3, dtype=np.float32)
        target.data.shape_keys.key_blocks[name].data.foreach_get("co", co)
        assert np.abs(co.reshape(-1, 3) - (solved.target_neutral + solved.deltas[k])).max() < 1e-6


def test_keys_read_through_points_are_the_keys_data(sample, shapesmith):
    """The rig read through ShapeKey.points against each key's items read one by one."""
    mesh_arrays = addon(shapesmith, ".blender.mesh_arrays")
    template = bpy.data.objects["Template"]
    rig = mesh_arrays.read_rig(template)
    blocks = template.data.shape_keys.key_blocks
    basis = np.array([point.co[:] for point in blocks[0].data], dtype=np.float32)
    assert np.array_equal(rig.neutral, basis)
    for k in (0, 17, len(rig.names) - 1):
        posed = np.array([point.co[:] for point in blocks[rig.names[k]].data], dtype=np.float32)
        assert np.array_equal(rig.deltas[k], posed - basis)
        assert np.abs(rig.deltas[k]).max() > 0  # a shape that moves, so the check can fail


def test_progress_only_moves_forward_and_stays_in_its_stage(shapesmith):
    """The stages' shares of the bar, checked without Blender's UI: native fractions land
    between reading and writing, and a second native call starting again from 0 (the carry
    after the transfer) does not move the bar back."""
    window_manager, workspace = WindowManager(), Workspace()
    progress = addon(shapesmith, ".operators.base").PanelProgress(window_manager, workspace, "Wrap")
    progress.keys(5, 10, writing=False)
    assert window_manager.calls[-1] == ("update", 5)
    assert progress(0.0) is True
    assert window_manager.calls[-1] == ("update", 10)
    progress(0.5)
    assert window_manager.calls[-1] == ("update", 50)
    progress(0.25)
    assert window_manager.calls[-1] == ("update", 50)
    progress(1.0)
    progress.keys(1, 2, writing=True)
    assert window_manager.calls[-1] == ("update", 95)
    assert workspace.texts[-1] == "Wrap: writing shape key 1 of 2, 95%"


def test_analyze_and_score_layout_run_with_their_progress(sample, shapesmith):
    """The two operators that gained a progress cursor (for the keys they read) store their
    results as before, and leave no key listener behind."""
    obj = make_active(bpy.data.objects["Template"])
    assert bpy.ops.shapesmith.analyze_rig() == {"FINISHED"}
    assert obj.shapesmith.analysis.done and obj.shapesmith.analysis.shapes == 52 and len(obj.shapesmith.pairs) > 10
    group = obj.vertex_groups.new(name="Tracked")
    group.add(np.linspace(0, len(obj.data.vertices) - 1, 40).astype(int).tolist(), 1.0, "REPLACE")
    assert bpy.ops.shapesmith.score_layout(group="Tracked") == {"FINISHED"}
    score = obj.shapesmith.landmark_score
    assert score.done and score.landmarks == 40 and 0.0 < score.mean_error <= score.max_error
    assert addon(shapesmith, ".blender.mesh_arrays").key_progress.get() is None


def test_scoring_a_layout_reports_its_poses_and_stops_when_asked(sample, shapesmith):
    """Score Layout's native call (seconds on a production-size rig) advances the progress
    once per test pose, and answering False stops it."""
    import pytest

    landmarks = addon(shapesmith, ".blender.landmarks")
    obj = bpy.data.objects["Template"]
    group = obj.vertex_groups.new(name="Tracked")
    group.add(np.linspace(0, len(obj.data.vertices) - 1, 40).astype(int).tolist(), 1.0, "REPLACE")
    seen = []
    score = landmarks.score_group(obj, "Tracked", progress=seen.append)
    assert seen == sorted(set(seen)) and seen[-1] == 1.0 and len(seen) > 10
    assert score == landmarks.score_group(obj, "Tracked")
    with pytest.raises(shapesmith.native.module().CancelledError):
        landmarks.score_group(obj, "Tracked", progress=lambda fraction: fraction < 0.5)
