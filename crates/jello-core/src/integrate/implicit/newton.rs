//! Newton's method for one backward-Euler solve: its iterations, the first iterate (from rest
//! where a body rests on a surface, the momentum shift), the line search along each direction,
//! and when a step converges (see the parent module's documentation for the method as a whole).

use crate::compute::team;
use crate::forces::ForceScratch;
use crate::model::Model;
use crate::state::Control;
use crate::vec3::Vec3;

use super::cg::sum_chunk;
use super::matrix::{newton_direction, solve_multigrid};
use super::residual::{has_potential, potential_fall, residual};
use super::SINGLE_PRECISION_REDUCTION;
use super::{chunk_size, ImplicitScratch, NotConverged, Row, CG_REDUCTION, CG_REDUCTION_EXACT};
use super::{KEEP_MOVE, MAX_EXPANSIONS, MAX_HALVINGS, SWIRL_STALLS, SWIRL_SWITCHES};
use super::{REST_MOVE, REST_STIFFNESS};

/// Newton's method for the step from `v₀` (see the `implicit` module's documentation; its first
/// iterate [`first_iterate`]'s), into `s.v`;
/// `swirls` when the field may swirl past the limit at the integrator's step
/// ([`can_swirl`](super::matrix::can_swirl)).
///
/// Where a field swirls, it first runs with the swirl in `A` (see
/// [`SWIRL_LIMIT`](super::SWIRL_LIMIT)), judged by `|g|²_M`. Should that stall (there is no
/// potential to descend, and `|g|²_M` has local minima where `A` is singular, as on a crushed
/// lattice), it starts again from `v0` with `A` symmetric and the incremental potential (with the
/// field's work) as the merit; that converges linearly at best (and the field's work is no
/// potential either: near the solution it may fall along no direction), so after four times
/// [`SWIRL_STALLS`] iterations the swirl goes back into `A` from the iterate reached, where
/// Newton's method with the exact `A` converges quickly. At most [`SWIRL_SWITCHES`] such changes a
/// step.
#[allow(clippy::too_many_arguments)]
pub(super) fn newton(
    model: &Model,
    control: &Control,
    force: &mut ForceScratch,
    s: &mut ImplicitScratch,
    x0: &[Vec3],
    v0: &[Vec3],
    h: f64,
    swirls: bool,
) -> Result<(), NotConverged> {
    first_iterate(s, model, v0, h);
    add_weight(model, control, s, x0, v0, h);
    (s.full_step_taken, s.anticipating) = (false, true);
    s.swirl_allowed = swirls;
    s.stats.solves += 1;
    let floor = rounding_floor(s, x0, h);
    let norm2 = residual(model, control, force, s, x0, v0, h, false);
    // Already solved (a body at rest, or moving as a whole without forces): the momentum shift
    // would cost a residual for nothing.
    let (norm, vmax) = max_norms(&s.g, &s.v);
    let target_at_first = target(model, floor, vmax);
    if norm <= target_at_first {
        return Ok(());
    }
    // Kept for the next step only where this one ends in Newton's fast regime.
    let kept = s.keep_across.take();
    // A shift below half the tolerance is not worth a residual's evaluation.
    let least = 0.5 * target_at_first;
    let mut norm2 = shift_by_momentum(model, control, force, s, x0, v0, h, norm2, least);
    let mut iterations = 0;
    // Whether this iteration may solve with the last one's `A` and multigrid.
    let mut keep = keeps_across_steps(s, kept, v0, h);
    #[cfg(test)]
    {
        s.kept_across += u32::from(keep);
    }
    let mut reduction = CG_REDUCTION;
    // The last iteration's reduction and its fall of `|g|²_M` (how many times smaller).
    let mut last = (CG_REDUCTION, f64::INFINITY);
    let mut shift = 0.0;
    let (mut stalled, mut symmetric, mut switches, mut best) = (0, 0, 0, norm2);
    // Whether the last iteration was in Newton's fast regime (see `solve_to`). A step whose
    // first iteration solves with the last step's `A` starts in it: that step ended there, and
    // `keeps_across_steps` found its springs' blocks barely changed since, so the first solve
    // too asks for what reaches the tolerance (a resting 32³ cube at 1/60 s, its first second:
    // 1.40 → 1.27 Newton iterations a step for as many conjugate-gradient ones, dropped 1.60
    // → 1.48; its settling steps take one iteration where they took two).
    let mut fast = keep;
    // Whether friction's growth with depth is in `A` (see below).
    let mut exact_friction = false;
    loop {
        let (norm, vmax) = max_norms(&s.g, &s.v);
        let target = target(model, floor, vmax);
        if norm <= target {
            s.keep_across = keep.then_some(h);
            return Ok(());
        }
        if iterations == model.newton.max_iterations {
            return Err(not_converged(&s.g, iterations));
        }
        iterations += 1;
        s.stats.newton_iterations += 1;
        // Friction that slides at its full size grows with the depth, which the symmetric `A`
        // leaves out, and Newton's method then converges only linearly (the 32³ cube dropped
        // on a floor at 1/60 s: two steps of 21 and 19 iterations at its impact). After an
        // iteration outside the fast regime, `A` takes that growth where friction slides, and
        // GMRES solves with it (`friction_growth`): those two steps took 9 and 15 iterations,
        // the job 1.60 Newton and 20.6 conjugate-gradient or GMRES iterations a step instead
        // of 1.87 and 22.3. Not in a step's first iteration: where that one is fast (the resting
        // cube's steps) GMRES would cost more for nothing (taken from the first, the resting
        // 32³ cube took 1.48 Newton and 14.5 conjugate-gradient iterations a step, not 1.40 and
        // 13.7). Once taken, for the rest of the step: a fast iteration without it, with `A`
        // kept, left the residual of the friction that slides, and the next iteration took the
        // growth again (the landing's steps alternated so; the dropped 8³ cube 1.04 → 0.98
        // Newton iterations a step with it kept, the 16³ one 1.18 → 1.12).
        #[cfg(test)]
        {
            exact_friction &= s.growth_sticks;
        }
        exact_friction |= iterations > 1 && !fast;
        s.exact_friction = exact_friction;
        #[cfg(test)]
        {
            s.exact_friction &= s.may_grow;
        }
        // A solve goes no further than the tolerance needs. Conjugate gradients stop once
        // their linear model puts every point within half the target, however little their
        // residual fell: near the solution that is much less than `CG_REDUCTION` asks (the 16³
        // benchmark at 1/60 s, once its cube slides on the floor: 5.1 → 1.9 iterations a
        // step, for 0.63 → 0.65 Newton iterations; its first 3 s 9–13 % fewer). Half: stopping
        // at 0.8 of the target saved 5 % more iterations for 5 % more Newton iterations (and
        // assemblies); at 0.95 the sliding steps took 0.95 Newton iterations each. GMRES (a
        // swirling field) is bounded by `enough_reduction` where it solves tighter than
        // `CG_REDUCTION`. Never looser than `CG_REDUCTION` otherwise: loosening that to 0.1
        // saved 0.3–3 % of the conjugate-gradient iterations at 16³ and 8³, not measured in
        // time.
        s.within = 0.5 * target;
        // After a full step with `A` Newton's own (its fast regime, where each step cuts the
        // residual by what its solve asked), the solve asks for what reaches the target, down to
        // the least reduction of single-precision products: a resting 32³ cube's first steps
        // cut `|g|` a hundredfold an iteration, `CG_REDUCTION`, for 4–6 iterations a step, each
        // with its residuals (BackwardEuler at 1/60 s, its first second: 1.60 → 1.40 Newton
        // iterations a step, as many conjugate-gradient iterations, 57.5 → 60.5 steps/s on 2
        // threads; dropped, 2.18 → 1.87, 33.7 → 35.1). The corpus at 1/60 s took 20 % fewer
        // Newton iterations and 7 % more conjugate-gradient ones, 3 % longer in all.
        let solve_to = if reduction < CG_REDUCTION {
            reduction.max(enough_reduction(s, target).min(CG_REDUCTION))
        } else if fast {
            enough_reduction(s, target).clamp(SINGLE_PRECISION_REDUCTION, CG_REDUCTION)
        } else {
            reduction
        };
        // A step's first solve may start from the last steps' first directions (see
        // `cg/recycle.rs`); the later ones correct this step's own error, which they do not
        // span.
        s.recycling = iterations == 1;
        #[cfg(test)]
        {
            s.recycling &= s.may_recycle;
        }
        // A kept `A` whose cycle fails even damped is assembled afresh.
        let own = (keep && solve_multigrid(s, solve_to))
            || newton_direction(
                model,
                control,
                force.anchors(),
                s,
                x0,
                h,
                solve_to,
                &mut shift,
            );
        s.recycling = false;
        let before = norm2;
        let swirled = s.swirl;
        let reached = line_search(model, control, force, s, x0, v0, h, norm2, floor);
        // In the fast regime, with `A` Newton's own and the end positions barely moved, `A` at
        // the new iterate differs by about `KEEP_MOVE`: keep it, and save its assembly and the
        // multigrid's setup (on the 16³ benchmark the conjugate gradients need as many
        // iterations with it; see `KEEP_MOVE` for a lattice where they need more). Not in
        // a field that is not uniform: its part of `A` is its gradient, which jumps at the faces
        // of its cells however little a point moves (`leapfrog.w` at 1/60 s took 1.7× as long
        // with `A` kept).
        let moved = |dv: &[Vec3]| {
            let (longest, chunks) = over_chunks(dv.len(), &|at| {
                dv[at]
                    .iter()
                    .map(|d| d.length_squared())
                    .fold(0.0, f64::max)
            });
            h * longest[..chunks]
                .iter()
                .fold(0.0, |a: f64, &b| a.max(b))
                .sqrt()
        };
        keep = own
            && model.field.as_ref().is_none_or(|f| f.uniform().is_some())
            && matches!(reached, Some((_, true)))
            && moved(&s.dv) <= KEEP_MOVE * s.shortest_spring;
        #[cfg(test)]
        {
            keep &= s.may_keep;
            s.kept += u32::from(keep);
        }
        let used = solve_to;
        fast = own && matches!(reached, Some((_, true)));
        match reached.map(|(n2, _)| n2) {
            Some(reached) => norm2 = reached,
            // An inexact direction may not lead down at all: solve exactly before giving up.
            None if reduction > CG_REDUCTION_EXACT => reduction = CG_REDUCTION_EXACT,
            // Nor may one whose `A` anticipated contacts (no longer Newton's own matrix): the
            // step goes on without anticipating.
            None if s.anticipating && s.full_step_taken => s.anticipating = false,
            None if swirls && (swirled || !s.swirl_allowed) && switches < SWIRL_SWITCHES => {
                stalled = SWIRL_STALLS
            }
            None => return Err(not_converged(&s.g, iterations)),
        }
        // A tighter solve whose step cut `|g|²_M` no more than the looser one's before it was
        // not held back by the solve: the direction's error is `A`'s own (a friction tie that
        // slides, whose force turns with the normal force as no symmetric `A` can; a
        // Levenberg–Marquardt shift), and Newton's method converges linearly however exactly it
        // solves. Back to the looser reduction (the 32³ cube dropped on a floor with friction at
        // 1/60 s: its two hardest steps took 948 and 1 025 conjugate-gradient iterations solving
        // to 1e-8 throughout, 493 and 288 so). Reverting whenever the fall was not twice as large
        // also cost `leapfrog.w` 1.6× at 1/60 s.
        //
        // A Newton step that cuts the residual less than tenfold does not make the next solve
        // tighter (it did, a hundredfold each time, until 2026-11-27): such steps are held back
        // by the residual's curvature more than by the solve, and solving tighter cost more than
        // it saved on every job measured: 10–20 % fewer conjugate-gradient iterations without it
        // on the benchmark scene at 16³ (1e-9 and 1e-5) and on the 16³ and 32³ cubes dropped on
        // a floor, 13 % fewer over the corpus at 1/60 s and 0.01 s (`leapfrog.w` a quarter as
        // many at 1/60 s), for at most 8 % more Newton iterations, with every run still
        // finishing.
        let fall = before / norm2;
        if reached.is_some() && used < last.0 && fall <= last.1 {
            reduction = last.0;
        }
        last = (used, fall);
        // Progress with the swirl in `A`: `|g|²_M` halved below its best.
        // Without the swirl, Newton's method converges linearly at best: back to the swirl after
        // a few times as long, however it went.
        if swirls && stalled < SWIRL_STALLS {
            if !s.swirl_allowed {
                symmetric += 1;
                if symmetric == 4 * SWIRL_STALLS {
                    stalled = SWIRL_STALLS;
                }
            } else if norm2 < 0.5 * best {
                (best, stalled) = (norm2, 0);
            } else if swirled {
                stalled += 1;
            }
        }
        if stalled >= SWIRL_STALLS && switches < SWIRL_SWITCHES {
            // Into the other mode, fresh; from the step's start the first time `A` leaves the
            // swirl out.
            if s.swirl_allowed && switches == 0 {
                s.v.copy_from_slice(v0);
                norm2 = residual(model, control, force, s, x0, v0, h, false);
            }
            s.swirl_allowed = !s.swirl_allowed;
            keep = false;
            (stalled, symmetric) = (0, 0);
            (best, reduction, shift) = (norm2, CG_REDUCTION, 0.0);
            last = (CG_REDUCTION, f64::INFINITY);
            switches += 1;
        }
    }
}

/// Newton's first iterate into `s.v`: `v₀`, but zero at the moving points of each body that
/// touches a surface at the step's start (`s.touching`) and would move less than [`REST_MOVE`]
/// times the shortest spring in the step at `v₀`, where the step is long against the stiffest
/// point's own time (`h²·K/m` at least [`REST_STIFFNESS`]): a body resting or settling on a
/// floor at a frame-rate step.
///
/// Near the solution `g(v) ≈ (I + h²·K/m)·(v − v*)` mode by mode, and backward Euler leaves
/// a mode of `h²·ω² ≫ 1` at `v* ≈ v₀/(1 + h²·ω²)`: for the stiff modes (a point pressed into
/// a floor, its friction tie) zero is far closer to `v*` than `v₀` is, and their `h²·K/m`
/// amplifies `v₀`'s part of the residual (3·10⁴ times at a resting 64³ cube's floor). The
/// soft modes, which keep `v₀`, are slow in such a body. A body that moves
/// (landing, thrown, sliding) or a step short enough to resolve the contacts keeps `v₀`: the
/// examples at their own steps of 0.5–1 ms (`h²·K/m` 2–15) took 8–24 % longer from rest.
/// From rest, at 1/60 s on 2 threads (this Xeon, in turn with the build before): the resting
/// 32³ cube 1.20 → 1.32× real time, the dropped one 0.83 → 0.91×; the resting 64³ cube 0.088
/// → 0.111× (its second step, where the bottom face's friction ties start, 13 → 3 Newton
/// iterations); the 8³ cubes 8–10 % faster on one thread.
pub(super) fn first_iterate(s: &mut ImplicitScratch, model: &Model, v0: &[Vec3], h: f64) {
    let size = chunk_size(v0.len());
    team::for_each_chunk([&mut s.v[..]], size, &|c, [v]| {
        v.copy_from_slice(&v0[c * size..c * size + v.len()]);
    });
    #[cfg(test)]
    if !s.may_start_at_rest {
        return;
    }
    if h * h * s.stiffness_over_mass < REST_STIFFNESS {
        return;
    }
    let reach = REST_MOVE * s.shortest_spring / h;
    for body in model.bodies() {
        let points = body.points();
        let (touching, v0) = (&s.touching[points.clone()], &v0[points.clone()]);
        let (found, chunks) = over_chunks(points.len(), &|at| {
            let fast = v0[at.clone()]
                .iter()
                .any(|v| v.length_squared() > reach * reach);
            (touching[at].contains(&true), fast)
        });
        let found = &found[..chunks];
        if !found.iter().any(|f| f.0) || found.iter().any(|f| f.1) {
            continue;
        }
        let free = &s.free[points.clone()];
        team::for_each_chunk([&mut s.v[points]], size, &|c, [v]| {
            for (v, &free) in v.iter_mut().zip(&free[c * size..]) {
                if free != 0.0 {
                    *v = Vec3::ZERO;
                }
            }
        });
    }
}

/// Adds to the first iterate of each body in free flight the velocity its weight gives it over
/// the step: `h·(g + n·F/M)`, for gravity `g` and a uniform field's force `F` on each of its `n`
/// moving points of mass `M` in all, the change of momentum under the only forces on it that do
/// not cancel within the body. That is the shift [`shift_by_momentum`]
/// makes after a first residual: a body falling clear of everything is then solved by the first
/// residual alone (the dropped cube's steps in free fall took two). In free flight: no point
/// pinned, pulled or pushed (by the control's forces), and nothing touched at the step's start or
/// at its end from the shifted velocities (a body resting just clear of a floor, shifted into
/// it, took more Newton iterations than from `v₀`: the resting 32³ cube at 1/60 s 1.22 → 1.42 a
/// step; see [`shift_by_momentum`] for a body about to land). Only the moving points are shifted
/// (not a lattice's holes).
pub(super) fn add_weight(
    model: &Model,
    control: &Control,
    s: &mut ImplicitScratch,
    x0: &[Vec3],
    v0: &[Vec3],
    h: f64,
) {
    let field = match &model.field {
        None => Vec3::ZERO,
        Some(field) => match field.uniform() {
            Some(force) => force,
            None => return,
        },
    };
    if (model.gravity == Vec3::ZERO && field == Vec3::ZERO) || !control.forces.is_empty() {
        return;
    }
    for body in model.bodies() {
        let points = body.points();
        let pinned = |&p: &u32| points.contains(&(p as usize));
        let pulled = |p: &crate::state::Pull| points.contains(&(p.point as usize));
        if s.touching[points.clone()].contains(&true)
            || model.pins.iter().any(pinned)
            || control.pulls.iter().any(pulled)
        {
            continue;
        }
        // `F/m` as the first residual's mean would give it, `n·F/M` summed over the moving
        // points: rounded otherwise in its last bit, the crushed cube of `gravityNoVelocity.w`
        // (BackwardEuler at 1/60 s) ended its first steps in another of their solutions (spring
        // energy 7.6e3 J after 0.1 s instead of 3.3e3 J).
        let (mass, free) = (&s.mass[points.clone()], &s.free[points.clone()]);
        let (sums, chunks) = over_chunks(points.len(), &|at| {
            let (mass, free) = (&mass[at.clone()], &free[at]);
            let moving = free.iter().sum::<f64>();
            (
                moving,
                mass.iter().zip(free).map(|(m, f)| m * f).sum::<f64>(),
            )
        });
        let (moving, mass) =
            (sums[..chunks].iter()).fold((0.0, 0.0), |a, b| (a.0 + b.0, a.1 + b.1));
        if mass <= 0.0 {
            continue;
        }
        let shift = (model.gravity + field * (moving / mass)) * h;
        if ends_touching(model, x0, (v0, shift), h, points.clone()) {
            continue;
        }
        let size = chunk_size(points.len());
        team::for_each_chunk([&mut s.v[points]], size, &|c, [v]| {
            for (v, &free) in v.iter_mut().zip(&free[c * size..]) {
                *v += shift * free;
            }
        });
    }
}

/// Whether a step's first Newton iteration may solve with the last step's `A` and multigrid,
/// `kept` the step size for which that step left them fit to keep (its last iteration in
/// Newton's fast regime; see [`KEEP_MOVE`]): at the same step size, where no spring's ends move
/// apart faster than that regime allows, `h·|v₀[a] − v₀[b]| ≤ KEEP_MOVE·(shortest spring)`.
/// The first iterate's end positions lie `h·v₀` beyond the step's start (or at it, for a body
/// started from rest: [`first_iterate`]), so the springs' blocks have changed by their relative
/// motion alone (a body moving or sliding as a whole keeps them). A body settled on a floor
/// then takes its steps without assembling `A`. What this
/// does not see (contacts that began, states or parameters set between steps) costs one
/// iteration at most: unless the kept `A`'s whole step cuts the residual tenfold, the next
/// iteration assembles `A` afresh, and convergence is judged on the residual alone.
fn keeps_across_steps(s: &ImplicitScratch, kept: Option<f64>, v0: &[Vec3], h: f64) -> bool {
    #[cfg(test)]
    if !s.may_keep {
        return false;
    }
    if kept != Some(h) {
        return false;
    }
    let limit = KEEP_MOVE * s.shortest_spring / h;
    // No two points differ in velocity by more than the diagonal of the box that holds every
    // point's velocity: within the limit, no spring is fast (a body at rest or moving as a
    // whole), and the springs need not be looked at (their loop was 3 % of a resting 32³ cube's
    // step on one thread).
    let (lo, hi) = team::bounds(v0, sum_chunk(v0.len()));
    if (hi - lo).length_squared() <= limit * limit {
        return true;
    }
    // Over the team: which thread finds a fast spring does not matter.
    let slow = std::sync::atomic::AtomicBool::new(true);
    let size = chunk_size(s.rows.len());
    team::for_each(s.rows.len().div_ceil(size), &|c| {
        let rows = &s.rows[c * size..((c + 1) * size).min(s.rows.len())];
        let apart = |r: &Row| (v0[r.a as usize] - v0[r.b as usize]).length_squared();
        if rows.iter().any(|r| apart(r) > limit * limit) {
            slow.store(false, std::sync::atomic::Ordering::Relaxed);
        }
    });
    slow.into_inner()
}

/// Newton's first iterate ([`first_iterate`]'s) with each body's moving points shifted by minus
/// the mass-weighted mean of their residual there, when that lowers `|g|²_M` (`norm2` there);
/// returns the iterate's `|g|²_M`. That mean is `−h` times the force on the body over its mass
/// (the springs and other internal forces cancel in it), so the shift is the body's change of
/// momentum over the step under the forces at `v₀`: a body in free flight is then solved but
/// for its deformation. From `v₀`, Newton's method spent whole iterations on that uniform part,
/// which the preconditioner's fine level scatters over the lattice (16³ benchmark at 1/60 s:
/// 4.5 Newton and 60 CG iterations a step from `v₀`, 3.5 and 55 from here). A shift no larger
/// than `least` (m/s) is not tried: a body resting on a floor, whose forces balance, would pay a
/// residual's evaluation for a shift below the tolerance (half the target at the first iterate,
/// from `newton`): 6–7 % of such a step at 16³ on one thread.
#[allow(clippy::too_many_arguments)]
pub(super) fn shift_by_momentum(
    model: &Model,
    control: &Control,
    force: &mut ForceScratch,
    s: &mut ImplicitScratch,
    x0: &[Vec3],
    v0: &[Vec3],
    h: f64,
    norm2: f64,
    least: f64,
) -> f64 {
    let mut largest: f64 = 0.0;
    for body in model.bodies() {
        // A body that touches anything at the step's start is not shifted: what holds it up
        // is missing from the mean, and shifted it presses further in. Such shifts were
        // rejected, each after a residual: a 32³ cube resting on a floor (its first second at
        // 1/60 s) 45 of 47, dropped on it 36 of 36, while its 24 shifts in free fall were kept.
        // Nor is one that the step at `v₀` carries into a surface: the mean then holds that
        // contact's force, which throws the whole body back, and is kept for the residual it
        // lowers at the contact (the dropped 16³ cube's landing step: shifted to 22 m/s
        // upwards, then 13 Newton iterations and 113 conjugate-gradient ones; unshifted 4 and
        // 50, the job 1.27 → 1.19 Newton and 9.2 → 8.6 conjugate-gradient iterations a step).
        if s.touching[body.points()].contains(&true)
            || ends_touching(model, x0, (v0, Vec3::ZERO), h, body.points())
        {
            s.dv[body.points()].fill(Vec3::ZERO);
            continue;
        }
        let shift = -mean_residual(s, body.points());
        largest = largest.max(shift.length());
        for p in body.points() {
            s.dv[p] = shift * s.free[p];
        }
    }
    if largest <= least {
        return norm2;
    }
    s.set_trial(1.0);
    let shifted = residual(model, control, force, s, x0, v0, h, true);
    if shifted < norm2 {
        s.take_trial();
        shifted
    } else {
        norm2
    }
}

/// Whether any of `points` touches a surface (a wall, the plane, an obstacle) at the end of a
/// step at the velocities `v` shifted by `shift`, `x0 + h·(v + shift)`.
fn ends_touching(
    model: &Model,
    x0: &[Vec3],
    (v, shift): (&[Vec3], Vec3),
    h: f64,
    points: std::ops::Range<usize>,
) -> bool {
    let (first, n) = (points.start, points.len());
    let (touches, chunks) = over_chunks(n, &|at| {
        let at = at.start + first..at.end + first;
        let end = |i: usize| x0[i] + (v[i] + shift) * h;
        if clear_of_surfaces(model, at.clone().map(end)) {
            return false;
        }
        let mut touches = false;
        for i in at {
            model.for_each_contact_of(i, end(i), true, |_| touches = true);
        }
        touches
    });
    touches[..chunks].contains(&true)
}

/// Whether none of `points` can touch a wall, the plane or an obstacle: their bounding box
/// touches nothing ([`Model::touches_nothing_in`]). A chunk of a body in flight, or of one
/// resting on a floor but its bottom, is cleared so in a pass of minima and maxima, where its
/// points' tests one at a time took a sixth of a falling 32³ cube's step (5.5–7.3 → 4.8–5.9 ms
/// on one thread of a 2-vCPU AMD EPYC with AVX2, runs in turn).
fn clear_of_surfaces(model: &Model, points: impl Iterator<Item = Vec3>) -> bool {
    let far = Vec3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY);
    let (lo, hi) = points.fold((far, -far), |(lo, hi), p| (lo.min(p), hi.max(p)));
    model.touches_nothing_in(lo, hi)
}

/// What a converged step takes out of the moving points' velocities: their mass-weighted mean
/// residual ([`mean_residual`]), so that internal forces conserve momentum to rounding, where
/// a shift of them all by one velocity changes no force on them but through their masses: no
/// point pinned or pulled, no field that varies in space, and no moving point on a wall, the
/// plane or an obstacle at the step's start or end (`x0 + h·v`); else nothing. There something
/// outside holds the points by where they are, momentum is not conserved, and the shift would
/// press them into it: it raises the residual there by `h²·k/m` times itself (3 640 times at
/// the resting 32³ cube's floor at 1/60 s, where a shift of 1e-11 m/s left 4e-8 m/s at its
/// bottom face, 40 times the tolerance, so that every step of the settled cube took a Newton
/// iteration to undo the last one's shift: the job 1.22 → 0.57 Newton iterations a step
/// without).
pub(super) fn momentum_shift(
    model: &Model,
    control: &Control,
    s: &ImplicitScratch,
    x0: &[Vec3],
    h: f64,
) -> Vec3 {
    let held = !model.pins.is_empty() || !control.pulls.is_empty();
    let varies = model.field.as_ref().is_some_and(|f| f.uniform().is_none());
    if held || varies || on_surfaces(model, s, x0, h) {
        return Vec3::ZERO;
    }
    mean_residual(s, 0..s.g.len())
}

/// Whether any moving point touches a surface (a wall, the plane, an obstacle) at the step's
/// start `x0` or at the iterate's end `x0 + h·v`.
fn on_surfaces(model: &Model, s: &ImplicitScratch, x0: &[Vec3], h: f64) -> bool {
    let (v, free) = (&s.v[..], &s.free[..]);
    let (touches, chunks) = over_chunks(x0.len(), &|at| {
        let ends = at.clone().map(|i| x0[i] + v[i] * h);
        if clear_of_surfaces(model, x0[at.clone()].iter().copied().chain(ends)) {
            return false;
        }
        at.filter(|&i| free[i] != 0.0).any(|i| {
            let mut touches = false;
            for p in [x0[i], x0[i] + v[i] * h] {
                model.for_each_contact_of(i, p, true, |_| touches = true);
            }
            touches
        })
    });
    touches[..chunks].contains(&true)
}

/// The mass-weighted mean residual `Σ m·g / Σ m` of the moving points among `points` (zero
/// when none moves).
pub(super) fn mean_residual(s: &ImplicitScratch, points: std::ops::Range<usize>) -> Vec3 {
    let (mut mg, mut m) = (Vec3::ZERO, 0.0);
    for p in points {
        mg += s.g[p] * (s.mass[p] * s.free[p]);
        m += s.mass[p] * s.free[p];
    }
    if m > 0.0 {
        mg / m
    } else {
        Vec3::ZERO
    }
}

/// The residual a step of size `h` from `x0` can be solved to in floating point, at least
/// (m/s): `ε·h·max(K/m)·max|x|`, `K` a point's spring and contact stiffness summed. The end
/// positions `x0 + h·v` carry a rounding of `ε·|x|` each, every spring's force `k·ε·|x|` of it,
/// and the residual `h/m` times their sum; so a stiff lattice at a large step cannot reach a
/// fixed tolerance (kElastic = kCollision = 10⁶ at 1/60 s: Newton's method stalls near 1e-8
/// m/s, where this floor is 7e-8), and converges at that floor instead. Negligible otherwise
/// (the classic cube at 1/60 s: 1.5e-11 m/s).
fn rounding_floor(s: &ImplicitScratch, x0: &[Vec3], h: f64) -> f64 {
    let free = &s.free[..];
    let (reach, chunks) = over_chunks(x0.len(), &|at| {
        x0[at.clone()]
            .iter()
            .zip(&free[at])
            .filter(|&(_, &free)| free != 0.0)
            .map(|(x, _)| x.x.abs().max(x.y.abs()).max(x.z.abs()))
            .fold(0.0, f64::max)
    });
    let reach = reach[..chunks].iter().fold(0.0, |a: f64, &b| a.max(b));
    f64::EPSILON * h * s.stiffness_over_mass * reach
}

/// `f` of each chunk of `n` points (at most [`team::OWNED_ITEMS`], fixed by `n` alone, as
/// [`sum_chunk`] fixes them), on the team, and how many there are: the serial loops over the
/// points that Newton's method folds (maxima, minima, a sum) are then split over the threads,
/// and each chunk's result is the same whoever computes it.
pub(super) fn over_chunks<R: Copy + Default + Send>(
    n: usize,
    f: &(dyn Fn(std::ops::Range<usize>) -> R + Sync),
) -> ([R; team::OWNED_ITEMS], usize) {
    team::map_chunks(n, sum_chunk(n), f)
}

/// The report of a step that stopped with residual `g` after `iterations`.
fn not_converged(g: &[Vec3], iterations: u32) -> NotConverged {
    let (point, residual) =
        g.iter()
            .map(|g| g.length())
            .enumerate()
            .fold(
                (0, 0.0),
                |best, (p, r)| if r > best.1 { (p, r) } else { best },
            );
    NotConverged {
        residual,
        point,
        iterations,
    }
}

/// Backtracks along the Newton direction `s.dv` from the iterate until the merit falls enough
/// (Armijo), and takes that point as the iterate; returns its `|g|²_M` and whether that was the
/// whole step `Δv` in the fast regime (it cut `|g|_M` tenfold), or `None` when no step along
/// `Δv` lowers the merit or the residual. The merit is the incremental potential when the
/// forces have one (see [`has_potential`]), else `|g|²_M`.
#[allow(clippy::too_many_arguments)]
fn line_search(
    model: &Model,
    control: &Control,
    force: &mut ForceScratch,
    s: &mut ImplicitScratch,
    x0: &[Vec3],
    v0: &[Vec3],
    h: f64,
    norm2: f64,
    floor: f64,
) -> Option<(f64, bool)> {
    // A direction from a swirling `A` need not lower the potential, only `|g|²_M`.
    let potential = has_potential(model) && !s.unsymmetric();
    // The potential's slope along Δv is M·g·Δv (negative); for |g|²_M a plain fall is asked.
    let slope: f64 = if potential {
        let (g, dv, mass) = (&s.g[..], &s.dv[..], &s.mass[..]);
        let (sums, chunks) = over_chunks(g.len(), &|at| {
            let terms = g[at.clone()].iter().zip(&dv[at.clone()]).zip(&mass[at]);
            terms.map(|((g, d), m)| m * g.dot(*d)).sum::<f64>()
        });
        sums[..chunks].iter().sum()
    } else {
        0.0
    };
    // The merit's fall to the trial, whose `|g|²_M` is `n2`, from `from`.
    let fall_to = |s: &mut ImplicitScratch, n2: f64, from: f64| {
        if !n2.is_finite() {
            f64::NEG_INFINITY
        } else if potential {
            potential_fall(model, control, s, x0, v0, h)
        } else {
            from - n2
        }
    };
    let mut alpha = 1.0;
    for _ in 0..=MAX_HALVINGS {
        if alpha == 1.0 {
            s.set_full_trial();
        } else {
            s.set_trial(alpha);
        }
        let n2 = residual(model, control, force, s, x0, v0, h, true);
        // A full step that cuts `|g|_M` tenfold is taken without the merit's fall (a third of
        // the line search's cost): Newton's method is then in its fast regime, where the merit
        // falls as its quadratic model says, and would not be followed further. So is one that
        // reaches the tolerance, where the solve stopped as soon as it could (see `within`): the
        // step is solved (on the 16³ benchmark sliding on its floor, the merit had cost 11 % of
        // the time).
        let solved = |s: &ImplicitScratch| converged(model, floor, &s.g_trial, &s.trial);
        if alpha == 1.0 && (n2 < 1e-2 * norm2 || solved(s)) {
            s.take_trial();
            return Some((n2, true));
        }
        let fall = fall_to(s, n2, norm2);
        // At a contact's kink the merit may not fall at all: a step that lowers the residual
        // is taken too.
        if fall > -1e-4 * alpha * slope.min(0.0) || n2 < norm2 {
            s.take_trial();
            let mut reached = n2;
            // A full step that lowers the potential by more than ¾ of its slope (a quadratic
            // model predicts ½) is sliding down a direction where `A` overstates the curvature
            // (a buckling lattice, whose negative stiffness was clamped): go on along it while
            // the potential keeps falling.
            if alpha == 1.0 && slope < 0.0 && fall > -0.75 * slope {
                for _ in 0..MAX_EXPANSIONS {
                    s.set_trial(1.0);
                    let n2 = residual(model, control, force, s, x0, v0, h, true);
                    if fall_to(s, n2, reached) <= 0.0 {
                        break;
                    }
                    s.take_trial();
                    reached = n2;
                    s.dv.iter_mut().for_each(|d| *d = *d * 2.0);
                }
            }
            return Some((reached, false));
        }
        alpha *= 0.5;
    }
    None
}

/// The reduction of the Newton system's residual `M·g` (over the moving points) after which its
/// linear model puts every point's `|g|` at or below `target`, with a factor 2 to spare for the
/// model's error: `|g′| ≤ |M·g′| / m_min`.
pub(super) fn enough_reduction(s: &ImplicitScratch, target: f64) -> f64 {
    let (g, mass, free) = (&s.g[..], &s.mass[..], &s.free[..]);
    let (parts, chunks) = over_chunks(g.len(), &|at| {
        let (mut norm2, mut lightest) = (0.0, f64::INFINITY);
        for ((g, &m), &free) in g[at.clone()].iter().zip(&mass[at.clone()]).zip(&free[at]) {
            if free != 0.0 && m > 0.0 {
                norm2 += (m * m) * g.dot(*g);
                lightest = lightest.min(m);
            }
        }
        (norm2, lightest)
    });
    let norm2: f64 = parts[..chunks].iter().map(|p| p.0).sum();
    let lightest = parts[..chunks]
        .iter()
        .map(|p| p.1)
        .fold(f64::INFINITY, f64::min);
    if norm2 > 0.0 && lightest.is_finite() {
        0.5 * lightest * target / norm2.sqrt()
    } else {
        0.0
    }
}

/// The largest `|g|` a point may keep, where the fastest point's speed is `vmax`: the model's
/// tolerance (scaled by speeds above 1 m/s; see [`TOLERANCE`](super::TOLERANCE)), no finer than the
/// rounding floor `floor` ([`rounding_floor`]).
fn target(model: &Model, floor: f64, vmax: f64) -> f64 {
    (model.newton.tolerance * vmax.max(1.0)).max(floor)
}

/// Whether the residual `g` at the iterate `v` is within its [`target`].
fn converged(model: &Model, floor: f64, g: &[Vec3], v: &[Vec3]) -> bool {
    let (norm, vmax) = max_norms(g, v);
    norm <= target(model, floor, vmax)
}

/// `max |g|` and `max |v|`, over the chunks of [`over_chunks`] on the team (a maximum does not
/// depend on the order it is taken in). The largest squares, then their roots: a square root is
/// correctly rounded and never decreasing, so the root of the largest square is the largest
/// root (two roots, not two a point).
pub(super) fn max_norms(g: &[Vec3], v: &[Vec3]) -> (f64, f64) {
    let (maxima, chunks) = over_chunks(g.len(), &|at| {
        (largest_square(&g[at.clone()]), largest_square(&v[at]))
    });
    let (g, v) = (maxima[..chunks].iter()).fold((0.0, 0.0), |(g, v), &(a, b)| {
        (f64::max(g, a), f64::max(v, b))
    });
    (g.sqrt(), v.sqrt())
}

crate::compute::simd::multiversion! {
    /// The largest `|x|²` of `x` (NaN counts as none), in lanes of eight, which vectorise: a
    /// fold in order waits for each maximum in turn.
    fn largest_square(x: &[Vec3]) -> f64 {
        let mut lanes = [0.0f64; 8];
        let mut chunks = x.chunks_exact(8);
        for chunk in &mut chunks {
            for (lane, x) in lanes.iter_mut().zip(chunk) {
                *lane = lane.max(x.length_squared());
            }
        }
        let rest = chunks.remainder().iter().map(|x| x.length_squared()).fold(0.0, f64::max);
        lanes.into_iter().fold(rest, f64::max)
    }
}
