//! Quantities read off a state, never mixed into stepping: energies, penetration, momentum.

use crate::model::Model;
use crate::state::State;
use crate::vec3::Vec3;

pub use crate::forces::max_penetration;

/// Mechanical energy (J) of a state. The force field is not a potential, so its work is not part
/// of it: with a field, the total changes by the work the field does.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Energy {
    /// `Σ ½ m |v|²`.
    pub kinetic: f64,
    /// `Σ ½ k (|L| − R)²` over the lattice springs.
    pub spring: f64,
    /// `Σ ½ kCollision depth²` over the box and plane penalty springs.
    pub collision: f64,
}

impl Energy {
    /// Kinetic plus potential energy.
    pub fn total(&self) -> f64 {
        self.kinetic + self.spring + self.collision
    }
}

/// Energy of `state` under `model`.
pub fn energy(model: &Model, state: &State) -> Energy {
    let kinetic = 0.5 * model.mass * state.vel.iter().map(|v| v.length_squared()).sum::<f64>();
    // Summed in spring-list order.
    let mut spring = 0.0;
    model.lattice.for_each_spring(|a, b, rest, kind| {
        let stretch = (state.pos[a] - state.pos[b]).length() - rest;
        spring += 0.5 * model.stiffness[kind as usize] * stretch * stretch;
    });
    // ½ kCollision depth² per contact (walls, plane, obstacles), summed point by point.
    let collision = state
        .pos
        .iter()
        .map(|&p| {
            model
                .bounds
                .wall_contacts(p)
                .chain(model.plane.and_then(|pl| pl.contact(p)))
                .chain(model.obstacles.iter().filter_map(|o| o.contact(p)))
                .fold(0.0, |sum, c| sum + c.depth * c.depth)
        })
        .sum::<f64>()
        * 0.5
        * model.k_collision;
    Energy {
        kinetic,
        spring,
        collision,
    }
}

/// Centre of mass (m); every point has the same mass.
pub fn centre_of_mass(pos: &[Vec3]) -> Vec3 {
    let sum = pos.iter().fold(Vec3::ZERO, |acc, &p| acc + p);
    sum / pos.len() as f64
}

/// Total linear momentum (kg·m/s).
pub fn momentum(model: &Model, vel: &[Vec3]) -> Vec3 {
    vel.iter().fold(Vec3::ZERO, |acc, &v| acc + v) * model.mass
}
