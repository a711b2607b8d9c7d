//! Jello's explicit integrators on a GPU, through wgpu (Vulkan, Metal, DX12; Mesa's lavapipe on a
//! machine without a GPU), in f32.
//!
//! [`GpuSimulation`] takes a model and a state from the f64 core, uploads them once, and steps
//! on the GPU: one WGSL module ([`SHADER`]), one thread per lattice point, gathers the forces on
//! the point (its springs, each evaluated at both its ends, so no atomics and the same result on
//! every run; the field, walls, plane, obstacles with their friction, contacts with other bodies,
//! control forces, pulls and gravity) and
//! applies one stage of Euler, symplectic Euler, RK2 or RK4. Many steps go into one submission;
//! the last stage of every step checks the state (finite, not past the escape margin) into a
//! status word and puts the pins that move on paths where their paths say (from a table of the
//! paths' offsets at each step's end, computed in f64 on the host as the core computes them),
//! and the state at the start of each submission is kept, so that a blow-up is found to the step
//! and reported like the core's [`BlowUp`](jello_core::BlowUp), the state left at the last good
//! step.
//!
//! Small models (one body of at most [`RESIDENT_POINTS`] points, without friction anchors or
//! pins on paths, the classic cube among them) step on a GPU with [`Kernel::Resident`] instead:
//! the whole lattice inside one workgroup ([`RESIDENT_SHADER`]), the stages separated by
//! workgroup barriers, up to 64 steps per dispatch, with the same f32 operations. (Not on an
//! adapter that runs on the CPU, where one workgroup is one thread.)
//!
//! The f64 CPU core stays the reference; results here agree with it to f32 rounding (tests in
//! `tests/agreement.rs` and `tests/scenes.rs`). Models the shader does not cover yet (the
//! implicit integrators, more than [`MAX_BODIES`] bodies) are refused by [`GpuSimulation::new`]
//! with a message that names what is missing.
//!
//! Creating, stepping and reading back are futures underneath ([`GpuSimulation::create`],
//! [`GpuSimulation::step_async`], [`GpuSimulation::read_state_async`]); natively the blocking
//! forms wait on them. For wasm32 the crate builds on wgpu's WebGPU backend, where only the
//! futures exist: the browser viewer steps with them (`jello-wasm`'s `JelloGpu`).
//!
//! Layout: `packing` packs a model into the buffers the shader reads, `simulation` drives the
//! device, and `shader/` holds the WGSL (`model.wgsl`, `stage.wgsl`, `forces.wgsl`,
//! `contact.wgsl`, `touch.wgsl`, `check.wgsl`, `step.wgsl`, `resident.wgsl`).
//!
//! Contacts between bodies are the core's surface contacts (`jello_core::contact::bodies`):
//! before every force pass, passes over the bodies' cells and contact samples (`touch.wgsl`)
//! sort the cells into a hashed grid, find each sample's touch and its force into a record, and
//! list the touches per cell; each point then gathers the forces of the samples it is a corner
//! of and of the touches in its cells, in the samples' order. Counting sorts with a sort of each
//! list after them: no float atomics, and the same bits on every run.

use std::fmt;

mod packing;
mod simulation;

pub use packing::{fits_resident, unsupported, MAX_BODIES, RESIDENT_POINTS};
pub use simulation::{GpuSimulation, Kernel};

/// The WGSL module every GPU path runs (native through wgpu, and WebGPU in a browser): its parts
/// in order.
pub const SHADER: &str = concat!(
    include_str!("shader/model.wgsl"),
    include_str!("shader/stage.wgsl"),
    include_str!("shader/forces.wgsl"),
    include_str!("shader/contact.wgsl"),
    include_str!("shader/touch.wgsl"),
    include_str!("shader/check.wgsl"),
    include_str!("shader/step.wgsl"),
);

/// The WGSL module that steps a small lattice inside one workgroup, many steps per dispatch (see
/// `shader/resident.wgsl`): the model and forces of [`SHADER`] over workgroup memory.
pub const RESIDENT_SHADER: &str = concat!(
    include_str!("shader/model.wgsl"),
    include_str!("shader/forces.wgsl"),
    include_str!("shader/contact.wgsl"),
    include_str!("shader/check.wgsl"),
    include_str!("shader/resident.wgsl"),
);

/// Why no GPU simulation could be made.
#[derive(Clone, Debug, PartialEq)]
pub enum GpuError {
    /// No usable adapter (no GPU driver, nor Mesa's lavapipe).
    NoAdapter(String),
    /// The model uses something the GPU shader does not cover yet.
    Unsupported(String),
    /// The model, state or control given is not valid (as the core's checks say).
    Invalid(String),
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
            GpuError::Invalid(why) => write!(f, "{why}"),
            GpuError::Device(why) => write!(f, "GPU error: {why}"),
        }
    }
}

impl std::error::Error for GpuError {}

/// Why [`GpuSimulation::step`] stopped.
#[derive(Clone, Debug, PartialEq)]
pub enum StepError {
    /// The simulation blew up; the state is at the last good step.
    BlowUp(jello_core::BlowUp),
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
