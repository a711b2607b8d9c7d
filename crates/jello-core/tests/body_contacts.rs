//! Contacts between bodies: the broad phase's hashed grid finds every pair an all-pairs search
//! finds, on random scenes of three and more bodies, and three bodies pressed together by known
//! overlaps feel the forces worked out by hand.

mod common;

use common::Lcg as Rng;
use jello_core::compute::soa::Soa;
use jello_core::contact::{pair_force, Contacts};
use jello_core::{Aabb, Body, Lattice, Material, Model, ModelBuilder, Vec3};

/// A full box of `counts` points of spacing `h`, its first point at `at`.
fn lattice_at(counts: [usize; 3], h: f64, at: Vec3) -> Body {
    let size = Vec3::new(
        h * (counts[0] - 1) as f64,
        h * (counts[1] - 1) as f64,
        h * (counts[2] - 1) as f64,
    );
    let mut material = Material::classic();
    material.mass = 0.01;
    Body::lattice_box(Lattice::new(counts, size), material)
        .placed(at, jello_core::model::body::IDENTITY)
}

fn model(bodies: Vec<Body>, friction: f64) -> Model {
    ModelBuilder::new()
        .bodies(bodies)
        .bounds(Aabb::new(Vec3::new(-9.0, -9.0, -9.0), Vec3::new(9.0, 9.0, 9.0)).unwrap())
        .collision(400.0, 0.3)
        .friction(friction)
        .build()
        .unwrap()
}

/// Every point's contact force by brute force: the pair force of every pair of active points of
/// different bodies, the friction's cap the pair's reduced mass over the step.
fn all_pairs(model: &Model, pos: &[Vec3], vel: &[Vec3]) -> Vec<Vec3> {
    let mut force = vec![Vec3::ZERO; pos.len()];
    let bodies = model.bodies();
    for (i, a) in bodies.iter().enumerate() {
        for (j, b) in bodies.iter().enumerate() {
            if i == j {
                continue;
            }
            let reach = a.contact_radius() + b.contact_radius();
            let (ma, mb) = (a.material.mass, b.material.mass);
            let c_max = ma * mb / ((ma + mb) * model.dt);
            let law = [model.k_collision, model.d_collision, model.friction, c_max];
            for p in a.points().filter(|&p| a.is_active(p - a.points().start)) {
                for q in b.points().filter(|&q| b.is_active(q - b.points().start)) {
                    force[p] += pair_force(pos[p] - pos[q], vel[p] - vel[q], reach, law);
                }
            }
        }
    }
    force
}

fn grid_forces(model: &Model, pos: &[Vec3], vel: &[Vec3]) -> Vec<Vec3> {
    let mut contacts = Contacts::new(model);
    contacts.compute(model, &Soa::from_aos(pos), &Soa::from_aos(vel));
    (0..pos.len()).map(|i| contacts.forces().get(i)).collect()
}

/// Random scenes of 3 to 6 small lattices of different spacings, heaped on one another with
/// random velocities: the grid's forces are the all-pairs search's, point for point (up to the
/// order of the sums), and many points are in contact.
#[test]
fn the_grid_finds_every_pair_an_all_pairs_search_finds() {
    let mut rng = Rng(11);
    let mut touching = 0;
    for scene in 0..40 {
        let count = 3 + scene % 4;
        let bodies: Vec<Body> = (0..count)
            .map(|_| {
                let counts = [0; 3].map(|_| 2 + (rng.next().abs() * 3.0) as usize);
                let h = 0.1 + 0.15 * rng.next().abs();
                lattice_at(counts, h, rng.vec3() * 0.3)
            })
            .collect();
        let model = model(bodies, if scene % 2 == 0 { 0.5 } else { 0.0 });
        let n = model.point_count();
        let mut pos = jello_core::State::at_rest(&model).pos;
        for p in &mut pos {
            *p += rng.vec3() * 0.05;
        }
        let vel: Vec<Vec3> = (0..n).map(|_| rng.vec3()).collect();
        let (want, got) = (
            all_pairs(&model, &pos, &vel),
            grid_forces(&model, &pos, &vel),
        );
        for (p, (w, g)) in want.iter().zip(&got).enumerate() {
            assert!(
                (*w - *g).max_abs() <= 1e-9 * (1.0 + w.max_abs()),
                "scene {scene}, point {p}: grid {g:?}, all pairs {w:?}"
            );
            touching += usize::from(w.max_abs() > 0.0);
        }
    }
    assert!(touching > 500, "only {touching} points in contact");
}

/// Three cubes of 2 × 2 × 2 points (spacing 0.2 m, balls of 0.1 m): A at the origin, B beside
/// it along x with its near face 0.15 m from A's (0.05 m of overlap), C above it along z with its
/// near face 0.18 m from A's top (0.02 m). With kCollision 400 N/m and no damping or friction,
/// each point of those faces is pushed by the point across from it, 400·depth along the line
/// between them (20 N and 8 N); the diagonal neighbours across (0.25 m and 0.27 m away) and the
/// other points feel nothing, and the forces sum to zero.
#[test]
fn three_bodies_feel_the_forces_of_their_overlaps() {
    let a = lattice_at([2; 3], 0.2, Vec3::ZERO);
    let b = lattice_at([2; 3], 0.2, Vec3::new(0.35, 0.0, 0.0));
    let c = lattice_at([2; 3], 0.2, Vec3::new(0.0, 0.0, 0.38));
    let model = ModelBuilder::new()
        .bodies(vec![a, b, c])
        .collision(400.0, 0.0)
        .friction(0.0)
        .build()
        .unwrap();
    let state = jello_core::State::at_rest(&model);
    let force = grid_forces(&model, &state.pos, &state.vel);
    // Point (i, j, k) of body `body` (A 0, B 1, C 2) is at flat index 8·body + 4i + 2j + k.
    let at = |body: usize, [i, j, k]: [usize; 3]| 8 * body + 4 * i + 2 * j + k;
    let mut want = vec![Vec3::ZERO; 24];
    for j in 0..2 {
        for k in 0..2 {
            // A's face i = 1 against B's face i = 0.
            want[at(0, [1, j, k])] += Vec3::new(-20.0, 0.0, 0.0);
            want[at(1, [0, j, k])] += Vec3::new(20.0, 0.0, 0.0);
        }
    }
    for i in 0..2 {
        for j in 0..2 {
            // A's top k = 1 against C's bottom k = 0.
            want[at(0, [i, j, 1])] += Vec3::new(0.0, 0.0, -8.0);
            want[at(2, [i, j, 0])] += Vec3::new(0.0, 0.0, 8.0);
        }
    }
    for (p, (g, w)) in force.iter().zip(&want).enumerate() {
        assert!((*g - *w).max_abs() < 1e-9, "point {p}: {g:?}, want {w:?}");
    }
    let total = force.iter().fold(Vec3::ZERO, |s, &f| s + f);
    assert!(total.max_abs() < 1e-9, "{total:?}");
}
