//! Backward Euler, the implicit integrator: stable at any time step.
//!
//! A step of size `h` finds the end velocity `v₁` with
//!
//! ```text
//! g(v₁) = v₁ − v₀ − h·M⁻¹·(f(x₀ + h·v₁) − D₀·v₁) = 0,        then x₁ = x₀ + h·v₁,
//! ```
//!
//! where `f` is every force of [`crate::forces`] but the dampers (springs, field, gravity, walls,
//! plane, obstacles with their friction ties, contacts between bodies, control forces, pulls),
//! at the end positions, and `D₀·v₁` the dampers' force: each spring's along its direction at the
//! step's start, each wall's, plane's and obstacle's along its normal for the points in contact
//! at the step's start, each pull's. Pinned and unused points keep their velocity. The dampers
//! are taken at the start because they switch on at a contact's surface with a jump of
//! `dCollision·|v·n|`: taken at the end, a point that reaches a surface during the step can
//! have no solution at all; and with their directions fixed, the equations are the stationarity
//! of the incremental potential `½|v − v₀|²_M + ½h·vᵀD₀v + U(x₀ + h·v)` whenever the other
//! forces have a potential `U`, which Newton's method can minimise. (Dampers between bodies
//! and on friction ties are not in `D₀` yet: in the implicit integrator those contacts are
//! undamped.) The scheme is first order; as `h → 0` it agrees with the explicit integrators.
//!
//! Newton's method: each iteration solves `A·Δv = −M·g` with `A = M + h·D₀ + h²·K`, `K` the
//! stiffness matrix of the springs (with a compressed spring's negative transverse stiffness,
//! or, when that leaves `A` not positive definite, clamped at zero), of the penalty springs the
//! point is in at the iterate (with an obstacle's friction ties along its surface) and of the
//! pulls, by conjugate gradients preconditioned with `A`'s 3×3 diagonal blocks; then a
//! backtracking line search on the incremental potential (one body and no friction: the common
//! case), or on `|g|²_M` otherwise.
//!
//! A step has converged when every point's residual `|g|` is at most [`TOLERANCE`] times
//! `max(1, max |v₁|)` (m/s; both settable, [`Model::newton`](crate::Model::newton)); then the
//! mass-weighted mean residual of the moving points is taken out of their velocities (the exact
//! solution has none), so internal forces conserve momentum to rounding. A step that does not
//! converge within [`MAX_NEWTON`] iterations (by default) is reported (the state stays at the
//! last good step) with the residual reached.
//!
//! Every loop here runs in a fixed order on the calling thread (the force evaluations are
//! bit-identical on any thread count), so results do not depend on the thread count; the buffers
//! are sized on the first implicit step and reused, so later steps do not allocate.

use crate::forces::{force_pass, ForceScratch};
use crate::model::Model;
use crate::soa::Soa;
use crate::state::{Control, State};
use crate::vec3::Vec3;

/// Converged when `max |g| ≤ TOLERANCE · max(1, max |v₁|)` (m/s), by default.
pub const TOLERANCE: f64 = 1e-9;

/// Newton iterations before a step is reported as not converged, by default.
pub const MAX_NEWTON: u32 = 60;

/// How closely a step is solved: converged when `max |g| ≤ tolerance · max(1, max |v₁|)`
/// (m/s), reported when that takes more than `max_iterations` Newton iterations.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Newton {
    /// m/s (> 0).
    pub tolerance: f64,
    /// At least 1.
    pub max_iterations: u32,
}

impl Default for Newton {
    fn default() -> Self {
        Newton {
            tolerance: TOLERANCE,
            max_iterations: MAX_NEWTON,
        }
    }
}

/// Conjugate-gradient iterations per Newton iteration, at most.
const MAX_CG: usize = 2000;

/// Conjugate gradients stop when the residual of `A·Δv = −M·g` has fallen by this factor.
const CG_REDUCTION: f64 = 1e-2;

/// Halvings of the Newton step before the line search gives up.
const MAX_HALVINGS: u32 = 30;

/// A symmetric 3×3 matrix: `[xx, yy, zz, xy, xz, yz]`.
type Sym = [f64; 6];

fn sym_mul(m: &Sym, v: Vec3) -> Vec3 {
    Vec3::new(
        m[0] * v.x + m[3] * v.y + m[4] * v.z,
        m[3] * v.x + m[1] * v.y + m[5] * v.z,
        m[4] * v.x + m[5] * v.y + m[2] * v.z,
    )
}

/// `m += c·n·nᵀ`.
fn add_outer(m: &mut Sym, n: Vec3, c: f64) {
    m[0] += c * n.x * n.x;
    m[1] += c * n.y * n.y;
    m[2] += c * n.z * n.z;
    m[3] += c * n.x * n.y;
    m[4] += c * n.x * n.z;
    m[5] += c * n.y * n.z;
}

/// The inverse of a symmetric positive definite 3×3 matrix.
fn sym_inverse(m: &Sym) -> Sym {
    let [a, d, f, b, c, e] = *m;
    // [[a b c] [b d e] [c e f]]
    let (c00, c01, c02) = (d * f - e * e, c * e - b * f, b * e - c * d);
    let det = a * c00 + b * c01 + c * c02;
    let inv = 1.0 / det;
    [
        c00 * inv,
        (a * f - c * c) * inv,
        (a * d - b * b) * inv,
        c01 * inv,
        c02 * inv,
        (b * c - a * e) * inv,
    ]
}

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

/// One spring's block of `A` at the current iterate: `axial·ûûᵀ + transverse·(I − ûûᵀ)` of its
/// stiffness, plus `damping·û₀û₀ᵀ` of its damper along its direction at the step's start.
#[derive(Clone, Copy, Debug, Default)]
struct Block {
    u: Vec3,
    axial: f64,
    transverse: f64,
    u0: Vec3,
    damping: f64,
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

/// The buffers of the implicit solver, sized on its first step for a model.
#[derive(Clone, Debug, Default)]
pub struct ImplicitScratch {
    rows: Vec<Row>,
    blocks: Vec<Block>,
    /// Each spring's direction at the step's start (zero for a spring of zero length).
    start_dir: Vec<Vec3>,
    /// The field's force on each point at the step's start (for the merit; see [`merit`]).
    start_field: Vec<Vec3>,
    /// Per point: mass (kg), and 1 for a point that moves, 0 for one pinned or unused.
    mass: Vec<f64>,
    free: Vec<f64>,
    /// Per point: the damping matrix `dCollision·Σ n nᵀ` of the walls, plane and obstacles it is
    /// in at the step's start.
    start_damping: Vec<Sym>,
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
    /// The force routine's inputs and output.
    x_soa: Soa,
    v_soa: Soa,
    acc: Soa,
}

impl ImplicitScratch {
    fn fits(&self, model: &Model) -> bool {
        self.mass.len() == model.point_count()
    }

    fn new(model: &Model) -> Self {
        let n = model.point_count();
        let zeros = vec![Vec3::ZERO; n];
        ImplicitScratch {
            rows: Vec::with_capacity(model.spring_count()),
            blocks: Vec::with_capacity(model.spring_count()),
            start_dir: Vec::with_capacity(model.spring_count()),
            start_field: vec![Vec3::ZERO; n],
            mass: vec![0.0; n],
            free: vec![0.0; n],
            start_damping: vec![[0.0; 6]; n],
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
            ap: zeros,
            x_soa: Soa::zeros(n),
            v_soa: Soa::zeros(n),
            acc: Soa::zeros(n),
        }
    }

    /// The model's springs, masses and free points, read afresh every step (a model may change
    /// between steps without changing its size).
    fn load(&mut self, model: &Model) {
        self.rows.clear();
        for body in model.bodies() {
            let first = body.points().start;
            body.for_each_spring(|s| {
                self.rows.push(Row {
                    a: (first + s.a) as u32,
                    b: (first + s.b) as u32,
                    rest: s.rest,
                    k: s.stiffness,
                    d: s.damping,
                })
            });
            for q in 0..body.len() {
                self.mass[first + q] = body.material.mass;
                self.free[first + q] = if body.is_active(q) { 1.0 } else { 0.0 };
            }
        }
        for &p in &model.pins {
            self.free[p as usize] = 0.0;
        }
        self.blocks.resize(self.rows.len(), Block::default());
        self.start_dir.resize(self.rows.len(), Vec3::ZERO);
    }

    /// The dampers at `x0` (the step's start): the springs' directions and the contacts each
    /// point is in.
    fn start_dampers(&mut self, model: &Model, x0: &[Vec3]) {
        for (row, u) in self.rows.iter().zip(self.start_dir.iter_mut()) {
            let d = x0[row.a as usize] - x0[row.b as usize];
            let l = d.length();
            *u = if l > 0.0 { d / l } else { Vec3::ZERO };
        }
        for (f, &p) in self.start_field.iter_mut().zip(x0) {
            *f = model
                .field
                .as_ref()
                .map_or(Vec3::ZERO, |field| field.sample(p));
        }
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

/// One backward-Euler step from `state` into `next_pos` and `next_vel` (not checked for
/// soundness here). `Err` when Newton's method did not converge.
pub(crate) fn step(
    model: &Model,
    state: &State,
    control: &Control,
    force: &mut ForceScratch,
    s: &mut ImplicitScratch,
    next_pos: &mut [Vec3],
    next_vel: &mut [Vec3],
) -> Result<(), NotConverged> {
    if !s.fits(model) {
        *s = ImplicitScratch::new(model);
    }
    s.load(model);
    let h = model.dt;
    let (x0, v0) = (&state.pos[..], &state.vel[..]);
    s.start_dampers(model, x0);
    // The forces but the dampers are evaluated at zero velocity.
    s.v_soa.fill_zero();
    s.v.copy_from_slice(v0);
    let (mut merit, mut norm2) = residual(model, control, force, s, x0, v0, h, false);
    let mut iterations = 0;
    loop {
        let (norm, vmax) = max_norms(&s.g, &s.v);
        if norm <= model.newton.tolerance * vmax.max(1.0) {
            break;
        }
        if iterations == model.newton.max_iterations {
            return Err(not_converged(&s.g, iterations));
        }
        iterations += 1;
        // The springs' true transverse stiffness first (a compressed spring's is negative, and
        // clamping it slows Newton's method down to a crawl on a crushed lattice); clamped at
        // zero when that makes A indefinite.
        assemble(model, control, s, x0, h, false);
        if !solve(s) {
            assemble(model, control, s, x0, h, true);
            solve(s);
        }
        // Backtrack until the merit falls enough (Armijo): its slope along Δv is M·g·Δv for the
        // incremental potential; for |g|²_M a plain decrease is asked.
        let slope: f64 = if has_potential(model) {
            s.g.iter()
                .zip(&s.dv)
                .zip(&s.mass)
                .map(|((g, d), m)| m * g.dot(*d))
                .sum()
        } else {
            0.0
        };
        let mut alpha = 1.0;
        let mut accepted = false;
        for _ in 0..=MAX_HALVINGS {
            for ((t, &v), &dv) in s.trial.iter_mut().zip(&s.v).zip(&s.dv) {
                *t = v + dv * alpha;
            }
            let (m, n2) = residual(model, control, force, s, x0, v0, h, true);
            // Near the solution the merit's decrease falls below its rounding, and at a
            // contact's kink it may not fall at all: a step that lowers the residual is taken
            // too.
            if m < merit + 1e-4 * alpha * slope.min(0.0) || n2 < norm2 {
                std::mem::swap(&mut s.v, &mut s.trial);
                std::mem::swap(&mut s.g, &mut s.g_trial);
                (merit, norm2) = (m, n2);
                accepted = true;
                break;
            }
            alpha *= 0.5;
        }
        if !accepted {
            return Err(not_converged(&s.g, iterations));
        }
    }
    // The exact solution has Σ m·g = 0 over the moving points (their momentum changes by h
    // times the force on them, which internal forces do not change): take the small mean
    // residual the tolerance allows out of their velocities, so that internal forces conserve
    // momentum to rounding rather than to the tolerance.
    let (mut mg, mut m) = (Vec3::ZERO, 0.0);
    for ((&g, &mass), &free) in s.g.iter().zip(&s.mass).zip(&s.free) {
        mg += g * (mass * free);
        m += mass * free;
    }
    let shift = if m > 0.0 { mg / m } else { Vec3::ZERO };
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

/// `max |g|` and `max |v|`.
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

fn max_norms(g: &[Vec3], v: &[Vec3]) -> (f64, f64) {
    let gmax = g.iter().map(|g| g.length()).fold(0.0, f64::max);
    let vmax = v.iter().map(|v| v.length()).fold(0.0, f64::max);
    (gmax, vmax)
}

/// The residual `g` of the iterate (or, when `trial`, of the trial point) into `s.g` (or
/// `s.g_trial`); returns the line search's merit there (see [`merit`]) and `|g|²_M` (a
/// non-finite value gives infinity, which the line search never accepts).
#[allow(clippy::too_many_arguments)]
fn residual(
    model: &Model,
    control: &Control,
    force: &mut ForceScratch,
    s: &mut ImplicitScratch,
    x0: &[Vec3],
    v0: &[Vec3],
    h: f64,
    trial: bool,
) -> (f64, f64) {
    {
        let v = if trial { &s.trial } else { &s.v };
        let [xx, xy, xz] = s.x_soa.parts_mut();
        for (i, (&x, &v)) in x0.iter().zip(v).enumerate() {
            let p = x + v * h;
            (xx[i], xy[i], xz[i]) = (p.x, p.y, p.z);
        }
    }
    // Every force but the dampers: at zero velocity.
    force_pass(
        model,
        &s.x_soa,
        &s.v_soa,
        control,
        force,
        s.acc.parts_mut(),
        &|_, out: [&mut [f64]; 3], a| {
            for (o, a) in out.into_iter().zip(a) {
                o.copy_from_slice(&a[..o.len()]);
            }
            true
        },
    );
    // The dampers' force −D₀·v, into the residual buffer first.
    let mut g = std::mem::take(if trial { &mut s.g_trial } else { &mut s.g });
    let v = if trial { &s.trial } else { &s.v };
    damper_force(control, s, v, &mut g);
    let (ax, ay, az) = (s.acc.x(), s.acc.y(), s.acc.z());
    for i in 0..g.len() {
        let a = Vec3::new(ax[i], ay[i], az[i]) + g[i] * (s.free[i] / s.mass[i]);
        g[i] = v[i] - v0[i] - a * h;
    }
    let m = merit(model, control, s, v, &g, v0, h);
    let norm: f64 = g
        .iter()
        .zip(&s.mass)
        .map(|(g, m)| m * g.length_squared())
        .sum();
    if trial {
        s.g_trial = g;
    } else {
        s.g = g;
    }
    let finite = |x: f64| if x.is_finite() { x } else { f64::INFINITY };
    (finite(m), finite(norm))
}

/// `out = −D₀·v`: the dampers' force at velocities `v` (N).
fn damper_force(control: &Control, s: &ImplicitScratch, v: &[Vec3], out: &mut [Vec3]) {
    for ((o, d), &v) in out.iter_mut().zip(&s.start_damping).zip(v) {
        *o = sym_mul(d, v) * -1.0;
    }
    for (row, &u) in s.rows.iter().zip(&s.start_dir) {
        let (a, b) = (row.a as usize, row.b as usize);
        let f = u * (row.d * u.dot(v[a] - v[b]));
        out[a] -= f;
        out[b] += f;
    }
    for pull in &control.pulls {
        let p = pull.point as usize;
        out[p] -= v[p] * pull.damping;
    }
}

/// True when the merit can be the incremental potential: one body (contacts between bodies are
/// found by a grid the merit does not have) and no friction ties. A field that is not uniform
/// has no potential; the merit takes its force at the step's start as constant, which is close
/// (the line search also takes any step that lowers the residual).
fn has_potential(model: &Model) -> bool {
    model.bodies().len() == 1 && (model.friction == 0.0 || model.obstacles.is_empty())
}

/// The line search's merit at `v` with residual `g`: the incremental potential
/// `½|v − v₀|²_M + ½h·vᵀD₀v + U(x₀ + h·v)` when the forces have a potential (its gradient is
/// `M·g`; a non-uniform field's, see [`has_potential`], nearly), else `|g|²_M`.
fn merit(
    model: &Model,
    control: &Control,
    s: &ImplicitScratch,
    v: &[Vec3],
    g: &[Vec3],
    v0: &[Vec3],
    h: f64,
) -> f64 {
    if !has_potential(model) {
        return g
            .iter()
            .zip(&s.mass)
            .map(|(g, m)| m * g.length_squared())
            .sum();
    }
    let x = |p: usize| Vec3::new(s.x_soa.x()[p], s.x_soa.y()[p], s.x_soa.z()[p]);
    let mut phi = 0.0;
    // Kinetic part and the dampers' ½h·vᵀD₀v.
    for p in 0..v.len() {
        let dv = v[p] - v0[p];
        phi += 0.5 * s.mass[p] * dv.length_squared();
        phi += 0.5 * h * v[p].dot(sym_mul(&s.start_damping[p], v[p]));
    }
    let mut spring = 0.0;
    for (row, &u) in s.rows.iter().zip(&s.start_dir) {
        let (a, b) = (row.a as usize, row.b as usize);
        let w = u.dot(v[a] - v[b]);
        phi += 0.5 * h * row.d * w * w;
        let stretch = (x(a) - x(b)).length() - row.rest;
        spring += 0.5 * row.k * stretch * stretch;
    }
    for pull in &control.pulls {
        let p = pull.point as usize;
        phi += 0.5 * h * pull.damping * v[p].length_squared();
        phi += 0.5 * pull.stiffness * (pull.target - x(p)).length_squared();
    }
    // Penalty springs, gravity, a uniform field and control forces, on the moving points (the
    // others do not move, so their terms are constant).
    let field = model
        .field
        .as_ref()
        .and_then(|f| f.uniform())
        .unwrap_or(Vec3::ZERO);
    let mut outside = 0.0;
    for p in (0..v.len()).filter(|&p| s.free[p] != 0.0) {
        let q = x(p);
        outside += model.contacts(q).map(|c| c.depth * c.depth).sum::<f64>();
        let mut push = model.gravity * s.mass[p] + field;
        if let Some(f) = control.forces.get(p) {
            push += *f;
        }
        phi -= push.dot(q);
    }
    phi + spring + 0.5 * model.k_collision * outside
}

/// The blocks of `A` at the iterate, the contact and pull parts, and the inverted diagonal.
fn assemble(
    model: &Model,
    control: &Control,
    s: &mut ImplicitScratch,
    x0: &[Vec3],
    h: f64,
    clamp: bool,
) {
    let h2 = h * h;
    let at = |p: usize, v: &[Vec3]| x0[p] + v[p] * h;
    for (i, e) in s.extra.iter_mut().enumerate() {
        *e = [0.0; 6];
        e[..3].fill(s.mass[i]);
    }
    for ((row, block), &u0) in s.rows.iter().zip(s.blocks.iter_mut()).zip(&s.start_dir) {
        let d = at(row.a as usize, &s.v) - at(row.b as usize, &s.v);
        let l = d.length();
        let damping = h * row.d;
        *block = if l > 0.0 {
            Block {
                u: d / l,
                axial: h2 * row.k,
                transverse: h2
                    * row.k
                    * (1.0 - row.rest / l).max(if clamp { 0.0 } else { f64::MIN }),
                u0,
                damping,
            }
        } else {
            Block {
                u0,
                damping,
                ..Block::default()
            }
        };
    }
    // Penalty springs of walls, plane and obstacles where the iterate is (friction ties act
    // along an obstacle's surface with the same stiffness), their dampers as at the start, and
    // pulls.
    let kc = model.k_collision;
    let tangential = if model.friction > 0.0 { h2 * kc } else { 0.0 };
    for (i, e) in s.extra.iter_mut().enumerate() {
        if s.free[i] == 0.0 {
            continue;
        }
        for (e, d) in e.iter_mut().zip(&s.start_damping[i]) {
            *e += h * d;
        }
        let p = at(i, &s.v);
        let walls = model
            .bounds
            .wall_contacts(p)
            .chain(model.plane.and_then(|pl| pl.contact(p)));
        for c in walls {
            add_outer(e, c.normal, h2 * kc);
        }
        for c in model.obstacles.iter().filter_map(|o| o.contact(p)) {
            // The normal's stiffness along it, the ties' (`tangential`) across it.
            add_outer(e, c.normal, h2 * kc - tangential);
            e[..3].iter_mut().for_each(|e| *e += tangential);
        }
    }
    for pull in &control.pulls {
        let e = &mut s.extra[pull.point as usize];
        let c = h * pull.damping + h2 * pull.stiffness;
        e[..3].iter_mut().for_each(|e| *e += c);
    }
    // The diagonal blocks: the point's own part plus each spring's block at both ends.
    s.diag_inv.copy_from_slice(&s.extra);
    for (row, b) in s.rows.iter().zip(&s.blocks) {
        let mut m = [b.transverse, b.transverse, b.transverse, 0.0, 0.0, 0.0];
        add_outer(&mut m, b.u, b.axial - b.transverse);
        add_outer(&mut m, b.u0, b.damping);
        for p in [row.a as usize, row.b as usize] {
            for (d, m) in s.diag_inv[p].iter_mut().zip(&m) {
                *d += m;
            }
        }
    }
    for d in s.diag_inv.iter_mut() {
        *d = sym_inverse(d);
    }
}

/// `y = A·x` over the free points (others give 0).
fn apply(s: &ImplicitScratch, x: &[Vec3], y: &mut [Vec3]) {
    for ((y, e), (&x, &f)) in y.iter_mut().zip(&s.extra).zip(x.iter().zip(&s.free)) {
        *y = sym_mul(e, x) * f;
    }
    for (row, b) in s.rows.iter().zip(&s.blocks) {
        let (a, c) = (row.a as usize, row.b as usize);
        let dx = x[a] - x[c];
        let along = b.u * b.u.dot(dx);
        let f = along * b.axial + (dx - along) * b.transverse + b.u0 * (b.damping * b.u0.dot(dx));
        y[a] += f * s.free[a];
        y[c] -= f * s.free[c];
    }
}

fn dot(a: &[Vec3], b: &[Vec3]) -> f64 {
    a.iter().zip(b).map(|(a, b)| a.dot(*b)).sum()
}

/// Solves `A·Δv = −M·g` into `s.dv` by preconditioned conjugate gradients, from zero; false
/// when `A` (or its diagonal) turns out not to be positive definite.
fn solve(s: &mut ImplicitScratch) -> bool {
    for i in 0..s.dv.len() {
        s.dv[i] = Vec3::ZERO;
        s.r[i] = s.g[i] * (-s.mass[i] * s.free[i]);
        s.z[i] = sym_mul(&s.diag_inv[i], s.r[i]) * s.free[i];
        s.p[i] = s.z[i];
    }
    let target = dot(&s.r, &s.r) * CG_REDUCTION * CG_REDUCTION;
    let mut rz = dot(&s.r, &s.z);
    if rz < 0.0 || !rz.is_finite() {
        return false;
    }
    for _ in 0..MAX_CG {
        if dot(&s.r, &s.r) <= target || rz == 0.0 {
            break;
        }
        let mut ap = std::mem::take(&mut s.ap);
        apply(s, &s.p, &mut ap);
        s.ap = ap;
        let pap = dot(&s.p, &s.ap);
        if pap <= 0.0 || !pap.is_finite() {
            return false;
        }
        let alpha = rz / pap;
        for i in 0..s.dv.len() {
            s.dv[i] += s.p[i] * alpha;
            s.r[i] -= s.ap[i] * alpha;
            s.z[i] = sym_mul(&s.diag_inv[i], s.r[i]) * s.free[i];
        }
        let rz_next = dot(&s.r, &s.z);
        if rz_next < 0.0 {
            return false;
        }
        let beta = rz_next / rz;
        rz = rz_next;
        for i in 0..s.p.len() {
            s.p[i] = s.z[i] + s.p[i] * beta;
        }
    }
    true
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_inverse_of_a_symmetric_matrix() {
        let m: Sym = [4.0, 5.0, 6.0, 1.0, 0.5, -0.7];
        let inv = sym_inverse(&m);
        for v in [Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.3, -2.0, 1.5)] {
            let back = sym_mul(&m, sym_mul(&inv, v));
            assert!((back - v).max_abs() < 1e-14, "{back:?}");
        }
    }
}
