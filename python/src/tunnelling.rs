//! `jello.TunnellingWarning`: points that passed through a box or ball obstacle, found by the
//! core's `TunnelWatch` over every step on the CPU (and every state read back on the GPU), and
//! said once per body and obstacle with the command line's facts and advice, the Python way
//! (`sim.dt = …`, `sim.set_collision(stiffness=…)`).

use jello_core::diagnostics::{
    bodies_sunk, crossing_warning, obstacles_through, sunk_warning, through_warning, Crossings,
    Knobs, Through, TunnelWatch,
};
use pyo3::create_exception;
use pyo3::exceptions::PyUserWarning;
use pyo3::prelude::*;

create_exception!(
    jello,
    TunnellingWarning,
    PyUserWarning,
    "Points of a body passed through a box or ball obstacle: a step (on the GPU, the steps \
     between two states read back) carried them past its middle, where the contact pushes them \
     out of the far side, so the body may end up through or impaled on it; or, at the end of a \
     call, an obstacle is through a body (edges of its lattice cross the obstacle's middle) \
     that no point was seen passing. Warned once per body and obstacle after the call that \
     found it, until the model changes. The message says how many points, when, and what to \
     try; attributes: body (its index in `bodies`), obstacle (the index of the obstacle, 0 for \
     the first), points (None for an obstacle found through the body), time (the start and \
     end (s) of the first step that did; the state's time twice for an obstacle found \
     through the body), suggested_dt and suggested_collision_stiffness (None when that would \
     not help)."
);

create_exception!(
    jello,
    OverlapWarning,
    PyUserWarning,
    "Two bodies end a call of `run` deeper inside each other than half the finer of their \
     cells, as `jello run` warns at its end: a contact too soft for their weight, or a body \
     thrown into the other faster than the contact stops it within a step. Warned once per pair \
     of bodies until the model changes. The message says how deep, where, and what to try; \
     attributes: bodies (their indices in `bodies`, the lower first), depth (m), at (where, m), \
     suggested_collision_stiffness (N/m: the stiffness that would hold them 2 % of a cell into \
     each other at rest)."
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
    /// The pairs of bodies warned of as overlapping.
    overlaps_warned: Vec<[usize; 2]>,
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

    /// `warnings.warn`s a `jello.TunnellingWarning` for each body and obstacle not warned of
    /// yet: points seen passing through, else (at `sim`'s state) the obstacle through the body;
    /// the message starts with `source`. `Err` when a warnings filter made one an error.
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
        let crossings: Vec<Crossings> = watch.crossings().to_vec();
        // An obstacle through a body that no point was seen passing (it passed between the
        // body's points, or between two states read back from a GPU).
        let through: Vec<Through> = obstacles_through(&sim.model, &sim.state.pos)
            .into_iter()
            .filter(|t| {
                !crossings
                    .iter()
                    .any(|c| (c.body, c.obstacle) == (t.body, t.obstacle))
            })
            .collect();
        for c in crossings {
            if self.warned.contains(&(c.body, c.obstacle)) {
                continue;
            }
            self.warned.push((c.body, c.obstacle));
            let text = crossing_warning(&sim.model, &c, body_names, &PYTHON);
            let warning = new_warning(py, format!("{source}: {text}"), c.body, c.obstacle)?;
            warning.setattr("points", c.points)?;
            warning.setattr("time", c.first)?;
            warning.setattr("suggested_dt", c.advised_dt())?;
            warning.setattr(
                "suggested_collision_stiffness",
                c.advised_stiffness(&sim.model),
            )?;
            warn(py, warning)?;
        }
        for t in through {
            if self.warned.contains(&(t.body, t.obstacle)) {
                continue;
            }
            self.warned.push((t.body, t.obstacle));
            let text = through_warning(&sim.model, &t, body_names);
            let warning = new_warning(py, format!("{source}: {text}"), t.body, t.obstacle)?;
            warning.setattr("points", py.None())?;
            warning.setattr("time", (sim.state.time, sim.state.time))?;
            warning.setattr("suggested_dt", py.None())?;
            warning.setattr("suggested_collision_stiffness", py.None())?;
            warn(py, warning)?;
        }
        Ok(())
    }

    /// `warnings.warn`s a `jello.OverlapWarning` for each pair of bodies at `sim`'s state deeper
    /// inside each other than half the finer of their cells, not warned of yet; the message
    /// starts with `source`. `Err` when a warnings filter made one an error.
    pub(crate) fn warn_overlaps(
        &mut self,
        py: Python<'_>,
        sim: &jello_core::Simulation,
        source: &str,
        body_names: &[String],
    ) -> PyResult<()> {
        if sim.model.bodies().len() < 2 {
            return Ok(());
        }
        for s in bodies_sunk(&sim.model, &sim.state.pos) {
            if self.overlaps_warned.contains(&s.bodies) {
                continue;
            }
            self.overlaps_warned.push(s.bodies);
            let text = sunk_warning(&sim.model, &s, body_names, &PYTHON);
            let warning = py
                .get_type::<OverlapWarning>()
                .call1((format!("{source}: {text}"),))?;
            warning.setattr("bodies", (s.bodies[0], s.bodies[1]))?;
            warning.setattr("depth", s.depth)?;
            warning.setattr("at", (s.at.x, s.at.y, s.at.z))?;
            warning.setattr(
                "suggested_collision_stiffness",
                s.advised_stiffness(&sim.model),
            )?;
            warn(py, warning)?;
        }
        Ok(())
    }
}

/// A `jello.TunnellingWarning` with `message`, its `body` and `obstacle` set.
fn new_warning(
    py: Python<'_>,
    message: String,
    body: usize,
    obstacle: usize,
) -> PyResult<Bound<'_, PyAny>> {
    let warning = py.get_type::<TunnellingWarning>().call1((message,))?;
    warning.setattr("body", body)?;
    warning.setattr("obstacle", obstacle)?;
    Ok(warning)
}

/// `warnings.warn(warning)`, attributed to the caller's line (`sim.run(…)`), as a warning from
/// Python code called there would be.
fn warn(py: Python<'_>, warning: Bound<'_, PyAny>) -> PyResult<()> {
    py.import("warnings")?
        .getattr("warn")?
        .call1((warning, py.None(), 1))?;
    Ok(())
}
