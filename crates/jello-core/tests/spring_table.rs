//! Per-spring rest lengths, stiffnesses and dampings (`Body::scale_springs`): the kernel, the
//! energy and the stability estimate read them, checked against brute force over pairs of points
//! and against closed forms.

mod common;

use common::{max_diff, Lcg as Rng};
use jello_core::diagnostics::energy;
use jello_core::forces::{accelerations, PARALLEL_MIN_POINTS};
use jello_core::integrate::stability::stable_dt;
use jello_core::{
    step, Aabb, Body, Control, Integrator, Lattice, Material, Model, ModelBuilder, Scratch, Spring,
    SpringScale, State, Vec3,
};

fn material() -> Material {
    Material {
        mass: 0.01,
        stiffness: [150.0, 90.0, 40.0],
        damping: [0.3, 0.2, 0.1],
    }
}

fn free_model(bodies: Vec<Body>) -> Model {
    ModelBuilder::new()
        .bodies(bodies)
        .bounds(Aabb::new(Vec3::new(-50.0, -50.0, -50.0), Vec3::new(50.0, 50.0, 50.0)).unwrap())
        .build()
        .unwrap()
}

/// Factors that depend only on the pair of points, in [0.5, 1.5) (damping in [0, 1)).
fn pair_scale(a: usize, b: usize) -> SpringScale {
    let (lo, hi) = (a.min(b), a.max(b));
    let h = |salt: usize| ((lo * 7919 + hi * 104_729 + salt * 31) % 97) as f64 / 97.0;
    SpringScale {
        rest: 0.5 + h(1),
        stiffness: 0.5 + h(2),
        damping: h(3),
    }
}

/// Every spring of a lattice by brute force over pairs of points (docs/spec.md: axis neighbours at
/// distance 1 structural, face and body diagonals shear, axis neighbours at distance 2 bend), of
/// those `keep` accepts: (a, b, rest length on the rest grid, kind index).
fn brute_force(
    lattice: &Lattice,
    keep: impl Fn(usize, usize) -> bool,
) -> Vec<(usize, usize, f64, usize)> {
    let n = lattice.len();
    let h = lattice.spacing();
    let mut springs = Vec::new();
    for a in 0..n {
        for b in a + 1..n {
            let (pa, pb) = (lattice.coords(a), lattice.coords(b));
            let d: [i64; 3] = std::array::from_fn(|i| pb[i] as i64 - pa[i] as i64);
            let nonzero = d.iter().filter(|&&c| c != 0).count();
            let big = d.iter().map(|c| c.abs()).max().unwrap();
            let kind = match (nonzero, big) {
                (1, 1) => 0,
                (2 | 3, 1) => 1,
                (1, 2) => 2,
                _ => continue,
            };
            if !keep(a, b) {
                continue;
            }
            let rest = Vec3::new(d[0] as f64 * h.x, d[1] as f64 * h.y, d[2] as f64 * h.z).length();
            springs.push((a, b, rest, kind));
        }
    }
    springs
}

/// Accelerations from the brute-force springs with their pair factors, docs/spec.md's law.
fn brute_force_accelerations(
    springs: &[(usize, usize, f64, usize)],
    m: &Material,
    pos: &[Vec3],
    vel: &[Vec3],
) -> Vec<Vec3> {
    let mut f = vec![Vec3::ZERO; pos.len()];
    for &(a, b, rest, kind) in springs {
        let s = pair_scale(a, b);
        let (r, k, d) = (
            rest * s.rest,
            m.stiffness[kind] * s.stiffness,
            m.damping[kind] * s.damping,
        );
        let l = pos[a] - pos[b];
        let u = l / l.length();
        let force = u * (-k * (l.length() - r)) - u * (d * (vel[a] - vel[b]).dot(u));
        f[a] += force;
        f[b] -= force;
    }
    f.iter().map(|f| *f / m.mass).collect()
}

fn scaled_by_pair(mut body: Body) -> Body {
    body.scale_springs(|s| pair_scale(s.a, s.b)).unwrap();
    assert!(body.spring_table().is_some());
    body
}

/// Deformed, moving positions and velocities around the rest shape.
fn jiggled(model: &Model, seed: u64) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut rng = Rng(seed);
    let pos: Vec<Vec3> = State::at_rest(model)
        .pos
        .iter()
        .map(|&p| p + rng.vec3() * 0.02)
        .collect();
    let vel = pos.iter().map(|_| rng.vec3()).collect();
    (pos, vel)
}

fn assert_close(got: &[Vec3], want: &[Vec3], what: &str) {
    let scale = want.iter().map(|a| a.length()).fold(0.0, f64::max);
    assert!(scale > 0.0);
    let diff = max_diff(got, want);
    assert!(diff <= 1e-12 * scale, "{what}: off by {diff} of {scale}");
}

/// Each spring's own rest length, stiffness and damping act exactly, on a full box (the masked
/// kernel path) and on a body with holes (the link-bit path), large enough for several chunks
/// and blocks.
#[test]
fn per_spring_values_act_exactly() {
    let lattice = Lattice::new([9, 12, 11], Vec3::new(1.0, 1.3, 1.1));
    let body = scaled_by_pair(Body::lattice_box(lattice.clone(), material()));
    let model = free_model(vec![body]);
    let (pos, vel) = jiggled(&model, 3);
    let want =
        brute_force_accelerations(&brute_force(&lattice, |_, _| true), &material(), &pos, &vel);
    let mut got = vec![Vec3::ZERO; pos.len()];
    accelerations(&model, &pos, &vel, &Control::none(), &mut got);
    assert_close(&got, &want, "full box");

    // Every other cell of a checkerboard of 2×2×2 blocks kept.
    let cells: Vec<bool> = (0..8 * 11 * 10)
        .map(|c| {
            let (i, j, k) = (c / 110, c / 10 % 11, c % 10);
            (i / 2 + j / 2 + k / 2) % 2 == 0 || i == 4
        })
        .collect();
    let holed = Body::from_cells(lattice.clone(), cells, material()).unwrap();
    let mut exists = std::collections::HashSet::new();
    holed.for_each_spring(|s| {
        exists.insert((s.a.min(s.b), s.a.max(s.b)));
    });
    let model = free_model(vec![scaled_by_pair(holed)]);
    let (pos, vel) = jiggled(&model, 4);
    let springs = brute_force(&lattice, |a, b| exists.contains(&(a, b)));
    assert_eq!(springs.len(), exists.len());
    let want = brute_force_accelerations(&springs, &material(), &pos, &vel);
    let mut got = vec![Vec3::ZERO; pos.len()];
    accelerations(&model, &pos, &vel, &Control::none(), &mut got);
    assert_close(&got, &want, "body with holes");
}

/// `Body::for_each_spring` reports the products the kernel uses: the lattice's rest length and
/// the material's values times the factors.
#[test]
fn the_springs_report_their_own_values() {
    let lattice = Lattice::new([4, 3, 5], Vec3::new(0.6, 0.4, 1.0));
    let body = scaled_by_pair(Body::lattice_box(lattice.clone(), material()));
    let want = brute_force(&lattice, |_, _| true);
    let mut got: Vec<Spring> = Vec::new();
    body.for_each_spring(|s| got.push(*s));
    got.sort_by_key(|s| (s.a.min(s.b), s.a.max(s.b)));
    assert_eq!(got.len(), want.len());
    for (g, &(a, b, rest, kind)) in got.iter().zip(&want) {
        let s = pair_scale(a, b);
        assert_eq!((g.a.min(g.b), g.a.max(g.b), g.kind as usize), (a, b, kind));
        assert!((g.rest - rest * s.rest).abs() <= 1e-15, "{g:?}");
        assert_eq!(g.stiffness, material().stiffness[kind] * s.stiffness);
        assert_eq!(g.damping, material().damping[kind] * s.damping);
    }
    let flat = jello_core::Model::springs(&free_model(vec![body]));
    assert_eq!(flat.len(), want.len());
    assert_eq!(flat.stiffness.len(), want.len());
}

/// All rest lengths scaled by `s`: the body's rest shape is its lattice scaled by `s`. There no
/// spring pulls (exactly, up to rounding), and a damped body let go from the lattice's shape
/// shrinks to it and stays.
#[test]
fn a_uniform_rest_factor_scales_the_rest_shape() {
    let s = 0.8;
    let lattice = Lattice::new([5, 5, 5], Vec3::new(1.0, 1.0, 1.0));
    let mut body = Body::lattice_box(lattice, Material::classic());
    (body.material.mass, body.material.damping) = (0.02, [0.5; 3]);
    body.scale_springs(|_| SpringScale {
        rest: s,
        ..SpringScale::ONE
    })
    .unwrap();
    let model = free_model(vec![body]);
    let mut state = State::at_rest(&model);
    let shrunk: Vec<Vec3> = state.pos.iter().map(|&p| p * s).collect();
    let mut acc = vec![Vec3::ZERO; shrunk.len()];
    let still = vec![Vec3::ZERO; shrunk.len()];
    accelerations(&model, &shrunk, &still, &Control::none(), &mut acc);
    // One spring at 1 % strain would give k·0.01·h/m = 200 · 0.0025 / 0.02 = 25 m/s².
    assert!(
        acc.iter().all(|a| a.length() < 1e-9),
        "no spring pulls at the scaled shape"
    );
    // At the lattice's shape every spring is stretched by 1/s: the body contracts.
    accelerations(&model, &state.pos, &still, &Control::none(), &mut acc);
    assert!(acc[0].x > 10.0 && acc[0].y > 10.0 && acc[0].z > 10.0);

    let mut scratch = Scratch::new(&model);
    for _ in 0..8000 {
        step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
    }
    // The centre of mass does not move; about it, the shape is the scaled lattice.
    let centre = Vec3::new(0.5, 0.5, 0.5);
    let want: Vec<Vec3> = shrunk.iter().map(|&p| p + centre * (1.0 - s)).collect();
    let off = max_diff(&state.pos, &want);
    assert!(off < 1e-6, "settled {off} m from the scaled shape");
}

/// Factors of exactly 2 on every stiffness give bit for bit the same steps as a material of twice
/// the stiffness, and the same energy and stable time step: kernel, diagnostics and stability
/// all read the one set of values.
#[test]
fn a_table_of_twos_is_the_doubled_material() {
    let lattice = Lattice::new([7, 6, 9], Vec3::new(0.7, 0.6, 0.9));
    let cells: Vec<bool> = (0..6 * 5 * 8).map(|c| c % 7 != 3).collect();
    for body in [
        Body::lattice_box(lattice.clone(), material()),
        Body::from_cells(lattice.clone(), cells, material()).unwrap(),
    ] {
        let mut doubled = body.clone();
        doubled.material.stiffness = material().stiffness.map(|k| 2.0 * k);
        doubled.material.damping = material().damping.map(|d| 0.5 * d);
        let mut scaled = body.clone();
        scaled
            .scale_springs(|_| SpringScale {
                rest: 1.0,
                stiffness: 2.0,
                damping: 0.5,
            })
            .unwrap();
        let (a, b) = (free_model(vec![doubled]), free_model(vec![scaled]));
        let (pos, vel) = jiggled(&a, 9);
        let start = State {
            pos,
            vel,
            ..State::at_rest(&a)
        };
        assert_eq!(energy(&a, &start), energy(&b, &start));
        for integrator in Integrator::ALL {
            assert_eq!(stable_dt(&a, integrator), stable_dt(&b, integrator));
        }
        let (mut sa, mut sb) = (start.clone(), start.clone());
        common::run(&a, &mut sa, 50);
        common::run(&b, &mut sb, 50);
        assert_eq!(sa, sb);
    }
}

/// The spring energy is Σ ½ k (|L| − R)² over the springs' own values.
#[test]
fn the_energy_uses_each_springs_values() {
    let lattice = Lattice::new([4, 5, 3], Vec3::new(0.5, 0.6, 0.3));
    let model = free_model(vec![scaled_by_pair(Body::lattice_box(
        lattice.clone(),
        material(),
    ))]);
    let (pos, vel) = jiggled(&model, 5);
    let state = State {
        pos: pos.clone(),
        vel,
        ..State::at_rest(&model)
    };
    let want: f64 = brute_force(&lattice, |_, _| true)
        .iter()
        .map(|&(a, b, rest, kind)| {
            let s = pair_scale(a, b);
            let stretch = (pos[a] - pos[b]).length() - rest * s.rest;
            0.5 * material().stiffness[kind] * s.stiffness * stretch * stretch
        })
        .sum();
    let got = energy(&model, &state).spring;
    assert!((got - want).abs() <= 1e-12 * want, "{got} {want}");
}

/// Stiffer springs in one place lower the stable time step by the square root of the factor
/// there (the stiffest mode lives where the springs are stiffest).
#[test]
fn stiffer_springs_lower_the_stable_step() {
    let lattice = Lattice::new([6, 6, 6], Vec3::new(1.0, 1.0, 1.0));
    let plain = Body::lattice_box(lattice, Material::classic());
    let mut stiff = plain.clone();
    // The springs from the first few points only: four times stiffer.
    stiff
        .scale_springs(|s| SpringScale {
            stiffness: if s.a < 40 { 4.0 } else { 1.0 },
            ..SpringScale::ONE
        })
        .unwrap();
    let (a, b) = (free_model(vec![plain]), free_model(vec![stiff]));
    let ratio = stable_dt(&a, Integrator::Rk4) / stable_dt(&b, Integrator::Rk4);
    assert!(ratio > 1.3 && ratio <= 2.0 + 1e-9, "ratio {ratio}");
}

/// Factors that cancel leave the body as it was; a bad factor is refused and changes nothing.
#[test]
fn factors_are_checked_and_cancel() {
    let lattice = Lattice::new([3, 3, 3], Vec3::new(1.0, 1.0, 1.0));
    let body = Body::lattice_box(lattice, Material::classic());
    let mut twice = body.clone();
    let double = SpringScale {
        rest: 2.0,
        stiffness: 4.0,
        damping: 0.5,
    };
    twice.scale_springs(|_| double).unwrap();
    assert!(twice.spring_table().is_some());
    twice
        .scale_springs(|_| SpringScale {
            rest: 0.5,
            stiffness: 0.25,
            damping: 2.0,
        })
        .unwrap();
    assert!(twice.spring_table().is_none());
    assert_eq!(twice, body);

    for (bad, what) in [
        (
            SpringScale {
                rest: 0.0,
                ..SpringScale::ONE
            },
            "rest length factor",
        ),
        (
            SpringScale {
                stiffness: -1.0,
                ..SpringScale::ONE
            },
            "stiffness factor",
        ),
        (
            SpringScale {
                damping: f64::NAN,
                ..SpringScale::ONE
            },
            "damping factor",
        ),
        (
            SpringScale {
                rest: f64::INFINITY,
                ..SpringScale::ONE
            },
            "rest length factor",
        ),
    ] {
        let mut b = body.clone();
        let mut n = 0;
        let err = b
            .scale_springs(|_| {
                n += 1;
                if n == 5 {
                    bad
                } else {
                    double
                }
            })
            .unwrap_err();
        assert!(err.0.contains(what), "{err}");
        assert_eq!(b, body, "a refused scaling changes nothing");
    }
    // A world file cannot hold per-spring values.
    let mut classic = Body::lattice_box(Lattice::classic(), Material::classic());
    classic.scale_springs(|_| double).unwrap();
    let model = ModelBuilder::new().bodies(vec![classic]).build().unwrap();
    let err = jello_core::World::from_simulation(&model, &State::at_rest(&model)).unwrap_err();
    assert!(err.0.contains("per-spring"), "{err}");
}

/// A body with per-spring values, large enough for threads, steps bit for bit the same on 1, 2
/// and 3 threads. (That it steps without allocating is checked in no_allocation.rs.)
#[test]
fn per_spring_values_are_bit_identical_on_any_thread_count() {
    let lattice = Lattice::new([22, 20, 20], Vec3::new(1.0, 0.9, 0.9));
    assert!(lattice.len() >= PARALLEL_MIN_POINTS);
    let mut body = scaled_by_pair(Body::lattice_box(lattice, Material::classic()));
    body.material.stiffness = [50.0; 3];
    let model = ModelBuilder::new()
        .bodies(vec![body])
        .dt(0.0002)
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .build()
        .unwrap();
    let start = State::at_rest(&model);
    let run = |threads| common::run_on_threads(&model, &start, 30, threads);
    let one = run(1);
    assert_eq!(one, run(2));
    assert_eq!(one, run(3));
}
