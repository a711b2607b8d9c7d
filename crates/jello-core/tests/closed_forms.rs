//! Physics against closed forms: free fall, the period of a single spring, rest stays rest.

mod common;

use common::{run, uniform_field};
use jello_core::{Integrator, Lattice, ModelBuilder, State, Vec3};

/// Under a uniform field every point falls as `z0 + v0 t − ½ g t²`; RK2 and RK4 integrate a
/// constant acceleration exactly, Euler with an error of exactly `½ g t dt`.
#[test]
fn free_fall_follows_the_parabola() {
    let (g, dt, steps) = (9.81, 2e-4, 1500);
    let mass = 1.0 / 512.0;
    for integrator in Integrator::ALL {
        let model = ModelBuilder::new()
            .integrator(integrator)
            .dt(dt)
            .field(uniform_field(Vec3::new(0.0, 0.0, -g * mass)))
            .build()
            .unwrap();
        let mut state = State::at_rest(&model);
        let v0 = Vec3::new(0.3, -0.2, 1.0);
        state.vel.iter_mut().for_each(|v| *v = v0);
        let start = state.pos.clone();
        run(&model, &mut state, steps);
        let t = dt * steps as f64;
        // Euler lags by ½ g t dt (it moves with the old velocity); symplectic Euler leads by it.
        let bias = match integrator {
            Integrator::Euler => 0.5 * g * t * dt,
            // Backward Euler too: the velocity first, then the position with it.
            Integrator::SymplecticEuler | Integrator::BackwardEuler => -0.5 * g * t * dt,
            _ => 0.0,
        };
        for (p, p0) in state.pos.iter().zip(&start) {
            let expected = *p0 + v0 * t + Vec3::new(0.0, 0.0, -0.5 * g * t * t + bias);
            assert!(
                (*p - expected).max_abs() < 1e-9,
                "{integrator}: {p:?} vs {expected:?}"
            );
        }
    }
}

/// Two points joined by one spring oscillate with period `2π √(m / 2k)` (reduced mass m/2).
#[test]
fn single_spring_period() {
    let (k, mass, rest, stretch) = (50.0, 0.02, 0.5, 0.05);
    let model = ModelBuilder::new()
        .lattice(Lattice::new([2, 1, 1], Vec3::new(rest, 1.0, 1.0)))
        .elastic(k, 0.0)
        .mass(mass)
        .dt(1e-5)
        .build()
        .unwrap();
    assert_eq!(model.spring_count(), 1);
    let mut state = State::new(
        vec![
            Vec3::new(-rest / 2.0 - stretch / 2.0, 0.0, 0.0),
            Vec3::new(rest / 2.0 + stretch / 2.0, 0.0, 0.0),
        ],
        vec![Vec3::ZERO; 2],
    );
    // Find the times the extension crosses zero going down; consecutive ones are a period apart.
    let mut scratch = jello_core::Scratch::new(&model);
    let control = jello_core::Control::none();
    let extension = |s: &State| (s.pos[1] - s.pos[0]).length() - rest;
    let mut crossings = Vec::new();
    let mut prev = extension(&state);
    while crossings.len() < 4 {
        let t0 = state.time;
        jello_core::step(&model, &mut state, &control, &mut scratch).unwrap();
        let e = extension(&state);
        if prev > 0.0 && e <= 0.0 {
            crossings.push(t0 + model.dt * prev / (prev - e));
        }
        prev = e;
    }
    let expected = 2.0 * std::f64::consts::PI * (mass / (2.0 * k)).sqrt();
    for w in crossings.windows(2) {
        let period = w[1] - w[0];
        assert!(
            (period - expected).abs() < 1e-6 * expected,
            "period {period} vs {expected}"
        );
    }
}

/// The undeformed cube at rest, inside the box, with no field, stays where it is.
#[test]
fn undeformed_cube_at_rest_stays_at_rest() {
    for integrator in Integrator::ALL {
        let model = ModelBuilder::new().integrator(integrator).build().unwrap();
        let mut state = State::at_rest(&model);
        let start = state.pos.clone();
        run(&model, &mut state, 10_000);
        assert!(
            common::max_diff(&state.pos, &start) < 1e-12,
            "{integrator} drifted"
        );
        assert!(
            state.vel.iter().all(|v| v.max_abs() < 1e-10),
            "{integrator} moves"
        );
    }
}
