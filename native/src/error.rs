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
    #[error("stopped at the caller's request")]
    Cancelled,
}

pub type ShapesmithResult<T> = Result<T, ShapesmithError>;

/// `work()`, with a panic (a bug) turned into a [`ShapesmithError::Solver`] that says so, so
/// that an entry point answers with an error rather than unwinding into its caller.
pub fn contain_panics<T>(work: impl FnOnce() -> ShapesmithResult<T>) -> ShapesmithResult<T> {
    std::panic::catch_unwind(std::panic::AssertUnwindSafe(work)).unwrap_or_else(|panic| Err(internal_error(panic.as_ref())))
}

/// The error for a caught panic, with its message when it has one.
pub fn internal_error(panic: &(dyn std::any::Any + Send)) -> ShapesmithError {
    let message = panic.downcast_ref::<&str>().map(|s| s.to_string()).or_else(|| panic.downcast_ref::<String>().cloned());
    ShapesmithError::Solver(format!("internal error, please report it: {}", message.unwrap_or_else(|| "panic".into())))
}

/// Shorthand for an [`ShapesmithError::InvalidInput`] with a formatted message.
#[macro_export]
macro_rules! invalid {
    ($($arg:tt)*) => { $crate::error::ShapesmithError::InvalidInput(format!($($arg)*)) };
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_panic_becomes_an_error_that_names_it() {
        let caught: ShapesmithResult<u32> = contain_panics(|| panic!("index 7 out of range"));
        match caught {
            Err(ShapesmithError::Solver(message)) => assert!(message.contains("index 7 out of range"), "{message}"),
            other => panic!("expected a Solver error, got {other:?}"),
        }
        assert_eq!(contain_panics(|| Ok(3)), Ok(3));
        assert_eq!(contain_panics::<u32>(|| Err(ShapesmithError::Cancelled)), Err(ShapesmithError::Cancelled));
    }
}
