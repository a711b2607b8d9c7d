//! `jello.TunnellingWarning`: points that passed through a box or ball obstacle, found by the
//! core's `TunnelWatch` over every step on the CPU (and every state read back on the GPU), and
//! said once per body and obstacle with the command line's facts and advice, the Python way
//! (`sim.dt = …`, `sim.set_collision(stiffness=…)`).

use jello_core::diagnostics::{crossing_warning, Crossings, Knobs, TunnelWatch};
use pyo3::create_exception;
use pyo3::exceptions::PyUserWarning;
use pyo3::prelude::*;

create_exception!(
    jello,
    TunnellingWarning,
    PyUserWarning,
    "Points of a body passed through a box or ball obstacle: a step (on the GPU, the steps \
     between two states read back) carried them past its middle, where the contact pushes them \
     out of the far side, so the body may end up through or impaled on it. Warned once per body \
     and obstacle after the call that found it, until the model changes. The message says how \
     many points, when, and what to try; attributes: body (its index in `bodies`), obstacle \
     (the index of the obstacle, 0 for the first), points, time (the start and end (s) of the \
     first step that did), suggested_dt and suggested_collision_stiffness (None when that \
     would not help)."
);

/// The knobs as Python sets them.
const PYTHON: Knobs = Knobs {
    dt: |dt| format!("sim.dt = {dt}"),
    stiffness: |k| format!("`sim.set_collision(stiffness={k})`"),
};

/// The watch over a simulation's states, and the crossings already warned of.
#[derive(Clone, Default)]
pub(crate) struct Watch {
    /// Started at the first step after the model changed (None until then, or when the model
    /// has no box or ball obstacle).
    watch: Option<TunnelWatch>,
    /// The step count of the last state observed.
    steps: u64,
    /// The (body, obstacle) pairs warned of.
    warned: Vec<(usize, usize)>,
}

impl Watch {
    /// The model changed: the crossings found are forgotten, and warned of again if they recur.
    pub(crate) fn reset(&mut self) {
        *self = Watch::default();
    }

    /// The positions were assigned: the next state is compared with them, not with the last
    /// stepped (those already warned of stay quiet).
    pub(crate) fn restart(&mut self) {
        self.watch = None;
    }

    /// Ready to observe the steps taken from `sim`'s state.
    pub(crate) fn start(&mut self, sim: &jello_core::Simulation) {
        if self.watch.is_none() && TunnelWatch::watches(&sim.model) {
            self.watch = Some(TunnelWatch::new(&sim.model, &sim.state));
            self.steps = sim.state.steps;
        }
    }

    /// Whether the states are compared (the model has a box or ball obstacle).
    pub(crate) fn watching(&self) -> bool {
        self.watch.is_some()
    }

    /// Compares `sim`'s state with the last observed, however many steps later (none: nothing
    /// compared).
    pub(crate) fn observe(&mut self, sim: &jello_core::Simulation) {
        if let Some(watch) = &mut self.watch {
            let apart = sim.state.steps.saturating_sub(self.steps);
            watch.observe_apart(&sim.model, &sim.state, apart);
            self.steps = sim.state.steps;
        }
    }

    /// `warnings.warn`s a `jello.TunnellingWarning` for each crossing not warned of yet, its
    /// message starting with `source`; `Err` when a warnings filter turned one into an error.
    pub(crate) fn warn(
        &mut self,
        py: Python<'_>,
        sim: &jello_core::Simulation,
        source: &str,
        body_names: &[String],
    ) -> PyResult<()> {
        let Some(watch) = &self.watch else {
            return Ok(());
        };
        let new: Vec<Crossings> = watch
            .crossings()
            .iter()
            .filter(|c| !self.warned.contains(&(c.body, c.obstacle)))
            .copied()
            .collect();
        if new.is_empty() {
            return Ok(());
        }
        let warn = py.import("warnings")?.getattr("warn")?;
        for c in new {
            self.warned.push((c.body, c.obstacle));
            let text = crossing_warning(&sim.model, &c, body_names, &PYTHON);
            let warning = py
                .get_type::<TunnellingWarning>()
                .call1((format!("{source}: {text}"),))?;
            warning.setattr("body", c.body)?;
            warning.setattr("obstacle", c.obstacle)?;
            warning.setattr("points", c.points)?;
            warning.setattr("time", c.first)?;
            warning.setattr("suggested_dt", c.advised_dt())?;
            warning.setattr(
                "suggested_collision_stiffness",
                c.advised_stiffness(&sim.model),
            )?;
            // Attributed to the caller's line (`sim.run(…)`), as a warning from Python code
            // called there would be.
            warn.call1((warning, py.None(), 1))?;
        }
        Ok(())
    }
}
