//! Contact: a cube thrown at a wall bounces back; the plane holds the cube on either side.

mod common;

use common::{run, uniform_field};
use jello_core::diagnostics::{centre_of_mass, max_penetration, momentum};
use jello_core::{Control, ModelBuilder, Plane, Scratch, State, Vec3};

/// The cube placed with its lower corner at `corner`, every point moving at `v`.
fn cube_at(corner: Vec3, v: Vec3) -> State {
    let model = ModelBuilder::new().build().unwrap();
    let pos = model
        .body(0)
        .lattice()
        .rest_positions()
        .into_iter()
        .map(|p| p + corner)
        .collect();
    State::new(pos, vec![v; 512])
}

/// Thrown at the −x wall, the cube comes back with positive x velocity, never deep in the wall.
#[test]
fn cube_thrown_at_a_wall_bounces_back() {
    let model = ModelBuilder::new()
        .elastic(500.0, 0.25)
        .collision(1000.0, 0.25)
        .build()
        .unwrap();
    let mut state = cube_at(Vec3::new(-0.5, -0.5, -0.5), Vec3::new(-5.0, 0.0, 0.0));
    let mut scratch = Scratch::new(&model);
    let mut deepest: f64 = 0.0;
    for _ in 0..1000 {
        jello_core::step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
        deepest = deepest.max(max_penetration(&model, &state.pos));
    }
    let v = momentum(&model, &state.vel) / (model.body(0).material.mass * 512.0);
    assert!(deepest > 0.0, "the cube should reach the wall");
    assert!(deepest < 0.3, "penetration {deepest} m");
    assert!(v.x > 1.0, "centre of mass velocity after the bounce: {v:?}");
}

/// Falling onto a plane from above (the positive side) and rising into it from below (the
/// negative side), the cube stays on its starting side, up to the penalty depth, and bounces.
#[test]
fn plane_holds_the_cube_on_either_side() {
    let mass = 1.0 / 512.0;
    for (coeffs, corner, v, push) in [
        // z = −1, cube above, moving down.
        (
            [0.0, 0.0, 1.0, 1.0],
            Vec3::new(-0.5, -0.5, -0.2),
            Vec3::new(0.0, 0.0, -3.0),
            -1.0,
        ),
        // z = 0.5, cube below, moving up.
        (
            [0.0, 0.0, 1.0, -0.5],
            Vec3::new(-0.5, -0.5, -1.7),
            Vec3::new(0.0, 0.0, 3.0),
            1.0,
        ),
        // A tilted plane with the cube on its negative side.
        (
            [1.0, 1.0, 1.0, -1.5],
            Vec3::new(-1.0, -1.0, -1.0),
            Vec3::new(2.0, 2.0, 2.0),
            1.0,
        ),
    ] {
        let start = cube_at(corner, v);
        let plane = Plane::facing(coeffs, centre_of_mass(&start.pos)).unwrap();
        let model = ModelBuilder::new()
            .plane(Some(plane))
            .field(uniform_field(Vec3::new(0.0, 0.0, 9.81 * mass * push)))
            .build()
            .unwrap();
        let side = plane.side;
        let mut state = start;
        let mut scratch = Scratch::new(&model);
        let mut worst: f64 = 0.0;
        let mut bounced = false;
        for _ in 0..2000 {
            jello_core::step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
            let normal_speed = momentum(&model, &state.vel).dot(plane.inward_normal());
            bounced |= normal_speed > 0.0;
            for p in &state.pos {
                worst = worst.max(-side * plane.value(*p) / plane.normal_length());
            }
        }
        assert!(worst > 0.0, "{coeffs:?}: the cube should touch the plane");
        assert!(worst < 0.3, "{coeffs:?}: {worst} m past the plane");
        assert!(bounced, "{coeffs:?}: never moved away from the plane");
    }
}

/// Negating the plane's coefficients names the same plane: the run is bit for bit the same.
#[test]
fn plane_sign_convention_does_not_matter() {
    let start = cube_at(Vec3::new(-0.5, -0.5, -0.2), Vec3::new(1.0, 0.5, -3.0));
    let com = centre_of_mass(&start.pos);
    let runs: Vec<State> = [[0.3, -0.2, 1.0, 1.0], [-0.3, 0.2, -1.0, -1.0]]
        .into_iter()
        .map(|c| {
            let model = ModelBuilder::new()
                .plane(Some(Plane::facing(c, com).unwrap()))
                .build()
                .unwrap();
            let mut s = start.clone();
            run(&model, &mut s, 1500);
            s
        })
        .collect();
    assert_eq!(runs[0], runs[1]);
}
