//! The implicit integrators (backward Euler and SDIRK2, `jello_core::integrate::implicit`): their
//! recurrences in closed form, stability far past the explicit limit, energy, convergence order,
//! momentum, threads, and the report of a step that does not converge.

mod common;

use common::{max_diff, stacked_cubes, Lcg as Rng};
use jello_core::diagnostics::{energy, momentum};
use jello_core::integrate::implicit::{SDIRK2_C, SDIRK2_GAMMA};
use jello_core::integrate::stability::stable_dt;
use jello_core::Newton;
use jello_core::{
    step, Aabb, BlowUpCause, Body, Control, ForceField, Integrator, Lattice, Material, Model,
    ModelBuilder, Obstacle, Plane, Scratch, State, Vec3,
};

fn far_walls() -> Aabb {
    Aabb::new(Vec3::new(-50.0, -50.0, -50.0), Vec3::new(50.0, 50.0, 50.0)).unwrap()
}

/// Two points joined by one spring of rest length `rest` along x.
fn dumbbell(rest: f64, material: Material, dt: f64, integrator: Integrator) -> Model {
    let body = Body::lattice_box(Lattice::new([2, 1, 1], Vec3::new(rest, 1.0, 1.0)), material);
    ModelBuilder::new()
        .bodies(vec![body])
        .bounds(far_walls())
        .dt(dt)
        .integrator(integrator)
        .build()
        .unwrap()
}

/// One step of each implicit method on the linear oscillator `s'' = −ω²s − γs'` (stretch `s`,
/// speed `r`): backward Euler is `r₁ = (r₀ − hω²s₀)/(1 + hγ + h²ω²)`, `s₁ = s₀ + h r₁`; SDIRK2
/// is two such steps of size `γ_S·h`, the second from `y₀ + c·(Y₁ − y₀)`.
fn oscillator_step(
    integrator: Integrator,
    (s, r): (f64, f64),
    w2: f64,
    gamma: f64,
    h: f64,
) -> (f64, f64) {
    let backward_euler = |(s, r): (f64, f64), k: f64| {
        let r1 = (r - k * w2 * s) / (1.0 + k * gamma + k * k * w2);
        (s + k * r1, r1)
    };
    match integrator {
        Integrator::BackwardEuler => backward_euler((s, r), h),
        Integrator::Sdirk2 => {
            let k = SDIRK2_GAMMA * h;
            let (s1, r1) = backward_euler((s, r), k);
            backward_euler((s + SDIRK2_C * (s1 - s), r + SDIRK2_C * (r1 - r)), k)
        }
        other => unreachable!("{other} is not implicit"),
    }
}

/// A damped spring moving along its axis is linear, so each method follows its recurrence
/// ([`oscillator_step`]) on the stretch and the stretching speed, with `ω² = 2k/m`,
/// `γ = 2d/m`; the centre of mass moves uniformly. At a step of 0.05 s, five times the
/// oscillator's period over 2π.
#[test]
fn a_damped_spring_follows_each_methods_recurrence() {
    let (k, d, m, rest, h) = (40.0, 0.3, 0.1, 0.5, 0.05);
    let material = Material {
        mass: m,
        stiffness: [k; 3],
        damping: [d; 3],
    };
    for integrator in [Integrator::BackwardEuler, Integrator::Sdirk2] {
        let model = dumbbell(rest, material, h, integrator);
        let mut state = State::new(
            vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(rest + 0.1, 0.0, 0.0)],
            vec![Vec3::new(0.3, 0.0, 0.0), Vec3::new(-0.2, 0.0, 0.0)],
        );
        let (w2, gamma) = (2.0 * k / m, 2.0 * d / m);
        let mut y = (0.1, -0.5);
        let centre = |st: &State| (st.pos[0].x + st.pos[1].x) * 0.5;
        let c0 = centre(&state);
        let mut scratch = Scratch::new(&model);
        for n in 1..=100 {
            step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
            y = oscillator_step(integrator, y, w2, gamma, h);
            let stretch = state.pos[1].x - state.pos[0].x - rest;
            let speed = state.vel[1].x - state.vel[0].x;
            assert!(
                (stretch - y.0).abs() < 1e-9,
                "{integrator} step {n}: stretch {stretch} vs {}",
                y.0
            );
            assert!(
                (speed - y.1).abs() < 1e-8,
                "{integrator} step {n}: speed {speed} vs {}",
                y.1
            );
            let drift = centre(&state) - (c0 + 0.05 * h * n as f64);
            assert!(
                drift.abs() < 1e-12,
                "{integrator} step {n}: centre off by {drift}"
            );
        }
    }
}

/// Two bars of two points, each a body moving as one (so that its own spring stays at rest),
/// side by side with their balls overlapping along y and pressed together: each pair of
/// points in contact is a damped penalty spring, so the overlap `s` follows each method's
/// recurrence with `ω² = 2kc/m`, `γ = 2dc/m` for as long as it lasts. Without the contacts'
/// dampers between bodies in the implicit step (until 2026-11-28) the overlap followed the
/// undamped recurrence instead.
#[test]
fn bodies_pressed_together_follow_each_methods_recurrence() {
    let (kc, dc, m) = (100.0, 5.0, 1.0);
    let material = Material {
        mass: m,
        stiffness: [50.0; 3],
        damping: [0.5; 3],
    };
    let bar = || Body::lattice_box(Lattice::new([2, 1, 1], Vec3::new(1.0, 1.0, 1.0)), material);
    for integrator in [Integrator::BackwardEuler, Integrator::Sdirk2] {
        for h in [0.01, 1.0 / 60.0] {
            let model = ModelBuilder::new()
                .bodies(vec![bar(), bar()])
                .bounds(far_walls())
                .collision(kc, dc)
                .integrator(integrator)
                .dt(h)
                .build()
                .unwrap();
            // Balls of radius 0.5: the bars overlap by 0.1 and close at 1 m/s.
            let (low, high) = (Vec3::new(0.0, 0.5, 0.0), Vec3::new(0.0, -0.5, 0.0));
            let mut state = State::new(
                vec![
                    Vec3::new(0.0, 0.0, 0.0),
                    Vec3::new(1.0, 0.0, 0.0),
                    Vec3::new(0.0, 0.9, 0.0),
                    Vec3::new(1.0, 0.9, 0.0),
                ],
                vec![low, low, high, high],
            );
            let (w2, gamma) = (2.0 * kc / m, 2.0 * dc / m);
            let mut y = (0.1, 1.0);
            let mut scratch = Scratch::new(&model);
            let mut steps = 0;
            // While the pair overlaps at both ends of the step.
            while oscillator_step(integrator, y, w2, gamma, h).0 > 0.0 {
                step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
                y = oscillator_step(integrator, y, w2, gamma, h);
                steps += 1;
                for (a, b) in [(0, 2), (1, 3)] {
                    let overlap = 1.0 - (state.pos[b].y - state.pos[a].y);
                    let closing = state.vel[a].y - state.vel[b].y;
                    let at = format!("{integrator}, h {h}, step {steps}, pair {a}–{b}");
                    assert!((overlap - y.0).abs() < 1e-9, "{at}: {overlap} vs {}", y.0);
                    assert!((closing - y.1).abs() < 1e-8, "{at}: {closing} vs {}", y.1);
                }
            }
            assert!(
                steps >= 8,
                "{integrator}, h {h}: only {steps} steps in contact"
            );
        }
    }
}

/// A point tied by friction to a floor is held across the normal by a spring of the collision
/// stiffness and a damper of the collision damping: a bar of two points resting on a floor
/// (their depth bearing their weight), tied where it rests and then pushed along it at
/// 0.5 m/s, within the friction cone all along, follows each method's recurrence with
/// `ω² = kc/m`, `γ = dc/m`. Without the tie's damper in the implicit step (until 2026-11-28)
/// it followed the undamped recurrence instead.
#[test]
fn a_bar_tied_to_a_floor_follows_each_methods_recurrence() {
    let (kc, dc, m, g, mu) = (1000.0, 8.0, 1.0, 9.81, 5.0);
    let material = Material {
        mass: m,
        stiffness: [50.0; 3],
        damping: [0.5; 3],
    };
    let bar = Body::lattice_box(Lattice::new([2, 1, 1], Vec3::new(1.0, 1.0, 1.0)), material);
    let floor = Plane::facing([0.0, 0.0, 1.0, 0.0], Vec3::new(0.0, 0.0, 1.0)).unwrap();
    for integrator in [Integrator::BackwardEuler, Integrator::Sdirk2] {
        for h in [0.01, 1.0 / 60.0] {
            let model = ModelBuilder::new()
                .bodies(vec![bar.clone()])
                .bounds(far_walls())
                .obstacle(Obstacle::Plane(floor))
                .collision(kc, dc)
                .friction(mu)
                .gravity(Vec3::new(0.0, 0.0, -g))
                .integrator(integrator)
                .dt(h)
                .build()
                .unwrap();
            let depth = m * g / kc;
            let mut state = State::new(
                vec![Vec3::new(0.0, 0.0, -depth), Vec3::new(1.0, 0.0, -depth)],
                vec![Vec3::ZERO; 2],
            );
            let mut scratch = Scratch::new(&model);
            // At rest, one step ties the points where they are.
            step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
            let anchors = [state.pos[0].x, state.pos[1].x];
            state.vel.fill(Vec3::new(0.5, 0.0, 0.0));
            let (w2, gamma) = (kc / m, dc / m);
            let mut y = (0.0, 0.5);
            for n in 1..=60 {
                step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
                y = oscillator_step(integrator, y, w2, gamma, h);
                for (p, anchor) in anchors.iter().enumerate() {
                    let (offset, speed) = (state.pos[p].x - anchor, state.vel[p].x);
                    let at = format!("{integrator}, h {h}, step {n}, point {p}");
                    assert!((offset - y.0).abs() < 1e-9, "{at}: {offset} vs {}", y.0);
                    assert!((speed - y.1).abs() < 1e-8, "{at}: {speed} vs {}", y.1);
                    assert!(
                        (state.pos[p].z + depth).abs() < 1e-9,
                        "{at}: left the floor"
                    );
                }
                // Within the cone (the closed form holds only there).
                assert!(kc * y.0.abs() + dc * y.1.abs() < 0.5 * mu * m * g);
            }
        }
    }
}

/// Friction between bodies, as the model has it: against the sliding velocity, of size `μ`
/// times the normal force but never more than a damper of the pair's reduced mass over the step
/// (see `friction::sliding`; the step here is shorter than the contact's own time, so the
/// implicit integrators' cap is that too: `friction::implicit_cap`). A bar of two points lies on a held one (each of its points on one
/// of the other's balls, its depth bearing its weight) and slides across it at 0.5 m/s: each
/// backward-Euler step takes `μ·g·h` off its speed while that leaves more than `2μgh` (the
/// friction at its full size, below the cap), then a third of its speed (at the cap, the
/// reduced mass `m/2`: `v₁ = v₀ − (h/m)·(m/2h)·v₁`), each within 0.5 %. Without
/// friction between bodies in the implicit step (until 2026-11-28) it slid on at 0.5 m/s. The
/// balls are large (radius 10 m) so that the bar's 3 cm of sliding barely tilts their contact
/// (the test adds the little that does to the closed form).
#[test]
fn a_bar_sliding_on_another_is_slowed_by_their_friction() {
    let (kc, m, g, mu, h) = (1000.0, 1.0, 9.81, 0.5, 1.0 / 60.0);
    let material = Material {
        mass: m,
        stiffness: [50.0; 3],
        damping: [0.5; 3],
    };
    let bar = || Body::lattice_box(Lattice::new([2, 1, 1], Vec3::new(20.0, 1.0, 1.0)), material);
    let model = ModelBuilder::new()
        .bodies(vec![bar(), bar()])
        .pins([0, 1])
        .bounds(far_walls())
        .collision(kc, 5.0)
        .friction(mu)
        .gravity(Vec3::new(0.0, 0.0, -g))
        .integrator(Integrator::BackwardEuler)
        .dt(h)
        .build()
        .unwrap();
    let top = 20.0 - m * g / kc;
    let mut state = State::new(
        vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(20.0, 0.0, 0.0),
            Vec3::new(0.0, 0.0, top),
            Vec3::new(20.0, 0.0, top),
        ],
        vec![
            Vec3::ZERO,
            Vec3::ZERO,
            Vec3::new(0.0, 0.5, 0.0),
            Vec3::new(0.0, 0.5, 0.0),
        ],
    );
    let mut scratch = Scratch::new(&model);
    let (fall, mut capped) = (mu * g * h, 0);
    for n in 1..=12 {
        let before = state.vel[2].y;
        step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
        // The contact's normal tilts by y/20 (the sum of the radii) from the top of the lower
        // ball, and the normal force, about the weight, pushes the bar on by g·y/20 (at the
        // step's end, where backward Euler takes the forces).
        let push = g * h * state.pos[2].y / 20.0;
        let expected = if before - fall > 2.0 * fall {
            before + push - fall
        } else {
            capped += 1;
            (before + push) * 2.0 / 3.0
        };
        for p in [2, 3] {
            let v = state.vel[p];
            assert!(
                (v.y - expected).abs() < 0.005 * (before - expected) && v.x.abs() < 1e-9,
                "step {n}, point {p}: {v:?}, expected {expected} m/s along y"
            );
        }
    }
    assert!(capped >= 6, "the cap bound at {capped} steps only");
}

/// A body resting on another on a slope below the friction angle creeps, at large steps too, as
/// slowly as where an explicit step resolves the contact: the sliding friction's cap between
/// bodies is the pair's reduced mass over the contact's own time `√(m_r/kc)` where that is
/// shorter than the step (`friction::implicit_cap`). A light bar (10 g a point) on a held one,
/// their contacts stiff (`√(m_r/kc)` = 1.1 ms), gravity tilted by 15° (μ = 0.5): at 1/60 s the
/// bar settles at the speed where the cap's damper carries the load, `2·g·sin θ·√(m_r/kc)`,
/// about 5.7 mm/s, within 1 %; with the cap over dt it slid at `2·g·sin θ·dt`, 85 mm/s.
#[test]
fn a_body_on_another_on_a_slope_creeps_as_slowly_at_large_steps() {
    let (kc, m, g, mu, h) = (4000.0, 0.01, 9.81, 0.5, 1.0 / 60.0);
    let theta: f64 = 15f64.to_radians();
    let material = Material {
        mass: m,
        stiffness: [50.0; 3],
        damping: [0.05; 3],
    };
    // Large balls (radius 100 m), so that the bar's creep does not tilt their contact.
    let spacing = 200.0;
    let bar = || {
        let size = Vec3::new(spacing, 1.0, 1.0);
        Body::lattice_box(Lattice::new([2, 1, 1], size), material)
    };
    let model = ModelBuilder::new()
        .bodies(vec![bar(), bar()])
        .pins([0, 1])
        .bounds(
            Aabb::new(
                Vec3::new(-500.0, -500.0, -500.0),
                Vec3::new(500.0, 500.0, 500.0),
            )
            .unwrap(),
        )
        .collision(kc, 1.0)
        .friction(mu)
        .gravity(Vec3::new(0.0, g * theta.sin(), -g * theta.cos()))
        .integrator(Integrator::BackwardEuler)
        .dt(h)
        .build()
        .unwrap();
    let top = spacing - m * g * theta.cos() / kc;
    let mut state = State::new(
        vec![
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(spacing, 0.0, 0.0),
            Vec3::new(0.0, 0.0, top),
            Vec3::new(spacing, 0.0, top),
        ],
        vec![Vec3::ZERO; 4],
    );
    let mut scratch = Scratch::new(&model);
    for _ in 0..30 {
        step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
    }
    let creep = 2.0 * g * theta.sin() * (0.5 * m / kc).sqrt();
    for p in [2, 3] {
        let v = state.vel[p];
        assert!(
            (v.y - creep).abs() < 0.01 * creep,
            "point {p}: {v:?}, expected a creep of {creep} m/s along y"
        );
    }
}

/// A stiff undamped spring at 100 times RK4's stable step: RK4 blows up; each implicit method
/// keeps the stretch bounded and the energy from ever growing, and damps the stiff mode away
/// (L-stable).
#[test]
fn a_stiff_spring_far_past_the_explicit_limit_stays_bounded() {
    let material = Material {
        mass: 1e-3,
        stiffness: [1e6; 3],
        damping: [0.0; 3],
    };
    let limit = stable_dt(
        &dumbbell(0.5, material, 1e-3, Integrator::Rk4),
        Integrator::Rk4,
    );
    let h = 100.0 * limit;
    let start = State::new(
        vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(0.55, 0.0, 0.0)],
        vec![Vec3::ZERO; 2],
    );
    let rk4 = dumbbell(0.5, material, h, Integrator::Rk4);
    let mut state = start.clone();
    let mut scratch = Scratch::new(&rk4);
    let blew_up = (0..200).any(|_| step(&rk4, &mut state, &Control::none(), &mut scratch).is_err());
    assert!(blew_up, "RK4 at 100× its limit blows up");

    for integrator in [Integrator::BackwardEuler, Integrator::Sdirk2] {
        let model = dumbbell(0.5, material, h, integrator);
        let mut state = start.clone();
        let mut scratch = Scratch::new(&model);
        let e0 = energy(&model, &state).total();
        let mut last = e0;
        for _ in 0..500 {
            step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
            let stretch = (state.pos[1].x - state.pos[0].x - 0.5).abs();
            assert!(stretch <= 0.05 + 1e-12, "{integrator}: stretch {stretch}");
            let e = energy(&model, &state).total();
            assert!(
                e <= last + 1e-12 * e0,
                "{integrator}: energy rose from {last} to {e}"
            );
            last = e;
        }
        assert!(
            last < 1e-3 * e0,
            "{integrator}: the stiff mode is damped away: {last} of {e0}"
        );
    }
}

/// With no field, no gravity and no outside force, the energy never rises above its start,
/// at frame-rate steps, while the cube tumbles and hits a wall.
#[test]
fn energy_never_rises_without_outside_work() {
    for (integrator, dt) in [
        (Integrator::BackwardEuler, 0.01),
        (Integrator::BackwardEuler, 1.0 / 60.0),
        (Integrator::Sdirk2, 0.01),
        (Integrator::Sdirk2, 1.0 / 60.0),
    ] {
        let model = ModelBuilder::new()
            .integrator(integrator)
            .dt(dt)
            .build()
            .unwrap();
        let mut rng = Rng(5);
        let mut state = State::at_rest(&model);
        for (p, v) in state.pos.iter_mut().zip(state.vel.iter_mut()) {
            *p += rng.vec3() * 0.03 - Vec3::new(0.5, 0.5, 0.5);
            *v = Vec3::new(3.0, -1.0, 2.0) + rng.vec3() * 0.5;
        }
        let start = energy(&model, &state).total();
        let mut scratch = Scratch::new(&model);
        let mut touched = false;
        for _ in 0..300 {
            step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
            let e = energy(&model, &state);
            touched |= e.collision > 0.0;
            assert!(
                e.total() <= start,
                "{integrator} dt {dt}: energy {} above {start}",
                e.total()
            );
        }
        assert!(touched, "dt {dt}: the cube reaches a wall");
        assert!(energy(&model, &state).total() < 0.5 * start);
    }
}

/// The state at t = 0.02 s of a perturbed, spinning classic cube under gravity (far walls).
fn perturbed_cube_at_20_ms(integrator: Integrator, dt: f64) -> Vec<Vec3> {
    let model = ModelBuilder::new()
        .integrator(integrator)
        .dt(dt)
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .bounds(far_walls())
        .build()
        .unwrap();
    let mut rng = Rng(9);
    let mut state = State::at_rest(&model);
    for (p, v) in state.pos.iter_mut().zip(state.vel.iter_mut()) {
        *p += rng.vec3() * 0.02;
        *v = rng.vec3() * 0.5;
    }
    common::run(&model, &mut state, (0.02 / dt).round() as usize);
    state.pos
}

/// Against a fine RK4 reference, SDIRK2's error at t = 0.02 s quarters when dt halves (second
/// order, the springs' dampers turning with them included).
#[test]
fn sdirk2_error_is_second_order() {
    let reference = perturbed_cube_at_20_ms(Integrator::Rk4, 1e-5);
    let errors: Vec<f64> = [1e-4, 5e-5, 2.5e-5]
        .iter()
        .map(|&dt| max_diff(&perturbed_cube_at_20_ms(Integrator::Sdirk2, dt), &reference))
        .collect();
    for pair in errors.windows(2) {
        let ratio = pair[0] / pair[1];
        assert!((3.6..4.4).contains(&ratio), "errors {errors:?}");
    }
}

/// Against a fine RK4 reference, backward Euler's error at t = 0.02 s halves when dt halves
/// (first order).
#[test]
fn the_error_is_first_order() {
    let reference = perturbed_cube_at_20_ms(Integrator::Rk4, 1e-5);
    let errors: Vec<f64> = [1e-4, 5e-5, 2.5e-5]
        .iter()
        .map(|&dt| {
            max_diff(
                &perturbed_cube_at_20_ms(Integrator::BackwardEuler, dt),
                &reference,
            )
        })
        .collect();
    for pair in errors.windows(2) {
        let ratio = pair[0] / pair[1];
        assert!((1.8..2.2).contains(&ratio), "errors {errors:?}");
    }
}

/// Internal forces conserve momentum: a cube in free flight keeps it to rounding.
#[test]
fn internal_forces_conserve_momentum() {
    for integrator in [Integrator::BackwardEuler, Integrator::Sdirk2] {
        let model = ModelBuilder::new()
            .integrator(integrator)
            .dt(1.0 / 60.0)
            .bounds(far_walls())
            .build()
            .unwrap();
        let mut rng = Rng(2);
        let mut state = State::at_rest(&model);
        for (p, v) in state.pos.iter_mut().zip(state.vel.iter_mut()) {
            *p += rng.vec3() * 0.05;
            *v = Vec3::new(0.2, 0.1, -0.1) + rng.vec3() * 0.3;
        }
        let p0 = momentum(&model, &state.vel);
        common::run(&model, &mut state, 120);
        let p1 = momentum(&model, &state.vel);
        assert!((p1 - p0).max_abs() < 1e-12, "{integrator}: {p0:?} → {p1:?}");
    }
}

/// The same bits on 1, 2 and 3 threads, on a lattice large enough for threads.
#[test]
fn implicit_steps_are_bit_identical_on_any_thread_count() {
    for integrator in [Integrator::BackwardEuler, Integrator::Sdirk2] {
        let model = ModelBuilder::new()
            .lattice(Lattice::new([22, 21, 20], Vec3::new(1.0, 1.0, 1.0)))
            .integrator(integrator)
            .dt(0.01)
            .gravity(Vec3::new(0.0, 0.0, -9.81))
            .build()
            .unwrap();
        let mut start = State::at_rest(&model);
        start
            .pos
            .iter_mut()
            .for_each(|p| *p -= Vec3::new(0.5, 0.5, 1.995));
        let run = |threads| common::run_on_threads(&model, &start, 6, threads);
        let one = run(1);
        assert!(
            one.pos.iter().any(|p| p.z < -2.0),
            "{integrator}: the cube reaches the floor"
        );
        assert_eq!(one, run(2), "{integrator}");
        assert_eq!(one, run(3), "{integrator}");
    }
}

/// The same on two bodies large enough for threads that collide (pairs found at the iterate, in
/// every level of the multigrid), one of them held by a few pinned points.
#[test]
fn implicit_steps_with_contacts_and_pins_are_bit_identical_on_any_thread_count() {
    let lower = common::cube(17, 0.5, Vec3::new(-0.25, 0.0, -0.25), common::jelly(0.002));
    let upper = common::cube(16, 0.4, Vec3::new(-0.2, 0.52, -0.2), common::jelly(0.002));
    let first_upper = (17 * 17 * 17) as u32;
    let model = common::stacked_cubes()
        .bodies(vec![lower, upper])
        .pins([first_upper + 15, first_upper + 16 * 16 - 1])
        .integrator(Integrator::BackwardEuler)
        .dt(0.01)
        .build()
        .unwrap();
    assert!(model.point_count() >= 8192);
    let mut start = State::at_rest(&model);
    for v in &mut start.vel[first_upper as usize..] {
        *v = Vec3::new(0.0, -1.5, 0.0);
    }
    let run = |threads| common::run_on_threads(&model, &start, 4, threads);
    let one = run(1);
    // Falling freely, the upper cube would move at −1.5 − 9.81·0.04 m/s: the lower one slowed it.
    let upper_vy = one.vel[first_upper as usize..]
        .iter()
        .map(|v| v.y)
        .sum::<f64>()
        / (16.0 * 16.0 * 16.0);
    assert!(upper_vy > -1.7, "the cubes met: {upper_vy}");
    assert_eq!(one, run(2));
    assert_eq!(one, run(3));
}

/// A step that does not converge within the allowed Newton iterations is reported with its
/// residual, and the state stays at the last good step.
#[test]
fn a_step_that_does_not_converge_is_reported() {
    let model = ModelBuilder::new()
        .integrator(Integrator::BackwardEuler)
        .dt(1.0 / 60.0)
        .newton(Newton {
            tolerance: 1e-9,
            max_iterations: 1,
            cutbacks: 0,
        })
        .build()
        .unwrap();
    let mut rng = Rng(4);
    let mut state = State::at_rest(&model);
    state.pos.iter_mut().for_each(|p| *p += rng.vec3() * 0.05);
    let before = state.clone();
    let err = step(
        &model,
        &mut state,
        &Control::none(),
        &mut Scratch::new(&model),
    )
    .unwrap_err();
    let BlowUpCause::NotConverged {
        residual,
        iterations,
        ..
    } = err.cause
    else {
        panic!("{err}")
    };
    assert_eq!(iterations, 1);
    assert!(residual > 1e-9, "{residual}");
    assert_eq!(state, before);
    let said = err.to_string();
    assert!(
        said.contains("did not converge at step 1")
            && said.contains(&format!("largest at point {}", err.point))
            && said.contains("after 1 Newton iterations"),
        "{said}"
    );
    for bad in [
        Newton {
            tolerance: 0.0,
            ..Newton::default()
        },
        Newton {
            max_iterations: 0,
            ..Newton::default()
        },
    ] {
        assert!(ModelBuilder::new().newton(bad).build().is_err());
    }
}

/// A field that pulls every point towards the centre, far stiffer than the masses at the step
/// (h²c/m ≈ 7: hω ≈ 2.7, past every explicit integrator’s limit): linear, so the trilinear field
/// is exact and the centre of mass follows backward Euler's recurrence for one point,
/// `v₁ = (v₀ − h·(c/m)·x₀)/(1 + h²c/m)`, `x₁ = x₀ + h·v₁`, whatever the springs do.
#[test]
fn a_stiff_field_pulling_to_the_centre_follows_the_recurrence() {
    let (c, h) = (50.0, 1.0 / 60.0);
    let field = ForceField::from_fn(5, Aabb::classic(), |p| p * -c).unwrap();
    let model = ModelBuilder::new()
        .integrator(Integrator::BackwardEuler)
        .dt(h)
        .field(Some(field))
        .build()
        .unwrap();
    let m = model.bodies()[0].material.mass;
    let mut rng = Rng(3);
    let mut state = State::at_rest(&model);
    for (p, v) in state.pos.iter_mut().zip(state.vel.iter_mut()) {
        *p += rng.vec3() * 0.02 - Vec3::new(0.2, 0.6, 0.4);
        *v = Vec3::new(1.0, 0.5, -0.5) + rng.vec3() * 0.3;
    }
    let centre = |s: &State| s.pos.iter().fold(Vec3::ZERO, |a, &p| a + p) / s.pos.len() as f64;
    let speed = |s: &State| s.vel.iter().fold(Vec3::ZERO, |a, &v| a + v) / s.vel.len() as f64;
    let (mut x, mut v) = (centre(&state), speed(&state));
    let mut scratch = Scratch::new(&model);
    for n in 1..=120 {
        step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
        v = (v - x * (h * c / m)) / (1.0 + h * h * c / m);
        x += v * h;
        let off = (centre(&state) - x).max_abs();
        assert!(off < 1e-9, "step {n}: the centre is {off} m off");
    }
}

/// A field that swirls (`f = c·(−y, x, 0)`: its gradient is antisymmetric, so it has no
/// potential) with `h²c/m = 5`: Newton's method with only a symmetric `A` would gain a factor of
/// about 5 in error per iteration. Linear, so the trilinear field is exact and the centre of
/// mass follows each method's recurrence for one point; backward Euler's step of size `k` solves
/// `(I − k²(c/m)S)·v₁ = v₀ + k(c/m)S·x₀`, `S` the quarter turn about z. (Backward Euler spirals
/// in to the axis; SDIRK2, like the swirl itself, out.)
#[test]
fn a_swirling_field_far_stiffer_than_the_masses_follows_the_recurrence() {
    let (c, h) = (5.0, 1.0 / 60.0);
    let field = ForceField::from_fn(3, far_walls(), |p| Vec3::new(-p.y, p.x, 0.0) * c).unwrap();
    for integrator in [Integrator::BackwardEuler, Integrator::Sdirk2] {
        let model = ModelBuilder::new()
            .integrator(integrator)
            .dt(h)
            .bounds(far_walls())
            .field(Some(field.clone()))
            .mass(h * h * c / 5.0)
            .build()
            .unwrap();
        let a = c / model.bodies()[0].material.mass;
        let mut rng = Rng(5);
        let mut state = State::at_rest(&model);
        for (p, v) in state.pos.iter_mut().zip(state.vel.iter_mut()) {
            *p += rng.vec3() * 0.02 - Vec3::new(0.3, 0.1, 0.2);
            *v = Vec3::new(0.5, -1.0, 0.25) + rng.vec3() * 0.3;
        }
        let centre = |s: &State| s.pos.iter().fold(Vec3::ZERO, |a, &p| a + p) / s.pos.len() as f64;
        let speed = |s: &State| s.vel.iter().fold(Vec3::ZERO, |a, &v| a + v) / s.vel.len() as f64;
        let turn = |v: Vec3| Vec3::new(-v.y, v.x, 0.0);
        // (I − q·S)·u = w with q = k²a: in x and y, [[1, q], [−q, 1]]·u = w.
        let backward_euler = |(x, v): (Vec3, Vec3), k: f64| {
            let w = v + turn(x) * (k * a);
            let q = k * k * a;
            let det = 1.0 + q * q;
            let v1 = Vec3::new((w.x - q * w.y) / det, (w.y + q * w.x) / det, w.z);
            (x + v1 * k, v1)
        };
        let (mut x, mut v) = (centre(&state), speed(&state));
        let mut scratch = Scratch::new(&model);
        for n in 1..=30 {
            step(&model, &mut state, &Control::none(), &mut scratch)
                .unwrap_or_else(|e| panic!("{integrator}, step {n}: {e}"));
            (x, v) = match integrator {
                Integrator::BackwardEuler => backward_euler((x, v), h),
                _ => {
                    let k = SDIRK2_GAMMA * h;
                    let (x1, v1) = backward_euler((x, v), k);
                    backward_euler((x + (x1 - x) * SDIRK2_C, v + (v1 - v) * SDIRK2_C), k)
                }
            };
            // (The tolerance on velocities scales with the fastest point's speed.)
            let off = (centre(&state) - x).max_abs();
            let allowed = 1e-8 * x.max_abs().max(1.0);
            assert!(
                off < allowed,
                "{integrator}, step {n}: the centre is {off} m off"
            );
            // SDIRK2 follows the swirl's growth out of the field's box within a few steps.
            if x.max_abs() > 5.0 {
                break;
            }
        }
    }
}

/// A lattice so stiff (kElastic = kCollision = 10⁶ N/m) that at 1/60 s the residual's rounding
/// (`h/m` times each spring's force error `k·ε·|x|`, about 1e-8 m/s) is above the 1e-9 m/s
/// tolerance: every step converges whole at that floor (cutbacks off), from a throw into the
/// walls until it rests. Under backward Euler the energy never rises above its start (no field,
/// no gravity; SDIRK2 is not algebraically stable, `M₁₁ = (1 − γ)(3γ − 1) < 0`, so it has no
/// such bound, and here its impact briefly raises the energy by a third).
#[test]
fn a_lattice_too_stiff_for_the_tolerance_converges_at_its_rounding_floor() {
    for integrator in [Integrator::BackwardEuler, Integrator::Sdirk2] {
        let model = ModelBuilder::new()
            .integrator(integrator)
            .dt(1.0 / 60.0)
            .elastic(1e6, 0.25)
            .collision(1e6, 0.25)
            .newton(Newton {
                cutbacks: 0,
                ..Newton::default()
            })
            .build()
            .unwrap();
        let mut state = State::at_rest(&model);
        state
            .vel
            .iter_mut()
            .for_each(|v| *v = Vec3::new(10.0, -10.0, 20.0));
        let start = energy(&model, &state).total();
        let mut scratch = Scratch::new(&model);
        for n in 0..120 {
            if let Err(e) = step(&model, &mut state, &Control::none(), &mut scratch) {
                panic!("{integrator}, step {n}: {e}");
            }
            let e = energy(&model, &state).total();
            if integrator == Integrator::BackwardEuler {
                assert!(e <= start, "step {n}: energy {e} above {start}");
            }
        }
        assert_eq!(scratch.cutbacks().split_steps, 0);
    }
}

/// Hard impacts at frame-rate steps (a cube at 50 m/s into the inclined plane, the lattice
/// crushed and its springs' stiffness indefinite): every step converges.
#[test]
fn hard_impacts_converge() {
    for dt in [0.01, 1.0 / 60.0] {
        let model = ModelBuilder::new()
            .integrator(Integrator::BackwardEuler)
            .dt(dt)
            .elastic(172.0, 0.0132)
            .collision(2800.0, 1.2)
            .mass(0.00132)
            .plane(Some(Plane::new([1.0, 1.0, 1.0, 0.5]).unwrap()))
            .build()
            .unwrap();
        let mut state = State::at_rest(&model);
        state
            .vel
            .iter_mut()
            .for_each(|v| *v = Vec3::new(-50.0, 0.0, 0.0));
        let mut scratch = Scratch::new(&model);
        for n in 0..60 {
            if let Err(e) = step(&model, &mut state, &Control::none(), &mut scratch) {
                panic!("dt {dt}, step {n}: {e}");
            }
        }
    }
}

/// A cube thrown onto a gentle slope with friction (an obstacle plane tilted 11°, μ = 0.5,
/// stiff contacts as in the example scenes, kCollision 2e5 N/m: it lands, its points tie to where
/// they touch and the ties slide as it skids) converges at every step under both methods, at
/// 0.01 s and 1/60 s, and stays on the slope. With a sliding tie's full stiffness in the Newton
/// matrix, backward Euler crept to ~1e-7 m/s and stopped at step 17 (as the example scenes
/// `mould.toml` and `blob.toml` did).
#[test]
fn a_cube_landing_on_a_slope_with_friction_converges() {
    let slope = Plane::new([-0.2, 0.0, 1.0, 0.0]).unwrap();
    for integrator in [Integrator::BackwardEuler, Integrator::Sdirk2] {
        for dt in [0.01, 1.0 / 60.0] {
            let model = ModelBuilder::new()
                .lattice(Lattice::new([6, 6, 6], Vec3::new(0.5, 0.5, 0.5)))
                .bounds(far_walls())
                .mass(0.1)
                .elastic(2e4, 10.0)
                .collision(2e5, 50.0)
                .gravity(Vec3::new(0.0, 0.0, -9.81))
                .friction(0.5)
                .obstacle(Obstacle::Plane(slope))
                .integrator(integrator)
                .dt(dt)
                .build()
                .unwrap();
            let mut state = State::at_rest(&model);
            // Its lowest corner 0.1 m above the slope, thrown along it at 1 m/s.
            state
                .pos
                .iter_mut()
                .for_each(|p| *p += Vec3::new(-0.25, -0.25, 0.2));
            state
                .vel
                .iter_mut()
                .for_each(|v| *v = Vec3::new(1.0, 0.0, 0.2));
            let mut scratch = Scratch::new(&model);
            for n in 0..(3.0 / dt) as usize {
                if let Err(e) = step(&model, &mut state, &Control::none(), &mut scratch) {
                    panic!("{integrator}, dt {dt}, step {n}: {e}");
                }
                let deepest = state
                    .pos
                    .iter()
                    .map(|p| -slope.value(*p))
                    .fold(0.0, f64::max);
                assert!(
                    deepest < 0.05,
                    "{integrator}, dt {dt}, step {n}: {deepest} m into the slope"
                );
            }
        }
    }
}

/// One cube dropped onto another resting on the floor, under gravity, with friction: every step
/// converges under both methods at 0.01 s and 1/60 s, the upper cube lands and stays on top. The
/// contacts between bodies are in the Newton matrix; without them backward Euler stopped at step
/// 12 here (its line search found no descent), and on the example `stack.toml` within half a
/// second.
#[test]
fn a_cube_dropped_on_another_converges() {
    for integrator in [Integrator::BackwardEuler, Integrator::Sdirk2] {
        for dt in [0.01, 1.0 / 60.0] {
            let model = stacked_cubes()
                .integrator(integrator)
                .dt(dt)
                .build()
                .unwrap();
            let (rl, ru) = (model.body(0).points(), model.body(1).points());
            let mut state = State::at_rest(&model);
            let mut scratch = Scratch::new(&model);
            for n in 0..(3.0 / dt) as usize {
                if let Err(e) = step(&model, &mut state, &Control::none(), &mut scratch) {
                    panic!("{integrator}, dt {dt}, step {n}: {e}");
                }
            }
            let top_of_lower = state.pos[rl].iter().map(|p| p.y).fold(f64::MIN, f64::max);
            let bottom_of_upper = state.pos[ru].iter().map(|p| p.y).fold(f64::MAX, f64::min);
            assert!(
                bottom_of_upper > top_of_lower,
                "{integrator}, dt {dt}: the upper body sank into the lower"
            );
        }
    }
}

/// SDIRK2 keeps far more of a slow oscillation than backward Euler at a frame-rate step: an
/// undamped spring of period 1 s after 1 s at dt = 1/60.
#[test]
fn sdirk2_damps_a_slow_oscillation_far_less_than_backward_euler() {
    let (m, rest) = (0.5, 0.5);
    // ω² = 2k/m = (2π)² for a 1 Hz oscillation of the stretch.
    let k = m * (2.0 * std::f64::consts::PI).powi(2) / 2.0;
    let material = Material {
        mass: m,
        stiffness: [k; 3],
        damping: [0.0; 3],
    };
    let kept = |integrator| {
        let model = dumbbell(rest, material, 1.0 / 60.0, integrator);
        let mut state = State::new(
            vec![Vec3::new(0.0, 0.0, 0.0), Vec3::new(rest + 0.1, 0.0, 0.0)],
            vec![Vec3::ZERO; 2],
        );
        let e0 = energy(&model, &state).total();
        common::run(&model, &mut state, 60);
        energy(&model, &state).total() / e0
    };
    let (be, sdirk2) = (kept(Integrator::BackwardEuler), kept(Integrator::Sdirk2));
    assert!(be < 0.6, "backward Euler keeps {be}");
    assert!(sdirk2 > 0.99, "SDIRK2 keeps {sdirk2}");
    // And the same fractions as the methods' amplification factors on the linear oscillator.
    for (integrator, fraction) in [
        (Integrator::BackwardEuler, be),
        (Integrator::Sdirk2, sdirk2),
    ] {
        let rho = jello_core::integrate::stability::spectral_radius(
            integrator,
            (2.0 * std::f64::consts::PI).powi(2),
            0.0,
            1.0 / 60.0,
        );
        let predicted = rho.powi(120);
        assert!(
            (fraction / predicted - 1.0).abs() < 0.02,
            "{integrator}: kept {fraction}, |R|^120 = {predicted}"
        );
    }
}

/// A scratch kept from step to step follows a model that changes between steps without changing
/// its size: another stiffness, damping or mass, or a cell cut out of the lattice, steps to the
/// same bits as a fresh scratch does.
#[test]
fn a_scratch_follows_a_model_that_changes_between_steps() {
    let model_with = |material: Material, cells: Option<Vec<bool>>| {
        let lattice = Lattice::new([5, 4, 6], Vec3::new(1.0, 1.0, 1.0));
        let body = match cells {
            Some(cells) => Body::from_cells(lattice, cells, material).unwrap(),
            None => Body::lattice_box(lattice, material),
        };
        ModelBuilder::new()
            .bodies(vec![body])
            .integrator(Integrator::BackwardEuler)
            .dt(1.0 / 60.0)
            .gravity(Vec3::new(0.0, 0.0, -9.81))
            .build()
            .unwrap()
    };
    let soft = common::jelly(0.01);
    let stiff = Material {
        stiffness: soft.stiffness.map(|k| 3.0 * k),
        ..soft
    };
    let damped = Material {
        damping: stiff.damping.map(|d| 0.5 * d),
        ..stiff
    };
    let heavy = Material {
        mass: 2.0 * damped.mass,
        ..damped
    };
    let mut holed = vec![true; 4 * 3 * 5];
    holed[17] = false;
    let models = [
        model_with(soft, None),
        model_with(stiff, None),
        model_with(damped, None),
        model_with(heavy, None),
        model_with(heavy, Some(holed)),
        model_with(soft, None),
    ];
    let mut state = State::at_rest(&models[0]);
    state.pos = common::deformed(&models[0], Vec3::new(0.0, 0.0, -0.2), 0.05, 3);
    let mut kept = Scratch::new(&models[0]);
    for (i, model) in models.iter().enumerate() {
        for _ in 0..3 {
            let mut fresh = state.clone();
            step(
                model,
                &mut fresh,
                &Control::none(),
                &mut Scratch::new(model),
            )
            .unwrap();
            step(model, &mut state, &Control::none(), &mut kept).unwrap();
            assert_eq!(state, fresh, "model {i}");
        }
    }
}

/// The solver's statistics count its work: one solve a backward-Euler step and two an SDIRK2
/// step (none cut back here), a Newton iteration at least a solve (each starts away from its
/// solution), a conjugate-gradient iteration at least a Newton iteration, fewer assemblies of
/// `A` than Newton iterations (in its fast regime Newton's method keeps `A`), and fewer Newton
/// iterations at a looser tolerance. The explicit integrators count nothing.
#[test]
fn the_solver_counts_its_work() {
    let steps = 20;
    let run = |integrator: Integrator, tolerance: f64| {
        let model = ModelBuilder::new()
            .integrator(integrator)
            .dt(1.0 / 60.0)
            .gravity(Vec3::new(0.0, 0.0, -9.81))
            .newton(Newton {
                tolerance,
                ..Newton::default()
            })
            .build()
            .unwrap();
        let mut rng = Rng(3);
        let mut state = State::at_rest(&model);
        for (p, v) in state.pos.iter_mut().zip(state.vel.iter_mut()) {
            *p += rng.vec3() * 0.02;
            *v = rng.vec3() * 0.5;
        }
        let mut sim = jello_core::Simulation::new(model, state);
        sim.advance(steps).unwrap();
        assert_eq!(sim.cutbacks().split_steps, 0, "{integrator}");
        sim.solver_stats()
    };
    let explicit = ModelBuilder::new().build().unwrap();
    let mut sim = jello_core::Simulation::new(explicit.clone(), State::at_rest(&explicit));
    sim.advance(steps).unwrap();
    assert_eq!(sim.solver_stats(), jello_core::SolverStats::default());

    for (integrator, solves) in [(Integrator::BackwardEuler, 1), (Integrator::Sdirk2, 2)] {
        let tight = run(integrator, 1e-9);
        let loose = run(integrator, 1e-5);
        for stats in [tight, loose] {
            assert_eq!(stats.solves, solves * steps, "{integrator}: {stats:?}");
            assert!(
                stats.newton_iterations >= stats.solves,
                "{integrator}: {stats:?}"
            );
            assert!(
                stats.linear_iterations >= stats.newton_iterations,
                "{integrator}: {stats:?}"
            );
        }
        assert!(
            tight.assemblies < tight.newton_iterations,
            "{integrator}: {tight:?}"
        );
        assert!(
            loose.newton_iterations < tight.newton_iterations,
            "{integrator}: {tight:?} {loose:?}"
        );
    }
}
