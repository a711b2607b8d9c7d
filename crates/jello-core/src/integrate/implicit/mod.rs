//! The implicit integrators, stable at any time step: backward Euler, and SDIRK2, whose two
//! stages are each solved as a backward-Euler step from a point of their own (see `step` below);
//! what follows is about that solve.
//!
//! A step of size `h` finds the end velocity `v₁` with
//!
//! ```text
//! g(v₁) = v₁ − v₀ − h·M⁻¹·(f(x₀ + h·v₁) − D₀·v₁) = 0,        then x₁ = x₀ + h·v₁,
//! ```
//!
//! where `f` is every force of [`crate::forces`] but the dampers (springs, field, gravity, walls,
//! plane, obstacles, contacts between bodies, control forces, pulls), at the end positions, with
//! friction (the obstacles' ties, spring and damper, and sliding friction; between bodies,
//! sliding friction) at the end positions and velocities (`contacts.rs`), and `D₀·v₁` the
//! dampers' force: each spring's along its direction at the step's start, each wall's,
//! plane's and obstacle's along its normal for the points in contact at the step's start,
//! each contact's between bodies along the direction of the pair that overlapped then, each
//! pull's. Pinned and unused points keep their velocity. The dampers are taken at the start
//! because they switch on at a contact's surface with a jump of `dCollision·|v·n|`: taken at
//! the end, a point that reaches a surface during the step can have no solution at all
//! (friction has no such jump: its size grows from zero with the depth); and with their
//! directions fixed, the equations are the stationarity of the incremental potential
//! `½|v − v₀|²_M + ½h·vᵀD₀v + U(x₀ + h·v)` whenever the other forces have a potential `U`
//! (one body, no friction), which Newton's method can minimise. The scheme is first order; as
//! `h → 0` it agrees with the explicit integrators.
//!
//! Newton's method, from `v₀` (from rest for a body resting on a surface at a step long for its
//! contacts, `first_iterate`) shifted by each body's change of momentum where that lowers the
//! residual (`shift_by_momentum`): each iteration solves `A·Δv = −M·g` with
//! `A = M + h·D₀ + h²·K`, `K` the stiffness matrix of the springs (with a compressed spring's
//! negative transverse stiffness; when that leaves `A` not positive definite, the masses in `A`
//! are scaled up by a Levenberg–Marquardt shift until it is, and only when no shift up to ~40
//! will do is that stiffness clamped at zero), of the penalty springs the point is in at the
//! iterate (with friction along an obstacle's surface: a tie's spring and damper while it
//! holds, their sliding part once it slides, and sliding friction), of the contacts between
//! bodies at the iterate (each pair of overlapping balls a pushing spring, with its friction,
//! and a damper for each pair that overlapped at the step's start), of the pulls and of the
//! field (the symmetric part of minus its gradient, made positive
//! semi-definite), by conjugate gradients preconditioned with a multigrid cycle over aggregates
//! of the lattice (`multigrid/`; `A·x` itself runs in stencil order, `stencil/`). They
//! stop when their residual has fallen a hundredfold, or sooner where their linear model already
//! puts every point within half the tolerance. A step's first solve with an `A` kept from the
//! last steps starts from the best combination, in `A`'s norm, of their first solves'
//! directions rather than from zero (`cg/recycle.rs`): a body settling on a floor rings down in
//! a few slow modes. When the line search finds no way down
//! along a direction so found, the next is solved to 1e-8 (or only as far as the tolerance
//! needs: `enough_reduction`), unless that did not help: where `A` itself is inexact (sliding
//! friction ties, a shift), no solve is exact enough, and the reduction goes back to the last.
//! (Solving a hundredfold tighter after each Newton iteration that did not cut `|g|` tenfold,
//! as until 2026-11-27, cost more than it saved: see `newton`.) In Newton's fast regime (the last
//! iteration took its whole step, which cut `|g|_M` tenfold, with `A` Newton's own, and moved
//! no end position by more than 1e-4 of the shortest spring; in a uniform field or none) the
//! next iteration solves with the same `A` and multigrid: `A` has changed by about that
//! fraction, Newton's method still cuts `|g|` about a hundredfold per iteration (the conjugate
//! gradients' reduction), and the assembly and the multigrid's setup are saved (the 16³
//! benchmark at 1/60 s and 1e-9 steps 1.5× as fast). A step that ended so passes its `A` on to
//! the next step's first iteration, at the same step size, where no spring's ends move apart
//! faster than that regime allows (`keeps_across_steps`): a body settled on a floor steps
//! without assembling `A`. Then a backtracking line search on the
//! incremental potential (one body and no friction: the common case; a field that is not
//! uniform has no potential, and its work along the line is added instead), or on `|g|²_M`
//! otherwise; the potential's fall is computed term by term from differences, so that it stays
//! visible below the potential's own rounding. A full step that falls faster than its
//! quadratic model is extended while the potential keeps falling (a buckling lattice slides).
//! A full step that cuts `|g|_M` tenfold is taken as it is, without the merit's fall: Newton's
//! method is then in its fast regime.
//! The gradient's antisymmetric part (a field's swirl) is not in that `A`, and Newton's method
//! then gains at best its size over the masses (`h²·|swirl|/m`) per iteration. Where that
//! passes 1, `A` takes the field's exact gradient instead and GMRES (`gmres.rs`) solves with
//! it, judged by `|g|²_M`; `newton` says how the two take turns when one stalls. Only a field
//! that can swirl past that limit at the model's step has GMRES's basis allocated from the start
//! (its swirl is bounded once, from its nodes: [`crate::ForceField::max_swirl`]).
//! Friction that slides at its full size `μ·kc·depth` grows with the depth, which is not
//! symmetric either: after a Newton iteration outside the fast regime, `A` takes that growth at
//! the points where friction slides ([`friction::limit_growth`](crate::contact::friction)) and
//! GMRES solves with it (its basis held wherever friction may slide), which turns the linear
//! convergence of a lattice landing on a floor with friction back into Newton's.
//!
//! A step has converged when every point's residual `|g|` is at most [`TOLERANCE`](crate::model::solver::TOLERANCE) times
//! `max(1, max |v₁|)` (m/s; both settable, [`Model::newton`](crate::Model::newton)), or at most
//! the residual's rounding floor where that is larger (`rounding_floor`: stiff springs at large
//! steps); then, where nothing outside holds the moving points by where they are (no pin, pull,
//! field that varies in space, or surface touched), their mass-weighted mean residual is taken
//! out of their velocities (the exact solution has none), so internal forces conserve momentum
//! to rounding (`momentum_shift`). A step that does not
//! converge within [`MAX_NEWTON`](crate::model::solver::MAX_NEWTON) iterations (by default) returns the residual reached; the
//! caller ([`crate::integrate::cutback`]) then takes it again in halves, and reports it only at the
//! smallest size allowed, with the state back at the step's start.
//!
//! On lattices of 4 096 points or more a step runs on a team of threads that spin between its
//! loops (`compute/team.rs`): the force evaluations, `A·x`, the conjugate gradients' vector
//! updates and dot products, the assembly, most of the multigrid and the line search's merit
//! are split into items that each sum in a fixed order whoever computes them (their sums then
//! added in the items' order; the dot products' items are fixed by the number of points), and
//! the rest (the small coarse levels, a few pointwise passes) runs in order on the leading
//! thread; so results do not depend on the thread count. The buffers are sized on the first
//! implicit step and reused, so later steps do not allocate.
//!
//! Where the parts are: this file has the step (backward Euler's and SDIRK2's stages) and the
//! solver's tuning constants; `scratch.rs` its buffers ([`ImplicitScratch`]) and what each step
//! loads into them; `newton.rs` Newton's
//! iterations, the first iterate and the momentum shift, the line search and when a step has
//! converged;
//! `residual.rs` the residual `g` and the potential's fall; `contacts.rs` the contacts'
//! friction and the dampers between bodies in `g`; `matrix.rs` the assembly of `A`
//! and the Newton direction (with its Levenberg–Marquardt shift); `cg/` the conjugate
//! gradients and their sums on the team (`single.rs` the usual solves', their vectors in
//! single precision; `recycle.rs` a step's first solve's start); `multigrid/` their
//! preconditioner; `stencil/` `A·x` in stencil order;
//! `gmres.rs` the solve where a field swirls; `sym.rs` symmetric 3×3 blocks; `tests.rs` and
//! `test_models.rs` the parts' unit tests.

use crate::compute::team;
use crate::forces::ForceScratch;
use crate::model::integrator::Integrator;
use crate::model::Model;
use crate::state::{Control, State};
use crate::vec3::Vec3;

/// `A` itself, the finest level of the multigrid (its held points have zero rows), borrowed
/// field by field from an [`ImplicitScratch`] so that its other buffers stay free to change.
/// (Defined before the submodules, which use it too.)
macro_rules! fine_operator {
    ($s:expr) => {
        Operator {
            own: &$s.extra,
            pairs: &$s.spring_pairs,
            blocks: $s.springs.blocks_by_spring(),
            more_pairs: &$s.pair_rows,
            more_blocks: &$s.pair_blocks,
            diag_inv: &$s.diag_inv,
            free: Some(&$s.free),
        }
    };
}

/// The finest level as the preconditioner takes it: its diagonal blocks (inverted) and held
/// points, without the springs' blocks, so that a solve's products may borrow those mutably
/// meanwhile (the preconditioner reads only the coarse levels' operators).
macro_rules! fine_diagonal {
    ($s:expr) => {
        Operator {
            own: &$s.extra,
            pairs: &[],
            blocks: $crate::integrate::implicit::multigrid::Blocks::Listed(&[]),
            more_pairs: &[],
            more_blocks: &[],
            diag_inv: &$s.diag_inv,
            free: Some(&$s.free),
        }
    };
}

mod cg;
mod contacts;
mod gmres;
mod matrix;
mod multigrid;
mod newton;
mod residual;
mod scratch;
mod stencil;
mod sym;
#[cfg(test)]
pub(crate) mod test_models;
#[cfg(test)]
mod tests;

use matrix::can_swirl;
use newton::{momentum_shift, newton};
pub use scratch::ImplicitScratch;
use scratch::Row;
use stencil::Precision;

/// Conjugate-gradient iterations per Newton iteration, at most.
const MAX_CG: usize = 2000;

/// Conjugate gradients stop when the residual of `A·Δv = −M·g` has fallen by this factor.
const CG_REDUCTION: f64 = 1e-2;

/// Solves asked for a reduction below this take their products with `A` in double precision;
/// the others in single precision (see `stencil.rs`), whose rounding (a relative 6e-8 of each
/// block, times the condition of `A`) would be a visible part of what an exact solve solves for.
const SINGLE_PRECISION_REDUCTION: f64 = 1e-4;

/// The precision of the products with `A` of a solve to `reduction`.
fn precision_for(reduction: f64) -> Precision {
    if reduction < SINGLE_PRECISION_REDUCTION {
        Precision::Double
    } else {
        Precision::Single
    }
}

/// The factor they reach after a line search found no way down along an inexact direction (or
/// less, where that meets the tolerance: [`enough_reduction`](newton::enough_reduction)).
const CG_REDUCTION_EXACT: f64 = 1e-8;

/// A field's swirl (the antisymmetric part of its gradient, times `h²/m`) above which `A`
/// takes it too, and GMRES solves for the Newton direction instead of conjugate gradients.
/// Left out of a symmetric `A`, the swirl makes Newton's method converge no faster than this
/// ratio per iteration, so not at all past 1. Below 1 the symmetric `A` is kept: with the
/// potential as the merit it is the more robust (at 0.1, a scene with friction ties and a swirl
/// of 0.7 stalled near the solution with the swirl in `A`, and converged without it).
const SWIRL_LIMIT: f64 = 1.0;

/// Newton iterations in a row that do not halve `|g|²_M` below its best, where a field swirls,
/// before Newton's method changes between `A` with and without the swirl (see
/// [`newton`](fn@newton)).
const SWIRL_STALLS: u32 = 5;

/// Changes between `A` with and without the swirl, at most, in a step.
const SWIRL_SWITCHES: u32 = 6;

/// How far (times the shortest spring's rest length) the end positions may have moved in a
/// Newton iteration in its fast regime for the next one to solve with the same `A` (see
/// [`newton`](fn@newton)): a spring's block changes by about that fraction. At 1e-3, `world.w`'s
/// solves with a kept `A` (kElastic 8000, 1/60 s) took 31–34 conjugate-gradient iterations instead
/// of 21–23, which cost more than the assembly saved (10 % slower); at 1e-4 it is 5 % faster than
/// with no `A` kept, and the 16³ benchmark as fast as at 1e-3.
const KEEP_MOVE: f64 = 1e-4;

/// How far (times the shortest spring's rest length) a body touching a surface may move in a
/// step at its start velocities for Newton's method to start it from rest, where the step is
/// long for the stiffest point (see `newton::first_iterate`). The resting and dropped 32³ cubes
/// at 1/60 s stepped as fast from 0.1 to 10; 0.1 leaves any body that moves on its `v₀`.
const REST_MOVE: f64 = 0.1;

/// The least `h²·K/m` (the stiffest point's, [`ImplicitScratch::stiffness_over_mass`]) at which
/// a body at rest on a surface starts Newton's method from rest: the frame-rate jobs have
/// 1e3 (8³) to 2e5 (64³) at 1/60 s, the examples at their own steps 2–15.
const REST_STIFFNESS: f64 = 100.0;

/// Fewest points in a chunk of a loop over points spread over threads ([`chunk_size`]):
/// smaller ones cost more to hand out than they save.
const MIN_CHUNK: usize = 1024;

/// Points per chunk of a loop over `n` points spread over the team.
fn chunk_size(n: usize) -> usize {
    team::chunk_size(n, MIN_CHUNK)
}

/// Halvings of the Newton step before the line search gives up.
const MAX_HALVINGS: u32 = 30;

/// Doublings of a Newton step that falls faster than its model, at most.
const MAX_EXPANSIONS: u32 = 10;

/// Why a step did not converge: the residual reached (m/s), where, and the Newton iterations
/// taken.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct NotConverged {
    /// `max |g|` at the last iterate (m/s).
    pub residual: f64,
    /// The point (flat index) with that residual.
    pub point: usize,
    /// Newton iterations taken.
    pub iterations: u32,
}

/// The work the implicit solver has done since its scratch was made, failed tries included:
/// what a step costs, and why (`jello bench` and `jello run` report it per step).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct SolverStats {
    /// Backward-Euler solves: one a step of backward Euler, two of SDIRK2 (its stages), more
    /// where a step was taken in parts (see [`crate::integrate::cutback`]).
    pub solves: u64,
    /// Newton iterations, over all the solves.
    pub newton_iterations: u64,
    /// Conjugate-gradient (or GMRES) iterations, over all the Newton iterations: each one
    /// product `A·x` and one multigrid cycle.
    pub linear_iterations: u64,
    /// Times `A` was assembled and its multigrid set up: fewer than the Newton iterations where
    /// Newton's method in its fast regime kept `A`, more where `A` was not positive definite
    /// and was assembled again with a Levenberg–Marquardt shift.
    pub assemblies: u64,
}

impl std::ops::Sub for SolverStats {
    type Output = SolverStats;

    /// The work done between two readings (`later − earlier`).
    fn sub(self, earlier: SolverStats) -> SolverStats {
        SolverStats {
            solves: self.solves - earlier.solves,
            newton_iterations: self.newton_iterations - earlier.newton_iterations,
            linear_iterations: self.linear_iterations - earlier.linear_iterations,
            assemblies: self.assemblies - earlier.assemblies,
        }
    }
}

/// SDIRK2's implicit coefficient `γ = 1 − √2/2`: each stage is a backward-Euler step of size
/// `γ·h` (the value that makes the method L-stable and of order 2).
pub const SDIRK2_GAMMA: f64 = 1.0 - 0.5 * std::f64::consts::SQRT_2;

/// The second stage starts from `y₀ + c·(Y₁ − y₀)`, `c = (1 − γ)/γ = 1 + √2`.
pub const SDIRK2_C: f64 = (1.0 - SDIRK2_GAMMA) / SDIRK2_GAMMA;

/// One step of size `h` (the model's `dt`, or a part of it where a step is cut back: see
/// [`crate::integrate::cutback`]) of the model's implicit integrator from `state` into `next_pos` and
/// `next_vel` (not checked for soundness here). `Err` when Newton's method did not converge.
///
/// SDIRK2 (Alexander 1977; `y = (x, v)`, `F(y) = (v, M⁻¹·(f(x) − D·v))`): the stage
/// `Y₁ = y₀ + γh·F(Y₁)`, a backward-Euler step of size `γh`; then `y₁ = y₀ + (1 − γ)h·F(Y₁) +
/// γh·F(y₁)`, which, as `γh·F(Y₁) = Y₁ − y₀`, is a backward-Euler step of size `γh` from
/// `y₀ + c·(Y₁ − y₀)`. No force is evaluated outside the solves, and every solve is the
/// minimisation below, so the stages are as robust as backward Euler's step. The dampers `D`
/// are taken for the whole step at `x₀ + (h/2)·v₀`, the step's predicted middle, which keeps the
/// method second order where the dampers turn with the springs.
#[allow(clippy::too_many_arguments)]
pub(crate) fn step(
    model: &Model,
    state: &State,
    control: &Control,
    force: &mut ForceScratch,
    s: &mut ImplicitScratch,
    h: f64,
    next_pos: &mut [Vec3],
    next_vel: &mut [Vec3],
) -> Result<(), NotConverged> {
    // The step's many short parallel loops run on a team whose threads spin between them,
    // where the products with `A` are split over threads at all.
    let mut on_team = || step_on_team(model, state, control, force, s, h, next_pos, next_vel);
    if model.point_count() < 2 * stencil::MIN_POINTS_PER_RANGE {
        return on_team();
    }
    team::run(on_team)
}

/// [`step`], on its team (if any).
#[allow(clippy::too_many_arguments)]
fn step_on_team(
    model: &Model,
    state: &State,
    control: &Control,
    force: &mut ForceScratch,
    s: &mut ImplicitScratch,
    h: f64,
    next_pos: &mut [Vec3],
    next_vel: &mut [Vec3],
) -> Result<(), NotConverged> {
    if !s.fits(model) {
        let stats = s.stats;
        *s = ImplicitScratch::new(model);
        s.stats = stats;
    }
    s.load(model);
    let swirls = can_swirl(model, h);
    s.springs.pack_products(!swirls);
    s.multigrid.start_step(swirls);
    let (x0, v0) = (&state.pos[..], &state.vel[..]);
    if model.integrator != Integrator::Sdirk2 {
        s.start_dampers(model, x0);
        return backward_euler(
            model, control, force, s, x0, v0, h, swirls, next_pos, next_vel,
        );
    }
    let k = SDIRK2_GAMMA * h;
    // The second stage's start lives in buffers taken out of the scratch while it is solved from.
    let (mut bx, mut bv) = (std::mem::take(&mut s.base_x), std::mem::take(&mut s.base_v));
    for ((b, &x), &v) in bx.iter_mut().zip(x0).zip(v0) {
        *b = x + v * (0.5 * h);
    }
    s.start_dampers(model, &bx);
    let first = backward_euler(
        model, control, force, s, x0, v0, k, swirls, next_pos, next_vel,
    );
    if first.is_ok() {
        for ((((bx, bv), (&x1, &v1)), &x), &v) in bx
            .iter_mut()
            .zip(bv.iter_mut())
            .zip(next_pos.iter().zip(next_vel.iter()))
            .zip(x0)
            .zip(v0)
        {
            *bx = x + (x1 - x) * SDIRK2_C;
            *bv = v + (v1 - v) * SDIRK2_C;
        }
    }
    let result = first.and_then(|()| {
        backward_euler(
            model, control, force, s, &bx, &bv, k, swirls, next_pos, next_vel,
        )
    });
    (s.base_x, s.base_v) = (bx, bv);
    result
}

/// One backward-Euler step of size `h` from `(x0, v0)` into `next_pos` and `next_vel`, the
/// scratch loaded and its dampers set; `swirls` as [`can_swirl`] says of the integrator's step.
#[allow(clippy::too_many_arguments)]
fn backward_euler(
    model: &Model,
    control: &Control,
    force: &mut ForceScratch,
    s: &mut ImplicitScratch,
    x0: &[Vec3],
    v0: &[Vec3],
    h: f64,
    swirls: bool,
    next_pos: &mut [Vec3],
    next_vel: &mut [Vec3],
) -> Result<(), NotConverged> {
    newton(model, control, force, s, x0, v0, h, swirls)?;
    // The exact solution has Σ m·g = 0 over the moving points (their momentum changes by h
    // times the force on them, which internal forces do not change): take the small mean
    // residual the tolerance allows out of their velocities, so that internal forces conserve
    // momentum to rounding rather than to the tolerance (`momentum_shift`: only where nothing
    // outside holds them by where they are).
    let shift = momentum_shift(model, control, s, x0, h);
    let (v, free, size) = (&s.v[..], &s.free[..], chunk_size(s.v.len()));
    team::for_each_chunk([next_pos, next_vel], size, &|c, [next_pos, next_vel]| {
        let at = c * size;
        for (i, (np, nv)) in next_pos.iter_mut().zip(next_vel).enumerate() {
            let v = v[at + i] - shift * free[at + i];
            *np = x0[at + i] + v * h;
            *nv = v;
        }
    });
    Ok(())
}
