//! Models and values for the unit tests of the solver's parts.

use crate::compute::team;
use crate::model::body::{rotation_xyz, Body, Material};
use crate::model::lattice::Lattice;
use crate::model::{Model, ModelBuilder};
use crate::vec3::Vec3;

/// `f` on a team of `threads` threads, in a pool of its own (so more threads than this
/// machine's cores too).
pub fn on_threads<R: Send>(threads: usize, f: impl FnOnce() -> R + Send) -> R {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| team::run(f))
}

/// A small deterministic generator of test values in [−1, 1).
pub fn values(seed: u64) -> impl FnMut() -> f64 {
    let mut x = seed;
    move || {
        x = x
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        (x >> 11) as f64 / (1u64 << 52) as f64 - 1.0
    }
}

/// A body of `points` lattice points (unit spacing) whose cells are kept where the values
/// of `seed` exceed `above`, the rest holes.
pub fn with_holes(points: [usize; 3], seed: u64, above: f64) -> Body {
    let mut next = values(seed);
    let cells = points.iter().map(|n| n - 1).product::<usize>();
    let cells = (0..cells).map(|_| next() > above).collect();
    let lattice = Lattice::new(points, Vec3::new(1.0, 1.0, 1.0));
    Body::from_cells(lattice, cells, Material::classic()).unwrap()
}

/// A full box of `points` lattice points (unit spacing) with its first corner at `at`.
pub fn box_at(points: [usize; 3], at: Vec3) -> Body {
    let lattice = Lattice::new(points, Vec3::new(1.0, 1.0, 1.0));
    Body::lattice_box(lattice, Material::classic()).placed(at, rotation_xyz([0.0; 3]))
}

/// Two bodies, one with holes, one with an axis of a single point.
pub fn two_bodies() -> Model {
    let holes = with_holes([6, 5, 7], 7, -0.6);
    let flat = box_at([4, 1, 5], Vec3::new(3.0, 0.0, 0.0));
    ModelBuilder::new()
        .bodies(vec![holes, flat])
        .build()
        .unwrap()
}

/// A body with holes and a full box beside it whose springs have factors drawn from `next`
/// (rest 0.9–1.1, stiffness and damping 0.5–2.5 times the material's).
pub fn holes_and_factors(next: &mut dyn FnMut() -> f64) -> Vec<Body> {
    let holes = with_holes([6, 5, 7], 7, -0.6);
    let mut scaled = box_at([3, 4, 3], Vec3::new(9.0, 0.0, 0.0));
    scaled
        .scale_springs(|_| crate::model::springs::SpringScale {
            rest: 1.0 + 0.1 * next(),
            stiffness: 1.5 + next(),
            damping: 1.5 + next(),
        })
        .unwrap();
    vec![holes, scaled]
}
