//! `--device gpu`: the GPU backend (crate `jello-gpu`) when this build has it (feature `gpu`);
//! in a build without it, the same calls, and opening one says how to get it.

use jello_core::{BlowUp, Control, Model, State};

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

    /// Takes `steps` steps (the state stays at the last good one on a blow-up).
    pub fn step(&mut self, steps: u64) -> Result<(), BlowUp> {
        self.0.step(steps)
    }

    /// The state now, in f64.
    pub fn read_state(&self) -> State {
        self.0.read_state()
    }

    /// The adapter's name and backend.
    pub fn adapter(&self) -> String {
        self.0.adapter()
    }

    /// The deepest penetration at the end of any step taken (m).
    pub fn max_penetration(&self) -> f64 {
        self.0.max_penetration()
    }
}

#[cfg(not(feature = "gpu"))]
impl Gpu {
    /// Says that this build has no GPU backend, and how to build one that has.
    pub fn open(_: &Model, _: &State, _: &Control, name: &str) -> Result<Self, CliError> {
        Err(CliError::usage(format!(
            "{name}: --device gpu: this jello was built without the GPU backend; build it with \
             `cargo build --release --features gpu`"
        )))
    }

    /// Never called: no `Gpu` exists in this build.
    pub fn step(&mut self, _: u64) -> Result<(), BlowUp> {
        match *self {}
    }

    /// Never called: no `Gpu` exists in this build.
    pub fn read_state(&self) -> State {
        match *self {}
    }

    /// Never called: no `Gpu` exists in this build.
    pub fn adapter(&self) -> String {
        match *self {}
    }

    /// Never called: no `Gpu` exists in this build.
    pub fn max_penetration(&self) -> f64 {
        match *self {}
    }
}
