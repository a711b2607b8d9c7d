//! [`GpuSimulation`]: the buffers of a model on a device, the passes of a step, batches of steps
//! with the status read back once per batch, and the checkpoint a blow-up goes back to.

use std::cell::RefCell;
use std::collections::HashMap;
use std::fmt;

use jello_core::integrate::stability;
use jello_core::{BlowUp, BlowUpCause, Control, Integrator, Model, State, Vec3};
use wgpu::util::DeviceExt;

use crate::packing::{self, Packed};
use crate::{GpuError, StepError, RESIDENT_SHADER, SHADER};

/// Threads per workgroup (the shader's `WORKGROUP`).
const WORKGROUP: u32 = 64;

/// Workgroups along x per dispatch, at most (WebGPU's limit); larger lattices use a second axis.
const MAX_GROUPS_X: u32 = 65_535;

/// Steps encoded into one submission, at most: the status is read back once per submission.
const BATCH: u64 = 512;

/// The status words at the start of a submission (see `status` in the shader): sound, no point
/// at fault, no penetration, the pin table's first row; the rest are zero (the contact grid had
/// room). The first six are read back.
const STATUS_START: [u32; 8] = [0, u32::MAX, 0, 0, 0, 0, 0, 0];
const STATUS_BYTES: u64 = 24;

/// The status word that counts the steps left in a submission of [`Kernel::Resident`].
const STEPS_LEFT_WORD: u64 = 4;

/// Steps one dispatch of [`Kernel::Resident`] takes, at most (the shader's
/// `STEPS_PER_DISPATCH`). Lavapipe's llvmpipe stopped a dispatch of RK4 on 8³ after 390 to 455
/// steps (however the loop was written, and with no error): well under that, and still
/// 64 times fewer dispatches than one per stage.
const STEPS_PER_DISPATCH: u64 = 64;

/// How the shader steps: a dispatch per stage over every point (`step.wgsl`), or the whole lattice
/// inside one workgroup, many steps per dispatch (`resident.wgsl`, for small models: see
/// [`packing::fits_resident`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Kernel {
    /// A dispatch per stage of every step.
    Stages,
    /// Every step of a batch in one dispatch of one workgroup.
    Resident,
}

impl fmt::Display for Kernel {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Kernel::Stages => "stages",
            Kernel::Resident => "resident",
        })
    }
}

impl Kernel {
    /// The kernel `JELLO_GPU_KERNEL` forces (`stages` or `resident`), natively; none when it is
    /// not set (or in a browser).
    fn from_env() -> Result<Option<Kernel>, GpuError> {
        #[cfg(not(target_arch = "wasm32"))]
        if let Ok(forced) = std::env::var("JELLO_GPU_KERNEL") {
            return match forced.as_str() {
                "stages" => Ok(Some(Kernel::Stages)),
                "resident" => Ok(Some(Kernel::Resident)),
                other => Err(GpuError::Invalid(format!(
                    "JELLO_GPU_KERNEL must be `stages` or `resident`, not `{other}`"
                ))),
            };
        }
        Ok(None)
    }

    /// The kernel for `model`: `forced`, or resident when the model fits it and the adapter is a
    /// GPU. On an adapter that runs on the CPU (lavapipe, SwiftShader) one workgroup is one CPU
    /// thread, and the resident kernel measured 0.55× a dispatch per stage on the 8³ cube
    /// (lavapipe, 2 cores).
    fn choose(
        model: &Model,
        forced: Option<Kernel>,
        cpu_adapter: bool,
    ) -> Result<Kernel, GpuError> {
        let fits = packing::fits_resident(model);
        match forced {
            Some(Kernel::Resident) if !fits => Err(GpuError::Unsupported(format!(
                "the resident kernel for this model: it takes one body of at most {} points \
                 without friction anchors or moving pins",
                packing::RESIDENT_POINTS
            ))),
            Some(kernel) => Ok(kernel),
            None if fits && !cpu_adapter => Ok(Kernel::Resident),
            None => Ok(Kernel::Stages),
        }
    }
}

/// One dispatch: an entry point's pipeline, its bind group, and its workgroup counts.
struct Pass {
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
    groups: (u32, u32),
}

/// Workgroups of [`WORKGROUP`] threads for `threads` threads, over a second axis past WebGPU's
/// limit on the first.
fn groups_for(threads: usize) -> (u32, u32) {
    let groups = (threads as u32).div_ceil(WORKGROUP).max(1);
    if groups <= MAX_GROUPS_X {
        (groups, 1)
    } else {
        (MAX_GROUPS_X, groups.div_ceil(MAX_GROUPS_X))
    }
}

/// A model stepping on the GPU. See the crate documentation.
pub struct GpuSimulation {
    device: wgpu::Device,
    queue: wgpu::Queue,
    adapter: wgpu::AdapterInfo,
    model: Model,
    points: u32,
    /// The state (and a step's start), a stage (and, for Euler and symplectic Euler, the state
    /// every other step), and the state at the start of the current submission. The other
    /// buffers live in the passes' bind groups.
    x: wgpu::Buffer,
    a: wgpu::Buffer,
    checkpoint: wgpu::Buffer,
    status: wgpu::Buffer,
    status_read: wgpu::Buffer,
    state_read: wgpu::Buffer,
    uniform: wgpu::Buffer,
    /// The scene buffer (see `packing.rs`), where the control forces start (bytes), and the friction
    /// anchors with their copy at the start of the current submission (byte offset, bytes).
    scene: wgpu::Buffer,
    control_at: u64,
    anchors: Option<(u64, u64, wgpu::Buffer)>,
    /// Where the points' paths and the pin table start in the scene (bytes; `None` without pins
    /// on paths).
    pins: Option<(u64, u64)>,
    /// Steps in one submission, at most: [`BATCH`], or fewer when the pin table has fewer rows.
    batch: u64,
    /// The passes of one step; for Euler and symplectic Euler, the steps from `x` into `a` and
    /// back, taken in turn.
    steps_from_x: Vec<Pass>,
    steps_from_a: Vec<Pass>,
    /// Euler and symplectic Euler: whether the state is in `a` now (after an odd step count).
    in_a: bool,
    /// With [`Kernel::Resident`], its one dispatch (a batch's steps in one, `x` in place);
    /// `steps_from_x` and `steps_from_a` are then empty.
    resident: Option<Pass>,
    /// Where the checkpoint was taken: `in_a`, the time and the step count then.
    checkpoint_at: (bool, f64, u64),
    /// The deepest penetration into a wall, the plane or an obstacle at the end of a step so
    /// far (m).
    deepest: f64,
    /// A uniform field's force, added to every control force.
    uniform_field: Vec3,
    /// Simulated time (s), as the core counts it. Pins on paths are placed by it, so it changes
    /// only by stepping and through [`GpuSimulation::set_state`].
    time: f64,
    /// Steps taken, as the core counts them (the loaded state's, plus those since).
    steps: u64,
}

impl GpuSimulation {
    /// Uploads `model` and `state` (with `control`'s forces and pulls, held for every step) to
    /// the first high-performance adapter wgpu finds (`WGPU_BACKEND` chooses a backend), and
    /// builds the passes for the model's integrator: the [`Kernel`] is resident when the model
    /// fits it and the adapter is a GPU, unless `JELLO_GPU_KERNEL` (`stages` or `resident`)
    /// forces one.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn new(model: &Model, state: &State, control: &Control) -> Result<Self, GpuError> {
        pollster::block_on(Self::create(model, state, control))
    }

    /// [`GpuSimulation::new`] with the kernel given (`None`: as `new` chooses); refused when
    /// the model does not fit [`Kernel::Resident`] and that is asked for.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn with_kernel(
        model: &Model,
        state: &State,
        control: &Control,
        kernel: Option<Kernel>,
    ) -> Result<Self, GpuError> {
        pollster::block_on(Self::create_with_kernel(model, state, control, kernel))
    }

    /// [`GpuSimulation::new`] as a future: the form a browser needs, where nothing may block.
    pub async fn create(model: &Model, state: &State, control: &Control) -> Result<Self, GpuError> {
        Self::create_with_kernel(model, state, control, Kernel::from_env()?).await
    }

    async fn create_with_kernel(
        model: &Model,
        state: &State,
        control: &Control,
        kernel: Option<Kernel>,
    ) -> Result<Self, GpuError> {
        if let Some(what) = packing::unsupported(model, control) {
            return Err(GpuError::Unsupported(what));
        }
        control
            .check(model)
            .map_err(|e| GpuError::Invalid(e.to_string()))?;
        check_state(model, state)?;
        let backends = wgpu::Backends::from_env().unwrap_or(wgpu::Backends::PRIMARY);
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor {
            backends,
            ..wgpu::InstanceDescriptor::new_without_display_handle()
        });
        let adapter = instance
            .request_adapter(&wgpu::RequestAdapterOptions {
                power_preference: wgpu::PowerPreference::HighPerformance,
                ..Default::default()
            })
            .await
            .map_err(|e| GpuError::NoAdapter(e.to_string()))?;
        let (device, queue) = adapter
            .request_device(&wgpu::DeviceDescriptor {
                label: Some("jello"),
                required_limits: adapter.limits(),
                ..Default::default()
            })
            .await
            .map_err(|e| GpuError::Device(e.to_string()))?;
        let info = adapter.get_info();
        let kernel = Kernel::choose(model, kernel, info.device_type == wgpu::DeviceType::Cpu)?;
        let packed = Packed::new(model, control, state, BATCH as usize);
        let limits = device.limits();
        let n = model.point_count();
        for (what, bytes) in [
            ("the state", n * 32),
            ("the scene", packed.scene.len() * 16),
            ("the contact buffer", contact_bytes(&packed)),
        ] {
            let bytes = bytes as u64;
            if bytes > limits.max_storage_buffer_binding_size || bytes > limits.max_buffer_size {
                return Err(GpuError::Device(format!(
                    "{what} of {n} points needs {bytes} bytes, more than this adapter binds \
                     ({} bytes)",
                    limits
                        .max_storage_buffer_binding_size
                        .min(limits.max_buffer_size)
                )));
            }
        }
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let sim = Self::build(device, queue, info, model, state, packed, kernel);
        if let Some(e) = scope.pop().await {
            return Err(GpuError::Device(e.to_string()));
        }
        Ok(sim)
    }

    fn build(
        device: wgpu::Device,
        queue: wgpu::Queue,
        adapter: wgpu::AdapterInfo,
        model: &Model,
        state: &State,
        packed: Packed,
        kernel: Kernel,
    ) -> Self {
        let n = model.point_count();
        let state_data = packing::pack_state(state);
        let storage = wgpu::BufferUsages::STORAGE
            | wgpu::BufferUsages::COPY_SRC
            | wgpu::BufferUsages::COPY_DST;
        let init = |label: &str, contents: &[u8], usage| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents,
                usage,
            })
        };
        let empty = |label: &str, size: u64, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage,
                mapped_at_creation: false,
            })
        };
        let x = init("state", bytemuck::cast_slice(&state_data), storage);
        let a = init("stage a", bytemuck::cast_slice(&state_data), storage);
        let b = init("stage b", bytemuck::cast_slice(&state_data), storage);
        let sums = init("slope sums", bytemuck::cast_slice(&state_data), storage);
        let checkpoint = init("checkpoint", bytemuck::cast_slice(&state_data), storage);
        let points = init("points", bytemuck::cast_slice(&packed.points), storage);
        let scene = init("scene", bytemuck::cast_slice(&packed.scene), storage);
        // Zeroed on creation: the counts start at zero (the scans leave them so).
        let grid = empty("contacts", contact_bytes(&packed) as u64, storage);
        let status = init("status", bytemuck::cast_slice(&STATUS_START), storage);
        let uniform = init(
            "params",
            &packed.uniform,
            wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        );
        let read = wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST;
        let status_read = empty("status readback", STATUS_BYTES, read);
        let state_read = empty("state readback", (n * 32) as u64, read);
        let anchors = packed.anchors_at.map(|at| {
            let bytes = (packed.anchor_slots * n * 16) as u64;
            let copy = empty("anchors checkpoint", bytes, storage);
            ((at * 16) as u64, bytes, copy)
        });

        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("jello"),
            source: wgpu::ShaderSource::Wgsl(SHADER.into()),
        });
        let pipelines: RefCell<HashMap<&str, wgpu::ComputePipeline>> = RefCell::default();
        // One dispatch of `entry` over `groups`, binding the uniform block and `bindings`
        // ((binding, buffer) pairs naming exactly the bindings the entry point uses: its
        // layout is the shader's).
        let pass = |entry: &'static str, bindings: &[(u32, &wgpu::Buffer)], groups| {
            let pipeline = pipelines
                .borrow_mut()
                .entry(entry)
                .or_insert_with(|| {
                    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                        label: Some(entry),
                        layout: None,
                        module: &module,
                        entry_point: Some(entry),
                        compilation_options: wgpu::PipelineCompilationOptions {
                            constants: &packed.overrides,
                            ..Default::default()
                        },
                        cache: None,
                    })
                })
                .clone();
            let mut entries = vec![wgpu::BindGroupEntry {
                binding: 0,
                resource: uniform.as_entire_binding(),
            }];
            entries.extend(
                bindings
                    .iter()
                    .map(|&(binding, buffer)| wgpu::BindGroupEntry {
                        binding,
                        resource: buffer.as_entire_binding(),
                    }),
            );
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(entry),
                layout: &pipeline.get_bind_group_layout(0),
                entries: &entries,
            });
            Pass {
                pipeline,
                bind_group,
                groups,
            }
        };
        let per_point = groups_for(n);
        // The passes that find the touches between bodies in the stage in `input` (none
        // without contacts between bodies: see touch.wgsl).
        let contacts_from = |input: &wgpu::Buffer| -> Vec<Pass> {
            let Some(layout) = packed.contacts else {
                return Vec::new();
            };
            let (per_cell, per_sample) = (groups_for(layout.cells), groups_for(layout.samples));
            let reads = [(1, input), (5, &points), (6, &scene), (9, &grid)];
            vec![
                pass("cells_count", &reads, per_cell),
                pass("cells_scan", &[(9, &grid)], (1, 1)),
                pass("cells_scatter", &[(8, &status), (9, &grid)], per_cell),
                pass("cells_sort", &[(9, &grid)], groups_for(layout.buckets)),
                pass("touch", &reads, per_sample),
                pass("touches_scan", &[(9, &grid)], (1, 1)),
                pass("touches_scatter", &[(9, &grid)], per_sample),
                pass("touches_sort", &[(9, &grid)], per_cell),
            ]
        };
        // A force pass: bindings 1 the stage read, 2 the step's start (base), 3 the stage
        // written, 4 the sums, 8 the status; with the model's 5, 6 and 7.
        let stage = |entry: &'static str, bindings: &[(u32, &wgpu::Buffer)]| {
            let mut all = bindings.to_vec();
            all.extend([(5, &points), (6, &scene), (7, &grid)]);
            let input = bindings
                .iter()
                .find(|(b, _)| *b == 1)
                .expect("a stage read")
                .1;
            let mut passes = contacts_from(input);
            passes.push(pass(entry, &all, per_point));
            passes
        };
        let resident = (kernel == Kernel::Resident).then(|| {
            let integrator = match model.integrator {
                Integrator::Euler => 0.0,
                Integrator::SymplecticEuler => 1.0,
                Integrator::Rk2 => 2.0,
                _ => 3.0,
            };
            let mut constants = packed.overrides.clone();
            constants.push(("INTEGRATOR", integrator));
            let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("jello resident"),
                source: wgpu::ShaderSource::Wgsl(RESIDENT_SHADER.into()),
            });
            let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some("resident"),
                layout: None,
                module: &module,
                entry_point: Some("resident"),
                compilation_options: wgpu::PipelineCompilationOptions {
                    constants: &constants,
                    ..Default::default()
                },
                cache: None,
            });
            let entries: Vec<_> = [
                (0, &uniform),
                (2, &x),
                (5, &points),
                (6, &scene),
                (7, &grid),
                (8, &status),
            ]
            .into_iter()
            .map(|(binding, buffer)| wgpu::BindGroupEntry {
                binding,
                resource: buffer.as_entire_binding(),
            })
            .collect();
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some("resident"),
                layout: &pipeline.get_bind_group_layout(0),
                entries: &entries,
            });
            Pass {
                pipeline,
                bind_group,
                groups: (1, 1),
            }
        });
        let (mut steps_from_x, mut steps_from_a) = match model.integrator {
            _ if resident.is_some() => (Vec::new(), Vec::new()),
            Integrator::Rk4 => (
                [
                    stage("rk4_1", &[(1, &x), (3, &a), (4, &sums)]),
                    stage("rk4_2", &[(1, &a), (2, &x), (3, &b), (4, &sums)]),
                    stage("rk4_3", &[(1, &b), (2, &x), (3, &a), (4, &sums)]),
                    stage("rk4_4", &[(1, &a), (2, &x), (4, &sums), (8, &status)]),
                ]
                .into_iter()
                .flatten()
                .collect(),
                Vec::new(),
            ),
            Integrator::Rk2 => (
                [
                    stage("rk2_1", &[(1, &x), (3, &a)]),
                    stage("rk2_2", &[(1, &a), (2, &x), (8, &status)]),
                ]
                .into_iter()
                .flatten()
                .collect(),
                Vec::new(),
            ),
            Integrator::Euler | Integrator::SymplecticEuler => {
                let entry = if model.integrator == Integrator::Euler {
                    "euler"
                } else {
                    "symplectic"
                };
                (
                    stage(entry, &[(1, &x), (3, &a), (8, &status)]),
                    stage(entry, &[(1, &a), (3, &x), (8, &status)]),
                )
            }
            Integrator::BackwardEuler | Integrator::Sdirk2 => {
                unreachable!("refused by GpuSimulation::new")
            }
        };
        // After each step, the friction anchors move with the step's end (the pins on paths
        // already placed by its last stage), and the next step reads the pin table's next row.
        let two_buffers = !steps_from_a.is_empty();
        if anchors.is_some() {
            let end_of_x = if two_buffers { &a } else { &x };
            steps_from_x.push(pass("anchors", &[(1, end_of_x), (10, &scene)], per_point));
            if two_buffers {
                steps_from_a.push(pass("anchors", &[(1, &x), (10, &scene)], per_point));
            }
        }
        if packed.pins.is_some() {
            steps_from_x.push(pass("pins_next", &[(8, &status)], (1, 1)));
            if two_buffers {
                steps_from_a.push(pass("pins_next", &[(8, &status)], (1, 1)));
            }
        }
        GpuSimulation {
            device,
            queue,
            adapter,
            model: model.clone(),
            points: n as u32,
            x,
            a,
            checkpoint,
            status,
            status_read,
            state_read,
            uniform,
            scene,
            control_at: (packed.control_at * 16) as u64,
            anchors,
            pins: packed
                .pins
                .map(|(points_at, table_at, _)| ((points_at * 16) as u64, (table_at * 16) as u64)),
            batch: packed.pins.map_or(BATCH, |(_, _, rows)| rows as u64),
            steps_from_x,
            steps_from_a,
            in_a: false,
            resident,
            checkpoint_at: (false, state.time, state.steps),
            deepest: 0.0,
            uniform_field: packed.uniform_field,
            time: state.time,
            steps: state.steps,
        }
    }

    /// The adapter in use: its name and backend, e.g. "NVIDIA H200 (Vulkan)".
    pub fn adapter(&self) -> String {
        format!("{} ({:?})", self.adapter.name, self.adapter.backend)
    }

    /// Whether the adapter runs on the CPU (Mesa's lavapipe, SwiftShader), as it says.
    pub fn on_cpu_adapter(&self) -> bool {
        self.adapter.device_type == wgpu::DeviceType::Cpu
    }

    /// How the shader steps this model.
    pub fn kernel(&self) -> Kernel {
        if self.resident.is_some() {
            Kernel::Resident
        } else {
            Kernel::Stages
        }
    }

    /// The buffer holding the state now.
    fn live(&self) -> &wgpu::Buffer {
        if self.in_a {
            &self.a
        } else {
            &self.x
        }
    }

    /// Takes `steps` steps. On a blow-up the state is left at the last good step and the error
    /// says which step failed, at which point, and why, as the CPU core says it.
    #[cfg(not(target_arch = "wasm32"))]
    pub fn step(&mut self, steps: u64) -> Result<(), StepError> {
        pollster::block_on(self.step_async(steps))
    }

    /// [`GpuSimulation::step`] as a future (for a browser).
    pub async fn step_async(&mut self, steps: u64) -> Result<(), StepError> {
        let mut left = steps;
        while left > 0 {
            let batch = left.min(self.batch);
            if !self.run_batch(batch).await? {
                // Back to the batch's start, then step by step to the one that fails (the
                // shader is deterministic, so one does).
                self.restore();
                for _ in 0..batch {
                    if !self.run_batch(1).await? {
                        let blow_up = self.blow_up().await?;
                        self.restore();
                        return Err(StepError::BlowUp(blow_up));
                    }
                }
            }
            left -= batch;
        }
        Ok(())
    }

    /// Encodes `steps` steps (at most `self.batch`) after saving the state (and the friction
    /// anchors) as the checkpoint and writing the pin table's rows for them, runs them and reads
    /// the status: whether every step ended sound. The time and step count advance either way.
    async fn run_batch(&mut self, steps: u64) -> Result<bool, GpuError> {
        let size = self.points as u64 * 32;
        self.checkpoint_at = (self.in_a, self.time, self.steps);
        self.queue
            .write_buffer(&self.status, 0, bytemuck::cast_slice(&STATUS_START));
        if let Some((_, table_at)) = self.pins {
            let rows = packing::pin_steps(&self.model, self.time, steps as usize);
            self.queue
                .write_buffer(&self.scene, table_at, bytemuck::cast_slice(&rows));
        }
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(self.live(), 0, &self.checkpoint, 0, size);
        if let Some((at, bytes, copy)) = &self.anchors {
            encoder.copy_buffer_to_buffer(&self.scene, *at, copy, 0, *bytes);
        }
        if let Some(resident) = &self.resident {
            // The batch's steps, counted down on the GPU by dispatches of at most
            // STEPS_PER_DISPATCH.
            self.queue.write_buffer(
                &self.status,
                4 * STEPS_LEFT_WORD,
                bytemuck::bytes_of(&(steps as u32)),
            );
            let mut pass = encoder.begin_compute_pass(&Default::default());
            pass.set_pipeline(&resident.pipeline);
            pass.set_bind_group(0, &resident.bind_group, &[]);
            for _ in 0..steps.div_ceil(STEPS_PER_DISPATCH) {
                pass.dispatch_workgroups(1, 1, 1);
            }
        } else {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            let mut in_a = self.in_a;
            for _ in 0..steps {
                let passes = if in_a {
                    &self.steps_from_a
                } else {
                    &self.steps_from_x
                };
                for p in passes {
                    pass.set_pipeline(&p.pipeline);
                    pass.set_bind_group(0, &p.bind_group, &[]);
                    pass.dispatch_workgroups(p.groups.0, p.groups.1, 1);
                }
                in_a ^= !self.steps_from_a.is_empty();
            }
            self.in_a = in_a;
        }
        self.queue.submit([encoder.finish()]);
        // The time as the core sums it: dt added once per step.
        for _ in 0..steps {
            self.time += self.model.dt;
        }
        self.steps += steps;
        let [unsound, _, deepest, overflow] = self.read_status().await?;
        if unsound == 0 {
            if overflow != 0 {
                // Contacts were missed: not a result to go on from.
                return Err(GpuError::Device(format!(
                    "the bodies' cells were stretched over more grid cells than the contact \
                     buffer has room for ({} per cell on average), in the {steps} steps to step \
                     {}",
                    packing::ENTRIES_PER_CELL,
                    self.steps
                )));
            }
            self.deepest = self.deepest.max(f32::from_bits(deepest) as f64);
        }
        Ok(unsound == 0)
    }

    /// Steps in one submission, at most: the status is read back after each, so reading the
    /// state back there too (every this many steps) costs little more than a copy.
    pub fn batch_steps(&self) -> u64 {
        self.batch
    }

    /// Simulated time (s) of the state on the device, as the core counts it.
    pub fn time(&self) -> f64 {
        self.time
    }

    /// Steps of the state on the device, as the core counts them.
    pub fn steps(&self) -> u64 {
        self.steps
    }

    /// The deepest any point has been into a wall, the plane or an obstacle at the end of a step
    /// taken here (m): the core's `max_penetration` over every step.
    pub fn max_penetration(&self) -> f64 {
        self.deepest
    }

    /// Replaces the state (positions, velocities, time and step count) with `state`, which has
    /// a point for each of the model's; pins on paths go on from where `state` has them.
    pub fn set_state(&mut self, state: &State) -> Result<(), GpuError> {
        check_state(&self.model, state)?;
        self.queue.write_buffer(
            self.live(),
            0,
            bytemuck::cast_slice(&packing::pack_state(state)),
        );
        if let Some((points_at, _)) = self.pins {
            let words = packing::pin_points(&self.model, state);
            self.queue
                .write_buffer(&self.scene, points_at, bytemuck::cast_slice(&words));
        }
        (self.time, self.steps) = (state.time, state.steps);
        Ok(())
    }

    /// Replaces the control forces and pulls with `control`'s (refused, as
    /// [`GpuSimulation::new`] refuses it, when it is not valid for the model), for the steps
    /// after this call.
    pub fn set_control(&mut self, control: &Control) -> Result<(), GpuError> {
        if let Some(what) = packing::unsupported(&self.model, control) {
            return Err(GpuError::Unsupported(what));
        }
        control
            .check(&self.model)
            .map_err(|e| GpuError::Invalid(e.to_string()))?;
        let words = packing::control_words(&self.model, control, self.uniform_field);
        self.queue
            .write_buffer(&self.scene, self.control_at, bytemuck::cast_slice(&words));
        self.queue.write_buffer(
            &self.uniform,
            packing::PULLS_FLAG_OFFSET,
            bytemuck::bytes_of(&packing::pulls_flag(control)),
        );
        Ok(())
    }

    /// Forgets the deepest penetration so far: [`GpuSimulation::max_penetration`] then covers
    /// the steps taken after this call.
    pub fn reset_max_penetration(&mut self) {
        self.deepest = 0.0;
    }

    /// Puts the checkpoint back as the state (and the friction anchors), with the time and step
    /// count it was taken at.
    fn restore(&mut self) {
        let size = self.points as u64 * 32;
        let (in_a, time, steps) = self.checkpoint_at;
        (self.in_a, self.time, self.steps) = (in_a, time, steps);
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&self.checkpoint, 0, self.live(), 0, size);
        if let Some((at, bytes, copy)) = &self.anchors {
            encoder.copy_buffer_to_buffer(copy, 0, &self.scene, *at, *bytes);
        }
        self.queue.submit([encoder.finish()]);
    }

    /// The status words: whether a step ended unsound, the lowest point at fault, the deepest
    /// penetration's bits, and whether the contact grid ran out of room.
    async fn read_status(&self) -> Result<[u32; 4], GpuError> {
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&self.status, 0, &self.status_read, 0, STATUS_BYTES);
        self.queue.submit([encoder.finish()]);
        let bytes = self.read(&self.status_read, STATUS_BYTES).await?;
        let words: &[u32] = bytemuck::cast_slice(&bytes);
        Ok([words[0], words[1], words[2], words[5]])
    }

    /// The report of the single step just taken, which failed (its state still in the buffers).
    async fn blow_up(&self) -> Result<BlowUp, GpuError> {
        let point = self.read_status().await?[1] as usize;
        let state = self.read_state_async().await?;
        let (p, v) = (state.pos[point], state.vel[point]);
        let finite = [p.x, p.y, p.z, v.x, v.y, v.z].iter().all(|c| c.is_finite());
        let (body, point_ijk) = self.model.locate(point);
        Ok(BlowUp {
            step: self.steps,
            time: self.checkpoint_at.1,
            point,
            body: body as u32,
            point_ijk: point_ijk.map(|c| c as u32),
            cause: if finite {
                BlowUpCause::Escaped(p)
            } else {
                BlowUpCause::NonFinite
            },
            integrator: self.model.integrator,
            dt: self.model.dt,
            suggested_dt: stability::suggest_dt(&self.model),
            escape_margin: self.model.escape_margin,
            // (The state before the failed step is not read back.)
            sunk: None,
        })
    }

    /// Maps a readback buffer after the work submitted so far, and copies it out.
    async fn read(&self, buffer: &wgpu::Buffer, size: u64) -> Result<Vec<u8>, GpuError> {
        let slice = buffer.slice(..size);
        let (mapped, is_mapped) = futures_channel::oneshot::channel();
        slice.map_async(wgpu::MapMode::Read, move |result| {
            let _ = mapped.send(result);
        });
        let device = |e: &dyn fmt::Display| GpuError::Device(format!("reading back: {e}"));
        // Natively the mapping completes while the device is polled; a browser's device polls
        // itself (this returns at once there) and the mapping completes as a promise.
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| device(&e))?;
        is_mapped
            .await
            .map_err(|e| device(&e))?
            .map_err(|e| device(&e))?;
        let out = slice.get_mapped_range().map_err(|e| device(&e))?.to_vec();
        buffer.unmap();
        Ok(out)
    }

    /// The state now, in f64 (positions and velocities as the GPU holds them, in f32).
    #[cfg(not(target_arch = "wasm32"))]
    pub fn read_state(&self) -> Result<State, GpuError> {
        pollster::block_on(self.read_state_async())
    }

    /// [`GpuSimulation::read_state`] as a future (for a browser).
    pub async fn read_state_async(&self) -> Result<State, GpuError> {
        let size = self.points as u64 * 32;
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(self.live(), 0, &self.state_read, 0, size);
        self.queue.submit([encoder.finish()]);
        let bytes = self.read(&self.state_read, size).await?;
        let mut state = packing::unpack_state(bytemuck::cast_slice(&bytes));
        state.time = self.time;
        state.steps = self.steps;
        Ok(state)
    }
}

/// Bytes of the contact buffer (see `touch.wgsl`); a word or four for a model without contacts
/// between bodies, which binds it but never reads it.
fn contact_bytes(packed: &Packed) -> usize {
    packed.contacts.map_or(16, |c| c.bytes())
}

/// Fails unless `state` has a position and a velocity for each of `model`'s points.
fn check_state(model: &Model, state: &State) -> Result<(), GpuError> {
    let n = model.point_count();
    if state.pos.len() != n || state.vel.len() != n {
        return Err(GpuError::Invalid(format!(
            "a state of {} positions and {} velocities for a model of {n} points",
            state.pos.len(),
            state.vel.len()
        )));
    }
    Ok(())
}
