//! Several bodies, obstacles with friction, pulls, and pins moving on paths on the GPU, against
//! the f64 CPU core (on lavapipe where there is no GPU; see `agreement.rs`).

use jello_core::diagnostics::{body_centre_of_mass, max_penetration, momentum};
use jello_core::model::body::rotation_xyz;
use jello_core::model::motion::Motion;
use jello_core::{
    Aabb, Body, Control, Integrator, Lattice, Material, Model, ModelBuilder, Obstacle, Plane, Pull,
    Simulation, Sphere, State, Vec3,
};
use jello_gpu::StepError;

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
    assert!((p1 - p0).length() < 2e-5 * scale, "{p0:?} became {p1:?}");
    // The same law in f32: a few micrometres apart (1.6e-6 m on lavapipe).
    let gap = largest_gap(&on_gpu, &reference);
    assert!(gap < 2e-5, "{gap:.3e} m from the core");
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

/// With the walls' and the plane's friction `mu`: the cube of [`obstacles`] on the inclined plane
/// of the classic worlds (the same slope), or (`floor`) a cube thrown at 1.5 m/s along the box's
/// floor.
fn walls_with_friction(mu: f64, floor: bool) -> (Model, State) {
    let (with_obstacles, _) = obstacles(mu, 20.0);
    let Obstacle::Plane(slope) = with_obstacles.obstacles[0] else {
        unreachable!("the first obstacle is the slope")
    };
    let builder = ModelBuilder::new()
        .collision(20000.0, 20.0)
        .wall_friction(mu)
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .dt(0.0005)
        .integrator(Integrator::Rk4);
    let builder = match floor {
        true => builder.bodies(vec![cube(4, Vec3::new(-1.0, 0.0, -2.0 + 0.001), [0.0; 3])]),
        false => builder
            .bodies(vec![with_obstacles.body(0).clone()])
            .plane(Some(slope)),
    };
    let model = builder.build().unwrap();
    let mut state = State::at_rest(&model);
    if floor {
        state
            .vel
            .iter_mut()
            .for_each(|v| *v = Vec3::new(1.5, 0.0, 0.0));
    }
    (model, state)
}

#[test]
fn walls_and_the_plane_with_friction_hold_and_stop_bodies_as_on_the_core() {
    // On the 20° slope the cube holds with μ = 0.6 and slides with μ = 0.1; the cube thrown
    // along the floor at 1.5 m/s stops after about v²/(2μg) (0.19 m with μ = 0.6, 1.1 m with
    // μ = 0.1): on both, to the same place.
    for floor in [false, true] {
        for (mu, sticks) in [(0.6, true), (0.1, false)] {
            let (model, state) = walls_with_friction(mu, floor);
            let control = Control::default();
            let mut sim = gpu(&model, &state, &control);
            let steps = 1600;
            sim.step(steps).unwrap();
            let on_gpu = sim.read_state().unwrap();
            let reference = cpu(&model, &state, &control, steps);
            let x = |s: &State| body_centre_of_mass(&model, 0, &s.pos).x;
            let what = if floor {
                "thrown along the floor"
            } else {
                "on the slope"
            };
            for (name, s) in [("GPU", &on_gpu), ("core", &reference)] {
                let moved = x(s) - x(&state);
                let (held, far) = if floor { (0.3, 0.6) } else { (0.1, 0.4) };
                if sticks {
                    assert!(
                        moved.abs() < held,
                        "{name}, {what}, μ = {mu}: moved {moved} m"
                    );
                } else {
                    assert!(
                        moved > far,
                        "{name}, {what}, μ = {mu}: moved only {moved} m"
                    );
                }
            }
            let gap = x(&on_gpu) - x(&reference);
            assert!(gap.abs() < 1e-3, "{what}, μ = {mu}: {gap} m from the core");
            assert_same_energy(&model, &on_gpu, &reference, &format!("{what}, μ = {mu}: "));
        }
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

/// A soft cube of 5³ points, 1 m wide, its top face (the points with the largest z) pinned and
/// moved along `motion`, starting at the path's velocity.
fn carried(motion: &Motion, integrator: Integrator) -> (Model, State, Vec<u32>) {
    let lattice = Lattice::new([5, 5, 5], Vec3::new(1.0, 1.0, 1.0));
    let top: Vec<u32> = (0..5)
        .flat_map(|i| (0..5).map(move |j| (i, j)))
        .map(|(i, j)| lattice.index(i, j, 4) as u32)
        .collect();
    let model = ModelBuilder::new()
        .lattice(lattice)
        .mass(0.01)
        .elastic(100.0, 0.2)
        .pin_motion(top.clone(), motion.clone())
        .integrator(integrator)
        .dt(0.0005)
        .build()
        .unwrap();
    let mut state = State::at_rest(&model);
    for &p in &top {
        state.vel[p as usize] = motion.velocity(0.0);
    }
    (model, state, top)
}

/// A vector rounded to f32, as the GPU holds it.
fn in_f32(v: Vec3) -> Vec3 {
    Vec3::new(v.x as f32 as f64, v.y as f32 as f64, v.z as f32 as f64)
}

/// Fails unless each of `pins` is at its start plus `motion`'s offset at the state's time (to
/// f32 rounding, which does not add up over the steps) and moves at the path's velocity there
/// (as f32).
fn assert_on_path(on_gpu: &State, start: &State, pins: &[u32], motion: &Motion, what: &str) {
    let t = on_gpu.time;
    for &p in pins {
        let p = p as usize;
        let want = start.pos[p] + motion.offset(t);
        let off = (on_gpu.pos[p] - want).max_abs();
        let rounding = 4.0 * f32::EPSILON as f64 * want.max_abs().max(1.0);
        assert!(
            off <= rounding,
            "{what}: pin {p} at t = {t} is {off:.2e} m off its path"
        );
        assert_eq!(on_gpu.vel[p], in_f32(motion.velocity(t)), "{what}: pin {p}");
    }
}

/// The paths of `carried`: a shake along x and z, and keyframes that go down, then across, then
/// hold (past their end at 0.2 s within the 600 steps).
fn paths() -> [(&'static str, Motion); 2] {
    [
        (
            "shake",
            Motion::Shake {
                amplitude: Vec3::new(0.1, 0.0, -0.05),
                frequency: 2.0,
            },
        ),
        (
            "path",
            Motion::Path(vec![
                (0.0, Vec3::ZERO),
                (0.1, Vec3::new(0.0, 0.0, -0.2)),
                (0.2, Vec3::new(0.15, -0.1, -0.2)),
            ]),
        ),
    ]
}

#[test]
fn pins_on_paths_move_the_body_as_on_the_core() {
    // Every explicit integrator (Euler and symplectic Euler take turns between two buffers, RK2
    // and RK4 end in place), over more than a batch, in unequal calls; the pins on their paths
    // at each call's end, the rest within 1e-4 m of the core.
    for integrator in Integrator::EXPLICIT {
        for (name, motion) in paths() {
            let what = format!("{integrator}, {name}");
            let (model, state, top) = carried(&motion, integrator);
            let control = Control::default();
            let mut sim = gpu(&model, &state, &control);
            let mut core = Simulation::new(model.clone(), state.clone());
            for steps in [250, 350] {
                sim.step(steps).unwrap();
                for _ in 0..steps {
                    core.step().unwrap();
                }
                let on_gpu = sim.read_state().unwrap();
                assert_eq!(on_gpu.time, core.state.time, "{what}");
                assert_on_path(&on_gpu, &state, &top, &motion, &what);
                let gap = largest_gap(&on_gpu, &core.state);
                assert!(gap < 1e-4, "{what}: {gap:.3e} m from the core");
            }
            // The body followed: its bottom moved too.
            let bottom = model.bodies()[0].lattice().index(2, 2, 0);
            let moved = (sim.read_state().unwrap().pos[bottom] - state.pos[bottom]).length();
            assert!(moved > 0.02, "{what}: the bottom moved {moved} m");
        }
    }
}

#[test]
fn a_blow_up_with_pins_on_paths_is_at_the_cores_step() {
    // The top face is carried out of the box at 5.7 m/s: it passes the escape margin (1 m) in
    // the middle of the second batch, at step 703 (t = 0.3512 s) on both; the GPU finds it by
    // stepping one at a time from the batch's start, refilling the pin table each time.
    let motion = Motion::Path(vec![
        (0.0, Vec3::ZERO),
        (1.0, Vec3::new(2.0 / 0.3512, 0.0, 0.0)),
    ]);
    for integrator in [Integrator::Rk4, Integrator::SymplecticEuler] {
        let (model, state, top) = carried(&motion, integrator);
        let model = model.to_builder().escape_margin(1.0).build().unwrap();
        let control = Control::default();
        let mut core = Simulation::new(model.clone(), state.clone());
        let expected = loop {
            if let Err(e) = core.step() {
                break e;
            }
        };
        assert_eq!(expected.step, 703, "{integrator}: the core");
        let mut sim = gpu(&model, &state, &control);
        let blow_up = match sim.step(2000) {
            Err(StepError::BlowUp(b)) => b,
            other => panic!("{integrator}: the path leaves the box, got {other:?}"),
        };
        assert_eq!(
            (blow_up.step, blow_up.point, blow_up.time),
            (expected.step, expected.point, expected.time),
            "{integrator}"
        );
        match (blow_up.cause, expected.cause) {
            (jello_core::BlowUpCause::Escaped(p), jello_core::BlowUpCause::Escaped(q)) => {
                assert!(
                    (p - q).length() < 1e-4,
                    "{integrator}: at {p:?}, the core's at {q:?}"
                )
            }
            other => panic!("{integrator}: {other:?}"),
        }
        // Left at the last good step, as the core is, the pins on their path there; stepping on
        // fails at the same step again.
        let kept = sim.read_state().unwrap();
        assert_eq!(kept.steps, blow_up.step - 1);
        assert!(largest_gap(&kept, &core.state) < 1e-4, "{integrator}");
        assert_on_path(&kept, &state, &top, &motion, &integrator.to_string());
        match sim.step(10) {
            Err(StepError::BlowUp(again)) => assert_eq!(again.step, blow_up.step),
            other => panic!("{integrator}: stepping on blows up again, got {other:?}"),
        }
    }
}

#[test]
fn pins_on_paths_drag_a_body_over_an_obstacle_with_friction_as_on_the_core() {
    // The cube on the plane obstacle, its top face pressed down 1 cm, then pushed 0.2 m along x:
    // the bottom, tied by friction anchors that move after the pins are placed, drags behind.
    let (model, _) = obstacles(0.5, 0.0);
    let state = State::at_rest(&model);
    let top_z = state.pos.iter().map(|p| p.z).fold(f64::MIN, f64::max);
    let top: Vec<u32> = (0..state.pos.len() as u32)
        .filter(|&p| state.pos[p as usize].z > top_z - 1e-9)
        .collect();
    let motion = Motion::Path(vec![
        (0.0, Vec3::ZERO),
        (0.05, Vec3::new(0.0, 0.0, -0.01)),
        (0.25, Vec3::new(0.2, 0.0, -0.01)),
    ]);
    let model = model
        .to_builder()
        .pin_motion(top.clone(), motion.clone())
        .build()
        .unwrap();
    let control = Control::default();
    let mut sim = gpu(&model, &state, &control);
    let steps = 500;
    sim.step(steps).unwrap();
    let on_gpu = sim.read_state().unwrap();
    let mut core = Simulation::new(model.clone(), state.clone());
    let mut core_deepest = 0.0f64;
    for _ in 0..steps {
        core.step().unwrap();
        core_deepest = core_deepest.max(max_penetration(&model, &core.state.pos));
    }
    assert_on_path(&on_gpu, &state, &top, &motion, "dragged");
    let gap = largest_gap(&on_gpu, &core.state);
    assert!(gap < 1e-4, "{gap:.3e} m from the core");
    let deepest = sim.max_penetration();
    assert!(core_deepest > 0.0, "it touched the obstacle");
    assert!(
        (deepest - core_deepest).abs() < 1e-3 * core_deepest,
        "{deepest} m deep on the GPU, {core_deepest} m on the core"
    );
    // The bottom lags behind the top (friction holds it).
    let x = |s: &State, p: usize| s.pos[p].x - state.pos[p].x;
    let bottom = (0..state.pos.len())
        .min_by(|&a, &b| state.pos[a].z.total_cmp(&state.pos[b].z))
        .unwrap();
    assert!(x(&on_gpu, bottom) < x(&on_gpu, top[0] as usize) - 0.01);
}

#[test]
fn a_state_set_between_steps_moves_the_pins_paths_with_it() {
    // Halfway, the pins are put 5 cm aside (as a front end assigning positions would): on the
    // core they go on from there along the path, and so they do on the GPU.
    let motion = paths()[1].1.clone();
    let (model, state, top) = carried(&motion, Integrator::Rk4);
    let control = Control::default();
    let mut sim = gpu(&model, &state, &control);
    let mut core = Simulation::new(model.clone(), state.clone());
    sim.step(150).unwrap();
    for _ in 0..150 {
        core.step().unwrap();
    }
    let aside = Vec3::new(0.0, 0.05, 0.0);
    for &p in &top {
        core.state.pos[p as usize] += aside;
    }
    sim.set_state(&core.state).unwrap();
    sim.step(150).unwrap();
    for _ in 0..150 {
        core.step().unwrap();
    }
    let on_gpu = sim.read_state().unwrap();
    let gap = largest_gap(&on_gpu, &core.state);
    assert!(gap < 1e-4, "{gap:.3e} m from the core");
    let mut moved = state.clone();
    for &p in &top {
        moved.pos[p as usize] += aside;
    }
    assert_on_path(&on_gpu, &moved, &top, &motion, "set aside");
}

#[test]
fn many_paths_step_in_shorter_batches_as_on_the_core() {
    // The top two layers of a 6³ lattice, each point on a shake of its own: 72 paths, more than
    // the pin table holds for a whole batch, so a batch is shorter (455 steps).
    let lattice = Lattice::new([6, 6, 6], Vec3::new(1.0, 1.0, 1.0));
    let mut builder = ModelBuilder::new()
        .lattice(lattice.clone())
        .mass(0.01)
        .elastic(100.0, 0.2)
        .dt(0.0005);
    let mut shaken = Vec::new();
    for (n, (i, j, k)) in (0..6)
        .flat_map(|i| (0..6).flat_map(move |j| [(i, j, 4), (i, j, 5)]))
        .enumerate()
    {
        let p = lattice.index(i, j, k) as u32;
        let motion = Motion::Shake {
            amplitude: Vec3::new(0.05, 0.02 * (n % 3) as f64, 0.0),
            frequency: 1.0 + 0.05 * n as f64,
        };
        builder = builder.pin_motion(vec![p], motion.clone());
        shaken.push((p, motion));
    }
    let model = builder.build().unwrap();
    let state = State::at_rest(&model);
    let control = Control::default();
    let mut sim = gpu(&model, &state, &control);
    sim.step(1000).unwrap();
    let on_gpu = sim.read_state().unwrap();
    let reference = cpu(&model, &state, &control, 1000);
    let gap = largest_gap(&on_gpu, &reference);
    assert!(gap < 1e-4, "{gap:.3e} m from the core");
    for (p, motion) in &shaken {
        assert_on_path(&on_gpu, &state, &[*p], motion, "many");
    }
}
