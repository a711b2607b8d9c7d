//! The implicit integrators (backward Euler and SDIRK2, `jello_core::integrate::implicit`):
//! stability far past the explicit limit, energy, convergence order, momentum, threads, hard
//! impacts, the report of a step that does not converge, the solver's counts and its budget on
//! the frame-rate job. Their recurrences in closed form are in `implicit_closed_forms.rs`.

mod common;
#[path = "common/oscillator.rs"]
mod oscillator;

use common::{max_diff, stacked_cubes, Lcg as Rng};
use jello_core::diagnostics::{energy, momentum};
use jello_core::integrate::stability::stable_dt;
use jello_core::Newton;
use jello_core::{
    step, BlowUpCause, Body, Control, Integrator, Lattice, Material, ModelBuilder, Obstacle, Plane,
    Scratch, State, Vec3,
};
use oscillator::{dumbbell, far_walls};

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
        assert_eq!(scratch.cutback_stats().split_steps, 0);
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
/// converges under both methods at 0.01 s and 1/60 s, the upper cube lands and stays on top,
/// resting on the lower with their surfaces touching (overlapping by under 2 % of a cell, no
/// gap). The contacts between bodies are in the Newton matrix; without them backward Euler
/// stopped at step 12 here (its line search found no descent).
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
            let top_of_lower = state.pos[rl.clone()]
                .iter()
                .map(|p| p.y)
                .fold(f64::MIN, f64::max);
            let bottom_of_upper = state.pos[ru.clone()]
                .iter()
                .map(|p| p.y)
                .fold(f64::MAX, f64::min);
            let gap = bottom_of_upper - top_of_lower;
            assert!(
                gap.abs() < 0.002,
                "{integrator}, dt {dt}: the upper body rests {gap} m above the lower"
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
        assert_eq!(sim.cutback_stats().split_steps, 0, "{integrator}");
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

/// The frame-rate job's first simulated second at 1/60 s (a 1 kg, 1 m cube of `n³` points
/// resting on a floor, or dropped onto it from 0.5 m: `jello bench --job rest|drop`): the
/// solver's work stays within its budget, and the cube ends at rest with the floor carrying its
/// weight, `Σ kc·depth = M·g`, within what the tolerance leaves of each point's force balance.
///
/// The solver's counts are deterministic and the same on every thread count and SIMD tier
/// (`implicit_steps_are_bit_identical_on_any_thread_count`, and `simd_tiers.rs`), so unlike its
/// time they can be tested: each budget is the count of 2026-12-07 (`7ce778b`, the same with
/// `JELLO_SIMD=baseline` as on AVX2) with about 10 % to spare. A change that needs more Newton or conjugate-gradient
/// iterations or assemblies on this job makes the frame-rate table slower (BENCHMARKS.md):
/// measure it there, say why in CHANGELOG.md and raise the budget in the same commit.
#[test]
fn the_frame_rate_jobs_stay_within_their_solver_budget() {
    use jello_core::benchmark::Job;
    // (job, n, budget of Newton iterations, of linear iterations, of assemblies) over the 60
    // steps; the counts of 2026-12-07 in the comments.
    let budgets = [
        (Job::Rest, 8, 45, 206, 10),  // 41, 187, 9
        (Job::Drop, 8, 70, 439, 26),  // 64, 399, 24
        (Job::Rest, 16, 36, 234, 9),  // 33, 213, 8
        (Job::Drop, 16, 62, 461, 28), // 56, 419, 25
        (Job::Rest, 32, 36, 297, 10), // 33, 270, 9
        (Job::Drop, 32, 65, 604, 29), // 59, 549, 26
    ];
    for (job, n, newton, linear, assemblies) in budgets {
        let name = format!("the {n}³ {} job", job.name());
        let (model, state) = job.scene(n, Integrator::BackwardEuler, None).unwrap();
        let (h, tolerance) = (model.dt, model.newton.tolerance);
        assert_eq!(h, 1.0 / 60.0, "{name}");
        let mut sim = jello_core::Simulation::new(model, state);
        sim.advance(59).unwrap();
        let before = sim.state.vel.clone();
        sim.advance(1).unwrap();

        let stats = sim.solver_stats();
        assert_eq!(sim.cutback_stats().split_steps, 0, "{name}: {stats:?}");
        assert_eq!(stats.solves, 60, "{name}: {stats:?}");
        assert!(
            stats.newton_iterations <= newton
                && stats.linear_iterations <= linear
                && stats.assemblies <= assemblies,
            "{name}: the solver took {} Newton iterations, {} linear iterations and {} \
             assemblies, over its budget of {newton}, {linear} and {assemblies}",
            stats.newton_iterations,
            stats.linear_iterations,
            stats.assemblies
        );

        // At rest: no point moves faster than 1 mm/s.
        let fastest = sim.state.vel.iter().map(|v| v.length()).fold(0.0, f64::max);
        assert!(fastest < 1e-3, "{name}: a point moves at {fastest} m/s");
        let change = (sim.state.vel.iter().zip(&before))
            .map(|(&v, &b)| (v - b).length())
            .fold(0.0, f64::max);
        // Each point's residual `Δv − h·F/m` is within the tolerance, so the vertical forces on
        // the cube (the floor's penalty springs and dampers below it, gravity; the springs'
        // forces and dampers cancel in pairs, friction is horizontal) sum to within
        // `M·(tolerance + the largest Δv)/h` of zero, and the floor's springs alone to within
        // that and what its dampers can give at the fastest point's speed.
        let model = &sim.model;
        let mass: f64 = model.bodies().iter().map(|b| b.total_mass()).sum();
        let gravity = -model.gravity.z;
        assert!(
            (mass - 1.0).abs() < 1e-12 && gravity == 9.81,
            "{name}: {mass} kg, {gravity} m/s²"
        );
        let k = model.k_collision;
        let below = || sim.state.pos.iter().filter(|p| p.z < 0.0);
        let carried: f64 = below().map(|p| -p.z * k).sum();
        let dampers = below().count() as f64 * model.d_collision * fastest;
        let within = mass * (tolerance + change) / h + dampers;
        assert!(
            (carried - mass * gravity).abs() <= within,
            "{name}: the floor carries {carried} N of the cube's {} N (to within {within} N)",
            mass * gravity
        );
    }
}
