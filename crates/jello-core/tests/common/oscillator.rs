//! Models and closed forms shared by the implicit integrators' tests: far walls, a dumbbell (two
//! points and one spring), and one step of each implicit method on the linear oscillator.
#![allow(dead_code)]

use jello_core::integrate::implicit::{SDIRK2_C, SDIRK2_GAMMA};
use jello_core::{Aabb, Body, Integrator, Lattice, Material, Model, ModelBuilder, Vec3};

pub fn far_walls() -> Aabb {
    Aabb::new(Vec3::new(-50.0, -50.0, -50.0), Vec3::new(50.0, 50.0, 50.0)).unwrap()
}

/// Two points joined by one spring of rest length `rest` along x.
pub fn dumbbell(rest: f64, material: Material, dt: f64, integrator: Integrator) -> Model {
    let body = Body::lattice_box(Lattice::new([2, 1, 1], Vec3::new(rest, 1.0, 1.0)), material);
    ModelBuilder::new()
        .bodies(vec![body])
        .bounds(far_walls())
        .dt(dt)
        .integrator(integrator)
        .build()
        .unwrap()
}

/// One step of each implicit method on the linear oscillator `s'' = −ω²s − γs'` (stretch `s`,
/// speed `r`): backward Euler is `r₁ = (r₀ − hω²s₀)/(1 + hγ + h²ω²)`, `s₁ = s₀ + h r₁`; SDIRK2
/// is two such steps of size `γ_S·h`, the second from `y₀ + c·(Y₁ − y₀)`.
pub fn oscillator_step(
    integrator: Integrator,
    (s, r): (f64, f64),
    w2: f64,
    gamma: f64,
    h: f64,
) -> (f64, f64) {
    let backward_euler = |(s, r): (f64, f64), k: f64| {
        let r1 = (r - k * w2 * s) / (1.0 + k * gamma + k * k * w2);
        (s + k * r1, r1)
    };
    match integrator {
        Integrator::BackwardEuler => backward_euler((s, r), h),
        Integrator::Sdirk2 => {
            let k = SDIRK2_GAMMA * h;
            let (s1, r1) = backward_euler((s, r), k);
            backward_euler((s + SDIRK2_C * (s1 - s), r + SDIRK2_C * (r1 - r)), k)
        }
        other => unreachable!("{other} is not implicit"),
    }
}
