//! Criterion benchmarks of the force pass and of one RK4 step on the benchmark scene
//! (`jello_core::benchmark::benchmark`) at N = 8, 16, 32, 64, 128.
//!
//! `cargo bench -p jello-core` (all sizes; 128³ takes a few minutes), or a subset:
//! `cargo bench -p jello-core -- 'force_pass/32'`. Threads: rayon's default (all cores); set
//! `RAYON_NUM_THREADS=1` for one.

use std::time::Duration;

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use jello_core::compute::soa::Soa;
use jello_core::forces::{accelerations_soa, ForceScratch};
use jello_core::{benchmark, Control, Integrator, Simulation};

const SIZES: [usize; 5] = [8, 16, 32, 64, 128];

fn force_pass(c: &mut Criterion) {
    let mut group = c.benchmark_group("force_pass");
    for n in SIZES {
        let (model, state) = benchmark::scene(n, Integrator::Rk4).unwrap();
        let (p, v) = (Soa::from_aos(&state.pos), Soa::from_aos(&state.vel));
        let mut acc = Soa::zeros(model.point_count());
        let mut scratch = ForceScratch::new(&model);
        let control = Control::none();
        group.throughput(Throughput::Elements(model.spring_count() as u64));
        configure(&mut group, n);
        group.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, _| {
            b.iter(|| accelerations_soa(&model, &p, &v, &control, &mut acc, &mut scratch))
        });
    }
    group.finish();
}

fn rk4_step(c: &mut Criterion) {
    let mut group = c.benchmark_group("rk4_step");
    for n in SIZES {
        let (model, state) = benchmark::scene(n, Integrator::Rk4).unwrap();
        // Springs evaluated per step: four force passes.
        group.throughput(Throughput::Elements(4 * model.spring_count() as u64));
        configure(&mut group, n);
        let mut sim = Simulation::new(model, state.clone());
        group.bench_with_input(BenchmarkId::from_parameter(n), &n, |b, _| {
            b.iter(|| {
                if sim.step().is_err() {
                    // Never at the scene's dt; start over rather than measure a broken state.
                    sim.state = state.clone();
                }
            })
        });
    }
    group.finish();
}

/// Fewer, longer samples for the large lattices (a 128³ RK4 step takes about a second).
fn configure(
    group: &mut criterion::BenchmarkGroup<'_, criterion::measurement::WallTime>,
    n: usize,
) {
    if n >= 64 {
        group
            .sample_size(10)
            .measurement_time(Duration::from_secs(if n >= 128 { 30 } else { 10 }));
    } else {
        group
            .sample_size(30)
            .measurement_time(Duration::from_secs(5));
    }
}

criterion_group!(benches, force_pass, rk4_step);
criterion_main!(benches);
