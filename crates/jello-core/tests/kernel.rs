//! The stencil force kernel against the plain definition, spring by spring from the spring list,
//! on lattices of many shapes; and the same bits for any number of threads.

mod common;

use common::Lcg;
use jello_core::forces::accelerations;
use jello_core::{benchmark, Control, Integrator, Lattice, Model, ModelBuilder, Simulation, Vec3};

/// Accelerations straight from docs/spec.md: every spring of `model.springs()` once, then the walls and
/// the mass (no field or plane in these models).
fn reference(model: &Model, pos: &[Vec3], vel: &[Vec3]) -> Vec<Vec3> {
    let mut f = vec![Vec3::ZERO; pos.len()];
    let s = &model.springs();
    for n in 0..s.len() {
        let (a, b) = (s.a[n] as usize, s.b[n] as usize);
        let kind = s.kind[n] as usize;
        let l = pos[a] - pos[b];
        let len = l.length();
        let dir = l / len;
        let force = dir * (-model.body(0).material.stiffness[kind] * (len - s.rest_len[n]))
            - dir * (model.body(0).material.damping[kind] * (vel[a] - vel[b]).dot(dir));
        f[a] += force;
        f[b] -= force;
    }
    f.iter().map(|f| *f / model.body(0).material.mass).collect()
}

#[test]
fn stencil_kernel_matches_the_spring_list() {
    let shapes = [
        [8, 8, 8],
        [2, 1, 1],
        [1, 1, 9],
        [1, 6, 1],
        [3, 3, 3],
        [5, 3, 7],
        [9, 2, 4],
        [4, 11, 2],
        [13, 5, 6],
        [6, 40, 3],
        // Large enough for threads: ranges of chunks, each range's first chunk completed after
        // the chunk before it (in another range) is done.
        [23, 19, 21],
    ];
    for counts in shapes {
        let lattice = Lattice::new(counts, Vec3::new(0.9, 1.1, 1.3));
        let model = ModelBuilder::new()
            .lattice(lattice)
            .spring_kind(jello_core::SpringKind::Shear, 150.0, 0.4)
            .spring_kind(jello_core::SpringKind::Bend, 90.0, 0.1)
            .build()
            .unwrap();
        let mut rng = Lcg(counts.iter().product::<usize>() as u64);
        let pos: Vec<Vec3> = model
            .body(0)
            .lattice()
            .rest_positions()
            .iter()
            .map(|p| *p - Vec3::new(0.5, 0.5, 0.5) + rng.vec3() * 0.03)
            .collect();
        let vel: Vec<Vec3> = pos.iter().map(|_| rng.vec3()).collect();
        let mut acc = vec![Vec3::ZERO; pos.len()];
        accelerations(&model, &pos, &vel, &Control::none(), &mut acc);
        let expected = reference(&model, &pos, &vel);
        let scale = expected.iter().map(|a| a.max_abs()).fold(1.0, f64::max);
        for (i, (a, e)) in acc.iter().zip(&expected).enumerate() {
            assert!(
                (*a - *e).max_abs() <= 1e-12 * scale,
                "{counts:?}, point {i}: {a:?} vs {e:?}"
            );
        }
    }
}

/// Bits of a state after `steps` steps of the benchmark scene on a pool of `threads` threads.
fn run_on(threads: usize, n: usize, integrator: Integrator, steps: u64) -> Vec<u64> {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let (model, state) = benchmark::scene(n, integrator).unwrap();
        let mut sim = Simulation::new(model, state);
        sim.advance(steps).unwrap();
        sim.state
            .pos
            .iter()
            .chain(&sim.state.vel)
            .flat_map(|v| v.to_array())
            .map(f64::to_bits)
            .collect()
    })
}

#[test]
fn results_are_bit_identical_for_any_thread_count() {
    // 23³ and 26³: large enough for the threaded path, chunks of planes that do not divide evenly;
    // from 5 threads on, ranges of planes that start inside chunks (with and without the halo
    // of the chunk before), down to 2 planes a range.
    for (n, integrator) in [(23, Integrator::Rk4), (26, Integrator::Euler)] {
        let one = run_on(1, n, integrator, 60);
        for threads in [2, 3, 5, 8, 11] {
            assert!(
                one == run_on(threads, n, integrator, 60),
                "{n}³ {integrator}: {threads} threads differ from 1"
            );
        }
    }
}

/// One step of `model.integrator` from (`pos`, `vel`) as the textbook writes it, on whole arrays,
/// with `accelerations` (checked against the spring list above) for every force evaluation.
fn textbook_step(model: &Model, pos: &[Vec3], vel: &[Vec3], control: &Control) -> [Vec<Vec3>; 2] {
    let acc = |p: &[Vec3], v: &[Vec3]| {
        let mut a = vec![Vec3::ZERO; p.len()];
        accelerations(model, p, v, control, &mut a);
        a
    };
    let axpy = |y: &[Vec3], k: &[Vec3], h: f64| -> Vec<Vec3> {
        y.iter().zip(k).map(|(&y, &k)| y + k * h).collect()
    };
    let dt = model.dt;
    match model.integrator {
        Integrator::BackwardEuler | Integrator::Sdirk2 => unreachable!("an explicit integrator"),
        Integrator::Euler => [axpy(pos, vel, dt), axpy(vel, &acc(pos, vel), dt)],
        Integrator::SymplecticEuler => {
            let v = axpy(vel, &acc(pos, vel), dt);
            [axpy(pos, &v, dt), v]
        }
        Integrator::Rk2 => {
            let a1 = acc(pos, vel);
            let (p2, v2) = (axpy(pos, vel, dt / 2.0), axpy(vel, &a1, dt / 2.0));
            [axpy(pos, &v2, dt), axpy(vel, &acc(&p2, &v2), dt)]
        }
        Integrator::Rk4 => {
            let a1 = acc(pos, vel);
            let (p2, v2) = (axpy(pos, vel, dt / 2.0), axpy(vel, &a1, dt / 2.0));
            let a2 = acc(&p2, &v2);
            let (p3, v3) = (axpy(pos, &v2, dt / 2.0), axpy(vel, &a2, dt / 2.0));
            let a3 = acc(&p3, &v3);
            let (p4, v4) = (axpy(pos, &v3, dt), axpy(vel, &a3, dt));
            let a4 = acc(&p4, &v4);
            let slope = |k1: &[Vec3], k2: &[Vec3], k3: &[Vec3], k4: &[Vec3]| -> Vec<Vec3> {
                (0..k1.len())
                    .map(|i| k1[i] + k2[i] * 2.0 + k3[i] * 2.0 + k4[i])
                    .collect()
            };
            [
                axpy(pos, &slope(vel, &v2, &v3, &v4), dt / 6.0),
                axpy(vel, &slope(&a1, &a2, &a3, &a4), dt / 6.0),
            ]
        }
    }
}

#[test]
fn every_integrator_steps_as_the_textbook_writes_it_on_a_threaded_lattice() {
    // The fused passes (accelerations and the integrator's update chunk by chunk, block by
    // block) against whole-array updates, on a lattice large enough for threads, with a field,
    // a plane, the walls and control forces all acting.
    let counts = [21, 22, 20];
    let field = jello_core::ForceField::from_fn(4, jello_core::Aabb::classic(), |p| {
        Vec3::new(-p.y, p.x, 0.3) * 0.2
    })
    .unwrap();
    let plane = jello_core::Plane::facing([0.0, 0.3, 1.0, 0.45], Vec3::ZERO).unwrap();
    let mut rng = Lcg(7);
    let base = ModelBuilder::new()
        .lattice(Lattice::new(counts, Vec3::new(1.0, 1.0, 1.0)))
        .dt(1e-4)
        .field(Some(field))
        .plane(Some(plane))
        .build()
        .unwrap();
    let pos: Vec<Vec3> = base
        .body(0)
        .lattice()
        .rest_positions()
        .iter()
        // Centred, so that some points are outside the box walls (±2) and below the plane.
        .map(|p| (*p - Vec3::new(0.5, 0.5, 0.5)) * 4.3 + rng.vec3() * 0.01)
        .collect();
    let vel: Vec<Vec3> = pos.iter().map(|_| rng.vec3()).collect();
    let control = Control {
        forces: pos.iter().map(|_| rng.vec3() * 0.01).collect(),
        ..Control::none()
    };
    for integrator in Integrator::EXPLICIT {
        let mut model = base.clone();
        model.integrator = integrator;
        let [p, v] = textbook_step(&model, &pos, &vel, &control);
        let mut state = jello_core::State::new(pos.clone(), vel.clone());
        let mut scratch = jello_core::Scratch::new(&model);
        jello_core::step(&model, &mut state, &control, &mut scratch).unwrap();
        let scale = v.iter().map(|a| a.max_abs()).fold(1.0, f64::max);
        for i in 0..pos.len() {
            assert!(
                (state.pos[i] - p[i]).max_abs() <= 1e-13 * scale
                    && (state.vel[i] - v[i]).max_abs() <= 1e-12 * scale,
                "{integrator}, point {i}: ({:?}, {:?}) vs ({:?}, {:?})",
                state.pos[i],
                state.vel[i],
                p[i],
                v[i]
            );
        }
    }
}
