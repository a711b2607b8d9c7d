//! One step of the chosen integrator, with blow-up detection at the step boundary.
//!
//! Every integrator writes the new state into scratch buffers; the state is replaced only when
//! every new position and velocity is finite and no point has escaped the box by more than the
//! model's escape margin. So after a [`BlowUp`] the state still holds the last good step, and
//! nothing non-finite ever reaches a caller, a renderer or a saved file.

use std::fmt;

use crate::cutback::Cutback;
use crate::forces::{force_pass, ForceScratch, PARALLEL_MIN_POINTS};
use crate::implicit::ImplicitScratch;
use crate::integrator::Integrator;
use crate::model::Model;
use crate::soa::Soa;

use crate::stability;
use crate::state::{Control, State};
use crate::vec3::Vec3;

/// Buffers the integrators work in, sized once for a model: stepping never allocates. The
/// integrators work in structures of arrays (see [`crate::soa`]) and write the step's result as
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
    /// How often implicit steps were taken in parts (see [`crate::cutback`]) since these
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

/// What went wrong when a step was rejected.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BlowUpCause {
    /// A position or velocity became NaN or infinite.
    NonFinite,
    /// A point went further outside the box than the escape margin; holds its position.
    Escaped(Vec3),
    /// The implicit solve did not converge: the residual reached (m/s, `max |g|`, see
    /// [`crate::implicit`]) after so many Newton iterations.
    NotConverged {
        /// Residual reached (m/s).
        residual: f64,
        /// Newton iterations taken.
        iterations: u32,
        /// The tolerance it was to reach (m/s, before scaling by the largest speed).
        tolerance: f64,
        /// Halvings of the step the solve was on: its size was `dt/2^halvings` (see
        /// [`crate::cutback`]).
        halvings: u32,
    },
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
    /// The body it belongs to (0 for the first).
    pub body: u32,
    /// Lattice coordinates of that point in its body.
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
        if let BlowUpCause::NotConverged {
            residual,
            iterations,
            tolerance,
            halvings,
        } = self.cause
        {
            let [i, j, k] = self.point_ijk;
            write!(
                f,
                "the implicit solve did not converge at step {} (t = {:.6} s): residual \
                 {residual:.3e} m/s, largest at point {} ({i}, {j}, {k}), after {iterations} \
                 Newton iterations",
                self.step, self.time, self.point
            )?;
            if halvings > 0 {
                write!(f, " on a substep of dt/{}", 1u64 << halvings)?;
            }
            return write!(
                f,
                " (the tolerance is {tolerance:.0e} m/s); {} with dt = {} s: try a smaller --dt",
                self.integrator, self.dt
            );
        }
        let [i, j, k] = self.point_ijk;
        write!(
            f,
            "simulation blew up at step {} (t = {:.6} s): point {} ({i}, {j}, {k}) ",
            self.step, self.time, self.point
        )?;
        if self.body > 0 {
            write!(f, "of body {} ", self.body + 1)?;
        }
        match self.cause {
            BlowUpCause::NonFinite => f.write_str("has a non-finite position or velocity")?,
            BlowUpCause::Escaped(p) => write!(
                f,
                "is more than {} m outside the box, at ({:.3e}, {:.3e}, {:.3e})",
                self.escape_margin, p.x, p.y, p.z
            )?,
            BlowUpCause::NotConverged { .. } => unreachable!("written above"),
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
/// by one. On a blow-up the state is unchanged and the error says where and what to try. An
/// implicit step that fails is first taken again in parts ([`crate::cutback`]).
///
/// Stepping allocates nothing. On lattices large enough for threads, the step runs on a team of
/// the rayon pool's threads ([`crate::team`]): call it from inside the pool (`ThreadPool::install`
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
        return crate::cutback::step(model, state, control, scratch);
    }
    // Large lattices step on a team of threads (the caller's, as in `Simulation::advance`, else
    // one for this step), each thread keeping its part of the lattice from pass to pass.
    let sound = match model.point_count() >= PARALLEL_MIN_POINTS {
        true => crate::team::run(|| integrate(model, state, control, scratch)),
        false => integrate(model, state, control, scratch),
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

/// The report of a step (the state's next one) whose result `pos`, `vel` is not sound, taken
/// with time step `dt`.
pub(crate) fn unsound(model: &Model, state: &State, pos: &[Vec3], vel: &[Vec3], dt: f64) -> BlowUp {
    let (point, cause) =
        find_blow_up(model, pos, vel).expect("an unsound state has a point at fault");
    let (body, point_ijk) = model.locate(point);
    BlowUp {
        step: state.steps + 1,
        time: state.time,
        point,
        body: body as u32,
        point_ijk,
        cause,
        integrator: model.integrator,
        dt,
        suggested_dt: stability::suggest_dt(model),
        escape_margin: model.escape_margin,
    }
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

/// One step of an explicit integrator from `state` into `s.next_pos` and `s.next_vel`; whether the
/// result is sound (every value finite, no point beyond the escape margin).
///
/// Each force evaluation is one [`force_pass`]: the integrator's update for a block of points
/// (and, in the last stage, the soundness check) runs right after the block's accelerations are
/// known, while its data is in cache, and writes into buffers other than the ones the pass reads.
/// The updates are element-wise per component and compiled for AVX-512 too (`multiversion!`).
fn integrate(model: &Model, state: &State, control: &Control, s: &mut Scratch) -> bool {
    let dt = model.dt;
    s.pos.team_copy_from(&state.pos);
    s.vel.team_copy_from(&state.vel);
    let Scratch {
        force,
        pos,
        vel,
        stage_pos,
        stage_vel,
        sum_vel,
        next_pos,
        next_vel,
        implicit: _,
        cutback: _,
    } = s;
    let (p, v) = (&*pos, &*vel);
    let sound = |np: &[Vec3], nv: &[Vec3]| block_is_sound(model, np, nv);
    let next = (&mut next_pos[..], &mut next_vel[..]);
    match model.integrator {
        Integrator::Euler => {
            force_pass(model, p, v, control, force, next, &|first, (np, nv), a| {
                let r = first..first + a[0].len();
                let (bp, bv) = (p.range(r.clone()), v.range(r));
                step_end_block(np, nv, bp, bv, bv, a, dt);
                sound(np, nv)
            })
        }
        Integrator::SymplecticEuler => {
            force_pass(model, p, v, control, force, next, &|first, (np, nv), a| {
                let r = first..first + a[0].len();
                let (bp, bv) = (p.range(r.clone()), v.range(r));
                symplectic_end_block(np, nv, bp, bv, a, dt);
                sound(np, nv)
            })
        }
        Integrator::Rk2 => {
            // Midpoint: k1 at y, then the whole step with the slope at y + dt/2·k1.
            let h = dt * 0.5;
            let mid = (stage_pos[0].parts_mut(), stage_vel[0].parts_mut());
            force_pass(model, p, v, control, force, mid, &|first, (sp, sv), a| {
                let r = first..first + a[0].len();
                let (bp, bv) = (p.range(r.clone()), v.range(r));
                for c in 0..3 {
                    axpy_block(sp[c], bp[c], bv[c], h);
                    axpy_block(sv[c], bv[c], a[c], h);
                }
                true
            });
            let (sp, sv) = (&stage_pos[0], &stage_vel[0]);
            force_pass(
                model,
                sp,
                sv,
                control,
                force,
                next,
                &|first, (np, nv), a| {
                    let r = first..first + a[0].len();
                    let (bp, bv, bsv) = (p.range(r.clone()), v.range(r.clone()), sv.range(r));
                    step_end_block(np, nv, bp, bv, bsv, a, dt);
                    sound(np, nv)
                },
            )
        }
        Integrator::Rk4 => {
            // Stages at y, y + dt/2·k1, y + dt/2·k2, y + dt·k3, each pass reading one stage and
            // writing the next. A stage's position slope is its velocity, so the end sums the
            // stage velocities kept in `stage_vel`; the velocity slopes (accelerations) are summed
            // as the stages go, k1 + 2k2 + 2k3, in `sum_vel`.
            let h = dt * 0.5;
            let [sp24, sp3] = stage_pos;
            let [sv2, sv3, sv4] = stage_vel;
            let to = (sum_vel.parts_mut(), (sp24.parts_mut(), sv2.parts_mut()));
            force_pass(
                model,
                p,
                v,
                control,
                force,
                to,
                &|first, (sum_v, (sp, sv)), a| {
                    let r = first..first + a[0].len();
                    let (bp, bv) = (p.range(r.clone()), v.range(r));
                    for c in 0..3 {
                        rk4_first_block(sum_v[c], sp[c], sv[c], bp[c], bv[c], a[c], h);
                    }
                    true
                },
            );
            let mut middle =
                |sp: &Soa, sv: &Soa, step: f64, sum_v: &mut Soa, to_p: &mut Soa, to_v: &mut Soa| {
                    let to = (sum_v.parts_mut(), (to_p.parts_mut(), to_v.parts_mut()));
                    force_pass(model, sp, sv, control, force, to, &|first, outs, a| {
                        let (sum_v, (to_p, to_v)): ([&mut [f64]; 3], _) = outs;
                        let r = first..first + a[0].len();
                        let (bp, bv, bsv) = (p.range(r.clone()), v.range(r.clone()), sv.range(r));
                        for c in 0..3 {
                            let to = [&mut *to_p[c], &mut *to_v[c]];
                            rk4_middle_block(sum_v[c], to, [bp[c], bv[c]], [bsv[c], a[c]], step);
                        }
                        true
                    })
                };
            middle(sp24, sv2, h, sum_vel, sp3, sv3);
            middle(sp3, sv3, dt, sum_vel, sp24, sv4);
            let (sv2, sv3, sum_v) = (&*sv2, &*sv3, &*sum_vel);
            force_pass(
                model,
                sp24,
                sv4,
                control,
                force,
                next,
                &|first, (np, nv), a| {
                    let r = first..first + a[0].len();
                    let (bp, bv) = (p.range(r.clone()), v.range(r.clone()));
                    let velocities = [sv2, sv3, &*sv4].map(|s| s.range(r.clone()));
                    let bsum_v = sum_v.range(r);
                    rk4_end_block(np, nv, [bp, bv], velocities, [bsum_v, a], dt / 6.0);
                    sound(np, nv)
                },
            )
        }
        Integrator::BackwardEuler | Integrator::Sdirk2 => {
            unreachable!("the implicit steps are taken by step()")
        }
    }
}

crate::simd::multiversion! {
    /// `out = a + b·h`, element by element.
    fn axpy_block(out: &mut [f64], a: &[f64], b: &[f64], h: f64) {
        let (a, b) = (&a[..out.len()], &b[..out.len()]);
        for i in 0..out.len() {
            out[i] = a[i] + b[i] * h;
        }
    }
}

crate::simd::multiversion! {
    /// The first RK4 stage once `k1 = (v, a)` is known: the acceleration sum starts at `a`, and
    /// the next stage is `y + h·k1`.
    fn rk4_first_block(
        sum_v: &mut [f64],
        sp: &mut [f64],
        sv: &mut [f64],
        p: &[f64],
        v: &[f64],
        a: &[f64],
        h: f64,
    ) {
        let n = sum_v.len();
        let (sp, sv, p, v, a) = (&mut sp[..n], &mut sv[..n], &p[..n], &v[..n], &a[..n]);
        for i in 0..n {
            sum_v[i] = a[i];
            sp[i] = p[i] + v[i] * h;
            sv[i] = v[i] + a[i] * h;
        }
    }
}

crate::simd::multiversion! {
    /// An RK4 middle stage once its slope `k = (k_p, k_v)` (the stage's velocity and
    /// acceleration) is known: add twice `k_v` to the acceleration sum, and write the next stage,
    /// `y + step·k`, to `to`.
    fn rk4_middle_block(
        sum_v: &mut [f64],
        to: [&mut [f64]; 2],
        y: [&[f64]; 2],
        k: [&[f64]; 2],
        step: f64,
    ) {
        let n = sum_v.len();
        let [to_p, to_v] = to.map(|s| &mut s[..n]);
        let [p, v] = y.map(|s| &s[..n]);
        let [kp, kv] = k.map(|s| &s[..n]);
        for i in 0..n {
            sum_v[i] += kv[i] * 2.0;
            to_p[i] = p[i] + kp[i] * step;
            to_v[i] = v[i] + kv[i] * step;
        }
    }
}

crate::simd::multiversion! {
    /// The end of a step with slopes `kp` (of position) and `kv` (of velocity):
    /// `(p + kp·dt, v + kv·dt)`, written to the next state.
    fn step_end_block(
        np: &mut [Vec3],
        nv: &mut [Vec3],
        p: [&[f64]; 3],
        v: [&[f64]; 3],
        kp: [&[f64]; 3],
        kv: [&[f64]; 3],
        dt: f64,
    ) {
        let n = np.len();
        let nv = &mut nv[..n];
        let ([px, py, pz], [vx, vy, vz]) = (p.map(|c| &c[..n]), v.map(|c| &c[..n]));
        let ([kx, ky, kz], [ax, ay, az]) = (kp.map(|c| &c[..n]), kv.map(|c| &c[..n]));
        for i in 0..n {
            np[i] = Vec3::new(px[i] + kx[i] * dt, py[i] + ky[i] * dt, pz[i] + kz[i] * dt);
            nv[i] = Vec3::new(vx[i] + ax[i] * dt, vy[i] + ay[i] * dt, vz[i] + az[i] * dt);
        }
    }
}

crate::simd::multiversion! {
    /// The end of a symplectic Euler step: the velocity first, `v + a·dt`, then the position
    /// with the new velocity, written to the next state.
    fn symplectic_end_block(
        np: &mut [Vec3],
        nv: &mut [Vec3],
        p: [&[f64]; 3],
        v: [&[f64]; 3],
        a: [&[f64]; 3],
        dt: f64,
    ) {
        let n = np.len();
        let nv = &mut nv[..n];
        let ([px, py, pz], [vx, vy, vz]) = (p.map(|c| &c[..n]), v.map(|c| &c[..n]));
        let [ax, ay, az] = a.map(|c| &c[..n]);
        for i in 0..n {
            let w = Vec3::new(vx[i] + ax[i] * dt, vy[i] + ay[i] * dt, vz[i] + az[i] * dt);
            nv[i] = w;
            np[i] = Vec3::new(px[i] + w.x * dt, py[i] + w.y * dt, pz[i] + w.z * dt);
        }
    }
}

crate::simd::multiversion! {
    /// The end of an RK4 step, written to the next state: the position moves by
    /// `w·(v + 2 v2 + 2 v3 + v4)` with the stage velocities `v2, v3, v4`, the velocity by
    /// `w·(sum + a4)` with the acceleration sum `k1 + 2k2 + 2k3`; `w = dt/6`.
    fn rk4_end_block(
        np: &mut [Vec3],
        nv: &mut [Vec3],
        y: [[&[f64]; 3]; 2],
        stage_vel: [[&[f64]; 3]; 3],
        acc: [[&[f64]; 3]; 2],
        w: f64,
    ) {
        let n = np.len();
        let nv = &mut nv[..n];
        let [[px, py, pz], [vx, vy, vz]] = y.map(|y| y.map(|c| &c[..n]));
        let [[ax2, ay2, az2], [ax3, ay3, az3], [ax4, ay4, az4]] =
            stage_vel.map(|s| s.map(|c| &c[..n]));
        let [[sx, sy, sz], [kx, ky, kz]] = acc.map(|s| s.map(|c| &c[..n]));
        // The same sums, in the same order, as k1 + 2k2 + 2k3 + k4 accumulated stage by stage.
        let slope = |v: f64, v2: f64, v3: f64, v4: f64| ((v + v2 * 2.0) + v3 * 2.0) + v4;
        for i in 0..n {
            np[i] = Vec3::new(
                px[i] + slope(vx[i], ax2[i], ax3[i], ax4[i]) * w,
                py[i] + slope(vy[i], ay2[i], ay3[i], ay4[i]) * w,
                pz[i] + slope(vz[i], az2[i], az3[i], az4[i]) * w,
            );
            nv[i] = Vec3::new(
                vx[i] + (sx[i] + kx[i]) * w,
                vy[i] + (sy[i] + ky[i]) * w,
                vz[i] + (sz[i] + kz[i]) * w,
            );
        }
    }
}

crate::simd::multiversion! {
    /// True when every position and velocity of a block is finite and no point is further
    /// outside the box than the escape margin. Branch-free, so it vectorises; [`find_blow_up`]
    /// then names the point when it is false.
    pub(crate) fn block_is_sound(model: &Model, pos: &[Vec3], vel: &[Vec3]) -> bool {
        let m = model.escape_margin;
        let (lo, hi) = (model.bounds.min, model.bounds.max);
        let (lo, hi) = ([lo.x - m, lo.y - m, lo.z - m], [hi.x + m, hi.y + m, hi.z + m]);
        let mut bad = false;
        for (p, v) in pos.iter().zip(vel) {
            // NaN fails every comparison, so it is caught too; an infinite velocity is not
            // finite.
            let inside = (p.x >= lo[0] && p.x <= hi[0])
                & (p.y >= lo[1] && p.y <= hi[1])
                & (p.z >= lo[2] && p.z <= hi[2]);
            let finite = v.x.is_finite() & v.y.is_finite() & v.z.is_finite();
            bad |= !inside | !finite;
        }
        !bad
    }
}

/// The first point whose position or velocity is not finite, or that is further outside the box
/// than the escape margin: by the same comparisons as [`block_is_sound`].
fn find_blow_up(model: &Model, pos: &[Vec3], vel: &[Vec3]) -> Option<(usize, BlowUpCause)> {
    let (lo, hi, m) = (model.bounds.min, model.bounds.max, model.escape_margin);
    let inside = |c: f64, lo: f64, hi: f64| c >= lo - m && c <= hi + m;
    (0..pos.len()).find_map(|i| {
        let (p, v) = (pos[i], vel[i]);
        if !(p.is_finite() && v.is_finite()) {
            Some((i, BlowUpCause::NonFinite))
        } else if !(inside(p.x, lo.x, hi.x) && inside(p.y, lo.y, hi.y) && inside(p.z, lo.z, hi.z)) {
            Some((i, BlowUpCause::Escaped(p)))
        } else {
            None
        }
    })
}
