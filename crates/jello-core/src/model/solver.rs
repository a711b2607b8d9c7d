//! How closely the implicit integrators solve a step ([`Newton`]): part of the model, set by
//! scenes, the command line and Python; the solver itself is in
//! [`crate::integrate::implicit`].

/// Converged when `max |g| ≤ TOLERANCE · max(1, max |v₁|)` (m/s), by default.
pub const TOLERANCE: f64 = 1e-9;

/// The loosest tolerance a model may set: a residual of a tenth of the speed is no longer
/// the method's solution in any useful sense.
pub const MAX_TOLERANCE: f64 = 0.1;

/// Newton iterations before a step is reported as not converged, by default.
pub const MAX_NEWTON: u32 = 200;

/// Halvings of a step that does not converge, by default (see [`crate::integrate::cutback`]): its smallest
/// substep is `dt/64`.
pub const CUTBACKS: u32 = 6;

/// The most halvings a model may allow (a step of a million substeps).
pub const MAX_CUTBACKS: u32 = 20;

/// How closely a step is solved: converged when `max |g| ≤ tolerance · max(1, max |v₁|)`
/// (m/s), not when that takes more than `max_iterations` Newton iterations; then the step is
/// taken as two halves, each of which may be halved again, `cutbacks` times in all, before it is
/// reported (see [`crate::integrate::cutback`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Newton {
    /// m/s, above 0 and at most [`MAX_TOLERANCE`]: the residual allowed at a point, times the
    /// fastest point's speed when that is above 1 m/s.
    pub tolerance: f64,
    /// At least 1.
    pub max_iterations: u32,
    /// 0 reports the first step that does not converge; at most [`MAX_CUTBACKS`].
    pub cutbacks: u32,
}

impl Default for Newton {
    fn default() -> Self {
        Newton {
            tolerance: TOLERANCE,
            max_iterations: MAX_NEWTON,
            cutbacks: CUTBACKS,
        }
    }
}
