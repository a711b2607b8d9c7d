//! Bodies with holes, several bodies, contacts between them, gravity and resolution-independent
//! materials: checked against brute force and physics, not against the kernel itself.

#[path = "common/alloc_watch.rs"]
mod alloc_watch;
mod common;
#[path = "common/meshes.rs"]
mod meshes;

use common::{cube, jelly, max_diff, stacked_cubes, Lcg as Rng};
use jello_core::diagnostics::{body_centre_of_mass, energy, momentum};
use jello_core::forces::accelerations;
use jello_core::{
    step, Aabb, Body, Control, Integrator, Lattice, Material, Model, ModelBuilder, Obstacle,
    Scratch, Sphere, State, Vec3,
};
use meshes::{cuboid, torus};

const MAX_CELLS: usize = 1 << 20;

/// A random set of kept cells, about `fill` of them.
fn random_cells(cells: usize, fill: f64, rng: &mut Rng) -> Vec<bool> {
    let mut kept: Vec<bool> = (0..cells)
        .map(|_| (rng.next() + 1.0) * 0.5 < fill)
        .collect();
    kept[cells / 2] = true;
    kept
}

/// The springs of a body by the rule "two points are joined by a spring of the stencil when some
/// kept cell has both as corners (a bend spring: when both its halves are springs)", by brute
/// force over pairs of points: (a, b, rest length, kind index).
fn brute_force_springs(
    counts: [usize; 3],
    size: Vec3,
    cells: &[bool],
) -> Vec<(usize, usize, f64, usize)> {
    let [nx, ny, nz] = counts;
    let (cy, cz) = (ny - 1, nz - 1);
    let h = Vec3::new(
        size.x / (nx - 1) as f64,
        size.y / (ny - 1) as f64,
        size.z / (nz - 1) as f64,
    );
    let index = |p: [usize; 3]| (p[0] * ny + p[1]) * nz + p[2];
    let in_kept_cell = |p: [usize; 3], q: [usize; 3]| {
        // Cells with both as corners: lower corner c with c ≤ p, q ≤ c + 1 on every axis.
        let lo = [0, 1, 2].map(|a| p[a].max(q[a]).saturating_sub(1));
        let hi = [0, 1, 2].map(|a| p[a].min(q[a]));
        (lo[0]..=hi[0].min(nx - 2)).any(|i| {
            (lo[1]..=hi[1].min(ny - 2))
                .any(|j| (lo[2]..=hi[2].min(nz - 2)).any(|k| cells[(i * cy + j) * cz + k]))
        })
    };
    let points: Vec<[usize; 3]> = (0..nx)
        .flat_map(|i| (0..ny).flat_map(move |j| (0..nz).map(move |k| [i, j, k])))
        .collect();
    let mut springs = Vec::new();
    for &p in &points {
        for &q in &points {
            if index(q) <= index(p) {
                continue;
            }
            let d = [0, 1, 2].map(|a| q[a] as isize - p[a] as isize);
            let rest = Vec3::new(d[0] as f64 * h.x, d[1] as f64 * h.y, d[2] as f64 * h.z).length();
            let steps: Vec<isize> = d.iter().map(|c| c.abs()).collect();
            let ones = steps.iter().filter(|&&c| c == 1).count();
            let twos = steps.iter().filter(|&&c| c == 2).count();
            let zeros = steps.iter().filter(|&&c| c == 0).count();
            if ones == 1 && zeros == 2 && in_kept_cell(p, q) {
                springs.push((index(p), index(q), rest, 0));
            } else if ones >= 2 && ones + zeros == 3 && in_kept_cell(p, q) {
                springs.push((index(p), index(q), rest, 1));
            } else if twos == 1 && zeros == 2 {
                let mid = [0, 1, 2].map(|a| (p[a] + q[a]) / 2);
                if in_kept_cell(p, mid) && in_kept_cell(mid, q) {
                    springs.push((index(p), index(q), rest, 2));
                }
            }
        }
    }
    springs.sort_by_key(|s| (s.0, s.1));
    springs
}

#[test]
fn the_springs_of_a_body_with_holes_are_those_of_its_kept_cells() {
    let mut rng = Rng(7);
    for (counts, fill) in [
        ([3, 3, 3], 0.5),
        ([4, 5, 3], 0.4),
        ([5, 4, 6], 0.7),
        ([6, 6, 6], 0.2),
    ] {
        let size = Vec3::new(1.0, 1.3, 0.8);
        let cells = random_cells(counts.iter().map(|n| n - 1).product(), fill, &mut rng);
        let lattice = Lattice::new(counts, size);
        let body = Body::from_cells(lattice, cells.clone(), Material::classic()).unwrap();
        let mut got = Vec::new();
        body.for_each_spring(|s| got.push((s.a.min(s.b), s.a.max(s.b), s.rest, s.kind as usize)));
        got.sort_by_key(|s| (s.0, s.1));
        let want = brute_force_springs(counts, size, &cells);
        assert_eq!(got.len(), want.len(), "{counts:?}");
        for (g, w) in got.iter().zip(&want) {
            assert_eq!((g.0, g.1, g.3), (w.0, w.1, w.3), "{counts:?}");
            assert!((g.2 - w.2).abs() < 1e-15);
        }
        let mut by_kind = [0; 3];
        want.iter().for_each(|s| by_kind[s.3] += 1);
        assert_eq!(body.spring_count_by_kind(), by_kind);
        // The active points are exactly the corners of kept cells, which every spring joins.
        let mut touched = vec![false; body.len()];
        want.iter()
            .for_each(|s| (touched[s.0], touched[s.1]) = (true, true));
        assert_eq!(body.active_mask(), &touched[..]);
    }
}

/// Accelerations of a body with holes at a deformed state: spring forces summed by brute force
/// from the independent spring rule, over the mass; inactive points do not accelerate.
#[test]
fn a_body_with_holes_feels_exactly_its_springs() {
    let mut rng = Rng(11);
    // Large enough for several chunks and the block loop.
    let counts = [9, 7, 10];
    let size = Vec3::new(1.0, 0.8, 1.2);
    let cells = random_cells(8 * 6 * 9, 0.55, &mut rng);
    let material = Material {
        mass: 0.01,
        stiffness: [150.0, 90.0, 40.0],
        damping: [0.3, 0.2, 0.1],
    };
    let body = Body::from_cells(Lattice::new(counts, size), cells.clone(), material).unwrap();
    let model = ModelBuilder::new()
        .bodies(vec![body.clone()])
        .bounds(Aabb::new(Vec3::new(-9.0, -9.0, -9.0), Vec3::new(9.0, 9.0, 9.0)).unwrap())
        .build()
        .unwrap();
    let state = State::at_rest(&model);
    let pos: Vec<Vec3> = state.pos.iter().map(|&p| p + rng.vec3() * 0.02).collect();
    let vel: Vec<Vec3> = pos.iter().map(|_| rng.vec3()).collect();
    let mut want = vec![Vec3::ZERO; pos.len()];
    for (a, b, rest, kind) in brute_force_springs(counts, size, &cells) {
        let d = pos[a] - pos[b];
        let l = d.length();
        let u = d / l;
        let f = u * (-material.stiffness[kind] * (l - rest))
            - u * (material.damping[kind] * (vel[a] - vel[b]).dot(u));
        want[a] += f;
        want[b] -= f;
    }
    let want: Vec<Vec3> = want.iter().map(|f| *f / material.mass).collect();
    let mut got = vec![Vec3::ZERO; pos.len()];
    accelerations(&model, &pos, &vel, &Control::none(), &mut got);
    let scale = want.iter().map(|a| a.length()).fold(0.0, f64::max);
    assert!(
        max_diff(&got, &want) <= 1e-12 * scale,
        "{}",
        max_diff(&got, &want)
    );
    for (p, a) in got.iter().enumerate() {
        if !body.is_active(p) {
            assert_eq!(*a, Vec3::ZERO, "inactive point {p}");
        }
    }
}

#[test]
fn keeping_every_cell_is_the_box_bit_for_bit() {
    let lattice = Lattice::new([6, 5, 7], Vec3::new(1.0, 1.0, 1.0));
    let full =
        Body::from_cells(lattice.clone(), vec![true; 5 * 4 * 6], Material::classic()).unwrap();
    assert_eq!(full, Body::lattice_box(lattice, Material::classic()));
}

/// A voxelised torus (a body with a hole through it) at rest with no forces stays at rest.
#[test]
fn a_shape_at_rest_stays_at_rest() {
    let mesh = torus(0.4, 0.15, 24, 12);
    let body = Body::from_mesh(
        &mesh.vertices,
        &mesh.triangles,
        10,
        MAX_CELLS,
        Material::classic(),
    )
    .unwrap();
    assert!(body.active_count() < body.len());
    let model = ModelBuilder::new().bodies(vec![body]).build().unwrap();
    let mut state = State::at_rest(&model);
    let rest = state.pos.clone();
    common::run(&model, &mut state, 500);
    assert!(
        max_diff(&state.pos, &rest) < 1e-13,
        "{}",
        max_diff(&state.pos, &rest)
    );
}

/// A cube body of `n` points per side and side `side`, resting with its lower corner at `at`.
/// Two bodies thrown at each other in empty space bounce apart: they never pass through each
/// other (at 2.5 m/s no point of one gets more than half a cell deep into the other), and internal plus
/// contact forces conserve linear momentum.
#[test]
fn colliding_bodies_bounce_and_conserve_momentum() {
    let far = Aabb::new(Vec3::new(-50.0, -50.0, -50.0), Vec3::new(50.0, 50.0, 50.0)).unwrap();
    let a = cube(5, 0.4, Vec3::new(-0.6, 0.0, 0.0), jelly(0.01));
    let b = cube(4, 0.5, Vec3::new(0.2, 0.1, 0.05), jelly(0.03));
    let model = ModelBuilder::new()
        .bodies(vec![a, b])
        .bounds(far)
        .collision(800.0, 0.5)
        .build()
        .unwrap();
    let mut state = State::at_rest(&model);
    let (ra, rb) = (model.body(0).points(), model.body(1).points());
    state.vel[ra.clone()]
        .iter_mut()
        .for_each(|v| *v = Vec3::new(1.5, 0.0, 0.0));
    state.vel[rb.clone()]
        .iter_mut()
        .for_each(|v| *v = Vec3::new(-1.0, 0.2, 0.0));
    let p0 = momentum(&model, &state.vel);
    let mut scratch = Scratch::new(&model);
    let mut touched = false;
    for _ in 0..3000 {
        step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
        let (deepest, _) = jello_core::contact::overlap(&model, &state.pos);
        assert!(
            deepest < 0.05,
            "the bodies passed into each other: {deepest} m deep"
        );
        touched |= deepest > 0.0;
        // And they stay in order along x.
        let centre = |r: std::ops::Range<usize>| state.pos[r].iter().map(|p| p.x).sum::<f64>();
        assert!(centre(ra.clone()) / 125.0 < centre(rb.clone()) / 64.0);
    }
    assert!(touched, "the bodies never met");
    let p1 = momentum(&model, &state.vel);
    assert!(
        (p1 - p0).length() < 1e-12 * p0.length().max(1.0),
        "{p0:?} → {p1:?}"
    );
    let va = body_centre_of_mass(&model, 0, &state.vel).x;
    let vb = body_centre_of_mass(&model, 1, &state.vel).x;
    assert!(va < 0.0 && vb > 0.0, "they bounce apart: {va} {vb}");
}

/// One cube stacked on another on the floor, under gravity: the upper stays on top, sinks into
/// the lower by at most a quarter of a cell at the landing, and comes to rest with the two
/// touching: no gap, and an overlap under 2 % of a cell (0.1 m).
#[test]
fn stacked_bodies_stay_stacked() {
    let model = stacked_cubes().dt(0.0002).build().unwrap();
    let mut state = State::at_rest(&model);
    let mut scratch = Scratch::new(&model);
    let (rl, ru) = (model.body(0).points(), model.body(1).points());
    for _ in 0..15000 {
        step(&model, &mut state, &Control::none(), &mut scratch).unwrap();

        let top_of_lower = state.pos[rl.clone()]
            .iter()
            .map(|p| p.y)
            .fold(f64::MIN, f64::max);
        let bottom_of_upper = state.pos[ru.clone()]
            .iter()
            .map(|p| p.y)
            .fold(f64::MAX, f64::min);
        assert!(
            top_of_lower - bottom_of_upper < 0.025,
            "the upper body sank into the lower: {} m",
            top_of_lower - bottom_of_upper
        );
    }
    let v = state.vel.iter().map(|v| v.length()).fold(0.0, f64::max);
    assert!(v < 0.02, "still moving at {v} m/s");
    // At rest the skins touch: no gap, an overlap of a fraction of a millimetre.
    let top = state.pos[rl].iter().map(|p| p.y).fold(f64::MIN, f64::max);
    let bottom = state.pos[ru].iter().map(|p| p.y).fold(f64::MAX, f64::min);
    assert!((bottom - top).abs() < 0.002, "gap {} m", bottom - top);
    let (deepest, _) = jello_core::contact::overlap(&model, &state.pos);
    assert!(deepest > 0.0 && deepest < 0.002, "overlap {deepest} m");
}

/// A slab 0.6 m wide and 0.3 m thick dropped from `drop` above a sphere of radius 0.3 m, its
/// centre `offset` to the side of the sphere's top, with friction `mu`; after 4 s: the model,
/// the state.
fn drop_on_sphere(offset: f64, drop: f64, mu: f64, modulus: f64) -> (jello_core::Model, State) {
    let room = Aabb::new(Vec3::new(-2.0, -1.0, -2.0), Vec3::new(2.0, 3.0, 2.0)).unwrap();
    let slab = cuboid(
        Vec3::new(offset - 0.3, drop + 0.3, -0.3),
        Vec3::new(offset + 0.3, drop + 0.6, 0.3),
    );
    let body = Body::from_mesh(
        &slab.vertices,
        &slab.triangles,
        8,
        MAX_CELLS,
        Material::classic(),
    )
    .unwrap()
    .with_modulus(modulus, 200.0, 400.0);
    let sphere = Sphere::new(Vec3::new(0.0, 0.0, 0.0), 0.3).unwrap();
    let model = ModelBuilder::new()
        .bodies(vec![body])
        .bounds(room)
        .obstacle(Obstacle::Sphere(sphere))
        .collision(3000.0, 20.0)
        .friction(mu)
        .gravity(Vec3::new(0.0, -9.81, 0.0))
        .dt(0.0002)
        .integrator(Integrator::SymplecticEuler)
        .build()
        .unwrap();
    let mut state = State::at_rest(&model);
    common::run(&model, &mut state, 20000);
    (model, state)
}

/// A body dropped on a sphere comes to rest on it: draped over the sphere, not moving, and not
/// sunk in deeper than half a cell.
#[test]
fn a_body_dropped_on_a_sphere_rests_on_it() {
    let (model, state) = drop_on_sphere(0.0, 0.3, 0.5, 8000.0);
    let body = model.body(0);
    let v = (0..body.len())
        .filter(|&p| body.is_active(p))
        .map(|p| state.vel[p].length())
        .fold(0.0, f64::max);
    assert!(v < 0.05, "still moving at {v} m/s");
    let centre = body_centre_of_mass(&model, 0, &state.pos);
    assert!(
        centre.y > 0.0 && centre.y < 1.0,
        "rests on the sphere: {centre:?}"
    );
    assert!(
        centre.x.abs() < 0.05 && centre.z.abs() < 0.05,
        "centred: {centre:?}"
    );
    let penetration = jello_core::diagnostics::max_penetration(&model, &state.pos);
    // The penalty springs hold the weight at a depth of weight / (kCollision · points touching):
    // a fraction of a cell here.
    assert!(penetration < 0.5 * body.min_spacing(), "{penetration}");
}

/// Several bodies with holes, large enough for threads, give bit-identical results on 1 to 7
/// threads.
#[test]
fn several_bodies_are_bit_identical_on_any_thread_count() {
    let mesh = torus(0.5, 0.2, 32, 16);
    let a = Body::from_mesh(&mesh.vertices, &mesh.triangles, 30, MAX_CELLS, jelly(0.01)).unwrap();
    assert!(a.len() >= jello_core::forces::PARALLEL_MIN_POINTS);
    let box_mesh = cuboid(Vec3::new(-0.3, -0.3, 0.21), Vec3::new(0.3, 0.3, 0.56));
    let b = Body::from_mesh(
        &box_mesh.vertices,
        &box_mesh.triangles,
        8,
        MAX_CELLS,
        jelly(0.004),
    )
    .unwrap();
    let model = ModelBuilder::new()
        .bodies(vec![a, b])
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .dt(0.0002)
        .build()
        .unwrap();
    let mut start = State::at_rest(&model);
    for p in model.body(1).points() {
        start.vel[p] = Vec3::new(0.0, 0.0, -3.0);
    }
    let run = |threads| common::run_on_threads(&model, &start, 60, threads);
    let one = run(1);
    assert!(
        jello_core::contact::overlap(&model, &one.pos).0 > 0.0,
        "the bodies touch"
    );
    // 5 and 7 threads cut the torus's planes into ranges that start inside chunks.
    for threads in [2, 3, 5, 7] {
        assert_eq!(one, run(threads), "{threads} threads");
    }
}

/// A pile of small bodies, each too small to cut into ranges of planes but together enough for
/// a team of threads (each thread then takes whole bodies): eight cubes of 7³ points, two
/// columns of four thrown into each other and onto the floor, with friction, give bit-identical
/// results on 1 to 5 threads.
#[test]
fn many_small_bodies_are_bit_identical_on_any_thread_count() {
    let (model, start) = eight_small_cubes_thrown_together();
    assert!(model.bodies().iter().all(|b| b.len() < 2048) && model.point_count() >= 2048);
    touch_with_the_same_bits_on_2_3_and_5_threads(&model, &start);
}

/// The contact passes' work is counted as the passes run: RK4 makes four passes a step, a
/// touch comes from a placed sample, a placed sample from a listed one; the counts are the same
/// on any thread count (they are what `jello run --timings` prints, to judge a change by where
/// timings drift), and an implicit integrator's own pass, which holds a step's touches, is
/// counted (and timed) too.
#[test]
fn the_contact_passes_work_is_counted_the_same_on_any_thread_count() {
    let (model, start) = eight_small_cubes_thrown_together();
    let steps = 80;
    let work_on = |model: &Model, threads| {
        common::on_threads(threads, || {
            let (mut state, mut scratch) = (start.clone(), Scratch::new(model));
            for _ in 0..steps {
                step(model, &mut state, &Control::none(), &mut scratch).expect("no blow-up");
            }
            (scratch.contact_work(), scratch.contact_time())
        })
    };
    let (one, _) = work_on(&model, 1);
    assert_eq!(one.passes, 4 * steps as u64, "{one:?}");
    assert!(
        one.touches > 0 && one.sorts >= 1 && one.sorts <= one.passes,
        "{one:?}"
    );
    assert!(
        one.placings >= one.touches && one.placed >= one.touches,
        "{one:?}"
    );
    assert!(one.listed >= one.sorts, "{one:?}");
    for threads in [2, 3] {
        assert_eq!(work_on(&model, threads).0, one, "{threads} threads");
    }
    let mut implicit = model.clone();
    implicit.integrator = Integrator::BackwardEuler;
    let (work, time) = work_on(&implicit, 1);
    assert!(work.passes >= steps as u64 && work.touches > 0, "{work:?}");
    assert!(
        time > std::time::Duration::ZERO,
        "the implicit pass is timed"
    );
}

/// Eight cubes of 7³ points, two columns of four, thrown into each other and onto the floor
/// (see [`thrown_together`]).
fn eight_small_cubes_thrown_together() -> (Model, State) {
    let cubes: Vec<Body> = (0..8)
        .map(|c| {
            let at = Vec3::new(0.45 * (c % 2) as f64, 0.05 + 0.32 * (c / 2) as f64, 0.0);
            cube(7, 0.3, at, jelly(0.01))
        })
        .collect();
    thrown_together(cubes, 0.3)
}

/// `cubes` on a floor (y up) with friction, each thrown at 2 m/s along x, the odd ones the
/// other way, down at 1 m/s and along z at `spread` m/s times its index.
fn thrown_together(cubes: Vec<Body>, spread: f64) -> (Model, State) {
    let floor = Aabb::new(Vec3::new(-2.0, 0.0, -2.0), Vec3::new(2.0, 4.0, 2.0)).unwrap();
    let model = ModelBuilder::new()
        .bodies(cubes)
        .bounds(floor)
        .collision(2000.0, 2.0)
        .friction(0.5)
        .gravity(Vec3::new(0.0, -9.81, 0.0))
        .dt(0.0005)
        .build()
        .unwrap();
    let mut start = State::at_rest(&model);
    for (b, body) in model.bodies().iter().enumerate() {
        let toward = if b % 2 == 0 { 2.0 } else { -2.0 };
        for p in body.points() {
            start.vel[p] = Vec3::new(toward, -1.0, spread * b as f64);
        }
    }
    (model, start)
}

/// 80 steps from `start`: the bodies touch, and 2, 3 and 5 threads give 1 thread's bits.
fn touch_with_the_same_bits_on_2_3_and_5_threads(model: &Model, start: &State) {
    let run = |threads| common::run_on_threads(model, start, 80, threads);
    let one = run(1);
    assert!(
        jello_core::contact::overlap(model, &one.pos).0 > 0.0,
        "the bodies touch"
    );
    for threads in [2, 3, 5] {
        assert_eq!(one, run(threads), "{threads} threads");
    }
}

/// Bodies large enough to be cut into ranges of planes on a team, none larger than a thread's
/// share of the points (three cubes of 13³ points and two of 7³, thrown into each other and onto
/// the floor): on 2 and 3 threads each thread takes whole bodies, on 5 the large ones are cut;
/// the bits are those of 1 thread either way.
#[test]
fn bodies_taken_whole_or_cut_are_bit_identical_on_any_thread_count() {
    let sizes = [13, 7, 13, 7, 13];
    let cubes: Vec<Body> = (sizes.iter().enumerate())
        .map(|(c, &n)| {
            let at = Vec3::new(0.4 * c as f64 - 0.8, 0.05 + 0.1 * (c % 2) as f64, 0.0);
            cube(n, 0.3, at, jelly(0.01))
        })
        .collect();
    let (model, start) = thrown_together(cubes, 0.0);
    let largest = model.bodies().iter().map(|b| b.len()).max().unwrap();
    assert!(
        largest >= 2048 && 3 * largest <= model.point_count() && 5 * largest > model.point_count()
    );
    touch_with_the_same_bits_on_2_3_and_5_threads(&model, &start);
}

/// With the material given by modulus, viscosity and density, refining the lattice keeps the
/// body's mass and its lowest frequency: a bar stretched by 2 % and let go contracts back in
/// about the same time at 4 and at 8 cells across.
#[test]
fn a_modulus_material_does_not_depend_on_the_resolution() {
    let half_period = |cells: usize| {
        let n = cells + 1;
        let body = Body::lattice_box(
            Lattice::new([2 * cells + 1, n, n], Vec3::new(1.0, 0.5, 0.5)),
            Material::classic(),
        )
        .with_modulus(2.0e4, 0.0, 1000.0);
        let mass = body.total_mass();
        let model = ModelBuilder::new()
            .bodies(vec![body])
            .bounds(Aabb::new(Vec3::new(-5.0, -5.0, -5.0), Vec3::new(5.0, 5.0, 5.0)).unwrap())
            .dt(2e-5)
            .build()
            .unwrap();
        let mut state = State::at_rest(&model);
        state.pos.iter_mut().for_each(|p| p.x *= 1.02);
        let length = |s: &State| {
            let xs = s.pos.iter().map(|p| p.x);
            xs.clone().fold(f64::MIN, f64::max) - xs.fold(f64::MAX, f64::min)
        };
        let mut scratch = Scratch::new(&model);
        let mut last = length(&state);
        loop {
            step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
            let now = length(&state);
            if now > last {
                return (state.time, mass);
            }
            last = now;
        }
    };
    let (t4, m4) = half_period(4);
    let (t8, m8) = half_period(8);
    assert!((m4 - m8).abs() < 1e-12 * m4, "{m4} {m8}");
    assert!(
        (m4 - 250.0).abs() < 1e-9,
        "1 × 0.5 × 0.5 m at 1000 kg/m³: {m4}"
    );
    assert!((t4 / t8 - 1.0).abs() < 0.1, "half periods {t4} and {t8}");
}

/// The modulus in absolute terms: a 4 × 4 × 4 lattice of side 0.6 m (spacing h = 0.2 m) at
/// modulus E = 2·10⁴ Pa and density 1000 kg/m³ has springs of E·h = 4000 N/m and points of
/// 1000·0.216/64 kg. Stretched along x by 1 %, it stores, spring by spring, `½·E·h·(|L| − R)²`:
/// the structural springs along x by 0.01·h, the bend springs along x by 0.02·h, the face and
/// body diagonals with an x component by the growth of their length, the rest not at all.
#[test]
fn a_modulus_material_stores_the_energy_of_springs_of_modulus_times_spacing() {
    let (e, rho, side, n) = (2.0e4, 1000.0, 0.6, 4usize);
    let h = side / (n - 1) as f64;
    let body = Body::lattice_box(
        Lattice::new([n; 3], Vec3::new(side, side, side)),
        Material::classic(),
    )
    .with_modulus(e, 0.0, rho);
    assert!((body.material.mass - rho * side.powi(3) / (n * n * n) as f64).abs() < 1e-15);
    let model = ModelBuilder::new().bodies(vec![body]).build().unwrap();
    let mut state = State::at_rest(&model);
    let stretch = 0.01;
    state.pos.iter_mut().for_each(|p| p.x *= 1.0 + stretch);
    // By hand: how many springs of each direction, and how much each grows.
    let (n, k) = (n as f64, e * h);
    let grows = |d: [f64; 3]| {
        let rest = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        let x = d[0] * (1.0 + stretch);
        (x * x + d[1] * d[1] + d[2] * d[2]).sqrt() - rest
    };
    let structural = (n - 1.0) * n * n * (stretch * h).powi(2);
    let bend = (n - 2.0) * n * n * (2.0 * stretch * h).powi(2);
    let face = 4.0 * (n - 1.0) * (n - 1.0) * n * grows([h, h, 0.0]).powi(2);
    let body_diagonal = 4.0 * (n - 1.0).powi(3) * grows([h, h, h]).powi(2);
    let want = 0.5 * k * (structural + bend + face + body_diagonal);
    let got = energy(&model, &state).spring;
    assert!(
        (got - want).abs() < 1e-12 * want,
        "{got} J against {want} J"
    );
}

/// Stepping several bodies with holes allocates nothing.
#[test]
fn stepping_several_bodies_does_not_allocate() {
    let mesh = torus(0.4, 0.15, 24, 12);
    let a = Body::from_mesh(&mesh.vertices, &mesh.triangles, 10, MAX_CELLS, jelly(0.01)).unwrap();
    let b = cube(4, 0.3, Vec3::new(-0.15, -0.15, 0.2), jelly(0.01));
    let model: Model = ModelBuilder::new().bodies(vec![a, b]).build().unwrap();
    let mut state = State::at_rest(&model);
    let mut scratch = Scratch::new(&model);
    let control = Control::none();
    step(&model, &mut state, &control, &mut scratch).unwrap();
    let (_, bytes) = alloc_watch::total_allocation(|| {
        for _ in 0..20 {
            step(&model, &mut state, &control, &mut scratch).unwrap();
        }
    });
    assert_eq!(bytes, 0);
}
