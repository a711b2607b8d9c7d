//! What a rejected step reports ([`BlowUp`]), and the checks that reject it: every position and
//! velocity finite, no point further outside the box than the model's escape margin.

use std::fmt;

use crate::contact::tunnelling::{deepest_sunk, Sunk};
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
    pub point_ijk: [u32; 3],
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
    /// The deepest two bodies were inside each other (or, under self-contact, one inside
    /// itself) in the last state before the step, where deeper than half the finer of their
    /// cells (see [`deepest_sunk`]): a body crushed by its load or thrown through another, which
    /// a shorter step alone does not cure. `None` where none was, or where it is not known (a
    /// GPU's steps). Boxed: a `BlowUp` is the error of every step's `Result`.
    pub sunk: Option<Box<Sunk>>,
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
            write!(
                f,
                " (the tolerance is {tolerance:.0e} m/s); {} with dt = {} s: try a smaller --dt",
                self.integrator, self.dt
            )?;
            return self.write_sunk(f);
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
            Some(dt) => write!(f, "; try --dt {dt}")?,
            None => write!(
                f,
                "; {} is unstable at every dt for these springs (no damping): try RK4 or SymplecticEuler",
                self.integrator
            )?,
        }
        self.write_sunk(f)
    }
}

impl BlowUp {
    /// What [`BlowUp::sunk`] says, after the rest of the message.
    fn write_sunk(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.sunk_note() {
            Some(note) => write!(f, ". {note}"),
            None => Ok(()),
        }
    }

    /// [`BlowUp::sunk`] in a sentence (without its full stop), where there is one: "Before the
    /// step bodies 1 and 2 were 13.1 cm inside each other, more than half of a 5 cm cell: …".
    pub fn sunk_note(&self) -> Option<String> {
        let s = self.sunk.as_deref()?;
        let cm = |m: f64| crate::vec3::significant(100.0 * m, 3);
        let [a, b] = s.bodies;
        let what = if a == b {
            format!("body {} was {} cm inside itself", a + 1, cm(s.depth))
        } else {
            format!(
                "bodies {} and {} were {} cm inside each other",
                a + 1,
                b + 1,
                cm(s.depth)
            )
        };
        Some(format!(
            "Before the step {what}, more than half of a {} cm cell: a body crushed by its load \
             or thrown through another, which a shorter step alone may not cure (a stiffer \
             material, a lighter load or a stiffer contact may)",
            cm(s.spacing)
        ))
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
        point_ijk: point_ijk.map(|c| c as u32),
        cause,
        integrator: model.integrator,
        dt,
        suggested_dt: stability::suggest_dt(model),
        escape_margin: model.escape_margin,
        sunk: deepest_sunk(model, &state.pos).map(Box::new),
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::body::{Body, Material, IDENTITY};
    use crate::model::lattice::Lattice;
    use crate::model::{Aabb, ModelBuilder};

    /// A blow-up after two bodies went deep into each other says so, with how deep and the
    /// cell; one after bodies apart says nothing of them.
    #[test]
    fn a_blow_up_names_bodies_deep_inside_each_other_before_it() {
        // Boxes 0.3 m on a side, their cells 0.1 m.
        let lattice = Lattice::new([4, 4, 4], Vec3::new(0.3, 0.3, 0.3));
        let bodies = [-0.5, 0.5].map(|x| {
            Body::lattice_box(lattice.clone(), Material::classic())
                .placed(Vec3::new(x, 0.0, 0.0), IDENTITY)
        });
        let model = ModelBuilder::new()
            .bodies(bodies.to_vec())
            .bounds(Aabb::new(Vec3::new(-2.0, -2.0, -2.0), Vec3::new(2.0, 2.0, 2.0)).unwrap())
            .collision(400.0, 0.3)
            .build()
            .unwrap();
        let apart = State::at_rest(&model);
        let mut sunk = apart.clone();
        // The second box moved 0.9 m towards the first: 0.2 m into it (their sides are 0.3 m),
        // its surface points up to 0.1 m inside.
        for q in model.bodies()[1].points() {
            sunk.pos[q].x -= 0.9;
        }
        let blown = |state: &State| {
            let mut pos = state.pos.clone();
            pos[3].y = f64::NAN;
            unsound(&model, state, &pos, &state.vel, model.dt)
        };
        let b = blown(&sunk);
        let s = b
            .sunk
            .as_deref()
            .expect("the boxes were 0.1 m inside each other");
        assert_eq!(s.bodies, [0, 1]);
        // (By the interpolated distance over its gradient: less than 0.1 m in the boxes' corners.)
        assert!(s.depth > 0.05 && s.depth <= 0.1 + 1e-9, "{}", s.depth);
        assert!((s.spacing - 0.1).abs() < 1e-12, "{}", s.spacing);
        let text = b.to_string();
        assert!(text.contains("has a non-finite position"), "{text}");
        let depth = crate::vec3::significant(100.0 * s.depth, 3);
        let said = format!(
            ". Before the step bodies 1 and 2 were {depth} cm inside each other, more than half \
             of a 10 cm cell: a body crushed by its load or thrown through another"
        );
        assert!(text.contains(&said), "{text}");
        let b = blown(&apart);
        assert_eq!(b.sunk, None);
        assert!(!b.to_string().contains("Before the step"), "{b}");
    }
}
