//! Integrators: one step of the chosen method, with blow-up detection at the step boundary.
//!
//! Every integrator writes the new state into scratch buffers; the state is replaced only when
//! every new position and velocity is finite and no point has escaped the box by more than the
//! model's escape margin. So after a [`BlowUp`] the state still holds the last good step, and
//! nothing non-finite ever reaches a caller, a renderer or a saved file.
//!
//! - this file: [`step`];
//! - `scratch.rs`: the buffers every integrator works in ([`Scratch`]), and what every step does
//!   with its result;
//! - [`explicit`]: Euler, RK2, RK4 and symplectic Euler, each stage one force pass;
//! - [`implicit`]: backward Euler and SDIRK2, solved by Newton's method;
//! - [`cutback`]: implicit steps that fail taken again in halves;
//! - [`blow_up`]: what a rejected step reports;
//! - [`stability`]: the largest stable time step of each integrator for a model.

pub mod blow_up;
pub mod cutback;
pub mod explicit;
pub mod implicit;
mod scratch;
pub mod stability;

pub use blow_up::{BlowUp, BlowUpCause};
pub use scratch::Scratch;

use crate::integrate::blow_up::unsound;
use crate::integrate::scratch::accept;
use crate::model::Model;
use crate::state::{Control, State};

/// Advances `state` by one step of `model.integrator` with `model.dt`.
///
/// On success the state holds the new positions and velocities, `time` grows by `dt` and `steps`
/// by one. On a blow-up the state is unchanged and the error says where and what to try. An
/// implicit step that fails is first taken again in parts ([`crate::integrate::cutback`]).
///
/// Stepping allocates nothing. On lattices large enough for threads, the step runs on a team of
/// the rayon pool's threads (`compute/team.rs`): call it from inside the pool (`ThreadPool::install`
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
    let sound = match crate::forces::steps_on_team(model) {
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
