//! The stencil force kernel against the plain definition, spring by spring from the spring list,
//! on lattices of many shapes; and the same bits for any number of threads.

mod common;

use common::Lcg;
use jello_core::forces::accelerations;
use jello_core::{scenes, Control, Integrator, Lattice, Model, ModelBuilder, Simulation, Vec3};

/// Accelerations straight from SPEC.md: every spring of `model.springs` once, then the walls and
/// the mass (no field or plane in these models).
fn reference(model: &Model, pos: &[Vec3], vel: &[Vec3]) -> Vec<Vec3> {
    let mut f = vec![Vec3::ZERO; pos.len()];
    let s = &model.springs;
    for n in 0..s.len() {
        let (a, b) = (s.a[n] as usize, s.b[n] as usize);
        let kind = s.kind[n] as usize;
        let l = pos[a] - pos[b];
        let len = l.length();
        let dir = l / len;
        let force = dir * (-model.stiffness[kind] * (len - s.rest_len[n]))
            - dir * (model.damping[kind] * (vel[a] - vel[b]).dot(dir));
        f[a] += force;
        f[b] -= force;
    }
    f.iter().map(|f| *f / model.mass).collect()
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
            .lattice
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
        let (model, state) = scenes::benchmark(n, integrator).unwrap();
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
    // 23³ and 26³: large enough for the threaded path, chunks of planes that do not divide evenly.
    for (n, integrator) in [(23, Integrator::Rk4), (26, Integrator::Euler)] {
        let one = run_on(1, n, integrator, 60);
        for threads in [2, 3, 5] {
            assert!(
                one == run_on(threads, n, integrator, 60),
                "{n}³ {integrator}: {threads} threads differ from 1"
            );
        }
    }
}
