//! Coulomb friction of obstacles, of the box's walls and of the inclined plane, against the
//! closed forms of a block on a slope: below the friction angle it holds (its contacts' anchors
//! do not creep), above it slides with acceleration `g (sin θ − μ cos θ)`, and a block thrown
//! along a floor stops after `v²/(2 μ g)`.
//!
//! The contacts are damped along the normal (dCollision); across it acts friction alone.
//!
//! The slope is a horizontal floor `z = 0` (a plane obstacle, the box's bottom wall, or the
//! inclined plane, each in turn) under gravity tilted by θ, the same physics without rotated
//! lattices. The block is a stiff 4×4×4 lattice so that it slides as one.

use jello_core::diagnostics::body_centre_of_mass;
use jello_core::{
    Aabb, Body, Lattice, Material, ModelBuilder, Obstacle, Plane, Simulation, State, Vec3,
};

const G: f64 = 9.81;
const DT: f64 = 0.0005;

/// What the floor `z = 0` is: a plane obstacle (with the model's `friction`), the box's bottom
/// wall or the inclined plane (with its `wall_friction`).
#[derive(Clone, Copy, Debug)]
enum Floor {
    Obstacle,
    Wall,
    Plane,
}

const FLOORS: [Floor; 3] = [Floor::Obstacle, Floor::Wall, Floor::Plane];

/// A stiff 0.3 m block resting on the floor `z = 0` of kind `floor` (its contact depth settled
/// first), under gravity of 9.81 m/s² tilted by `theta` toward +x, with friction `mu`, moving at
/// `v0` along x.
fn block_on(floor: Floor, theta: f64, mu: f64, v0: f64) -> Simulation {
    let material = Material {
        mass: 0.01,
        stiffness: [2000.0; 3],
        damping: [2.0; 3],
    };
    let side = 0.3;
    let body = Body::lattice_box(Lattice::new([4; 3], Vec3::new(side, side, side)), material)
        .placed(
            Vec3::new(0.0, 0.0, side / 2.0),
            jello_core::model::body::IDENTITY,
        );
    let plane = Plane::facing([0.0, 0.0, 1.0, 0.0], Vec3::new(0.0, 0.0, 1.0)).unwrap();
    let far = Aabb::new(Vec3::new(-50.0, -50.0, -50.0), Vec3::new(50.0, 50.0, 50.0)).unwrap();
    let builder = ModelBuilder::new().bodies(vec![body]);
    let builder = match floor {
        Floor::Obstacle => builder
            .bounds(far)
            .obstacle(Obstacle::Plane(plane))
            .friction(mu),
        Floor::Wall => builder
            .bounds(Aabb::new(Vec3::new(-50.0, -50.0, 0.0), Vec3::new(50.0, 50.0, 50.0)).unwrap())
            .wall_friction(mu),
        Floor::Plane => builder.bounds(far).plane(Some(plane)).wall_friction(mu),
    };
    let settle = builder
        .collision(4000.0, 2.0)
        .dt(DT)
        .gravity(Vec3::new(0.0, 0.0, -G))
        .build()
        .unwrap();
    // Settle straight down first (no sideways load), so the slide starts from a resting contact.
    let mut sim = Simulation::new(settle.clone(), State::at_rest(&settle));
    sim.advance(2000).unwrap();
    let model = settle
        .to_builder()
        .gravity(Vec3::new(G * theta.sin(), 0.0, -G * theta.cos()))
        .build()
        .unwrap();
    let mut state = sim.state.clone();
    for v in &mut state.vel {
        *v = Vec3::new(v0, 0.0, 0.0);
    }
    state.time = 0.0;
    Simulation::new(model, state)
}

fn centre_x(sim: &Simulation) -> f64 {
    body_centre_of_mass(&sim.model, 0, &sim.state.pos).x
}

#[test]
fn below_the_friction_angle_a_block_holds() {
    for floor in FLOORS {
        below_the_friction_angle_a_block_holds_on(floor);
    }
}

fn below_the_friction_angle_a_block_holds_on(floor: Floor) {
    // tan θ = 0.3 < μ = 0.5.
    let theta = 0.3f64.atan();
    let mut sim = block_on(floor, theta, 0.5, 0.0);
    let x0 = centre_x(&sim);
    // The contacts' tangential springs take up the load within a fraction of a second (a
    // deflection of load / kCollision), then hold: no creep.
    sim.advance(400).unwrap();
    let x1 = centre_x(&sim);
    let deflection = x1 - x0;
    sim.advance(4000).unwrap(); // 2 s more
    let crept = centre_x(&sim) - x1;
    assert!(
        deflection.abs() < 5e-3,
        "{floor:?}: deflected {deflection} m"
    );
    assert!(crept.abs() < 1e-4, "{floor:?}: crept {crept} m in 2 s");
    // Without friction the same block slides away: x = ½ g sin θ t² (1 s).
    let mut slippery = block_on(floor, theta, 0.0, 0.0);
    slippery.advance(2000).unwrap();
    let slid = centre_x(&slippery) - x0;
    let free = 0.5 * G * theta.sin();
    assert!(
        (slid - free).abs() < 0.05 * free,
        "{floor:?}: slid {slid} m, closed form {free} m"
    );
}

#[test]
fn above_the_friction_angle_a_block_slides_at_the_closed_form_rate() {
    for floor in FLOORS {
        above_the_friction_angle_a_block_slides_on(floor);
    }
}

fn above_the_friction_angle_a_block_slides_on(floor: Floor) {
    // tan θ = 0.7 > μ = 0.3: a = g (sin θ − μ cos θ).
    let (theta, mu) = (0.7f64.atan(), 0.3);
    let mut sim = block_on(floor, theta, mu, 0.0);
    let x0 = centre_x(&sim);
    sim.advance(1000).unwrap(); // 0.5 s
    let slid = centre_x(&sim) - x0;
    let expected = 0.5 * G * (theta.sin() - mu * theta.cos()) * 0.25;
    assert!(
        (slid - expected).abs() < 0.05 * expected,
        "{floor:?}: slid {slid} m, closed form {expected} m"
    );
}

#[test]
fn a_block_thrown_along_the_floor_stops_after_the_closed_form_distance() {
    for floor in FLOORS {
        a_block_thrown_along_the_floor_stops_on(floor);
    }
}

fn a_block_thrown_along_the_floor_stops_on(floor: Floor) {
    let (mu, v0) = (0.4, 1.5);
    let mut sim = block_on(floor, 0.0, mu, v0);
    let x0 = centre_x(&sim);
    sim.advance(2000).unwrap(); // 1 s: it stops after v0 / (μ g) = 0.38 s
    let stopped = centre_x(&sim) - x0;
    let expected = v0 * v0 / (2.0 * mu * G);
    assert!(
        (stopped - expected).abs() < 0.05 * expected,
        "{floor:?}: stopped after {stopped} m, closed form {expected} m"
    );
    let speed = jello_core::diagnostics::momentum(&sim.model, &sim.state.vel).length()
        / sim.model.body(0).total_mass();
    assert!(speed < 0.01, "{floor:?}: still moving at {speed} m/s");
}
