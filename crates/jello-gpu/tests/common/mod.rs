//! What the GPU tests share: opening a GPU simulation (failing, not skipping, without an
//! adapter), the core's run to compare with, and the distance between two states.

#![allow(dead_code)]

use jello_core::diagnostics::energy;
use jello_core::{Control, Model, Simulation, State};
use jello_gpu::{GpuError, GpuSimulation};

pub fn gpu(model: &Model, state: &State, control: &Control) -> GpuSimulation {
    match GpuSimulation::new(model, state, control) {
        Ok(sim) => sim,
        Err(e @ GpuError::NoAdapter(_)) => {
            panic!("{e}: these tests need one (scripts/setup.sh installs lavapipe)")
        }
        Err(e) => panic!("{e}"),
    }
}

pub fn cpu(model: &Model, state: &State, control: &Control, steps: u64) -> State {
    let mut sim = Simulation::new(model.clone(), state.clone());
    sim.control = control.clone();
    for _ in 0..steps {
        sim.step().expect("the CPU run is stable");
    }
    sim.state
}

pub fn largest_gap(a: &State, b: &State) -> f64 {
    a.pos
        .iter()
        .zip(&b.pos)
        .map(|(p, q)| (*p - *q).length())
        .fold(0.0, f64::max)
}

/// Fails unless the total energy of `on_gpu` is within 1 % of the core's `reference` (`what`
/// labels the message).
pub fn assert_same_energy(model: &Model, on_gpu: &State, reference: &State, what: &str) {
    let (e_gpu, e_cpu) = (
        energy(model, on_gpu).total(),
        energy(model, reference).total(),
    );
    assert!(
        (e_gpu - e_cpu).abs() <= 0.01 * e_cpu.abs(),
        "{what}energy {e_gpu} on the GPU, {e_cpu} on the core"
    );
}
