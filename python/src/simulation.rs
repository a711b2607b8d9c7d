//! `jello.Simulation`: a world or scene being stepped, with its state as numpy arrays; and
//! `jello.load` / `jello.loads`, which make one from a file or its text.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use jello_core::diagnostics::{energy, max_penetration};
use jello_core::model::solver::Newton;
use jello_core::{Integrator, Material, ModelBuilder};
use jello_io::Source;
use numpy::{PyArray1, PyArray2};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PySlice;

use crate::active::ActivePoints;
use crate::arrays::{from_array, to_array};
use crate::errors::{blow_up_error, unreadable, world_error, write_error};
use crate::gpu::{Device, Mirror};
use crate::tunnelling::Watch;

/// How long a step call runs with the GIL released before it takes the GIL back to look for
/// Ctrl-C (and lets other Python threads run their Python code).
const SIGNAL_CHECK_EVERY: Duration = Duration::from_millis(50);

/// Why stepping stopped before the steps asked for; the state is at the last good step.
pub(crate) enum Stopped {
    /// A step blew up.
    BlowUp(Box<jello_core::BlowUp>),
    /// Ctrl-C (or another signal handler's exception) between steps, or on the GPU a device
    /// that failed (`jello.GpuError`) or a model it cannot step (`ValueError`).
    Raised(PyErr),
}

/// A simulation: the model (what does not change), its state (positions, velocities, time) and
/// the forces from outside, stepped by the core or on a GPU (see `gpu.rs`).
#[pyclass(module = "jello", name = "Simulation")]
#[derive(Clone)]
pub struct Simulation {
    pub(crate) sim: jello_core::Simulation,
    /// What it was read from or built as, for `save`.
    pub(crate) source: Source,
    /// The file name (or a label) that starts blow-up messages, as the CLI's do.
    pub(crate) name: String,
    /// Each body's name, in order.
    pub(crate) body_names: Vec<String>,
    /// Each body's material as loaded or built, so that a saved scene records changes to it.
    pub(crate) initial_materials: Vec<Material>,
    /// The points the arrays show (see `active.rs`).
    active: ActivePoints,
    /// Where `step` and `run` compute, and the GPU's copy when that is the GPU.
    device: Device,
    gpu: Mirror,
    /// Points passing through obstacles, watched over every call that steps.
    tunnel: Watch,
}

impl Simulation {
    /// A simulation made from what `jello-io` loaded.
    pub(crate) fn new(sim: jello_core::Simulation, source: Source, name: String) -> Self {
        let body_names = match &source {
            Source::World(_) => vec!["jello".to_string()],
            Source::Scene(file) => file.body_names(),
        };
        let initial_materials = sim.model.bodies().iter().map(|b| b.material).collect();
        let active = ActivePoints::of(&sim.model);
        Simulation {
            sim,
            source,
            name,
            body_names,
            initial_materials,
            active,
            device: Device::Cpu,
            gpu: Mirror::default(),
            tunnel: Watch::default(),
        }
    }

    /// The exception for stepping that stopped: `jello.BlowUp` (with `max_penetration` when
    /// `deepest` is given), or the one raised.
    fn raise(&self, py: Python<'_>, stop: Stopped, deepest: Option<f64>) -> PyErr {
        match stop {
            Stopped::BlowUp(b) => {
                let err = blow_up_error(py, &self.name, &b);
                // `point` is the row of `positions` (the message keeps the lattice's index and
                // coordinates, as the CLI's does); a point at fault is always active.
                if let Some(row) = self.active.row_of(b.point) {
                    let _ = err.value(py).setattr("point", row);
                }
                if let Some(d) = deepest {
                    let _ = err.value(py).setattr("max_penetration", d);
                }
                err
            }
            Stopped::Raised(e) => e,
        }
    }

    /// `n` steps on the device, `after_step` called with the state after each step on the CPU
    /// (after each chunk read back on the GPU), each state watched for points passing through
    /// obstacles, and the `jello.TunnellingWarning`s found warned of. Returns why stepping
    /// stopped, if it did, for [`Simulation::finish`], with the error a warnings filter made of
    /// a warning, if any.
    fn advance_watched(
        &mut self,
        py: Python<'_>,
        n: u64,
        mut after_step: impl FnMut(&jello_core::Simulation) + Send,
    ) -> (Result<(), Stopped>, PyResult<()>) {
        self.tunnel.start(&self.sim);
        // Out of `self` while stepping, which borrows `self` whole.
        let mut tunnel = std::mem::take(&mut self.tunnel);
        let watching = tunnel.watching();
        let mut watched = |sim: &jello_core::Simulation| {
            tunnel.observe(sim);
            after_step(sim);
        };
        let result = match self.device {
            Device::Cpu => self.step_cpu(py, n, &mut watched),
            Device::Gpu => self
                .gpu
                .advance(py, &mut self.sim, n, watching, &mut watched),
        };
        self.tunnel = tunnel;
        // Warned of even when stepping stopped: the state is the last good step's.
        let warned = self
            .tunnel
            .warn(py, &self.sim, &self.name, &self.body_names);
        (result, warned)
    }

    /// The outcome of [`Simulation::advance_watched`]: the exception of stepping that stopped
    /// (see [`Simulation::raise`]; `deepest` as there), else the warning made an error, if any.
    fn finish(
        &self,
        py: Python<'_>,
        (result, warned): (Result<(), Stopped>, PyResult<()>),
        deepest: Option<f64>,
    ) -> PyResult<()> {
        match result {
            Ok(()) => warned,
            Err(stop) => {
                let err = self.raise(py, stop, deepest);
                // A warning a filter made an error is not lost: it caused the raise to follow.
                if let Err(w) = warned {
                    err.set_cause(py, Some(w));
                }
                Err(err)
            }
        }
    }

    /// This simulation set to step on `device` (see `Simulation.device`).
    fn on(mut self, py: Python<'_>, device: Device) -> PyResult<Self> {
        self.set_device(py, device.name())?;
        Ok(self)
    }

    /// The file text of the current state, in the format it was read from or built as.
    fn state_text(&self) -> Result<String, String> {
        match &self.source {
            Source::World(_) => self.source.state_text(&self.sim),
            Source::Scene(file) => {
                let mut file = file.with_state(&self.sim.model, &self.sim.state);
                file.record_materials(&self.sim.model, &self.initial_materials);
                Ok(file.to_toml())
            }
        }
    }

    /// `n` steps with the GIL released, `after_step` called after each, in chunks of about
    /// [`SIGNAL_CHECK_EVERY`] between which Ctrl-C is looked for (a `KeyboardInterrupt` leaves a
    /// whole step). `Err` with the first blow-up, the state at the last good step.
    fn step_cpu(
        &mut self,
        py: Python<'_>,
        n: u64,
        mut after_step: impl FnMut(&jello_core::Simulation) + Send,
    ) -> Result<(), Stopped> {
        let mut left = n;
        while left > 0 {
            let sim = &mut self.sim;
            let (done, result) = py.detach(|| {
                let start = Instant::now();
                let mut done = 0;
                while done < left {
                    if let Err(b) = sim.step() {
                        return (done, Err(b));
                    }
                    after_step(sim);
                    done += 1;
                    if done % 8 == 0 && start.elapsed() >= SIGNAL_CHECK_EVERY {
                        break;
                    }
                }
                (done, Ok(()))
            });
            left -= done;
            result.map_err(|b| Stopped::BlowUp(Box::new(b)))?;
            py.check_signals().map_err(Stopped::Raised)?;
        }
        Ok(())
    }

    /// Rebuilds the model with another integrator or time step; the state and the control carry
    /// on.
    fn rebuild(&mut self, integrator: Integrator, dt: f64) -> PyResult<()> {
        let builder = self.sim.model.to_builder().integrator(integrator).dt(dt);
        self.replace_model(builder)
    }

    /// Builds the model `builder` describes and carries the state and control over to it;
    /// changes nothing when the model is invalid.
    fn replace_model(&mut self, builder: ModelBuilder) -> PyResult<()> {
        let model = builder
            .build()
            .map_err(|e| PyValueError::new_err(e.to_string()))?;
        if self.device == Device::Gpu {
            if let Some(what) = jello_gpu::unsupported(&model, &self.sim.control) {
                return Err(crate::gpu::gpu_error(jello_gpu::GpuError::Unsupported(
                    what,
                )));
            }
        }
        self.gpu.clear();
        self.tunnel.reset();
        let control = std::mem::take(&mut self.sim.control);
        let state = self.sim.state.clone();
        self.sim = jello_core::Simulation::new(model, state);
        self.sim.control = control;
        self.active = ActivePoints::of(&self.sim.model);
        Ok(())
    }
}

#[pymethods]
impl Simulation {
    /// Advances `n` steps with the GIL released. Raises `jello.BlowUp` at the first step that
    /// blows up, leaving the state at the last good step (`steps` says how many were taken);
    /// Ctrl-C stops between steps, leaving a whole step too. Warns `jello.TunnellingWarning`
    /// when points passed through an obstacle (once per body and obstacle).
    #[pyo3(signature = (n = 1))]
    fn step(&mut self, py: Python<'_>, n: i64) -> PyResult<()> {
        let n = step_count(n)?;
        let outcome = self.advance_watched(py, n, |_| {});
        self.finish(py, outcome, None)
    }

    /// Advances `n` steps: `step(n)` under the Rust core's name (`Simulation::advance`), so
    /// that `step` is one step and `advance(n)` is `n` in both.
    fn advance(&mut self, py: Python<'_>, n: i64) -> PyResult<()> {
        self.step(py, n)
    }

    /// Steps `n` times as `step` does and returns the deepest penetration (m) into a wall, the
    /// plane or an obstacle at the start and after every step, as `jello run` reports it. A
    /// `jello.BlowUp` carries it as `max_penetration`, up to the last good step. At its end, as
    /// `jello run` at its end, warns `jello.OverlapWarning` for two bodies deeper inside each
    /// other than half the finer of their cells (once per pair until the model changes).
    fn run(&mut self, py: Python<'_>, n: i64) -> PyResult<f64> {
        let n = step_count(n)?;
        let mut deepest = max_penetration(&self.sim.model, &self.sim.state.pos);
        // Read off every step on the CPU; on the GPU the shaders track it.
        let on_cpu = self.device == Device::Cpu;
        let outcome = self.advance_watched(py, n, |sim| {
            if on_cpu {
                deepest = deepest.max(max_penetration(&sim.model, &sim.state.pos));
            }
        });
        if !on_cpu {
            deepest = deepest.max(self.gpu.deepest());
        }
        self.finish(py, outcome, Some(deepest))?;
        (self.tunnel)
            .warn_overlaps(py, &self.sim, &self.name, &self.body_names)
            .map(|()| deepest)
    }

    /// Sets the springs' stiffness (N/m) and damping (N·s/m), a number or one per kind
    /// (structural, shear, bend), and the mass of each point (kg), of every body or of body
    /// number `body`; what is not given stays. The state carries on.
    #[pyo3(signature = (*, stiffness = None, damping = None, mass = None, body = None))]
    fn set_material(
        &mut self,
        stiffness: Option<&Bound<'_, PyAny>>,
        damping: Option<&Bound<'_, PyAny>>,
        mass: Option<f64>,
        body: Option<usize>,
    ) -> PyResult<()> {
        let stiffness = stiffness
            .map(|v| crate::build::one_or_three(v, "stiffness"))
            .transpose()?;
        let damping = damping
            .map(|v| crate::build::one_or_three(v, "damping"))
            .transpose()?;
        let mut bodies = self.sim.model.bodies().to_vec();
        if let Some(b) = body {
            if b >= bodies.len() {
                return Err(PyValueError::new_err(format!(
                    "body: {b} does not exist (there are {})",
                    bodies.len()
                )));
            }
        }
        for (b, spec) in bodies.iter_mut().enumerate() {
            if body.is_some_and(|only| only != b) {
                continue;
            }
            let m = &mut spec.material;
            if let Some(k) = stiffness {
                m.stiffness = k;
            }
            if let Some(d) = damping {
                m.damping = d;
            }
            if let Some(mass) = mass {
                m.mass = mass;
            }
        }
        self.replace_model(self.sim.model.to_builder().bodies(bodies))
    }

    /// Sets the penalty springs' stiffness (N/m) and damping (N·s/m) of the walls, the plane,
    /// obstacles and contacts between bodies; what is not given stays.
    #[pyo3(signature = (*, stiffness = None, damping = None))]
    fn set_collision(&mut self, stiffness: Option<f64>, damping: Option<f64>) -> PyResult<()> {
        let model = &self.sim.model;
        let builder = model.to_builder().collision(
            stiffness.unwrap_or(model.k_collision),
            damping.unwrap_or(model.d_collision),
        );
        self.replace_model(builder)
    }

    /// The current state as the text of a world file (a world) or scene file (a scene), as
    /// `save` writes it.
    fn dumps(&self) -> PyResult<String> {
        self.state_text()
            .map_err(|e| PyValueError::new_err(format!("{}: {e}", self.name)))
    }

    /// Positions (m) of the active points, a new `(n, 3)` float64 array each time; assign an
    /// `(n, 3)` array to move them.
    #[getter]
    fn positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        to_array(py, &self.active.gather(&self.sim.state.pos))
    }

    #[setter]
    fn set_positions(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let values = from_array(value, self.active.len(), "positions")?;
        self.active.scatter(values, &mut self.sim.state.pos);
        self.gpu.state_changed(&self.sim.state);
        self.tunnel.restart();
        Ok(())
    }

    /// Velocities (m/s) of the active points, a new `(n, 3)` float64 array each time; assign to
    /// set them.
    #[getter]
    fn velocities<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        to_array(py, &self.active.gather(&self.sim.state.vel))
    }

    #[setter]
    fn set_velocities(&mut self, value: &Bound<'_, PyAny>) -> PyResult<()> {
        let values = from_array(value, self.active.len(), "velocities")?;
        self.active.scatter(values, &mut self.sim.state.vel);
        self.gpu.state_changed(&self.sim.state);
        Ok(())
    }

    /// Positions (m) of every lattice point, active or not, in lattice order: a body voxelised
    /// from a mesh keeps a regular lattice whose points outside its cells never move (`active`
    /// says which). Read only; `positions` is the same without them.
    #[getter]
    fn lattice_positions<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray2<f64>> {
        to_array(py, &self.sim.state.pos)
    }

    /// Per lattice point (the rows of `lattice_positions`), whether it is active: a new bool
    /// array; `lattice_positions[sim.active]` is `positions`.
    #[getter]
    fn active<'py>(&self, py: Python<'py>) -> Bound<'py, PyArray1<bool>> {
        PyArray1::from_vec(py, self.active.mask())
    }

    /// Extra force on each active point (N), held through every step until changed: an
    /// `(n, 3)` array, or `None` for none.
    #[getter]
    fn control_forces<'py>(&self, py: Python<'py>) -> Option<Bound<'py, PyArray2<f64>>> {
        let forces = &self.sim.control.forces;
        (!forces.is_empty()).then(|| to_array(py, &self.active.gather(forces)))
    }

    #[setter]
    fn set_control_forces(&mut self, value: Option<&Bound<'_, PyAny>>) -> PyResult<()> {
        self.sim.control.forces = match value {
            None => Vec::new(),
            Some(v) => {
                let values = from_array(v, self.active.len(), "control_forces")?;
                // The inactive points never move: no force on them.
                let mut all = vec![jello_core::Vec3::ZERO; self.sim.state.pos.len()];
                self.active.scatter(values, &mut all);
                all
            }
        };
        self.gpu.control_changed(&self.sim.control);
        Ok(())
    }

    /// Where `step` and `run` compute: "cpu" (the f64 core, the default) or "gpu" (f32 WGSL
    /// shaders through wgpu: the explicit integrators, with bodies, obstacles, friction and pulls;
    /// not pins on paths). Assign to change it: "gpu" raises `ValueError` for a model the GPU does not cover
    /// and `jello.GpuError` when there is no usable GPU, leaving the device as it was. On the
    /// GPU the state is read back after every call (and every 50 ms or so within one), so every
    /// property reads as on the CPU, rounded to f32.
    #[getter]
    fn device(&self) -> &'static str {
        self.device.name()
    }

    #[setter]
    fn set_device(&mut self, py: Python<'_>, name: &str) -> PyResult<()> {
        let device = Device::parse(name)?;
        if device == Device::Gpu {
            self.gpu.make(py, &self.sim)?;
        } else {
            self.gpu.clear();
        }
        self.device = device;
        Ok(())
    }

    /// The GPU `step` and `run` use ("NVIDIA H100 (Vulkan)", "llvmpipe (LLVM 15.0.6, 256 bits)
    /// (Vulkan)"), or None on the CPU.
    #[getter]
    fn adapter(&mut self, py: Python<'_>) -> PyResult<Option<String>> {
        if self.device == Device::Cpu {
            return Ok(None);
        }
        Ok(Some(self.gpu.make(py, &self.sim)?.adapter()))
    }

    /// Simulated time (s).
    #[getter]
    fn time(&self) -> f64 {
        self.sim.state.time
    }

    /// Steps taken since the state was loaded.
    #[getter]
    fn steps(&self) -> u64 {
        self.sim.state.steps
    }

    /// Number of active points (the rows of `positions`; `jello info` counts the same).
    #[getter]
    fn point_count(&self) -> usize {
        self.active.len()
    }

    fn __len__(&self) -> usize {
        self.active.len()
    }

    /// Time step (s); assign to change it (the state carries on).
    #[getter]
    fn dt(&self) -> f64 {
        self.sim.model.dt
    }

    #[setter]
    fn set_dt(&mut self, dt: f64) -> PyResult<()> {
        if !(dt.is_finite() && dt > 0.0) {
            return Err(PyValueError::new_err(format!(
                "dt: expected a positive time step (s), found {dt}"
            )));
        }
        self.rebuild(self.sim.model.integrator, dt)
    }

    /// Integrator name ("Euler", "RK2", "RK4", "SymplecticEuler", "BackwardEuler", "SDIRK2");
    /// assign a name (any case, aliases as in world files) to change it.
    #[getter]
    fn integrator(&self) -> &'static str {
        self.sim.model.integrator.name()
    }

    #[setter]
    fn set_integrator(&mut self, name: &str) -> PyResult<()> {
        let integrator = name
            .parse::<Integrator>()
            .map_err(|e| PyValueError::new_err(format!("integrator: {e}")))?;
        self.rebuild(integrator, self.sim.model.dt)
    }

    /// How many times an implicit step whose solve fails may be halved (taken again as 2, 4, …
    /// 2^n substeps of the same method) before `step` raises `jello.BlowUp`; 0 raises at once.
    /// Assign to change it (at most 20; the state carries on).
    #[getter]
    fn cutbacks(&self) -> u32 {
        self.sim.model.newton.cutbacks
    }

    #[setter]
    fn set_cutbacks(&mut self, n: u32) -> PyResult<()> {
        let newton = Newton {
            cutbacks: n,
            ..self.sim.model.newton
        };
        self.replace_model(self.sim.model.to_builder().newton(newton))
    }

    /// The residual an implicit integrator solves each step to, per point (m/s, times the
    /// fastest point's speed when that is above 1 m/s). 1e-9 by default; assign a looser one
    /// (at most 0.1) to trade exactness for speed. Not used by the explicit integrators.
    #[getter]
    fn tolerance(&self) -> f64 {
        self.sim.model.newton.tolerance
    }

    #[setter]
    fn set_tolerance(&mut self, tolerance: f64) -> PyResult<()> {
        let newton = Newton {
            tolerance,
            ..self.sim.model.newton
        };
        self.replace_model(self.sim.model.to_builder().newton(newton))
    }

    /// Steps an implicit integrator took in parts (see `cutbacks`) since the model last changed.
    #[getter]
    fn split_steps(&self) -> u64 {
        self.sim.cutback_stats().split_steps
    }

    /// Wall-clock seconds the steps spent on contacts between bodies (finding them, and their
    /// forces) since the model last changed: with the time of the steps, the contact pass's
    /// share (0 for a model whose surfaces cannot touch, and on the GPU).
    #[getter]
    fn contact_seconds(&self) -> f64 {
        self.sim.contact_time().as_secs_f64()
    }

    /// The implicit solver's work since the model last changed: solves, Newton and
    /// conjugate-gradient iterations, assemblies of its matrix (all zero under an explicit
    /// integrator or on the GPU).
    #[getter]
    fn solver_stats(&self) -> SolverStats {
        let s = self.sim.solver_stats();
        SolverStats {
            solves: s.solves,
            newton_iterations: s.newton_iterations,
            linear_iterations: s.linear_iterations,
            assemblies: s.assemblies,
        }
    }

    /// The contact passes' work between bodies since the model last changed, counted: the same
    /// on any machine and thread count, where `contact_seconds` drifts (all zero for a model
    /// whose surfaces cannot touch, and on the GPU).
    #[getter]
    fn contact_work(&self) -> ContactWork {
        let w = self.sim.contact_work();
        ContactWork {
            passes: w.passes,
            sorts: w.sorts,
            listed: w.listed,
            placed: w.placed,
            placings: w.placings,
            touches: w.touches,
        }
    }

    /// Steps per displayed frame (the world file's `n`).
    #[getter]
    fn steps_per_frame(&self) -> u32 {
        self.sim.model.steps_per_frame
    }

    /// The file this simulation was read from, or the label it was given.
    #[getter]
    fn name(&self) -> &str {
        &self.name
    }

    /// The bodies, in order: each one's name and the slice of its points in `positions`.
    #[getter]
    fn bodies<'py>(&self, py: Python<'py>) -> PyResult<Vec<(String, Bound<'py, PySlice>)>> {
        Ok(self
            .active
            .body_ranges()
            .iter()
            .zip(&self.body_names)
            .map(|(r, name)| {
                (
                    name.clone(),
                    PySlice::new(py, r.start as isize, r.end as isize, 1),
                )
            })
            .collect())
    }

    /// Kinetic, spring and collision energy (J) of the current state.
    fn energy(&self) -> Energy {
        let e = energy(&self.sim.model, &self.sim.state);
        Energy {
            kinetic: e.kinetic,
            spring: e.spring,
            collision: e.collision,
        }
    }

    /// How far the deepest point is inside a wall, the plane or an obstacle (m); 0 when none is.
    fn max_penetration(&self) -> f64 {
        max_penetration(&self.sim.model, &self.sim.state.pos)
    }

    /// Saves the current state: a world file (`.w`) for a world, a scene file (`.toml`) for a
    /// scene, written whole or not at all. Raises `ValueError` for the wrong extension and
    /// `OSError` when it cannot be written.
    fn save(&self, path: PathBuf) -> PyResult<()> {
        let scene = matches!(self.source, Source::Scene(_));
        if scene != jello_io::is_scene(&path) {
            return Err(PyValueError::new_err(format!(
                "{}: a {} saves as {}",
                path.display(),
                if scene { "scene" } else { "world" },
                if scene { ".toml" } else { ".w" }
            )));
        }
        jello_io::check_writable_target(&path).map_err(|e| write_error(e.message))?;
        let text = self
            .state_text()
            .map_err(|e| write_error(format!("{}: {e}", path.display())))?;
        jello_io::write_atomic(&path, text.as_bytes()).map_err(|e| write_error(e.message))
    }

    /// An independent copy (model, state and control).
    fn copy(&self) -> Simulation {
        self.clone()
    }

    fn __copy__(&self) -> Simulation {
        self.clone()
    }

    fn __deepcopy__(&self, _memo: &Bound<'_, PyAny>) -> Simulation {
        self.clone()
    }

    fn __repr__(&self) -> String {
        format!(
            "Simulation({:?}, {} points, {}, dt={}, t={}{})",
            self.name,
            self.active.len(),
            self.sim.model.integrator.name(),
            self.sim.model.dt,
            self.sim.state.time,
            match self.device {
                Device::Cpu => "",
                Device::Gpu => ", device='gpu' (f32)",
            }
        )
    }
}

/// Kinetic, spring and collision energy (J); `total` is their sum.
#[pyclass(module = "jello", frozen, get_all)]
#[derive(Clone, Copy)]
pub struct Energy {
    /// `Σ ½ m |v|²`.
    pub kinetic: f64,
    /// `Σ ½ k (|L| − R)²` over the springs.
    pub spring: f64,
    /// `Σ ½ kCollision depth²` over the walls, plane, obstacles and contacts between bodies.
    pub collision: f64,
}

#[pymethods]
impl Energy {
    /// Kinetic plus potential energy (J).
    #[getter]
    fn total(&self) -> f64 {
        self.kinetic + self.spring + self.collision
    }

    fn __repr__(&self) -> String {
        format!(
            "Energy(kinetic={:e}, spring={:e}, collision={:e}, total={:e})",
            self.kinetic,
            self.spring,
            self.collision,
            self.total()
        )
    }
}

/// The contact passes' work between bodies (see `Simulation.contact_work`), summed over the
/// passes.
#[pyclass(module = "jello", frozen, get_all)]
#[derive(Clone, Copy)]
pub struct ContactWork {
    /// Contact passes: one each time the forces between bodies are found (four a step of
    /// `RK4`), or an implicit step's touches are.
    pub passes: u64,
    /// Sorts of the broad phase's grid, each listing anew the samples that may touch.
    pub sorts: u64,
    /// Samples listed, summed over the sorts.
    pub listed: u64,
    /// Listed samples looked for in their cells, summed over the passes.
    pub placed: u64,
    /// Cells a sample was sought in, summed over the passes.
    pub placings: u64,
    /// Touches found, summed over the passes.
    pub touches: u64,
}

#[pymethods]
impl ContactWork {
    fn __repr__(&self) -> String {
        format!(
            "ContactWork(passes={}, sorts={}, listed={}, placed={}, placings={}, touches={})",
            self.passes, self.sorts, self.listed, self.placed, self.placings, self.touches
        )
    }
}

/// The implicit solver's work (see `Simulation.solver_stats`), counted over every try of a
/// step, those that failed and were cut back included.
#[pyclass(module = "jello", frozen, get_all)]
#[derive(Clone, Copy)]
pub struct SolverStats {
    /// Backward-Euler solves: one a step of `BackwardEuler`, two of `SDIRK2`, more where a
    /// step was taken in parts.
    pub solves: u64,
    /// Newton iterations over all the solves.
    pub newton_iterations: u64,
    /// Conjugate-gradient (or GMRES) iterations over all the Newton iterations.
    pub linear_iterations: u64,
    /// Times the Newton matrix was assembled and its multigrid set up.
    pub assemblies: u64,
}

#[pymethods]
impl SolverStats {
    fn __repr__(&self) -> String {
        format!(
            "SolverStats(solves={}, newton_iterations={}, linear_iterations={}, assemblies={})",
            self.solves, self.newton_iterations, self.linear_iterations, self.assemblies
        )
    }
}

/// An integrator by name, for the loaders' keyword.
/// The number of steps `n` of `step`, `advance` or `run`: a `ValueError` naming the argument for
/// a negative one (rather than the `OverflowError` of an unsigned conversion).
fn step_count(n: i64) -> PyResult<u64> {
    u64::try_from(n).map_err(|_| {
        PyValueError::new_err(format!("n: the number of steps must be 0 or more, not {n}"))
    })
}

fn parse_integrator(name: Option<&str>) -> PyResult<Option<Integrator>> {
    name.map(|n| {
        n.parse::<Integrator>()
            .map_err(|e| PyValueError::new_err(format!("integrator: {e}")))
    })
    .transpose()
}

/// A positive time step, for the loaders' keyword.
fn check_dt(dt: Option<f64>) -> PyResult<Option<f64>> {
    match dt {
        Some(d) if !(d.is_finite() && d > 0.0) => Err(PyValueError::new_err(format!(
            "dt: expected a positive time step (s), found {d}"
        ))),
        d => Ok(d),
    }
}

/// Reads a world file (`.w`) or a scene file (`.toml`), with the integrator and time step
/// replaced when given, to step on `device` ("cpu" or "gpu", as `Simulation.device`). Raises
/// `jello.WorldError` naming the file and line for a bad file and `FileNotFoundError` (or another
/// `OSError`) for one that cannot be read.
#[pyfunction]
#[pyo3(signature = (path, *, integrator = None, dt = None, device = "cpu"))]
pub fn load(
    py: Python<'_>,
    path: PathBuf,
    integrator: Option<&str>,
    dt: Option<f64>,
    device: &str,
) -> PyResult<Simulation> {
    let device = Device::parse(device)?;
    let integrator = parse_integrator(integrator)?;
    let dt = check_dt(dt)?;
    if let Some(err) = unreadable(&path) {
        return Err(err);
    }
    let name = path.display().to_string();
    let (sim, source) = jello_io::load(&path, integrator, dt)
        .map_err(|e| world_error(py, e.message, Some(&name)))?;
    Simulation::new(sim, source, name).on(py, device)
}

/// Reads a world (`format="w"`) or a scene (`format="toml"`) from its text, `name` labelling
/// errors and blow-ups; otherwise as `load`.
#[pyfunction]
#[pyo3(signature = (
    text, *, format = "w", name = "<string>", integrator = None, dt = None, device = "cpu"
))]
#[allow(clippy::too_many_arguments)]
pub fn loads(
    py: Python<'_>,
    text: &Bound<'_, PyAny>,
    format: &str,
    name: &str,
    integrator: Option<&str>,
    dt: Option<f64>,
    device: &str,
) -> PyResult<Simulation> {
    let device = Device::parse(device)?;
    let integrator = parse_integrator(integrator)?;
    let dt = check_dt(dt)?;
    let scene = match format.trim_start_matches('.').to_ascii_lowercase().as_str() {
        "w" => false,
        "toml" => true,
        other => {
            return Err(PyValueError::new_err(format!(
                "format: expected \"w\" (a world) or \"toml\" (a scene), found {other:?}"
            )))
        }
    };
    let bytes: Vec<u8> = match text.extract::<String>() {
        Ok(s) => s.into_bytes(),
        Err(_) => text.extract::<Vec<u8>>().map_err(|_| {
            PyValueError::new_err("text: expected str or bytes holding a world or scene file")
        })?,
    };
    let (sim, source) = jello_io::load_bytes(&bytes, name, scene, integrator, dt)
        .map_err(|e| world_error(py, e.message, Some(name)))?;
    Simulation::new(sim, source, name.to_string()).on(py, device)
}
