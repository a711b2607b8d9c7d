//! The residual `g` of the backward-Euler equations at an iterate, and the merit the line search
//! judges a trial by: the incremental potential's fall, computed term by term from differences.

use crate::compute::team;
use crate::forces::{force_pass_with, ForceScratch, Ties};
use crate::model::Model;
use crate::state::Control;
use crate::vec3::Vec3;

use super::cg::sum_chunk;
use super::contacts;
use super::newton::over_chunks;
use super::sym::{sym_mul, Sym};
use super::{chunk_size, ImplicitScratch};

/// Points, and springs, per chunk of [`potential_fall`]'s sums (fixed: the chunks decide the
/// order of the additions).
const FALL_CHUNK: usize = 4096;

/// Chunks of [`potential_fall`] for `points` points and `springs` springs.
pub(super) fn fall_chunks(points: usize, springs: usize) -> usize {
    points.max(springs).div_ceil(FALL_CHUNK)
}

/// The residual `g` of the iterate (or, when `trial`, of the trial point) into `s.g` (or
/// `s.g_trial`); returns `|g|²_M` there (a non-finite value gives infinity, which the line
/// search never accepts).
#[allow(clippy::too_many_arguments)]
pub(super) fn residual(
    model: &Model,
    control: &Control,
    force: &mut ForceScratch,
    s: &mut ImplicitScratch,
    x0: &[Vec3],
    v0: &[Vec3],
    h: f64,
    trial: bool,
) -> f64 {
    // At rest (a step's first iterate where a body rests on a floor), no damper acts: the
    // springs' forces alone (see `Dampers::AtRest`), and no dampers' forces from the step's
    // start. The same bits, but for the signs of zeros. The test, in chunks over the team, ends
    // each chunk at its first point that moves.
    let v = if trial { &s.trial } else { &s.v };
    let (moving, chunks) = over_chunks(v.len(), &|at| v[at].iter().any(|v| *v != Vec3::ZERO));
    let at_rest = !moving[..chunks].contains(&true);
    {
        let size = chunk_size(x0.len());
        let parts = (s.x_soa.parts_mut(), s.velocity_soa.parts_mut());
        team::for_each_chunk_pair(parts, size, &|chunk, (x, velocity)| {
            let at = chunk * size;
            ends_chunk(&x0[at..], &v[at..], h, x, velocity);
        });
        // The field at the end positions, for the line search's work of the field.
        let field = if trial {
            &mut s.field_trial
        } else {
            &mut s.field
        };
        if let (Some(f), true) = (&model.field, has_potential(model)) {
            for (out, (&x, &v)) in field.iter_mut().zip(x0.iter().zip(v)) {
                *out = f.sample(x + v * h);
            }
        }
    }
    // Every force but friction and the dampers of walls, planes, obstacles and pulls: at zero
    // velocity, without the friction ties, the springs' dampers along their directions at the
    // step's start, at the iterate's velocities.
    force_pass_with(
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
        Ties::Ignored {
            start: s.springs.start(),
            velocity: (!at_rest).then_some(&s.velocity_soa),
        },
    );
    // The other dampers' force (from the step's start) and friction, into the residual buffer
    // first.
    let mut g = std::mem::take(if trial { &mut s.g_trial } else { &mut s.g });
    let v = if trial { &s.trial } else { &s.v };
    let (damping, size) = (&s.start_damping[..], chunk_size(g.len()));
    team::for_each_chunk([&mut g[..]], size, &|chunk, [g]| match at_rest {
        true => g.fill(Vec3::ZERO),
        false => damper_forces_chunk(&damping[chunk * size..], &v[chunk * size..], g),
    });
    for pull in &control.pulls {
        let p = pull.point as usize;
        g[p] -= v[p] * pull.damping;
    }
    contacts::add_forces(
        model,
        force.anchors(),
        &s.start_touches,
        &s.x_soa,
        &s.touched_at,
        v,
        &s.mass,
        &s.free,
        &mut g,
    );
    // `g` and `|g|²_M`, over the team: each chunk of `sum_chunk` points summed in order, then
    // the chunks' sums in order (the same bits on any number of threads).
    let (ax, ay, az) = (s.acc.x(), s.acc.y(), s.acc.z());
    let (mass, free) = (&s.mass[..], &s.free[..]);
    let size = sum_chunk(g.len());
    team::for_each_chunk_into([&mut g[..]], size, &mut s.dots, &|chunk, [g]| {
        let at = chunk * size..chunk * size + g.len();
        let a = [&ax[at.clone()], &ay[at.clone()], &az[at.clone()]];
        let points = (
            &v[at.clone()],
            &v0[at.clone()],
            &mass[at.clone()],
            &free[at],
        );
        residual_chunk(a, points, h, g)
    });
    let norm: f64 = s.dots.iter().sum();
    if trial {
        s.g_trial = g;
    } else {
        s.g = g;
    }
    if norm.is_finite() {
        norm
    } else {
        f64::INFINITY
    }
}

crate::compute::simd::multiversion! {
    /// The end positions `x0 + h·v` and the velocities `v` of a chunk's points into `x` and
    /// `velocity` (structure of arrays; as many points as they hold).
    fn ends_chunk(x0: &[Vec3], v: &[Vec3], h: f64, x: [&mut [f64]; 3], velocity: [&mut [f64]; 3]) {
        let ([xx, xy, xz], [vx, vy, vz]) = (x, velocity);
        for (i, (&x, &v)) in x0.iter().zip(v).take(xx.len()).enumerate() {
            let p = x + v * h;
            (xx[i], xy[i], xz[i]) = (p.x, p.y, p.z);
            (vx[i], vy[i], vz[i]) = (v.x, v.y, v.z);
        }
    }
}

crate::compute::simd::multiversion! {
    /// The dampers' force from the step's start, `−D₀·v`, of a chunk's points into `g`.
    fn damper_forces_chunk(damping: &[Sym], v: &[Vec3], g: &mut [Vec3]) {
        for ((g, d), &v) in g.iter_mut().zip(damping).zip(v) {
            *g = -sym_mul(d, v);
        }
    }
}

crate::compute::simd::multiversion! {
    /// A chunk's residual `g = v − v₀ − h·a`, `a` the forces' accelerations `a` plus the
    /// forces in `g` over the masses (at moving points), and its `|g|²_M`.
    fn residual_chunk(
        a: [&[f64]; 3],
        points: (&[Vec3], &[Vec3], &[f64], &[f64]),
        h: f64,
        g: &mut [Vec3],
    ) -> f64 {
        let ([ax, ay, az], (v, v0, mass, free)) = (a, points);
        let mut norm = 0.0;
        for (i, g) in g.iter_mut().enumerate() {
            let a = Vec3::new(ax[i], ay[i], az[i]) + *g * (free[i] / mass[i]);
            *g = v[i] - v0[i] - a * h;
            norm += mass[i] * g.length_squared();
        }
        norm
    }
}

/// The work of the field from the iterate's end positions to the trial's (J), by the trapezoid
/// rule: its part of the potential's fall (see [`potential_fall`]). A field that is not uniform
/// has no potential; along a line this is the work that would be its potential's fall, to
/// second order, and its slope at the iterate is the field's part of `M·g·Δv`, as the line
/// search needs.
fn field_work(s: &ImplicitScratch, h: f64) -> f64 {
    let mut work = 0.0;
    for ((((&a, &b), &v), &t), &free) in s
        .field
        .iter()
        .zip(&s.field_trial)
        .zip(&s.v)
        .zip(&s.trial)
        .zip(&s.free)
    {
        work += free * 0.5 * (a + b).dot(t - v) * h;
    }
    work
}

/// True when the merit can be the incremental potential: no surfaces touching (contacts between
/// bodies and self-contact are found by a grid the merit does not have) and no friction ties; a field's part is added along
/// each line (see [`field_work`]).
pub(super) fn has_potential(model: &Model) -> bool {
    !model.surfaces_touch() && (model.friction == 0.0 || model.obstacles.is_empty())
}

/// How much the incremental potential `½|v − v₀|²_M + ½h·vᵀD₀v + U(x₀ + h·v)` falls from the
/// iterate `v` to the trial `t` (J; with [`field_work`], so that its slope is `−M·g·Δv`). Each
/// term's change is computed from the difference of its arguments (`a² − b² = (a − b)(a + b)`),
/// not as the difference of two sums: near the solution the fall is far below the rounding of
/// the potential itself, and the line search must still see it.
pub(super) fn potential_fall(
    model: &Model,
    control: &Control,
    s: &mut ImplicitScratch,
    x0: &[Vec3],
    v0: &[Vec3],
    h: f64,
) -> f64 {
    s.start_directions();
    let mut falls = std::mem::take(&mut s.falls);
    let fall = fall_by_chunks(model, control, s, &mut falls, x0, v0, h);
    s.falls = falls;
    fall
}

/// [`potential_fall`], summed over fixed chunks of [`FALL_CHUNK`] points and springs spread over
/// the team (their sums into `falls`), then the chunks' sums in order: the same bits on any
/// number of threads. Run by the leader alone, this pass over every spring took an eighth of the
/// 32³ benchmark's crushing steps on two threads (their line searches backtrack far), the other
/// thread waiting.
fn fall_by_chunks(
    model: &Model,
    control: &Control,
    s: &ImplicitScratch,
    falls: &mut [[f64; 3]],
    x0: &[Vec3],
    v0: &[Vec3],
    h: f64,
) -> f64 {
    let (v, t) = (&s.v[..], &s.trial[..]);
    let at = |p: usize, w: &[Vec3]| x0[p] + w[p] * h;
    let (points, springs) = (v.len(), s.rows.len());
    team::for_each_mut(falls, &|c, fall| {
        let [mut moved, mut stretched, mut outside] = [0.0; 3];
        // Kinetic part and the contacts' dampers; penalty springs, gravity and control forces,
        // on the moving points (the others do not move).
        for p in c * FALL_CHUNK..((c + 1) * FALL_CHUNK).min(points) {
            let step = t[p] - v[p];
            moved -= 0.5 * s.mass[p] * step.dot((t[p] - v0[p]) + (v[p] - v0[p]));
            moved -= 0.5 * h * step.dot(sym_mul(&s.start_damping[p], t[p] + v[p]));
            if s.free[p] != 0.0 {
                outside += contact_change(model, p, at(p, v), at(p, t), step * h);
                let mut push = model.gravity * s.mass[p];
                if let Some(f) = control.forces.get(p) {
                    push += *f;
                }
                moved += push.dot(step * h);
            }
        }
        // Springs and their dampers.
        let chunk = c * FALL_CHUNK..((c + 1) * FALL_CHUNK).min(springs);
        for (row, &u) in s.rows[chunk.clone()].iter().zip(&s.start_dir[chunk]) {
            let (a, b) = (row.a as usize, row.b as usize);
            let relative = (t[a] - v[a]) - (t[b] - v[b]);
            let (wv, wt) = (u.dot(v[a] - v[b]), u.dot(t[a] - t[b]));
            stretched -= 0.5 * h * row.d * u.dot(relative) * (wt + wv);
            let (dv, dt) = (at(a, v) - at(b, v), at(a, t) - at(b, t));
            let (lv, lt) = (dv.length(), dt.length());
            if lv + lt > 0.0 {
                let lengthening = (relative * h).dot(dt + dv) / (lt + lv);
                stretched -= 0.5 * row.k * lengthening * (lt + lv - 2.0 * row.rest);
            }
        }
        *fall = [moved, stretched, outside];
    });
    let mut fall = field_work(s, h);
    let mut outside = 0.0;
    for [moved, stretched, out] in &*falls {
        fall += moved + stretched;
        outside += out;
    }
    for pull in &control.pulls {
        let p = pull.point as usize;
        let step = t[p] - v[p];
        fall -= 0.5 * h * pull.damping * step.dot(t[p] + v[p]);
        let (xv, xt) = (at(p, v), at(p, t));
        fall -= 0.5 * pull.stiffness * (step * -h).dot((pull.target - xt) + (pull.target - xv));
    }
    fall - 0.5 * model.k_collision * outside
}

/// The change of point `i`'s `Σ depth²` over its contacts from `xv` to `xt = xv + step`: for
/// contacts with the same flat surface at both (the same normal), `(dₜ − dᵥ)(dₜ + dᵥ)` with
/// `dₜ − dᵥ = −n·step` exactly; otherwise the difference of the sums.
fn contact_change(model: &Model, i: usize, xv: Vec3, xt: Vec3, step: Vec3) -> f64 {
    let (mut at_v, mut at_t) = (model.contacts_of(i, xv), model.contacts_of(i, xt));
    let mut paired = 0.0;
    loop {
        match (at_v.next(), at_t.next()) {
            (None, None) => return paired,
            (Some(cv), Some(ct)) if cv.normal == ct.normal => {
                paired += -ct.normal.dot(step) * (ct.depth + cv.depth);
            }
            _ => break,
        }
    }
    let sum = |c: &mut dyn Iterator<Item = crate::model::obstacle::ObstacleContact>| {
        c.map(|c| c.depth * c.depth).sum::<f64>()
    };
    let whole_v = sum(&mut model.contacts_of(i, xv));
    let whole_t = sum(&mut model.contacts_of(i, xt));
    whole_t - whole_v
}
