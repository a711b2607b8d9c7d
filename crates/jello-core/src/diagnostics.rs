//! Quantities read off a state, never mixed into stepping: energies, penetration, momentum, and
//! points that passed through an obstacle between two states.

use crate::model::Model;
use crate::state::State;
use crate::vec3::Vec3;

pub use crate::contact::obstacles::max_penetration;
pub use crate::contact::tunnel_warning::{crossing_warning, sunk_warning, through_warning, Knobs};
pub use crate::contact::tunnelling::{
    bodies_sunk, obstacles_through, Crossings, Sunk, Through, TunnelWatch,
};

/// Mechanical energy (J) of a state. The force field is not a potential, so its work is not part
/// of it: with a field, the total changes by the work the field does.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct Energy {
    /// `Σ ½ m |v|²`.
    pub kinetic: f64,
    /// `Σ ½ k (|L| − R)²` over the lattice springs.
    pub spring: f64,
    /// `Σ ½ kCollision depth²` over the box, plane, obstacle and body-to-body penalty springs,
    /// and under self-contact the cells' guard's energy (see [`crate::contact::cell_guard`]).
    pub collision: f64,
}

impl Energy {
    /// Kinetic plus potential energy.
    pub fn total(&self) -> f64 {
        self.kinetic + self.spring + self.collision
    }
}

/// Energy of `state` under `model`, over the active points of every body.
pub fn energy(model: &Model, state: &State) -> Energy {
    let (mut kinetic, mut spring, mut collision) = (0.0, 0.0, 0.0);
    for body in model.bodies() {
        let (pos, vel) = (&state.pos[body.points()], &state.vel[body.points()]);
        let active = |&(q, _): &(usize, &Vec3)| body.is_active(q);
        kinetic += 0.5
            * body.material.mass
            * vel
                .iter()
                .enumerate()
                .filter(active)
                .map(|(_, v)| v.length_squared())
                .sum::<f64>();
        // Summed in spring-list order.
        body.for_each_spring(|s| {
            let stretch = (pos[s.a] - pos[s.b]).length() - s.rest;
            spring += 0.5 * s.stiffness * stretch * stretch;
        });
        // ½ kCollision depth² per contact (walls, plane, obstacles; each point's clearance
        // taken off), summed point by point.
        let first = body.points().start;
        collision += pos
            .iter()
            .enumerate()
            .filter(active)
            .map(|(q, &p)| {
                model
                    .contacts_of(first + q, p)
                    .fold(0.0, |sum, c| sum + c.depth * c.depth)
            })
            .sum::<f64>()
            * 0.5
            * model.k_collision;
    }
    if model.surfaces_touch() {
        collision += crate::contact::overlap(model, &state.pos).1;
        collision += crate::contact::cell_guard::energy(model, &state.pos);
    }
    Energy {
        kinetic,
        spring,
        collision,
    }
}

/// Centre of the points `pos` (m): the centre of mass when every point has the same mass.
pub fn centre_of_mass(pos: &[Vec3]) -> Vec3 {
    let sum = pos.iter().fold(Vec3::ZERO, |acc, &p| acc + p);
    sum / pos.len() as f64
}

/// Centre of mass (m) of one body's active points at positions `pos` (the model's arrays).
pub fn body_centre_of_mass(model: &Model, body: usize, pos: &[Vec3]) -> Vec3 {
    let body = model.body(body);
    let first = body.points().start;
    let sum = (0..body.len())
        .filter(|&q| body.is_active(q))
        .fold(Vec3::ZERO, |acc, q| acc + pos[first + q]);
    sum / body.active_count() as f64
}

/// Centre of mass (m) of every body's active points at positions `pos`: for one body, exactly
/// [`body_centre_of_mass`].
pub fn model_centre_of_mass(model: &Model, pos: &[Vec3]) -> Vec3 {
    if let [_] = model.bodies() {
        return body_centre_of_mass(model, 0, pos);
    }
    let (sum, mass) = (0..model.bodies().len()).fold((Vec3::ZERO, 0.0), |(sum, mass), b| {
        let m = model.body(b).total_mass();
        (sum + body_centre_of_mass(model, b, pos) * m, mass + m)
    });
    sum / mass
}

/// Total linear momentum (kg·m/s) of every body's active points.
pub fn momentum(model: &Model, vel: &[Vec3]) -> Vec3 {
    model.bodies().iter().fold(Vec3::ZERO, |total, body| {
        let first = body.points().start;
        let sum = (0..body.len())
            .filter(|&q| body.is_active(q))
            .fold(Vec3::ZERO, |acc, q| acc + vel[first + q]);
        total + sum * body.material.mass
    })
}
