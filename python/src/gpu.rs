//! `device="gpu"`: stepping on a GPU through `jello-gpu` (its f32 WGSL shaders, the explicit
//! integrators).
//!
//! The core's `jello_core::Simulation` stays the simulation's whole truth: every property reads
//! it, and every change from Python goes into it. The GPU holds a copy of its model, state and
//! control forces (the [`Mirror`]), made when the device is set to "gpu" (or on the next step
//! after the model changed): positions, velocities and control forces assigned from Python are
//! written into it, and a change of the model (dt, integrator, material…) drops it, so that the
//! next step makes it again from the core. After each chunk of steps the state is read back into
//! the core's, so positions, energy, `save` and the rest read as on the CPU, rounded to f32.

use std::time::{Duration, Instant};

use jello_gpu::{GpuSimulation, StepError};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;

use crate::errors::GpuError;
use crate::simulation::Stopped;

/// Where `step` and `run` compute.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub(crate) enum Device {
    /// The f64 core (the reference).
    #[default]
    Cpu,
    /// The f32 shaders of `jello-gpu`.
    Gpu,
}

impl Device {
    pub(crate) fn parse(name: &str) -> PyResult<Device> {
        match name.to_ascii_lowercase().as_str() {
            "cpu" => Ok(Device::Cpu),
            "gpu" => Ok(Device::Gpu),
            _ => Err(PyValueError::new_err(format!(
                "device: expected \"cpu\" or \"gpu\", found {name:?}"
            ))),
        }
    }

    pub(crate) fn name(self) -> &'static str {
        match self {
            Device::Cpu => "cpu",
            Device::Gpu => "gpu",
        }
    }
}

/// The GPU's copy of a simulation (see the module documentation). A copy of the simulation
/// (`Simulation.copy`) does not share it: it makes its own on its first step.
#[derive(Default)]
pub(crate) struct Mirror(Option<GpuSimulation>);

impl Clone for Mirror {
    fn clone(&self) -> Self {
        Mirror(None)
    }
}

/// How long a chunk of GPU steps should take at most, between looks for Ctrl-C.
const CHUNK_TIME: Duration = Duration::from_millis(50);

/// Steps per chunk, at most (the GPU backend submits 512 at a time).
const MAX_CHUNK: u64 = 4096;

impl Mirror {
    /// Forgets the copy: the model changed (or the copy cannot be trusted).
    pub(crate) fn clear(&mut self) {
        self.0 = None;
    }

    /// The state was assigned from Python: into the copy, if there is one (or the copy goes).
    pub(crate) fn state_changed(&mut self, state: &jello_core::State) {
        if let Some(gpu) = &mut self.0 {
            if gpu.set_state(state).is_err() {
                self.clear();
            }
        }
    }

    /// The control forces were assigned from Python: into the copy, if there is one (or the
    /// copy goes, and the next step makes it again or says why it cannot).
    pub(crate) fn control_changed(&mut self, control: &jello_core::Control) {
        if let Some(gpu) = &mut self.0 {
            if gpu.set_control(control).is_err() {
                self.clear();
            }
        }
    }

    /// The copy, made from `sim` when there is none (with the GIL released: it compiles the
    /// shaders). `ValueError` for a model the shaders do not cover, `jello.GpuError` when there
    /// is no usable GPU.
    pub(crate) fn make(
        &mut self,
        py: Python<'_>,
        sim: &jello_core::Simulation,
    ) -> PyResult<&mut GpuSimulation> {
        let gpu = match self.0.take() {
            Some(gpu) => gpu,
            None => py
                .detach(|| GpuSimulation::new(&sim.model, &sim.state, &sim.control))
                .map_err(gpu_error)?,
        };
        Ok(self.0.insert(gpu))
    }

    /// The deepest penetration at the end of a step of the last [`Mirror::advance`] (m): the
    /// shaders' measure, the core's `max_penetration`.
    pub(crate) fn deepest(&self) -> f64 {
        self.0.as_ref().map_or(0.0, GpuSimulation::max_penetration)
    }

    /// `n` steps on the GPU with the GIL released, in chunks of at most about [`CHUNK_TIME`]
    /// after each of which the state is read back into `sim`, `after_chunk` is called with it
    /// and Ctrl-C is looked for; on a blow-up, `sim` holds the last good step. `watched`: the
    /// states are compared for points passing through obstacles, so a chunk is at most one
    /// submission of the GPU's (after which it waits for its status anyway).
    pub(crate) fn advance(
        &mut self,
        py: Python<'_>,
        sim: &mut jello_core::Simulation,
        n: u64,
        watched: bool,
        after_chunk: impl FnMut(&jello_core::Simulation),
    ) -> Result<(), Stopped> {
        if let Some(gpu) = &mut self.0 {
            gpu.reset_max_penetration();
        }
        if n == 0 {
            // As on the CPU: nothing to do, and nothing to fail.
            return Ok(());
        }
        let gpu = self.make(py, sim).map_err(Stopped::Raised)?;
        let max_chunk = if watched {
            gpu.batch_steps().min(MAX_CHUNK)
        } else {
            MAX_CHUNK
        };
        let result = chunks(py, gpu, sim, n, max_chunk, after_chunk);
        if let Err(Stopped::Raised(_)) = &result {
            // A failed device (or Ctrl-C): the copy is made anew from the core's state, read
            // back at the last good chunk, on the next step.
            self.clear();
        }
        result
    }
}

/// [`Mirror::advance`] on the copy `gpu`, in chunks of at most `max_chunk` steps.
fn chunks(
    py: Python<'_>,
    gpu: &mut GpuSimulation,
    sim: &mut jello_core::Simulation,
    n: u64,
    max_chunk: u64,
    mut after_chunk: impl FnMut(&jello_core::Simulation),
) -> Result<(), Stopped> {
    let (mut left, mut chunk) = (n, 8.min(max_chunk));
    while left > 0 {
        let take = chunk.min(left);
        let start = Instant::now();
        let outcome = py.detach(|| -> Result<_, jello_gpu::GpuError> {
            let blow_up = match gpu.step(take) {
                Ok(()) => None,
                Err(StepError::BlowUp(b)) => Some(b),
                Err(StepError::Device(e)) => return Err(e),
            };
            // The state after the chunk, or at the last good step of a blow-up.
            Ok((blow_up, gpu.read_state()?))
        });
        let (blow_up, state) = outcome.map_err(|e| Stopped::Raised(gpu_error(e)))?;
        sim.state = state;
        after_chunk(sim);
        if let Some(b) = blow_up {
            return Err(Stopped::BlowUp(Box::new(b)));
        }
        left -= take;
        if start.elapsed() < CHUNK_TIME / 2 {
            chunk = (chunk * 2).min(max_chunk);
        } else if start.elapsed() > CHUNK_TIME * 2 && chunk > 1 {
            chunk /= 2;
        }
        py.check_signals().map_err(Stopped::Raised)?;
    }
    Ok(())
}

/// A model the shaders do not cover, or a state or control that is not valid for it, is the
/// caller's to change (`ValueError`); no usable GPU or a failed one is `jello.GpuError`.
pub(crate) fn gpu_error(e: jello_gpu::GpuError) -> PyErr {
    match e {
        jello_gpu::GpuError::Unsupported(_) | jello_gpu::GpuError::Invalid(_) => {
            PyValueError::new_err(e.to_string())
        }
        jello_gpu::GpuError::NoAdapter(_) | jello_gpu::GpuError::Device(_) => {
            GpuError::new_err(e.to_string())
        }
    }
}
