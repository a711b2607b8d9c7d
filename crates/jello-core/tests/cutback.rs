//! Cutbacks (`jello_core::integrate::cutback`): an implicit step whose solve fails is taken again in halves,
//! each half the same method at the smaller step, and only a failure at the smallest allowed
//! size is reported, with the state back at the step's start.
//!
//! The scene: the classic cube at 1/60 s, its points scattered by a few centimetres, with
//! Newton's method allowed a few iterations: too few for a step of 1/60 s or 1/120 s from there
//! and enough for 1/240 s (checked below, with cutbacks off), so the first step needs two
//! halvings.

mod common;

use common::{deformed, max_diff, Lcg as Rng};
use jello_core::model::solver::{Newton, MAX_CUTBACKS};
use jello_core::{
    step, BlowUpCause, Control, CutbackStats, Integrator, Model, ModelBuilder, Scratch, Simulation,
    State, Vec3,
};

const DT: f64 = 1.0 / 60.0;

/// Newton iterations allowed, and the scatter (m) of the start, for each method.
fn hard_start(integrator: Integrator) -> (u32, f64) {
    match integrator {
        Integrator::Sdirk2 => (7, 0.08),
        // (With 7, since the solves stopped tightening after slow Newton iterations, not even
        // 1/240 s converges.)
        _ => (8, 0.05),
    }
}

fn model(integrator: Integrator, dt: f64, cutbacks: u32) -> Model {
    ModelBuilder::new()
        .integrator(integrator)
        .dt(dt)
        .newton(Newton {
            tolerance: 1e-9,
            max_iterations: hard_start(integrator).0,
            cutbacks,
        })
        .build()
        .unwrap()
}

fn scattered(model: &Model) -> State {
    let mut state = State::at_rest(model);
    state.pos = deformed(model, Vec3::ZERO, hard_start(model.integrator).1, 4);
    state
}

/// `n` steps of `model` from `start` with cutbacks off; `None` when one fails.
fn plain_steps(model: &Model, start: &State, n: usize) -> Option<State> {
    let mut state = start.clone();
    let mut scratch = Scratch::new(model);
    for _ in 0..n {
        step(model, &mut state, &Control::none(), &mut scratch).ok()?;
    }
    Some(state)
}

/// The first step fails at 1/60 s and 1/120 s and is taken as four steps of 1/240 s: bit for bit
/// those four steps, counted as one step ending at `dt`. The next step starts from the size that
/// worked last (after four successes, twice it: 1/120 s), not from 1/60 s.
#[test]
fn a_step_that_fails_is_taken_in_halves_until_it_converges() {
    for integrator in [Integrator::BackwardEuler, Integrator::Sdirk2] {
        let full = model(integrator, DT, MAX_CUTBACKS);
        let start = scattered(&full);
        // The premise: too few iterations for 1/60 s and 1/120 s, enough for 1/240 s.
        assert!(plain_steps(&model(integrator, DT, 0), &start, 1).is_none());
        assert!(plain_steps(&model(integrator, DT / 2.0, 0), &start, 1).is_none());
        let Some(four) = plain_steps(&model(integrator, DT / 4.0, 0), &start, 4) else {
            panic!("{integrator}: the quarter steps do not converge")
        };
        let Some(then_two) = plain_steps(&model(integrator, DT / 2.0, 0), &four, 2) else {
            panic!("{integrator}: the half steps after them do not converge")
        };

        let mut sim = Simulation::new(full, start.clone());
        sim.step().unwrap();
        let differ = (
            max_diff(&sim.state.pos, &four.pos),
            max_diff(&sim.state.vel, &four.vel),
        );
        assert_eq!(differ, (0.0, 0.0), "{integrator}");
        assert_eq!((sim.state.steps, sim.state.time), (1, DT));
        let first = CutbackStats {
            split_steps: 1,
            substeps: 4,
            retries: 2,
            finest: 2,
        };
        assert_eq!(sim.cutback_stats(), first, "{integrator}");
        // The solver's statistics count the failed tries' work too: a backward-Euler solve a
        // try, each failed one after all its iterations.
        if integrator == Integrator::BackwardEuler {
            let solver = sim.solver_stats();
            assert_eq!(solver.solves, first.retries + first.substeps, "{solver:?}");
            let failed = first.retries * u64::from(hard_start(integrator).0);
            assert!(solver.newton_iterations > failed, "{solver:?}");
        }
        sim.step().unwrap();
        let differ = (
            max_diff(&sim.state.pos, &then_two.pos),
            max_diff(&sim.state.vel, &then_two.vel),
        );
        assert_eq!(differ, (0.0, 0.0), "{integrator}");
        assert_eq!((sim.state.steps, sim.state.time), (2, 2.0 * DT));
        let second = CutbackStats {
            split_steps: 2,
            substeps: 6,
            ..first
        };
        assert_eq!(sim.cutback_stats(), second, "{integrator}");
    }
}

/// Allowed one halving only, the step fails: reported with the substep's size, and the state
/// is exactly the step's start. With cutbacks off, the failure is the full step's.
#[test]
fn a_step_that_fails_at_the_smallest_size_is_reported_and_undone() {
    for (cutbacks, said) in [(1, "on a substep of dt/2 "), (0, "Newton iterations (")] {
        let model = model(Integrator::BackwardEuler, DT, cutbacks);
        let mut state = scattered(&model);
        let before = state.clone();
        let mut scratch = Scratch::new(&model);
        let err = step(&model, &mut state, &Control::none(), &mut scratch).unwrap_err();
        let BlowUpCause::NotConverged {
            iterations,
            halvings,
            ..
        } = err.cause
        else {
            panic!("{err}")
        };
        assert_eq!(
            (iterations, halvings),
            (hard_start(model.integrator).0, cutbacks)
        );
        assert_eq!(state, before);
        assert_eq!((err.step, err.time), (1, 0.0));
        let text = err.to_string();
        assert!(text.contains(said), "{text}");
        assert_eq!(scratch.cutback_stats().split_steps, 0);
    }
}

/// A step that fails after some of its substeps succeeded goes back to its start: the
/// substeps are undone, positions, velocities and all.
#[test]
fn a_failure_after_good_substeps_undoes_them() {
    // One halving allowed, and the first half converges only by luck of where it starts and
    // of the iterations allowed: find a start and a number of Newton iterations where the first
    // half succeeds and the second fails, at 1/120 s with cutbacks off, then check the cut-back
    // step puts it all back.
    let with = |max_iterations: u32, dt: f64, cutbacks: u32| {
        ModelBuilder::new()
            .integrator(Integrator::BackwardEuler)
            .dt(dt)
            .newton(Newton {
                tolerance: 1e-9,
                max_iterations,
                cutbacks,
            })
            .build()
            .unwrap()
    };
    let found = (5..=12u32).find_map(|iterations| {
        let half = with(iterations, DT / 2.0, 0);
        (0..400u64).find_map(|seed| {
            let mut rng = Rng(seed);
            let mut start = State::at_rest(&half);
            let scale = 0.02 + 0.0004 * seed as f64;
            start.pos.iter_mut().for_each(|p| *p += rng.vec3() * scale);
            let full_fails = plain_steps(&with(iterations, DT, 0), &start, 1).is_none();
            let first = plain_steps(&half, &start, 1).is_some();
            let both = plain_steps(&half, &start, 2).is_some();
            (full_fails && first && !both).then_some((iterations, start))
        })
    });
    let Some((iterations, start)) = found else {
        panic!("no start found where only the first half step converges")
    };
    let model = with(iterations, DT, 1);
    let mut state = start.clone();
    let err = step(
        &model,
        &mut state,
        &Control::none(),
        &mut Scratch::new(&model),
    )
    .unwrap_err();
    assert!(matches!(
        err.cause,
        BlowUpCause::NotConverged { halvings: 1, .. }
    ));
    assert_eq!(state, start);
    assert!(max_diff(&state.pos, &start.pos) == 0.0);
}

/// A step that converges at full size is untouched by cutbacks: the same bits whatever the
/// number allowed, and nothing counted.
#[test]
fn a_step_that_converges_is_untouched() {
    let at = |cutbacks| {
        let model = ModelBuilder::new()
            .integrator(Integrator::BackwardEuler)
            .dt(DT)
            .newton(Newton {
                cutbacks,
                ..Newton::default()
            })
            .build()
            .unwrap();
        let mut sim = Simulation::new(model, scattered_classic());
        sim.advance(5).unwrap();
        assert_eq!(sim.cutback_stats(), CutbackStats::default());
        sim.state
    };
    assert_eq!(at(0), at(MAX_CUTBACKS));
}

fn scattered_classic() -> State {
    let model = ModelBuilder::new().build().unwrap();
    let mut state = State::at_rest(&model);
    state.pos = deformed(&model, Vec3::new(0.0, 0.0, 0.1), 0.02, 9);
    state
}

#[test]
fn more_halvings_than_allowed_are_refused() {
    let bad = Newton {
        cutbacks: MAX_CUTBACKS + 1,
        ..Newton::default()
    };
    let err = ModelBuilder::new().newton(bad).build().unwrap_err();
    assert!(err.to_string().contains("halved at most"), "{err}");
}
