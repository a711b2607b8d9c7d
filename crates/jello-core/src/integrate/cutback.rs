//! Cutbacks: an implicit step that fails is taken again in halves.
//!
//! A step of an implicit integrator fails when Newton's method does not converge within its
//! iterations, or when its result is not sound (see [`mod@crate::integrate`]). It is then taken again
//! as two substeps of half the size, each of which may itself be halved, down to
//! `dt/2^cutbacks` ([`Newton::cutbacks`](crate::model::solver::Newton)). Only a substep of that
//! size that still fails is reported, with the state back at the step's start (friction anchors
//! included). This is the increment cutback of implicit finite-element codes.
//!
//! Each substep solves the integrator's own equations (backward Euler's or SDIRK2's) at its
//! size, to the same tolerance. So a step taken in parts is the same method at the smaller
//! step there: as stable, and at least as accurate. The step still ends at `t + dt` and counts
//! as one step.
//!
//! Why it is needed: the step's equations approach the identity as the step shrinks, so Newton's
//! method converges on small enough steps. At large ones it can fail to find a solution:
//! - on a lattice crushed against a wall within the step;
//! - in a field far stronger than the springs that changes sign from cell to cell
//!   (`leapfrog.w`: 22 000 m/s², `h²·|∇f|/m` ≈ 50 at 1/60 s).
//!
//! The size is remembered from step to step, so a hard stretch does not pay for a failed
//! full-size try on every step. After [`COARSEN_AFTER`] substeps in a row succeed at one size,
//! the next one that starts on the coarser grid is tried at twice the size. A try that fails at
//! once doubles that count for the next try, up to [`COARSEN_AFTER_MAX`]. Substep sizes are
//! `dt` over powers of two and their ends are on that grid, so the times stay exact. Like the
//! friction anchors, the remembered size lives in the step's scratch: results depend on the
//! model and the steps taken since the scratch was made (never on threads), and a run resumed
//! from a saved state starts again at full size.

use crate::compute::team;
use crate::contact::friction::Anchors;
use crate::integrate::blow_up::{block_is_sound, unsound};
use crate::integrate::blow_up::{BlowUp, BlowUpCause};
use crate::integrate::implicit;
use crate::integrate::scratch::{accept, Scratch};
use crate::integrate::stability;
use crate::model::Model;
use crate::state::{Control, State};
use crate::vec3::Vec3;

/// Fewest points in a chunk of the test that a step's result is sound.
const SOUND_CHUNK: usize = 4096;

/// Substeps in a row that succeed at one size before twice the size is tried again.
pub const COARSEN_AFTER: u32 = 4;

/// The most that count grows to after tries that failed.
pub const COARSEN_AFTER_MAX: u32 = 256;

/// What cutbacks have done since the scratch was made: how often steps were taken in parts.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct CutbackStats {
    /// Steps taken as substeps.
    pub split_steps: u64,
    /// The substeps those steps were taken as.
    pub substeps: u64,
    /// Tries that failed and were taken again in halves.
    pub retries: u64,
    /// The most halvings a step needed: its smallest substep was `dt/2^finest`.
    pub finest: u32,
}

/// The cutback state carried from step to step, and the step's start to go back to.
#[derive(Clone, Debug)]
pub(crate) struct Cutback {
    /// Halvings the next substep is tried at.
    halvings: u32,
    /// Substeps in a row that succeeded at that size.
    streak: u32,
    /// Successes wanted before a coarser try.
    wanted: u32,
    /// The last substep was a coarser try.
    coarsened: bool,
    stats: CutbackStats,
    /// The step's start, saved before its first substep that is not the whole step.
    start_pos: Vec<Vec3>,
    start_vel: Vec<Vec3>,
    start_anchors: Anchors,
}

impl Default for Cutback {
    fn default() -> Self {
        Cutback {
            halvings: 0,
            streak: 0,
            wanted: COARSEN_AFTER,
            coarsened: false,
            stats: CutbackStats::default(),
            start_pos: Vec::new(),
            start_vel: Vec::new(),
            start_anchors: Anchors::default(),
        }
    }
}

impl Cutback {
    pub(crate) fn stats(&self) -> CutbackStats {
        self.stats
    }
}

/// One step of the model's implicit integrator, cut back where it fails (see the module's
/// documentation). On success the state holds the step's end, `time` has grown by `dt` and
/// `steps` by one; on failure the state is as it was.
pub(crate) fn step(
    model: &Model,
    state: &mut State,
    control: &Control,
    scratch: &mut Scratch,
) -> Result<(), BlowUp> {
    let n = model.point_count();
    let c = &mut scratch.cutback;
    // Sized on the first implicit step, so that a later cutback does not allocate.
    if c.start_pos.len() != n {
        c.start_pos.resize(n, Vec3::ZERO);
        c.start_vel.resize(n, Vec3::ZERO);
    }
    let most = model.newton.cutbacks;
    // The step in units of its smallest substep; `done` of them are taken.
    let whole = 1u64 << most;
    let (t_start, dt) = (state.time, model.dt);
    let time_at = |units: u64| {
        if units == whole {
            t_start + dt
        } else {
            t_start + dt * (units as f64 / whole as f64)
        }
    };
    let mut halvings = scratch.cutback.halvings.min(most);
    let (mut done, mut saved, mut finest) = (0u64, false, 0);
    while done < whole {
        if halvings > 0 && !saved {
            save(scratch, state);
            saved = true;
        }
        let units = whole >> halvings;
        let h = dt / (1u64 << halvings) as f64;
        let times = (time_at(done), time_at(done + units));
        let result = substep(model, state, control, scratch, h, times);
        let c = &mut scratch.cutback;
        match result {
            Ok(()) => {
                if halvings > 0 {
                    c.stats.substeps += 1;
                }
                done += units;
                finest = finest.max(halvings);
                if c.coarsened {
                    c.wanted = COARSEN_AFTER;
                    c.coarsened = false;
                }
                c.streak = c.streak.saturating_add(1);
                if halvings > 0 && c.streak >= c.wanted && done % (2 * units) == 0 {
                    halvings -= 1;
                    (c.streak, c.coarsened) = (0, true);
                }
            }
            Err(failure) if halvings == most => {
                (c.halvings, c.streak, c.coarsened) = (halvings, 0, false);
                let report = report(model, state, scratch, failure, halvings);
                if saved {
                    restore(scratch, state);
                }
                return Err(report);
            }
            Err(_) => {
                c.stats.retries += 1;
                if c.coarsened {
                    c.wanted = (2 * c.wanted).min(COARSEN_AFTER_MAX);
                    c.coarsened = false;
                }
                halvings += 1;
                c.streak = 0;
            }
        }
    }
    let c = &mut scratch.cutback;
    c.halvings = halvings;
    if finest > 0 {
        c.stats.split_steps += 1;
        c.stats.finest = c.stats.finest.max(finest);
    }
    state.time = t_start + dt;
    state.steps += 1;
    Ok(())
}

/// Why a substep failed.
enum Failure {
    NotConverged(implicit::NotConverged),
    /// Its result, in the scratch's buffers, is not sound.
    Unsound,
}

/// One substep of size `h` from the state at `t0` to `t1`, taken into the state when it is
/// sound.
fn substep(
    model: &Model,
    state: &mut State,
    control: &Control,
    s: &mut Scratch,
    h: f64,
    (t0, t1): (f64, f64),
) -> Result<(), Failure> {
    implicit::step(
        model,
        state,
        control,
        &mut s.force,
        &mut s.implicit,
        h,
        &mut s.next_pos,
        &mut s.next_vel,
    )
    .map_err(Failure::NotConverged)?;
    // In chunks over the team (where the step had one), as the anchors' update below.
    let (pos, vel) = (&s.next_pos[..], &s.next_vel[..]);
    let size = team::chunk_size(pos.len(), SOUND_CHUNK);
    let (sound, chunks) = team::map_chunks(pos.len(), size, &|at| {
        block_is_sound(model, &pos[at.clone()], &vel[at])
    });
    if sound[..chunks].contains(&false) {
        return Err(Failure::Unsound);
    }
    accept(model, state, s, t0, t1);
    Ok(())
}

/// The report of a step whose substep of `dt/2^halvings` failed; the state is still at the
/// step's start (its time and count are not advanced until the step ends). Made only for the
/// failure reported; a retry needs none.
fn report(model: &Model, state: &State, s: &Scratch, failure: Failure, halvings: u32) -> BlowUp {
    let e = match failure {
        Failure::Unsound => return unsound(model, state, &s.next_pos, &s.next_vel, model.dt),
        Failure::NotConverged(e) => e,
    };
    let (body, point_ijk) = model.locate(e.point);
    let h = model.dt / (1u64 << halvings) as f64;
    BlowUp {
        step: state.steps + 1,
        time: state.time,
        point: e.point,
        body: body as u32,
        point_ijk: point_ijk.map(|c| c as u32),
        cause: BlowUpCause::NotConverged {
            residual: e.residual,
            iterations: e.iterations,
            tolerance: model.newton.tolerance,
            halvings,
        },
        integrator: model.integrator,
        dt: model.dt,
        suggested_dt: Some(stability::round_down_2(0.5 * h)),
        escape_margin: model.escape_margin,
        sunk: crate::contact::tunnelling::deepest_sunk(model, &state.pos).map(Box::new),
    }
}

/// Saves the step's start: the state and the friction anchors.
fn save(s: &mut Scratch, state: &State) {
    let c = &mut s.cutback;
    c.start_pos.copy_from_slice(&state.pos);
    c.start_vel.copy_from_slice(&state.vel);
    c.start_anchors.copy_from(s.force.anchors());
}

/// Puts the saved start back.
fn restore(s: &mut Scratch, state: &mut State) {
    let c = &s.cutback;
    state.pos.copy_from_slice(&c.start_pos);
    state.vel.copy_from_slice(&c.start_vel);
    s.force.anchors_mut().copy_from(&c.start_anchors);
}
