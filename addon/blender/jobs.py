"""Cancel for the long tools (Generate ARKit Keys, Wrap, Transfer onto Character, Transfer Shape
Keys, Personalise, Pack Expressions, Place Landmarks, Score Layout): one job at a time, whose stop request every native loop sees through its progress callback (returning
False stops the core at its next checkpoint with `CancelledError`). Each tool solves in full
before it writes, and removes what it made on the way, so a cancelled job leaves the file as
it was.

Two ways to run a job's function, the same function either way:
- blocking (`run_blocking`): on the calling thread, as batch and background Blender run it (modal
  operators and timers never run there); `cancel()` from any thread stops it;
- threaded (`ThreadedJob`): the panel's. The function runs on a worker thread, but only one of
  the two threads runs at any moment outside native work: the worker holds a baton while it
  runs Python (and reads or writes Blender data) and hands it to the main thread for the
  length of each native call (`native.module()` wraps the calls, see `in_native`), so Blender
  redraws, shows the progress and takes Esc or the Cancel button while the core computes, and
  the worker never touches Blender data while the main thread runs.
"""

import threading
from contextlib import contextmanager

_stop = threading.Event()
_local = threading.local()
_current = None


class JobCancelled(Exception):
    """The user cancelled: nothing was written."""


def cancel():
    """Asks the running job (if any) to stop; it stops at its next native checkpoint."""
    _stop.set()


def cancelling():
    return _stop.is_set()


def current():
    """The running threaded job, or None."""
    return _current if _current is not None and _current.state == "running" else None


def keep_going(callback=None):
    """A progress callback for the native core: reports to `callback` (fraction) when given and
    returns False once `cancel()` was called."""

    def progress(fraction):
        if callback is not None:
            callback(fraction)
        return not _stop.is_set()

    return progress


def cancelled_error():
    """The native `CancelledError` type (None without the native core)."""
    from .. import native

    try:
        return native.module().CancelledError
    except native.NativeUnavailableError:
        return None


def run_blocking(function, callback, *args, **kwargs):
    """Runs `function(progress, *args, **kwargs)` here, `progress` reporting to `callback`
    (None: nowhere) and stopping on `cancel()`; the native `CancelledError` becomes
    `JobCancelled`. The stop flag is cleared first (a request belongs to one job)."""
    _stop.clear()
    error_type = cancelled_error()
    try:
        return function(keep_going(callback), *args, **kwargs)
    except Exception as error:
        if error_type is not None and isinstance(error, error_type):
            raise JobCancelled("cancelled: nothing was changed") from None
        raise
    finally:
        _stop.clear()


def on_worker():
    """True on a threaded job's worker (its native calls then hand the baton over)."""
    return getattr(_local, "job", None) is not None


@contextmanager
def in_native():
    """Around a native call: on a job's worker the baton goes to the main thread for the
    call's length and comes back before the worker touches Blender again; elsewhere nothing."""
    job = getattr(_local, "job", None)
    if job is None:
        yield
        return
    job._hand_over()
    try:
        yield
    finally:
        job._take_back()


class ThreadedJob:
    """`ThreadedJob(label, function, *args)` runs `function(progress, *args)` on a worker; the main thread
    calls `step()` (a modal operator's timer) until it returns False. `state`: "running", then
    "finished" (`value`), "cancelled" or "failed" (`error`). `fraction` is the last progress
    the function reported through `progress()`."""

    def __init__(self, label, function, *args, **kwargs):
        global _current
        if current() is not None:
            raise RuntimeError(f"'{_current.label}' is running: wait for it or cancel it")
        _stop.clear()
        self.label, self.state, self.fraction = label, "running", 0.0
        self.value, self.error = None, None
        # Whose turn: "waiting" (the worker wants the baton), "python" (the worker has it),
        # "native" (the worker computes without it), "done".
        self._phase = "waiting"
        self._baton = threading.Condition()
        self._worker = threading.Thread(target=self._work, args=(function, args, kwargs), name=f"Shapesmith {label}", daemon=True)
        _current = self
        self._worker.start()

    def progress(self, fraction):
        """The native callback (on the worker, inside native work): records, never touches Blender."""
        self.fraction = fraction
        return not _stop.is_set()

    def _work(self, function, args, kwargs):
        _local.job = self
        self._take_back()
        error_type = cancelled_error()
        try:
            self.value, state = function(self.progress, *args, **kwargs), "finished"
        except Exception as error:  # handed to the main thread, which reports or raises it
            cancelled = isinstance(error, JobCancelled) or (error_type is not None and isinstance(error, error_type))
            self.error, state = (JobCancelled("cancelled: nothing was changed"), "cancelled") if cancelled else (error, "failed")
        _local.job = None
        with self._baton:
            self.state, self._phase = state, "done"
            self._baton.notify_all()

    def _hand_over(self):
        with self._baton:
            self._phase = "native"
            self._baton.notify_all()

    def _take_back(self):
        with self._baton:
            if self._phase == "native":
                self._phase = "waiting"
                self._baton.notify_all()
            self._baton.wait_for(lambda: self._phase == "python")

    def step(self):
        """Main thread: when the worker is back from native work, lets it run its Python until
        its next native call (or its end); returns True while the job runs."""
        with self._baton:
            if self._phase == "waiting":
                self._phase = "python"
                self._baton.notify_all()
                # Until the worker lets go: in native work, done, or already back from a
                # short call and waiting for its next turn.
                self._baton.wait_for(lambda: self._phase != "python")
        return self.state == "running"

    def wait(self):
        """Steps until the job ends (a background test's stand-in for the timer)."""
        while self.step():
            self._worker.join(0.02)
        self._worker.join()
