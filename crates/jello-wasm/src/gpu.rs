//! [`JelloGpu`]: a [`JelloSim`]'s model stepped on the GPU through WebGPU, by the same WGSL and
//! the same passes as the native GPU backend (`jello-gpu`, built here on wgpu's WebGPU backend).
//!
//! The simulation stays the page's [`JelloSim`]: it is the f64 copy everything else reads
//! (positions drawn, the skin, saving). [`JelloGpu::step`] steps on the GPU, in f32, and reads the
//! state back; [`JelloSim::adopt_gpu_state`] then makes it the simulation's state, with the
//! blow-up if there was one (the state at the last good step, as on the CPU). A browser may not
//! block, so creating and stepping are promises; while one runs, the others are refused with an
//! error instead of waiting.

use std::cell::RefCell;
use std::rc::Rc;

use jello_core::{BlowUp, State};
use jello_gpu::{GpuError, GpuSimulation, StepError};
use wasm_bindgen::prelude::*;
use wasm_bindgen_futures::future_to_promise;

use crate::{js_err, JelloSim};

/// What a step leaves for [`JelloSim::adopt_gpu_state`]: the state read back, and the blow-up
/// that stopped it.
#[derive(Default)]
struct Outcome {
    state: Option<State>,
    blow_up: Option<BlowUp>,
}

/// The GPU copy, out of its cell while a promise uses it (`None` then).
#[derive(Default)]
struct Shared {
    gpu: Option<GpuSimulation>,
    outcome: Outcome,
}

/// A simulation's model on the GPU (WebGPU, f32). See the module documentation.
#[wasm_bindgen]
pub struct JelloGpu {
    shared: Rc<RefCell<Shared>>,
    kernel: String,
}

const BUSY: &str = "the GPU is still busy with the last request";

impl Shared {
    /// Takes the GPU copy out for a promise; fails while another promise has it.
    fn take(cell: &RefCell<Shared>) -> Result<GpuSimulation, JsError> {
        cell.borrow_mut()
            .gpu
            .take()
            .ok_or_else(|| JsError::new(BUSY))
    }
}

#[wasm_bindgen]
impl JelloGpu {
    /// Uploads `sim`'s model, state and control forces to the first WebGPU adapter; resolves to
    /// the GPU copy. Rejects, with the reason, when this browser has no WebGPU adapter or the
    /// GPU does not step this model (an implicit integrator, more than 224 bodies): the page then
    /// steps on the CPU.
    #[wasm_bindgen(unchecked_return_type = "Promise<JelloGpu>")]
    pub fn create(sim: &JelloSim) -> js_sys::Promise {
        let (model, state, control) = (
            sim.sim.model.clone(),
            sim.sim.state.clone(),
            sim.sim.control.clone(),
        );
        future_to_promise(async move {
            let gpu = GpuSimulation::create(&model, &state, &control)
                .await
                .map_err(|e| JsValue::from(js_err(e)))?;
            let kernel = gpu.kernel().to_string();
            Ok(JelloGpu {
                kernel,
                shared: Rc::new(RefCell::new(Shared {
                    gpu: Some(gpu),
                    outcome: Outcome::default(),
                })),
            }
            .into())
        })
    }

    /// How the shader steps: `resident` (a small lattice inside one workgroup, on a GPU) or
    /// `stages` (a dispatch per stage).
    #[wasm_bindgen(getter)]
    pub fn kernel(&self) -> String {
        self.kernel.clone()
    }

    /// Takes `n` steps, then reads the state back; resolves to the steps taken, fewer than `n`
    /// after a blow-up. [`JelloSim::adopt_gpu_state`] hands the state over. Rejects when the
    /// device fails (its state is then not to be trusted) or a request is still running.
    #[wasm_bindgen(unchecked_return_type = "Promise<number>")]
    pub fn step(&self, n: u32) -> js_sys::Promise {
        let shared = Rc::clone(&self.shared);
        future_to_promise(async move {
            let mut gpu = Shared::take(&shared)?;
            let start = gpu.steps();
            let stepped = gpu.step_async(n as u64).await;
            let read = gpu.read_state_async().await;
            let taken = (gpu.steps() - start) as u32;
            shared.borrow_mut().gpu = Some(gpu);
            let blow_up = match stepped {
                Ok(()) => None,
                Err(StepError::BlowUp(b)) => Some(b),
                Err(StepError::Device(e)) => return Err(js_err(e).into()),
            };
            let state = read.map_err(js_err)?;
            shared.borrow_mut().outcome = Outcome {
                state: Some(state),
                blow_up,
            };
            Ok(JsValue::from(taken))
        })
    }

    /// Replaces the GPU's control forces and pulls with `sim`'s (after a drag or a push).
    /// Throws while a request runs.
    #[wasm_bindgen(js_name = setControl)]
    pub fn set_control(&self, sim: &JelloSim) -> Result<(), JsError> {
        self.with_gpu(|gpu| gpu.set_control(&sim.sim.control))
    }
}

impl JelloGpu {
    fn with_gpu(
        &self,
        f: impl FnOnce(&mut GpuSimulation) -> Result<(), GpuError>,
    ) -> Result<(), JsError> {
        let mut shared = self
            .shared
            .try_borrow_mut()
            .map_err(|_| JsError::new(BUSY))?;
        let gpu = shared.gpu.as_mut().ok_or_else(|| JsError::new(BUSY))?;
        f(gpu).map_err(js_err)
    }
}

#[wasm_bindgen]
impl JelloSim {
    /// Makes the state `gpu` read back after its last step this simulation's state, with the
    /// blow-up that stopped it if one did; returns whether there was a state to take (a second
    /// call, before the next step, finds none).
    #[wasm_bindgen(js_name = adoptGpuState)]
    pub fn adopt_gpu_state(&mut self, gpu: &JelloGpu) -> Result<bool, JsError> {
        let mut shared = gpu
            .shared
            .try_borrow_mut()
            .map_err(|_| JsError::new(BUSY))?;
        let Outcome { state, blow_up } = std::mem::take(&mut shared.outcome);
        let Some(state) = state else {
            return Ok(false);
        };
        if state.pos.len() != self.sim.model.point_count() {
            return Err(JsError::new(
                "the GPU copy is of another simulation (its point count differs)",
            ));
        }
        self.sim.state = state;
        if blow_up.is_some() {
            self.blow_up = blow_up;
        }
        Ok(true)
    }

    /// Why the GPU would not step this simulation (an implicit integrator, ...), or `undefined`
    /// when it would: the page's choice of integrator for a large scene depends on it.
    #[wasm_bindgen(js_name = gpuRefusal)]
    pub fn gpu_refusal(&self) -> Option<String> {
        jello_gpu::unsupported(&self.sim.model, &self.sim.control)
            .map(|what| GpuError::Unsupported(what).to_string())
    }
}
