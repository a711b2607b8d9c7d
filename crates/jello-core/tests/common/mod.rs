//! Helpers shared by the physics tests.
#![allow(dead_code)]

use std::path::PathBuf;

use jello_core::{
    Aabb, Body, Control, ForceField, Lattice, Material, Model, ModelBuilder, Scratch, State, Vec3,
};

/// The world files collected from the wild, beside the project (`../shared/worlds`). A test
/// that reads them carries `#[cfg_attr(not(shared_worlds), ignore = "…")]` (see `build.rs`), so
/// that without them it is listed as ignored rather than passing unchecked.
pub fn shared_worlds() -> PathBuf {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../../../shared/worlds");
    assert!(dir.is_dir(), "{} is absent", dir.display());
    dir
}

/// A uniform force field over the classic box.
pub fn uniform_field(f: Vec3) -> Option<ForceField> {
    Some(ForceField::from_fn(2, Aabb::classic(), |_| f).unwrap())
}

/// Steps `n` times, panicking on a blow-up.
pub fn run(model: &Model, state: &mut State, n: usize) {
    let mut scratch = Scratch::new(model);
    let control = Control::none();
    for _ in 0..n {
        jello_core::step(model, state, &control, &mut scratch).expect("no blow-up");
    }
}

/// Runs `f` on a fresh rayon pool of `threads` threads (so the threaded path splits its work
/// that many ways).
pub fn on_threads<T: Send>(threads: usize, f: impl FnOnce() -> T + Send) -> T {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap()
        .install(f)
}

/// `steps` steps from `start` on a fresh pool of `threads` threads (see [`on_threads`]).
pub fn run_on_threads(model: &Model, start: &State, steps: usize, threads: usize) -> State {
    on_threads(threads, || {
        let mut state = start.clone();
        run(model, &mut state, steps);
        state
    })
}

/// A deterministic pseudo-random number in [−1, 1) (64-bit LCG).
pub struct Lcg(pub u64);

impl Lcg {
    pub fn next(&mut self) -> f64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((self.0 >> 11) as f64 / (1u64 << 53) as f64) * 2.0 - 1.0
    }

    pub fn vec3(&mut self) -> Vec3 {
        Vec3::new(self.next(), self.next(), self.next())
    }
}

/// The model's rest shape moved by `offset`, each point jittered by up to `jitter` m.
pub fn deformed(model: &Model, offset: Vec3, jitter: f64, seed: u64) -> Vec<Vec3> {
    let mut rng = Lcg(seed);
    model
        .body(0)
        .lattice()
        .rest_positions()
        .into_iter()
        .map(|p| p + offset + rng.vec3() * jitter)
        .collect()
}

/// Largest difference between two point sets.
pub fn max_diff(a: &[Vec3], b: &[Vec3]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(p, q)| (*p - *q).max_abs())
        .fold(0.0, f64::max)
}

/// A full `n³` lattice body of side `side`, its corner at `at`.
pub fn cube(n: usize, side: f64, at: Vec3, material: Material) -> Body {
    Body::lattice_box(Lattice::new([n; 3], Vec3::new(side, side, side)), material)
        .placed(at, jello_core::model::body::IDENTITY)
}

/// A soft material of `mass` per point (stiffness 400 N/m, damping 1 N·s/m on every spring).
pub fn jelly(mass: f64) -> Material {
    Material {
        mass,
        stiffness: [400.0; 3],
        damping: [1.0; 3],
    }
}

/// One cube above another on the floor (y up, the floor at y = 0), under gravity, with friction
/// 0.5 and collision 2000 N/m, 2 N·s/m: the upper one 0.15 m above the lower. Add the step and
/// integrator.
pub fn stacked_cubes() -> ModelBuilder {
    let floor = Aabb::new(Vec3::new(-2.0, 0.0, -2.0), Vec3::new(2.0, 4.0, 2.0)).unwrap();
    let lower = cube(5, 0.5, Vec3::new(-0.25, 0.0, -0.25), jelly(0.02));
    let upper = cube(5, 0.4, Vec3::new(-0.2, 0.65, -0.2), jelly(0.015));
    ModelBuilder::new()
        .bodies(vec![lower, upper])
        .bounds(floor)
        .collision(2000.0, 2.0)
        .friction(0.5)
        .gravity(Vec3::new(0.0, -9.81, 0.0))
}
