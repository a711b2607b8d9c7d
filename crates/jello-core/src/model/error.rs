//! [`ModelError`], and the checks of values that every part of a model shares.

use std::fmt;

/// A model that could not be built, or a value outside its allowed range.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ModelError(pub String);

impl ModelError {
    /// An error with this message.
    pub fn new(msg: impl Into<String>) -> Self {
        ModelError(msg.into())
    }
}

impl fmt::Display for ModelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ModelError {}

pub(crate) fn positive(what: &str, v: f64) -> Result<(), ModelError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(ModelError::new(format!(
            "{what} must be finite and positive (got {v})"
        )))
    }
}

pub(crate) fn non_negative(what: &str, v: f64) -> Result<(), ModelError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(ModelError::new(format!(
            "{what} must be finite and at least 0 (got {v})"
        )))
    }
}
