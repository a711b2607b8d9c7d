//! The GPU backend against the f64 CPU core. These run on any adapter wgpu finds: on machines
//! without a GPU, Mesa's lavapipe (scripts/setup.sh installs Debian's mesa-vulkan-drivers), so
//! they fail rather than skip when there is none.

use jello_core::{
    Aabb, Body, Control, ForceField, Integrator, Lattice, Material, Model, ModelBuilder, Plane,
    Simulation, SpringKind, SpringScale, State, Vec3,
};
use jello_gpu::{GpuError, GpuSimulation, StepError};

mod common;
use common::{assert_same_energy, cpu, gpu, largest_gap};

/// A lattice of unequal sides in free flight inside the box: spinning, in a swirling sampled
/// field, with control forces and a pinned point, touching nothing.
fn free_flight(integrator: Integrator) -> (Model, State, Control) {
    let lattice = Lattice::new([12, 10, 9], Vec3::new(0.55, 0.45, 0.4));
    let swirl = ForceField::from_fn(9, Aabb::classic(), |p| {
        Vec3::new(-p.y, p.x, 0.2 * p.z) * 0.004
    })
    .unwrap();
    let model = ModelBuilder::new()
        .lattice(lattice)
        .mass(0.002)
        .spring_kind(SpringKind::Structural, 300.0, 0.3)
        .spring_kind(SpringKind::Shear, 200.0, 0.2)
        .spring_kind(SpringKind::Bend, 120.0, 0.1)
        .field(Some(swirl))
        .gravity(Vec3::new(0.0, 0.0, -1.0))
        .pins([5])
        .dt(0.0005)
        .integrator(integrator)
        .build()
        .unwrap();
    let mut state = State::at_rest(&model);
    let centre = Vec3::new(0.27, 0.22, 0.2);
    for (p, v) in state.pos.iter_mut().zip(state.vel.iter_mut()) {
        let r = *p - centre;
        *p = r * 1.05;
        *v = Vec3::new(-r.y, r.x, 0.1) * 2.0 + Vec3::new(0.3, 0.0, 0.0);
    }
    state.vel[5] = Vec3::ZERO;
    let control = Control {
        forces: (0..model.point_count())
            .map(|i| Vec3::new(0.0, 0.001 * (i % 7) as f64, 0.0))
            .collect(),
        ..Control::default()
    };
    (model, state, control)
}

#[test]
fn every_integrator_agrees_with_the_core_in_free_flight() {
    for integrator in Integrator::EXPLICIT {
        let (model, state, control) = free_flight(integrator);
        let mut sim = gpu(&model, &state, &control);
        sim.step(200).expect("the GPU run is stable");
        let reference = cpu(&model, &state, &control, 200);
        let on_gpu = sim.read_state().unwrap();
        let gap = largest_gap(&on_gpu, &reference);
        assert!(gap < 1e-4, "{integrator}: {gap:.3e} m from the core");
        assert_eq!(on_gpu.steps, 200);
        assert_eq!(
            on_gpu.time, reference.time,
            "{integrator}: time as the core sums it"
        );
        // The pinned point stayed.
        assert!((on_gpu.pos[5] - state.pos[5]).length() < 1e-6);
    }
}

#[test]
fn a_lattice_with_holes_agrees_with_the_core() {
    // An L of cells: the springs of the missing corner are gone, its points do not move.
    let n = 7;
    let c = n - 1;
    let cells = (0..c * c * c)
        .map(|f| {
            let (i, j) = (f / (c * c), (f / c) % c);
            i < 3 || j < 3
        })
        .collect();
    let lattice = Lattice::new([n, n, n], Vec3::new(0.6, 0.6, 0.6));
    let body = Body::from_cells(lattice, cells, Material::classic()).unwrap();
    body_agrees_with_the_core(body, |i| {
        Vec3::new(0.5 + 0.1 * (i % 3) as f64, -0.2, 0.1 + 0.2 * (i % 5) as f64)
    });
}

#[test]
fn per_spring_values_agree_with_the_core() {
    // Regions: springs of their own rest length, stiffness and damping, varying along the body.
    let lattice = Lattice::new([9, 8, 7], Vec3::new(0.5, 0.45, 0.4));
    let mut body = Body::lattice_box(lattice, Material::classic());
    body.scale_springs(|s| SpringScale {
        rest: if s.kind == SpringKind::Shear {
            0.95
        } else {
            1.0
        },
        stiffness: 1.0 + 0.3 * (s.a % 5) as f64,
        damping: 1.0 + 0.5 * (s.b % 3) as f64,
    })
    .unwrap();
    body_agrees_with_the_core(body, |i| {
        Vec3::new(0.2 * (i % 3) as f64, -0.1, 0.1 * (i % 4) as f64)
    });
}

/// `body` alone in the box, at rest shape with point `i` moving at `velocity(i)` (enough to
/// deform it), 200 RK4 steps on the GPU and on the core: within 1e-4 m.
fn body_agrees_with_the_core(body: Body, velocity: impl Fn(usize) -> Vec3) {
    let model = ModelBuilder::new()
        .bodies(vec![body])
        .dt(0.0005)
        .integrator(Integrator::Rk4)
        .build()
        .unwrap();
    let mut state = State::at_rest(&model);
    for (i, v) in state.vel.iter_mut().enumerate() {
        *v = velocity(i);
    }
    let control = Control::default();
    let mut sim = gpu(&model, &state, &control);
    sim.step(200).unwrap();
    let gap = largest_gap(
        &sim.read_state().unwrap(),
        &cpu(&model, &state, &control, 200),
    );
    assert!(gap < 1e-4, "{gap:.3e} m from the core");
}

#[test]
fn with_contacts_the_outcome_is_the_same() {
    // The classic cube thrown against a wall and onto an inclined plane: 3 000 RK4 steps of
    // contacts, where f32 and f64 part ways point by point but not in what happens.
    let model = ModelBuilder::new()
        .lattice(Lattice::new([8, 8, 8], Vec3::new(1.0, 1.0, 1.0)))
        .plane(Some(Plane::new([0.3, 0.0, 1.0, 1.2]).unwrap()))
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .dt(0.0005)
        .integrator(Integrator::Rk4)
        .build()
        .unwrap();
    let mut state = State::at_rest(&model);
    state
        .vel
        .iter_mut()
        .for_each(|v| *v = Vec3::new(4.0, 1.0, -2.0));
    let control = Control::default();
    let mut sim = gpu(&model, &state, &control);
    sim.step(3000).unwrap();
    let on_gpu = sim.read_state().unwrap();
    let reference = cpu(&model, &state, &control, 3000);
    assert_same_energy(&model, &on_gpu, &reference, "");
    // Nothing went through a wall: no deeper than the core's own penetration, plus a margin.
    let depth = |s: &State| {
        s.pos
            .iter()
            .map(|p| (p.x.abs().max(p.y.abs()).max(p.z.abs()) - 2.0).max(0.0))
            .fold(0.0, f64::max)
    };
    assert!(depth(&on_gpu) <= depth(&reference) + 0.01);
}

#[test]
fn a_blow_up_is_reported_and_the_state_kept() {
    // Euler far past its stable step: it blows up within a few hundred steps.
    let (model, state, control) = free_flight(Integrator::Euler);
    let model = model
        .to_builder()
        .dt(0.004)
        .spring_kind(SpringKind::Structural, 20000.0, 0.0)
        .build()
        .unwrap();
    let mut sim = gpu(&model, &state, &control);
    let blow_up = match sim.step(100_000) {
        Err(StepError::BlowUp(b)) => b,
        other => panic!("Euler at 0.004 s blows up, got {other:?}"),
    };
    let kept = sim.read_state().unwrap();
    assert_eq!(
        kept.steps,
        blow_up.step - 1,
        "the state is the last good step"
    );
    assert!(kept
        .pos
        .iter()
        .chain(&kept.vel)
        .all(|v| v.x.is_finite() && v.y.is_finite() && v.z.is_finite()));
    assert!(blow_up.to_string().contains("blew up at step"), "{blow_up}");
    // The CPU blows up too, within a few steps of it.
    let mut cpu = Simulation::new(model.clone(), state.clone());
    cpu.control = control;
    let cpu_step = loop {
        if let Err(e) = cpu.step() {
            break e.step;
        }
    };
    assert!(
        cpu_step.abs_diff(blow_up.step) <= 5,
        "GPU at {}, core at {cpu_step}",
        blow_up.step
    );
}

#[test]
fn models_the_shader_does_not_cover_are_refused() {
    let (model, state, control) = free_flight(Integrator::Rk4);
    let implicit = model
        .to_builder()
        .integrator(Integrator::BackwardEuler)
        .build()
        .unwrap();
    match GpuSimulation::new(&implicit, &state, &control) {
        Err(GpuError::Unsupported(what)) => assert!(what.contains("BackwardEuler"), "{what}"),
        other => panic!("expected a refusal, got {:?}", other.err()),
    }
    let sdirk = model
        .to_builder()
        .integrator(Integrator::Sdirk2)
        .build()
        .unwrap();
    match GpuSimulation::new(&sdirk, &state, &control) {
        Err(GpuError::Unsupported(what)) => assert!(what.contains("SDIRK2"), "{what}"),
        other => panic!("expected a refusal, got {:?}", other.err()),
    }
    // More bodies than the uniform block holds.
    let small = Body::lattice_box(
        Lattice::new([2, 2, 2], Vec3::new(0.05, 0.05, 0.05)),
        Material::classic(),
    );
    let many: Vec<Body> = (0..=jello_gpu::MAX_BODIES)
        .map(|b| {
            small.clone().placed(
                Vec3::new(-1.9 + 0.1 * (b % 30) as f64, 0.1 * (b / 30) as f64, 0.0),
                jello_core::model::body::IDENTITY,
            )
        })
        .collect();
    let crowd = ModelBuilder::new().bodies(many).build().unwrap();
    let err = GpuSimulation::new(&crowd, &State::at_rest(&crowd), &Control::default()).err();
    match err {
        Some(GpuError::Unsupported(what)) => assert!(what.contains("at most 224"), "{what}"),
        other => panic!("expected a refusal, got {other:?}"),
    }
    // A control that is not valid for the model.
    let mut bad = control.clone();
    bad.forces.pop();
    match GpuSimulation::new(&model, &state, &bad) {
        Err(GpuError::Invalid(why)) => assert!(why.contains("control forces"), "{why}"),
        other => panic!("expected a refusal, got {:?}", other.err()),
    }
}
