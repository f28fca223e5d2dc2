//! The one error type every entry point returns, split by cause so that callers (and the
//! Python layer, which maps each kind to its own exception class) can tell bad input from a
//! solver failure.

use thiserror::Error;

#[derive(Debug, Error, Clone, PartialEq)]
pub enum ShapesmithError {
    /// The caller's data is unusable as given; the message says what to fix and names the
    /// offending vertex, triangle or shape.
    #[error("{0}")]
    InvalidInput(String),
    /// The constraints admit no solution (e.g. contradictory refinements).
    #[error("{0}")]
    Infeasible(String),
    /// A numerical solver failed on valid input (singular system, HiGHS error).
    #[error("{0}")]
    Solver(String),
    /// The caller asked to stop through [`crate::Progress`].
    #[error("cancelled")]
    Cancelled,
}

pub type ShapesmithResult<T> = Result<T, ShapesmithError>;

/// Shorthand for an [`ShapesmithError::InvalidInput`] with a formatted message.
#[macro_export]
macro_rules! invalid {
    ($($arg:tt)*) => { $crate::error::ShapesmithError::InvalidInput(format!($($arg)*)) };
}
