//! Unit tests of the solver's parts: each against its definition, a closed form or the same
//! computation on another number of threads.

use super::cg::{advance, apply_to, dot, sum_chunk, sum_chunks};
use super::matrix::{assemble, solve_multigrid, Curvature};
use super::newton::shift_by_momentum;
use super::newton::{add_weight, enough_reduction, first_iterate, max_norms, momentum_shift};
use super::residual::residual;
use super::test_models::values;
use super::*;
use crate::model::body::{Body, Material};
use crate::model::field::ForceField;
use crate::model::lattice::Lattice;
use crate::model::solver::TOLERANCE;
use crate::model::{Aabb, ModelBuilder};

/// A scratch for `model`, loaded, its dampers at the step's start `x0`.
fn scratch_at(model: &crate::Model, x0: &[Vec3]) -> ImplicitScratch {
    let mut s = ImplicitScratch::new(model);
    s.load(model);
    s.start_dampers(model, x0);
    s
}

/// The residual of the step from `(x0, v0)` at the iterate `v`, into `s.g`; returns `|g|²_M`.
fn residual_at(
    model: &crate::Model,
    control: &Control,
    force: &mut ForceScratch,
    s: &mut ImplicitScratch,
    (x0, v0): (&[Vec3], &[Vec3]),
    v: &[Vec3],
    h: f64,
) -> f64 {
    s.v.copy_from_slice(v);
    residual(model, control, force, s, x0, v0, h, false)
}

/// A solve stopped at `enough_reduction` leaves every moving point's residual within the
/// tolerance however the linear model's residual falls, even all on the lightest point;
/// held points and the scale of `g` do not change that.
#[test]
fn enough_reduction_bounds_every_points_residual() {
    let model = test_models::two_bodies();
    let mut s = ImplicitScratch::new(&model);
    let mut next = values(11);
    for (p, ((g, m), free)) in s.g.iter_mut().zip(&mut s.mass).zip(&mut s.free).enumerate() {
        *g = Vec3::new(next(), next(), next()) * 1e3;
        *m = 0.01 + (1.0 + next());
        *free = if p % 7 == 3 { 0.0 } else { 1.0 };
    }
    // A held point's large residual and small mass count for nothing.
    s.g[3] = Vec3::new(1e9, 0.0, 0.0);
    s.mass[3] = 1e-6;
    let target = 1e-9;
    let reduction = enough_reduction(&s, target);
    let moving = || (0..s.g.len()).filter(|&p| s.free[p] != 0.0);
    let norm = moving()
        .map(|p| (s.mass[p] * s.g[p]).dot(s.mass[p] * s.g[p]))
        .sum::<f64>()
        .sqrt();
    let lightest = moving().map(|p| s.mass[p]).fold(f64::INFINITY, f64::min);
    // The worst case: the whole remaining residual `reduction·|M·g|` at the lightest point.
    let worst = reduction * norm / lightest;
    assert!(
        worst <= 0.5 * target * (1.0 + 1e-12),
        "{worst:e} > {target:e} / 2"
    );
    assert!(
        worst >= 0.5 * target * (1.0 - 1e-12),
        "{worst:e}: needlessly tight"
    );
    assert_eq!(
        enough_reduction(&ImplicitScratch::new(&model), target),
        0.0,
        "g = 0"
    );
}

/// A solve may stop once its residual is within `m·within` at every point, each point
/// judged by its own mass: not while one point is over, not without a bound. (A step of
/// length 0 leaves `r` as set here.)
#[test]
fn each_point_within_judges_every_point_by_its_mass() {
    let model = test_models::two_bodies();
    let mut s = ImplicitScratch::new(&model);
    let mut next = values(5);
    s.within = 1e-9;
    for (r, m) in s.r.iter_mut().zip(&mut s.mass) {
        *m = 0.01 + (1.0 + next());
        // Each point's residual at 0.99 of its own bound, in a random direction.
        let d = Vec3::new(next(), next(), next());
        *r = d * (0.99 * *m * s.within / d.length());
    }
    let each_point_within = |s: &mut ImplicitScratch| advance(s, 0.0).1;
    assert!(each_point_within(&mut s));
    // One point over its bound, though within the heaviest point's.
    let last = s.r.len() - 1;
    let heaviest = s.mass.iter().fold(0.0, |a: f64, &m| a.max(m));
    s.mass[last] = 0.5 * heaviest;
    s.r[last] = Vec3::new(0.0, 0.0, 1.01 * s.mass[last] * s.within);
    assert!(!each_point_within(&mut s));
    s.r[last] = Vec3::ZERO;
    assert!(each_point_within(&mut s));
    s.within = 0.0;
    assert!(
        !each_point_within(&mut s),
        "no bound: only the reduction stops a solve"
    );
}

/// The conjugate gradients' sums are taken over chunks fixed by the number of points alone,
/// each chunk's in order, then the chunks' in order: the same bits on any number of threads,
/// from one thread's loops and from a team's (more threads than this machine's cores
/// included).
#[test]
fn the_solves_sums_are_the_same_on_any_number_of_threads() {
    let n = 5 * MIN_CHUNK + 17;
    assert!(sum_chunks(n) > 1);
    let mut next = values(9);
    let mut vector = || -> Vec<Vec3> {
        (0..n)
            .map(|_| Vec3::new(next(), next(), next()) * (1.0 + 1e3 * next().abs()))
            .collect()
    };
    let (a, b, p, ap, r) = (vector(), vector(), vector(), vector(), vector());
    let mass: Vec<f64> = (0..n).map(|i| 1.0 + i as f64 * 1e-3).collect();
    let size = sum_chunk(n);
    let chunked = |f: &dyn Fn(usize) -> f64| -> f64 {
        (0..n)
            .step_by(size)
            .map(|start| (start..(start + size).min(n)).map(f).sum::<f64>())
            .sum()
    };
    let run = |threads: usize| {
        test_models::on_threads(threads, || {
            let mut s = ImplicitScratch::new(&test_models::two_bodies());
            s.dots = vec![0.0; sum_chunks(n)];
            s.advanced = vec![(0.0, false); sum_chunks(n)];
            s.dv = vec![Vec3::ZERO; n];
            (s.p, s.ap, s.r, s.mass) = (p.clone(), ap.clone(), r.clone(), mass.clone());
            s.within = 1e3;
            let ab = dot(&a, &b, &mut s.dots);
            let (rr, _) = advance(&mut s, 0.37);
            (ab.to_bits(), rr.to_bits(), s.r.clone(), s.dv.clone())
        })
    };
    let one = run(1);
    assert_eq!(one.0, chunked(&|i| a[i].dot(b[i])).to_bits());
    let stepped = |i: usize| r[i] - ap[i] * 0.37;
    assert_eq!(one.1, chunked(&|i| stepped(i).length_squared()).to_bits());
    assert!((0..n).all(|i| one.2[i] == stepped(i) && one.3[i] == p[i] * 0.37));
    for threads in [2, 3, 8] {
        assert_eq!(run(threads), one, "{threads} threads");
    }
}

/// GMRES's basis and the field's corrections are held only for a field whose swirl can pass
/// the limit at the model's step: not for a gentle field that is not uniform, nor for the
/// same field at a step too short for it. GMRES's basis and room for friction's growth with
/// depth at every point, only where friction may slide at its full size: on the walls (or the
/// inclined plane) with their friction, on an obstacle with the model's.
#[test]
fn only_a_field_that_can_swirl_past_the_limit_or_friction_gets_gmres() {
    let box_ = Aabb::new(Vec3::new(-2.0, -2.0, -2.0), Vec3::new(2.0, 2.0, 2.0)).unwrap();
    // c·(−y, x, 0) swirls by c (N/m); the classic mass is 1/512 kg.
    let turning = |c: f64| ForceField::from_fn(5, box_, move |p| Vec3::new(-p.y, p.x, 0.0) * c);
    let model = |c: f64, dt: f64| {
        let body = Body::lattice_box(
            Lattice::new([3, 3, 3], Vec3::new(0.5, 0.5, 0.5)),
            Material::classic(),
        );
        let model = ModelBuilder::new().bodies(vec![body]);
        model
            .field(Some(turning(c).unwrap()))
            .dt(dt)
            .build()
            .unwrap()
    };
    let h = 1.0 / 60.0;
    let at_limit = SWIRL_LIMIT / 512.0 / (h * h);
    for (c, dt, held) in [
        (2.0 * at_limit, h, true),
        (0.5 * at_limit, h, false),
        (2.0 * at_limit, 0.5 * h, false),
    ] {
        let model = model(c, dt);
        let s = ImplicitScratch::new(&model);
        let n = model.point_count();
        assert_eq!(can_swirl(&model, model.dt), held, "field {c} N/m, dt {dt}");
        assert_eq!(s.gmres.fits(n), held, "field {c} N/m, dt {dt}");
        assert_eq!(s.field_correction.len(), if held { n } else { 0 });
        assert_eq!(s.friction_growth.capacity(), 0);
    }
    let ball = || crate::Obstacle::Sphere(crate::Sphere::new(Vec3::ZERO, 0.1).unwrap());
    let with = |walls: f64, obstacles: f64, obstacle: bool| {
        let mut model = ModelBuilder::new().wall_friction(walls).friction(obstacles);
        if obstacle {
            model = model.obstacle(ball());
        }
        model.build().unwrap()
    };
    for (model, held) in [
        (with(0.5, 0.0, false), true),
        (with(0.0, 0.5, true), true),
        (with(0.0, 0.5, false), false),
        (with(0.0, 0.0, true), false),
    ] {
        let s = ImplicitScratch::new(&model);
        let n = model.point_count();
        let what = (model.wall_friction, model.friction, model.obstacles.len());
        assert_eq!(s.gmres.fits(n), held, "{what:?}");
        assert_eq!(s.friction_growth.capacity() >= n, held, "{what:?}");
    }
}

/// An undeformed body flying in a uniform field needs no Newton iteration: the first
/// iterate, shifted by the body's change of momentum, is the step's solution to rounding.
/// Held at a point, the body would be bent by the shift, which is then not taken; nor is a
/// shift no larger than the least one asked for (not even tried: a residual saved).
#[test]
fn a_body_in_free_flight_is_solved_by_its_change_of_momentum() {
    let box_ = Aabb::new(Vec3::new(-9.0, -9.0, -9.0), Vec3::new(9.0, 9.0, 9.0)).unwrap();
    let pull = Vec3::new(0.3, -0.2, -9.81 / 512.0);
    let field = ForceField::from_fn(2, box_, |_| pull).unwrap();
    let body = || {
        Body::lattice_box(
            Lattice::new([4, 3, 5], Vec3::new(0.6, 0.4, 0.8)),
            Material::classic(),
        )
    };
    let h = 1.0 / 60.0;
    for pins in [vec![], vec![7]] {
        let model = ModelBuilder::new()
            .bodies(vec![body()])
            .bounds(box_)
            .field(Some(field.clone()))
            .dt(h)
            .pins(pins.clone())
            .build()
            .unwrap();
        let x0 = crate::State::at_rest(&model).pos;
        let v0 = vec![Vec3::new(1.0, -0.5, 2.0); x0.len()];
        let (control, mut force) = (Control::none(), ForceScratch::new(&model));
        let mut s = scratch_at(&model, &x0);
        let norm2 = residual_at(&model, &control, &mut force, &mut s, (&x0, &v0), &v0, h);
        // The shift is `h·pull/m` (the springs are at rest): asked for a larger one, none.
        let shift = (pull * (h * 512.0)).length();
        let g = s.g.clone();
        let mut shift_by = |least: f64, s: &mut ImplicitScratch| {
            shift_by_momentum(&model, &control, &mut force, s, &x0, &v0, h, norm2, least)
        };
        assert_eq!(shift_by(1.01 * shift, &mut s), norm2);
        assert_eq!((&s.v, &s.g), (&v0, &g));
        let reached = shift_by(0.99 * shift, &mut s);
        let (worst, _) = max_norms(&s.g, &s.v);
        if pins.is_empty() {
            assert!(reached < 1e-20 * norm2, "|g|²_M {norm2} → {reached}");
            // Rounding alone: the springs' forces at the shifted end positions.
            assert!(worst <= 0.01 * TOLERANCE, "max |g| {worst} m/s");
        } else {
            // Held, the body cannot fly: the shift would bend it, and is not taken.
            assert_eq!(reached, norm2);
            assert_eq!(s.v, v0);
        }
    }
}

/// A body in free flight starts from its weight's change of momentum over the step (gravity and
/// a uniform field's force, `h·(g + n·F/M)` over its `n` moving points of mass `M`): its first
/// residual is then within the tolerance, no Newton iteration needed; a lattice with holes moves
/// at its moving points alone. A body pinned at a point, pulled, pushed by the control's forces,
/// in a field that is not uniform, or that the shift would carry into a floor starts from `v₀`
/// (its momentum changes by what the first residual finds).
#[test]
fn a_body_in_free_flight_starts_from_its_weights_change_of_momentum() {
    let box_ = Aabb::new(Vec3::new(-9.0, -9.0, -9.0), Vec3::new(9.0, 9.0, 9.0)).unwrap();
    let force = Vec3::new(0.3, -0.2, 0.1);
    let uniform = ForceField::from_fn(2, box_, |_| force).unwrap();
    let swirling = ForceField::from_fn(2, box_, |p| Vec3::new(-p.y, p.x, 0.0) * 1e-3).unwrap();
    let gravity = Vec3::new(0.0, 0.0, -9.81);
    let h = 1.0 / 60.0;
    let box_body = || {
        Body::lattice_box(
            Lattice::new([4, 3, 5], Vec3::new(0.6, 0.4, 0.8)),
            Material::classic(),
        )
    };
    let with = |body: Body, field: &ForceField, pins: Vec<u32>| {
        (ModelBuilder::new().bodies(vec![body]).bounds(box_))
            .field(Some(field.clone()))
            .gravity(gravity)
            .dt(h)
            .pins(pins)
            .build()
            .unwrap()
    };
    let pull = crate::state::Pull {
        point: 5,
        target: Vec3::new(0.0, 0.0, 1.0),
        stiffness: 10.0,
        damping: 0.0,
    };
    let model = |field: &ForceField, pins: Vec<u32>| with(box_body(), field, pins);
    let free = model(&uniform, vec![]);
    let n = free.point_count();
    // A lattice with holes: its points outside every kept cell do not move, and are not shifted.
    let holes = with(
        test_models::with_holes([4, 4, 4], 3, -0.3),
        &uniform,
        vec![],
    );
    let cases = [
        ("free", free.clone(), Control::none(), true),
        ("with holes", holes, Control::none(), true),
        ("held", model(&uniform, vec![7]), Control::none(), false),
        (
            "swirling field",
            model(&swirling, vec![]),
            Control::none(),
            false,
        ),
        (
            "pulled",
            free.clone(),
            Control {
                pulls: vec![pull],
                ..Control::none()
            },
            false,
        ),
        (
            "pushed",
            free.clone(),
            Control {
                forces: vec![Vec3::ZERO; n],
                ..Control::none()
            },
            false,
        ),
    ];
    for (what, model, control, shifted) in cases {
        let x0 = crate::State::at_rest(&model).pos;
        let v0 = vec![Vec3::new(1.0, -0.5, 2.0); model.point_count()];
        let mut force_scratch = ForceScratch::new(&model);
        let mut s = scratch_at(&model, &x0);
        first_iterate(&mut s, &model, &v0, h);
        add_weight(&model, &control, &mut s, &x0, &v0, h);
        if !shifted {
            assert_eq!(s.v, v0, "{what}");
            continue;
        }
        // The moving points' momentum changes by `h` times the forces on them, `n·F` and `M·g`.
        let moving: f64 = s.free.iter().sum();
        let mass: f64 = s.mass.iter().zip(&s.free).map(|(m, f)| m * f).sum();
        assert_eq!(s.free.contains(&0.0), what == "with holes", "{what}");
        let shift = (gravity + force * (moving / mass)) * h;
        for (v, &free) in s.v.iter().zip(&s.free) {
            assert!(
                (*v - v0[0] - shift * free).length() <= 1e-15,
                "{what}: {v:?}"
            );
        }
        residual(
            &model,
            &control,
            &mut force_scratch,
            &mut s,
            &x0,
            &v0,
            h,
            false,
        );
        let (worst, _) = max_norms(&s.g, &s.v);
        // Rounding alone: the springs' forces at the shifted end positions.
        assert!(worst <= 0.01 * TOLERANCE, "{what}: max |g| {worst} m/s");
    }
    // At rest 1 mm above a floor, the shift (2.7 mm down in the step) would carry the body into
    // it; 1 m above, it flies.
    for (above, shifted) in [(0.001, false), (1.0, true)] {
        let (model, x0) = dropped_cube_with_its_bottom_at(4, above);
        let v0 = vec![Vec3::ZERO; x0.len()];
        let mut s = scratch_at(&model, &x0);
        assert!(
            !s.touching.contains(&true),
            "clear of the floor at the start"
        );
        first_iterate(&mut s, &model, &v0, h);
        add_weight(&model, &Control::none(), &mut s, &x0, &v0, h);
        assert_eq!(s.v != v0, shifted, "{above} m above the floor");
    }
}

/// A body that a step at its velocities would carry into a surface is not shifted by its change
/// of momentum: the mean residual then holds the contact's force, which would throw the whole
/// body back (the dropped 16³ cube's landing: shifted to 22 m/s upwards, its step took 13 Newton
/// iterations instead of 4). The same body falling clear of the floor is shifted.
#[test]
fn a_body_about_to_land_is_not_shifted_by_its_change_of_momentum() {
    let control = Control::none();
    // Falling at 3 m/s, 5 cm a step: from 1 cm above the floor into it, from 1 m clear of it.
    for (above, lands) in [(0.01, true), (1.0, false)] {
        let (model, x0) = dropped_cube_with_its_bottom_at(8, above);
        let h = model.dt;
        let v0 = vec![Vec3::new(0.0, 0.0, -3.0); x0.len()];
        let mut force = ForceScratch::new(&model);
        let mut s = scratch_at(&model, &x0);
        assert!(
            !s.touching.contains(&true),
            "clear of the floor at the start"
        );
        let norm2 = residual_at(&model, &control, &mut force, &mut s, (&x0, &v0), &v0, h);
        let reached = shift_by_momentum(
            &model, &control, &mut force, &mut s, &x0, &v0, h, norm2, 0.0,
        );
        if lands {
            assert_eq!(reached, norm2);
            assert_eq!(s.v, v0);
        } else {
            assert!(reached < norm2, "|g|²_M {norm2} → {reached}");
            assert!(s.v != v0);
        }
    }
}

/// The model of the `drop` job's cube of `n³` points at 1/60 s, and its points moved up or down
/// so that its bottom is `above` the floor (m; below it where negative).
fn dropped_cube_with_its_bottom_at(n: usize, above: f64) -> (crate::Model, Vec<Vec3>) {
    let (model, start) = crate::benchmark::Job::Drop
        .scene(n, Integrator::BackwardEuler, None)
        .unwrap();
    let bottom = start.pos.iter().map(|p| p.z).fold(f64::INFINITY, f64::min);
    let lift = Vec3::new(0.0, 0.0, above - bottom);
    let x0 = start.pos.iter().map(|&p| p + lift).collect();
    (model, x0)
}

/// `A` anticipates the contacts the last whole Newton step reached: a point clear of the floor
/// at the iterate that the step took into it gets the floor's penalty stiffness `h²·kc·nnᵀ` in
/// its block, and no other point's block changes (those the step left clear of the floor);
/// before a solve's first direction, nothing is anticipated.
#[test]
fn a_anticipates_the_contacts_the_last_newton_step_reached() {
    // At rest 1 cm above the floor (or already 1 cm into it); the whole step takes the bottom
    // layer 3 cm down, the others 1 cm.
    for above in [0.01, -0.01] {
        let (model, x0) = dropped_cube_with_its_bottom_at(6, above);
        let h = model.dt;
        let on_bottom = |p: Vec3| p.z < above + 1e-9;
        let full: Vec<Vec3> = (x0.iter())
            .map(|&p| Vec3::new(0.0, 0.0, if on_bottom(p) { -0.03 } else { -0.01 } / h))
            .collect();
        let (control, force) = (Control::none(), ForceScratch::new(&model));
        let mut s = scratch_at(&model, &x0);
        s.v.fill(Vec3::ZERO);
        let mut blocks = |taken: bool| {
            s.full_step.copy_from_slice(&full);
            s.full_step_taken = taken;
            let (anchors, curvature) = (force.anchors(), Curvature::True { shift: 0.0 });
            assemble(&model, &control, anchors, &mut s, &x0, h, curvature);
            s.extra.clone()
        };
        let (plain, anticipated) = (blocks(false), blocks(true));
        let k = h * h * model.k_collision;
        let mut landing = 0;
        for ((&p, plain), anticipated) in x0.iter().zip(&plain).zip(&anticipated) {
            if on_bottom(p) && above > 0.0 {
                let mut expected = *plain;
                expected[2] += k;
                assert_eq!(*anticipated, expected, "at {p:?}");
                landing += 1;
            } else {
                // Clear of the floor all along, or on it already (its spring is in `A`).
                assert_eq!(anticipated, plain, "at {p:?}");
            }
        }
        assert_eq!(landing, if above > 0.0 { 36 } else { 0 });
    }
}

/// The residual is the backward-Euler equation spring by spring: `g = v − v₀ − h·f/m`, each
/// spring's force at the end positions `x₀ + h·v`, and its damper's along its direction at the
/// step's start `x₀` at the velocities `v` (`−d·(u₀·(vₐ − v_b))·u₀`), on a lattice with holes
/// and a second body, with per-spring factors on one (the force pass computes the dampers with
/// the springs).
#[test]
fn the_residual_is_the_backward_euler_equation_spring_by_spring() {
    let big = Aabb::new(Vec3::new(-50.0, -50.0, -50.0), Vec3::new(50.0, 50.0, 50.0)).unwrap();
    let mut next = values(23);
    let model = ModelBuilder::new()
        .bodies(test_models::holes_and_factors(&mut next))
        .bounds(big)
        .build()
        .unwrap();
    let n = model.point_count();
    let h = 0.01;
    let x0: Vec<Vec3> = crate::State::at_rest(&model)
        .pos
        .iter()
        .map(|&p| p + Vec3::new(next(), next(), next()) * 0.05)
        .collect();
    let v0: Vec<Vec3> = (0..n).map(|_| Vec3::new(next(), next(), next())).collect();
    let v: Vec<Vec3> = (0..n).map(|_| Vec3::new(next(), next(), next())).collect();
    let (control, mut force) = (Control::none(), ForceScratch::new(&model));
    let mut s = scratch_at(&model, &x0);
    residual_at(&model, &control, &mut force, &mut s, (&x0, &v0), &v, h);

    let end: Vec<Vec3> = x0.iter().zip(&v).map(|(&x, &v)| x + v * h).collect();
    let mut f = vec![Vec3::ZERO; n];
    let mut springs = 0;
    for body in model.bodies() {
        let first = body.points().start;
        body.for_each_spring(|spring| {
            let (a, b) = (first + spring.a, first + spring.b);
            let l = end[a] - end[b];
            let stretch = l * (-spring.stiffness * (l.length() - spring.rest) / l.length());
            let u0 = (x0[a] - x0[b]) / (x0[a] - x0[b]).length();
            let damper = u0 * (-spring.damping * u0.dot(v[a] - v[b]));
            f[a] += stretch + damper;
            f[b] -= stretch + damper;
            springs += 1;
        });
    }
    assert!(springs > 300, "{springs} springs");
    let mut largest: f64 = 0.0;
    for p in 0..n {
        let want = v[p] - v0[p] - f[p] * (h / s.mass[p]);
        largest = largest.max(want.max_abs());
        assert!(
            (s.g[p] - want).max_abs() <= 1e-12 * (1.0 + want.max_abs()),
            "point {p}: {:?} ≠ {want:?}",
            s.g[p]
        );
    }
    assert!(largest > 1.0, "the forces matter: {largest}");
}

/// Each step's end velocities of two runs agree to within 1e-10 m/s at every point.
fn assert_same_steps(a: &[Vec<Vec3>], b: &[Vec<Vec3>]) {
    assert_eq!(a.len(), b.len());
    for (step, (a, b)) in a.iter().zip(b).enumerate() {
        let worst = a.iter().zip(b).map(|(a, b)| (*a - *b).length());
        let worst = worst.fold(0.0, f64::max);
        assert!(
            worst < 1e-10,
            "step {step}: velocities differ by {worst} m/s"
        );
    }
}

/// Newton's iterations in the fast regime keep the last one's `A`, and the steps end at the
/// same velocities as with `A` assembled every iteration, to within the tolerance: a cube
/// dropped onto a plane at 1/60 s, settling over 40 steps.
#[test]
fn newton_in_its_fast_regime_keeps_a_and_reaches_the_same_solution() {
    let body = Body::lattice_box(
        Lattice::new([6, 6, 6], Vec3::new(1.0, 1.0, 1.0)),
        Material::classic(),
    );
    let mut model = ModelBuilder::new()
        .bodies(vec![body])
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .plane(Some(crate::Plane::new([0.0, 0.0, 1.0, 0.05]).unwrap()))
        .dt(1.0 / 60.0)
        .integrator(Integrator::BackwardEuler)
        .build()
        .unwrap();
    model.newton.tolerance = 1e-11;
    let h = model.dt;
    let start = crate::State::at_rest(&model);
    let (control, mut force) = (Control::none(), ForceScratch::new(&model));
    let run = |may_keep: bool, force: &mut ForceScratch| {
        let mut s = ImplicitScratch::new(&model);
        s.may_keep = may_keep;
        let mut state = start.clone();
        let mut ends = vec![];
        let (mut pos, mut vel) = (state.pos.clone(), state.vel.clone());
        for _ in 0..40 {
            step(
                &model, &state, &control, force, &mut s, h, &mut pos, &mut vel,
            )
            .unwrap();
            state.pos.copy_from_slice(&pos);
            state.vel.copy_from_slice(&vel);
            ends.push(state.vel.clone());
        }
        (ends, s.kept)
    };
    let (kept_a, kept) = run(true, &mut force);
    let (fresh_a, none) = run(false, &mut force);
    assert_eq!(none, 0);
    assert!(kept >= 20, "{kept} iterations kept A in 40 steps");
    assert_same_steps(&kept_a, &fresh_a);
}

/// With friction's growth with depth in `A` once Newton's method leaves its fast regime, a
/// cube dropped onto a floor with friction (the `drop` job at 12³, 1/60 s) lands in fewer Newton
/// iterations, its hardest step in fewer, and its steps end where they end without it, to
/// within the tolerance.
#[test]
fn friction_growth_in_a_cuts_the_newton_iterations_of_a_landing() {
    let (grown, grown_iterations, grown_hardest) = landing(true, true);
    let (plain, plain_iterations, plain_hardest) = landing(false, true);
    // (41 and 6 with it, 55 and 13 without, when this was written; 59 and 11, 66 and 14
    // before the landing kept the growth for the step and anticipated its contacts.)
    assert!(
        grown_iterations < plain_iterations && grown_hardest < plain_hardest,
        "Newton iterations, in all and in the hardest step: {grown_iterations} and \
         {grown_hardest} with the growth, {plain_iterations} and {plain_hardest} without"
    );
    assert_same_steps(&grown, &plain);
}

/// Once friction's growth with depth is in `A`, it stays there for the rest of the step: taken
/// out again after a fast iteration, the next iteration left the sliding friction's residual
/// and the one after took the growth back, and the landing's steps alternated so. The same
/// landing as above takes fewer Newton iterations with it kept, to the same steps.
#[test]
fn friction_growth_once_in_a_stays_for_the_step() {
    let (kept, kept_iterations, _) = landing(true, true);
    let (dropped, dropped_iterations, _) = landing(true, false);
    // (41 and 50 when this was written.)
    assert!(
        kept_iterations < dropped_iterations,
        "Newton iterations: {kept_iterations} with the growth kept for the step, \
         {dropped_iterations} taken out after a fast iteration"
    );
    assert_same_steps(&kept, &dropped);
}

/// The first 30 steps of the cube dropped onto a floor with friction (the `drop` job at 12³,
/// 1/60 s): their end velocities, the Newton iterations in all and in the hardest step, with
/// friction's growth in `A` (`may_grow`) and kept there for the step once in (`sticks`) or not.
fn landing(may_grow: bool, sticks: bool) -> (Vec<Vec<Vec3>>, u64, u64) {
    let (model, start) = crate::benchmark::Job::Drop
        .scene(12, Integrator::BackwardEuler, None)
        .unwrap();
    let h = model.dt;
    let control = Control::none();
    let mut force = ForceScratch::new(&model);
    let mut s = ImplicitScratch::new(&model);
    (s.may_grow, s.growth_sticks) = (may_grow, sticks);
    let mut state = start.clone();
    let (mut ends, mut hardest) = (vec![], 0);
    let (mut pos, mut vel) = (state.pos.clone(), state.vel.clone());
    for _ in 0..30 {
        let before = s.stats.newton_iterations;
        step(
            &model, &state, &control, &mut force, &mut s, h, &mut pos, &mut vel,
        )
        .unwrap();
        hardest = hardest.max(s.stats.newton_iterations - before);
        force.update_anchors(&model, &pos);
        state.pos.copy_from_slice(&pos);
        state.vel.copy_from_slice(&vel);
        ends.push(state.vel.clone());
    }
    (ends, s.stats.newton_iterations, hardest)
}

/// Newton's first iterate is zero at the moving points of a body that rests on a surface at a
/// step long for its contacts, and `v₀` elsewhere: at a held point, on a body in the air, on a
/// body moving faster than a tenth of its shortest spring in a step, and at a step short
/// enough to resolve the contacts.
#[test]
fn a_body_resting_on_a_surface_starts_newton_from_rest() {
    let model = |dt: f64| {
        ModelBuilder::new()
            .bodies(vec![
                test_models::box_at([4, 4, 4], Vec3::new(0.0, 0.0, -0.01)),
                test_models::box_at([4, 4, 4], Vec3::new(0.0, 0.0, 5.0)),
            ])
            .bounds(Aabb::new(Vec3::new(-9.0, -9.0, -9.0), Vec3::new(9.0, 9.0, 9.0)).unwrap())
            .plane(Some(crate::Plane::new([0.0, 0.0, 1.0, 0.0]).unwrap()))
            .pins(vec![1])
            .collision(1e4, 0.25)
            .dt(dt)
            .integrator(Integrator::BackwardEuler)
            .build()
            .unwrap()
    };
    let first = |model: &crate::Model, v0: &[Vec3]| {
        let mut s = scratch_at(model, &crate::State::at_rest(model).pos);
        first_iterate(&mut s, model, v0, model.dt);
        s.v
    };
    let long = model(1.0 / 60.0);
    let n = long.point_count();
    let (resting, flying) = (long.body(0).points(), long.body(1).points());
    let slow: Vec<Vec3> = (0..n)
        .map(|p| Vec3::new(1e-3, -2e-3, p as f64 * 1e-5))
        .collect();
    let v = first(&long, &slow);
    for p in resting.clone() {
        let want = if p == 1 { slow[p] } else { Vec3::ZERO };
        assert_eq!(v[p], want, "resting body, point {p}");
    }
    assert_eq!(v[flying.clone()], slow[flying]);
    // One point of the resting body a tenth of a spring a step too fast.
    let mut fast = slow.clone();
    fast[resting.start + 20] = Vec3::new(0.0, 1.01 * 0.1 * 60.0, 0.0);
    assert_eq!(first(&long, &fast), fast);
    // The same body at a step that resolves its contacts.
    let short = model(1e-4);
    assert_eq!(first(&short, &slow), slow);
}

/// The first 60 steps of the `rest` job at 12³ (1/60 s, solved to 1e-11 m/s), the solver's
/// scratch set up by `setup`: each step's end velocities, and the solver's work.
fn rest_job_steps(setup: impl Fn(&mut ImplicitScratch)) -> (Vec<Vec<Vec3>>, SolverStats) {
    rest_job(12, 60, setup)
}

/// [`rest_job_steps`] for an `n`³ cube and `steps` steps.
fn rest_job(
    n: usize,
    steps: usize,
    setup: impl Fn(&mut ImplicitScratch),
) -> (Vec<Vec<Vec3>>, SolverStats) {
    let (mut model, start) = crate::benchmark::Job::Rest
        .scene(n, Integrator::BackwardEuler, None)
        .unwrap();
    model.newton.tolerance = 1e-11;
    let (control, mut force) = (Control::none(), ForceScratch::new(&model));
    let mut s = ImplicitScratch::new(&model);
    setup(&mut s);
    let mut state = start.clone();
    let mut ends = vec![];
    let (mut pos, mut vel) = (state.pos.clone(), state.vel.clone());
    for _ in 0..steps {
        let h = model.dt;
        step(
            &model, &state, &control, &mut force, &mut s, h, &mut pos, &mut vel,
        )
        .unwrap();
        force.update_anchors(&model, &pos);
        state.pos.copy_from_slice(&pos);
        state.vel.copy_from_slice(&vel);
        ends.push(state.vel.clone());
    }
    (ends, s.stats)
}

/// Started from rest where it rests on a floor, the `rest` job at 12³ ([`rest_job_steps`])
/// takes fewer Newton iterations over its first 60 steps than from `v₀`, to the same steps
/// within the tolerance.
#[test]
fn a_resting_body_started_from_rest_takes_fewer_newton_iterations() {
    let (from_rest, at_rest) = rest_job_steps(|s| s.may_start_at_rest = true);
    let (from_v0, from_v0_stats) = rest_job_steps(|s| s.may_start_at_rest = false);
    let (rest_iterations, v0_iterations) =
        (at_rest.newton_iterations, from_v0_stats.newton_iterations);
    eprintln!("Newton iterations: {rest_iterations} from rest, {v0_iterations} from v₀");
    assert!(
        rest_iterations < v0_iterations,
        "Newton iterations: {rest_iterations} from rest, {v0_iterations} from v₀"
    );
    assert_same_steps(&from_rest, &from_v0);
}

/// A step's first solve started from the last steps' directions (`cg/recycle.rs`): the `rest`
/// job at 12³ ([`rest_job_steps`]), whose cube settles in its first second with `A` kept
/// across most steps, takes a fifth fewer conjugate-gradient iterations or more over its first
/// 60 steps than from zero, for as many Newton iterations, to the same steps within the
/// tolerance.
#[test]
fn a_settling_body_recycles_its_directions_into_fewer_iterations() {
    let (recycled, with) = rest_job_steps(|s| s.may_recycle = true);
    let (from_zero, without) = rest_job_steps(|s| s.may_recycle = false);
    eprintln!("recycled: {with:?}\nfrom zero: {without:?}");
    assert!(
        5 * with.linear_iterations < 4 * without.linear_iterations,
        "conjugate-gradient iterations: {} recycled, {} from zero",
        with.linear_iterations,
        without.linear_iterations
    );
    assert_eq!(with.newton_iterations, without.newton_iterations);
    assert_same_steps(&recycled, &from_zero);
}

/// The starts from the last steps' directions take the same bits on any number of threads:
/// the `rest` job at 16³ (4 096 points, stepped on a team), its settling steps recycling.
#[test]
fn recycled_starts_are_the_same_on_any_number_of_threads() {
    let run = |threads: usize, recycle: bool| {
        test_models::on_threads(threads, || rest_job(16, 30, |s| s.may_recycle = recycle))
    };
    let (one, with) = run(1, true);
    let (_, without) = run(1, false);
    assert!(
        with.linear_iterations < without.linear_iterations,
        "the starts were taken: {} against {} conjugate-gradient iterations",
        with.linear_iterations,
        without.linear_iterations
    );
    for threads in [2, 3] {
        assert!(
            run(threads, true) == (one.clone(), with),
            "{threads} threads"
        );
    }
}

/// A step's first Newton iteration keeps the last step's `A` where that step ended in the
/// fast regime and no spring's ends move apart faster than the regime allows: a cube
/// settling on a plane does, in most of its steps that take an iteration, and its steps end
/// where those assembling `A` end, to within the tolerance; once settled, its steps take no
/// Newton iteration at all (they start within the tolerance: no step's momentum shift pressed
/// it into the plane); a cube spinning in free flight (its springs turning) never keeps `A`.
#[test]
fn a_settled_body_keeps_a_across_steps_and_a_spinning_one_does_not() {
    let cube = || {
        Body::lattice_box(
            Lattice::new([6, 6, 6], Vec3::new(1.0, 1.0, 1.0)),
            Material::classic(),
        )
    };
    let model = |gravity: f64, plane: bool| {
        let mut model = ModelBuilder::new()
            .bodies(vec![cube()])
            .gravity(Vec3::new(0.0, 0.0, -gravity))
            .plane(plane.then(|| crate::Plane::new([0.0, 0.0, 1.0, 0.05]).unwrap()))
            .dt(1.0 / 60.0)
            .integrator(Integrator::BackwardEuler)
            .build()
            .unwrap();
        model.newton.tolerance = 1e-11;
        model
    };
    // Steps `from..to` (after `from` steps), with `A` kept or not: each step's end
    // velocities, the steps that kept the last step's `A`, the Newton iterations, and the
    // steps that took any.
    let run = |model: &Model, start: &crate::State, may_keep: bool, steps: [usize; 2]| {
        let (control, mut force) = (Control::none(), ForceScratch::new(model));
        let mut s = ImplicitScratch::new(model);
        let mut state = start.clone();
        let (mut pos, mut vel, mut ends) = (state.pos.clone(), state.vel.clone(), vec![]);
        let (mut kept, mut iterations, mut iterating) = (0, 0, 0);
        for n in 0..steps[1] {
            s.may_keep = may_keep || n < steps[0];
            let before = (s.kept_across, s.stats.newton_iterations);
            let h = model.dt;
            step(
                model, &state, &control, &mut force, &mut s, h, &mut pos, &mut vel,
            )
            .unwrap();
            (state.pos, state.vel) = (pos.clone(), vel.clone());
            if n >= steps[0] {
                kept += s.kept_across - before.0;
                let taken = s.stats.newton_iterations - before.1;
                iterations += taken;
                iterating += u32::from(taken > 0);
                ends.push(state.vel.clone());
            }
        }
        (ends, kept, iterations, iterating)
    };
    let resting = model(9.81, true);
    let start = crate::State::at_rest(&resting);
    let (kept_a, kept, _, iterating) = run(&resting, &start, true, [10, 50]);
    let (fresh_a, none, _, _) = run(&resting, &start, false, [10, 50]);
    assert!(
        iterating >= 20 && 2 * kept > iterating,
        "{kept} of the {iterating} settling steps that iterated kept the last step's A"
    );
    assert_eq!(none, 0);
    assert_same_steps(&kept_a, &fresh_a);
    let (_, _, settled, _) = run(&resting, &start, true, [40, 80]);
    assert_eq!(settled, 0, "Newton iterations in 40 settled steps");
    let free = model(0.0, false);
    let mut spinning = crate::State::at_rest(&free);
    let centre = Vec3::new(0.5, 0.5, 0.5);
    for (v, &p) in spinning.vel.iter_mut().zip(&spinning.pos) {
        let r = p - centre;
        *v = Vec3::new(-r.y, r.x, 0.0) * 2.0;
    }
    let (_, kept, iterations, _) = run(&free, &spinning, true, [0, 20]);
    assert!(
        iterations >= 20,
        "{iterations} Newton iterations in 20 steps"
    );
    assert_eq!(kept, 0, "a spinning cube kept A across {kept} steps");
}

/// A converged step takes its moving points' mean residual out of their velocities only where
/// a shift of them all changes no force: a cube in free flight is shifted by it; one pinned,
/// pulled, in a field that varies in space, or pressed into a floor (at the step's start or
/// at its end) is not, and clear of the floor it is again.
#[test]
fn the_momentum_shift_is_taken_only_where_nothing_outside_holds_the_points() {
    let h = 0.01;
    let model = |builder: ModelBuilder| {
        let cube = Body::lattice_box(
            Lattice::new([3, 3, 3], Vec3::new(1.0, 1.0, 1.0)),
            Material::classic(),
        );
        (builder.bodies(vec![cube]).dt(h))
            .integrator(Integrator::BackwardEuler)
            .build()
            .unwrap()
    };
    let mean = Vec3::new(1e-10, -2e-10, 3e-10);
    // The shift with every point's residual `mean`, the cube raised by `lift` and moving at
    // `v` (its end `h·v` further).
    let shift = |model: &Model, control: &Control, lift: f64, v: Vec3| {
        let mut s = ImplicitScratch::new(model);
        s.load(model);
        s.g.fill(mean);
        s.v.fill(v);
        let at = crate::State::at_rest(model).pos;
        let x0: Vec<Vec3> = at.iter().map(|&p| p + Vec3::new(0.0, 0.0, lift)).collect();
        momentum_shift(model, control, &s, &x0, h)
    };
    let none = Control::none();
    let shifted = |got: Vec3| (got - mean).max_abs() < 1e-24;
    assert!(shifted(shift(
        &model(ModelBuilder::new()),
        &none,
        0.0,
        Vec3::ZERO
    )));
    let pinned = model(ModelBuilder::new().pins([0]));
    assert_eq!(shift(&pinned, &none, 0.0, Vec3::ZERO), Vec3::ZERO);
    let pull = crate::state::Pull {
        point: 13,
        target: Vec3::new(0.5, 0.5, 2.0),
        stiffness: 10.0,
        damping: 0.0,
    };
    let pulled = Control {
        pulls: vec![pull],
        ..Control::none()
    };
    assert_eq!(
        shift(&model(ModelBuilder::new()), &pulled, 0.0, Vec3::ZERO),
        Vec3::ZERO
    );
    let box_ = Aabb::new(Vec3::new(-2.0, -2.0, -2.0), Vec3::new(2.0, 2.0, 2.0)).unwrap();
    let field = |f: fn(Vec3) -> Vec3| Some(ForceField::from_fn(3, box_, f).unwrap());
    let uniform = model(ModelBuilder::new().field(field(|_| Vec3::new(0.0, 0.0, -1.0))));
    assert!(shifted(shift(&uniform, &none, 0.0, Vec3::ZERO)));
    let varying = model(ModelBuilder::new().field(field(|p| Vec3::new(-p.y, p.x, 0.0))));
    assert_eq!(shift(&varying, &none, 0.0, Vec3::ZERO), Vec3::ZERO);
    // A floor 1 mm above the cube's bottom face.
    let floor =
        model(ModelBuilder::new().plane(Some(crate::Plane::new([0.0, 0.0, 1.0, -1e-3]).unwrap())));
    assert_eq!(shift(&floor, &none, 0.0, Vec3::ZERO), Vec3::ZERO);
    assert!(shifted(shift(&floor, &none, 1.0, Vec3::ZERO)));
    // Clear of it at the start, into it at the end (falling 1 m in the step), and the reverse.
    let falling = Vec3::new(0.0, 0.0, -100.0);
    assert_eq!(shift(&floor, &none, 0.5, falling), Vec3::ZERO);
    assert_eq!(shift(&floor, &none, 0.0, -falling), Vec3::ZERO);
}

/// With a swirling field's exact gradient in it, `A` is `M·∂g/∂v`: `A·d` matches the central
/// difference of `M·g` along `d`, at a lattice stretched and turned so that its springs'
/// transverse stiffness matters, in a field that is neither linear nor a gradient.
#[test]
fn a_with_the_swirl_is_the_derivative_of_the_residual() {
    let box_ = Aabb::new(Vec3::new(-2.0, -2.0, -2.0), Vec3::new(2.0, 2.0, 2.0)).unwrap();
    let swirl = |p: Vec3| Vec3::new(-p.y, p.x + 0.5 * p.z * p.z, p.x * p.y) * 12.0;
    let field = ForceField::from_fn(9, box_, swirl).unwrap();
    let body = Body::lattice_box(
        Lattice::new([4, 3, 3], Vec3::new(0.9, 0.6, 0.6)),
        Material::classic(),
    );
    let h = 1.0 / 60.0;
    let model = ModelBuilder::new()
        .bodies(vec![body])
        .field(Some(field))
        .dt(h)
        .pins([5])
        .build()
        .unwrap();
    let mut next = values(11);
    let mut random = || Vec3::new(next(), next(), next());
    let x0: Vec<Vec3> = crate::State::at_rest(&model)
        .pos
        .iter()
        .map(|&p| Vec3::new(p.x * 1.3 - 0.4, p.y - 0.1 * p.z, p.z + 0.2 * p.x))
        .collect();
    let v: Vec<Vec3> = (0..x0.len()).map(|_| random() * 2.0).collect();
    let d: Vec<Vec3> = (0..x0.len()).map(|_| random()).collect();
    let (control, mut force) = (Control::none(), ForceScratch::new(&model));
    let mut s = scratch_at(&model, &x0);
    let mut m_g = |s: &mut ImplicitScratch, v: &[Vec3]| {
        residual_at(&model, &control, &mut force, s, (&x0, &x0), v, h);
        (s.g.iter().zip(&s.mass))
            .map(|(&g, &m)| g * m)
            .collect::<Vec<_>>()
    };
    let eps = 1e-6;
    let along = |sign: f64| -> Vec<Vec3> {
        v.iter()
            .zip(&d)
            .map(|(&v, &d)| v + d * (sign * eps))
            .collect()
    };
    let (up, down) = (m_g(&mut s, &along(1.0)), m_g(&mut s, &along(-1.0)));
    m_g(&mut s, &v);
    s.swirl_allowed = true;
    assemble(
        &model,
        &control,
        force.anchors(),
        &mut s,
        &x0,
        h,
        Curvature::True { shift: 0.0 },
    );
    assert!(
        s.swirl,
        "the field should swirl past the limit at this step"
    );
    let mut ad = vec![Vec3::ZERO; d.len()];
    let correction = Some(&s.field_correction[..]);
    let pairs = (&s.pair_rows[..], &s.pair_blocks[..]);
    apply_to(
        &mut s.springs,
        &s.free,
        pairs.0,
        pairs.1,
        (correction, &[]),
        &d,
        &mut ad,
        Precision::Double,
    );
    let scale = ad.iter().map(|a| a.max_abs()).fold(0.0, f64::max);
    for (p, ((&a, &u), &w)) in ad.iter().zip(&up).zip(&down).enumerate() {
        let difference = (u - w) / (2.0 * eps) * s.free[p];
        let off = (a - difference).max_abs();
        assert!(
            off <= 1e-6 * scale,
            "point {p}: A·d {a:?}, difference {difference:?}"
        );
    }
    // Without the swirl's correction, A·d misses it by far more.
    apply_to(
        &mut s.springs,
        &s.free,
        pairs.0,
        pairs.1,
        (None, &[]),
        &d,
        &mut ad,
        Precision::Double,
    );
    let worst = ad
        .iter()
        .zip(up.iter().zip(&down))
        .zip(&s.free)
        .map(|((&a, (&u, &w)), &f)| (a - (u - w) / (2.0 * eps) * f).max_abs())
        .fold(0.0, f64::max);
    assert!(worst > 1e-3 * scale, "{worst} against {scale}");
}

/// The conjugate gradients of the usual solves, with their vectors in single precision, reach
/// the reduction they are asked for in `A·Δv = −M·g` itself (its residual computed afresh in
/// double precision, not the solve's own), and take the same iterations to the same bits on
/// any number of threads: a 16³ lattice (two ranges of rows on two threads) with random
/// positions and velocities, two held points.
#[test]
fn single_precision_solves_reach_their_reduction_with_the_same_bits_on_any_number_of_threads() {
    let model = ModelBuilder::new()
        .bodies(vec![test_models::box_at([16, 16, 16], Vec3::ZERO)])
        .pins(vec![0, 5])
        .build()
        .unwrap();
    let n = model.point_count();
    let h = 0.01;
    let mut next = values(31);
    let x0: Vec<Vec3> = crate::State::at_rest(&model)
        .pos
        .iter()
        .map(|&p| p + Vec3::new(next(), next(), next()) * 0.05)
        .collect();
    let v: Vec<Vec3> = (0..n).map(|_| Vec3::new(next(), next(), next())).collect();
    let solve_on = |threads: usize| {
        test_models::on_threads(threads, || {
            let (control, mut force) = (Control::none(), ForceScratch::new(&model));
            let mut s = scratch_at(&model, &x0);
            residual_at(&model, &control, &mut force, &mut s, (&x0, &v), &v, h);
            // Positive definite: the compressed springs' negative stiffness clamped.
            let curvature = Curvature::Clamped;
            assemble(&model, &control, force.anchors(), &mut s, &x0, h, curvature);
            s.within = 0.0;
            let reduction = 1e-3;
            assert_eq!(precision_for(reduction), Precision::Single);
            assert!(cg::solve(&mut s, reduction, cg::Preconditioner::Multigrid));
            // `−M·g − A·Δv`, `A` in double precision.
            let b: Vec<Vec3> = (0..n).map(|p| s.g[p] * (-s.mass[p] * s.free[p])).collect();
            let mut a_dv = vec![Vec3::ZERO; n];
            let (pairs, blocks) = (s.pair_rows.clone(), s.pair_blocks.clone());
            let (free, dv) = (s.free.clone(), s.dv.clone());
            apply_to(
                &mut s.springs,
                &free,
                &pairs,
                &blocks,
                (None, &[]),
                &dv,
                &mut a_dv,
                Precision::Double,
            );
            let norm = |r: &dyn Fn(usize) -> Vec3| {
                (0..n).map(|p| r(p).length_squared()).sum::<f64>().sqrt()
            };
            let fell = norm(&|p| b[p] - a_dv[p]) / norm(&|p| b[p]);
            (s.dv, s.stats.linear_iterations, fell)
        })
    };
    let (dv, iterations, fell) = solve_on(1);
    assert!(
        iterations >= 5,
        "{iterations} iterations: not a test of the solve"
    );
    assert!(
        fell <= 1.1e-3,
        "the residual fell to {fell:e} of itself, not 1e-3"
    );
    assert!(dv.iter().all(|d| d.is_finite()) && dv[0] == Vec3::ZERO && dv[5] == Vec3::ZERO);
    for threads in [2, 3, 8] {
        let (other, other_iterations, _) = solve_on(threads);
        assert_eq!(other_iterations, iterations, "{threads} threads");
        assert!(other == dv, "{threads} threads: other bits");
    }
}

/// A multigrid cycle that the conjugate gradients find not positive definite (its coarse levels
/// over-relaxed past what their Jacobi sweeps bear) is retried damped, on the same `A`, before
/// anything else: `solve_multigrid`, which a kept `A` and a new one both solve through.
#[test]
fn a_cycle_found_not_positive_definite_is_retried_damped() {
    let model = ModelBuilder::new()
        .bodies(vec![test_models::box_at([16, 16, 16], Vec3::ZERO)])
        .build()
        .unwrap();
    let n = model.point_count();
    let h = 0.01;
    let mut next = values(41);
    let x0 = crate::State::at_rest(&model).pos;
    let v: Vec<Vec3> = (0..n).map(|_| Vec3::new(next(), next(), next())).collect();
    let (control, mut force) = (Control::none(), ForceScratch::new(&model));
    let mut s = scratch_at(&model, &x0);
    residual_at(&model, &control, &mut force, &mut s, (&x0, &v), &v, h);
    assemble(
        &model,
        &control,
        force.anchors(),
        &mut s,
        &x0,
        h,
        Curvature::True { shift: 0.0 },
    );
    s.within = 0.0;
    // Jacobi at 3 diverges on every level: `D⁻¹A`'s eigenvalues average 1, so its largest is 1
    // or more, and the sweep stays convergent only while `ω·λ_max < 2`.
    s.multigrid.start_step(false);
    s.multigrid.over_relax_by(3.0);
    assert!(!cg::solve(&mut s, 1e-3, cg::Preconditioner::Multigrid));
    assert!(s.multigrid_failed, "the cycle, not A, found indefinite");
    s.multigrid.start_step(false);
    assert!(solve_multigrid(&mut s, 1e-3), "solved damped");
    assert!(!s.multigrid_failed);
    assert_eq!(s.multigrid.omega(), 0.9, "damped for the rest of the step");
    assert!(s.dv.iter().all(|d| d.is_finite()));
}

/// A residual at rest (every velocity zero) computes neither the springs' dampers
/// (`Dampers::AtRest`) nor friction (`PointInputs::friction`): its force pass gives the same
/// accelerations as the pass with the dampers along their start directions at zero velocities,
/// and as an explicit step's pass at zero velocities (its friction slides at zero speed: none),
/// on a body with holes and one with per-spring factors, pressed into a wall and a plane, both
/// with friction.
#[test]
fn a_pass_at_rest_leaves_out_only_forces_that_are_zero() {
    use crate::compute::soa::Soa;
    use crate::forces::{force_pass_with, Ties};
    use crate::model::obstacle::{Obstacle, Plane};
    let big = Aabb::new(Vec3::new(0.3, -50.0, -50.0), Vec3::new(50.0, 50.0, 50.0)).unwrap();
    let floor = Plane::facing([0.0, 0.0, 1.0, -0.3], Vec3::new(0.0, 0.0, 10.0)).unwrap();
    let mut next = values(31);
    let model = ModelBuilder::new()
        .bodies(test_models::holes_and_factors(&mut next))
        .bounds(big)
        .obstacle(Obstacle::Plane(floor))
        .collision(400.0, 0.25)
        .friction(0.5)
        .wall_friction(0.5)
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .build()
        .unwrap();
    let n = model.point_count();
    let at = |scale: f64, next: &mut dyn FnMut() -> f64| -> Vec<Vec3> {
        let rest = crate::State::at_rest(&model).pos;
        let moved = rest
            .iter()
            .map(|&p| p + Vec3::new(next(), next(), next()) * scale);
        moved.collect()
    };
    let (x, start) = (at(0.2, &mut next), at(0.2, &mut next));
    let pressed = |p: &Vec3| p.x < 0.3 || p.z < 0.3;
    let (pressed, all) = (x.iter().filter(|p| pressed(p)).count(), x.len());
    assert!(
        pressed > 10 && pressed < all - 10,
        "{pressed} of {all} points pressed"
    );
    let (p, zero, start) = (Soa::from_aos(&x), Soa::zeros(n), Soa::from_aos(&start));
    let control = Control::none();
    let pass = |ties: Ties| {
        let mut a = Soa::zeros(n);
        let copy = |_, out: [&mut [f64]; 3], a: [&[f64]; 3]| {
            for (o, a) in out.into_iter().zip(a) {
                o.copy_from_slice(&a[..o.len()]);
            }
            true
        };
        let mut scratch = ForceScratch::new(&model);
        force_pass_with(
            &model,
            &p,
            &zero,
            &control,
            &mut scratch,
            a.parts_mut(),
            &copy,
            ties,
        );
        let mut out = vec![Vec3::ZERO; n];
        a.copy_to(&mut out);
        out
    };
    let at_rest = pass(Ties::Ignored {
        start: &start,
        velocity: None,
    });
    let at_start = pass(Ties::Ignored {
        start: &start,
        velocity: Some(&zero),
    });
    let held = pass(Ties::Held);
    for (i, ((r, s), h)) in at_rest.iter().zip(&at_start).zip(&held).enumerate() {
        // `==`: the same bits but for the signs of zeros.
        assert!(r == s && r == h, "point {i}: {r:?}, {s:?}, {h:?}");
    }
    assert!(
        at_rest.iter().any(|a| a.max_abs() > 100.0),
        "the springs pull"
    );
}

/// `max_norms` is the largest `|g|` and `|v|`, to the bit, wherever the largest is among the
/// lanes and the remainder, NaN counting as none.
#[test]
fn max_norms_are_the_largest_lengths() {
    let mut next = values(41);
    for n in [0, 1, 7, 8, 9, 31, 100, 5000] {
        let mut g: Vec<Vec3> = (0..n).map(|_| Vec3::new(next(), next(), next())).collect();
        let v: Vec<Vec3> = (0..n)
            .map(|_| Vec3::new(next(), next(), next()) * 3.0)
            .collect();
        if n > 2 {
            g[1] = Vec3::new(f64::NAN, 0.0, 0.0);
        }
        let largest = |x: &[Vec3]| x.iter().map(|x| x.length()).fold(0.0, f64::max);
        let want = (largest(&g), largest(&v));
        assert_eq!(max_norms(&g, &v), want, "{n} points");
        if n > 0 {
            let last = n - 1;
            g[last] = Vec3::new(0.0, 9.0, 0.0);
            assert_eq!(max_norms(&g, &v).0, 9.0, "{n} points, the last the largest");
        }
    }
}

/// The single-precision solvers' products read the springs' blocks in 16 bits from
/// `PACKED_FROM` points on (a 26³ cube, 17 576 points; not a 24³ one, 13 824), and not where the
/// model's field swirls past the limit at the step (`stencil/packed.rs`).
#[test]
fn products_in_16_bits_only_for_large_lattices_without_a_swirl() {
    let box_ = Aabb::new(Vec3::new(-2.0, -2.0, -2.0), Vec3::new(2.0, 2.0, 2.0)).unwrap();
    let turning = |c: f64| ForceField::from_fn(5, box_, move |p| Vec3::new(-p.y, p.x, 0.0) * c);
    let packs = |n: usize, swirl: f64| {
        let body = Body::lattice_box(
            Lattice::new([n; 3], Vec3::new(0.04, 0.04, 0.04)),
            Material::classic(),
        );
        let model = ModelBuilder::new().bodies(vec![body]).dt(1.0 / 60.0);
        let mut model = model.field(Some(turning(swirl).unwrap())).build().unwrap();
        // Whether or not the step converges, the products are chosen at its start: one
        // iteration is enough.
        model.newton.max_iterations = 1;
        let state = crate::State::at_rest(&model);
        let (control, mut force) = (Control::none(), ForceScratch::new(&model));
        let mut s = ImplicitScratch::new(&model);
        let (mut pos, mut vel) = (state.pos.clone(), state.vel.clone());
        let h = model.dt;
        let _ = step(
            &model, &state, &control, &mut force, &mut s, h, &mut pos, &mut vel,
        );
        (s.springs.packs_products(), can_swirl(&model, h))
    };
    // Twice the swirl at the limit, for the classic point mass (1/512 kg).
    let past_limit = 2.0 * SWIRL_LIMIT / 512.0 * 3600.0;
    assert_eq!(packs(26, 0.0), (true, false));
    assert_eq!(packs(24, 0.0), (false, false));
    assert_eq!(packs(26, past_limit), (false, true));
}

/// The multigrid's coarse levels are smoothed over-relaxed, but where the step's field swirls
/// (see `OMEGA_DAMPED`), chosen at each step's start.
#[test]
fn the_coarse_smoother_is_over_relaxed_unless_a_field_swirls() {
    let box_ = Aabb::new(Vec3::new(-2.0, -2.0, -2.0), Vec3::new(2.0, 2.0, 2.0)).unwrap();
    let turning = |c: f64| ForceField::from_fn(5, box_, move |p| Vec3::new(-p.y, p.x, 0.0) * c);
    let body = Body::lattice_box(
        Lattice::new([8; 3], Vec3::new(0.04, 0.04, 0.04)),
        Material::classic(),
    );
    let mut s = None;
    // Twice the swirl at the limit, for the classic point mass (1/512 kg), then none.
    for swirl in [2.0 * SWIRL_LIMIT / 512.0 * 3600.0, 0.0] {
        let model = ModelBuilder::new()
            .bodies(vec![body.clone()])
            .dt(1.0 / 60.0);
        let mut model = model.field(Some(turning(swirl).unwrap())).build().unwrap();
        model.newton.max_iterations = 1;
        let state = crate::State::at_rest(&model);
        let (control, mut force) = (Control::none(), ForceScratch::new(&model));
        // One scratch for both models: the weight follows the step, not the scratch's history.
        let s = s.get_or_insert_with(|| ImplicitScratch::new(&model));
        let (mut pos, mut vel) = (state.pos.clone(), state.vel.clone());
        let _ = step(
            &model, &state, &control, &mut force, s, model.dt, &mut pos, &mut vel,
        );
        let want = if swirl > 0.0 { 0.9 } else { 1.2 };
        assert_eq!(s.multigrid.omega(), want, "swirl {swirl}");
        assert_eq!(can_swirl(&model, model.dt), swirl > 0.0);
    }
}
