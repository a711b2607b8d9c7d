//! What a rejected step reports ([`BlowUp`]), and the checks that reject it: every position and
//! velocity finite, no point further outside the box than the model's escape margin.

use std::fmt;

use crate::integrate::stability;
use crate::model::integrator::Integrator;
use crate::model::Model;
use crate::state::State;
use crate::vec3::Vec3;

/// What went wrong when a step was rejected.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum BlowUpCause {
    /// A position or velocity became NaN or infinite.
    NonFinite,
    /// A point went further outside the box than the escape margin; holds its position.
    Escaped(Vec3),
    /// The implicit solve did not converge: the residual reached (m/s, `max |g|`, see
    /// [`crate::integrate::implicit`]) after so many Newton iterations.
    NotConverged {
        /// Residual reached (m/s).
        residual: f64,
        /// Newton iterations taken.
        iterations: u32,
        /// The tolerance it was to reach (m/s, before scaling by the largest speed).
        tolerance: f64,
        /// Halvings of the step the solve was on: its size was `dt/2^halvings` (see
        /// [`crate::integrate::cutback`]).
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

crate::compute::simd::multiversion! {
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
