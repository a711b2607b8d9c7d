//! Bodies made from meshes meet the walls, the plane and the obstacles with their skins, not the
//! cage of cells around them (docs/scenes.md, "Walls, planes and obstacles"): a sphere turned so
//! that its cage's corners stick out past its skin rests on a plate, or on the box's floor,
//! where the unturned one does, under an explicit and an implicit integrator.

#[path = "common/meshes.rs"]
mod meshes;

use jello_core::diagnostics::max_penetration;
use jello_core::model::body::rotation_xyz;
use jello_core::{
    Aabb, Body, Integrator, Material, Model, ModelBuilder, Obstacle, Simulation, State, Vec3,
};

const RADIUS: f64 = 0.3;

/// A sphere of radius 0.3 m about the origin voxelised with 6 cells (5 cm cells), of a light
/// jelly (22 kg), turned about its middle by `degrees` about x, y and z.
fn sphere(degrees: [f64; 3]) -> Body {
    let mesh = meshes::uv_sphere(Vec3::ZERO, RADIUS, 12, 24);
    let body = Body::from_mesh(
        &mesh.vertices,
        &mesh.triangles,
        6,
        10_000,
        Material::classic(),
    )
    .unwrap()
    .with_modulus(1.0e5, 30.0, 200.0);
    // Turned about the sphere's centre: lattice point 0 goes to R·origin.
    let turn = rotation_xyz(degrees);
    let o = body.origin;
    let origin = Vec3::new(turn[0].dot(o), turn[1].dot(o), turn[2].dot(o));
    body.placed(origin, turn)
}

/// The lowest point of body 0's skin and of its active lattice points (m).
fn lowest(model: &Model, pos: &[Vec3]) -> (f64, f64) {
    let body = model.body(0);
    let points = &pos[body.points()];
    let skin = body.skin.as_ref().unwrap();
    let mut vertices = vec![Vec3::ZERO; skin.len()];
    skin.positions(points, &mut vertices);
    let skin_low = vertices.iter().map(|v| v.z).fold(f64::INFINITY, f64::min);
    let cage_low = (0..body.len())
        .filter(|&q| body.is_active(q))
        .map(|q| points[q].z)
        .fold(f64::INFINITY, f64::min);
    (skin_low, cage_low)
}

/// The sphere turned by `degrees` dropped 2 cm onto a 10 cm plate (`floor`: onto the box's
/// floor) and left 3 s: where its skin's and its cage's lowest points end, against the surface
/// it rests on, and its deepest penetration then.
fn rest(degrees: [f64; 3], floor: bool, integrator: Integrator, dt: f64) -> (f64, f64, f64) {
    let body = sphere(degrees);
    let start = ModelBuilder::new()
        .bodies(vec![body.clone()])
        .build()
        .unwrap();
    let (skin_low, _) = lowest(&start, &State::at_rest(&start).pos);
    let top = skin_low - 0.02;
    let mut builder = ModelBuilder::new()
        .bodies(vec![body])
        .collision(1.0e5, 5.0)
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .integrator(integrator)
        .dt(dt);
    builder = if floor {
        builder
            .bounds(Aabb::new(Vec3::new(-2.0, -2.0, top), Vec3::new(2.0, 2.0, top + 4.0)).unwrap())
    } else {
        let plate = Aabb::new(Vec3::new(-1.0, -1.0, top - 0.1), Vec3::new(1.0, 1.0, top));
        builder.obstacle(Obstacle::Box(plate.unwrap()))
    };
    let model = builder.build().unwrap();
    let mut sim = Simulation::new(model.clone(), State::at_rest(&model));
    let steps = (3.0 / dt).round() as usize;
    for _ in 0..steps {
        sim.step().unwrap();
    }
    let (skin, cage) = lowest(&model, &sim.state.pos);
    (
        skin - top,
        cage - top,
        max_penetration(&model, &sim.state.pos),
    )
}

#[test]
fn a_turned_sphere_rests_on_its_skin_where_the_unturned_one_does() {
    for (integrator, dt) in [
        (Integrator::Rk4, 0.0005),
        (Integrator::BackwardEuler, 1.0 / 60.0),
    ] {
        for floor in [false, true] {
            let what = format!(
                "{integrator:?}, on the {}",
                if floor { "floor" } else { "plate" }
            );
            let (straight, straight_cage, _) = rest([0.0, 0.0, 0.0], floor, integrator, dt);
            let (turned, turned_cage, deepest) = rest([45.0, 35.0, 0.0], floor, integrator, dt);
            eprintln!(
                "{what}: skin {straight:.4} m (cage {straight_cage:.4}) unturned, \
                 {turned:.4} m (cage {turned_cage:.4}) turned, deepest {deepest:.4} m"
            );
            // The skin touches: a little into the surface at most, never above it. Turned, it
            // goes up to 1.4 cm in (a seventh of a cell: a point's clearance is its distance to
            // the nearest skin, which may lie aslant, not straight above it; on the plate, the
            // corners further out than half its thickness pass it by), while the cage's corner
            // sits centimetres into the surface, where it used to hold the skin 7 cm above it.
            let (above, below) = (0.001, 0.02);
            for (skin, name) in [(straight, "unturned"), (turned, "turned")] {
                assert!(
                    (-below..=above).contains(&skin),
                    "{what}, {name}: the skin rests {skin} m from the surface"
                );
            }
            assert!(straight > -0.005, "{what}: {straight} m");
            assert!(
                turned_cage < -0.05,
                "{what}: the cage's corner at {turned_cage} m"
            );
            // The deepest penetration is the skin's, not the cage's.
            assert!(deepest < 0.01, "{what}: {deepest} m deep");
        }
    }
}
