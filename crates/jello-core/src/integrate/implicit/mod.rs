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
//! Newton's method, from `v₀` shifted by each body's change of momentum where that lowers the
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
//! of the lattice (`multigrid.rs`; `A·x` itself runs in stencil order, `stencil.rs`). They
//! stop when their residual has fallen a hundredfold, or sooner where their linear model already
//! puts every point within half the tolerance. When the line search finds no way down
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
//! that can swirl past that limit at the model's step has GMRES's basis allocated (its swirl is
//! bounded once, from its nodes: [`crate::ForceField::max_swirl`]).
//!
//! A step has converged when every point's residual `|g|` is at most [`TOLERANCE`](crate::model::solver::TOLERANCE) times
//! `max(1, max |v₁|)` (m/s; both settable, [`Model::newton`](crate::Model::newton)), or at most
//! the residual's rounding floor where that is larger (`rounding_floor`: stiff springs at large
//! steps); then the
//! mass-weighted mean residual of the moving points is taken out of their velocities (the exact
//! solution has none), so internal forces conserve momentum to rounding. A step that does not
//! converge within [`MAX_NEWTON`](crate::model::solver::MAX_NEWTON) iterations (by default) returns the residual reached; the
//! caller ([`crate::integrate::cutback`]) then takes it again in halves, and reports it only at the
//! smallest size allowed, with the state back at the step's start.
//!
//! On lattices of 4 096 points or more a step runs on a team of threads that spin between its
//! loops ([`crate::compute::team`]): the force evaluations, `A·x`, the conjugate gradients' vector
//! updates and dot products, the assembly, most of the multigrid and the line search's merit
//! are split into items that each sum in a fixed order whoever computes them (their sums then
//! added in the items' order; the dot products' items are fixed by the number of points), and
//! the rest (the small coarse levels, a few pointwise passes) runs in order on the leading
//! thread; so results do not depend on the thread count. The buffers are sized on the first
//! implicit step and reused, so later steps do not allocate.
//!
//! Where the parts are: this file has the step (backward Euler's and SDIRK2's stages), its
//! buffers ([`ImplicitScratch`]) and the solver's tuning constants; `newton.rs` Newton's
//! iterations, the momentum shift, the line search and when a step has converged;
//! `residual.rs` the residual `g` and the potential's fall; `contacts.rs` the contacts'
//! friction and the dampers between bodies in `g`; `matrix.rs` the assembly of `A`
//! and the Newton direction (with its Levenberg–Marquardt shift); `cg.rs` the conjugate
//! gradients and their sums on the team; `multigrid.rs` their preconditioner; `stencil.rs`
//! `A·x` and the forces in stencil order; `gmres.rs` the solve where a field swirls; `sym.rs`
//! symmetric 3×3 blocks.

use crate::compute::soa::Soa;
use crate::compute::team;
use crate::contact::Contacts;
use crate::forces::ForceScratch;
use crate::model::body::Body;
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
            blocks: &$s.spring_blocks,
            more_pairs: &$s.pair_rows,
            more_blocks: &$s.pair_blocks,
            diag_inv: &$s.diag_inv,
            free: Some(&$s.free),
            incidence: None,
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
mod stencil;
mod sym;

use cg::sum_chunks;
use contacts::StartPair;
use gmres::Gmres;
use matrix::can_swirl;
use multigrid::Multigrid;
use newton::{mean_residual, newton};
use residual::fall_chunks;
use stencil::{Precision, SpringMatrix};
use sym::{add_outer, Sym};

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

/// One spring as the solver needs it: its ends (flat indices of the model), rest length,
/// stiffness and damping.
#[derive(Clone, Copy, Debug, Default)]
struct Row {
    a: u32,
    b: u32,
    rest: f64,
    k: f64,
    d: f64,
}

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

/// The buffers of the implicit solver, sized on its first step for a model.
#[derive(Clone, Debug, Default)]
pub struct ImplicitScratch {
    /// The work done so far (kept when the buffers are sized anew).
    stats: SolverStats,
    rows: Vec<Row>,
    /// The springs as the bodies list them, before they are put in slot order.
    listed_rows: Vec<Row>,
    /// The bodies whose springs are listed (none before the first step).
    loaded: Option<Vec<Body>>,
    /// The springs' ends, and each spring's block of `A` at the iterate (see
    /// [`Operator`](multigrid::Operator)): `axial·ûûᵀ + transverse·(I − ûûᵀ)` of its stiffness plus
    /// `damping·û₀û₀ᵀ` of its damper along its direction at the step's start.
    spring_pairs: Vec<[u32; 2]>,
    spring_blocks: Vec<Sym>,
    /// The same blocks by stencil slot, for `A·x`.
    springs: SpringMatrix,
    /// Each spring's direction at the step's start (zero for a spring of zero length).
    start_dir: Vec<Vec3>,
    /// The field's force on each point at the iterate's and the trial's end positions (for the
    /// line search; see `residual::field_work`).
    field: Vec<Vec3>,
    field_trial: Vec<Vec3>,
    /// Per point: mass (kg), and 1 for a point that moves, 0 for one pinned or unused.
    mass: Vec<f64>,
    free: Vec<f64>,
    /// The masses and moving points of the last step (an `A` kept from it has its masses).
    last_mass: Vec<f64>,
    last_free: Vec<f64>,
    /// Per point: the stiffness of its springs, summed (N/m); and the largest of that plus the
    /// contacts' over the mass among the moving points (1/s², see `newton::rounding_floor`).
    point_stiffness: Vec<f64>,
    stiffness_over_mass: f64,
    /// The shortest rest length of a spring of the model (m; zero when it has none): the scale
    /// of a move that changes `A` (see [`KEEP_MOVE`]).
    shortest_spring: f64,
    /// The step size whose last Newton iteration left `A` fit to keep for the next step's first
    /// (see `newton::keeps_across_steps`); `None` once the model's springs, masses or held points
    /// change, and after a step that did not converge.
    keep_across: Option<f64>,
    /// Newton iterations that kept the last one's `A`, and whether they may (tests only).
    #[cfg(test)]
    kept: u32,
    #[cfg(test)]
    may_keep: bool,
    /// Steps whose first Newton iteration kept the last step's `A` (tests only).
    #[cfg(test)]
    kept_across: u32,
    /// Per point: the damping matrix `dCollision·Σ n nᵀ` of the walls, plane and obstacles it is
    /// in at the step's start.
    start_damping: Vec<Sym>,
    /// The dampers between bodies: the pairs of points that overlap at the step's start.
    start_pairs: Vec<StartPair>,
    /// Per point: the walls', plane's, obstacles' and pulls' part of `A`, then the inverse of the
    /// diagonal block.
    extra: Vec<Sym>,
    diag_inv: Vec<Sym>,
    /// The iterate and its trial along the Newton direction.
    v: Vec<Vec3>,
    trial: Vec<Vec3>,
    /// Residuals of the iterate and the trial.
    g: Vec<Vec3>,
    g_trial: Vec<Vec3>,
    /// Conjugate gradients: the solution, residual, preconditioned residual, direction and
    /// `A` times the direction.
    dv: Vec<Vec3>,
    r: Vec<Vec3>,
    z: Vec<Vec3>,
    p: Vec<Vec3>,
    ap: Vec<Vec3>,
    /// SDIRK2: the start of its second stage (positions, velocities).
    base_x: Vec<Vec3>,
    base_v: Vec<Vec3>,
    /// The force routine's inputs and output.
    x_soa: Soa,
    v_soa: Soa,
    acc: Soa,
    /// Contacts between bodies at the iterate, for `A`: the pairs of points in contact and
    /// their blocks (a penalty spring's, as a spring's block is), found through a contact pass of
    /// their own.
    contacts: Contacts,
    pair_rows: Vec<[u32; 2]>,
    pair_blocks: Vec<Sym>,
    /// The coarse levels of `A` for the conjugate gradients' preconditioner, and whether the
    /// last solve stopped because their cycle was not positive definite.
    multigrid: Multigrid,
    multigrid_failed: bool,
    /// Where a solve may stop however little its residual fell: once its residual `r = −M·g′`
    /// (the linear model's) is within `m·within` at every point (m/s; half the Newton
    /// iteration's target, 0 for none).
    within: f64,
    /// A field that may swirl past the limit ([`can_swirl`]): per point, the part of `A` that
    /// its exact gradient adds to the symmetric, positive semi-definite stiffness in `extra` (a
    /// general 3×3, row-major); used when `swirl` is set.
    field_correction: Vec<[f64; 9]>,
    /// True when the field's swirl at the iterate passes [`SWIRL_LIMIT`] and `swirl_allowed`
    /// (see [`newton`](fn@newton)): `A` is not symmetric then, and GMRES (with its basis here)
    /// solves in place of conjugate gradients.
    swirl: bool,
    swirl_allowed: bool,
    gmres: Gmres,
    /// [`potential_fall`](fn@residual::potential_fall)'s sums over each chunk of
    /// `residual::FALL_CHUNK` points and springs.
    falls: Vec<[f64; 3]>,
    /// The conjugate gradients' sums over each chunk of [`sum_chunk`](cg::sum_chunk) points: of a
    /// product ([`dot`](cg::dot)), and of `r·r` with whether `r` is within its bound there
    /// ([`advance`](cg::advance)).
    dots: Vec<f64>,
    advanced: Vec<(f64, bool)>,
}

impl ImplicitScratch {
    /// The trial point `v + α·Δv`.
    fn set_trial(&mut self, alpha: f64) {
        for ((t, &v), &dv) in self.trial.iter_mut().zip(&self.v).zip(&self.dv) {
            *t = v + dv * alpha;
        }
    }

    /// The trial point (with its residual and field) becomes the iterate.
    fn take_trial(&mut self) {
        std::mem::swap(&mut self.v, &mut self.trial);
        std::mem::swap(&mut self.g, &mut self.g_trial);
        std::mem::swap(&mut self.field, &mut self.field_trial);
    }

    /// The work done so far.
    pub(crate) fn stats(&self) -> SolverStats {
        self.stats
    }

    fn fits(&self, model: &Model) -> bool {
        let n = model.point_count();
        self.mass.len() == n
            && self.contacts.fits(model)
            && self.springs.fits(model)
            && (!can_swirl(model, model.dt)
                || (self.gmres.fits(n) && self.field_correction.len() == n))
    }

    fn new(model: &Model) -> Self {
        let n = model.point_count();
        // A step cut back is shorter than `dt`, so swirls less.
        let swirls = can_swirl(model, model.dt);
        let several = model.bodies().len() > 1;
        let zeros = vec![Vec3::ZERO; n];
        ImplicitScratch {
            stats: SolverStats::default(),
            rows: Vec::with_capacity(model.spring_count()),
            listed_rows: Vec::with_capacity(model.spring_count()),
            loaded: None,
            spring_pairs: Vec::with_capacity(model.spring_count()),
            spring_blocks: Vec::with_capacity(model.spring_count()),
            springs: SpringMatrix::new(model),
            start_dir: Vec::with_capacity(model.spring_count()),
            field: zeros.clone(),
            field_trial: zeros.clone(),
            mass: vec![0.0; n],
            last_mass: vec![0.0; n],
            last_free: vec![0.0; n],
            within: 0.0,
            free: vec![0.0; n],
            point_stiffness: vec![0.0; n],
            stiffness_over_mass: 0.0,
            shortest_spring: 0.0,
            #[cfg(test)]
            kept: 0,
            #[cfg(test)]
            may_keep: true,
            #[cfg(test)]
            kept_across: 0,
            keep_across: None,
            start_damping: vec![[0.0; 6]; n],
            start_pairs: Vec::with_capacity(if several { 8 * n } else { 0 }),
            extra: vec![[0.0; 6]; n],
            diag_inv: vec![[0.0; 6]; n],
            v: zeros.clone(),
            trial: zeros.clone(),
            g: zeros.clone(),
            g_trial: zeros.clone(),
            dv: zeros.clone(),
            r: zeros.clone(),
            z: zeros.clone(),
            p: zeros.clone(),
            ap: zeros.clone(),
            base_x: zeros.clone(),
            base_v: zeros,
            x_soa: Soa::zeros(n),
            v_soa: Soa::zeros(n),
            acc: Soa::zeros(n),
            contacts: Contacts::new(model),
            // Room for 8 contacts a point (two lattices of the same spacing touch at most 8
            // points of the other) at the iterate, and as many dampers from the step's start,
            // so stepping does not allocate.
            pair_rows: Vec::with_capacity(if several { 16 * n } else { 0 }),
            pair_blocks: Vec::with_capacity(if several { 16 * n } else { 0 }),
            multigrid: Multigrid::default(),
            multigrid_failed: false,
            field_correction: vec![[0.0; 9]; if swirls { n } else { 0 }],
            swirl: false,
            swirl_allowed: false,
            gmres: if swirls {
                Gmres::new(n)
            } else {
                Gmres::default()
            },
            // Sized with the springs, by `list_springs`.
            falls: Vec::new(),
            dots: vec![0.0; sum_chunks(n)],
            advanced: vec![(0.0, false); sum_chunks(n)],
        }
    }

    /// The model's springs, masses and free points, read every step (a model may change between
    /// steps without changing its size). The springs are listed again only when a body's
    /// springs may have changed (see [`Body::has_springs_of`]): listing them is a tenth of a
    /// step of the 16³ benchmark at 1/60 s and 1e-3 m/s.
    fn load(&mut self, model: &Model) {
        let same = self.loaded.as_ref().is_some_and(|loaded| {
            loaded.len() == model.bodies().len()
                && loaded
                    .iter()
                    .zip(model.bodies())
                    .all(|(a, b)| a.has_springs_of(b))
        });
        if !same {
            self.list_springs(model);
            self.loaded = Some(model.bodies().to_vec());
        }
        std::mem::swap(&mut self.mass, &mut self.last_mass);
        std::mem::swap(&mut self.free, &mut self.last_free);
        for body in model.bodies() {
            let first = body.points().start;
            for q in 0..body.len() {
                self.mass[first + q] = body.material.mass;
                self.free[first + q] = if body.is_active(q) { 1.0 } else { 0.0 };
            }
        }
        for &p in &model.pins {
            self.free[p as usize] = 0.0;
        }
        if self.mass != self.last_mass || self.free != self.last_free {
            self.keep_across = None;
        }
        // Penalty springs: three walls, the plane and each obstacle at once, at most.
        let contacts = (4 + model.obstacles.len()) as f64 * model.k_collision;
        self.stiffness_over_mass = self
            .point_stiffness
            .iter()
            .zip(&self.mass)
            .zip(&self.free)
            .filter(|&(_, &free)| free != 0.0)
            .map(|((&k, &m), _)| (k + contacts) / m)
            .fold(0.0, f64::max);
    }

    /// The model's springs as the bodies list them, into the springs' slot order (see
    /// `SpringMatrix`), with what follows from them: their pairs, each point's stiffness, the
    /// multigrid's levels.
    fn list_springs(&mut self, model: &Model) {
        self.keep_across = None;
        self.listed_rows.clear();
        self.springs.begin();
        for body in model.bodies() {
            let first = body.points().start;
            body.for_each_spring_entry(|s, entry| {
                self.springs.push(first + s.a, entry);
                self.listed_rows.push(Row {
                    a: (first + s.a) as u32,
                    b: (first + s.b) as u32,
                    rest: s.rest,
                    k: s.stiffness,
                    d: s.damping,
                })
            });
        }
        self.springs.finish();
        self.rows.resize(self.listed_rows.len(), Row::default());
        for (j, row) in self.listed_rows.iter().enumerate() {
            self.rows[self.springs.rank(j)] = *row;
        }
        for (s, r) in self.rows.iter().enumerate() {
            self.springs.set_spring(s, r.rest, r.k, r.d);
        }
        self.spring_pairs.clear();
        self.spring_pairs
            .extend(self.rows.iter().map(|r| [r.a, r.b]));
        self.spring_blocks.resize(self.rows.len(), [0.0; 6]);
        self.start_dir.resize(self.rows.len(), Vec3::ZERO);
        self.falls
            .resize(fall_chunks(self.mass.len(), self.rows.len()), [0.0; 3]);
        self.shortest_spring = self
            .rows
            .iter()
            .map(|r| r.rest)
            .filter(|&rest| rest > 0.0)
            .fold(f64::INFINITY, f64::min);
        if self.shortest_spring == f64::INFINITY {
            self.shortest_spring = 0.0;
        }
        self.point_stiffness.fill(0.0);
        for r in &self.rows {
            self.point_stiffness[r.a as usize] += r.k;
            self.point_stiffness[r.b as usize] += r.k;
        }
        self.multigrid
            .build(model, &self.spring_pairs, self.pair_rows.capacity());
    }

    /// The dampers at `x0` (the step's start): the springs' directions (also into the stencil
    /// matrix, whose product gives the dampers' force in each residual), the contacts each
    /// point is in, and the pairs of points of different bodies that overlap.
    fn start_dampers(&mut self, model: &Model, x0: &[Vec3]) {
        if model.bodies().len() > 1 {
            let [xx, xy, xz] = self.x_soa.parts_mut();
            for (i, p) in x0.iter().enumerate() {
                (xx[i], xy[i], xz[i]) = (p.x, p.y, p.z);
            }
            let (contacts, pairs) = (&mut self.contacts, &mut self.start_pairs);
            contacts::start_pairs(model, contacts, &self.x_soa, &self.v_soa, pairs);
        } else {
            self.start_pairs.clear();
        }
        self.springs.start_dampers(x0, &mut self.start_dir);
        for ((d, &p), &free) in self.start_damping.iter_mut().zip(x0).zip(&self.free) {
            *d = [0.0; 6];
            if free == 0.0 {
                continue;
            }
            for c in model.contacts(p) {
                add_outer(d, c.normal, model.d_collision);
            }
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
    // momentum to rounding rather than to the tolerance.
    let shift = mean_residual(s, 0..s.g.len());
    for ((((np, nv), &x), &v), &free) in next_pos
        .iter_mut()
        .zip(next_vel.iter_mut())
        .zip(x0)
        .zip(&s.v)
        .zip(&s.free)
    {
        let v = v - shift * free;
        *np = x + v * h;
        *nv = v;
    }
    Ok(())
}

/// Models and values for the unit tests of the solver's parts.
#[cfg(test)]
mod test_models {
    use crate::model::body::{rotation_xyz, Body, Material};
    use crate::model::lattice::Lattice;
    use crate::model::{Model, ModelBuilder};
    use crate::vec3::Vec3;

    /// A small deterministic generator of test values in [−1, 1).
    pub fn values(seed: u64) -> impl FnMut() -> f64 {
        let mut x = seed;
        move || {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (x >> 11) as f64 / (1u64 << 52) as f64 - 1.0
        }
    }

    /// A body of `points` lattice points (unit spacing) whose cells are kept where the values
    /// of `seed` exceed `above`, the rest holes.
    pub fn with_holes(points: [usize; 3], seed: u64, above: f64) -> Body {
        let mut next = values(seed);
        let cells = points.iter().map(|n| n - 1).product::<usize>();
        let cells = (0..cells).map(|_| next() > above).collect();
        let lattice = Lattice::new(points, Vec3::new(1.0, 1.0, 1.0));
        Body::from_cells(lattice, cells, Material::classic()).unwrap()
    }

    /// A full box of `points` lattice points (unit spacing) with its first corner at `at`.
    pub fn box_at(points: [usize; 3], at: Vec3) -> Body {
        let lattice = Lattice::new(points, Vec3::new(1.0, 1.0, 1.0));
        Body::lattice_box(lattice, Material::classic()).placed(at, rotation_xyz([0.0; 3]))
    }

    /// Two bodies, one with holes, one with an axis of a single point.
    pub fn two_bodies() -> Model {
        let holes = with_holes([6, 5, 7], 7, -0.6);
        let flat = box_at([4, 1, 5], Vec3::new(3.0, 0.0, 0.0));
        ModelBuilder::new()
            .bodies(vec![holes, flat])
            .build()
            .unwrap()
    }
}

#[cfg(test)]
mod tests {
    use super::cg::{advance, apply_to, dot, sum_chunk};
    use super::matrix::{assemble, Curvature};
    use super::newton::{enough_reduction, max_norms, shift_by_momentum};
    use super::residual::residual;
    use super::test_models::values;
    use super::*;
    use crate::model::body::{Body, Material};
    use crate::model::field::ForceField;
    use crate::model::lattice::Lattice;
    use crate::model::solver::TOLERANCE;
    use crate::model::{Aabb, ModelBuilder};

    /// A solve stopped at `enough_reduction` leaves every moving point's residual within the
    /// tolerance however the linear model's residual falls, even all on the lightest point;
    /// held points and the scale of `g` do not change that.
    #[test]
    fn enough_reduction_bounds_every_points_residual() {
        let model = test_models::two_bodies();
        let mut s = ImplicitScratch::new(&model);
        let mut next = values(11);
        for (p, ((g, m), free)) in s.g.iter_mut().zip(&mut s.mass).zip(&mut s.free).enumerate() {
            *g = Vec3::new(next(), next(), next()) * 1e3;
            *m = 0.01 + (1.0 + next());
            *free = if p % 7 == 3 { 0.0 } else { 1.0 };
        }
        // A held point's large residual and small mass count for nothing.
        s.g[3] = Vec3::new(1e9, 0.0, 0.0);
        s.mass[3] = 1e-6;
        let target = 1e-9;
        let reduction = enough_reduction(&s, target);
        let moving = || (0..s.g.len()).filter(|&p| s.free[p] != 0.0);
        let norm = moving()
            .map(|p| (s.mass[p] * s.g[p]).dot(s.mass[p] * s.g[p]))
            .sum::<f64>()
            .sqrt();
        let lightest = moving().map(|p| s.mass[p]).fold(f64::INFINITY, f64::min);
        // The worst case: the whole remaining residual `reduction·|M·g|` at the lightest point.
        let worst = reduction * norm / lightest;
        assert!(
            worst <= 0.5 * target * (1.0 + 1e-12),
            "{worst:e} > {target:e} / 2"
        );
        assert!(
            worst >= 0.5 * target * (1.0 - 1e-12),
            "{worst:e}: needlessly tight"
        );
        assert_eq!(
            enough_reduction(&ImplicitScratch::new(&model), target),
            0.0,
            "g = 0"
        );
    }

    /// A solve may stop once its residual is within `m·within` at every point, each point
    /// judged by its own mass: not while one point is over, not without a bound. (A step of
    /// length 0 leaves `r` as set here.)
    #[test]
    fn each_point_within_judges_every_point_by_its_mass() {
        let model = test_models::two_bodies();
        let mut s = ImplicitScratch::new(&model);
        let mut next = values(5);
        s.within = 1e-9;
        for (r, m) in s.r.iter_mut().zip(&mut s.mass) {
            *m = 0.01 + (1.0 + next());
            // Each point's residual at 0.99 of its own bound, in a random direction.
            let d = Vec3::new(next(), next(), next());
            *r = d * (0.99 * *m * s.within / d.length());
        }
        let each_point_within = |s: &mut ImplicitScratch| advance(s, 0.0).1;
        assert!(each_point_within(&mut s));
        // One point over its bound, though within the heaviest point's.
        let last = s.r.len() - 1;
        let heaviest = s.mass.iter().fold(0.0, |a: f64, &m| a.max(m));
        s.mass[last] = 0.5 * heaviest;
        s.r[last] = Vec3::new(0.0, 0.0, 1.01 * s.mass[last] * s.within);
        assert!(!each_point_within(&mut s));
        s.r[last] = Vec3::ZERO;
        assert!(each_point_within(&mut s));
        s.within = 0.0;
        assert!(
            !each_point_within(&mut s),
            "no bound: only the reduction stops a solve"
        );
    }

    /// The conjugate gradients' sums are taken over chunks fixed by the number of points alone,
    /// each chunk's in order, then the chunks' in order: the same bits on any number of threads,
    /// from one thread's loops and from a team's (more threads than this machine's cores
    /// included).
    #[test]
    fn the_solves_sums_are_the_same_on_any_number_of_threads() {
        let n = 5 * MIN_CHUNK + 17;
        assert!(sum_chunks(n) > 1);
        let mut next = values(9);
        let mut vector = || -> Vec<Vec3> {
            (0..n)
                .map(|_| Vec3::new(next(), next(), next()) * (1.0 + 1e3 * next().abs()))
                .collect()
        };
        let (a, b, p, ap, r) = (vector(), vector(), vector(), vector(), vector());
        let mass: Vec<f64> = (0..n).map(|i| 1.0 + i as f64 * 1e-3).collect();
        let size = sum_chunk(n);
        let chunked = |f: &dyn Fn(usize) -> f64| -> f64 {
            (0..n)
                .step_by(size)
                .map(|start| (start..(start + size).min(n)).map(f).sum::<f64>())
                .sum()
        };
        let run = |threads: usize| {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            pool.install(|| {
                team::run(|| {
                    let mut s = ImplicitScratch::new(&test_models::two_bodies());
                    s.dots = vec![0.0; sum_chunks(n)];
                    s.advanced = vec![(0.0, false); sum_chunks(n)];
                    s.dv = vec![Vec3::ZERO; n];
                    (s.p, s.ap, s.r, s.mass) = (p.clone(), ap.clone(), r.clone(), mass.clone());
                    s.within = 1e3;
                    let ab = dot(&a, &b, &mut s.dots);
                    let (rr, _) = advance(&mut s, 0.37);
                    (ab.to_bits(), rr.to_bits(), s.r.clone(), s.dv.clone())
                })
            })
        };
        let one = run(1);
        assert_eq!(one.0, chunked(&|i| a[i].dot(b[i])).to_bits());
        let stepped = |i: usize| r[i] - ap[i] * 0.37;
        assert_eq!(one.1, chunked(&|i| stepped(i).length_squared()).to_bits());
        assert!((0..n).all(|i| one.2[i] == stepped(i) && one.3[i] == p[i] * 0.37));
        for threads in [2, 3, 8] {
            assert_eq!(run(threads), one, "{threads} threads");
        }
    }

    /// GMRES's basis and the field's corrections are held only for a field whose swirl can pass
    /// the limit at the model's step: not for a gentle field that is not uniform, nor for the
    /// same field at a step too short for it.
    #[test]
    fn only_a_field_that_can_swirl_past_the_limit_gets_gmres() {
        let box_ = Aabb::new(Vec3::new(-2.0, -2.0, -2.0), Vec3::new(2.0, 2.0, 2.0)).unwrap();
        // c·(−y, x, 0) swirls by c (N/m); the classic mass is 1/512 kg.
        let turning = |c: f64| ForceField::from_fn(5, box_, move |p| Vec3::new(-p.y, p.x, 0.0) * c);
        let model = |c: f64, dt: f64| {
            let body = Body::lattice_box(
                Lattice::new([3, 3, 3], Vec3::new(0.5, 0.5, 0.5)),
                Material::classic(),
            );
            let model = ModelBuilder::new().bodies(vec![body]);
            model
                .field(Some(turning(c).unwrap()))
                .dt(dt)
                .build()
                .unwrap()
        };
        let h = 1.0 / 60.0;
        let at_limit = SWIRL_LIMIT / 512.0 / (h * h);
        for (c, dt, held) in [
            (2.0 * at_limit, h, true),
            (0.5 * at_limit, h, false),
            (2.0 * at_limit, 0.5 * h, false),
        ] {
            let model = model(c, dt);
            let s = ImplicitScratch::new(&model);
            let n = model.point_count();
            assert_eq!(can_swirl(&model, model.dt), held, "field {c} N/m, dt {dt}");
            assert_eq!(s.gmres.fits(n), held, "field {c} N/m, dt {dt}");
            assert_eq!(s.field_correction.len(), if held { n } else { 0 });
        }
    }

    /// An undeformed body flying in a uniform field needs no Newton iteration: the first
    /// iterate, shifted by the body's change of momentum, is the step's solution to rounding.
    /// Held at a point, the body would be bent by the shift, which is then not taken; nor is a
    /// shift no larger than the least one asked for (not even tried: a residual saved).
    #[test]
    fn a_body_in_free_flight_is_solved_by_its_change_of_momentum() {
        let box_ = Aabb::new(Vec3::new(-9.0, -9.0, -9.0), Vec3::new(9.0, 9.0, 9.0)).unwrap();
        let pull = Vec3::new(0.3, -0.2, -9.81 / 512.0);
        let field = ForceField::from_fn(2, box_, |_| pull).unwrap();
        let body = || {
            Body::lattice_box(
                Lattice::new([4, 3, 5], Vec3::new(0.6, 0.4, 0.8)),
                Material::classic(),
            )
        };
        let h = 1.0 / 60.0;
        for pins in [vec![], vec![7]] {
            let model = ModelBuilder::new()
                .bodies(vec![body()])
                .bounds(box_)
                .field(Some(field.clone()))
                .dt(h)
                .pins(pins.clone())
                .build()
                .unwrap();
            let x0 = crate::State::at_rest(&model).pos;
            let v0 = vec![Vec3::new(1.0, -0.5, 2.0); x0.len()];
            let (control, mut force) = (Control::none(), ForceScratch::new(&model));
            let mut s = ImplicitScratch::new(&model);
            s.load(&model);
            s.start_dampers(&model, &x0);
            s.v_soa.fill_zero();
            s.v.copy_from_slice(&v0);
            let norm2 = residual(&model, &control, &mut force, &mut s, &x0, &v0, h, false);
            // The shift is `h·pull/m` (the springs are at rest): asked for a larger one, none.
            let shift = (pull * (h * 512.0)).length();
            let g = s.g.clone();
            let mut shift_by = |least: f64, s: &mut ImplicitScratch| {
                shift_by_momentum(&model, &control, &mut force, s, &x0, &v0, h, norm2, least)
            };
            assert_eq!(shift_by(1.01 * shift, &mut s), norm2);
            assert_eq!((&s.v, &s.g), (&v0, &g));
            let reached = shift_by(0.99 * shift, &mut s);
            let (worst, _) = max_norms(&s.g, &s.v);
            if pins.is_empty() {
                assert!(reached < 1e-20 * norm2, "|g|²_M {norm2} → {reached}");
                // Rounding alone: the springs' forces at the shifted end positions.
                assert!(worst <= 0.01 * TOLERANCE, "max |g| {worst} m/s");
            } else {
                // Held, the body cannot fly: the shift would bend it, and is not taken.
                assert_eq!(reached, norm2);
                assert_eq!(s.v, v0);
            }
        }
    }

    /// Each step's end velocities of two runs agree to within 1e-10 m/s at every point.
    fn assert_same_steps(a: &[Vec<Vec3>], b: &[Vec<Vec3>]) {
        assert_eq!(a.len(), b.len());
        for (step, (a, b)) in a.iter().zip(b).enumerate() {
            let worst = a.iter().zip(b).map(|(a, b)| (*a - *b).length());
            let worst = worst.fold(0.0, f64::max);
            assert!(
                worst < 1e-10,
                "step {step}: velocities differ by {worst} m/s"
            );
        }
    }

    /// Newton's iterations in the fast regime keep the last one's `A`, and the steps end at the
    /// same velocities as with `A` assembled every iteration, to within the tolerance: a cube
    /// dropped onto a plane at 1/60 s, settling over 40 steps.
    #[test]
    fn newton_in_its_fast_regime_keeps_a_and_reaches_the_same_solution() {
        let body = Body::lattice_box(
            Lattice::new([6, 6, 6], Vec3::new(1.0, 1.0, 1.0)),
            Material::classic(),
        );
        let mut model = ModelBuilder::new()
            .bodies(vec![body])
            .gravity(Vec3::new(0.0, 0.0, -9.81))
            .plane(Some(crate::Plane::new([0.0, 0.0, 1.0, 0.05]).unwrap()))
            .dt(1.0 / 60.0)
            .integrator(Integrator::BackwardEuler)
            .build()
            .unwrap();
        model.newton.tolerance = 1e-11;
        let h = model.dt;
        let start = crate::State::at_rest(&model);
        let (control, mut force) = (Control::none(), ForceScratch::new(&model));
        let run = |may_keep: bool, force: &mut ForceScratch| {
            let mut s = ImplicitScratch::new(&model);
            s.may_keep = may_keep;
            let mut state = start.clone();
            let mut ends = vec![];
            let (mut pos, mut vel) = (state.pos.clone(), state.vel.clone());
            for _ in 0..40 {
                step(
                    &model, &state, &control, force, &mut s, h, &mut pos, &mut vel,
                )
                .unwrap();
                state.pos.copy_from_slice(&pos);
                state.vel.copy_from_slice(&vel);
                ends.push(state.vel.clone());
            }
            (ends, s.kept)
        };
        let (kept_a, kept) = run(true, &mut force);
        let (fresh_a, none) = run(false, &mut force);
        assert_eq!(none, 0);
        assert!(kept >= 20, "{kept} iterations kept A in 40 steps");
        assert_same_steps(&kept_a, &fresh_a);
    }

    /// A step's first Newton iteration keeps the last step's `A` where that step ended in the
    /// fast regime and no spring's ends move apart faster than the regime allows: a cube
    /// settled on a plane does, in most steps, and its steps end where those assembling `A` end,
    /// to within the tolerance; a cube spinning in free flight (its springs turning) never does.
    #[test]
    fn a_settled_body_keeps_a_across_steps_and_a_spinning_one_does_not() {
        let cube = || {
            Body::lattice_box(
                Lattice::new([6, 6, 6], Vec3::new(1.0, 1.0, 1.0)),
                Material::classic(),
            )
        };
        let model = |gravity: f64, plane: bool| {
            let mut model = ModelBuilder::new()
                .bodies(vec![cube()])
                .gravity(Vec3::new(0.0, 0.0, -gravity))
                .plane(plane.then(|| crate::Plane::new([0.0, 0.0, 1.0, 0.05]).unwrap()))
                .dt(1.0 / 60.0)
                .integrator(Integrator::BackwardEuler)
                .build()
                .unwrap();
            model.newton.tolerance = 1e-11;
            model
        };
        // Steps `from..to` (after `from` steps to settle), with `A` kept or not: each step's
        // end velocities, the steps that kept the last step's `A`, and the Newton iterations.
        let run = |model: &Model, start: &crate::State, may_keep: bool, steps: [usize; 2]| {
            let (control, mut force) = (Control::none(), ForceScratch::new(model));
            let mut s = ImplicitScratch::new(model);
            let mut state = start.clone();
            let (mut pos, mut vel, mut ends) = (state.pos.clone(), state.vel.clone(), vec![]);
            let (mut kept, mut iterations) = (0, 0);
            for n in 0..steps[1] {
                s.may_keep = may_keep || n < steps[0];
                let before = (s.kept_across, s.stats.newton_iterations);
                let h = model.dt;
                step(
                    model, &state, &control, &mut force, &mut s, h, &mut pos, &mut vel,
                )
                .unwrap();
                (state.pos, state.vel) = (pos.clone(), vel.clone());
                if n >= steps[0] {
                    kept += s.kept_across - before.0;
                    iterations += s.stats.newton_iterations - before.1;
                    ends.push(state.vel.clone());
                }
            }
            (ends, kept, iterations)
        };
        let settled = model(9.81, true);
        let start = crate::State::at_rest(&settled);
        let (kept_a, kept, _) = run(&settled, &start, true, [40, 80]);
        let (fresh_a, none, _) = run(&settled, &start, false, [40, 80]);
        assert!(
            kept >= 20,
            "{kept} of 40 settled steps kept the last step's A"
        );
        assert_eq!(none, 0);
        assert_same_steps(&kept_a, &fresh_a);
        let free = model(0.0, false);
        let mut spinning = crate::State::at_rest(&free);
        let centre = Vec3::new(0.5, 0.5, 0.5);
        for (v, &p) in spinning.vel.iter_mut().zip(&spinning.pos) {
            let r = p - centre;
            *v = Vec3::new(-r.y, r.x, 0.0) * 2.0;
        }
        let (_, kept, iterations) = run(&free, &spinning, true, [0, 20]);
        assert!(
            iterations >= 20,
            "{iterations} Newton iterations in 20 steps"
        );
        assert_eq!(kept, 0, "a spinning cube kept A across {kept} steps");
    }

    /// With a swirling field's exact gradient in it, `A` is `M·∂g/∂v`: `A·d` matches the central
    /// difference of `M·g` along `d`, at a lattice stretched and turned so that its springs'
    /// transverse stiffness matters, in a field that is neither linear nor a gradient.
    #[test]
    fn a_with_the_swirl_is_the_derivative_of_the_residual() {
        let box_ = Aabb::new(Vec3::new(-2.0, -2.0, -2.0), Vec3::new(2.0, 2.0, 2.0)).unwrap();
        let swirl = |p: Vec3| Vec3::new(-p.y, p.x + 0.5 * p.z * p.z, p.x * p.y) * 12.0;
        let field = ForceField::from_fn(9, box_, swirl).unwrap();
        let body = Body::lattice_box(
            Lattice::new([4, 3, 3], Vec3::new(0.9, 0.6, 0.6)),
            Material::classic(),
        );
        let h = 1.0 / 60.0;
        let model = ModelBuilder::new()
            .bodies(vec![body])
            .field(Some(field))
            .dt(h)
            .pins([5])
            .build()
            .unwrap();
        let mut next = values(11);
        let mut random = || Vec3::new(next(), next(), next());
        let x0: Vec<Vec3> = crate::State::at_rest(&model)
            .pos
            .iter()
            .map(|&p| Vec3::new(p.x * 1.3 - 0.4, p.y - 0.1 * p.z, p.z + 0.2 * p.x))
            .collect();
        let v: Vec<Vec3> = (0..x0.len()).map(|_| random() * 2.0).collect();
        let d: Vec<Vec3> = (0..x0.len()).map(|_| random()).collect();
        let (control, mut force) = (Control::none(), ForceScratch::new(&model));
        let mut s = ImplicitScratch::new(&model);
        s.load(&model);
        s.start_dampers(&model, &x0);
        let mut m_g = |s: &mut ImplicitScratch, v: &[Vec3]| {
            s.v_soa.fill_zero();
            s.v.copy_from_slice(v);
            residual(&model, &control, &mut force, s, &x0, &x0, h, false);
            (s.g.iter().zip(&s.mass))
                .map(|(&g, &m)| g * m)
                .collect::<Vec<_>>()
        };
        let eps = 1e-6;
        let along = |sign: f64| -> Vec<Vec3> {
            v.iter()
                .zip(&d)
                .map(|(&v, &d)| v + d * (sign * eps))
                .collect()
        };
        let (up, down) = (m_g(&mut s, &along(1.0)), m_g(&mut s, &along(-1.0)));
        m_g(&mut s, &v);
        s.swirl_allowed = true;
        assemble(
            &model,
            &control,
            force.anchors(),
            &mut s,
            &x0,
            h,
            Curvature::True { shift: 0.0 },
        );
        assert!(
            s.swirl,
            "the field should swirl past the limit at this step"
        );
        let mut ad = vec![Vec3::ZERO; d.len()];
        let correction = Some(&s.field_correction[..]);
        let pairs = (&s.pair_rows[..], &s.pair_blocks[..]);
        apply_to(
            &mut s.springs,
            &s.extra,
            &s.free,
            pairs.0,
            pairs.1,
            correction,
            &d,
            &mut ad,
            Precision::Double,
        );
        let scale = ad.iter().map(|a| a.max_abs()).fold(0.0, f64::max);
        for (p, ((&a, &u), &w)) in ad.iter().zip(&up).zip(&down).enumerate() {
            let difference = (u - w) / (2.0 * eps) * s.free[p];
            let off = (a - difference).max_abs();
            assert!(
                off <= 1e-6 * scale,
                "point {p}: A·d {a:?}, difference {difference:?}"
            );
        }
        // Without the swirl's correction, A·d misses it by far more.
        apply_to(
            &mut s.springs,
            &s.extra,
            &s.free,
            pairs.0,
            pairs.1,
            None,
            &d,
            &mut ad,
            Precision::Double,
        );
        let worst = ad
            .iter()
            .zip(up.iter().zip(&down))
            .zip(&s.free)
            .map(|((&a, (&u, &w)), &f)| (a - (u - w) / (2.0 * eps) * f).max_abs())
            .fold(0.0, f64::max);
        assert!(worst > 1e-3 * scale, "{worst} against {scale}");
    }
}
