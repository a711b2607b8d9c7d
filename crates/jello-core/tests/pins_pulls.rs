//! Pinned points and pulls (sparse target springs in `Control`), checked against closed forms.
//!
//! - A pinned point never accelerates: at rest it stays exactly where it is, bit for bit, while
//!   the cube hangs from it; moving, it keeps its velocity exactly.
//! - A pull is `k (target − p) − d v`, evaluated at every stage: a pair of points pulled as one
//!   follows the damped oscillator's closed form, and RK4's error falls 16× when dt halves (a
//!   pull held constant through a step would make it first order).
//! - Pins moved along a path (a shake, keyframes) are where the path says after every step, to
//!   rounding, whatever the integrator, and carry the body with them.
//! - The same bits on 1 and 3 threads; bad pins and pulls are errors.

mod common;

use jello_core::diagnostics::centre_of_mass;
use jello_core::model::motion::Motion;
use jello_core::{
    benchmark, step, Aabb, Control, ForceField, Integrator, Lattice, ModelBuilder, Pull, Scratch,
    State, Vec3,
};

/// The classic cube pinned at its four top corners, hanging under gravity.
#[test]
fn a_cube_hangs_from_pinned_corners() {
    let mass = 1.0 / 512.0;
    let lattice = Lattice::classic();
    let corners =
        [(0, 0, 7), (0, 7, 7), (7, 0, 7), (7, 7, 7)].map(|(i, j, k)| lattice.index(i, j, k) as u32);
    let gravity = Vec3::new(0.0, 0.0, -9.81 * mass);
    let model = ModelBuilder::new()
        .elastic(400.0, 0.5)
        .field(Some(
            ForceField::from_fn(2, Aabb::classic(), |_| gravity).unwrap(),
        ))
        .pins(corners)
        .dt(0.0002)
        .build()
        .unwrap();
    let mut state = State::at_rest(&model);
    let start = state.clone();
    let mut scratch = Scratch::new(&model);
    for _ in 0..5000 {
        step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
    }
    for &c in &corners {
        let c = c as usize;
        assert_eq!(state.pos[c], start.pos[c], "pinned corner {c} moved");
        assert_eq!(state.vel[c], Vec3::ZERO);
    }
    // The rest sags a little below them and hangs still (it would have fallen ½gt² = 4.9 m
    // in that second, through the floor, if the pins let go).
    let com = centre_of_mass(&state.pos);
    assert!(com.z < 0.5 - 1e-3 && com.z > 0.45, "centre of mass {com:?}");
    let fastest = state.vel.iter().map(|v| v.length()).fold(0.0, f64::max);
    assert!(fastest < 0.05, "still moving at {fastest} m/s");
    let (top, bottom) = (lattice.index(3, 3, 7), lattice.index(3, 3, 0));
    assert!(
        state.pos[bottom].z < start.pos[bottom].z - 1e-3 && state.pos[top].z < start.pos[top].z,
        "the middle of the cube does not hang: top {:?}, bottom {:?}",
        state.pos[top],
        state.pos[bottom]
    );
}

/// A pinned point moving at the start keeps exactly its velocity.
#[test]
fn a_moving_pin_keeps_its_velocity() {
    for integrator in Integrator::ALL {
        let model = ModelBuilder::new()
            .pins([0])
            .integrator(integrator)
            .build()
            .unwrap();
        let mut state = State::at_rest(&model);
        let v = Vec3::new(0.25, -0.5, 0.125);
        state.vel[0] = v;
        let p0 = state.pos[0];
        let mut scratch = Scratch::new(&model);
        for _ in 0..400 {
            step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
        }
        assert_eq!(state.vel[0], v, "{integrator}");
        let expected = p0 + v * (400.0 * model.dt);
        assert!(
            (state.pos[0] - expected).max_abs() < 1e-12,
            "{integrator}: {:?} vs {expected:?}",
            state.pos[0]
        );
    }
}

/// Shaken pins follow `A sin(2π f t)` exactly at every step's end, on every integrator, and
/// shake the body: its far side swings too.
#[test]
fn shaken_pins_follow_their_sine_and_shake_the_body() {
    let lattice = Lattice::new([5, 5, 5], Vec3::new(1.0, 1.0, 1.0));
    let mut top = Vec::new();
    for i in 0..5 {
        for j in 0..5 {
            top.push(lattice.index(i, j, 4) as u32);
        }
    }
    let bottom = lattice.index(2, 2, 0);
    let amplitude = Vec3::new(0.1, 0.0, 0.0);
    let shake = Motion::Shake {
        amplitude,
        frequency: 2.0,
    };
    for integrator in Integrator::ALL {
        let model = ModelBuilder::new()
            .lattice(lattice.clone())
            .mass(0.01)
            .elastic(100.0, 0.2)
            .pin_motion(top.clone(), shake.clone())
            .integrator(integrator)
            .dt(0.0005)
            .build()
            .unwrap();
        let mut state = State::at_rest(&model);
        let start = state.clone();
        for &p in &top {
            state.vel[p as usize] = shake.velocity(0.0);
        }
        let mut scratch = Scratch::new(&model);
        let mut far_reach = 0.0f64;
        for _ in 0..1000 {
            step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
            let t = state.time;
            for &p in &top {
                let p = p as usize;
                let want = start.pos[p] + amplitude * (std::f64::consts::TAU * 2.0 * t).sin();
                assert!(
                    (state.pos[p] - want).max_abs() < 1e-12,
                    "{integrator} at t = {t}: {:?} vs {want:?}",
                    state.pos[p]
                );
                assert!((state.vel[p] - shake.velocity(t)).max_abs() < 1e-12);
            }
            far_reach = far_reach.max((state.pos[bottom].x - start.pos[bottom].x).abs());
        }
        assert!(
            far_reach > 0.02,
            "{integrator}: the bottom swung {far_reach} m"
        );
    }
}

/// A pin carried along keyframes is at each keyframe's offset when the step lands on its time,
/// and holds the last one after.
#[test]
fn a_pin_carried_along_keyframes_lands_on_them() {
    let path = Motion::Path(vec![
        (0.0, Vec3::ZERO),
        (0.25, Vec3::new(0.0, 0.0, 0.5)),
        (0.5, Vec3::new(0.3, 0.0, 0.5)),
    ]);
    let model = ModelBuilder::new()
        .pin_motion(vec![0], path.clone())
        .dt(0.0005)
        .build()
        .unwrap();
    let mut state = State::at_rest(&model);
    let p0 = state.pos[0];
    state.vel[0] = path.velocity(0.0);
    let mut scratch = Scratch::new(&model);
    for (steps, want) in [
        (500, path.offset(0.25)),
        (500, path.offset(0.5)),
        (400, path.offset(9.0)),
    ] {
        for _ in 0..steps {
            step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
        }
        assert!(
            (state.pos[0] - (p0 + want)).max_abs() < 1e-12,
            "{:?}",
            state.pos[0]
        );
    }
    assert_eq!(state.vel[0], Vec3::ZERO);
    // A motion on a point that is not pinned, or a bad path, is an error.
    let bad = ModelBuilder::new()
        .pin_motion(vec![0], Motion::Path(vec![]))
        .build();
    assert!(bad.unwrap_err().to_string().contains("pin motion 1"));
}

/// Two points 1 m apart, both pulled toward targets 1 m apart (the spring between them stays at
/// rest length): each follows `m x'' = −k x − d x'`, `x` its offset from its target.
fn pulled_pair(integrator: Integrator, dt: f64, t_end: f64) -> (f64, f64) {
    let (m, k, d) = (0.125, 50.0, 0.5);
    let model = ModelBuilder::new()
        .lattice(Lattice::new([2, 1, 1], Vec3::new(1.0, 1.0, 1.0)))
        .mass(m)
        .integrator(integrator)
        .dt(dt)
        .build()
        .unwrap();
    let mut state = State::at_rest(&model);
    let offset = Vec3::new(0.0, 0.3, -0.2);
    let control = Control {
        pulls: (0..2)
            .map(|p| Pull {
                point: p,
                target: model.body(0).lattice().rest_position(p as usize, 0, 0) + offset,
                stiffness: k,
                damping: d,
            })
            .collect(),
        ..Control::none()
    };
    let mut scratch = Scratch::new(&model);
    let steps = (t_end / dt).round() as usize;
    for _ in 0..steps {
        step(&model, &mut state, &control, &mut scratch).unwrap();
    }
    // Closed form: x(0) = −offset, x'(0) = 0, underdamped.
    let t = steps as f64 * dt;
    let (gamma, w0) = (d / (2.0 * m), (k / m).sqrt());
    let w = (w0 * w0 - gamma * gamma).sqrt();
    let x = |x0: f64| x0 * (-gamma * t).exp() * ((w * t).cos() + gamma / w * (w * t).sin());
    let want = Vec3::new(0.0, x(-0.3), x(0.2)) + offset;
    let err = (0..2)
        .map(|p| (state.pos[p] - model.body(0).lattice().rest_position(p, 0, 0) - want).max_abs())
        .fold(0.0, f64::max);
    (err, (state.pos[0] - state.pos[1]).length())
}

#[test]
fn a_pull_follows_the_damped_oscillator_and_rk4_stays_fourth_order() {
    let (err, length) = pulled_pair(Integrator::Rk4, 1e-4, 0.5);
    assert!(err < 1e-10, "RK4 error {err}");
    assert!(
        (length - 1.0).abs() < 1e-12,
        "the pair's spring stretched to {length}"
    );
    // Halving dt divides RK4's error by about 16: the pull is re-evaluated inside the step.
    let (coarse, _) = pulled_pair(Integrator::Rk4, 0.004, 0.5);
    let (fine, _) = pulled_pair(Integrator::Rk4, 0.002, 0.5);
    let ratio = coarse / fine;
    assert!(
        (12.0..20.0).contains(&ratio),
        "RK4 error ratio {ratio} ({coarse} / {fine})"
    );
    let (coarse, _) = pulled_pair(Integrator::Rk2, 0.004, 0.5);
    let (fine, _) = pulled_pair(Integrator::Rk2, 0.002, 0.5);
    let ratio = coarse / fine;
    assert!((3.0..5.0).contains(&ratio), "RK2 error ratio {ratio}");
}

#[test]
fn pins_and_pulls_are_bit_identical_on_any_thread_count() {
    let run = |threads: usize| {
        common::on_threads(threads, || {
            let (scene, mut state) = benchmark::scene(22, Integrator::Rk4).unwrap();
            let n = scene.point_count() as u32;
            let model = ModelBuilder::new()
                .lattice(scene.body(0).lattice().clone())
                .mass(scene.body(0).material.mass)
                .field(scene.field.clone())
                .pins([0, 7, n / 2, n - 1])
                .build()
                .unwrap();
            let control = Control {
                pulls: [3, n / 3, 2 * n / 3 + 5]
                    .map(|p| Pull {
                        point: p,
                        target: Vec3::new(0.5, -0.25, 1.0),
                        stiffness: 20.0,
                        damping: 0.1,
                    })
                    .to_vec(),
                ..Control::none()
            };
            let mut scratch = Scratch::new(&model);
            for _ in 0..5 {
                step(&model, &mut state, &control, &mut scratch).unwrap();
            }
            state
        })
    };
    let (one, three) = (run(1), run(3));
    assert!(one.pos == three.pos && one.vel == three.vel);
}

#[test]
fn bad_pins_and_pulls_are_errors() {
    let err = ModelBuilder::new().pins([512]).build().unwrap_err();
    assert!(err.to_string().contains("pinned point 512"), "{err}");
    let model = ModelBuilder::new().pins([3, 1, 3]).build().unwrap();
    assert_eq!(model.pins, vec![1, 3], "sorted, without repeats");
    let pull = Pull {
        point: 0,
        target: Vec3::ZERO,
        stiffness: 1.0,
        damping: 0.0,
    };
    let check = |pull: Pull| {
        Control {
            pulls: vec![pull],
            ..Control::none()
        }
        .check(&model)
    };
    assert!(check(pull).is_ok());
    for bad in [
        Pull { point: 512, ..pull },
        Pull {
            target: Vec3::new(f64::NAN, 0.0, 0.0),
            ..pull
        },
        Pull {
            stiffness: -1.0,
            ..pull
        },
        Pull {
            damping: f64::INFINITY,
            ..pull
        },
    ] {
        assert!(check(bad).unwrap_err().to_string().starts_with("pull 1:"));
    }
    let forces = Control {
        forces: vec![Vec3::ZERO; 3],
        ..Control::none()
    };
    assert!(forces.check(&model).is_err());
}
