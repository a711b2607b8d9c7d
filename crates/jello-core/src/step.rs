//! One step of the chosen integrator, with blow-up detection at the step boundary.
//!
//! Every integrator writes the new state into scratch buffers; the state is replaced only when
//! every new position and velocity is finite and no point has escaped the box by more than the
//! model's escape margin. So after a [`BlowUp`] the state still holds the last good step, and
//! nothing non-finite ever reaches a caller, a renderer or a saved file.

use std::fmt;

use crate::forces::{accelerations_soa, ForceScratch, PARALLEL_MIN_POINTS};
use crate::integrator::Integrator;
use crate::model::Model;
use crate::soa::Soa;

use crate::stability;
use crate::state::{Control, State};
use crate::vec3::Vec3;
#[cfg(feature = "parallel")]
use rayon::prelude::*;

/// Buffers the integrators work in, sized once for a model: stepping never allocates. All are
/// structures of arrays (see [`crate::soa`]).
#[derive(Clone, Debug, Default)]
pub struct Scratch {
    force: ForceScratch,
    pos: Soa,
    vel: Soa,
    acc: Soa,
    stage_pos: Soa,
    stage_vel: Soa,
    sum_pos: Soa,
    sum_vel: Soa,
    next_pos: Soa,
    next_vel: Soa,
}

impl Scratch {
    /// Buffers for a model's point count.
    pub fn new(model: &Model) -> Self {
        let z = Soa::zeros(model.point_count());
        Scratch {
            force: ForceScratch::new(model),
            pos: z.clone(),
            vel: z.clone(),
            acc: z.clone(),
            stage_pos: z.clone(),
            stage_vel: z.clone(),
            sum_pos: z.clone(),
            sum_vel: z.clone(),
            next_pos: z.clone(),
            next_vel: z,
        }
    }
}

/// What went wrong when a step was rejected.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BlowUpCause {
    /// A position or velocity became NaN or infinite.
    NonFinite,
    /// A point went further outside the box than the escape margin; holds its position.
    Escaped(Vec3),
}

/// A step that was rejected because the state blew up. The state is left at the last good step.
#[derive(Clone, Debug, PartialEq)]
pub struct BlowUp {
    /// The rejected step, counted from 1 since the state was loaded.
    pub step: u64,
    /// Simulated time (s) at the start of the rejected step.
    pub time: f64,
    /// The first point (flat index) found at fault.
    pub point: usize,
    /// Lattice coordinates of that point.
    pub point_ijk: [usize; 3],
    /// What was found.
    pub cause: BlowUpCause,
    /// Integrator in use.
    pub integrator: Integrator,
    /// Time step in use (s).
    pub dt: f64,
    /// A time step likely to be stable (see [`stability::suggest_dt`]); `None` when no time step
    /// makes this integrator stable for the model.
    pub suggested_dt: Option<f64>,
    /// Escape margin of the model (m).
    pub escape_margin: f64,
}

impl fmt::Display for BlowUp {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let [i, j, k] = self.point_ijk;
        write!(
            f,
            "simulation blew up at step {} (t = {:.6} s): point {} ({i}, {j}, {k}) ",
            self.step, self.time, self.point
        )?;
        match self.cause {
            BlowUpCause::NonFinite => f.write_str("has a non-finite position or velocity")?,
            BlowUpCause::Escaped(p) => write!(
                f,
                "is more than {} m outside the box, at ({:.3e}, {:.3e}, {:.3e})",
                self.escape_margin, p.x, p.y, p.z
            )?,
        }
        write!(
            f,
            "; {} with dt = {} s is unstable here",
            self.integrator, self.dt
        )?;
        match self.suggested_dt {
            Some(dt) => write!(f, "; try --dt {dt}"),
            None => write!(
                f,
                "; {} is unstable at every dt for these springs (no damping): try RK4 or SymplecticEuler",
                self.integrator
            ),
        }
    }
}

impl std::error::Error for BlowUp {}

/// Advances `state` by one step of `model.integrator` with `model.dt`.
///
/// On success the state holds the new positions and velocities, `time` grows by `dt` and `steps`
/// by one. On a blow-up the state is unchanged and the error says where and what to try.
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
    let dt = model.dt;
    let sound = integrate(model, state, control, scratch);

    // Step boundary: accept the new state only if it is sound.
    let s = scratch;
    if !sound {
        let (point, cause) = find_blow_up(model, &s.next_pos, &s.next_vel)
            .expect("an unsound state has a point at fault");
        return Err(BlowUp {
            step: state.steps + 1,
            time: state.time,
            point,
            point_ijk: model.lattice.coords(point),
            cause,
            integrator: model.integrator,
            dt,
            suggested_dt: stability::suggest_dt(model),
            escape_margin: model.escape_margin,
        });
    }
    #[cfg(feature = "parallel")]
    if model.point_count() >= PARALLEL_MIN_POINTS {
        s.next_pos.par_copy_to(&mut state.pos);
        s.next_vel.par_copy_to(&mut state.vel);
    } else {
        s.next_pos.copy_to(&mut state.pos);
        s.next_vel.copy_to(&mut state.vel);
    }
    #[cfg(not(feature = "parallel"))]
    {
        s.next_pos.copy_to(&mut state.pos);
        s.next_vel.copy_to(&mut state.vel);
    }
    state.time += dt;
    state.steps += 1;
    Ok(())
}

/// One step of the integrator from `state` into `s.next_pos` and `s.next_vel`; whether the
/// result is sound (every value finite, no point beyond the escape margin).
///
/// The updates between force passes are element-wise over whole structure-of-arrays buffers
/// (x, y and z alike), so each is one loop, split into blocks for threads on large lattices;
/// every loop body is compiled for AVX-512 too (`multiversion!`).
fn integrate(model: &Model, state: &State, control: &Control, s: &mut Scratch) -> bool {
    let dt = model.dt;
    let par = model.point_count() >= PARALLEL_MIN_POINTS;
    #[cfg(feature = "parallel")]
    if par {
        s.pos.par_copy_from(&state.pos);
        s.vel.par_copy_from(&state.vel);
    } else {
        s.pos.copy_from(&state.pos);
        s.vel.copy_from(&state.vel);
    }
    #[cfg(not(feature = "parallel"))]
    {
        s.pos.copy_from(&state.pos);
        s.vel.copy_from(&state.vel);
    }
    let (p, v) = (&s.pos, &s.vel);
    match model.integrator {
        Integrator::Euler => {
            accelerations_soa(model, p, v, control, &mut s.acc, &mut s.force);
            axpy(par, s.next_pos.all_mut(), p.all(), v.all(), dt);
            axpy(par, s.next_vel.all_mut(), v.all(), s.acc.all(), dt);
        }
        Integrator::SymplecticEuler => {
            accelerations_soa(model, p, v, control, &mut s.acc, &mut s.force);
            axpy(par, s.next_vel.all_mut(), v.all(), s.acc.all(), dt);
            axpy(par, s.next_pos.all_mut(), p.all(), s.next_vel.all(), dt);
        }
        Integrator::Rk2 => {
            // Midpoint: k1 at y, then the whole step with the slope at y + dt/2·k1.
            let h = dt * 0.5;
            accelerations_soa(model, p, v, control, &mut s.acc, &mut s.force);
            axpy(par, s.stage_pos.all_mut(), p.all(), v.all(), h);
            axpy(par, s.stage_vel.all_mut(), v.all(), s.acc.all(), h);
            let (sp, sv) = (&s.stage_pos, &s.stage_vel);
            accelerations_soa(model, sp, sv, control, &mut s.acc, &mut s.force);
            axpy(par, s.next_pos.all_mut(), p.all(), sv.all(), dt);
            axpy(par, s.next_vel.all_mut(), v.all(), s.acc.all(), dt);
        }
        Integrator::Rk4 => {
            // Stages at y, y + dt/2·k1, y + dt/2·k2, y + dt·k3; the sums accumulate
            // k1 + 2k2 + 2k3 + k4 in that order. A stage's position slope is its velocity.
            let h = dt * 0.5;
            accelerations_soa(model, p, v, control, &mut s.acc, &mut s.force);
            s.sum_pos.copy_from_soa(v);
            s.sum_vel.copy_from_soa(&s.acc);
            axpy(par, s.stage_pos.all_mut(), p.all(), v.all(), h);
            axpy(par, s.stage_vel.all_mut(), v.all(), s.acc.all(), h);
            for stage_step in [h, dt] {
                let (sp, sv) = (&s.stage_pos, &s.stage_vel);
                accelerations_soa(model, sp, sv, control, &mut s.acc, &mut s.force);
                let sums = [s.sum_pos.all_mut(), s.sum_vel.all_mut()];
                let stage = [s.stage_pos.all_mut(), s.stage_vel.all_mut()];
                rk4_stage(
                    par,
                    sums,
                    stage,
                    [p.all(), v.all(), s.acc.all()],
                    stage_step,
                );
            }
            let (sp, sv) = (&s.stage_pos, &s.stage_vel);
            accelerations_soa(model, sp, sv, control, &mut s.acc, &mut s.force);
            let next = [s.next_pos.all_mut(), s.next_vel.all_mut()];
            let sums = [s.sum_pos.all(), s.sum_vel.all()];
            let k4 = [s.stage_vel.all(), s.acc.all()];
            rk4_finish(par, next, sums, k4, [p.all(), v.all()], dt / 6.0);
        }
    }
    is_sound(model, &s.next_pos, &s.next_vel)
}

/// Element-wise passes are split into blocks of this many numbers for threads.
#[cfg(feature = "parallel")]
const BLOCK: usize = 16 * 1024;

crate::simd::multiversion! {
    /// `out = a + b·h`, element by element.
    fn axpy_block(out: &mut [f64], a: &[f64], b: &[f64], h: f64) {
        let (a, b) = (&a[..out.len()], &b[..out.len()]);
        for i in 0..out.len() {
            out[i] = a[i] + b[i] * h;
        }
    }
}

/// `out = a + b·h`, element by element, in blocks on threads when `par`.
fn axpy(par: bool, out: &mut [f64], a: &[f64], b: &[f64], h: f64) {
    #[cfg(feature = "parallel")]
    if par {
        (
            out.par_chunks_mut(BLOCK),
            a.par_chunks(BLOCK),
            b.par_chunks(BLOCK),
        )
            .into_par_iter()
            .for_each(|(o, a, b)| axpy_block(o, a, b, h));
        return;
    }
    let _ = par;
    axpy_block(out, a, b, h);
}

crate::simd::multiversion! {
    /// An RK4 middle stage once its slope `(k_p, k_v) = (stage velocity, acceleration)` is known:
    /// add twice the slope to the sums, then move the stage to `y + stage_step·k`.
    fn rk4_stage_block(
        sum_p: &mut [f64],
        sum_v: &mut [f64],
        sp: &mut [f64],
        sv: &mut [f64],
        p: &[f64],
        v: &[f64],
        a: &[f64],
        stage_step: f64,
    ) {
        let n = sum_p.len();
        let (sum_v, sp, sv) = (&mut sum_v[..n], &mut sp[..n], &mut sv[..n]);
        let (p, v, a) = (&p[..n], &v[..n], &a[..n]);
        for i in 0..n {
            let (kp, kv) = (sv[i], a[i]);
            sum_p[i] += kp * 2.0;
            sum_v[i] += kv * 2.0;
            sp[i] = p[i] + kp * stage_step;
            sv[i] = v[i] + kv * stage_step;
        }
    }
}

/// [`rk4_stage_block`] over whole buffers, in blocks on threads when `par`.
fn rk4_stage(
    par: bool,
    [sum_p, sum_v]: [&mut [f64]; 2],
    [sp, sv]: [&mut [f64]; 2],
    [p, v, a]: [&[f64]; 3],
    stage_step: f64,
) {
    #[cfg(feature = "parallel")]
    if par {
        let blocks = (
            sum_p.par_chunks_mut(BLOCK),
            sum_v.par_chunks_mut(BLOCK),
            sp.par_chunks_mut(BLOCK),
            sv.par_chunks_mut(BLOCK),
            p.par_chunks(BLOCK),
            v.par_chunks(BLOCK),
            a.par_chunks(BLOCK),
        );
        blocks
            .into_par_iter()
            .for_each(|(s0, s1, s2, s3, p, v, a)| {
                rk4_stage_block(s0, s1, s2, s3, p, v, a, stage_step)
            });
        return;
    }
    let _ = par;
    rk4_stage_block(sum_p, sum_v, sp, sv, p, v, a, stage_step);
}

crate::simd::multiversion! {
    /// The end of an RK4 step: `y + dt/6·(k1 + 2k2 + 2k3 + k4)` from the sums and `k4`, with
    /// `w = dt/6`.
    fn rk4_finish_block(
        np: &mut [f64],
        nv: &mut [f64],
        sum_p: &[f64],
        sum_v: &[f64],
        k4p: &[f64],
        k4v: &[f64],
        p: &[f64],
        v: &[f64],
        w: f64,
    ) {
        let n = np.len();
        let nv = &mut nv[..n];
        let (sum_p, sum_v, k4p, k4v) = (&sum_p[..n], &sum_v[..n], &k4p[..n], &k4v[..n]);
        let (p, v) = (&p[..n], &v[..n]);
        for i in 0..n {
            np[i] = p[i] + (sum_p[i] + k4p[i]) * w;
            nv[i] = v[i] + (sum_v[i] + k4v[i]) * w;
        }
    }
}

/// [`rk4_finish_block`] over whole buffers, in blocks on threads when `par`.
fn rk4_finish(
    par: bool,
    [np, nv]: [&mut [f64]; 2],
    [sum_p, sum_v]: [&[f64]; 2],
    [k4p, k4v]: [&[f64]; 2],
    [p, v]: [&[f64]; 2],
    w: f64,
) {
    #[cfg(feature = "parallel")]
    if par {
        let blocks = (
            np.par_chunks_mut(BLOCK),
            nv.par_chunks_mut(BLOCK),
            sum_p.par_chunks(BLOCK),
            sum_v.par_chunks(BLOCK),
            k4p.par_chunks(BLOCK),
            k4v.par_chunks(BLOCK),
            p.par_chunks(BLOCK),
            v.par_chunks(BLOCK),
        );
        blocks
            .into_par_iter()
            .for_each(|(np, nv, sp, sv, kp, kv, p, v)| {
                rk4_finish_block(np, nv, sp, sv, kp, kv, p, v, w)
            });
        return;
    }
    let _ = par;
    rk4_finish_block(np, nv, sum_p, sum_v, k4p, k4v, p, v, w);
}

crate::simd::multiversion! {
/// True when every position and velocity is finite and no point is further outside the box than
/// the escape margin. Branch-free over all points, so it vectorises; [`find_blow_up`] then names
/// the point when it is false.
fn is_sound(model: &Model, pos: &Soa, vel: &Soa) -> bool {
    let (lo, hi, m) = (model.bounds.min, model.bounds.max, model.escape_margin);
    let mut bad = false;
    for (c, v, lo, hi) in [
        (pos.x(), vel.x(), lo.x, hi.x),
        (pos.y(), vel.y(), lo.y, hi.y),
        (pos.z(), vel.z(), lo.z, hi.z),
    ] {
        let (lo, hi) = (lo - m, hi + m);
        for (&c, &v) in c.iter().zip(v.iter()) {
            // NaN fails every comparison, so it is caught too; an infinite velocity is not
            // finite.
            let inside = c >= lo && c <= hi;
            bad |= !inside | !v.is_finite();
        }
    }
    !bad
}
}

/// The first point whose position or velocity is not finite, or that is further outside the box
/// than the escape margin: by the same comparisons as [`is_sound`].
fn find_blow_up(model: &Model, pos: &Soa, vel: &Soa) -> Option<(usize, BlowUpCause)> {
    let (lo, hi, m) = (model.bounds.min, model.bounds.max, model.escape_margin);
    let inside = |c: f64, lo: f64, hi: f64| c >= lo - m && c <= hi + m;
    (0..pos.len()).find_map(|i| {
        let (p, v) = (pos.get(i), vel.get(i));
        if !(p.is_finite() && v.is_finite()) {
            Some((i, BlowUpCause::NonFinite))
        } else if !(inside(p.x, lo.x, hi.x) && inside(p.y, lo.y, hi.y) && inside(p.z, lo.z, hi.z)) {
            Some((i, BlowUpCause::Escaped(p)))
        } else {
            None
        }
    })
}
