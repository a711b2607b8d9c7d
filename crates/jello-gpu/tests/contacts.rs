//! Contacts between bodies on the GPU against the f64 core's surface contacts: the forces of
//! bodies pressed into each other (boxes, a lattice with holes, a body made from a mesh with
//! its skin's samples, a sheet without volume), a cube resting on another, and the same bits on
//! every run (on lavapipe where there is no GPU; see `agreement.rs`).

use jello_core::contact::overlap;
use jello_core::model::body::rotation_xyz;
use jello_core::model::contact_surface::{FINE_REFINE, REFINE};
use jello_core::{Body, Control, Integrator, Lattice, Material, Model, ModelBuilder, State, Vec3};

mod common;
use common::{cpu, gpu, largest_gap};

/// A box of `counts` points, `size` wide, of a stiff material, its corner at `origin`, turned
/// by `degrees` about x, y and z.
fn block(counts: [usize; 3], size: Vec3, origin: Vec3, degrees: [f64; 3]) -> Body {
    Body::lattice_box(Lattice::new(counts, size), Material::classic())
        .with_modulus(2.0e5, 40.0, 1000.0)
        .placed(origin, rotation_xyz(degrees))
}

/// A lattice of 6 × 5 × 4 points, 0.5 × 0.4 × 0.3 m, with a slot cut along y through its top
/// half and a hole through its bottom, its corner at `origin`.
fn holey(origin: Vec3) -> Body {
    let (cx, cy, cz) = (5, 4, 3);
    let kept = (0..cx * cy * cz)
        .map(|c| {
            let (i, j, k) = (c / (cy * cz), c / cz % cy, c % cz);
            let slot = (2..=3).contains(&i) && k >= 1;
            let hole = i == 1 && j == 1 && k == 0;
            !(slot || hole)
        })
        .collect();
    let lattice = Lattice::new([cx + 1, cy + 1, cz + 1], Vec3::new(0.5, 0.4, 0.3));
    Body::from_cells(lattice, kept, Material::classic())
        .unwrap()
        .with_modulus(2.0e5, 40.0, 1000.0)
        .placed(origin, rotation_xyz([0.0, 0.0, 0.0]))
}

/// An octahedron of radius `r` about `centre`, voxelised with 5 cells along its side and
/// carrying its mesh as its skin (samples inside cells, not at their corners).
fn octahedron(centre: Vec3, r: f64) -> Body {
    let axis = |x, y, z| Vec3::new(x, y, z);
    turned_octahedron(
        centre,
        r,
        [
            axis(1.0, 0.0, 0.0),
            axis(0.0, 1.0, 0.0),
            axis(0.0, 0.0, 1.0),
        ],
    )
}

/// An octahedron of radius `r` about `centre`, its tips along the right-handed orthonormal
/// `frame`, voxelised as `octahedron`.
fn turned_octahedron(centre: Vec3, r: f64, [ex, ey, ez]: [Vec3; 3]) -> Body {
    let axes = [ex * r, ex * -r, ey * r, ey * -r, ez * r, ez * -r];
    let vertices: Vec<Vec3> = axes.iter().map(|&a| centre + a).collect();
    let mut triangles = Vec::new();
    for (x, sx) in [(0u32, 1.0), (1, -1.0)] {
        for (y, sy) in [(2u32, 1.0), (3, -1.0)] {
            for (z, sz) in [(4u32, 1.0), (5, -1.0)] {
                // Wound outward: (x, y, z) in a right-handed octant, reversed in the others.
                triangles.push(if sx * sy * sz > 0.0 {
                    [x, y, z]
                } else {
                    [x, z, y]
                });
            }
        }
    }
    Body::from_mesh(&vertices, &triangles, 5, 10_000, Material::classic())
        .unwrap()
        .with_modulus(2.0e5, 40.0, 1000.0)
}

/// A sheet of 4 × 4 points one point thick (no cells: each point a sample, nothing inside it).
fn sheet(origin: Vec3) -> Body {
    Body::lattice_box(
        Lattice::new([4, 4, 1], Vec3::new(0.3, 0.3, 0.1)),
        Material::classic(),
    )
    .placed(origin, rotation_xyz([0.0, 0.0, 0.0]))
}

/// `bodies` in zero gravity, touching with friction `mu`, stepped by `integrator`; each body
/// moving at its own velocity (so that the contacts' damping and friction act), at rest shape.
fn scene(bodies: Vec<Body>, mu: f64, integrator: Integrator) -> (Model, State) {
    let model = ModelBuilder::new()
        .bodies(bodies)
        .collision(20000.0, 20.0)
        .friction(mu)
        .gravity(Vec3::ZERO)
        .dt(0.0001)
        .integrator(integrator)
        .build()
        .unwrap();
    let mut state = State::at_rest(&model);
    for (b, body) in model.bodies().iter().enumerate() {
        let v = Vec3::new(0.3 - 0.2 * b as f64, 0.1 * b as f64, -0.2 + 0.15 * b as f64);
        state.vel[body.points()].iter_mut().for_each(|u| *u = v);
    }
    (model, state)
}

/// Two cubes pressed 3 mm into each other, the upper turned and shifted across the lower's
/// edge.
fn stacked() -> Vec<Body> {
    vec![
        block(
            [5, 5, 5],
            Vec3::new(0.4, 0.4, 0.4),
            Vec3::new(-0.2, -0.2, -0.4),
            [0.0, 0.0, 0.0],
        ),
        block(
            [4, 5, 4],
            Vec3::new(0.3, 0.35, 0.3),
            Vec3::new(-0.05, -0.13, -0.003),
            [0.0, 0.0, 17.0],
        ),
    ]
}

/// A lattice with holes; an octahedron wedged into its slot, its tips 1 cm deep in the slot's
/// walls and floor; a cube pressed 4 mm into its bottom, under its hole; a sheet lying 2 mm deep
/// in its top.
fn crowd() -> Vec<Body> {
    vec![
        holey(Vec3::new(-0.25, -0.2, -0.3)),
        octahedron(Vec3::new(0.05, 0.02, -0.1), 0.11),
        block(
            [3, 3, 3],
            Vec3::new(0.2, 0.2, 0.2),
            Vec3::new(-0.12, -0.05, -0.5 + 0.004),
            [0.5, 0.0, 0.0],
        ),
        sheet(Vec3::new(-0.24, -0.19, -0.002)),
    ]
}

/// The accelerations of every point at `state` by one Euler step, on the GPU and on the core.
fn accelerations(model: &Model, state: &State) -> (Vec<Vec3>, Vec<Vec3>) {
    let control = Control::default();
    let mut sim = gpu(model, state, &control);
    sim.step(1).unwrap();
    let on_gpu = sim.read_state().unwrap();
    let on_cpu = cpu(model, state, &control, 1);
    // The start as the GPU holds it (f32).
    let start = jello_gpu_start(state);
    let slope = |end: &State, start: &[Vec3]| -> Vec<Vec3> {
        end.vel
            .iter()
            .zip(start)
            .map(|(v, v0)| (*v - *v0) * (1.0 / model.dt))
            .collect()
    };
    (slope(&on_gpu, &start), slope(&on_cpu, &state.vel))
}

/// The velocities of `state` in f32, as uploaded.
fn jello_gpu_start(state: &State) -> Vec<Vec3> {
    let f = |x: f64| x as f32 as f64;
    state
        .vel
        .iter()
        .map(|v| Vec3::new(f(v.x), f(v.y), f(v.z)))
        .collect()
}

/// Fails unless every point's acceleration on the GPU is the core's to `tolerance` of the
/// largest; returns how many points the contacts push (more than 1 % of the largest).
fn assert_same_accelerations(model: &Model, state: &State, tolerance: f64, what: &str) -> usize {
    let (on_gpu, on_cpu) = accelerations(model, state);
    let largest = on_cpu.iter().map(|a| a.length()).fold(0.0, f64::max);
    let mut worst = 0.0f64;
    for (p, (g, c)) in on_gpu.iter().zip(&on_cpu).enumerate() {
        let gap = (*g - *c).length();
        worst = worst.max(gap);
        assert!(
            gap <= tolerance * largest,
            "{what}: point {p}: {g:?} on the GPU, {c:?} on the core (largest {largest:.3e})"
        );
    }
    eprintln!("{what}: largest acceleration {largest:.3e}, worst gap {worst:.3e}");
    on_cpu
        .iter()
        .filter(|a| a.length() > 0.01 * largest)
        .count()
}

#[test]
fn contact_forces_agree_with_the_core() {
    for (what, bodies, least) in [("stacked", stacked(), 20), ("crowd", crowd(), 30)] {
        for (mu, integrator) in [(0.0, Integrator::Euler), (0.5, Integrator::Euler)] {
            let (model, state) = scene(bodies.clone(), mu, integrator);
            let what = format!("{what}, μ = {mu}");
            let pushed = assert_same_accelerations(&model, &state, 1e-4, &what);
            assert!(pushed >= least, "{what}: only {pushed} points pushed");
        }
    }
}

/// An octahedron's tip pressed 5 mm into the upper face of another, turned so that its edges
/// lie across the lattice's planes, where a grid four times as fine rounds them: its distance
/// grid is eight times as fine as its lattice, the upper one's four times. The GPU reads each as
/// the core does.
#[test]
fn distance_grids_of_either_fineness_agree_with_the_core() {
    let r = 0.11;
    // The lower one's (1, 1, 1) face turned to face up: its frame maps (1, −1, 0)/√2 to x,
    // (1, 1, −2)/√6 to y and (1, 1, 1)/√3 to z.
    let (a, b, c) = (0.5f64.sqrt(), (1.0f64 / 6.0).sqrt(), (1.0f64 / 3.0).sqrt());
    let frame = [
        Vec3::new(a, b, c),
        Vec3::new(-a, b, c),
        Vec3::new(0.0, -2.0 * b, c),
    ];
    let below = turned_octahedron(Vec3::ZERO, r, frame);
    let above = octahedron(Vec3::new(0.004, -0.003, r * c + r - 0.005), r);
    assert_eq!(below.contact_surface().refine(), FINE_REFINE);
    assert_eq!(above.contact_surface().refine(), REFINE);
    let (model, state) = scene(vec![below, above], 0.5, Integrator::Euler);
    let pushed = assert_same_accelerations(&model, &state, 1e-4, "tip on face");
    assert!(pushed >= 4, "only {pushed} points pushed");
}

#[test]
fn a_cube_resting_on_another_moves_as_on_the_core() {
    // Under gravity the upper cube settles onto the lower, which rests on the box's floor; both
    // bounce a little and settle, as on the core.
    let bodies = vec![
        block(
            [5, 5, 5],
            Vec3::new(0.4, 0.4, 0.4),
            Vec3::new(-0.2, -0.2, -2.0),
            [0.0, 0.0, 0.0],
        ),
        block(
            [4, 4, 4],
            Vec3::new(0.3, 0.3, 0.3),
            Vec3::new(-0.1, -0.05, -1.6 + 0.001),
            [0.0, 0.0, 20.0],
        ),
    ];
    let model = ModelBuilder::new()
        .bodies(bodies)
        .collision(20000.0, 20.0)
        .friction(0.4)
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .dt(0.0005)
        .integrator(Integrator::Rk4)
        .build()
        .unwrap();
    let state = State::at_rest(&model);
    let control = Control::default();
    let steps = 600;
    let mut sim = gpu(&model, &state, &control);
    sim.step(steps).unwrap();
    let on_gpu = sim.read_state().unwrap();
    let reference = cpu(&model, &state, &control, steps);
    let gap = largest_gap(&on_gpu, &reference);
    eprintln!("resting: {gap:.3e} m from the core");
    assert!(gap < 1e-5, "{gap:.3e} m from the core");
    // It rests on the lower cube: sunk into it by its weight over the touching samples'
    // stiffness, a millimetre or so, not fallen through.
    let (deepest, _) = overlap(&model, &on_gpu.pos);
    eprintln!("resting: {deepest:.3e} m deep");
    assert!(deepest > 0.0 && deepest < 0.01, "{deepest} m deep");
}

#[test]
fn contacts_of_every_kind_of_body_give_the_same_bits_every_run() {
    let (model, state) = scene(crowd(), 0.5, Integrator::Rk4);
    let control = Control::default();
    let run = || {
        let mut sim = gpu(&model, &state, &control);
        sim.step(150).unwrap();
        sim.step(50).unwrap();
        sim.read_state().unwrap()
    };
    let (first, second) = (run(), run());
    assert!(
        first.pos != state.pos,
        "the bodies moved (the run did something)"
    );
    assert_eq!(first.pos, second.pos);
    assert_eq!(first.vel, second.vel);
}

/// The octahedron turned by 45° and 35° (its cage's corners stick out past its skin) sunk into
/// the box's floor and a solid box, moving, with friction on both: every point's acceleration as
/// on the core, which takes each point's clearance off its depth; some points are pushed, and
/// some that are inside the floor are not (their skin is not).
#[test]
fn a_turned_mesh_body_meets_walls_and_obstacles_with_its_skin_as_on_the_core() {
    use jello_core::{Aabb, Obstacle};
    let body = octahedron(Vec3::ZERO, 0.3);
    let turned = body
        .clone()
        .placed(body.origin, rotation_xyz([45.0, 35.0, 0.0]));
    let rest = ModelBuilder::new()
        .bodies(vec![turned.clone()])
        .build()
        .unwrap();
    let at_rest = State::at_rest(&rest);
    let lowest = |axis: usize| {
        (0..rest.point_count())
            .filter(|&q| rest.body(0).is_active(q))
            .map(|q| at_rest.pos[q].to_array()[axis])
            .fold(f64::INFINITY, f64::min)
    };
    // The floor 18 cm above the lowest point, a solid box's face 18 cm inside the lowest x: past
    // the clearance of the cage's corners (14 cm), not of the points beside them.
    let (floor, side) = (lowest(2) + 0.18, lowest(0) + 0.18);
    let model = ModelBuilder::new()
        .bodies(vec![turned])
        .bounds(Aabb::new(Vec3::new(-2.0, -2.0, floor), Vec3::new(2.0, 2.0, 2.0)).unwrap())
        .obstacle(Obstacle::Box(
            Aabb::new(Vec3::new(-2.0, -1.0, -1.0), Vec3::new(side, 1.0, 1.0)).unwrap(),
        ))
        .collision(20000.0, 20.0)
        .friction(0.5)
        .wall_friction(0.4)
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .dt(0.0001)
        .integrator(Integrator::Euler)
        .build()
        .unwrap();
    assert!(!model.clearance().is_empty());
    let mut state = State::at_rest(&model);
    state
        .vel
        .iter_mut()
        .for_each(|v| *v = Vec3::new(-0.3, 0.2, -0.4));
    let pushed = assert_same_accelerations(&model, &state, 1e-4, "turned octahedron");
    let clear = (0..model.point_count())
        .filter(|&i| {
            let p = state.pos[i];
            let depth = (floor - p.z).max(side - p.x);
            depth > 0.0 && depth < model.clearance_of(i)
        })
        .count();
    assert!(
        pushed >= 2 && clear >= 1,
        "{pushed} pushed, {clear} inside but clear"
    );
}
