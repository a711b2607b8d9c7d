//! The explicit integrators of docs/spec.md: Euler, RK2 (midpoint), RK4 and symplectic Euler. Each
//! stage is one [`force_pass`], whose blocks the integrator updates while they are in cache.

use super::blow_up::block_is_sound;
use super::scratch::Scratch;
use crate::compute::soa::Soa;
use crate::forces::force_pass;
use crate::model::integrator::Integrator;
use crate::model::Model;
use crate::state::{Control, State};
use crate::vec3::Vec3;

/// One step of an explicit integrator from `state` into `s.next_pos` and `s.next_vel`; whether the
/// result is sound (every value finite, no point beyond the escape margin).
///
/// Each force evaluation is one [`force_pass`]: the integrator's update for a block of points
/// (and, in the last stage, the soundness check) runs right after the block's accelerations are
/// known, while its data is in cache, and writes into buffers other than the ones the pass reads.
/// The updates are element-wise per component and compiled for AVX-512 too (`multiversion!`).
pub(super) fn integrate(model: &Model, state: &State, control: &Control, s: &mut Scratch) -> bool {
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

crate::compute::simd::multiversion! {
    /// `out = a + b·h`, element by element.
    fn axpy_block(out: &mut [f64], a: &[f64], b: &[f64], h: f64) {
        let (a, b) = (&a[..out.len()], &b[..out.len()]);
        for i in 0..out.len() {
            out[i] = a[i] + b[i] * h;
        }
    }
}

crate::compute::simd::multiversion! {
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

crate::compute::simd::multiversion! {
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

crate::compute::simd::multiversion! {
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

crate::compute::simd::multiversion! {
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

crate::compute::simd::multiversion! {
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
