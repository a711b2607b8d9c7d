//! The Newton direction: `A = M + h·D₀ + h²·K` assembled at the iterate (with a
//! Levenberg–Marquardt shift where the true stiffness leaves it indefinite) and solved for.

use crate::compute::team;
use crate::contact::friction::{self, Anchors, Surface};
use crate::model::field;
use crate::model::obstacle::ObstacleContact;
use crate::model::Model;
use crate::state::Control;
use crate::vec3::Vec3;

use super::cg::{solve, Preconditioner};
use super::multigrid::Operator;
use super::sym::{add_outer, Sym};
use super::{ImplicitScratch, SWIRL_LIMIT};

/// Solves for the Newton direction at the iterate into `s.dv`, with the springs' true transverse
/// stiffness (a compressed spring's is negative; clamping it slows Newton's method down to a
/// crawl on a crushed lattice). When that makes `A` indefinite, the masses in it are scaled up
/// by a shift until it is not: a Levenberg–Marquardt step, which keeps the true curvature where
/// it is positive, and becomes Newton's method again as the shift decays (a quarter per solve
/// that needs none larger) near the solution. Only when no shift up to ~40 will do are the
/// negative stiffnesses clamped at zero. `shift` carries over between iterations of a step.
/// True when `A` was Newton's own (the true stiffness, no shift) and the multigrid
/// preconditioned it: a matrix the next iteration may keep.
#[allow(clippy::too_many_arguments)]
pub(super) fn newton_direction(
    model: &Model,
    control: &Control,
    anchors: &Anchors,
    s: &mut ImplicitScratch,
    x0: &[Vec3],
    h: f64,
    reduction: f64,
    shift: &mut f64,
) -> bool {
    // The preconditioner that solved, if any.
    let mut solve_with = |curvature| {
        assemble(model, control, anchors, s, x0, h, curvature);
        // Where the multigrid fails even damped, the diagonal alone decides, as it did before
        // the multigrid.
        if solve_multigrid(s, reduction) {
            Some(Preconditioner::Multigrid)
        } else if s.multigrid_failed && solve(s, reduction, Preconditioner::Diagonal) {
            Some(Preconditioner::Diagonal)
        } else {
            None
        }
    };
    if let Some(solved) = solve_with(Curvature::True { shift: *shift }) {
        let own = *shift == 0.0 && solved == Preconditioner::Multigrid;
        *shift = if *shift < 1e-3 { 0.0 } else { *shift * 0.25 };
        return own;
    }
    let mut tried = if *shift == 0.0 { 1e-2 } else { *shift * 4.0 };
    for _ in 0..5 {
        if solve_with(Curvature::True { shift: tried }).is_some() {
            *shift = tried;
            return false;
        }
        tried *= 8.0;
    }
    solve_with(Curvature::Clamped);
    false
}

/// Solves with `A` as assembled, preconditioned by the multigrid; true when that solved. Where
/// `A` is nearly indefinite its coarse copies may be indefinite, and the cycle with them, though
/// `A` is not; or the cycle's over-relaxed smoother diverges on them: the conjugate gradients
/// find the cycle not positive definite (`s.multigrid_failed`), and the solve is tried again
/// with the smoother damped for the rest of the step ([`Multigrid::damp`]), whether `A` was
/// assembled for this iteration or kept from the last one.
///
/// [`Multigrid::damp`]: super::multigrid::Multigrid::damp
pub(super) fn solve_multigrid(s: &mut ImplicitScratch, reduction: f64) -> bool {
    solve(s, reduction, Preconditioner::Multigrid)
        || (s.multigrid_failed
            && s.multigrid.damp()
            && solve(s, reduction, Preconditioner::Multigrid))
}

/// Which stiffness [`assemble`] puts in `A`.
#[derive(Clone, Copy, Debug)]
pub(super) enum Curvature {
    /// The true one (a compressed spring's transverse stiffness is negative), with the masses
    /// scaled by `1 + shift` (a Levenberg–Marquardt shift, 0 for Newton's method itself).
    True { shift: f64 },
    /// Negative transverse stiffnesses clamped at zero: `A` is positive definite.
    Clamped,
}

/// The blocks of `A` at the iterate, the contact and pull parts, and the inverted diagonal.
pub(super) fn assemble(
    model: &Model,
    control: &Control,
    anchors: &Anchors,
    s: &mut ImplicitScratch,
    x0: &[Vec3],
    h: f64,
    curvature: Curvature,
) {
    s.stats.assemblies += 1;
    let h2 = h * h;
    let (clamp, shift) = match curvature {
        Curvature::True { shift } => (false, shift),
        Curvature::Clamped => (true, 0.0),
    };
    let at = |p: usize, v: &[Vec3]| x0[p] + v[p] * h;
    let floor = if clamp { 0.0 } else { f64::MIN };
    s.springs.assemble(x0, &s.v, h, floor);
    // Each point's mass (scaled by the shift), the penalty springs of walls, plane and obstacles
    // where the iterate is, their dampers as at the start, and friction along the surfaces at
    // the iterate: each point's own, so the points in chunks over the team.
    let (mass, free, v, start_damping) = (&s.mass[..], &s.free[..], &s.v[..], &s.start_damping[..]);
    let full_step = (s.anticipating && s.full_step_taken).then_some(&s.full_step[..]);
    let size = super::chunk_size(s.extra.len());
    let parts = ([&mut s.extra[..]], [&mut s.slides[..]]);
    team::for_each_chunk_pair(parts, size, &|chunk, ([extra], [slides])| {
        for (j, (e, slides)) in extra.iter_mut().zip(slides).enumerate() {
            let i = chunk * size + j;
            (*e, *slides) = ([0.0; 6], false);
            e[..3].fill(mass[i] * (1.0 + shift));
            if free[i] == 0.0 {
                continue;
            }
            for (e, d) in e.iter_mut().zip(&start_damping[i]) {
                *e += h * d;
            }
            let mut growth = |_, _| *slides = true;
            add_surfaces(
                model,
                anchors,
                i,
                at(i, v),
                v[i],
                mass[i],
                h,
                e,
                &mut growth,
            );
            if let Some(full) = full_step {
                add_anticipated(model, i, at(i, v), at(i, full), h, e);
            }
        }
    });
    // The unsymmetric part of the friction that slides, point by point (few points: those on a
    // surface whose friction slides).
    s.friction_growth.clear();
    for i in (0..s.slides.len()).filter(|&i| s.slides[i]) {
        let mut part = [0.0; 9];
        let mut growth = |g: Vec3, n: Vec3| {
            for (r, g) in g.to_array().into_iter().enumerate() {
                for (c, n) in n.to_array().into_iter().enumerate() {
                    part[3 * r + c] += g * n;
                }
            }
        };
        let (p, v, mut e) = (at(i, &s.v), s.v[i], [0.0; 6]);
        add_surfaces(model, anchors, i, p, v, s.mass[i], h, &mut e, &mut growth);
        s.friction_growth.push((i as u32, part));
    }
    // A field that is not uniform: its gradient's stiffness, and its swirl.
    let mut swirl: f64 = 0.0;
    if let Some(field) = model.field.as_ref().filter(|f| f.uniform().is_none()) {
        for (i, e) in s.extra.iter_mut().enumerate() {
            if s.free[i] == 0.0 {
                continue;
            }
            let gradient = field.gradient(at(i, &s.v));
            let k = field_stiffness(&gradient);
            for (e, k) in e.iter_mut().zip(k) {
                *e += h2 * k;
            }
            if let Some(c) = s.field_correction.get_mut(i) {
                *c = field_correction(&gradient, &k).map(|c| h2 * c);
                swirl = swirl.max(h2 * field::swirl(&gradient) / s.mass[i]);
            }
        }
    }
    s.swirl = s.swirl_allowed && swirl > SWIRL_LIMIT;
    for pull in &control.pulls {
        let e = &mut s.extra[pull.point as usize];
        let c = h * pull.damping + h2 * pull.stiffness;
        e[..3].iter_mut().for_each(|e| *e += c);
    }
    // Under self-contact, the cells' guard at the iterate: the Gauss–Newton curvature of each
    // squeezed corner's energy, `k·ggᵀ`, at each of its points (its couplings between points
    // left out: `A` stays positive definite where the guard acts, and Newton's method, judged
    // on the residual, converges on without them).
    let (free, extra) = (&s.free, &mut s.extra);
    crate::contact::cell_guard::for_each_squeezed(
        model,
        |i| at(i, &s.v),
        |q| {
            for (&p, &g) in q.points.iter().zip(&q.gradient) {
                if free[p] != 0.0 {
                    super::sym::add_outer(&mut extra[p], g, h2 * q.stiffness);
                }
            }
        },
    );
    // Contacts between bodies: each touch found at the step's start, its penalty spring along
    // the normal it had then while it is in, its sliding friction, and its damper where it
    // touched at the start, each on the sample's displacement relative to the other body.
    s.pair_rows.clear();
    s.pair_blocks.clear();
    for t in &s.start_touches {
        let touched_at = &s.touched_at;
        if let Some(block) =
            super::contacts::touch_block(model, t, |i| at(i, &s.v), touched_at, &s.v, h)
        {
            add_coupling(
                (&mut s.pair_rows, &mut s.pair_blocks),
                &t.points,
                &t.weights,
                &block,
            );
        }
    }
    // The diagonal blocks: the point's own part plus each spring's block at both ends, in
    // stencil order, and each contact's; then the coarse levels.
    s.springs.set_own(&s.extra);
    s.springs.diagonal(&mut s.diag_inv);
    Operator::add_and_invert((&s.pair_rows, &s.pair_blocks), &mut s.diag_inv);
    s.single.set_diagonal(&s.diag_inv);
    s.multigrid.assemble(&fine_operator!(s));
}

/// Point `i`'s part of `A` from the walls, the plane and the obstacles at `p` (its end position
/// at the iterate, `v` its velocity there) into `e`: each penalty spring's `h²·kCollision·nnᵀ`
/// and its friction's, the walls' and plane's before the obstacles'; and, for each friction that
/// slides at its full size, the unsymmetric part `g·nᵀ` its limit's growth with depth adds
/// ([`friction::limit_growth`]), through `growth(g, n)`.
#[allow(clippy::too_many_arguments)]
// Inlined into the assembly's loop over the points: out of line (as the split into codegen
// units once left it), its point came through memory and stalled its first products, and the
// dropped 16³ cube took 3 % longer.
#[inline(always)]
fn add_surfaces(
    model: &Model,
    anchors: &Anchors,
    i: usize,
    p: Vec3,
    v: Vec3,
    mass: f64,
    h: f64,
    e: &mut Sym,
    growth: &mut impl FnMut(Vec3, Vec3),
) {
    let (kc, dc, h2) = (model.k_collision, model.d_collision, h * h);
    let clearance = model.clearance_of(i);
    let walls = (model.bounds.wall_contacts(p))
        .chain(model.plane.and_then(|pl| pl.contact(p)))
        .filter_map(|c| c.less(clearance));
    for c in walls {
        add_outer(e, c.normal, h2 * kc);
    }
    let c_max = friction::implicit_cap(mass, model.dt, kc);
    // The walls' and the plane's friction, as the obstacles' below.
    if model.wall_friction > 0.0 {
        let walls = (0..6).map(Surface::Wall);
        let surfaces = walls.chain(model.plane.map(|_| Surface::Plane));
        for surface in surfaces.filter(|s| s.may_touch(model, p)) {
            if let Some(c) = surface.contact_of(model, i, p) {
                let anchor = anchors.anchor(surface, i);
                let law = [kc, dc, model.wall_friction];
                let (depth, n) = (c.depth, c.normal);
                let tangent = friction::obstacle_tangent(p, v, depth, n, anchor, law, c_max, h);
                add_tangent(e, n, tangent);
                if let Some(g) = friction::limit_growth(tangent.1, law, h) {
                    growth(g, n);
                }
            }
        }
    }
    for (o, c) in model
        .obstacles
        .iter()
        .enumerate()
        .filter_map(|(o, ob)| ob.contact(p)?.less(clearance).map(|c| (o, c)))
    {
        add_outer(e, c.normal, h2 * kc);
        // Friction: the tie's spring and damper while it holds, its sliding part once it
        // slides (a tie that slides with its holding stiffness in `A` cut Newton's steps
        // along the slide to `m/(m + h²·kc)`, and scenes with friction crept to a
        // standstill); sliding friction where the point has no anchor yet.
        if model.friction > 0.0 {
            let anchor = anchors.of(o).get(i).copied().unwrap_or(friction::NONE);
            let law = [kc, dc, model.friction];
            let (depth, n) = (c.depth, c.normal);
            let tangent = friction::obstacle_tangent(p, v, depth, n, anchor, law, c_max, h);
            add_tangent(e, n, tangent);
            if let Some(g) = friction::limit_growth(tangent.1, law, h) {
                growth(g, n);
            }
        }
    }
}

/// The penalty springs that point `i` is clear of at the iterate's end position `p` but that
/// the last whole Newton step took it into (at `q`): their `h²·kCollision·nnᵀ` too (the normal
/// at `q`), into `e`. Without them a point landing on a surface is clear of it at each iterate
/// and driven into it by each Newton step, which the line search then cuts short: the point
/// creeps down to the surface over several iterations (the dropped 32³ cube's hardest step at
/// 1/60 s took 15 Newton iterations with the creep, 9 without; the job 1.48 → 1.38 Newton and
/// 20.7 → 19.6 conjugate-gradient iterations a step). Where the point then stays clear, the next
/// Newton step, with the spring in `A`, stops it short of the surface, and the one after leaves
/// the spring out again. Friction, which needs a contact at the iterate, is not anticipated.
fn add_anticipated(model: &Model, i: usize, p: Vec3, q: Vec3, h: f64, e: &mut Sym) {
    let clearance = model.clearance_of(i);
    let touch = |c: Option<ObstacleContact>| c.and_then(|c| c.less(clearance));
    let k = h * h * model.k_collision;
    // Each wall's contact has its own normal (one per wall crossed).
    for c in model
        .bounds
        .wall_contacts(q)
        .filter_map(|c| c.less(clearance))
    {
        let wall = |d: &ObstacleContact| d.normal == c.normal;
        if !model
            .bounds
            .wall_contacts(p)
            .filter_map(|c| c.less(clearance))
            .any(|d| wall(&d))
        {
            add_outer(e, c.normal, k);
        }
    }
    let surfaces = model.plane.iter().map(|pl| (pl.contact(p), pl.contact(q)));
    let obstacles = model.obstacles.iter().map(|o| (o.contact(p), o.contact(q)));
    for (at_p, at_q) in surfaces.chain(obstacles) {
        if let (None, Some(c)) = (touch(at_p), touch(at_q)) {
            add_outer(e, c.normal, k);
        }
    }
}

/// A block `K` on the displacement of a touch's sample relative to the other body,
/// `δ = Σ wᵢ xᵢ` (the weights sum to zero: the other body's are negated), as pairs of points:
/// `A += (w wᵀ) ⊗ K = Σ_{i<j} −wᵢwⱼ·[[K, −K], [−K, K]]` over the points `(i, j)` with weights
/// (a pair of the same body gets a negative block; their sum is the positive coupling).
fn add_coupling(
    (rows, blocks): (&mut Vec<[u32; 2]>, &mut Vec<Sym>),
    points: &[u32; 16],
    weights: &[f64; 16],
    k: &Sym,
) {
    for i in 0..16 {
        if weights[i] == 0.0 {
            continue;
        }
        for j in i + 1..16 {
            // A point in both cells (a body touching itself next to the sample's cell) pairs
            // with itself: its term `(x_i − x_j)ᵀ k (x_i − x_j)` is 0.
            if weights[j] == 0.0 || points[j] == points[i] {
                continue;
            }
            let c = -weights[i] * weights[j];
            rows.push([points[i], points[j]]);
            blocks.push(k.map(|k| k * c));
        }
    }
}

/// `m += c·(I − nnᵀ − eeᵀ)` for friction's part of `A` across the unit normal `n`, given as `c`
/// and `e` (see [`friction::obstacle_tangent`]).
pub(super) fn add_tangent(m: &mut Sym, n: Vec3, (c, e): (f64, Option<Vec3>)) {
    if c == 0.0 {
        return;
    }
    m[..3].iter_mut().for_each(|m| *m += c);
    add_outer(m, n, -c);
    if let Some(e) = e {
        add_outer(m, e, -c);
    }
}

/// A spring's block of `A` (without its damper): `axial·uuᵀ + transverse·(I − uuᵀ)` (what
/// the stencil's assembly computes; its tests compare with it).
#[cfg(test)]
pub(super) fn spring_block(u: Vec3, axial: f64, transverse: f64) -> Sym {
    let mut m = [transverse, transverse, transverse, 0.0, 0.0, 0.0];
    add_outer(&mut m, u, axial - transverse);
    m
}

/// The field's stiffness at `p` for `A`: minus the symmetric part of its gradient (a field has
/// no potential, so its gradient need not be symmetric, and `A` must be), made positive
/// semi-definite by adding its Gershgorin bound on the smallest eigenvalue when that is negative.
/// A field that pulls towards a point (stiffer there than the masses) needs it, or Newton's
/// method crawls.
fn field_stiffness(&[dx, dy, dz]: &[Vec3; 3]) -> Sym {
    let mut k: Sym = [
        -dx.x,
        -dy.y,
        -dz.z,
        -0.5 * (dy.x + dx.y),
        -0.5 * (dz.x + dx.z),
        -0.5 * (dz.y + dy.z),
    ];
    let lowest = (k[0] - k[3].abs() - k[4].abs())
        .min(k[1] - k[3].abs() - k[5].abs())
        .min(k[2] - k[4].abs() - k[5].abs());
    if lowest < 0.0 {
        k[..3].iter_mut().for_each(|k| *k -= lowest);
    }
    k
}

/// What `A` needs besides the field's stiffness in `extra` for the field's exact gradient
/// `J` (`gradient[j]` the derivative along axis `j`), `−J − k`, row-major (N/m).
fn field_correction(gradient: &[Vec3; 3], k: &Sym) -> [f64; 9] {
    let jacobian = |i: usize, j: usize| gradient[j].to_array()[i];
    let sym = |i: usize, j: usize| match (i, j) {
        (0, 0) | (1, 1) | (2, 2) => k[i],
        (0, 1) | (1, 0) => k[3],
        (0, 2) | (2, 0) => k[4],
        _ => k[5],
    };
    std::array::from_fn(|e| {
        let (i, j) = (e / 3, e % 3);
        -jacobian(i, j) - sym(i, j)
    })
}

/// True when friction in the model may slide at its full size on a wall, the inclined plane or
/// an obstacle (then `A` may take its growth with depth, and the solver holds GMRES's basis and
/// room for that part at every point: see [`friction::limit_growth`]).
pub(super) fn can_slide(model: &Model) -> bool {
    model.wall_friction > 0.0 || (model.friction > 0.0 && !model.obstacles.is_empty())
}

/// True when the model's field may swirl past [`SWIRL_LIMIT`] at a step of size `h`: the
/// field's largest swirl ([`ForceField::max_swirl`](crate::ForceField::max_swirl)) times `h²`
/// over the lightest point mass (an SDIRK2 stage is shorter than `h`). Only then does the solver
/// hold GMRES's basis and the field's corrections (for `h = dt`), and take turns between the two
/// kinds of `A`.
pub(super) fn can_swirl(model: &Model, h: f64) -> bool {
    let lightest = model
        .bodies()
        .iter()
        .map(|b| b.material.mass)
        .fold(f64::INFINITY, f64::min);
    model
        .field
        .as_ref()
        .is_some_and(|f| h * h * f.max_swirl() / lightest > SWIRL_LIMIT)
}
