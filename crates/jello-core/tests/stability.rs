//! The stability estimate is close to where the classic world really becomes unstable.

use jello_core::integrate::stability::stable_dt;
use jello_core::{Integrator, ModelBuilder, Simulation, State, Vec3};

/// The classic jello, deformed as in the official jello.w (corner dragged by 1/7 per axis).
fn blows_up(integrator: Integrator, dt: f64) -> bool {
    let model = ModelBuilder::new()
        .integrator(integrator)
        .dt(dt)
        .build()
        .unwrap();
    let mut state = State::at_rest(&model);
    let corner = model.body(0).lattice().index(7, 7, 7);
    state.pos[corner] += Vec3::new(1.0, 1.0, 1.0) / 7.0;
    let mut sim = Simulation::new(model, state);
    sim.advance((1.0 / dt) as u64).is_err()
}

/// Below the estimate the run is stable; at 1.5 times the estimate it blows up. (Explicit Euler
/// is left out of the second half: it degrades gradually, bounded by the springs' nonlinearity.)
#[test]
fn estimate_brackets_the_real_limit() {
    let model = ModelBuilder::new().build().unwrap();
    for integrator in [
        Integrator::Rk2,
        Integrator::Rk4,
        Integrator::SymplecticEuler,
        Integrator::Euler,
    ] {
        let h = stable_dt(&model, integrator);
        assert!(h > 0.0 && h.is_finite(), "{integrator}: {h}");
        assert!(
            !blows_up(integrator, 0.9 * h),
            "{integrator} blew up below its estimate {h}"
        );
        if integrator != Integrator::Euler {
            assert!(
                blows_up(integrator, 1.5 * h),
                "{integrator} survived 1.5 × its estimate {h}"
            );
        }
    }
}

/// Without damping, explicit Euler amplifies every oscillation: no step is stable.
#[test]
fn undamped_euler_has_no_stable_step() {
    let model = ModelBuilder::new()
        .elastic(200.0, 0.0)
        .collision(400.0, 0.0)
        .build()
        .unwrap();
    assert_eq!(stable_dt(&model, Integrator::Euler), 0.0);
    assert!(stable_dt(&model, Integrator::Rk4) > 0.0);
}
