//! One step of the chosen integrator, with blow-up detection at the step boundary.
//!
//! Every integrator writes the new state into scratch buffers; the state is replaced only when
//! every new position and velocity is finite and no point has escaped the box by more than the
//! model's escape margin. So after a [`BlowUp`] the state still holds the last good step, and
//! nothing non-finite ever reaches a caller, a renderer or a saved file.

use std::fmt;

use crate::forces::accelerations;
use crate::integrator::Integrator;
use crate::model::Model;
use crate::stability;
use crate::state::{Control, State};
use crate::vec3::Vec3;

/// Buffers the integrators work in, sized once for a model: stepping never allocates.
#[derive(Clone, Debug, Default)]
pub struct Scratch {
    acc: Vec<Vec3>,
    stage_pos: Vec<Vec3>,
    stage_vel: Vec<Vec3>,
    sum_pos: Vec<Vec3>,
    sum_vel: Vec<Vec3>,
    next_pos: Vec<Vec3>,
    next_vel: Vec<Vec3>,
}

impl Scratch {
    /// Buffers for a model's point count.
    pub fn new(model: &Model) -> Self {
        let z = vec![Vec3::ZERO; model.point_count()];
        Scratch {
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
    if scratch.acc.len() != n {
        *scratch = Scratch::new(model);
    }
    let dt = model.dt;
    let (p, v) = (&state.pos[..], &state.vel[..]);
    let s = scratch;
    match model.integrator {
        Integrator::Euler => {
            accelerations(model, p, v, control, &mut s.acc);
            for i in 0..n {
                s.next_pos[i] = p[i] + v[i] * dt;
                s.next_vel[i] = v[i] + s.acc[i] * dt;
            }
        }
        Integrator::SymplecticEuler => {
            accelerations(model, p, v, control, &mut s.acc);
            for i in 0..n {
                s.next_vel[i] = v[i] + s.acc[i] * dt;
                s.next_pos[i] = p[i] + s.next_vel[i] * dt;
            }
        }
        Integrator::Rk2 => {
            // Midpoint: k1 at y, then the whole step with the slope at y + dt/2·k1.
            let h = dt * 0.5;
            accelerations(model, p, v, control, &mut s.acc);
            for i in 0..n {
                s.stage_pos[i] = p[i] + v[i] * h;
                s.stage_vel[i] = v[i] + s.acc[i] * h;
            }
            accelerations(model, &s.stage_pos, &s.stage_vel, control, &mut s.acc);
            for i in 0..n {
                s.next_pos[i] = p[i] + s.stage_vel[i] * dt;
                s.next_vel[i] = v[i] + s.acc[i] * dt;
            }
        }
        Integrator::Rk4 => {
            // Stages at y, y + dt/2·k1, y + dt/2·k2, y + dt·k3; the sums accumulate
            // k1 + 2k2 + 2k3 + k4 in that order. A stage's position slope is its velocity.
            let h = dt * 0.5;
            accelerations(model, p, v, control, &mut s.acc);
            for i in 0..n {
                s.sum_pos[i] = v[i];
                s.sum_vel[i] = s.acc[i];
                s.stage_pos[i] = p[i] + v[i] * h;
                s.stage_vel[i] = v[i] + s.acc[i] * h;
            }
            for stage_step in [h, dt] {
                accelerations(model, &s.stage_pos, &s.stage_vel, control, &mut s.acc);
                for i in 0..n {
                    let (kp, kv) = (s.stage_vel[i], s.acc[i]);
                    s.sum_pos[i] += kp * 2.0;
                    s.sum_vel[i] += kv * 2.0;
                    s.stage_pos[i] = p[i] + kp * stage_step;
                    s.stage_vel[i] = v[i] + kv * stage_step;
                }
            }
            accelerations(model, &s.stage_pos, &s.stage_vel, control, &mut s.acc);
            let w = dt / 6.0;
            for i in 0..n {
                s.next_pos[i] = p[i] + (s.sum_pos[i] + s.stage_vel[i]) * w;
                s.next_vel[i] = v[i] + (s.sum_vel[i] + s.acc[i]) * w;
            }
        }
    }

    // Step boundary: accept the new state only if it is sound.
    if let Some((point, cause)) = find_blow_up(model, &s.next_pos, &s.next_vel) {
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
    std::mem::swap(&mut state.pos, &mut s.next_pos);
    std::mem::swap(&mut state.vel, &mut s.next_vel);
    state.time += dt;
    state.steps += 1;
    Ok(())
}

/// The first point whose position or velocity is not finite, or that is further outside the box
/// than the escape margin.
fn find_blow_up(model: &Model, pos: &[Vec3], vel: &[Vec3]) -> Option<(usize, BlowUpCause)> {
    pos.iter().zip(vel).enumerate().find_map(|(i, (&p, &v))| {
        if !(p.is_finite() && v.is_finite()) {
            Some((i, BlowUpCause::NonFinite))
        } else if model.bounds.excursion(p) > model.escape_margin {
            Some((i, BlowUpCause::Escaped(p)))
        } else {
            None
        }
    })
}
