//! The implicit integrators (backward Euler and SDIRK2) against their recurrences in closed
//! form: a damped spring, a bar pressed into a block, a bar tied to a floor by friction, a bar
//! sliding on a block, a body creeping on a slope, a stiff field pulling to the centre and a
//! swirling field.

mod common;
#[path = "common/oscillator.rs"]
mod oscillator;

use common::Lcg as Rng;
use jello_core::integrate::implicit::{SDIRK2_C, SDIRK2_GAMMA};
use jello_core::{
    step, Aabb, Body, Control, ForceField, Integrator, Lattice, Material, ModelBuilder, Obstacle,
    Plane, Scratch, State, Vec3,
};
use oscillator::{dumbbell, far_walls, oscillator_step};

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

/// A held block 4 × 4 × 2 m (cells of 1 m) with its top face at z = 2, and a bar of two points
/// (a body without volume: its points press on others) pressed into that face at 1 m/s: each
/// point is a damped penalty spring against the face, so its depth `s` follows each method's
/// recurrence with `ω² = kc/m`, `γ = dc/m` for as long as it lasts (the block's distance to its
/// surface is exactly linear under the middle of its top face, so the contact is linear there).
/// Without the contacts' dampers between bodies in the implicit step (until 2026-11-28) the
/// depth followed the undamped recurrence instead.
#[test]
fn a_bar_pressed_into_a_held_block_follows_each_methods_recurrence() {
    let (kc, dc, m) = (100.0, 5.0, 1.0);
    let material = Material {
        mass: m,
        stiffness: [50.0; 3],
        damping: [0.5; 3],
    };
    for integrator in [Integrator::BackwardEuler, Integrator::Sdirk2] {
        for h in [0.01, 1.0 / 60.0] {
            let model = bar_on_a_held_block(material, kc, dc, 0.0, Vec3::ZERO, integrator, h);
            // The bar 0.1 m into the face, closing at 1 m/s.
            let mut state = State::at_rest(&model);
            let bar = model.body(1).points();
            for (p, x) in bar.clone().zip([1.5, 2.5]) {
                state.pos[p] = Vec3::new(x, 2.0, 1.9);
                state.vel[p] = Vec3::new(0.0, 0.0, -1.0);
            }
            let (w2, gamma) = (kc / m, dc / m);
            let mut y = (0.1, 1.0);
            let mut scratch = Scratch::new(&model);
            let mut steps = 0;
            // While the bar is in the face at both ends of the step.
            while oscillator_step(integrator, y, w2, gamma, h).0 > 0.0 {
                step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
                y = oscillator_step(integrator, y, w2, gamma, h);
                steps += 1;
                for p in bar.clone() {
                    let (depth, closing) = (2.0 - state.pos[p].z, -state.vel[p].z);
                    let at = format!("{integrator}, h {h}, step {steps}, point {p}");
                    assert!((depth - y.0).abs() < 1e-9, "{at}: {depth} vs {}", y.0);
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

/// A block of 5 × 5 × 3 points 1 m apart, every point held, its top face at z = 2, and a bar of
/// two points 1 m apart along x above the face's middle (placed by the test), with the given
/// material, collision stiffness and damping, friction and gravity.
fn bar_on_a_held_block(
    material: Material,
    kc: f64,
    dc: f64,
    mu: f64,
    gravity: Vec3,
    integrator: Integrator,
    h: f64,
) -> jello_core::Model {
    let block = Body::lattice_box(Lattice::new([5, 5, 3], Vec3::new(4.0, 4.0, 2.0)), material);
    let bar = Body::lattice_box(Lattice::new([2, 1, 1], Vec3::new(1.0, 1.0, 1.0)), material)
        .placed(Vec3::new(1.5, 2.0, 3.0), jello_core::model::body::IDENTITY);
    ModelBuilder::new()
        .bodies(vec![block, bar])
        .pins(0..75)
        .bounds(far_walls())
        .collision(kc, dc)
        .friction(mu)
        .gravity(gravity)
        .integrator(integrator)
        .dt(h)
        .build()
        .unwrap()
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
            let mut model = ModelBuilder::new()
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
            // Each step solved well within the comparison's bounds (at the default 1e-9 m/s,
            // SDIRK2's speeds wander by up to 1.3e-8 m/s from the recurrence over 60 steps,
            // each within the tolerance).
            model.newton.tolerance = 1e-11;
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
/// implicit integrators' cap is that too: `friction::implicit_cap`). A bar of two points lies
/// on a held block (its depth bearing its weight) and slides across it at 0.5 m/s: each
/// backward-Euler step takes `μ·g·h` off its speed while that leaves more than `2μgh` (the
/// friction at its full size, below the cap), then a third of its speed (at the cap, the
/// reduced mass `m/2`: `v₁ = v₀ − (h/m)·(m/2h)·v₁`). Without friction between bodies in the
/// implicit step (until 2026-11-28) it slid on at 0.5 m/s.
#[test]
fn a_bar_sliding_on_a_block_is_slowed_by_their_friction() {
    let (kc, m, g, mu, h) = (1000.0, 1.0, 9.81, 0.5, 1.0 / 60.0);
    let material = Material {
        mass: m,
        stiffness: [50.0; 3],
        damping: [0.5; 3],
    };
    let gravity = Vec3::new(0.0, 0.0, -g);
    let integrator = Integrator::BackwardEuler;
    let model = bar_on_a_held_block(material, kc, 5.0, mu, gravity, integrator, h);
    let top = 2.0 - m * g / kc;
    let mut state = State::at_rest(&model);
    let bar = model.body(1).points();
    for (p, x) in bar.clone().zip([1.5, 2.5]) {
        state.pos[p] = Vec3::new(x, 1.5, top);
        state.vel[p] = Vec3::new(0.0, 0.5, 0.0);
    }
    let mut scratch = Scratch::new(&model);
    let (fall, mut capped) = (mu * g * h, 0);
    for n in 1..=12 {
        let before = state.vel[bar.start].y;
        step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
        let expected = if before - fall > 2.0 * fall {
            before - fall
        } else {
            capped += 1;
            before * 2.0 / 3.0
        };
        for p in bar.clone() {
            let v = state.vel[p];
            assert!(
                (v.y - expected).abs() < 1e-9 && v.x.abs() < 1e-9 && v.z.abs() < 1e-9,
                "step {n}, point {p}: {v:?}, expected {expected} m/s along y"
            );
        }
    }
    assert!(capped >= 6, "the cap bound at {capped} steps only");
}

/// A body resting on another on a slope below the friction angle creeps, at large steps too, as
/// slowly as where an explicit step resolves the contact: the sliding friction's cap between
/// bodies is the pair's reduced mass over the contact's own time `√(m_r/kc)` where that is
/// shorter than the step (`friction::implicit_cap`). A light bar (10 g a point) on a held
/// block, their contacts stiff (`√(m_r/kc)` = 1.1 ms), gravity tilted by 15° (μ = 0.5): at
/// 1/60 s the bar settles at the speed where the cap's damper carries the load,
/// `2·g·sin θ·√(m_r/kc)`, about 5.7 mm/s, within 1 %; with the cap over dt it slid at
/// `2·g·sin θ·dt`, 85 mm/s.
#[test]
fn a_body_on_another_on_a_slope_creeps_as_slowly_at_large_steps() {
    let (kc, m, g, mu, h) = (4000.0, 0.01, 9.81, 0.5, 1.0 / 60.0);
    let theta: f64 = 15f64.to_radians();
    let material = Material {
        mass: m,
        stiffness: [50.0; 3],
        damping: [0.05; 3],
    };
    let gravity = Vec3::new(0.0, g * theta.sin(), -g * theta.cos());
    let integrator = Integrator::BackwardEuler;
    let model = bar_on_a_held_block(material, kc, 1.0, mu, gravity, integrator, h);
    let top = 2.0 - m * g * theta.cos() / kc;
    let mut state = State::at_rest(&model);
    let bar = model.body(1).points();
    for (p, x) in bar.clone().zip([1.5, 2.5]) {
        state.pos[p] = Vec3::new(x, 1.5, top);
    }
    let mut scratch = Scratch::new(&model);
    for _ in 0..30 {
        step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
    }
    let creep = 2.0 * g * theta.sin() * (0.5 * m / kc).sqrt();
    for p in bar {
        let v = state.vel[p];
        assert!(
            (v.y - creep).abs() < 0.01 * creep,
            "point {p}: {v:?}, expected a creep of {creep} m/s along y"
        );
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
