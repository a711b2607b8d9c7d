//! Saving a state and loading it again continues bit for bit.

mod common;

use jello_core::{
    Aabb, ForceField, Integrator, ModelBuilder, Plane, ReadOptions, Simulation, State, Vec3, World,
};

fn bits(s: &State) -> Vec<u64> {
    s.pos
        .iter()
        .chain(&s.vel)
        .flat_map(|v| v.to_array())
        .map(f64::to_bits)
        .collect()
}

/// Run 200 steps straight, or 100, save to text, load, and 100 more: identical bits.
fn check_continuation(sim: Simulation) {
    let mut straight = sim.clone();
    straight.advance(200).unwrap();

    let mut first = sim;
    first.advance(100).unwrap();
    let text = first.to_world().unwrap().to_text();
    let loaded = World::parse(text.as_bytes(), "saved.w", ReadOptions::default()).unwrap();
    let mut second = Simulation::from_world(&loaded).unwrap();
    assert_eq!(second.model, first.model, "the saved model differs");
    second.advance(100).unwrap();
    assert_eq!(bits(&second.state), bits(&straight.state));
}

#[test]
fn save_then_load_continues_bit_for_bit() {
    for integrator in Integrator::ALL {
        let start = ModelBuilder::new().build().unwrap();
        let mut state = State::at_rest(&start);
        state
            .pos
            .iter_mut()
            .for_each(|p| *p += Vec3::new(-0.9, -0.4, 0.3));
        state
            .vel
            .iter_mut()
            .for_each(|v| *v = Vec3::new(-7.0, 1.0 / 3.0, -2.5));
        let field = ForceField::from_fn(7, Aabb::classic(), |p| Vec3::new(-p.y, p.x, -0.02) * 0.01)
            .unwrap();
        let plane = Plane::facing([0.1, 1.0, 1.0, 1.2], Vec3::new(0.0, 0.0, 0.8)).unwrap();
        let model = ModelBuilder::new()
            .integrator(integrator)
            .dt(1.0 / 3000.0)
            .plane(Some(plane))
            .field(Some(field))
            .build()
            .unwrap();
        check_continuation(Simulation::new(model, state));
    }
}

#[test]
#[cfg_attr(
    not(shared_worlds),
    ignore = "needs ../shared/worlds, absent when this crate was built"
)]
fn official_worlds_save_and_load_bit_for_bit() {
    let dir = common::shared_worlds();
    for name in [
        "jello.w",
        "gravity.w",
        "moveLeft.w",
        "rotate.w",
        "skewedCorner.w",
    ] {
        let bytes = std::fs::read(dir.join(name)).unwrap();
        let world = World::parse(&bytes, name, ReadOptions::default()).unwrap();
        // Loading and writing straight away keeps every value.
        let again = World::parse(world.to_text().as_bytes(), name, ReadOptions::default()).unwrap();
        assert_eq!(again, world, "{name}");
        check_continuation(Simulation::from_world(&world).unwrap());
    }
}
