//! The benchmark scene, built in code: what `jello bench`, the criterion benchmarks and the peer
//! implementations in `bench/peers` step.

use crate::model::field::ForceField;
use crate::model::integrator::Integrator;
use crate::model::lattice::Lattice;
use crate::model::{Aabb, Model, ModelBuilder, ModelError};
use crate::state::State;
use crate::vec3::Vec3;

/// The benchmark scene of `jello bench` (and of the peer implementations in `bench/peers`):
/// an `n × n × n` lattice of side 1 (spacing 1/(n−1)) centred in the box `[−2, 2]³`, kElastic 200,
/// dElastic 0.25, kCollision 400, dCollision 0.25, mass 1/512 per point at every `n`, every point
/// starting at velocity (10, −10, 20), gravity (0, 0, −9.81) as a uniform field of force
/// `mass·g`, no plane, dt 0.0005.
pub fn scene(n: usize, integrator: Integrator) -> Result<(Model, State), ModelError> {
    let mass = 1.0 / 512.0;
    let gravity = Vec3::new(0.0, 0.0, -9.81 * mass);
    let model = ModelBuilder::new()
        .lattice(Lattice::new([n, n, n], Vec3::new(1.0, 1.0, 1.0)))
        .elastic(200.0, 0.25)
        .collision(400.0, 0.25)
        .mass(mass)
        .field(Some(ForceField::from_fn(2, Aabb::classic(), |_| gravity)?))
        .dt(0.0005)
        .integrator(integrator)
        .build()?;
    let mut state = State::at_rest(&model);
    let centre = Vec3::new(0.5, 0.5, 0.5);
    state.pos.iter_mut().for_each(|p| *p -= centre);
    state
        .vel
        .iter_mut()
        .for_each(|v| *v = Vec3::new(10.0, -10.0, 20.0));
    Ok((model, state))
}
