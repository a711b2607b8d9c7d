//! [`State`], what the integrator advances, and [`Control`], per-step input from outside.

use crate::model::{Model, ModelError};
use crate::vec3::Vec3;

/// Positions, velocities and time of every point (MuJoCo's mjData, without the scratch).
/// Cheap to clone, snapshot, restore and save.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Position of each point (m), flat lattice index; length = point count.
    pub pos: Vec<Vec3>,
    /// Velocity of each point (m/s), flat lattice index; length = point count.
    pub vel: Vec<Vec3>,
    /// Simulated time (s) since the state was loaded.
    pub time: f64,
    /// Steps taken since the state was loaded.
    pub steps: u64,
}

impl State {
    /// A state at time 0 from positions and velocities of equal length.
    pub fn new(pos: Vec<Vec3>, vel: Vec<Vec3>) -> Self {
        assert_eq!(
            pos.len(),
            vel.len(),
            "positions and velocities differ in length"
        );
        State {
            pos,
            vel,
            time: 0.0,
            steps: 0,
        }
    }

    /// Every body at its rest positions and placement, at rest.
    pub fn at_rest(model: &Model) -> Self {
        let pos: Vec<Vec3> = model
            .bodies()
            .iter()
            .flat_map(|b| b.rest_positions())
            .collect();
        let vel = vec![Vec3::ZERO; pos.len()];
        State::new(pos, vel)
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.pos.len()
    }

    /// True when the state has no points.
    pub fn is_empty(&self) -> bool {
        self.pos.is_empty()
    }
}

/// Forces applied from outside for the next steps (a user's drag, a script's push).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Control {
    /// Extra force on each point (N), flat lattice index, held constant through a step. Empty
    /// means none; otherwise its length is the point count.
    pub forces: Vec<Vec3>,
    /// Springs pulling single points toward targets, evaluated at every stage of a step (so an
    /// RK4 step sees the pull change as the point moves). A handful is cheap; each block of
    /// points scans the list.
    pub pulls: Vec<Pull>,
}

impl Control {
    /// No extra forces.
    pub fn none() -> Self {
        Control::default()
    }

    /// Fails when the forces are neither empty nor one per point or not finite, or a pull names
    /// a point the model does not have or has a value that is not finite (or a negative
    /// stiffness or damping). Front ends check a control they are handed with this:
    /// [`crate::step()`] panics on forces of the wrong length or a pull on a point that does not
    /// exist, and non-finite values make the step blow up.
    pub fn check(&self, model: &Model) -> Result<(), ModelError> {
        let n = model.point_count();
        if !(self.forces.is_empty() || self.forces.len() == n) {
            return Err(ModelError::new(format!(
                "control forces: {} given for {n} points (give none or one per point)",
                self.forces.len()
            )));
        }
        if let Some(f) = self.forces.iter().find(|f| !f.is_finite()) {
            return Err(ModelError::new(format!(
                "control forces must be finite ({f})"
            )));
        }
        for (i, pull) in self.pulls.iter().enumerate() {
            let ok = (pull.point as usize) < n
                && pull.target.is_finite()
                && pull.stiffness.is_finite()
                && pull.stiffness >= 0.0
                && pull.damping.is_finite()
                && pull.damping >= 0.0;
            if !ok {
                return Err(ModelError::new(format!(
                    "pull {}: point {} of {n}, target {}, stiffness {}, damping {}: expected an \
                     existing point, a finite target and finite stiffness and damping of at least 0",
                    i + 1,
                    pull.point,
                    pull.target,
                    pull.stiffness,
                    pull.damping
                )));
            }
        }
        Ok(())
    }
}

/// A spring from one point to a target position: `k (target − p) − d v` on the point (a zero
/// rest length spring with damping against the point's velocity).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Pull {
    /// The point pulled (flat lattice index).
    pub point: u32,
    /// Where it is pulled to (m).
    pub target: Vec3,
    /// Stiffness (N/m), at least 0.
    pub stiffness: f64,
    /// Damping (N·s/m), at least 0.
    pub damping: f64,
}

impl Pull {
    /// The pull's force (N) on its point at `p` moving at `v`.
    #[inline]
    pub fn force(&self, p: Vec3, v: Vec3) -> Vec3 {
        (self.target - p) * self.stiffness - v * self.damping
    }
}

/// The velocity at `p` of a rigid motion: translation at `v0` (m/s) plus rotation at `spin`
/// (rad/s) about `centre`, `v0 + spin × (p − centre)`. How `jello create` and scene files give a
/// body its initial velocity (`--velocity`, `--spin` about the centre of mass).
pub fn rigid_velocity(v0: Vec3, spin: Vec3, centre: Vec3, p: Vec3) -> Vec3 {
    v0 + spin.cross(p - centre)
}
