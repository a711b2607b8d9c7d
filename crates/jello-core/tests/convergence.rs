//! Convergence order measured from the error at dt, dt/2, dt/4 against a fine RK4 reference:
//! Euler and symplectic Euler 1, RK2 2, RK4 4.

mod common;

use common::{deformed, max_diff, run};
use jello_core::{Integrator, Lattice, Model, ModelBuilder, State, Vec3};

/// A 4×4×4 jello, deformed and moving, well inside the box (collisions would make the forces
/// only continuous, not smooth, and spoil the orders).
fn model(integrator: Integrator, dt: f64) -> Model {
    ModelBuilder::new()
        .lattice(Lattice::new([4, 4, 4], Vec3::new(1.0, 1.0, 1.0)))
        .elastic(20.0, 0.05)
        .integrator(integrator)
        .dt(dt)
        .build()
        .unwrap()
}

fn initial(model: &Model) -> State {
    let mut pos = deformed(model, Vec3::new(-0.5, -0.5, -0.5), 0.05, 21);
    pos[63] += Vec3::new(0.15, 0.1, 0.12);
    let vel = pos
        .iter()
        .map(|p| Vec3::new(0.5, -0.3, 0.2) + Vec3::new(-p.y, p.x, 0.0))
        .collect();
    State::new(pos, vel)
}

/// Positions at time `t` with `integrator` at step `dt`.
fn solve(integrator: Integrator, dt: f64, t: f64) -> Vec<Vec3> {
    let m = model(integrator, dt);
    let mut state = initial(&m);
    run(&m, &mut state, (t / dt).round() as usize);
    state.pos
}

#[test]
fn observed_orders_match_the_theory() {
    let t = 0.04;
    let reference = solve(Integrator::Rk4, 2.5e-6, t);
    for (integrator, dt) in [
        (Integrator::Euler, 2e-4),
        (Integrator::SymplecticEuler, 2e-4),
        (Integrator::Rk2, 1e-3),
        (Integrator::Rk4, 4e-3),
    ] {
        let errors: Vec<f64> = [dt, dt / 2.0, dt / 4.0]
            .iter()
            .map(|&h| max_diff(&solve(integrator, h, t), &reference))
            .collect();
        let orders = [
            (errors[0] / errors[1]).log2(),
            (errors[1] / errors[2]).log2(),
        ];
        let expected = integrator.order() as f64;
        for order in orders {
            assert!(
                (order - expected).abs() < 0.25,
                "{integrator}: errors {errors:?}, observed orders {orders:?}, expected {expected}"
            );
        }
    }
}
