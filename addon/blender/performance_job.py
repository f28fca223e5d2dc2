"""Solve Performance without freezing Blender: the native solve runs on a worker thread (it
releases the GIL, and stops at its next checkpoint, every 4 frames, once its progress
callback returns False), while Blender's main thread steps the job from a timer, shows its
progress and keys the result only once the solve has finished. So a cancelled or failed
solve writes nothing: the file stays as it was.

A plain class, free of operators and timers, so that a background test (where modal
operators and timers never run) can step it by hand as the Solve operator's timer does.
"""

import threading

from .mesh_arrays import MeshDataError
from .performance import SolveRequest, write_animation

_current = None


def current():
    """The job running in this Blender session (one at a time), or None. A cancelled job whose
    worker has stopped is ended here, should nothing step it any more."""
    job = _current
    if job is not None and job.cancelling and not job._worker.is_alive():
        job.step()
    return job if job is not None and job.state == "running" else None


class SolveJob:
    """One solve: `SolveJob(obj, tracks, settings, target)` reads the rig and starts the worker; `step()`
    on the main thread until it returns False; `cancel()` at any time. `state` is "running",
    then "finished" (keyed; `document` holds the report), "cancelled" or "failed" (`error`)."""

    def __init__(self, obj, tracks, settings=None, target=None):
        global _current
        if current() is not None:
            raise MeshDataError("a solve is already running: wait for it or cancel it")
        self.request = SolveRequest(obj, tracks, settings)
        self.vertex_count = len(obj.data.vertices)
        self.target_name = target.name if target is not None else None
        self.state, self.fraction, self.document, self.error = "running", 0.0, None, None
        self._stop = threading.Event()
        self._solved, self._failure = None, None
        self._worker = threading.Thread(target=self._work, name="Shapesmith Solve Performance", daemon=True)
        _current = self
        self._worker.start()

    def _progress(self, fraction):
        self.fraction = fraction
        return not self._stop.is_set()

    def _work(self):
        try:
            self._solved = self.request.run(self._progress)
        except Exception as error:  # handed to the main thread, which reports or raises it
            self._failure = error

    def cancel(self):
        """Asks the solve to stop; nothing is written once asked, even if it was just done."""
        self._stop.set()

    def wait(self, timeout):
        """Waits up to `timeout` seconds for the worker to end (after `cancel`, it stops at its
        next checkpoint, within about 25 ms)."""
        self._worker.join(timeout)

    @property
    def cancelling(self):
        return self._stop.is_set() and self.state == "running"

    def step(self):
        """Main thread: True while the solve runs. Once the worker has ended, keys the result
        (finished) or nothing (cancelled, failed) and returns False."""
        if self.state != "running":
            return False
        if self._worker.is_alive():
            return True
        self._worker.join()
        if self._stop.is_set():
            self.state = "cancelled"
        elif self._failure is not None:
            self.state, self.error = "failed", self._failure
        else:
            try:
                obj, target = self._objects()
                document = self.request.document(self._solved)
                write_animation(obj, document, target)
            except MeshDataError as error:
                self.state, self.error = "failed", error
            else:
                self.state, self.document, self.fraction = "finished", document, 1.0
        return False

    def _objects(self):
        """The head and the pose target by name (an undo during the solve replaces the Python
        objects), checked to be what was solved."""
        import bpy

        name = self.request.object_name
        obj = bpy.data.objects.get(name)
        keys = obj.data.shape_keys if obj is not None and obj.type == "MESH" else None
        if keys is None or len(obj.data.vertices) != self.vertex_count:
            raise MeshDataError(f"'{name}' was removed or its mesh changed during the solve: solve again")
        missing = [n for n in self.request.rig.names if n not in keys.key_blocks]
        if missing:
            raise MeshDataError(f"shape keys of '{name}' were removed during the solve ({', '.join(missing[:3])}): solve again")
        target = None
        if self.target_name is not None:
            target = bpy.data.objects.get(self.target_name)
            if target is None:
                raise MeshDataError(f"the pose target '{self.target_name}' was removed during the solve: solve again")
        return obj, target
