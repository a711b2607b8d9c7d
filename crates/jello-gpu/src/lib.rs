//! Jello's explicit integrators on a GPU, through wgpu (Vulkan, Metal, DX12; Mesa's lavapipe on a
//! machine without a GPU), in f32.
//!
//! [`GpuSimulation`] takes a model and a state from the f64 core, uploads them once, and steps
//! on the GPU: one WGSL compute shader (`step.wgsl`), one thread per lattice point, gathers the
//! forces of the point's springs (each spring is evaluated at both its ends, so no atomics and
//! the same result on every run), the field, walls, plane, control force and gravity, and applies
//! one stage of Euler, symplectic Euler, RK2 or RK4. Many steps go into one submission; the last
//! stage of every step checks the state (finite, not past the escape margin) into a status word,
//! and the state at the start of each submission is kept, so that a blow-up is found to the step
//! and reported like the core's [`BlowUp`], the state left at the last good step.
//!
//! The f64 CPU core stays the reference; results here agree with it to f32 rounding (tests in
//! `tests/agreement.rs`). Models the shader does not cover yet (several bodies, obstacles, pulls,
//! pins on paths, the implicit integrators) are refused by
//! [`GpuSimulation::new`] with a message that names what is missing.

use std::fmt;

use jello_core::lattice::STENCIL;
use jello_core::stability;
use jello_core::{BlowUp, BlowUpCause, Control, Integrator, Model, State, Vec3};
use wgpu::util::DeviceExt;

/// Threads per workgroup (the shader's `WORKGROUP`).
const WORKGROUP: u32 = 64;

/// Workgroups along x per dispatch, at most (WebGPU's limit); larger lattices use a second axis.
const MAX_GROUPS_X: u32 = 65_535;

/// Steps encoded into one submission, at most: the status is read back once per submission.
const BATCH: u64 = 512;

/// The status words at the start of a submission (see `status` in the shader): sound, no point
/// at fault, no penetration.
const STATUS_START: [u32; 4] = [0, u32::MAX, 0, 0];
const STATUS_BYTES: u64 = 16;

/// Why no GPU simulation could be made.
#[derive(Clone, Debug, PartialEq)]
pub enum GpuError {
    /// No usable adapter (no GPU driver, nor Mesa's lavapipe).
    NoAdapter(String),
    /// The model uses something the GPU shader does not cover yet.
    Unsupported(String),
    /// The device refused or lost something (out of memory, a limit, a validation error).
    Device(String),
}

impl fmt::Display for GpuError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            GpuError::NoAdapter(why) => write!(
                f,
                "no usable GPU: {why} (a Vulkan, Metal or DX12 driver is needed; on Linux without \
                 a GPU, Mesa's lavapipe: Debian's mesa-vulkan-drivers)"
            ),
            GpuError::Unsupported(what) => {
                write!(
                    f,
                    "the GPU backend does not support {what} yet; run it on the CPU"
                )
            }
            GpuError::Device(why) => write!(f, "GPU error: {why}"),
        }
    }
}

impl std::error::Error for GpuError {}

/// Why [`GpuSimulation::step`] stopped.
#[derive(Clone, Debug, PartialEq)]
pub enum StepError {
    /// The simulation blew up; the state is at the last good step.
    BlowUp(BlowUp),
    /// The device failed (lost, out of memory); the state on it is not to be trusted.
    Device(GpuError),
}

impl fmt::Display for StepError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            StepError::BlowUp(b) => b.fmt(f),
            StepError::Device(e) => e.fmt(f),
        }
    }
}

impl std::error::Error for StepError {}

impl From<GpuError> for StepError {
    fn from(e: GpuError) -> Self {
        StepError::Device(e)
    }
}

/// The shader's uniform block (see `Params` in `step.wgsl`): every field 16 bytes, no padding.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, bytemuck::Pod, bytemuck::Zeroable)]
struct Params {
    dims: [u32; 4],
    offsets: [[i32; 4]; 4],
    rest: [[f32; 4]; 4],
    stiff: [[f32; 4]; 4],
    damp: [[f32; 4]; 4],
    material: [f32; 4],
    flags: [f32; 4],
    box_lo: [f32; 4],
    box_hi: [f32; 4],
    plane: [f32; 4],
    plane_side: [f32; 4],
    gravity: [f32; 4],
    field_lo: [f32; 4],
    field_hi: [f32; 4],
    field_res: [u32; 4],
}

fn vec4(v: Vec3) -> [f32; 4] {
    [v.x as f32, v.y as f32, v.z as f32, 0.0]
}

/// What in `model` (with `control`) the GPU shader does not cover, if anything.
pub fn unsupported(model: &Model, control: &Control) -> Option<String> {
    let bodies = model.bodies();
    let what = if bodies.len() != 1 {
        "several bodies (contacts between bodies)"
    } else if !model.obstacles.is_empty() {
        "obstacles (spheres and boxes)"
    } else if !model.pin_motions.is_empty() {
        "pins that move on paths"
    } else if !control.pulls.is_empty() {
        "pulls on points"
    } else if model.integrator.is_implicit() {
        return Some(format!(
            "the implicit integrator {} (the GPU steps Euler, SymplecticEuler, RK2 and RK4)",
            model.integrator
        ));
    } else {
        return None;
    };
    Some(what.to_string())
}

/// One entry point: its pipeline, and its bind group of the buffers it uses.
struct Stage {
    pipeline: wgpu::ComputePipeline,
    bind_group: wgpu::BindGroup,
}

/// A model stepping on the GPU. See the module documentation.
pub struct GpuSimulation {
    device: wgpu::Device,
    queue: wgpu::Queue,
    adapter: wgpu::AdapterInfo,
    model: Model,
    points: u32,
    groups: (u32, u32),
    /// The state (and a step's start), a stage (and, for Euler and symplectic Euler, the state
    /// every other step), and the state at the start of the current submission. The other
    /// buffers live in the stages' bind groups.
    x: wgpu::Buffer,
    a: wgpu::Buffer,
    checkpoint: wgpu::Buffer,
    status: wgpu::Buffer,
    status_read: wgpu::Buffer,
    state_read: wgpu::Buffer,
    /// The dispatches of one step; for Euler and symplectic Euler, the steps from `x` into `a`
    /// and back, taken in turn.
    steps_from_x: Vec<Stage>,
    steps_from_a: Vec<Stage>,
    /// Euler and symplectic Euler: whether the state is in `a` now (after an odd step count).
    in_a: bool,
    /// Where the checkpoint was taken: `in_a`, the time and the step count then.
    checkpoint_at: (bool, f64, u64),
    /// The deepest penetration into a wall or the plane at the end of a step so far (m).
    deepest: f64,
    /// Per point: the control force plus a uniform field's force, then 1 for a point that
    /// moves, 0 for a pinned one and −1 for one outside the body (it never moves, and is in no
    /// contact); on the GPU and here, with the uniform field's force, for
    /// [`GpuSimulation::set_control`].
    extra: wgpu::Buffer,
    extra_host: Vec<[f32; 4]>,
    uniform: Vec3,
    /// Simulated time (s) and steps, as the core counts them.
    pub time: f64,
    /// Steps taken since the state was loaded.
    pub steps: u64,
}

impl GpuSimulation {
    /// Uploads `model` and `state` (with `control`'s forces, held for every step) to the first
    /// high-performance adapter wgpu finds (`WGPU_BACKEND` chooses a backend), and builds the
    /// shader for the model's integrator.
    pub fn new(model: &Model, state: &State, control: &Control) -> Result<Self, GpuError> {
        if let Some(what) = unsupported(model, control) {
            return Err(GpuError::Unsupported(what));
        }
        pollster::block_on(Self::create(model, state, control))
    }

    async fn create(model: &Model, state: &State, control: &Control) -> Result<Self, GpuError> {
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
        let points = model.point_count();
        let bytes = (points * 32) as u64;
        if bytes > device.limits().max_storage_buffer_binding_size {
            return Err(GpuError::Device(format!(
                "{points} points need {bytes} bytes of state, more than this adapter binds \
                 ({} bytes)",
                device.limits().max_storage_buffer_binding_size
            )));
        }
        let scope = device.push_error_scope(wgpu::ErrorFilter::Validation);
        let sim = Self::build(device, queue, info, model, state, control);
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
        control: &Control,
    ) -> Self {
        let body = &model.bodies()[0];
        let n = model.point_count();
        let [nx, ny, nz] = body.lattice().counts;
        let spacing = body.lattice().spacing();

        // Per stencil entry: flat offset, rest length, stiffness, damping.
        let mut params = Params {
            dims: [nx as u32, ny as u32, nz as u32, n as u32],
            ..Params::default()
        };
        for (s, (d, kind)) in STENCIL.iter().enumerate() {
            let (e, c) = (s / 4, s % 4);
            params.offsets[e][c] = ((d[0] * ny as isize + d[1]) * nz as isize + d[2]) as i32;
            params.rest[e][c] = Vec3::new(
                d[0] as f64 * spacing.x,
                d[1] as f64 * spacing.y,
                d[2] as f64 * spacing.z,
            )
            .length() as f32;
            params.stiff[e][c] = body.material.stiffness[*kind as usize] as f32;
            params.damp[e][c] = body.material.damping[*kind as usize] as f32;
        }
        params.material = [
            body.material.mass as f32,
            model.dt as f32,
            model.k_collision as f32,
            model.d_collision as f32,
        ];
        params.box_lo = vec4(model.bounds.min);
        params.box_hi = vec4(model.bounds.max);
        params.gravity = vec4(model.gravity);
        if let Some(plane) = model.plane {
            let [a, b, c, d] = plane.coeffs;
            params.plane = [a as f32, b as f32, c as f32, d as f32];
            params.plane_side = [plane.normal_length() as f32, plane.side as f32, 0.0, 0.0];
        }
        // The field: a uniform one is a constant force, added to the control forces below.
        let (mut uniform, mut nodes) = (Vec3::ZERO, vec![[0.0f32; 4]]);
        if let Some(field) = &model.field {
            match field.uniform() {
                Some(f) => uniform = f,
                None => {
                    nodes = field.forces().iter().map(|&f| vec4(f)).collect();
                    let b = field.bounds();
                    params.field_lo = vec4(b.min);
                    params.field_hi = vec4(b.max);
                    params.field_res = [field.res() as u32, 0, 0, 0];
                }
            }
        }
        let has_field = model.field.as_ref().is_some_and(|f| f.uniform().is_none());
        let own_values = body.spring_table().is_some();
        params.flags = [
            model.escape_margin as f32,
            if has_field { 1.0 } else { 0.0 },
            if model.plane.is_some() { 1.0 } else { 0.0 },
            if own_values { 1.0 } else { 0.0 },
        ];

        // Per point: the springs it has (forward and backward bits), with their own values when
        // the body has them (regions), and its control force with whether it moves.
        let mut links = vec![0u32; n];
        let mut values = vec![[0.0f32; 4]; if own_values { 16 * n } else { 1 }];
        body.for_each_spring_entry(|spring, s| {
            links[spring.a] |= 1 << s;
            links[spring.b] |= 1 << (16 + s);
            if own_values {
                values[16 * spring.a + s] = [
                    spring.rest as f32,
                    spring.stiffness as f32,
                    spring.damping as f32,
                    0.0,
                ];
            }
        });
        let mut extra: Vec<[f32; 4]> = (0..n)
            .map(|p| {
                let f = control.forces.get(p).copied().unwrap_or(Vec3::ZERO) + uniform;
                [
                    f.x as f32,
                    f.y as f32,
                    f.z as f32,
                    if body.is_active(p) { 1.0 } else { -1.0 },
                ]
            })
            .collect();
        for &p in &model.pins {
            if extra[p as usize][3] > 0.0 {
                extra[p as usize][3] = 0.0;
            }
        }

        let state_data = pack_state(state);
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
        let x = init("state", bytemuck::cast_slice(&state_data), storage);
        let a = init("stage a", bytemuck::cast_slice(&state_data), storage);
        let b = init("stage b", bytemuck::cast_slice(&state_data), storage);
        let sums = init("slope sums", bytemuck::cast_slice(&state_data), storage);
        let checkpoint = init("checkpoint", bytemuck::cast_slice(&state_data), storage);
        let links = init("links", bytemuck::cast_slice(&links), storage);
        let extra_host = extra;
        let extra = init("extra", bytemuck::cast_slice(&extra_host), storage);
        let field = init("field", bytemuck::cast_slice(&nodes), storage);
        let springs = init("spring values", bytemuck::cast_slice(&values), storage);
        let status = init("status", bytemuck::cast_slice(&STATUS_START), storage);
        let uniform_buffer = init(
            "params",
            bytemuck::bytes_of(&params),
            wgpu::BufferUsages::UNIFORM,
        );
        let read = |label: &str, size: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let status_read = read("status readback", STATUS_BYTES);
        let state_read = read("state readback", (n * 32) as u64);

        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("step.wgsl"),
            source: wgpu::ShaderSource::Wgsl(include_str!("step.wgsl").into()),
        });
        // One pipeline per entry point, each with the layout of the bindings it uses: (binding,
        // buffer) pairs below must name exactly those.
        let stage = |entry: &str, bindings: &[(u32, &wgpu::Buffer)]| {
            let pipeline = device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: None,
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            });
            let mut entries = vec![wgpu::BindGroupEntry {
                binding: 0,
                resource: uniform_buffer.as_entire_binding(),
            }];
            let shared = [(5, &links), (6, &extra), (7, &field), (9, &springs)];
            for &(binding, buffer) in bindings.iter().chain(&shared) {
                entries.push(wgpu::BindGroupEntry {
                    binding,
                    resource: buffer.as_entire_binding(),
                });
            }
            let bind_group = device.create_bind_group(&wgpu::BindGroupDescriptor {
                label: Some(entry),
                layout: &pipeline.get_bind_group_layout(0),
                entries: &entries,
            });
            Stage {
                pipeline,
                bind_group,
            }
        };
        // Bindings: 1 the stage read, 2 the step's start (base), 3 the stage written, 4 the sums,
        // 8 the status.
        let (steps_from_x, steps_from_a) = match model.integrator {
            Integrator::Rk4 => (
                vec![
                    stage("rk4_1", &[(1, &x), (3, &a), (4, &sums)]),
                    stage("rk4_2", &[(1, &a), (2, &x), (3, &b), (4, &sums)]),
                    stage("rk4_3", &[(1, &b), (2, &x), (3, &a), (4, &sums)]),
                    stage("rk4_4", &[(1, &a), (2, &x), (4, &sums), (8, &status)]),
                ],
                Vec::new(),
            ),
            Integrator::Rk2 => (
                vec![
                    stage("rk2_1", &[(1, &x), (3, &a)]),
                    stage("rk2_2", &[(1, &a), (2, &x), (8, &status)]),
                ],
                Vec::new(),
            ),
            Integrator::Euler | Integrator::SymplecticEuler => {
                let entry = if model.integrator == Integrator::Euler {
                    "euler"
                } else {
                    "symplectic"
                };
                (
                    vec![stage(entry, &[(1, &x), (3, &a), (8, &status)])],
                    vec![stage(entry, &[(1, &a), (3, &x), (8, &status)])],
                )
            }
            Integrator::BackwardEuler | Integrator::Sdirk2 => {
                unreachable!("refused by GpuSimulation::new")
            }
        };
        let groups = (n as u32).div_ceil(WORKGROUP);
        let groups = if groups <= MAX_GROUPS_X {
            (groups, 1)
        } else {
            (MAX_GROUPS_X, groups.div_ceil(MAX_GROUPS_X))
        };
        GpuSimulation {
            device,
            queue,
            adapter,
            model: model.clone(),
            points: n as u32,
            groups,
            x,
            a,
            checkpoint,
            status,
            status_read,
            state_read,
            steps_from_x,
            steps_from_a,
            in_a: false,
            checkpoint_at: (false, state.time, state.steps),
            deepest: 0.0,
            extra,
            extra_host,
            uniform,
            time: state.time,
            steps: state.steps,
        }
    }

    /// The adapter in use: its name and backend, e.g. "NVIDIA H200 (Vulkan)".
    pub fn adapter(&self) -> String {
        format!("{} ({:?})", self.adapter.name, self.adapter.backend)
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
    pub fn step(&mut self, steps: u64) -> Result<(), StepError> {
        let mut left = steps;
        while left > 0 {
            let batch = left.min(BATCH);
            if !self.run_batch(batch)? {
                // Back to the batch's start, then step by step to the one that fails (the
                // shader is deterministic, so one does).
                self.restore();
                for _ in 0..batch {
                    if !self.run_batch(1)? {
                        let blow_up = self.blow_up()?;
                        self.restore();
                        return Err(StepError::BlowUp(blow_up));
                    }
                }
            }
            left -= batch;
        }
        Ok(())
    }

    /// Encodes `steps` steps after saving the state as the checkpoint, runs them and reads the
    /// status: whether every step ended sound. The time and step count advance either way.
    fn run_batch(&mut self, steps: u64) -> Result<bool, GpuError> {
        let size = self.points as u64 * 32;
        self.checkpoint_at = (self.in_a, self.time, self.steps);
        self.queue
            .write_buffer(&self.status, 0, bytemuck::cast_slice(&STATUS_START));
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(self.live(), 0, &self.checkpoint, 0, size);
        {
            let mut pass = encoder.begin_compute_pass(&Default::default());
            let mut in_a = self.in_a;
            for _ in 0..steps {
                let stages = if in_a {
                    &self.steps_from_a
                } else {
                    &self.steps_from_x
                };
                for stage in stages {
                    pass.set_pipeline(&stage.pipeline);
                    pass.set_bind_group(0, &stage.bind_group, &[]);
                    pass.dispatch_workgroups(self.groups.0, self.groups.1, 1);
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
        let [unsound, _, deepest] = self.read_status()?;
        if unsound == 0 {
            self.deepest = self.deepest.max(f32::from_bits(deepest) as f64);
        }
        Ok(unsound == 0)
    }

    /// The deepest any point has been into a wall or the plane at the end of a step taken here
    /// (m): the core's `max_penetration` over every step.
    pub fn max_penetration(&self) -> f64 {
        self.deepest
    }

    /// Replaces the state (positions, velocities, time and step count) with `state`, which has
    /// a point for each of the model's.
    pub fn set_state(&mut self, state: &State) -> Result<(), GpuError> {
        if state.pos.len() != self.points as usize || state.vel.len() != self.points as usize {
            return Err(GpuError::Device(format!(
                "a state of {} points for a model of {}",
                state.pos.len(),
                self.points
            )));
        }
        self.queue
            .write_buffer(self.live(), 0, bytemuck::cast_slice(&pack_state(state)));
        (self.time, self.steps) = (state.time, state.steps);
        Ok(())
    }

    /// Replaces the control forces with `control`'s (refused, as [`GpuSimulation::new`] refuses
    /// it, when it holds what the shader does not cover), for the steps after this call.
    pub fn set_control(&mut self, control: &Control) -> Result<(), GpuError> {
        if let Some(what) = unsupported(&self.model, control) {
            return Err(GpuError::Unsupported(what));
        }
        for (p, e) in self.extra_host.iter_mut().enumerate() {
            let f = control.forces.get(p).copied().unwrap_or(Vec3::ZERO) + self.uniform;
            (e[0], e[1], e[2]) = (f.x as f32, f.y as f32, f.z as f32);
        }
        self.queue
            .write_buffer(&self.extra, 0, bytemuck::cast_slice(&self.extra_host));
        Ok(())
    }

    /// Forgets the deepest penetration so far: [`GpuSimulation::max_penetration`] then covers
    /// the steps taken after this call.
    pub fn reset_max_penetration(&mut self) {
        self.deepest = 0.0;
    }

    /// Puts the checkpoint back as the state, with the time and step count it was taken at.
    fn restore(&mut self) {
        let size = self.points as u64 * 32;
        let (in_a, time, steps) = self.checkpoint_at;
        (self.in_a, self.time, self.steps) = (in_a, time, steps);
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&self.checkpoint, 0, self.live(), 0, size);
        self.queue.submit([encoder.finish()]);
    }

    /// The status words: whether a step ended unsound, the lowest point at fault, and the
    /// deepest penetration's bits.
    fn read_status(&self) -> Result<[u32; 3], GpuError> {
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&self.status, 0, &self.status_read, 0, STATUS_BYTES);
        self.queue.submit([encoder.finish()]);
        let bytes = self.read(&self.status_read, STATUS_BYTES)?;
        let words: &[u32] = bytemuck::cast_slice(&bytes);
        Ok([words[0], words[1], words[2]])
    }

    /// The report of the single step just taken, which failed (its state still in the buffers).
    fn blow_up(&self) -> Result<BlowUp, GpuError> {
        let point = self.read_status()?[1] as usize;
        let state = self.read_state()?;
        let (p, v) = (state.pos[point], state.vel[point]);
        let finite = [p.x, p.y, p.z, v.x, v.y, v.z].iter().all(|c| c.is_finite());
        let (body, point_ijk) = self.model.locate(point);
        Ok(BlowUp {
            step: self.steps,
            time: self.checkpoint_at.1,
            point,
            body: body as u32,
            point_ijk,
            cause: if finite {
                BlowUpCause::Escaped(p)
            } else {
                BlowUpCause::NonFinite
            },
            integrator: self.model.integrator,
            dt: self.model.dt,
            suggested_dt: stability::suggest_dt(&self.model),
            escape_margin: self.model.escape_margin,
        })
    }

    /// Maps a readback buffer after the work submitted so far, and copies it out.
    fn read(&self, buffer: &wgpu::Buffer, size: u64) -> Result<Vec<u8>, GpuError> {
        let slice = buffer.slice(..size);
        slice.map_async(wgpu::MapMode::Read, |_| {});
        let device = |e: &dyn fmt::Display| GpuError::Device(format!("reading back: {e}"));
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| device(&e))?;
        let out = slice.get_mapped_range().map_err(|e| device(&e))?.to_vec();
        buffer.unmap();
        Ok(out)
    }

    /// The state now, in f64 (positions and velocities as the GPU holds them, in f32).
    pub fn read_state(&self) -> Result<State, GpuError> {
        let size = self.points as u64 * 32;
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(self.live(), 0, &self.state_read, 0, size);
        self.queue.submit([encoder.finish()]);
        let bytes = self.read(&self.state_read, size)?;
        let data: &[[f32; 4]] = bytemuck::cast_slice(&bytes);
        let v3 = |c: &[f32; 4]| Vec3::new(c[0] as f64, c[1] as f64, c[2] as f64);
        let pos = data.iter().step_by(2).map(v3).collect();
        let vel = data.iter().skip(1).step_by(2).map(v3).collect();
        let mut state = State::new(pos, vel);
        state.time = self.time;
        state.steps = self.steps;
        Ok(state)
    }
}

/// The state as the shader holds it: per point its position, then its velocity, as vec4.
fn pack_state(state: &State) -> Vec<[f32; 4]> {
    state
        .pos
        .iter()
        .zip(&state.vel)
        .flat_map(|(&p, &v)| [vec4(p), vec4(v)])
        .collect()
}
