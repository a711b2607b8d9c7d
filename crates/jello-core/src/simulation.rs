//! [`Simulation`]: a model with its state, control and scratch, the handle the front ends drive.

use crate::compute::team;
use crate::forces;
use crate::formats::world::World;
use crate::integrate::cutback::CutbackStats;
use crate::integrate::implicit::SolverStats;
use crate::integrate::{step, BlowUp, Scratch};
use crate::model::{Model, ModelError};
use crate::state::{Control, State};

/// A model with its state, control and scratch: the convenient handle that the front ends (the
/// `jello` command line and the browser's `jello-wasm`) drive.
#[derive(Clone, Debug)]
pub struct Simulation {
    /// What does not change while stepping.
    pub model: Model,
    /// What stepping advances.
    pub state: State,
    /// Forces from outside.
    pub control: Control,
    scratch: Scratch,
}

impl Simulation {
    /// A simulation of `model` starting from `state`.
    pub fn new(model: Model, state: State) -> Self {
        let scratch = Scratch::new(&model);
        Simulation {
            model,
            state,
            control: Control::none(),
            scratch,
        }
    }

    /// The simulation a world file describes.
    pub fn from_world(world: &World) -> Result<Self, ModelError> {
        let (model, state) = world.to_simulation()?;
        Ok(Simulation::new(model, state))
    }

    /// One step; on a blow-up the state stays at the last good step.
    pub fn step(&mut self) -> Result<(), BlowUp> {
        step(
            &self.model,
            &mut self.state,
            &self.control,
            &mut self.scratch,
        )
    }

    /// How often implicit steps were taken in parts since this simulation was made (see
    /// [`cutback`](crate::integrate::cutback); "cutbacks", everywhere else, is how many times a
    /// step may be halved: [`Newton::cutbacks`](crate::model::solver::Newton)).
    pub fn cutback_stats(&self) -> CutbackStats {
        self.scratch.cutback_stats()
    }

    /// Wall-clock time this simulation's steps spent on contacts between bodies (finding them,
    /// and their forces), since it was made: with the time of the steps, the contact pass's
    /// share of stepping (`jello run --timings`). Zero for a model whose surfaces cannot touch
    /// (one body without self-contact), and in the browser.
    pub fn contact_time(&self) -> std::time::Duration {
        self.scratch.contact_time()
    }

    /// The contact passes' work between bodies since this simulation was made, counted (see
    /// [`ContactWork`](crate::contact::bodies::ContactWork)): the same on any machine.
    pub fn contact_work(&self) -> crate::contact::bodies::ContactWork {
        self.scratch.contact_work()
    }

    /// The implicit solver's work since this simulation was made (see [`SolverStats`]).
    pub fn solver_stats(&self) -> SolverStats {
        self.scratch.solver_stats()
    }

    /// `n` steps, stopping at the first blow-up.
    ///
    /// On models large enough for threads (a large lattice, or several bodies: see
    /// `forces::steps_on_team`) the steps share one team of threads (see
    /// `compute/team.rs`): its threads wait for the next step's work spinning, and each keeps the same
    /// part of the lattice from step to step. The results are the same as `n` calls of
    /// [`Simulation::step`].
    pub fn advance(&mut self, n: u64) -> Result<(), BlowUp> {
        let steps = |sim: &mut Simulation| (0..n).try_for_each(|_| sim.step());
        if n > 1 && forces::steps_on_team(&self.model) {
            return team::run(|| steps(self));
        }
        steps(self)
    }

    /// The current state as a world file, when the model fits the classic format.
    pub fn to_world(&self) -> Result<World, ModelError> {
        World::from_simulation(&self.model, &self.state)
    }
}
