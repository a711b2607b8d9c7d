//! `--device gpu`: the GPU backend (crate `jello-gpu`) when this build has it (feature `gpu`);
//! in a build without it, the same calls, and opening one says how to get it.

use jello_core::{Control, Model, State};

use crate::error::CliError;

/// A model stepping on the GPU.
#[cfg(feature = "gpu")]
pub struct Gpu(jello_gpu::GpuSimulation);

/// A model stepping on the GPU: none can be opened in a build without the backend.
#[cfg(not(feature = "gpu"))]
pub enum Gpu {}

#[cfg(feature = "gpu")]
impl Gpu {
    /// Uploads the model and state; `name` labels errors (a model the shader does not cover,
    /// no usable adapter).
    pub fn open(
        model: &Model,
        state: &State,
        control: &Control,
        name: &str,
    ) -> Result<Self, CliError> {
        jello_gpu::GpuSimulation::new(model, state, control)
            .map(Gpu)
            .map_err(|e| CliError::input(format!("{name}: --device gpu: {e}")))
    }

    /// Takes `steps` steps: a blow-up (the state stays at the last good step) is exit 3, a
    /// failed device exit 1; `name` labels the message.
    pub fn step(&mut self, steps: u64, name: &str) -> Result<(), CliError> {
        self.0.step(steps).map_err(|e| match e {
            jello_gpu::StepError::BlowUp(b) => CliError::blow_up(format!("{name}: {b}")),
            jello_gpu::StepError::Device(e) => CliError::input(format!("{name}: {e}")),
        })
    }

    /// The state now, in f64; `name` labels the error of a failed device.
    pub fn read_state(&self, name: &str) -> Result<State, CliError> {
        self.0
            .read_state()
            .map_err(|e| CliError::input(format!("{name}: {e}")))
    }

    /// The adapter's name and backend.
    pub fn adapter(&self) -> String {
        self.0.adapter()
    }

    /// How the shader steps: `resident` (a small lattice in one workgroup) or `stages`.
    pub fn kernel(&self) -> String {
        self.0.kernel().to_string()
    }

    /// The deepest penetration at the end of any step taken (m).
    pub fn max_penetration(&self) -> f64 {
        self.0.max_penetration()
    }

    /// Steps in one submission, after which the GPU waits for its status anyway: reading the
    /// state back every this many steps costs little more.
    pub fn batch_steps(&self) -> u64 {
        self.0.batch_steps()
    }
}

#[cfg(not(feature = "gpu"))]
impl Gpu {
    /// Says that this build has no GPU backend, and how to build one that has.
    pub fn open(_: &Model, _: &State, _: &Control, name: &str) -> Result<Self, CliError> {
        Err(CliError::usage(format!(
            "{name}: --device gpu: this jello was built without the GPU backend; build it with \
             `cargo build --release -p jello-cli --features gpu`"
        )))
    }

    /// Never called: no `Gpu` exists in this build.
    pub fn step(&mut self, _: u64, _: &str) -> Result<(), CliError> {
        match *self {}
    }

    /// Never called: no `Gpu` exists in this build.
    pub fn read_state(&self, _: &str) -> Result<State, CliError> {
        match *self {}
    }

    /// Never called: no `Gpu` exists in this build.
    pub fn adapter(&self) -> String {
        match *self {}
    }

    /// Never called: no `Gpu` exists in this build.
    pub fn kernel(&self) -> String {
        match *self {}
    }

    /// Never called: no `Gpu` exists in this build.
    pub fn max_penetration(&self) -> f64 {
        match *self {}
    }

    /// Never called: no `Gpu` exists in this build.
    pub fn batch_steps(&self) -> u64 {
        match *self {}
    }
}
