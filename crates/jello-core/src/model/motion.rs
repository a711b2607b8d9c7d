//! Pinned points moved along a given path, so a body can be shaken or carried: a [`Motion`] is an
//! offset from where the points start, as a function of time.
//!
//! **How it is imposed.** Pinned points never accelerate (see [`crate::Model::pins`]), so within a
//! step they move at the velocity they start it with. At the end of every step
//! ([`PinMotion::apply`]) each moving pin is put exactly where the path says: its position becomes
//! its position at the step's start plus the path's change over the step, and its velocity the
//! path's velocity at the step's end. Positions follow the path to rounding, with no drift
//! however long the run; within a step the pins' neighbours see them move in a straight line at
//! the step's starting velocity (a first-order approximation of a curved path, inside a step).

use crate::model::error::ModelError;
use crate::vec3::Vec3;

/// An offset (m) as a function of time (s), zero at `t = 0` for a shake.
#[derive(Clone, Debug, PartialEq)]
pub enum Motion {
    /// `amplitude · sin(2π · frequency · t)`: shaking back and forth about the start.
    Shake {
        /// Largest offset along each axis (m).
        amplitude: Vec3,
        /// Cycles per second (Hz), above 0.
        frequency: f64,
    },
    /// Straight lines between keyframes `(time, offset)`, times increasing: the first offset
    /// before the first time, the last after the last.
    Path(Vec<(f64, Vec3)>),
}

impl Motion {
    /// The offset at time `t`.
    pub fn offset(&self, t: f64) -> Vec3 {
        match self {
            Motion::Shake {
                amplitude,
                frequency,
            } => *amplitude * (std::f64::consts::TAU * frequency * t).sin(),
            Motion::Path(keys) => {
                let after = keys.partition_point(|&(k, _)| k <= t);
                match (after.checked_sub(1).map(|i| keys[i]), keys.get(after)) {
                    (None, _) => keys[0].1,
                    (Some((_, last)), None) => last,
                    (Some((t0, a)), Some(&(t1, b))) => a + (b - a) * ((t - t0) / (t1 - t0)),
                }
            }
        }
    }

    /// The velocity (m/s) at time `t`: the derivative of the offset (for a path, the slope of
    /// the segment `t` is in, counting a keyframe's time with the segment after it; zero outside
    /// the keyframes).
    pub fn velocity(&self, t: f64) -> Vec3 {
        match self {
            Motion::Shake {
                amplitude,
                frequency,
            } => {
                let w = std::f64::consts::TAU * frequency;
                *amplitude * (w * (w * t).cos())
            }
            Motion::Path(keys) => {
                let after = keys.partition_point(|&(k, _)| k <= t);
                match (after.checked_sub(1).map(|i| keys[i]), keys.get(after)) {
                    (Some((t0, a)), Some(&(t1, b))) => (b - a) / (t1 - t0),
                    _ => Vec3::ZERO,
                }
            }
        }
    }

    /// Fails for a value that is not finite, a frequency not above 0, an empty path, or
    /// keyframe times that do not increase.
    pub fn check(&self) -> Result<(), ModelError> {
        match self {
            Motion::Shake {
                amplitude,
                frequency,
            } => {
                if !(amplitude.is_finite() && frequency.is_finite() && *frequency > 0.0) {
                    return Err(ModelError::new(
                        "a shake needs a finite amplitude and a finite frequency above 0",
                    ));
                }
            }
            Motion::Path(keys) => {
                if keys.is_empty() {
                    return Err(ModelError::new("a path needs at least one keyframe"));
                }
                if keys.iter().any(|(t, p)| !t.is_finite() || !p.is_finite()) {
                    return Err(ModelError::new("path keyframes must be finite"));
                }
                if let Some(w) = keys.windows(2).find(|w| w[1].0 <= w[0].0) {
                    return Err(ModelError::new(format!(
                        "path keyframe times must increase ({} then {})",
                        w[0].0, w[1].0
                    )));
                }
            }
        }
        Ok(())
    }
}

/// Pinned points (flat indices, each also in [`crate::Model::pins`]) moving together along a
/// [`Motion`].
#[derive(Clone, Debug, PartialEq)]
pub struct PinMotion {
    /// The points moved.
    pub points: Vec<u32>,
    /// How they move.
    pub motion: Motion,
}

impl PinMotion {
    /// Puts the points where the motion has them at the end of a step from `t0` to `t1`: their
    /// positions `start` (at `t0`) plus the motion's change, into `pos`, and the motion's
    /// velocity at `t1` into `vel`.
    pub fn apply(&self, t0: f64, t1: f64, start: &[Vec3], pos: &mut [Vec3], vel: &mut [Vec3]) {
        let delta = self.motion.offset(t1) - self.motion.offset(t0);
        let v = self.motion.velocity(t1);
        for &p in &self.points {
            let p = p as usize;
            pos[p] = start[p] + delta;
            vel[p] = v;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_path_interpolates_its_keyframes_and_holds_the_ends() {
        let path = Motion::Path(vec![
            (0.5, Vec3::new(0.0, 0.0, 0.0)),
            (1.5, Vec3::new(1.0, -2.0, 0.0)),
            (2.0, Vec3::new(1.0, -2.0, 3.0)),
        ]);
        path.check().unwrap();
        assert_eq!(path.offset(0.0), Vec3::ZERO);
        assert_eq!(path.offset(1.0), Vec3::new(0.5, -1.0, 0.0));
        assert_eq!(path.offset(1.75), Vec3::new(1.0, -2.0, 1.5));
        assert_eq!(path.offset(9.0), Vec3::new(1.0, -2.0, 3.0));
        assert_eq!(path.velocity(1.0), Vec3::new(1.0, -2.0, 0.0));
        assert_eq!(path.velocity(1.5), Vec3::new(0.0, 0.0, 6.0));
        assert_eq!(path.velocity(0.2), Vec3::ZERO);
        assert_eq!(path.velocity(2.0), Vec3::ZERO);
        let backwards = Motion::Path(vec![(1.0, Vec3::ZERO), (1.0, Vec3::ZERO)]);
        assert!(backwards
            .check()
            .unwrap_err()
            .to_string()
            .contains("increase"));
        assert!(Motion::Path(vec![]).check().is_err());
    }

    #[test]
    fn a_shake_is_a_sine_with_its_derivative() {
        let a = Vec3::new(0.1, 0.0, -0.05);
        let shake = Motion::Shake {
            amplitude: a,
            frequency: 2.0,
        };
        shake.check().unwrap();
        assert_eq!(shake.offset(0.0), Vec3::ZERO);
        assert!((shake.offset(0.125) - a).max_abs() < 1e-15);
        let h = 1e-6;
        let numeric = (shake.offset(0.3 + h) - shake.offset(0.3 - h)) / (2.0 * h);
        assert!((numeric - shake.velocity(0.3)).max_abs() < 1e-8);
        let bad = Motion::Shake {
            amplitude: a,
            frequency: 0.0,
        };
        assert!(bad.check().is_err());
    }
}
