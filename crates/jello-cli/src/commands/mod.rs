//! The subcommands of `jello`.

pub mod bench;
pub mod create;
pub mod create_scene;
pub mod info;
pub mod run;
pub mod shape;
mod tunnelling;
pub mod view;

use jello_core::{Integrator, SolverStats};

/// Where `jello run` and `jello bench` step.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum Device {
    /// The f64 core on the CPU (the reference).
    Cpu,
    /// The f32 WGSL shaders on a GPU through wgpu (a build with `--features gpu`).
    Gpu,
}

/// Parses an integrator name for clap, listing the known names on failure.
pub fn parse_integrator(s: &str) -> Result<Integrator, String> {
    s.parse::<Integrator>().map_err(|e| e.to_string())
}

/// Parses a finite, positive number for clap (which names the flag: `invalid value '-0.001' for
/// '--dt <DT>': must be a finite number above 0 (got -0.001)`).
pub fn parse_positive(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 => Ok(v),
        Ok(_) => Err(format!("must be a finite number above 0 (got {s})")),
        Err(_) => Err(format!("expected a finite number above 0, found \"{s}\"")),
    }
}

/// Parses a whole number for clap: a count of steps, frames or threads, at least `min`.
pub fn parse_count(min: u64) -> impl Fn(&str) -> Result<u64, String> + Clone {
    move |s: &str| match s.parse::<i128>() {
        Ok(v) if v >= i128::from(min) && v <= i128::from(u64::MAX) => Ok(v as u64),
        Ok(_) => Err(format!("must be a whole number ≥ {min} (got {s})")),
        Err(_) => Err(format!("expected a whole number ≥ {min}, found \"{s}\"")),
    }
}

/// Parses an implicit integrator's tolerance (m/s) for clap: above 0 and at most
/// [`jello_core::model::solver::MAX_TOLERANCE`].
pub fn parse_tolerance(s: &str) -> Result<f64, String> {
    let max = jello_core::model::solver::MAX_TOLERANCE;
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v > 0.0 && v <= max => Ok(v),
        _ => Err(format!(
            "expected a tolerance above 0 and at most {max} m/s, found \"{s}\""
        )),
    }
}

/// The values clap takes for `--cutbacks`: 0 to [`jello_core::model::solver::MAX_CUTBACKS`] halvings.
pub fn cutbacks_range() -> clap::builder::RangedI64ValueParser<u32> {
    clap::value_parser!(u32).range(0..=jello_core::model::solver::MAX_CUTBACKS as i64)
}

/// A usage error unless `integrator` is implicit: `flag` only means something to those.
pub fn require_implicit(
    integrator: jello_core::Integrator,
    flag: &str,
) -> Result<(), crate::error::CliError> {
    if integrator.is_implicit() {
        Ok(())
    } else {
        Err(crate::error::CliError::usage(format!(
            "{flag}: {integrator} is explicit; only the implicit integrators (BackwardEuler, \
             SDIRK2) solve their steps to a tolerance, and cut back those that fail"
        )))
    }
}

/// Parses a finite number that is at least 0 for clap.
pub fn parse_non_negative(s: &str) -> Result<f64, String> {
    match s.parse::<f64>() {
        Ok(v) if v.is_finite() && v >= 0.0 => Ok(v),
        Ok(_) => Err(format!("must be a finite number ≥ 0 (got {s})")),
        Err(_) => Err(format!("expected a finite number ≥ 0, found \"{s}\"")),
    }
}

/// The implicit solver's work per step over `steps` steps, as `jello run` and `jello bench`
/// end their line with it: ", per step N Newton and M conjugate-gradient iterations, K
/// assemblies".
pub fn solver_work_per_step(work: SolverStats, steps: u64) -> String {
    let per_step = |count: u64| count as f64 / steps as f64;
    format!(
        ", per step {:.2} Newton and {:.1} conjugate-gradient iterations, {:.2} assemblies",
        per_step(work.newton_iterations),
        per_step(work.linear_iterations),
        per_step(work.assemblies)
    )
}
