//! Contacts between bodies, surface to surface: three bodies pressed together by known depths
//! feel the forces worked out by hand, and the contact forces of random heaps of bodies sum to
//! zero (they conserve momentum). The broad phase is compared with a search over every cell in
//! the contact module's own tests.

mod common;

use common::Lcg as Rng;
use jello_core::compute::soa::Soa;
use jello_core::contact::Contacts;
use jello_core::model::body::IDENTITY;
use jello_core::{Aabb, Body, Lattice, Material, Model, ModelBuilder, State, Vec3};

/// A full box of `counts` points and sides `size`, its first point at `at`.
fn box_at(counts: [usize; 3], size: Vec3, at: Vec3) -> Body {
    let mut material = Material::classic();
    material.mass = 0.01;
    Body::lattice_box(Lattice::new(counts, size), material).placed(at, IDENTITY)
}

fn forces(model: &Model, pos: &[Vec3], vel: &[Vec3]) -> Vec<Vec3> {
    let mut contacts = Contacts::new(model);
    contacts.compute(model, &Soa::from_aos(pos), &Soa::from_aos(vel));
    (0..pos.len()).map(|i| contacts.forces().get(i)).collect()
}

/// A coarse slab B (5 × 5 × 3 points, 2 × 2 × 1 m, cells of 0.5 m) and two small cubes on it (3
/// × 3 × 3 points, 0.2 m), A sunk 1 cm into its top and C 2 cm, both well inside its top face
/// and between its lattice points (so that none of B's surface points is inside them). Each of
/// a cube's nine bottom points is pushed up by kCollision × its depth (4 N and 8 N at 400 N/m,
/// no damping), every other point of the cubes feels nothing, and the slab takes exactly the
/// opposite.
#[test]
fn three_bodies_feel_the_forces_of_their_depths() {
    let slab = box_at([5, 5, 3], Vec3::new(2.0, 2.0, 1.0), Vec3::ZERO);
    let side = Vec3::new(0.2, 0.2, 0.2);
    let a = box_at([3; 3], side, Vec3::new(0.6, 0.6, 1.0 - 0.01));
    let c = box_at([3; 3], side, Vec3::new(1.1, 1.1, 1.0 - 0.02));
    let model = ModelBuilder::new()
        .bodies(vec![slab, a, c])
        .collision(400.0, 0.0)
        .friction(0.0)
        .build()
        .unwrap();
    let state = State::at_rest(&model);
    let f = forces(&model, &state.pos, &state.vel);
    for (b, depth) in [(1, 0.01), (2, 0.02)] {
        let body = model.body(b);
        for (q, p) in body.points().enumerate() {
            let [_, _, k] = body.lattice().coords(q);
            let want = if k == 0 {
                Vec3::new(0.0, 0.0, 400.0 * depth)
            } else {
                Vec3::ZERO
            };
            assert!(
                (f[p] - want).max_abs() < 1e-9,
                "body {b}, point {q}: {:?}",
                f[p]
            );
        }
    }
    let on_slab = model.body(0).points().fold(Vec3::ZERO, |s, p| s + f[p]);
    let want = Vec3::new(0.0, 0.0, -9.0 * 400.0 * (0.01 + 0.02));
    assert!((on_slab - want).max_abs() < 1e-9, "{on_slab:?}");
}

/// Heaps of 3 to 6 boxes of different spacings, overlapping, moving at random with friction:
/// the contact forces on all points sum to zero (each touch's force and its reaction have
/// weights summing to one), and many points are pushed.
#[test]
fn contact_forces_conserve_momentum() {
    let mut rng = Rng(11);
    let mut pushed = 0;
    for scene in 0..30 {
        let count = 3 + scene % 4;
        let bodies: Vec<Body> = (0..count)
            .map(|_| {
                let counts = [0; 3].map(|_| 3 + (rng.next().abs() * 3.0) as usize);
                let h = 0.1 + 0.1 * rng.next().abs();
                let size = Vec3::new(
                    h * (counts[0] - 1) as f64,
                    h * (counts[1] - 1) as f64,
                    h * (counts[2] - 1) as f64,
                );
                box_at(counts, size, rng.vec3() * 0.3)
            })
            .collect();
        let model = ModelBuilder::new()
            .bodies(bodies)
            .bounds(Aabb::new(Vec3::new(-9.0, -9.0, -9.0), Vec3::new(9.0, 9.0, 9.0)).unwrap())
            .collision(400.0, 0.3)
            .friction(0.5)
            .build()
            .unwrap();
        let vel: Vec<Vec3> = (0..model.point_count()).map(|_| rng.vec3()).collect();
        let f = forces(&model, &State::at_rest(&model).pos, &vel);
        let total = f.iter().fold(Vec3::ZERO, |s, &f| s + f);
        let largest = f.iter().map(|f| f.max_abs()).fold(0.0, f64::max);
        assert!(
            total.max_abs() <= 1e-12 * largest.max(1.0),
            "scene {scene}: {total:?}"
        );
        pushed += f.iter().filter(|f| f.max_abs() > 0.0).count();
    }
    assert!(pushed > 300, "only {pushed} points pushed");
}

/// A U of soft cells (3 × 3 cells of 0.1 m in x and z, two deep: a bottom of three cells and
/// two arms of two cells each, a cell of air between them), its arms thrown at each other at
/// 2 m/s each with no gravity. With self-contact off they pass into each other; with it on
/// they meet and stay apart (the deepest any sample gets inside the other arm is a few
/// millimetres, the penalty's give: v·√(m/kCollision) at most), under an explicit and an
/// implicit integrator; either way, momentum stays zero (the self-contact's forces on a
/// sample's corners and on the cell it is in cancel).
#[test]
fn a_folded_bar_meets_itself() {
    use jello_core::Integrator;
    use jello_core::Simulation;
    let lattice = Lattice::new([4, 3, 4], Vec3::new(0.3, 0.2, 0.3));
    // Cells in flat order ((i · 2 + j) · 3 + k): the bottom row, and columns 0 and 2.
    let kept = (0..18).map(|c| c % 3 == 0 || c / 6 != 1).collect();
    let material = Material {
        mass: 0.01,
        stiffness: [0.5; 3],
        damping: [0.01; 3],
    };
    let body = Body::from_cells(lattice, kept, material).unwrap();
    let deepest = |integrator, dt: f64, self_contact: bool| {
        let model = ModelBuilder::new()
            .bodies(vec![body.clone()])
            .bounds(Aabb::new(Vec3::new(-9.0, -9.0, -9.0), Vec3::new(9.0, 9.0, 9.0)).unwrap())
            .gravity(Vec3::ZERO)
            .collision(2000.0, 0.0)
            .friction(0.0)
            .self_contact(self_contact)
            .integrator(integrator)
            .dt(dt)
            .build()
            .unwrap();
        let judge = model.to_builder().self_contact(true).build().unwrap();
        let mut state = State::at_rest(&model);
        for (q, v) in state.vel.iter_mut().enumerate() {
            let [i, _, k] = body.lattice().coords(q);
            if k >= 2 {
                *v = Vec3::new(if i <= 1 { 2.0 } else { -2.0 }, 0.0, 0.0);
            }
        }
        let mut sim = Simulation::new(model, state);
        let mut deepest: f64 = 0.0;
        for _ in 0..(0.1 / dt).round() as usize {
            sim.step().unwrap();
            deepest = deepest.max(jello_core::contact::overlap(&judge, &sim.state.pos).0);
            let momentum = sim.state.vel.iter().fold(Vec3::ZERO, |s, &v| s + v * 0.01);
            assert!(momentum.max_abs() < 1e-9, "{momentum:?}");
        }
        deepest
    };
    for (integrator, dt) in [(Integrator::Rk4, 1e-4), (Integrator::BackwardEuler, 1e-3)] {
        let off = deepest(integrator, dt, false);
        let on = deepest(integrator, dt, true);
        assert!(
            off > 0.03,
            "{integrator}: the arms stay apart without self-contact: {off}"
        );
        assert!(
            on < 0.006,
            "{integrator}: the arms go {on} m into each other"
        );
    }
}

/// Two cubes one above the other, 1 cm apart, then sunk 5 mm into each other, and one 2 m away:
/// the diagnostic reports the gap and the overlap of the pair within a cell, and nothing of the
/// far cube.
#[test]
fn the_closest_pairs_report_their_gap_and_overlap() {
    let side = Vec3::new(0.4, 0.4, 0.4);
    for (z, want) in [(0.41, -0.01), (0.395, 0.005)] {
        let model = ModelBuilder::new()
            .bodies(vec![
                box_at([5; 3], side, Vec3::ZERO),
                box_at([5; 3], side, Vec3::new(0.05, 0.02, z)),
                box_at([5; 3], side, Vec3::new(2.0, 0.0, 0.0)),
            ])
            .bounds(Aabb::new(Vec3::new(-9.0, -9.0, -9.0), Vec3::new(9.0, 9.0, 9.0)).unwrap())
            .build()
            .unwrap();
        let pairs = jello_core::contact::closest(&model, &State::at_rest(&model).pos);
        assert_eq!(pairs.len(), 1, "{pairs:?}");
        assert_eq!(pairs[0].bodies, [0, 1]);
        assert!((pairs[0].depth - want).abs() < 1e-9, "{pairs:?}");
    }
    // Two cubes in the same place: their surfaces coincide (no surface point is inside the
    // other), but the middles of their cells are: the deepest, half a cell from the faces
    // (0.1 m cells, inside 0.2 m from the nearest face at the middle cells: 0.15 m).
    let model = ModelBuilder::new()
        .bodies(vec![
            box_at([5; 3], side, Vec3::ZERO),
            box_at([5; 3], side, Vec3::ZERO),
        ])
        .build()
        .unwrap();
    let pairs = jello_core::contact::closest(&model, &State::at_rest(&model).pos);
    assert_eq!(pairs.len(), 1, "{pairs:?}");
    assert!((pairs[0].depth - 0.15).abs() < 1e-9, "{pairs:?}");
}

/// Under self-contact a body does not push on itself where it is not folded: a torus of 8
/// cells (its skin's samples on faces, edges and corners its cells share, and next to them) and
/// an L of three cells, at rest and with every point moved at random by up to 2 % of a cell,
/// feel no contact force. (A sample is found in the cells next to its own only at, or a rounding
/// from, its own place: no more than half a cell apart at rest, the same surface.)
#[test]
fn a_body_not_folded_does_not_push_on_itself() {
    use jello_core::formats::mesh::TriMesh;
    let mut rng = Rng(5);
    let ring = TriMesh::torus(0.3, 0.1, 24, 12);
    let torus = Body::from_mesh(
        &ring.vertices,
        &ring.triangles,
        8,
        1000,
        Material::classic(),
    );
    for body in [torus.unwrap(), ell()] {
        let model = ModelBuilder::new()
            .bodies(vec![body])
            .collision(2000.0, 1.0)
            .self_contact(true)
            .build()
            .unwrap();
        let cell = model.body(0).min_spacing();
        let mut pos = State::at_rest(&model).pos;
        let vel: Vec<Vec3> = (0..pos.len()).map(|_| rng.vec3()).collect();
        for jiggle in [0.0, 0.02 * cell] {
            for p in &mut pos {
                *p += rng.vec3() * jiggle;
            }
            let f = forces(&model, &pos, &vel);
            assert!(
                f.iter().all(|f| *f == Vec3::ZERO),
                "jiggled by {jiggle} m: {:?}",
                f.iter().find(|f| **f != Vec3::ZERO)
            );
        }
    }
}

/// An L of cells of 0.1 m, two deep (a corner, an arm beside it along x and one above it along
/// z: the arms' cells share only edges), its upper arm folded 120° about that edge onto the
/// lower one. The point in the middle of its upper arm's edge that was 0.1 m above the hinge is
/// now 0.05 m inside the lower arm, whose nearest face is 1.34 cm away: under self-contact it
/// is pushed out by kCollision × that depth along the face's normal, and the lower arm takes
/// the opposite force (momentum is kept). Cells that share an edge or a corner were never
/// tested against each other before: such a fold went through itself unseen.
#[test]
fn a_fold_between_neighbouring_cells_is_pushed_apart() {
    let h = 0.1;
    let model = ModelBuilder::new()
        .bodies(vec![ell()])
        .collision(2000.0, 0.0)
        .friction(0.0)
        .self_contact(true)
        .build()
        .unwrap();
    let body = model.body(0);
    let mut pos = State::at_rest(&model).pos;
    // The upper arm's top points turned 120° about the edge x = z = h, toward +x.
    let (sin, cos) = (120f64.to_radians().sin(), 120f64.to_radians().cos());
    for (q, p) in body.points().enumerate() {
        let [_, _, k] = body.lattice().coords(q);
        if k == 2 {
            let (x, z) = (pos[p].x - h, pos[p].z - h);
            pos[p].x = h + x * cos + z * sin;
            pos[p].z = h - x * sin + z * cos;
        }
    }
    let f = forces(&model, &pos, &vec![Vec3::ZERO; pos.len()]);
    let total = f.iter().fold(Vec3::ZERO, |s, &f| s + f);
    assert!(total.max_abs() < 1e-12, "{total:?}");
    // The point that was at (h, h, 2h) is now at (1.866 h, h, 0.5 h): 0.134 h inside the lower
    // arm's right face x = 2h (and 0.5 h below its top, h from its sides): pushed toward +x, by
    // 2000 N/m × 1.34 cm.
    let want = 2000.0 * (2.0 - (1.0 + sin)) * h;
    for (q, p) in body.points().enumerate() {
        if body.lattice().coords(q) == [1, 1, 2] {
            assert!(
                (f[p].x - want).abs() < 0.05 * want && f[p].y.abs() < 0.05 * want,
                "point {q} at {:?}: {:?}, want {want} along x",
                pos[p],
                f[p]
            );
        }
    }
}

/// An L of cells of 0.1 m, two cells deep along y: lattice 3 × 3 × 3 points, the cells
/// (0, j, 0), (1, j, 0) and (0, j, 1).
fn ell() -> Body {
    let lattice = Lattice::new([3; 3], Vec3::new(0.2, 0.2, 0.2));
    // Cells in flat order ((i · 2 + j) · 2 + k).
    let kept = (0..8).map(|c| !(c / 4 == 1 && c % 2 == 1)).collect();
    let mut material = Material::classic();
    material.mass = 0.01;
    Body::from_cells(lattice, kept, material).unwrap()
}

/// One cell of 0.1 m (springs of 100 N/m, points of 10 g, no damping, no gravity) with its
/// corner (1, 1, 1) pushed 0.6 of the way along the diagonal toward the opposite one, at rest:
/// that corner is turned inside out (its volume −0.8 of its volume at rest), and under
/// self-contact the cells' guard pushes it back out (a cell alone has no other surface to
/// touch).
fn squeezed_cell(
    self_contact: bool,
    integrator: jello_core::Integrator,
    dt: f64,
) -> (Model, State) {
    let material = Material {
        mass: 0.01,
        stiffness: [100.0; 3],
        damping: [0.0; 3],
    };
    let body = Body::lattice_box(Lattice::new([2; 3], Vec3::new(0.1, 0.1, 0.1)), material);
    let model = ModelBuilder::new()
        .bodies(vec![body])
        .bounds(Aabb::new(Vec3::new(-9.0, -9.0, -9.0), Vec3::new(9.0, 9.0, 9.0)).unwrap())
        .gravity(Vec3::ZERO)
        .self_contact(self_contact)
        .integrator(integrator)
        .dt(dt)
        .build()
        .unwrap();
    let mut state = State::at_rest(&model);
    let top = state.pos.len() - 1;
    state.pos[top] -= Vec3::new(0.1, 0.1, 0.1) * 0.6;
    (model, state)
}

/// The squeezed cell let go under RK4 (dt 10 µs, 0.05 s): it springs back, and its energy
/// (kinetic, springs', and the guard's, counted with the collisions') stays what it was to
/// 1e-6, as forces that are minus the gradient of the energy counted keep it; the guard holds
/// a third of it at the start.
#[test]
fn the_cells_guard_keeps_the_energy_it_counts() {
    use jello_core::{diagnostics::energy, Integrator, Simulation};
    let (model, state) = squeezed_cell(true, Integrator::Rk4, 1e-5);
    let start = energy(&model, &state);
    let guard = jello_core::contact::cell_guard::energy(&model, &state.pos);
    assert!(
        guard > 0.3 * start.total() && start.collision == guard,
        "{start:?}, guard {guard}"
    );
    let mut sim = Simulation::new(model, state);
    let mut fastest: f64 = 0.0;
    for _ in 0..5000 {
        sim.step().unwrap();
        let now = energy(&sim.model, &sim.state);
        assert!(
            (now.total() - start.total()).abs() < 1e-6 * start.total(),
            "{now:?} against {start:?}"
        );
        fastest = fastest.max(now.kinetic);
    }
    // It moved: most of the energy was kinetic at some point.
    assert!(fastest > 0.5 * start.total(), "{fastest}");
}

/// Backward Euler's step holds the guard in its residual: one step of 1 µs from the squeezed
/// cell at rest changes the squeezed corner's velocity by dt times its acceleration (springs
/// and guard, as the explicit force pass gives it) to 1e-4, and without self-contact by the
/// springs' alone, which differ from it by more than a tenth.
#[test]
fn an_implicit_step_feels_the_cells_guard() {
    use jello_core::{Integrator, Simulation};
    let dt = 1e-6;
    let mut pushes = Vec::new();
    for self_contact in [true, false] {
        let (model, state) = squeezed_cell(self_contact, Integrator::BackwardEuler, dt);
        let mut acc = vec![Vec3::ZERO; state.pos.len()];
        jello_core::forces::accelerations(
            &model,
            &state.pos,
            &state.vel,
            &Default::default(),
            &mut acc,
        );
        let top = state.pos.len() - 1;
        let mut sim = Simulation::new(model, state);
        sim.step().unwrap();
        let dv = sim.state.vel[top];
        assert!(
            (dv - acc[top] * dt).length() < 1e-4 * (acc[top] * dt).length(),
            "self-contact {self_contact}: Δv {dv:?}, dt·a {:?}",
            acc[top] * dt
        );
        pushes.push(acc[top]);
    }
    assert!(
        (pushes[0] - pushes[1]).length() > 0.1 * pushes[1].length(),
        "{pushes:?}"
    );
}
