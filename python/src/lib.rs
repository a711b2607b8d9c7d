//! `jello._jello`: the native half of the Python package `jello`, a thin face over
//! `jello-core` (the physics), `jello-io` (the files) and `jello-gpu` (stepping on a GPU).
//! `jello/__init__.py` re-exports it; `_jello.pyi` types it. No physics here: only conversions
//! between numpy and the core's types, and errors turned into Python exceptions.

mod active;
mod arrays;
mod build;
mod errors;
mod gpu;
mod simulation;
mod tunnelling;

use pyo3::prelude::*;

/// The SIMD tier the force loops run on this CPU: "baseline", "avx2" or "avx512".
#[pyfunction]
fn simd_tier() -> &'static str {
    jello_core::compute::simd::active_tier().name()
}

/// The integrators' names, as `Simulation.integrator` and world files spell them.
#[pyfunction]
fn integrators() -> Vec<&'static str> {
    jello_core::Integrator::ALL
        .iter()
        .map(|i| i.name())
        .collect()
}

#[pymodule]
fn _jello(m: &Bound<'_, PyModule>) -> PyResult<()> {
    let py = m.py();
    // A JELLO_SIMD the core cannot honour is said at import (the core then runs the best tier).
    if let Err(e) = jello_core::compute::simd::tier_from_env() {
        let warnings = py.import("warnings")?;
        warnings.call_method1("warn", (format!("jello: {e}; running the best tier"),))?;
    }
    m.add("BlowUp", py.get_type::<errors::BlowUp>())?;
    m.add("WorldError", py.get_type::<errors::WorldError>())?;
    m.add("GpuError", py.get_type::<errors::GpuError>())?;
    m.add(
        "TunnellingWarning",
        py.get_type::<tunnelling::TunnellingWarning>(),
    )?;
    m.add(
        "OverlapWarning",
        py.get_type::<tunnelling::OverlapWarning>(),
    )?;
    m.add_class::<simulation::Simulation>()?;
    m.add_class::<simulation::Energy>()?;
    m.add_class::<simulation::SolverStats>()?;
    m.add_class::<simulation::ContactWork>()?;
    m.add_class::<build::Body>()?;
    m.add_class::<build::Obstacle>()?;
    m.add_class::<build::Pin>()?;
    m.add_class::<build::Region>()?;
    m.add_function(wrap_pyfunction!(simulation::load, m)?)?;
    m.add_function(wrap_pyfunction!(simulation::loads, m)?)?;
    m.add_function(wrap_pyfunction!(build::cube, m)?)?;
    m.add_function(wrap_pyfunction!(build::mesh, m)?)?;
    m.add_function(wrap_pyfunction!(build::read_mesh, m)?)?;
    m.add_function(wrap_pyfunction!(build::sphere, m)?)?;
    m.add_function(wrap_pyfunction!(build::solid_box, m)?)?;
    m.add_function(wrap_pyfunction!(build::pin, m)?)?;
    m.add_function(wrap_pyfunction!(build::region, m)?)?;
    m.add_function(wrap_pyfunction!(build::create, m)?)?;
    m.add_function(wrap_pyfunction!(simd_tier, m)?)?;
    m.add_function(wrap_pyfunction!(integrators, m)?)?;
    Ok(())
}
