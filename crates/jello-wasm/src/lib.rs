//! # jello-wasm
//!
//! A thin [wasm-bindgen] wrapper of `jello-core` for the browser viewer: [`JelloSim`] holds a
//! [`Simulation`] and hands the page what it draws (positions, surface triangles, springs by
//! kind, plane, field samples) and what it changes (parameters, drag forces). No physics lives
//! here or in TypeScript; every step is `jello_core::step`.
//!
//! Errors reach JavaScript as exceptions whose message is the core's (a bad world file names the
//! file, the line and what was expected). A blow-up is not an exception: [`JelloSim::step`]
//! stops, the state stays at the last good step (the core guarantees it), and
//! [`JelloSim::blow_up_message`] and [`JelloSim::suggested_dt`] say what happened.
//!
//! [wasm-bindgen]: https://rustwasm.github.io/wasm-bindgen/

#![warn(missing_docs)]

use jello_core::stability;
use jello_core::{
    Aabb, BlowUp, BlowUpCause, ForceField, Integrator, Lattice, Model, ModelBuilder, ReadOptions,
    Simulation, SpringKind, State, Vec3, World,
};
use wasm_bindgen::prelude::*;

/// A simulation the page drives: the model and state being stepped, the world it was loaded
/// from (for reset), and what the renderer needs that never changes while stepping.
#[wasm_bindgen]
pub struct JelloSim {
    sim: Simulation,
    /// Model and state as loaded, restored by [`JelloSim::reset`].
    initial: (Model, State),
    /// Label of the source (a file name), for messages.
    name: String,
    /// The blow-up that stopped stepping, until a reset or a parameter change.
    blow_up: Option<BlowUp>,
    /// Surface triangles, 3 point indices each (fixed by the lattice).
    triangles: Vec<u32>,
    /// Surface points (flat indices).
    surface: Vec<u32>,
    /// Spring end pairs `[a0, b0, a1, b1, …]` per kind, only springs whose ends are both on the
    /// surface (what the wireframe draws).
    surface_springs: [Vec<u32>; 3],
}

/// Turns a core error into a JavaScript `Error` with the same message.
fn js_err(e: impl std::fmt::Display) -> JsError {
    JsError::new(&e.to_string())
}

#[wasm_bindgen]
impl JelloSim {
    /// A simulation of the world file `text`; `name` labels error messages (`name:line: …`).
    /// Throws with the reader's message when the file is not a valid world.
    #[wasm_bindgen(js_name = fromWorld)]
    pub fn from_world(text: &str, name: &str) -> Result<JelloSim, JsError> {
        let world = World::parse(text.as_bytes(), name, ReadOptions::default()).map_err(js_err)?;
        let (model, state) = world
            .to_simulation()
            .map_err(|e| js_err(format!("{name}: {e}")))?;
        Ok(JelloSim::new(model, state, name))
    }

    /// A benchmark scene: an `n × n × n` lattice of side 1 m and total mass 1 kg with the classic
    /// springs (k = 200 N/m, d = 0.25 N·s/m), dropped from rest under gravity (9.81 m/s²) in the
    /// classic box, stepped by RK4 at the classic dt 0.0005 s or 90 % of the stability estimate
    /// when that is smaller. `n = 8` is the classic cube.
    pub fn cube(n: usize) -> Result<JelloSim, JsError> {
        if !(2..=64).contains(&n) {
            return Err(js_err(format!("lattice side {n} must be between 2 and 64")));
        }
        let mass = 1.0 / (n * n * n) as f64;
        let gravity = Vec3::new(0.0, 0.0, -9.81 * mass);
        let field = ForceField::from_fn(2, Aabb::classic(), |_| gravity).map_err(js_err)?;
        let builder = ModelBuilder::new()
            .lattice(Lattice::new([n; 3], Vec3::new(1.0, 1.0, 1.0)))
            .mass(mass)
            .field(Some(field));
        let probe = builder.clone().build().map_err(js_err)?;
        let dt = f64::min(
            jello_core::defaults::DT,
            0.9 * stability::stable_dt(&probe, Integrator::Rk4),
        );
        let model = builder.dt(dt).build().map_err(js_err)?;
        // Centred over the floor, a little above the middle of the box.
        let mut state = State::at_rest(&model);
        for p in &mut state.pos {
            *p += Vec3::new(-0.5, -0.5, 0.0);
        }
        Ok(JelloSim::new(model, state, &format!("cube {n}³")))
    }

    /// Takes up to `n` steps; returns how many were taken. Fewer than `n` means the simulation
    /// blew up (see [`JelloSim::blow_up_message`]); after that it takes none until a reset or a
    /// parameter change.
    pub fn step(&mut self, n: u32) -> u32 {
        if self.blow_up.is_some() {
            return 0;
        }
        for taken in 0..n {
            if let Err(e) = self.sim.step() {
                self.blow_up = Some(e);
                return taken;
            }
        }
        n
    }

    /// Back to the world as loaded: model (parameters) and state; clears forces and any blow-up.
    pub fn reset(&mut self) {
        let (model, state) = self.initial.clone();
        self.sim = Simulation::new(model, state);
        self.blow_up = None;
    }

    /// Label of the loaded world (its file name).
    #[wasm_bindgen(getter)]
    pub fn name(&self) -> String {
        self.name.clone()
    }

    /// Number of mass points.
    #[wasm_bindgen(getter, js_name = pointCount)]
    pub fn point_count(&self) -> usize {
        self.sim.model.point_count()
    }

    /// Points per axis `[nx, ny, nz]`.
    #[wasm_bindgen(getter)]
    pub fn counts(&self) -> Vec<u32> {
        self.sim
            .model
            .body(0)
            .lattice()
            .counts
            .map(|c| c as u32)
            .to_vec()
    }

    /// Positions `[x0, y0, z0, x1, …]` (m), a copy as a `Float32Array` (what the GPU takes).
    pub fn positions(&self) -> Vec<f32> {
        let mut out = Vec::with_capacity(3 * self.sim.state.pos.len());
        for p in &self.sim.state.pos {
            out.extend_from_slice(&[p.x as f32, p.y as f32, p.z as f32]);
        }
        out
    }

    /// Velocities `[vx0, vy0, vz0, …]` (m/s) as a `Float64Array` copy (for damping a drag).
    pub fn velocities(&self) -> Vec<f64> {
        self.sim
            .state
            .vel
            .iter()
            .flat_map(|v| v.to_array())
            .collect()
    }

    /// Rest positions of the lattice `[x0, y0, z0, …]` (m), for the falloff of a grab.
    #[wasm_bindgen(js_name = restPositions)]
    pub fn rest_positions(&self) -> Vec<f32> {
        let rest = self.sim.model.body(0).rest_positions();
        rest.iter()
            .flat_map(|p| [p.x as f32, p.y as f32, p.z as f32])
            .collect()
    }

    /// Surface triangles as point indices, three per triangle, wound outwards.
    #[wasm_bindgen(js_name = surfaceTriangles)]
    pub fn surface_triangles(&self) -> Vec<u32> {
        self.triangles.clone()
    }

    /// Indices of the surface points.
    #[wasm_bindgen(js_name = surfacePoints)]
    pub fn surface_points(&self) -> Vec<u32> {
        self.surface.clone()
    }

    /// End pairs `[a0, b0, a1, b1, …]` of the springs of `kind` (0 structural, 1 shear, 2 bend)
    /// whose two ends are surface points. Throws for another kind.
    #[wasm_bindgen(js_name = surfaceSprings)]
    pub fn surface_springs(&self, kind: u32) -> Result<Vec<u32>, JsError> {
        self.surface_springs
            .get(kind as usize)
            .cloned()
            .ok_or_else(|| js_err(format!("spring kind {kind} is not 0, 1 or 2")))
    }

    /// The bounding box `[minx, miny, minz, maxx, maxy, maxz]` (m).
    #[wasm_bindgen(js_name = boundingBox)]
    pub fn bounding_box(&self) -> Vec<f64> {
        let b = self.sim.model.bounds;
        [b.min.to_array(), b.max.to_array()].concat()
    }

    /// The inclined plane `[a, b, c, d]` of `a x + b y + c z + d = 0`, or `undefined` when absent.
    pub fn plane(&self) -> Option<Vec<f64>> {
        self.sim.model.plane.map(|p| p.coeffs.to_vec())
    }

    /// Force field resolution (nodes per axis); 0 when there is no field.
    #[wasm_bindgen(getter, js_name = fieldRes)]
    pub fn field_res(&self) -> usize {
        self.sim.model.field.as_ref().map_or(0, |f| f.res())
    }

    /// Field nodes `[x, y, z, fx, fy, fz, …]` (m and N), `i` outermost; empty without a field.
    #[wasm_bindgen(js_name = fieldSamples)]
    pub fn field_samples(&self) -> Vec<f32> {
        let Some(field) = &self.sim.model.field else {
            return Vec::new();
        };
        let res = field.res();
        let mut out = Vec::with_capacity(6 * res * res * res);
        for (n, f) in field.forces().iter().enumerate() {
            let p = field.node_position([n / (res * res), (n / res) % res, n % res]);
            out.extend([p.x, p.y, p.z, f.x, f.y, f.z].map(|v| v as f32));
        }
        out
    }

    /// Integrator name (`Euler`, `RK2`, `RK4`, `SymplecticEuler`).
    #[wasm_bindgen(getter)]
    pub fn integrator(&self) -> String {
        self.sim.model.integrator.name().to_string()
    }

    /// Every integrator name, in the order to list them.
    #[wasm_bindgen(js_name = integratorNames)]
    pub fn integrator_names() -> Vec<String> {
        Integrator::ALL
            .iter()
            .map(|i| i.name().to_string())
            .collect()
    }

    /// Time step (s).
    #[wasm_bindgen(getter)]
    pub fn dt(&self) -> f64 {
        self.sim.model.dt
    }

    /// Structural spring stiffness (N/m); every kind has it in a world file.
    #[wasm_bindgen(getter)]
    pub fn stiffness(&self) -> f64 {
        self.sim.model.body(0).material.stiffness[SpringKind::Structural as usize]
    }

    /// Structural spring damping (N·s/m).
    #[wasm_bindgen(getter)]
    pub fn damping(&self) -> f64 {
        self.sim.model.body(0).material.damping[SpringKind::Structural as usize]
    }

    /// Mass of each point (kg).
    #[wasm_bindgen(getter)]
    pub fn mass(&self) -> f64 {
        self.sim.model.body(0).material.mass
    }

    /// Simulated time (s) since load or reset.
    #[wasm_bindgen(getter)]
    pub fn time(&self) -> f64 {
        self.sim.state.time
    }

    /// Steps taken since load or reset.
    #[wasm_bindgen(getter)]
    pub fn steps(&self) -> f64 {
        self.sim.state.steps as f64
    }

    /// Largest stable time step (s) of the current integrator for this model at rest (see
    /// `jello_core::stability`); 0 when none is stable.
    #[wasm_bindgen(js_name = stableDt)]
    pub fn stable_dt(&self) -> f64 {
        stability::stable_dt(&self.sim.model, self.sim.model.integrator)
    }

    /// Sets integrator, time step, stiffness and damping (every spring kind) and point mass by
    /// building a new model that keeps everything else; the state (positions, velocities, time)
    /// carries on. Clears a blow-up, so stepping resumes from the last good state. Throws, and
    /// changes nothing, when a value is out of range or the integrator is unknown.
    #[wasm_bindgen(js_name = setParameters)]
    pub fn set_parameters(
        &mut self,
        integrator: &str,
        dt: f64,
        stiffness: f64,
        damping: f64,
        mass: f64,
    ) -> Result<(), JsError> {
        let integrator = integrator.parse::<Integrator>().map_err(js_err)?;
        let model = self
            .sim
            .model
            .to_builder()
            .integrator(integrator)
            .dt(dt)
            .elastic(stiffness, damping)
            .mass(mass)
            .build()
            .map_err(js_err)?;
        let control = std::mem::take(&mut self.sim.control);
        let state = self.sim.state.clone();
        self.sim = Simulation::new(model, state);
        self.sim.control = control;
        self.blow_up = None;
        Ok(())
    }

    /// Sets an outside force on every point (N), `[fx0, fy0, fz0, …]`, held until changed; an
    /// empty array removes them. Throws when the length is not 3 × the point count or a force is
    /// not finite.
    #[wasm_bindgen(js_name = setForces)]
    pub fn set_forces(&mut self, forces: &[f64]) -> Result<(), JsError> {
        if forces.is_empty() {
            self.sim.control.forces.clear();
            return Ok(());
        }
        let n = self.point_count();
        if forces.len() != 3 * n {
            return Err(js_err(format!(
                "expected {} force components (3 per point), got {}",
                3 * n,
                forces.len()
            )));
        }
        if forces.iter().any(|f| !f.is_finite()) {
            return Err(js_err("forces must be finite"));
        }
        self.sim.control.forces.clear();
        self.sim
            .control
            .forces
            .extend(forces.chunks_exact(3).map(|c| Vec3::new(c[0], c[1], c[2])));
        Ok(())
    }

    /// The current state as world-file text. Throws for what the format cannot hold (a lattice
    /// other than the classic 8³ cube).
    #[wasm_bindgen(js_name = toWorldText)]
    pub fn to_world_text(&self) -> Result<String, JsError> {
        Ok(self.sim.to_world().map_err(js_err)?.to_text())
    }

    /// True after a blow-up, until a reset or a parameter change.
    #[wasm_bindgen(getter, js_name = blownUp)]
    pub fn blown_up(&self) -> bool {
        self.blow_up.is_some()
    }

    /// What the blow-up was, for a person: the step, the time, the point and the cause; `undefined`
    /// when there was none.
    #[wasm_bindgen(js_name = blowUpMessage)]
    pub fn blow_up_message(&self) -> Option<String> {
        self.blow_up.as_ref().map(describe_blow_up)
    }

    /// A time step likely to be stable after the blow-up (s); `undefined` when there was no
    /// blow-up or no dt makes this integrator stable (undamped explicit Euler).
    #[wasm_bindgen(js_name = suggestedDt)]
    pub fn suggested_dt(&self) -> Option<f64> {
        self.blow_up.as_ref().and_then(|b| b.suggested_dt)
    }
}

impl JelloSim {
    fn new(model: Model, state: State, name: &str) -> JelloSim {
        let lattice = model.body(0).lattice();
        let triangles = lattice.surface_triangles().concat();
        let surface: Vec<u32> = lattice
            .surface_points()
            .into_iter()
            .map(|p| p as u32)
            .collect();
        let mut on_surface = vec![false; model.point_count()];
        for &p in &surface {
            on_surface[p as usize] = true;
        }
        let mut surface_springs: [Vec<u32>; 3] = Default::default();
        let s = &model.springs();
        for ((&a, &b), &kind) in s.a.iter().zip(&s.b).zip(&s.kind) {
            if on_surface[a as usize] && on_surface[b as usize] {
                surface_springs[kind as usize].extend([a, b]);
            }
        }
        JelloSim {
            sim: Simulation::new(model.clone(), state.clone()),
            initial: (model, state),
            name: name.to_string(),
            blow_up: None,
            triangles,
            surface,
            surface_springs,
        }
    }
}

/// The blow-up in words for the viewer's banner (the core's `Display` speaks to the command
/// line, with its `--dt` flag).
fn describe_blow_up(b: &BlowUp) -> String {
    let [i, j, k] = b.point_ijk;
    let cause = match b.cause {
        BlowUpCause::NonFinite => "got a non-finite position or velocity".to_string(),
        BlowUpCause::Escaped(_) => format!("flew more than {} m outside the box", b.escape_margin),
    };
    let advice = match b.suggested_dt {
        Some(dt) => format!("try dt = {dt} s"),
        None => format!(
            "{} is unstable at every dt for these springs (no damping): try RK4 or SymplecticEuler",
            b.integrator
        ),
    };
    format!(
        "The simulation blew up at step {} (t = {:.4} s): point ({i}, {j}, {k}) {cause}. {} with dt = {} s is unstable here; {advice}.",
        b.step, b.time, b.integrator, b.dt
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    const JELLO: &str = include_str!("../../../examples/jello.w");

    fn sim() -> JelloSim {
        let world = World::parse(JELLO.as_bytes(), "jello.w", ReadOptions::default()).unwrap();
        let (model, state) = world.to_simulation().unwrap();
        JelloSim::new(model, state, "jello.w")
    }

    #[test]
    fn wireframe_springs_join_surface_points_only() {
        let s = sim();
        let surface: std::collections::HashSet<u32> = s.surface.iter().copied().collect();
        assert_eq!(surface.len(), 8 * 8 * 8 - 6 * 6 * 6);
        for kind in 0..3 {
            let pairs = &s.surface_springs[kind];
            assert!(!pairs.is_empty());
            assert!(pairs.iter().all(|p| surface.contains(p)));
        }
        assert_eq!(s.triangles.len(), 6 * 7 * 7 * 2 * 3);
    }

    #[test]
    fn parameters_rebuild_the_model_and_keep_the_state() {
        let mut s = sim();
        assert_eq!(s.step(10), 10);
        let before = s.sim.state.clone();
        s.set_parameters("symplectic", 0.0002, 300.0, 0.5, 0.002)
            .unwrap();
        assert_eq!(s.sim.state, before);
        let m = &s.sim.model;
        assert_eq!(m.integrator, Integrator::SymplecticEuler);
        assert_eq!(
            (
                m.dt,
                m.body(0).material.stiffness,
                m.body(0).material.damping,
                m.body(0).material.mass
            ),
            (0.0002, [300.0; 3], [0.5; 3], 0.002)
        );
        assert!(m.plane.is_some() && m.field.is_some());
        s.reset();
        assert_eq!(s.sim.model.dt, 0.0005);
        assert_eq!(s.sim.state.steps, 0);
    }

    #[test]
    fn a_blow_up_stops_stepping_and_suggests_a_dt() {
        let mut s = sim();
        s.set_parameters("RK4", 0.01, 200.0, 0.25, 1.0 / 512.0)
            .unwrap();
        let taken = s.step(10_000);
        assert!(taken < 10_000);
        assert!(s.blow_up.is_some());
        assert!(s.sim.state.pos.iter().all(|p| p.is_finite()));
        let suggested = s.blow_up.as_ref().unwrap().suggested_dt.unwrap();
        assert!(suggested < 0.01);
        assert!(describe_blow_up(s.blow_up.as_ref().unwrap()).contains("try dt ="));
        assert_eq!(s.step(5), 0);
        s.reset();
        assert_eq!(s.step(5), 5);
    }

    #[test]
    fn saved_text_reads_back() {
        let mut s = sim();
        s.step(100);
        let world = s.sim.to_world().unwrap();
        let again = World::parse(world.to_text().as_bytes(), "x", ReadOptions::default()).unwrap();
        assert_eq!(again.positions, s.sim.state.pos);
    }
}
