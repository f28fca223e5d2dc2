//! How the bindings run core work: with the GIL released, a panic (a bug) answered as a
//! `SolverError` rather than pyo3's `PanicException`, and, for long work, a progress callback.
//! With a callback the work runs on a scoped thread while the calling thread relays its
//! progress to the callback, so the callback runs on the caller's thread (in Blender the main
//! thread, where it may update the UI) and never races the work for the GIL. The callback
//! returning `False` stops the work (`CancelledError`); an exception it raises stops the work
//! and propagates.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, RecvTimeoutError, Sender};
use std::sync::Mutex;
use std::time::Duration;

use pyo3::prelude::*;

use super::errors::py_err;
use crate::error::{contain_panics, internal_error, ShapesmithResult};
use crate::progress::{NoProgress, Progress};

/// How often the calling thread looks at a worker that has not reported.
const POLL: Duration = Duration::from_millis(20);

/// Forwards each report to the calling thread and answers with its last word.
struct Relay {
    sender: Mutex<Sender<f64>>,
    stop: AtomicBool,
}

impl Progress for Relay {
    fn report(&self, fraction: f64) -> bool {
        if let Ok(sender) = self.sender.lock() {
            // The receiver outlives the work; a send can only fail after it is gone.
            let _ = sender.send(fraction);
        }
        !self.stop.load(Ordering::Relaxed)
    }
}

/// Runs `work` with the GIL released.
pub fn detached<T: Send>(py: Python<'_>, work: impl FnOnce() -> ShapesmithResult<T> + Send) -> PyResult<T> {
    py.detach(|| contain_panics(work)).map_err(py_err(py))
}

/// Runs `work` with the GIL released, reporting to `callback(fraction)` when one is given.
pub fn detached_with_progress<T: Send>(
    py: Python<'_>,
    callback: Option<&Bound<'_, PyAny>>,
    work: impl FnOnce(&dyn Progress) -> ShapesmithResult<T> + Send,
) -> PyResult<T> {
    let Some(callback) = callback else {
        return detached(py, || work(&NoProgress));
    };
    let callback = callback.clone().unbind();
    let (sender, receiver) = mpsc::channel();
    let relay = Relay { sender: Mutex::new(sender), stop: AtomicBool::new(false) };
    let mut callback_error: Option<PyErr> = None;
    let relay_ref = &relay;
    let error_slot = &mut callback_error;
    let outcome = py.detach(move || {
        std::thread::scope(|scope| {
            let worker = scope.spawn(move || work(relay_ref));
            // Reports from parallel workers arrive out of order: the callback sees each
            // fraction only when it advances.
            let mut last = f64::NEG_INFINITY;
            loop {
                match receiver.recv_timeout(POLL) {
                    Ok(fraction) => {
                        if error_slot.is_some() || relay_ref.stop.load(Ordering::Relaxed) || fraction <= last {
                            continue;
                        }
                        last = fraction;
                        let keep_going = Python::attach(|py| match callback.call1(py, (fraction,)) {
                            Ok(answer) => !matches!(answer.extract::<bool>(py), Ok(false)),
                            Err(error) => {
                                *error_slot = Some(error);
                                false
                            }
                        });
                        if !keep_going {
                            relay_ref.stop.store(true, Ordering::Relaxed);
                        }
                    }
                    Err(RecvTimeoutError::Timeout) if !worker.is_finished() => {}
                    Err(_) => break,
                }
            }
            worker.join().unwrap_or_else(|panic| Err(internal_error(panic.as_ref())))
        })
    });
    if let Some(error) = callback_error {
        return Err(error);
    }
    outcome.map_err(py_err(py))
}
