//! Obstacles beyond the box and the classic plane: spheres, solid boxes and planes.
//!
//! - Exact accelerations at hand-placed points, every expected value written out from the penalty
//!   spring of an obstacle (`(kCollision·depth − dCollision·v·n)·n`: docs/spec.md's spring and normal
//!   damping, plus Coulomb friction when the model has a coefficient) and each shape's geometry, on
//!   a 2-point lattice whose spring exerts exactly no force (as in `forces_exact.rs`).
//! - The collision energy's negative gradient (central differences) is the static contact force,
//!   for every shape: the energy and the force describe the same contacts.
//! - A cube dropped on a sphere comes to rest on top of it; the same bits on 1 and 3 threads.
//! - Bad obstacles are errors naming the obstacle; world files refuse them.

mod common;

use jello_core::diagnostics::{centre_of_mass, energy, max_penetration, momentum};
use jello_core::forces::accelerations;
use jello_core::{
    benchmark, step, Aabb, Control, ForceField, Integrator, Lattice, Model, ModelBuilder, Obstacle,
    Plane, Scratch, Sphere, State, Vec3, World,
};

const KC: f64 = 350.0;
const DC: f64 = 1.75;
const MASS: f64 = 0.0625;

/// A 2-point lattice along x of rest length 1, with the given obstacles.
fn pair(obstacles: Vec<Obstacle>) -> Model {
    ModelBuilder::new()
        .lattice(Lattice::new([2, 1, 1], Vec3::new(1.0, 1.0, 1.0)))
        .elastic(200.0, 0.5)
        .collision(KC, DC)
        .mass(MASS)
        .obstacles(obstacles)
        .build()
        .unwrap()
}

/// Accelerations of the pair with its first point at `a` (the second 1 m along x), both moving
/// at `v`: the spring is exactly at rest length, so only the obstacles act.
fn pair_acc(model: &Model, a: Vec3, v: Vec3) -> [Vec3; 2] {
    let pos = [a, a + Vec3::new(1.0, 0.0, 0.0)];
    let mut acc = [Vec3::ZERO; 2];
    accelerations(model, &pos, &[v, v], &Control::none(), &mut acc);
    acc
}

/// An obstacle's penalty spring over the mass (no friction).
fn by_hand(depth: f64, n: Vec3, v: Vec3) -> Vec3 {
    n * (KC * depth - DC * v.dot(n)) / MASS
}

fn assert_close(got: Vec3, want: Vec3, what: &str) {
    let scale = want.max_abs().max(1.0);
    assert!(
        (got - want).max_abs() <= 1e-12 * scale,
        "{what}: got {got:?}, want {want:?}"
    );
}

/// With friction μ, a point sliding into an obstacle (no anchor yet, as outside a step) also
/// feels `μ·kCollision·depth` against its tangential velocity, or the cap `m/dt·|vt|` when that
/// is less.
#[test]
fn friction_opposes_sliding_by_mu_times_the_normal_force() {
    let sphere = Sphere::new(Vec3::new(0.0, 0.0, 0.0), 0.5).unwrap();
    let mu = 0.4;
    let model = pair(vec![Obstacle::Sphere(sphere)])
        .to_builder()
        .friction(mu)
        .build()
        .unwrap();
    let a = Vec3::new(0.0, 0.0, 0.45); // 5 cm deep, normal +z
    let n = Vec3::new(0.0, 0.0, 1.0);
    for (v, capped) in [
        (Vec3::new(3.0, -4.0, -1.0), false),
        (Vec3::new(0.003, 0.0, 0.0), true),
    ] {
        let [acc, _] = pair_acc(&model, a, v);
        let vt = Vec3::new(v.x, v.y, 0.0);
        let limit = mu * KC * 0.05;
        let size = if capped {
            MASS / model.dt * vt.length()
        } else {
            limit
        };
        assert!(capped == (size < limit));
        let want = by_hand(0.05, n, v) - vt * (size / vt.length()) / MASS;
        assert_close(acc, want, "sliding friction");
    }
}

#[test]
fn sphere_pushes_out_along_the_radius() {
    let centre = Vec3::new(0.25, -0.5, 0.125);
    let model = pair(vec![Obstacle::Sphere(Sphere::new(centre, 0.75).unwrap())]);
    let v = Vec3::new(0.5, -1.25, 2.0);
    // First point 0.3, 0.4, 0 off the centre (distance 0.5, depth 0.25); the second, 1 m along
    // x, is outside (distance √(1.3² + 0.4²) > 0.75).
    let a = centre + Vec3::new(0.3, 0.4, 0.0);
    let [got, other] = pair_acc(&model, a, v);
    let n = Vec3::new(0.6, 0.8, 0.0);
    assert_close(got, by_hand(0.25, n, v), "inside the sphere");
    assert_eq!(other, Vec3::ZERO, "outside the sphere: no force");
    // On the surface (distance exactly 0.75 along z): no force.
    let [on, _] = pair_acc(&model, centre + Vec3::new(0.0, 0.0, 0.75), v);
    assert_eq!(on, Vec3::ZERO, "on the surface");
    // At the centre: pushed along +z by the whole radius.
    let [mid, _] = pair_acc(&model, centre, v);
    assert_close(
        mid,
        by_hand(0.75, Vec3::new(0.0, 0.0, 1.0), v),
        "at the centre",
    );
}

#[test]
fn solid_box_pushes_out_through_the_nearest_face() {
    // Narrower than the pair (0.75 along x), so the second point is always outside.
    let b = Aabb::new(Vec3::new(-1.0, -0.5, -1.5), Vec3::new(-0.25, 1.0, -0.25)).unwrap();
    let model = pair(vec![Obstacle::Box(b)]);
    let v = Vec3::new(-0.75, 0.5, 1.5);
    // Nearest faces, each at a depth smaller than to any other face.
    for (a, depth, n) in [
        (
            Vec3::new(-0.875, 0.25, -1.0),
            0.125,
            Vec3::new(-1.0, 0.0, 0.0),
        ),
        (
            Vec3::new(-0.5, 0.875, -0.75),
            0.125,
            Vec3::new(0.0, 1.0, 0.0),
        ),
        (
            Vec3::new(-0.5, 0.25, -1.4375),
            0.0625,
            Vec3::new(0.0, 0.0, -1.0),
        ),
        (
            Vec3::new(-0.5, 0.25, -0.375),
            0.125,
            Vec3::new(0.0, 0.0, 1.0),
        ),
    ] {
        // The second point, 1 m along x, is past the +x face: outside.
        let [got, other] = pair_acc(&model, a, v);
        assert_close(got, by_hand(depth, n, v), &format!("at {a:?}"));
        assert_eq!(other, Vec3::ZERO);
    }
    // A point outside, and one on a face: no force.
    for a in [Vec3::new(-1.5, 0.0, -1.0), Vec3::new(-1.0, 0.0, -1.0)] {
        assert_eq!(pair_acc(&model, a, v)[0], Vec3::ZERO, "{a:?}");
    }
}

#[test]
fn plane_obstacles_and_overlapping_obstacles_add_up() {
    // z ≥ −1 allowed (normal (0, 0, 2) points into it); a sphere overlapping the same region.
    let plane = Plane::new([0.0, 0.0, 2.0, 2.0]).unwrap();
    let sphere = Sphere::new(Vec3::new(0.0, 0.0, -1.5), 1.0).unwrap();
    let model = pair(vec![Obstacle::Plane(plane), Obstacle::Sphere(sphere)]);
    let v = Vec3::new(0.25, 0.5, -1.0);
    // 0.25 below the plane, 0.25 above the sphere's centre (depth 0.75 into it, normal +z).
    let a = Vec3::new(0.0, 0.0, -1.25);
    let [got, _] = pair_acc(&model, a, v);
    let z = Vec3::new(0.0, 0.0, 1.0);
    let want = by_hand(0.25, z, v) + by_hand(0.75, z, v);
    assert_close(got, want, "plane and sphere together");
    // The same plane with its coefficients scaled by λ > 0 gives the same force.
    let scaled = pair(vec![
        Obstacle::Plane(Plane::new([0.0, 0.0, 6.0, 6.0]).unwrap()),
        Obstacle::Sphere(sphere),
    ]);
    assert_close(pair_acc(&scaled, a, v)[0], want, "scaled plane");
    // Penetration is the deepest contact.
    let pos = [a, a + Vec3::new(1.0, 0.0, 0.0)];
    assert_eq!(max_penetration(&model, &pos), 0.75);
}

/// −∇(collision energy) at rest equals the contact force: energy and force read the same
/// contacts, for every shape, the walls and the classic plane.
#[test]
fn contact_force_is_minus_the_energy_gradient() {
    let model = ModelBuilder::new()
        .lattice(Lattice::new([2, 1, 1], Vec3::new(1.0, 1.0, 1.0)))
        .collision(KC, DC)
        .mass(MASS)
        .plane(Some(
            Plane::facing([0.3, -0.2, 1.0, 1.1], Vec3::ZERO).unwrap(),
        ))
        .obstacles(vec![
            Obstacle::Sphere(Sphere::new(Vec3::new(0.4, 0.2, -1.6), 0.9).unwrap()),
            Obstacle::Box(
                Aabb::new(Vec3::new(-1.9, -1.0, -2.5), Vec3::new(-0.8, 1.0, -1.0)).unwrap(),
            ),
            Obstacle::Plane(Plane::new([-1.0, 0.0, 0.0, 1.7]).unwrap()),
        ])
        .build()
        .unwrap();
    let mut rng = common::Lcg(11);
    let h = 1e-6;
    let mut checked = 0;
    for _ in 0..400 {
        // Random places in and around the obstacles, the second point 1 m along x (the spring
        // at rest), both at rest: the acceleration is the static contact force over the mass.
        let a = Vec3::new(-1.05, 0.1, -1.3) + rng.vec3();
        let pos = vec![a, a + Vec3::new(1.0, 0.0, 0.0)];
        let vel = vec![Vec3::ZERO; 2];
        let mut acc = vec![Vec3::ZERO; 2];
        accelerations(&model, &pos, &vel, &Control::none(), &mut acc);
        let collision_at = |point: usize, axis: usize, step: f64| {
            let mut moved = pos.clone();
            let mut c = moved[point].to_array();
            c[axis] += step;
            moved[point] = Vec3::from_array(c);
            energy(&model, &State::new(moved, vel.clone())).collision
        };
        for (point, acc) in acc.iter().enumerate() {
            let force = *acc * MASS;
            let mut minus_grad = [0.0; 3];
            let mut kink = false;
            for (axis, g) in minus_grad.iter_mut().enumerate() {
                let (e_plus, e_0, e_minus) = (
                    collision_at(point, axis, h),
                    collision_at(point, axis, 0.0),
                    collision_at(point, axis, -h),
                );
                // The energy is piecewise quadratic: where the one-sided slopes disagree, a
                // contact starts or its nearest face changes within h of the point (a kink).
                let (forward, backward) = ((e_plus - e_0) / h, (e_0 - e_minus) / h);
                kink |= (forward - backward).abs() > 1e-2;
                *g = -(e_plus - e_minus) / (2.0 * h);
            }
            if kink {
                continue;
            }
            let minus_grad = Vec3::from_array(minus_grad);
            // Rounding of the energy differences, ≈ E·ε/h: about 1e-7 of the forces here.
            assert!(
                (force - minus_grad).max_abs() <= 1e-5 * force.max_abs().max(1.0),
                "point {point} at {:?}: force {force:?}, −∇E {minus_grad:?}",
                pos[point]
            );
            if force.max_abs() > 0.0 {
                checked += 1;
            }
        }
    }
    assert!(
        checked > 100,
        "only {checked} points in contact were checked"
    );
}

/// A cube dropped on a sphere under gravity comes to rest on top of it.
#[test]
fn cube_dropped_on_a_sphere_comes_to_rest_on_it() {
    let mass = 1.0 / 512.0;
    let gravity = Vec3::new(0.0, 0.0, -9.81 * mass);
    let sphere = Sphere::new(Vec3::new(0.0, 0.0, -1.0), 0.6).unwrap();
    let model = ModelBuilder::new()
        .elastic(400.0, 0.8)
        .collision(2000.0, 5.0)
        .mass(mass)
        .field(Some(
            ForceField::from_fn(2, Aabb::classic(), |_| gravity).unwrap(),
        ))
        .obstacle(Obstacle::Sphere(sphere))
        .dt(0.0001)
        .build()
        .unwrap();
    // The cube centred over the sphere, its bottom 0.3 m above the sphere's top. Damped enough
    // (contacts near critically) to settle in 4.5 s.
    let mut state = State::at_rest(&model);
    state
        .pos
        .iter_mut()
        .for_each(|p| *p += Vec3::new(-0.5, -0.5, -0.1));
    let mut scratch = Scratch::new(&model);
    let control = Control::none();
    for _ in 0..45_000 {
        step(&model, &mut state, &control, &mut scratch).unwrap();
    }
    let com = centre_of_mass(&state.pos);
    let v = momentum(&model, &state.vel) / (mass * 512.0);
    let top = sphere.centre.z + sphere.radius;
    let lowest = state.pos.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
    // At rest: the centre of mass still over the sphere, above its top, not moving.
    assert!(
        v.length() < 1e-2,
        "centre-of-mass velocity {v:?} after 4.5 s"
    );
    assert!(
        com.x.abs() < 0.05 && com.y.abs() < 0.05,
        "slid off: centre of mass {com:?}"
    );
    assert!(
        com.z > top,
        "centre of mass {com:?} below the sphere's top {top}"
    );
    // Resting on it: the lowest points sag around the sphere a little, never through it.
    assert!(lowest < top, "not touching: lowest point {lowest}");
    assert!(
        max_penetration(&model, &state.pos) < 0.05,
        "penetration {}",
        max_penetration(&model, &state.pos)
    );
}

/// Obstacles on the threaded path, with friction (anchors tied and dragged): the same bits on 1
/// and 3 threads.
#[test]
fn threaded_contacts_are_bit_identical() {
    let run = |threads: usize| {
        common::on_threads(threads, || {
            let (model, mut state) = benchmark::scene(22, Integrator::Rk4).unwrap();
            let model = ModelBuilder::new()
                .lattice(model.body(0).lattice().clone())
                .mass(model.body(0).material.mass)
                .field(model.field.clone())
                .obstacles(vec![
                    Obstacle::Sphere(Sphere::new(Vec3::new(0.3, -0.2, 0.4), 0.5).unwrap()),
                    Obstacle::Box(
                        Aabb::new(Vec3::new(-0.6, -0.6, -0.6), Vec3::new(-0.2, 0.1, 0.0)).unwrap(),
                    ),
                    Obstacle::Plane(Plane::new([0.0, 1.0, 1.0, 0.45]).unwrap()),
                ])
                .friction(0.5)
                .build()
                .unwrap();
            let mut scratch = Scratch::new(&model);
            for _ in 0..5 {
                step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
            }
            state
        })
    };
    let (one, three) = (run(1), run(3));
    assert!(one.pos == three.pos && one.vel == three.vel);
    assert!(
        max_penetration(&ModelBuilder::new().build().unwrap(), &one.pos) == 0.0,
        "the scene stays inside the box"
    );
}

#[test]
fn bad_obstacles_are_errors_naming_them() {
    let sphere = |c: Vec3, r: f64| {
        Obstacle::Sphere(Sphere {
            centre: c,
            radius: r,
        })
    };
    let ok = sphere(Vec3::ZERO, 1.0);
    for (bad, what) in [
        (sphere(Vec3::ZERO, 0.0), "radius"),
        (sphere(Vec3::ZERO, -1.0), "radius"),
        (sphere(Vec3::new(f64::NAN, 0.0, 0.0), 1.0), "centre"),
        (sphere(Vec3::ZERO, f64::INFINITY), "radius"),
        (
            Obstacle::Box(Aabb {
                min: Vec3::new(0.0, 0.0, 0.0),
                max: Vec3::new(1.0, -1.0, 1.0),
            }),
            "min < max",
        ),
        (
            Obstacle::Plane(Plane {
                coeffs: [0.0, 0.0, 0.0, 1.0],
                side: 1.0,
            }),
            "normal",
        ),
    ] {
        let err = ModelBuilder::new()
            .obstacles(vec![ok, bad])
            .build()
            .unwrap_err()
            .to_string();
        assert!(
            err.starts_with("obstacle 2: ") && err.contains(what),
            "{bad:?}: {err}"
        );
    }
    assert!(Sphere::new(Vec3::ZERO, -1.0).is_err());
    assert!(Aabb::new(Vec3::ZERO, Vec3::ZERO).is_err());
    assert!(Plane::new([0.0, 0.0, 0.0, 1.0]).is_err());
}

#[test]
fn world_files_refuse_obstacles() {
    let model = ModelBuilder::new()
        .obstacle(Obstacle::Sphere(Sphere::new(Vec3::ZERO, 0.5).unwrap()))
        .build()
        .unwrap();
    let state = State::at_rest(&model);
    let err = World::from_simulation(&model, &state)
        .unwrap_err()
        .to_string();
    assert!(err.contains("obstacles"), "{err}");
}
