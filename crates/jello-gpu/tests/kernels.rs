//! The resident kernel (a small lattice inside one workgroup, many steps per dispatch) against
//! the kernel of a dispatch per stage, on the same models; and which models get which.

mod common;

use common::largest_gap;
use jello_core::{Control, Integrator, Lattice, Model, ModelBuilder, Plane, State, Vec3};
use jello_gpu::{GpuError, GpuSimulation, Kernel, RESIDENT_POINTS};

fn start(kernel: Kernel, model: &Model, state: &State) -> GpuSimulation {
    let sim = GpuSimulation::with_kernel(model, state, &Control::default(), Some(kernel))
        .unwrap_or_else(|e| panic!("{e}"));
    assert_eq!(sim.kernel(), kernel);
    sim
}

/// The classic cube with `integrator`, under gravity, over an inclined plane, thrown at a wall
/// with every point at its own velocity (so its springs work from the first step).
fn thrown(integrator: Integrator) -> (Model, State) {
    let model = ModelBuilder::new()
        .lattice(Lattice::new([8, 8, 8], Vec3::new(1.0, 1.0, 1.0)))
        .plane(Some(Plane::new([0.3, 0.0, 1.0, 1.2]).unwrap()))
        .gravity(Vec3::new(0.0, 0.0, -9.81))
        .dt(0.0005)
        .integrator(integrator)
        .build()
        .unwrap();
    let mut state = State::at_rest(&model);
    for (i, v) in state.vel.iter_mut().enumerate() {
        let i = i as f64;
        *v = Vec3::new(
            6.0 + 0.3 * (i % 7.0),
            0.2 * (i % 5.0),
            -1.0 + 0.1 * (i % 3.0),
        );
    }
    (model, state)
}

#[test]
fn the_resident_kernel_steps_as_a_dispatch_per_stage_does() {
    // 0.15 s: the cube's springs work throughout and it reaches the wall at x = 2 (after about
    // 0.075 s) and bounces. The two kernels do the same f32 operations in the same order.
    for integrator in [
        Integrator::Rk4,
        Integrator::Rk2,
        Integrator::SymplecticEuler,
        Integrator::Euler,
    ] {
        let (model, state) = thrown(integrator);
        let model = match integrator {
            // Explicit Euler needs a smaller step to stay bounded.
            Integrator::Euler => model.to_builder().dt(0.0001).build().unwrap(),
            _ => model,
        };
        let steps = (0.15 / model.dt).round() as u64;
        let mut resident = start(Kernel::Resident, &model, &state);
        let mut stages = start(Kernel::Stages, &model, &state);
        resident.step(steps).unwrap();
        stages.step(steps).unwrap();
        let (r, s) = (resident.read_state().unwrap(), stages.read_state().unwrap());
        assert!(
            r.pos.iter().any(|p| p.x > 1.9),
            "{integrator}: the cube reached the wall"
        );
        let gap = largest_gap(&r, &s);
        assert!(gap < 1e-5, "{integrator}: the kernels differ by {gap} m");
        assert_eq!((r.time, r.steps), (s.time, s.steps));
    }
}

#[test]
fn steps_are_counted_across_dispatches_and_calls() {
    // A submission's steps are taken by dispatches of at most 64: any count, in one call or one
    // step per call, ends in the same state, bit for bit.
    let (model, state) = thrown(Integrator::Rk4);
    for steps in [1, 63, 64, 65, 130, 600] {
        let mut at_once = start(Kernel::Resident, &model, &state);
        at_once.step(steps).unwrap();
        let mut one_by_one = start(Kernel::Resident, &model, &state);
        for _ in 0..steps {
            one_by_one.step(1).unwrap();
        }
        let (a, b) = (
            at_once.read_state().unwrap(),
            one_by_one.read_state().unwrap(),
        );
        assert_eq!(a.pos, b.pos, "{steps} steps");
        assert_eq!(a.vel, b.vel, "{steps} steps");
        assert_eq!(a.steps, steps);
    }
}

#[test]
fn small_models_of_one_body_step_resident_on_a_gpu_unless_told_otherwise() {
    let (model, state) = thrown(Integrator::Rk4);
    let sim = GpuSimulation::new(&model, &state, &Control::default()).unwrap();
    // On an adapter that runs on the CPU (lavapipe in CI) a dispatch per stage is faster.
    let expected = if sim.on_cpu_adapter() {
        Kernel::Stages
    } else {
        Kernel::Resident
    };
    assert_eq!(
        sim.kernel(),
        expected,
        "the classic cube on {}",
        sim.adapter()
    );

    let large = ModelBuilder::new()
        .lattice(Lattice::new([9, 9, 9], Vec3::new(1.0, 1.0, 1.0)))
        .build()
        .unwrap();
    assert!(large.point_count() > RESIDENT_POINTS);
    let at_rest = State::at_rest(&large);
    let sim = GpuSimulation::new(&large, &at_rest, &Control::default()).unwrap();
    assert_eq!(sim.kernel(), Kernel::Stages, "9³ = 729 points");
    match GpuSimulation::with_kernel(
        &large,
        &at_rest,
        &Control::default(),
        Some(Kernel::Resident),
    ) {
        Err(GpuError::Unsupported(why)) => assert!(why.contains("at most 512 points"), "{why}"),
        other => panic!("expected a refusal, got {:?}", other.map(|s| s.kernel())),
    }
}

/// Every entry point of both modules, with everything a model may have compiled in, makes a
/// pipeline on a device of WebGPU's default limits (at most 8 storage buffers a stage, 16 KiB of
/// workgroup memory, ...), as a browser gives the viewer: nothing leans on the native adapter's
/// larger limits.
#[test]
fn every_entry_point_fits_webgpus_default_limits() {
    let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
        backends: wgpu::Backends::from_env().unwrap_or(wgpu::Backends::PRIMARY),
        ..wgpu::InstanceDescriptor::new_without_display_handle()
    });
    let adapter = pollster::block_on(instance.request_adapter(&Default::default()))
        .expect("an adapter (scripts/setup.sh installs lavapipe)");
    let (device, _queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
        required_limits: wgpu::Limits::default(),
        ..Default::default()
    }))
    .unwrap();
    let mut constants: Vec<(&str, f64)> = [
        "CONTACTS",
        "OBSTACLES",
        "FRICTION",
        "WALL_FRICTION",
        "FIELD",
        "CLASSIC_PLANE",
        "SPRING_VALUES",
        "PINS",
    ]
    .map(|name| (name, 1.0))
    .to_vec();
    constants.push(("ONE_BODY", 0.0));
    let mut checked = 0;
    for (source, extra) in [
        (jello_gpu::SHADER, None),
        (jello_gpu::RESIDENT_SHADER, Some(("INTEGRATOR", 3.0))),
    ] {
        let mut constants = constants.clone();
        constants.extend(extra);
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: None,
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });
        // The entry points: the function after each `@compute`.
        let entries: Vec<&str> = source
            .split("@compute")
            .skip(1)
            .filter_map(|rest| rest.split("fn ").nth(1)?.split('(').next())
            .collect();
        for entry in &entries {
            let _ = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: None,
                module: &module,
                entry_point: Some(entry),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: &constants,
                    ..Default::default()
                },
                cache: None,
            });
            checked += 1;
        }
        if let Some(e) = pollster::block_on(scope.pop()) {
            panic!("{entries:?}: {e}");
        }
    }
    assert!(checked >= 19, "only {checked} entry points");
}
