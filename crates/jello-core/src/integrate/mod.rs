//! Integrators: one step of the chosen method, with blow-up detection at the step boundary.
//!
//! Every integrator writes the new state into scratch buffers; the state is replaced only when
//! every new position and velocity is finite and no point has escaped the box by more than the
//! model's escape margin. So after a [`BlowUp`] the state still holds the last good step, and
//! nothing non-finite ever reaches a caller, a renderer or a saved file.
//!
//! - this file: [`step`], the buffers it works in ([`Scratch`]) and what every step does at its
//!   end;
//! - [`explicit`]: Euler, RK2, RK4 and symplectic Euler, each stage one force pass;
//! - [`implicit`]: backward Euler and SDIRK2, solved by Newton's method;
//! - [`cutback`]: implicit steps that fail taken again in halves;
//! - [`blow_up`]: what a rejected step reports;
//! - [`stability`]: the largest stable time step of each integrator for a model.

pub mod blow_up;
pub mod cutback;
pub mod explicit;
pub mod implicit;
pub mod stability;

pub use blow_up::{BlowUp, BlowUpCause};

use crate::compute::soa::Soa;
use crate::forces::{ForceScratch, PARALLEL_MIN_POINTS};
use crate::integrate::blow_up::unsound;
use crate::integrate::cutback::Cutback;
use crate::integrate::implicit::ImplicitScratch;
use crate::model::Model;
use crate::state::{Control, State};
use crate::vec3::Vec3;

/// Buffers the integrators work in, sized once for a model: stepping never allocates. The
/// integrators work in structures of arrays (see [`crate::compute::soa`]) and write the step's result as
/// arrays of vectors, which are swapped into the state.
#[derive(Clone, Debug, Default)]
pub struct Scratch {
    pub(crate) force: ForceScratch,
    pos: Soa,
    vel: Soa,
    /// Positions of the intermediate stages: RK2's midpoint; RK4's stages 2 and 4 in the first,
    /// stage 3 in the second.
    stage_pos: [Soa; 2],
    /// Velocities of RK4's stages 2, 3 and 4 (RK2's midpoint in the first): all three are the
    /// position slopes the end of the step sums, so none is overwritten.
    stage_vel: [Soa; 3],
    /// RK4's sum of the velocity slopes `k1 + 2k2 + 2k3` (accelerations).
    sum_vel: Soa,
    /// The step's result, swapped into the state when it is sound.
    pub(crate) next_pos: Vec<Vec3>,
    pub(crate) next_vel: Vec<Vec3>,
    /// The implicit solver's buffers (sized on its first step).
    pub(crate) implicit: ImplicitScratch,
    /// How implicit steps are being cut back, and the state to go back to.
    pub(crate) cutback: Cutback,
}

impl Scratch {
    /// How often implicit steps were taken in parts (see [`crate::integrate::cutback`]) since these
    /// buffers were made.
    pub fn cutbacks(&self) -> crate::CutbackStats {
        self.cutback.stats()
    }

    /// The implicit solver's work (solves, Newton and conjugate-gradient iterations,
    /// assemblies of its matrix) since these buffers were made; zero under explicit integrators.
    pub fn solver_stats(&self) -> crate::SolverStats {
        self.implicit.stats()
    }

    /// Buffers for a model's point count.
    pub fn new(model: &Model) -> Self {
        // Buffers read in the same loops get different colors (cache sets, see Soa).
        let z = |color| Soa::with_color(model.point_count(), color);
        Scratch {
            force: ForceScratch::new(model),
            pos: z(0),
            vel: z(1),
            stage_pos: [z(2), z(0)],
            stage_vel: [z(3), z(1), z(3)],
            sum_vel: z(2),
            next_pos: vec![Vec3::ZERO; model.point_count()],
            next_vel: vec![Vec3::ZERO; model.point_count()],
            implicit: ImplicitScratch::default(),
            cutback: Cutback::default(),
        }
    }
}

/// Advances `state` by one step of `model.integrator` with `model.dt`.
///
/// On success the state holds the new positions and velocities, `time` grows by `dt` and `steps`
/// by one. On a blow-up the state is unchanged and the error says where and what to try. An
/// implicit step that fails is first taken again in parts ([`crate::integrate::cutback`]).
///
/// Stepping allocates nothing. On lattices large enough for threads, the step runs on a team of
/// the rayon pool's threads ([`crate::compute::team`]): call it from inside the pool (`ThreadPool::install`
/// around the stepping loop, as `jello bench` does), since from outside, the join that starts
/// the team goes through rayon's global queue, which allocates a small block every 63 jobs.
/// Several steps in a row share one team through [`crate::Simulation::advance`].
pub fn step(
    model: &Model,
    state: &mut State,
    control: &Control,
    scratch: &mut Scratch,
) -> Result<(), BlowUp> {
    let n = model.point_count();
    assert_eq!(
        state.pos.len(),
        n,
        "state does not match the model's point count"
    );
    if scratch.pos.len() != n {
        *scratch = Scratch::new(model);
    }
    if model.integrator.is_implicit() {
        return crate::integrate::cutback::step(model, state, control, scratch);
    }
    // Large lattices step on a team of threads (the caller's, as in `Simulation::advance`, else
    // one for this step), each thread keeping its part of the lattice from pass to pass.
    let sound = match model.point_count() >= PARALLEL_MIN_POINTS {
        true => crate::compute::team::run(|| explicit::integrate(model, state, control, scratch)),
        false => explicit::integrate(model, state, control, scratch),
    };
    if !sound {
        let s = scratch;
        return Err(unsound(model, state, &s.next_pos, &s.next_vel, model.dt));
    }
    let (t0, t1) = (state.time, state.time + model.dt);
    accept(model, state, scratch, t0, t1);
    state.time = t1;
    state.steps += 1;
    Ok(())
}

/// The sound result of a step from `t0` to `t1`, in the scratch's buffers, becomes the state's
/// positions and velocities (its time and step count are the caller's): swapped in (the old
/// ones are overwritten by the next step), then the moving pins put where their paths say, and
/// the obstacles' friction anchors dragged or let go.
pub(crate) fn accept(model: &Model, state: &mut State, s: &mut Scratch, t0: f64, t1: f64) {
    std::mem::swap(&mut state.pos, &mut s.next_pos);
    std::mem::swap(&mut state.vel, &mut s.next_vel);
    // From the positions at the step's start, now in the scratch's buffer.
    for m in &model.pin_motions {
        m.apply(t0, t1, &s.next_pos, &mut state.pos, &mut state.vel);
    }
    s.force.update_anchors(model, &state.pos);
}
