//! Invariants: Newton's third law, momentum, energy drift ordered by accuracy, damping settles.

mod common;

use common::{deformed, run, Lcg};
use jello_core::diagnostics::{energy, momentum};
use jello_core::forces::accelerations;
use jello_core::{Control, Integrator, ModelBuilder, State, Vec3};

/// Spring forces come in equal and opposite central pairs: they sum to zero and exert no torque.
#[test]
fn internal_forces_sum_to_zero() {
    let model = ModelBuilder::new().build().unwrap();
    let pos = deformed(&model, Vec3::new(-0.5, -0.5, -0.5), 0.05, 7);
    let mut rng = Lcg(11);
    let vel: Vec<Vec3> = pos.iter().map(|_| rng.vec3() * 3.0).collect();
    let mut acc = vec![Vec3::ZERO; pos.len()];
    accelerations(&model, &pos, &vel, &Control::none(), &mut acc);
    let forces: Vec<Vec3> = acc
        .iter()
        .map(|a| *a * model.body(0).material.mass)
        .collect();
    let scale = forces.iter().map(|f| f.length()).fold(0.0, f64::max);
    assert!(scale > 1.0, "the deformation should produce forces");
    let total = forces.iter().fold(Vec3::ZERO, |s, f| s + *f);
    let torque = pos
        .iter()
        .zip(&forces)
        .fold(Vec3::ZERO, |s, (p, f)| s + p.cross(*f));
    assert!(
        total.max_abs() < 1e-12 * scale * pos.len() as f64,
        "net force {total:?}"
    );
    assert!(
        torque.max_abs() < 1e-12 * scale * pos.len() as f64,
        "net torque {torque:?}"
    );
}

/// With no external force and no contact, every integrator keeps the total momentum.
#[test]
fn momentum_is_conserved_in_free_flight() {
    for integrator in Integrator::ALL {
        let model = ModelBuilder::new()
            .integrator(integrator)
            .dt(1e-4)
            .build()
            .unwrap();
        let mut state = State::new(
            deformed(&model, Vec3::new(-0.5, -0.5, -0.5), 0.03, 3),
            vec![Vec3::new(0.2, 0.1, -0.1); 512],
        );
        let p0 = momentum(&model, &state.vel);
        run(&model, &mut state, 1000);
        let p1 = momentum(&model, &state.vel);
        assert!((p1 - p0).max_abs() < 1e-12, "{integrator}: {p0:?} → {p1:?}");
    }
}

/// Without damping the energy should stay constant; the error shrinks with the order:
/// RK4 < RK2 < Euler.
#[test]
fn energy_drift_is_ordered_by_accuracy() {
    let drift = |integrator| {
        let model = ModelBuilder::new()
            .integrator(integrator)
            .elastic(50.0, 0.0)
            .dt(5e-5)
            .build()
            .unwrap();
        let mut state = State::new(
            deformed(&model, Vec3::new(-0.5, -0.5, -0.5), 0.04, 5),
            vec![Vec3::ZERO; 512],
        );
        let e0 = energy(&model, &state).total();
        run(&model, &mut state, 2000);
        (energy(&model, &state).total() - e0).abs() / e0
    };
    let (euler, rk2, rk4) = (
        drift(Integrator::Euler),
        drift(Integrator::Rk2),
        drift(Integrator::Rk4),
    );
    assert!(
        rk4 < rk2 && rk2 < euler,
        "drift RK4 {rk4:e}, RK2 {rk2:e}, Euler {euler:e}"
    );
    assert!(rk4 < 1e-6, "RK4 drift {rk4:e}");
}

/// A deformed, damped cube flying free returns to its rest shape up to a rigid motion: every
/// pairwise distance returns to its rest value.
#[test]
fn damped_deformed_cube_returns_to_rest_shape() {
    let model = ModelBuilder::new().dt(1e-3).build().unwrap();
    let mut pos = deformed(&model, Vec3::new(-0.5, -0.5, -0.5), 0.04, 9);
    let corner = model.body(0).lattice().index(7, 7, 7);
    pos[corner] += Vec3::new(0.1, 0.1, 0.1);
    let mut rng = Lcg(4);
    let vel: Vec<Vec3> = pos.iter().map(|_| rng.vec3() * 0.2).collect();
    let mut state = State::new(pos, vel);
    run(&model, &mut state, 3000);
    let rest = model.body(0).lattice().rest_positions();
    let mut worst: f64 = 0.0;
    for a in 0..512 {
        for b in a + 1..512 {
            let now = (state.pos[a] - state.pos[b]).length();
            let then = (rest[a] - rest[b]).length();
            worst = worst.max((now - then).abs());
        }
    }
    assert!(worst < 1e-5, "largest distance error {worst:e} m");
}
