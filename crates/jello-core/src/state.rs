//! [`State`], what the integrator advances, and [`Control`], per-step input from outside.

use crate::model::Model;
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

    /// The model's lattice at its rest positions, at rest.
    pub fn at_rest(model: &Model) -> Self {
        let pos = model.lattice.rest_positions();
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
    /// Extra force on each point (N), flat lattice index. Empty means none; otherwise its length
    /// is the point count.
    pub forces: Vec<Vec3>,
}

impl Control {
    /// No extra forces.
    pub fn none() -> Self {
        Control::default()
    }
}
