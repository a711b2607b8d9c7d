//! Every instruction-set tier this CPU can run computes the same bits: the state after stepping
//! is identical, integrator by integrator, on the classic lattice (one thread) and on a lattice
//! large enough for threads, with a non-uniform field (sampled per point), a plane, walls, a
//! sphere and a solid box, pins, control forces and a pull in play.
//!
//! The tier is process-wide, so this file holds one test: nothing else in this test binary runs
//! while it switches tiers. On a CPU with only the baseline the comparison is trivial and says so.

mod common;

use common::Lcg;
use jello_core::compute::simd::{force_tier, Tier};
use jello_core::{
    Aabb, Control, ForceField, Integrator, Lattice, Model, ModelBuilder, Obstacle, Plane, Pull,
    Scratch, Sphere, State, Vec3,
};

/// A model that exercises every term of the force: a swirling field, a plane the lattice
/// starts partly below, per-kind springs, and points beyond the walls.
fn scene(counts: [usize; 3], integrator: Integrator) -> (Model, State, Control) {
    let field = ForceField::from_fn(7, Aabb::classic(), |p| {
        Vec3::new(-p.y, p.x, 0.3 * p.z - 0.02) * 0.004
    })
    .unwrap();
    let model = ModelBuilder::new()
        .lattice(Lattice::new(counts, Vec3::new(1.2, 1.0, 0.9)))
        .spring_kind(jello_core::SpringKind::Shear, 170.0, 0.3)
        .field(Some(field))
        .plane(Some(
            Plane::facing([0.2, 0.1, 1.0, 1.4], Vec3::ZERO).unwrap(),
        ))
        .obstacle(Obstacle::Sphere(
            Sphere::new(Vec3::new(0.1, 0.0, -1.9), 0.35).unwrap(),
        ))
        .obstacle(Obstacle::Box(
            Aabb::new(Vec3::new(-0.7, -0.6, -2.5), Vec3::new(-0.3, 0.2, -1.95)).unwrap(),
        ))
        .pins([0, 3])
        .integrator(integrator)
        .build()
        .unwrap();
    let mut rng = Lcg(7);
    let mut state = State::at_rest(&model);
    for (p, v) in state.pos.iter_mut().zip(&mut state.vel) {
        // Centred low in the box: some points below the plane, some past the floor.
        *p += Vec3::new(-0.6, -0.5, -2.3) + rng.vec3() * 0.02;
        *v = rng.vec3() * 0.5;
    }
    let n = model.point_count();
    let control = Control {
        forces: (0..n).map(|_| rng.vec3() * 1e-3).collect(),
        pulls: vec![Pull {
            point: (n / 2) as u32,
            target: Vec3::new(0.5, 0.5, 0.5),
            stiffness: 5.0,
            damping: 0.05,
        }],
    };
    (model, state, control)
}

/// The bits of the state after `steps` steps.
fn run(counts: [usize; 3], integrator: Integrator, steps: usize) -> Vec<u64> {
    let (mut model, mut state, control) = scene(counts, integrator);
    if integrator.is_implicit() {
        // Frame-rate steps, where the solves take their products with `A` in single precision.
        model = model.to_builder().dt(1.0 / 60.0).build().unwrap();
    }
    let mut scratch = Scratch::new(&model);
    for _ in 0..steps {
        jello_core::step(&model, &mut state, &control, &mut scratch).expect("no blow-up");
    }
    state
        .pos
        .iter()
        .chain(&state.vel)
        .flat_map(|v| [v.x, v.y, v.z])
        .map(f64::to_bits)
        .collect()
}

#[test]
fn every_tier_computes_the_same_bits() {
    let tiers: Vec<Tier> = Tier::ALL.into_iter().filter(|t| t.is_supported()).collect();
    if tiers.len() < 2 {
        eprintln!("only the baseline tier runs on this CPU: nothing to compare");
    }
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(3)
        .build()
        .unwrap();
    let cases = [
        (Integrator::Rk4, [8, 8, 8], 60),
        (Integrator::Euler, [8, 8, 8], 60),
        (Integrator::Rk2, [8, 8, 8], 60),
        (Integrator::SymplecticEuler, [8, 8, 8], 60),
        (Integrator::BackwardEuler, [8, 8, 8], 20),
        (Integrator::Sdirk2, [8, 8, 8], 10),
        // Threaded: at least PARALLEL_MIN_POINTS points.
        (Integrator::Rk4, [22, 21, 20], 6),
        (Integrator::SymplecticEuler, [22, 21, 20], 6),
        (Integrator::BackwardEuler, [22, 21, 20], 3),
    ];
    for (integrator, counts, steps) in cases {
        let results: Vec<(Tier, Vec<u64>)> = tiers
            .iter()
            .map(|&tier| {
                force_tier(tier).unwrap();
                (tier, pool.install(|| run(counts, integrator, steps)))
            })
            .collect();
        let (first, reference) = &results[0];
        for (tier, bits) in &results[1..] {
            let differ = bits.iter().zip(reference).filter(|(a, b)| a != b).count();
            assert_eq!(
                differ, 0,
                "{integrator} on {counts:?}: {differ} numbers differ between the {first} and {tier} tiers"
            );
        }
    }
}
