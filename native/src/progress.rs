//! Progress reporting for long work: the core reports a fraction between chunks and stops
//! when the caller asks it to.

use crate::error::{ShapesmithError, ShapesmithResult};

pub trait Progress: Sync {
    /// Reports `fraction` in [0, 1] of the current job; returns `false` to ask for a stop.
    fn report(&self, fraction: f64) -> bool;

    /// Reports and turns a stop request into [`ShapesmithError::Cancelled`].
    fn checkpoint(&self, fraction: f64) -> ShapesmithResult<()> {
        if self.report(fraction) {
            Ok(())
        } else {
            Err(ShapesmithError::Cancelled)
        }
    }
}

/// Ignores progress and never stops.
pub struct NoProgress;

impl Progress for NoProgress {
    fn report(&self, _fraction: f64) -> bool {
        true
    }
}

/// One stage of a longer job: reports the stage's own fraction as its share
/// `[start, start + span]` of the whole job's.
pub struct Stage<'a> {
    pub whole: &'a dyn Progress,
    pub start: f64,
    pub span: f64,
}

impl Progress for Stage<'_> {
    fn report(&self, fraction: f64) -> bool {
        self.whole.report(self.start + self.span * fraction.clamp(0.0, 1.0))
    }
}
