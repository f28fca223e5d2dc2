"""Poll checks that explain why a button is disabled, and the one place that turns expected
errors (bad mesh, bad input, infeasible program) into an operator report."""

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
