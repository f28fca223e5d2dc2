"""Poll checks that explain why a button is disabled, the one place that turns expected
errors (bad mesh, bad input, infeasible program) into an operator report, and the progress
cursor of long native work."""

from contextlib import contextmanager

from .. import native
from ..blender.mesh_arrays import MeshDataError


def poll_mesh(cls, context):
    """True for a mesh in Object Mode; otherwise says why the button is disabled."""
    obj = context.active_object
    if obj is None or obj.type != "MESH":
        cls.poll_message_set("Select a mesh object")
        return False
    if obj.mode != "OBJECT":
        cls.poll_message_set("Switch to Object Mode")
        return False
    return True


def poll_packed(cls, context):
    """A mesh in Object Mode that carries a Pack Expressions result."""
    if not poll_mesh(cls, context):
        return False
    if not context.active_object.shapesmith.pack.result.done:
        cls.poll_message_set("Pack the expressions first")
        return False
    return True


def poll_landmarks(cls, context):
    """A mesh in Object Mode that carries a landmark layout."""
    if not poll_mesh(cls, context):
        return False
    if not context.active_object.shapesmith.landmarks.done:
        cls.poll_message_set("Run Place Landmarks first")
        return False
    return True


def expected_errors():
    """Errors that are the user's to fix: reported with `report({'ERROR'})`, the operator
    cancelled (and the .blend left as it was). Anything else is a bug and propagates."""
    errors = (MeshDataError, native.NativeUnavailableError)
    try:
        return errors + native.error_types()
    except native.NativeUnavailableError:
        return errors


@contextmanager
def progress_cursor(context):
    """Blender's progress cursor for the length of a long native call; yields the callback
    (fraction in [0, 1]) that the native core calls on this, the main, thread."""
    window_manager = context.window_manager
    window_manager.progress_begin(0, 100)
    try:
        yield lambda fraction: window_manager.progress_update(int(100 * fraction))
    finally:
        window_manager.progress_end()
