//! `jello run`'s warnings about bodies that passed through obstacles (see
//! `jello_core::contact::tunnelling`), with a time step and a collision stiffness to try, named
//! as the command line sets them.

use jello_core::diagnostics::{Crossings, Knobs, Sunk};
use jello_core::Model;

/// The command line's knobs: `--dt`, and the scene's or `jello create`'s collision stiffness.
const COMMAND_LINE: Knobs = Knobs {
    dt: |dt| format!("--dt {dt}"),
    stiffness: |_| "`[collision] stiffness`, `jello create --collision-stiffness`".to_string(),
};

/// The warning for one body's crossings of one obstacle, with what to try.
pub(crate) fn crossing_warning(model: &Model, c: &Crossings, names: &[String]) -> String {
    jello_core::diagnostics::crossing_warning(model, c, names, &COMMAND_LINE)
}

/// The warning for two bodies that end inside each other, with what to try.
pub(crate) fn sunk_warning(model: &Model, s: &Sunk, names: &[String]) -> String {
    jello_core::diagnostics::sunk_warning(model, s, names, &COMMAND_LINE)
}
