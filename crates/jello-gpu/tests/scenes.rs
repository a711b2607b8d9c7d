//! Several bodies, obstacles with friction, and pulls on the GPU, against the f64 CPU core (on
//! lavapipe where there is no GPU; see `agreement.rs`).

use jello_core::body::rotation_xyz;
use jello_core::diagnostics::{body_centre_of_mass, max_penetration, momentum};
use jello_core::{
    Aabb, Body, Control, Integrator, Lattice, Material, Model, ModelBuilder, Obstacle, Plane, Pull,
    Sphere, State, Vec3,
};

mod common;
use common::{assert_same_energy, cpu, gpu, largest_gap};

/// A cube of `n`³ points, 0.4 m wide, of a stiff material, resting with its corner at `origin`
/// turned by `degrees` about x, y and z.
fn cube(n: usize, origin: Vec3, degrees: [f64; 3]) -> Body {
    let side = 0.4;
    let lattice = Lattice::new([n, n, n], Vec3::new(side, side, side));
    Body::lattice_box(lattice, Material::classic())
        .with_modulus(2.0e5, 40.0, 1000.0)
        .placed(origin, rotation_xyz(degrees))
}

/// Two cubes in zero gravity thrown at each other, with friction between them.
fn collision() -> (Model, State) {
    let model = ModelBuilder::new()
        .bodies(vec![
            cube(5, Vec3::new(-0.7, -0.1, -0.2), [0.0, 0.0, 0.0]),
            cube(5, Vec3::new(0.25, -0.2, -0.1), [10.0, 20.0, 5.0]),
        ])
        .collision(20000.0, 20.0)
        .friction(0.4)
        .gravity(Vec3::ZERO)
        .dt(0.0005)
        .integrator(Integrator::Rk4)
        .build()
        .unwrap();
    let mut state = State::at_rest(&model);
    for body in model.bodies() {
        let v = if body.points().start == 0 {
            Vec3::new(1.5, 0.2, 0.0)
        } else {
            Vec3::new(-1.5, 0.0, 0.1)
        };
        state.vel[body.points()].iter_mut().for_each(|u| *u = v);
    }
    (model, state)
}

#[test]
fn bodies_collide_as_on_the_core() {
    let (model, state) = collision();
    let control = Control::default();
    let mut sim = gpu(&model, &state, &control);
    let steps = 800;
    sim.step(steps).unwrap();
    let on_gpu = sim.read_state().unwrap();
    let reference = cpu(&model, &state, &control, steps);
    // They met: each bounced back (its x velocity changed sign), on both.
    let centre_x = |s: &State, b: usize| body_centre_of_mass(&model, b, &s.pos).x;
    for s in [&on_gpu, &reference] {
        assert!(centre_x(s, 0) < centre_x(&state, 0) + 0.3, "body 0 bounced");
    }
    assert_same_energy(&model, &on_gpu, &reference, "");
    // Contacts push both bodies equally and oppositely: momentum stays (to f32 rounding).
    let (p0, p1) = (momentum(&model, &state.vel), momentum(&model, &on_gpu.vel));
    let scale = p0.length();
    assert!((p1 - p0).length() < 1e-4 * scale, "{p0:?} became {p1:?}");
    let gap = largest_gap(&on_gpu, &reference);
    assert!(gap < 1e-3, "{gap:.3e} m from the core");
}

#[test]
fn contacts_between_bodies_give_the_same_result_every_run() {
    let (model, state) = collision();
    let control = Control::default();
    let run = || {
        let mut sim = gpu(&model, &state, &control);
        // Unequal calls, so batches end at other steps.
        sim.step(333).unwrap();
        sim.step(267).unwrap();
        sim.read_state().unwrap()
    };
    let (first, second) = (run(), run());
    assert_eq!(first.pos, second.pos);
    assert_eq!(first.vel, second.vel);
}

/// A cube resting (1 mm above) on a plane obstacle tilted `degrees` about y, its bottom face
/// along it; a ball and a solid box beside; friction `mu`.
fn obstacles(mu: f64, degrees: f64) -> (Model, State) {
    let t = degrees.to_radians();
    let (s, c) = t.sin_cos();
    let slope = Plane::new([s, 0.0, c, 1.0]).unwrap();
    let x0 = -0.6;
    let origin = Vec3::new(x0, -0.2, -(1.0 + s * x0) / c) + Vec3::new(s, 0.0, c) * 0.001;
    let model = ModelBuilder::new()
        .bodies(vec![cube(5, origin, [0.0, degrees, 0.0])])
        .obstacle(Obstacle::Plane(slope))
        .obstacle(Obstacle::Sphere(
            Sphere::new(Vec3::new(1.2, 0.0, -1.0), 0.4).unwrap(),
        ))
        .obstacle(Obstacle::Box(
            Aabb::new(Vec3::new(-1.6, -1.0, -2.0), Vec3::new(-1.2, 1.0, -0.7)).unwrap(),
        ))
        .collision(20000.0, 20.0)
        .friction(mu)
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .dt(0.0005)
        .integrator(Integrator::Rk4)
        .build()
        .unwrap();
    (model.clone(), State::at_rest(&model))
}

#[test]
fn obstacles_with_friction_hold_a_body_on_a_slope_as_on_the_core() {
    // The cube settles on the slope (20°): it holds with μ = 0.6 > tan 20° (after creeping a
    // few cm while it bounces on the penalty springs, where the cone shrinks with the depth),
    // and slides downhill (+x) with μ = 0.1 (at (sin 20° − 0.1 cos 20°) g ≈ 2.4 m/s²); on
    // both, to the same place.
    for (mu, sticks) in [(0.6, true), (0.1, false)] {
        let (model, state) = obstacles(mu, 20.0);
        let control = Control::default();
        let mut sim = gpu(&model, &state, &control);
        let steps = 1600;
        sim.step(steps).unwrap();
        let on_gpu = sim.read_state().unwrap();
        // The core, with its deepest penetration at the end of any step.
        let mut core = jello_core::Simulation::new(model.clone(), state.clone());
        let mut core_deepest = 0.0f64;
        for _ in 0..steps {
            core.step().unwrap();
            core_deepest = core_deepest.max(max_penetration(&model, &core.state.pos));
        }
        let reference = core.state;
        let drift = |s: &State| body_centre_of_mass(&model, 0, &s.pos).x;
        let start = drift(&state);
        for (name, s) in [("GPU", &on_gpu), ("core", &reference)] {
            let moved = drift(s) - start;
            if sticks {
                assert!(moved.abs() < 0.1, "{name}, μ = {mu}: slid {moved} m");
            } else {
                assert!(moved > 0.4, "{name}, μ = {mu}: slid only {moved} m");
            }
        }
        assert!(
            (drift(&on_gpu) - drift(&reference)).abs() < 1e-3,
            "μ = {mu}: the GPU's cube {} m from the core's",
            drift(&on_gpu) - drift(&reference)
        );
        assert_same_energy(&model, &on_gpu, &reference, &format!("μ = {mu}: "));
        // Nothing went through the slope: as deep as on the core.
        let deepest = sim.max_penetration();
        assert!(
            (deepest - core_deepest).abs() < 0.05 * core_deepest,
            "μ = {mu}: {deepest} m deep on the GPU, {core_deepest} m on the core"
        );
    }
}

#[test]
fn a_ball_and_a_solid_box_push_points_out_as_on_the_core() {
    // In zero gravity, with friction, a cube overlapping the ball and another the solid box are
    // pushed out along the radius and through the nearest face (no anchors in the first step,
    // then tied): 200 steps within 1e-4 m of the core.
    let (model, _) = obstacles(0.3, 0.0);
    for origin in [Vec3::new(0.55, -0.2, -0.85), Vec3::new(-1.35, -0.1, -0.9)] {
        let model = model
            .to_builder()
            .bodies(vec![cube(5, origin, [0.0, 0.0, 0.0])])
            .gravity(Vec3::ZERO)
            .build()
            .unwrap();
        let mut state = State::at_rest(&model);
        state
            .vel
            .iter_mut()
            .for_each(|v| *v = Vec3::new(0.1, -0.2, 0.05));
        let control = Control::default();
        let mut sim = gpu(&model, &state, &control);
        sim.step(200).unwrap();
        let on_gpu = sim.read_state().unwrap();
        let gap = largest_gap(&on_gpu, &cpu(&model, &state, &control, 200));
        assert!(gap < 1e-4, "{origin:?}: {gap:.3e} m from the core");
        assert!(
            largest_gap(&on_gpu, &state) > 0.01,
            "{origin:?}: pushed out"
        );
    }
}

#[test]
fn pulls_agree_with_the_core_and_follow_a_new_control() {
    let model = ModelBuilder::new()
        .bodies(vec![cube(6, Vec3::new(-0.2, -0.2, -0.2), [0.0, 30.0, 0.0])])
        .gravity(Vec3::ZERO)
        .dt(0.0005)
        .integrator(Integrator::Rk4)
        .build()
        .unwrap();
    let state = State::at_rest(&model);
    let pull = |point: u32, target: Vec3, stiffness: f64| Pull {
        point,
        target,
        stiffness,
        damping: 0.05,
    };
    // Two pulls on one point and one on another.
    let first = Control {
        pulls: vec![
            pull(0, Vec3::new(-0.8, 0.0, 0.0), 20.0),
            pull(0, Vec3::new(-0.5, -0.5, 0.0), 10.0),
            pull(215, Vec3::new(0.6, 0.6, 0.6), 30.0),
        ],
        ..Control::default()
    };
    let second = Control {
        pulls: vec![pull(100, Vec3::new(0.0, 0.0, 1.0), 40.0)],
        ..Control::default()
    };
    let mut sim = gpu(&model, &state, &first);
    sim.step(150).unwrap();
    sim.set_control(&second).unwrap();
    sim.step(150).unwrap();
    let mut core = jello_core::Simulation::new(model.clone(), state.clone());
    core.control = first;
    for _ in 0..150 {
        core.step().unwrap();
    }
    core.control = second;
    for _ in 0..150 {
        core.step().unwrap();
    }
    let on_gpu = sim.read_state().unwrap();
    let gap = largest_gap(&on_gpu, &core.state);
    assert!(gap < 1e-4, "{gap:.3e} m from the core");
    // The pulls moved it.
    assert!(largest_gap(&on_gpu, &state) > 0.01);
}
