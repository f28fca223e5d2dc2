"""Poll checks that explain why a button is disabled, the one place that turns expected
errors (bad mesh, bad input, infeasible program) into an operator report, and the progress
cursor of long native work."""

from contextlib import contextmanager

from .. import native
from ..blender.mesh_arrays import MeshDataError, key_progress


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


def poll_character(cls, context, bundled=False):
    """True for a character mesh in Object Mode with a template picked in the Transfer panel
    (the wrap's buttons; with `bundled`, none picked stands for the bundled ARKit template);
    otherwise says why the button is disabled."""
    if not poll_mesh(cls, context):
        return False
    template = context.scene.shapesmith.transfer.source
    if template == context.active_object or (template is None and not bundled):
        cls.poll_message_set("Pick the template in the Transfer panel and make the character active")
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


class PanelProgress:
    """The progress of one long operator, shown by Blender's progress cursor and by the status
    bar's text (`label: stage, percent`). The bar runs through three stages: reading the
    rig's shape keys (the first `READING` of it), the native work (the callback the core calls,
    fraction in [0, 1]) and writing keys (the last `WRITING`), so that reading and writing 150
    keys on a 100k-vertex head advance the bar too. Each stage only moves it forward."""

    READING, WRITING = 0.1, 0.1

    def __init__(self, window_manager, workspace, label):
        self.window_manager, self.workspace, self.label = window_manager, workspace, label
        self.shown = 0.0

    def show(self, fraction, stage):
        self.shown = max(self.shown, min(max(fraction, 0.0), 1.0))
        self.window_manager.progress_update(int(100 * self.shown))
        if self.workspace is not None:
            self.workspace.status_text_set(f"{self.label}: {stage}, {int(100 * self.shown)}%")

    def __call__(self, fraction):
        """The native core's callback; True lets the work go on."""
        self.show(self.READING + (1.0 - self.READING - self.WRITING) * fraction, "computing")
        return True

    def keys(self, done, total, writing):
        """`mesh_arrays.key_progress`'s callback: `done` of `total` keys read or written."""
        if writing:
            self.show(1.0 - self.WRITING + self.WRITING * done / total, f"writing shape key {done} of {total}")
        else:
            self.show(self.READING * done / total, f"reading shape key {done} of {total}")


@contextmanager
def progress_cursor(context, label="Shapesmith"):
    """Blender's progress cursor and status text for the length of a long operator; yields
    the callback (fraction in [0, 1]) that the native core calls on this, the main, thread,
    and advances through the keys read and written meanwhile (`mesh_arrays.key_progress`)."""
    window_manager = context.window_manager
    workspace = getattr(context, "workspace", None)
    progress = PanelProgress(window_manager, workspace, label)
    window_manager.progress_begin(0, 100)
    token = key_progress.set(progress.keys)
    try:
        yield progress
    finally:
        key_progress.reset(token)
        window_manager.progress_end()
        if workspace is not None:
            workspace.status_text_set(None)
