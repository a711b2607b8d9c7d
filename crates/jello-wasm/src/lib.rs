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
//! In the browser build (wasm32), `JelloGpu` steps a `JelloSim`'s model on the GPU through
//! WebGPU, with `jello-gpu`'s WGSL and passes (module `gpu`); the viewer falls back to
//! `JelloSim::step` where the browser has no WebGPU adapter or the GPU does not cover the model.
//!
//! [wasm-bindgen]: https://rustwasm.github.io/wasm-bindgen/

#![warn(missing_docs)]

use jello_core::formats::scene::SceneFile;
use jello_core::integrate::stability;
use jello_core::model::solver::Newton;
use jello_core::surface::{CageVertices, Surface};
use jello_core::{
    Aabb, BlowUp, BlowUpCause, ForceField, Integrator, Lattice, Material, Model, ModelBuilder,
    Obstacle, Pull, ReadOptions, Simulation, State, Vec3, World,
};
use wasm_bindgen::prelude::*;

#[cfg(target_arch = "wasm32")]
mod gpu;
#[cfg(target_arch = "wasm32")]
pub use gpu::JelloGpu;

/// A simulation the page drives: the model and state being stepped, what it was loaded from
/// (for reset and save), and what the renderer needs that never changes while stepping.
#[wasm_bindgen]
pub struct JelloSim {
    sim: Simulation,
    /// Model and state as loaded, restored by [`JelloSim::reset`].
    initial: (Model, State),
    /// Label of the source (a file name), for messages.
    name: String,
    /// The scene file it was loaded from (saving writes it back with the current state); `None`
    /// for a world file or a built cube.
    scene: Option<SceneFile>,
    /// Body names (a scene's, or "jello").
    body_names: Vec<String>,
    /// The blow-up that stopped stepping, until a reset or a parameter change.
    blow_up: Option<BlowUp>,
    /// What is drawn lit: every body's skin, or its cage surface when it has none.
    surface: Surface,
    /// Surface triangles, 3 surface-vertex indices each.
    surface_triangles: Vec<u32>,
    /// Per surface vertex: its body.
    surface_bodies: Vec<u32>,
    /// Scratch for surface positions.
    surface_scratch: Vec<Vec3>,
    /// Points on the cages' surfaces (flat indices): what the wireframe draws.
    cage_points: Vec<u32>,
    /// Spring end pairs `[a0, b0, a1, b1, …]` per kind, only springs whose ends are both on a
    /// cage surface (what the wireframe draws).
    cage_springs: [Vec<u32>; 3],
}

/// Turns a core error into a JavaScript `Error` with the same message.
fn js_err(e: impl std::fmt::Display) -> JsError {
    JsError::new(&e.to_string())
}

/// True when `name` ends in `.toml` (any case): a scene file.
fn is_scene_name(name: &str) -> bool {
    name.rsplit_once('.')
        .is_some_and(|(_, e)| e.eq_ignore_ascii_case("toml"))
}

#[wasm_bindgen]
impl JelloSim {
    /// A simulation of the file `text` named `name`: a scene when the name ends in `.toml`, else
    /// a world file. Throws with the reader's message (file, line and, for scenes, column) when
    /// the file is not valid.
    pub fn load(text: &str, name: &str) -> Result<JelloSim, JsError> {
        JelloSim::try_load(text, name).map_err(js_err)
    }

    /// A simulation of the world file `text`; `name` labels error messages (`name:line: …`).
    /// Throws with the reader's message when the file is not a valid world.
    #[wasm_bindgen(js_name = fromWorld)]
    pub fn from_world(text: &str, name: &str) -> Result<JelloSim, JsError> {
        JelloSim::try_world(text, name).map_err(js_err)
    }

    /// A simulation of the scene file (TOML) `text`; `name` labels error messages
    /// (`name:line:column: …`). Throws when the file is not a valid scene.
    #[wasm_bindgen(js_name = fromScene)]
    pub fn from_scene(text: &str, name: &str) -> Result<JelloSim, JsError> {
        JelloSim::try_scene(text, name).map_err(js_err)
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
        let name = format!("cube {n}³");
        Ok(JelloSim::new(
            model,
            state,
            &name,
            None,
            vec!["jello".into()],
        ))
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

    /// Back to the file as loaded: model (parameters) and state; clears pulls, pushes and any
    /// blow-up.
    pub fn reset(&mut self) {
        let (model, state) = self.initial.clone();
        self.sim = Simulation::new(model, state);
        self.blow_up = None;
    }

    /// Label of the loaded file (its name).
    #[wasm_bindgen(getter)]
    pub fn name(&self) -> String {
        self.name.clone()
    }

    /// True when loaded from a scene file (saving writes a scene).
    #[wasm_bindgen(getter, js_name = isScene)]
    pub fn is_scene(&self) -> bool {
        self.scene.is_some()
    }

    /// Number of mass points, over all bodies.
    #[wasm_bindgen(getter, js_name = pointCount)]
    pub fn point_count(&self) -> usize {
        self.sim.model.point_count()
    }

    /// Number of bodies.
    #[wasm_bindgen(getter, js_name = bodyCount)]
    pub fn body_count(&self) -> usize {
        self.sim.model.bodies().len()
    }

    /// The bodies' names, in order.
    #[wasm_bindgen(js_name = bodyNames)]
    pub fn body_names(&self) -> Vec<String> {
        self.body_names.clone()
    }

    /// Mass of body `b` (kg): its active points times their mass. Throws for a body that does
    /// not exist.
    #[wasm_bindgen(js_name = bodyMass)]
    pub fn body_mass(&self, b: usize) -> Result<f64, JsError> {
        self.checked_body(b)
            .map(|body| body.total_mass())
            .map_err(js_err)
    }

    /// Per point (flat index): its body.
    #[wasm_bindgen(js_name = pointBodies)]
    pub fn point_bodies(&self) -> Vec<u32> {
        let mut out = Vec::with_capacity(self.point_count());
        for (b, body) in self.sim.model.bodies().iter().enumerate() {
            out.extend(std::iter::repeat_n(b as u32, body.len()));
        }
        out
    }

    /// Per point: 1 when it is part of its body, 0 for the unused corners of a shape's lattice
    /// (they never move and are not drawn).
    #[wasm_bindgen(js_name = activePoints)]
    pub fn active_points(&self) -> Vec<u8> {
        let mut out = Vec::with_capacity(self.point_count());
        for body in self.sim.model.bodies() {
            out.extend((0..body.len()).map(|p| u8::from(body.is_active(p))));
        }
        out
    }

    /// Points per axis `[nx, ny, nz]` of the first body.
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

    /// Positions `[x0, y0, z0, x1, …]` (m) of every point, a copy as a `Float32Array` (what the
    /// GPU takes).
    pub fn positions(&self) -> Vec<f32> {
        let mut out = Vec::with_capacity(3 * self.sim.state.pos.len());
        for p in &self.sim.state.pos {
            out.extend_from_slice(&[p.x as f32, p.y as f32, p.z as f32]);
        }
        out
    }

    /// Velocities `[vx0, vy0, vz0, …]` (m/s) as a `Float64Array` copy.
    pub fn velocities(&self) -> Vec<f64> {
        self.sim
            .state
            .vel
            .iter()
            .flat_map(|v| v.to_array())
            .collect()
    }

    /// Rest positions `[x0, y0, z0, …]` (m) of every point, each body in its own frame (so only
    /// distances within a body mean anything): for the falloff of a grab.
    #[wasm_bindgen(js_name = restPositions)]
    pub fn rest_positions(&self) -> Vec<f32> {
        let mut out = Vec::with_capacity(3 * self.point_count());
        for body in self.sim.model.bodies() {
            for p in body.rest_positions() {
                out.extend([p.x, p.y, p.z].map(|c| c as f32));
            }
        }
        out
    }

    /// Number of vertices of the drawn surface (skins, and cage surfaces of bodies without one).
    #[wasm_bindgen(getter, js_name = surfaceVertexCount)]
    pub fn surface_vertex_count(&self) -> usize {
        self.surface.vertex_count()
    }

    /// The drawn surface's triangles, three vertex indices each, wound outwards.
    #[wasm_bindgen(js_name = surfaceTriangles)]
    pub fn surface_triangles(&self) -> Vec<u32> {
        self.surface_triangles.clone()
    }

    /// Per surface vertex: its body (for colouring).
    #[wasm_bindgen(js_name = surfaceBodies)]
    pub fn surface_bodies(&self) -> Vec<u32> {
        self.surface_bodies.clone()
    }

    /// The surface vertices' positions now `[x0, y0, z0, …]` (m): skin vertices follow their
    /// cells by trilinear weights.
    #[wasm_bindgen(js_name = surfacePositions)]
    pub fn surface_positions(&mut self) -> Vec<f32> {
        self.surface
            .positions(&self.sim.model, &self.sim.state, &mut self.surface_scratch);
        let mut out = Vec::with_capacity(3 * self.surface_scratch.len());
        for p in &self.surface_scratch {
            out.extend_from_slice(&[p.x as f32, p.y as f32, p.z as f32]);
        }
        out
    }

    /// The point (flat index) that carries surface vertex `v` most: what pulling the surface
    /// there pulls. Throws for a vertex that does not exist.
    #[wasm_bindgen(js_name = surfaceVertexPoint)]
    pub fn surface_vertex_point(&self, v: usize) -> Result<u32, JsError> {
        self.try_vertex_point(v).map_err(js_err)
    }

    /// Indices of the points on the cages' surfaces.
    #[wasm_bindgen(js_name = surfacePoints)]
    pub fn surface_points(&self) -> Vec<u32> {
        self.cage_points.clone()
    }

    /// End pairs `[a0, b0, a1, b1, …]` of the springs of `kind` (0 structural, 1 shear, 2 bend)
    /// whose two ends are on a cage's surface. Throws for another kind.
    #[wasm_bindgen(js_name = surfaceSprings)]
    pub fn surface_springs(&self, kind: u32) -> Result<Vec<u32>, JsError> {
        self.cage_springs
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

    /// The obstacles, seven numbers each: a kind and six values. Kind 0, a plane:
    /// `a, b, c, d, 0, 0`; 1, a sphere: `x, y, z, radius, 0, 0`; 2, a box: `min, max`.
    pub fn obstacles(&self) -> Vec<f64> {
        let mut out = Vec::with_capacity(7 * self.sim.model.obstacles.len());
        for o in &self.sim.model.obstacles {
            match o {
                Obstacle::Plane(p) => {
                    out.push(0.0);
                    out.extend(p.coeffs);
                    out.extend([0.0, 0.0]);
                }
                Obstacle::Sphere(s) => {
                    out.push(1.0);
                    out.extend(s.centre.to_array());
                    out.extend([s.radius, 0.0, 0.0]);
                }
                Obstacle::Box(b) => {
                    out.push(2.0);
                    out.extend(b.min.to_array());
                    out.extend(b.max.to_array());
                }
            }
        }
        out
    }

    /// The pinned points (flat indices).
    pub fn pins(&self) -> Vec<u32> {
        self.sim.model.pins.clone()
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

    /// Integrator name (one of [`JelloSim::integrator_names`]).
    #[wasm_bindgen(getter)]
    pub fn integrator(&self) -> String {
        self.sim.model.integrator.name().to_string()
    }

    /// True when the integrator in use is implicit (no stability limit on dt).
    #[wasm_bindgen(getter, js_name = isImplicit)]
    pub fn is_implicit(&self) -> bool {
        self.sim.model.integrator.is_implicit()
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

    /// Structural spring stiffness of the first body (N/m).
    #[wasm_bindgen(getter)]
    pub fn stiffness(&self) -> f64 {
        self.sim.model.body(0).material.stiffness[0]
    }

    /// Structural spring damping of the first body (N·s/m).
    #[wasm_bindgen(getter)]
    pub fn damping(&self) -> f64 {
        self.sim.model.body(0).material.damping[0]
    }

    /// Mass of each point of the first body (kg).
    #[wasm_bindgen(getter)]
    pub fn mass(&self) -> f64 {
        self.sim.model.body(0).material.mass
    }

    /// How closely an implicit integrator solves each step: the residual allowed per point
    /// (m/s, times the fastest point's speed above 1 m/s). Carried, and unused, by explicit ones.
    #[wasm_bindgen(getter)]
    pub fn tolerance(&self) -> f64 {
        self.sim.model.newton.tolerance
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

    /// Newton iterations the implicit solver has taken since load, reset or the last change of
    /// parameters (0 under an explicit integrator; see `jello_core::SolverStats`).
    #[wasm_bindgen(getter, js_name = newtonIterations)]
    pub fn newton_iterations(&self) -> f64 {
        self.sim.solver_stats().newton_iterations as f64
    }

    /// Largest stable time step (s) of the current integrator for this model at rest (see
    /// `jello_core::integrate::stability`); 0 when none is stable.
    #[wasm_bindgen(js_name = stableDt)]
    pub fn stable_dt(&self) -> f64 {
        stability::stable_dt(&self.sim.model, self.sim.model.integrator)
    }

    /// Sets integrator, time step and the implicit integrators' tolerance (m/s; above 0, at most
    /// `jello_core::model::solver::MAX_TOLERANCE`), and the springs' stiffness and damping (every
    /// kind) and the point mass, by building a new model that keeps everything else; the state
    /// (positions, velocities, time) carries on. Stiffness, damping and mass are shown as the
    /// first body's; one that differs from that is given to every body, one that does not leaves
    /// the bodies' own values alone (a scene's bodies may differ, and its kinds too). Clears a
    /// blow-up, so stepping resumes from the last good state. Throws, and changes nothing, when
    /// a value is out of range or the integrator is unknown.
    #[wasm_bindgen(js_name = setParameters)]
    pub fn set_parameters(
        &mut self,
        integrator: &str,
        dt: f64,
        stiffness: f64,
        damping: f64,
        mass: f64,
        tolerance: f64,
    ) -> Result<(), JsError> {
        self.try_set_parameters(integrator, dt, stiffness, damping, mass, tolerance)
            .map_err(js_err)
    }

    /// Pulls points toward targets: point `points[i]` by a spring of stiffness `stiffness[i]`
    /// (N/m) toward `targets[3i..3i+3]` (m), damped by `damping[i]` (N·s/m) against its
    /// velocity. The core evaluates them at every stage of every step (the page only moves the
    /// targets); they replace the previous pulls and hold until changed. Empty arrays remove
    /// them. Throws, and changes nothing, when the lengths disagree, a point does not exist or a
    /// value is not finite (or negative).
    #[wasm_bindgen(js_name = setPulls)]
    pub fn set_pulls(
        &mut self,
        points: &[u32],
        targets: &[f64],
        stiffness: &[f64],
        damping: &[f64],
    ) -> Result<(), JsError> {
        self.try_set_pulls(points, targets, stiffness, damping)
            .map_err(js_err)
    }

    /// Pushes body `body` (every body when negative) with the acceleration `(ax, ay, az)`
    /// (m/s²): a force of mass times that on each of its points, held until changed; zero
    /// removes it. Throws for a body that does not exist or a value that is not finite.
    #[wasm_bindgen(js_name = setPush)]
    pub fn set_push(&mut self, body: i32, ax: f64, ay: f64, az: f64) -> Result<(), JsError> {
        self.try_set_push(body, Vec3::new(ax, ay, az))
            .map_err(js_err)
    }

    /// The current state as world-file text. Throws for what the format cannot hold (a scene,
    /// or a lattice other than the classic 8³ cube).
    #[wasm_bindgen(js_name = toWorldText)]
    pub fn to_world_text(&self) -> Result<String, JsError> {
        Ok(self.sim.to_world().map_err(js_err)?.to_text())
    }

    /// The current state as scene text (TOML): the loaded scene with every point's position and
    /// velocity, and the time step, integrator and materials now in use. Throws when not loaded
    /// from a scene.
    #[wasm_bindgen(js_name = toSceneText)]
    pub fn to_scene_text(&self) -> Result<String, JsError> {
        self.try_scene_text().map_err(js_err)
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
    fn new(
        model: Model,
        state: State,
        name: &str,
        scene: Option<SceneFile>,
        body_names: Vec<String>,
    ) -> JelloSim {
        let surface = Surface::new(&model, CageVertices::Used);
        let surface_triangles = surface.triangles().concat();
        let mut surface_bodies = vec![0u32; surface.vertex_count()];
        for (b, range) in surface.body_vertices(&model).into_iter().enumerate() {
            surface_bodies[range].fill(b as u32);
        }
        let mut on_surface = vec![false; model.point_count()];
        for body in model.bodies() {
            for t in body.surface_triangles() {
                for p in t {
                    on_surface[body.points().start + p as usize] = true;
                }
            }
        }
        let cage_points: Vec<u32> = (0..model.point_count() as u32)
            .filter(|&p| on_surface[p as usize])
            .collect();
        let mut cage_springs: [Vec<u32>; 3] = Default::default();
        let s = &model.springs();
        for ((&a, &b), &kind) in s.a.iter().zip(&s.b).zip(&s.kind) {
            if on_surface[a as usize] && on_surface[b as usize] {
                cage_springs[kind as usize].extend([a, b]);
            }
        }
        JelloSim {
            sim: Simulation::new(model.clone(), state.clone()),
            initial: (model, state),
            name: name.to_string(),
            scene,
            body_names,
            blow_up: None,
            surface,
            surface_triangles,
            surface_bodies,
            surface_scratch: Vec::new(),
            cage_points,
            cage_springs,
        }
    }

    /// See [`JelloSim::load`]; errors as text (so that native tests can see them).
    fn try_load(text: &str, name: &str) -> Result<JelloSim, String> {
        if is_scene_name(name) {
            JelloSim::try_scene(text, name)
        } else {
            JelloSim::try_world(text, name)
        }
    }

    fn try_world(text: &str, name: &str) -> Result<JelloSim, String> {
        let world = World::parse(text.as_bytes(), name, ReadOptions::default())
            .map_err(|e| e.to_string())?;
        let (model, state) = world.to_simulation().map_err(|e| format!("{name}: {e}"))?;
        Ok(JelloSim::new(
            model,
            state,
            name,
            None,
            vec!["jello".into()],
        ))
    }

    fn try_scene(text: &str, name: &str) -> Result<JelloSim, String> {
        let file = SceneFile::parse(text.as_bytes(), name).map_err(|e| e.to_string())?;
        let scene = file.to_scene(name).map_err(|e| e.to_string())?;
        Ok(JelloSim::new(
            scene.model,
            scene.state,
            name,
            Some(file),
            scene.names,
        ))
    }

    fn try_vertex_point(&self, v: usize) -> Result<u32, String> {
        if v >= self.surface.vertex_count() {
            return Err(format!(
                "surface vertex {v} does not exist (there are {})",
                self.surface.vertex_count()
            ));
        }
        Ok(self.surface.vertex_point(&self.sim.model, v) as u32)
    }

    /// [`JelloSim::set_parameters`], its error as text (a `JsError` is made only in wasm).
    fn try_set_parameters(
        &mut self,
        integrator: &str,
        dt: f64,
        stiffness: f64,
        damping: f64,
        mass: f64,
        tolerance: f64,
    ) -> Result<(), String> {
        let integrator = integrator
            .parse::<Integrator>()
            .map_err(|e| e.to_string())?;
        let (k0, d0, m0) = (self.stiffness(), self.damping(), self.mass());
        let mut bodies = self.sim.model.bodies().to_vec();
        for body in &mut bodies {
            let m = &mut body.material;
            if stiffness != k0 {
                m.stiffness = [stiffness; 3];
            }
            if damping != d0 {
                m.damping = [damping; 3];
            }
            if mass != m0 {
                m.mass = mass;
            }
        }
        let model = self
            .sim
            .model
            .to_builder()
            .bodies(bodies)
            .integrator(integrator)
            .dt(dt)
            .newton(Newton {
                tolerance,
                ..self.sim.model.newton
            })
            .build()
            .map_err(|e| e.to_string())?;
        let control = std::mem::take(&mut self.sim.control);
        let state = self.sim.state.clone();
        self.sim = Simulation::new(model, state);
        self.sim.control = control;
        self.blow_up = None;
        Ok(())
    }

    fn try_set_pulls(
        &mut self,
        points: &[u32],
        targets: &[f64],
        stiffness: &[f64],
        damping: &[f64],
    ) -> Result<(), String> {
        let n = points.len();
        if targets.len() != 3 * n || stiffness.len() != n || damping.len() != n {
            return Err(format!(
                "pulls: {n} points need {} target components, {n} stiffnesses and {n} dampings; got {}, {} and {}",
                3 * n,
                targets.len(),
                stiffness.len(),
                damping.len()
            ));
        }
        let mut control = self.sim.control.clone();
        control.pulls = (0..n)
            .map(|i| Pull {
                point: points[i],
                target: Vec3::new(targets[3 * i], targets[3 * i + 1], targets[3 * i + 2]),
                stiffness: stiffness[i],
                damping: damping[i],
            })
            .collect();
        control.check(&self.sim.model).map_err(|e| e.to_string())?;
        self.sim.control = control;
        Ok(())
    }

    fn try_set_push(&mut self, body: i32, a: Vec3) -> Result<(), String> {
        if !a.is_finite() {
            return Err("push: the acceleration must be finite".into());
        }
        if body >= 0 {
            self.checked_body(body as usize)?;
        }
        let forces = &mut self.sim.control.forces;
        forces.clear();
        if a == Vec3::ZERO {
            return Ok(());
        }
        forces.resize(self.sim.model.point_count(), Vec3::ZERO);
        for (b, model_body) in self.sim.model.bodies().iter().enumerate() {
            if body < 0 || b == body as usize {
                forces[model_body.points()].fill(a * model_body.material.mass);
            }
        }
        Ok(())
    }

    fn try_scene_text(&self) -> Result<String, String> {
        let Some(file) = &self.scene else {
            return Err(format!(
                "{} is not a scene: save it as a world file",
                self.name
            ));
        };
        let model = &self.sim.model;
        let mut file = file.with_state(model, &self.sim.state);
        let initial: Vec<Material> = self.initial.0.bodies().iter().map(|b| b.material).collect();
        file.record_materials(model, &initial);
        Ok(file.to_toml())
    }

    fn checked_body(&self, b: usize) -> Result<&jello_core::Body, String> {
        self.sim
            .model
            .bodies()
            .get(b)
            .ok_or_else(|| format!("body {b} does not exist (there are {})", self.body_count()))
    }
}

/// The blow-up in words for the viewer's banner (the core's `Display` speaks to the command
/// line, with its `--dt` flag), with what the core says of bodies deep inside each other before
/// it (`BlowUp::sunk_note`).
fn describe_blow_up(b: &BlowUp) -> String {
    let what = describe_failure(b);
    match b.sunk_note() {
        Some(note) => format!("{what} {note}."),
        None => what,
    }
}

/// The failed step itself, for [`describe_blow_up`].
fn describe_failure(b: &BlowUp) -> String {
    if let BlowUpCause::NotConverged {
        residual,
        iterations,
        halvings,
        ..
    } = b.cause
    {
        let substep = match halvings {
            0 => String::new(),
            h => format!(" on a substep of dt/{}", 1u64 << h),
        };
        return format!(
            "The implicit solve did not converge at step {} (t = {:.4} s): residual {residual:.2e} m/s after {iterations} Newton iterations{substep}. Try a smaller dt than {} s.",
            b.step, b.time, b.dt
        );
    }
    let [i, j, k] = b.point_ijk;
    let cause = match b.cause {
        BlowUpCause::NonFinite => "got a non-finite position or velocity".to_string(),
        BlowUpCause::Escaped(_) => format!("flew more than {} m outside the box", b.escape_margin),
        BlowUpCause::NotConverged { .. } => unreachable!("described above"),
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
        JelloSim::try_load(JELLO, "jello.w").unwrap()
    }

    const STACK: &str = include_str!("../../../examples/stack.toml");
    const TORUS: &str = include_str!("../../../examples/torus.toml");

    #[test]
    fn wireframe_springs_join_surface_points_only() {
        let s = sim();
        let surface: std::collections::HashSet<u32> = s.cage_points.iter().copied().collect();
        assert_eq!(surface.len(), 8 * 8 * 8 - 6 * 6 * 6);
        for kind in 0..3 {
            let pairs = &s.cage_springs[kind];
            assert!(!pairs.is_empty());
            assert!(pairs.iter().all(|p| surface.contains(p)));
        }
        // The classic cube's drawn surface is its lattice surface, over the surface points.
        assert_eq!(s.surface_triangles.len(), 6 * 7 * 7 * 2 * 3);
        assert_eq!(s.surface.vertex_count(), surface.len());
        for v in 0..s.surface.vertex_count() {
            assert!(surface.contains(&s.try_vertex_point(v).unwrap()));
        }
    }

    #[test]
    fn a_scene_loads_with_its_bodies_obstacles_and_skins() {
        let mut s = JelloSim::try_load(STACK, "stack.toml").unwrap();
        assert!(s.is_scene());
        assert_eq!(s.body_count(), 3);
        assert_eq!(s.body_names(), ["bottom", "middle", "top"]);
        assert_eq!(s.obstacles(), [1.0, 0.0, 0.0, -1.5, 0.45, 0.0, 0.0]);
        let bodies = s.point_bodies();
        assert_eq!(bodies.len(), 375);
        assert_eq!(bodies.iter().filter(|&&b| b == 2).count(), 125);
        // Each body's surface vertices pull points of that body.
        let vertex_bodies = s.surface_bodies();
        for (v, &b) in vertex_bodies.iter().enumerate() {
            let p = s.try_vertex_point(v).unwrap();
            assert_eq!(bodies[p as usize], b);
        }
        assert!(s.try_vertex_point(vertex_bodies.len()).is_err());
        assert_eq!(s.step(10), 10);

        let torus = JelloSim::try_load(TORUS, "torus.toml").unwrap();
        let mesh = jello_core::TriMesh::shape("torus", 8).unwrap();
        assert_eq!(torus.surface_vertex_count(), mesh.vertices.len());
        assert_eq!(torus.surface_triangles().len(), 3 * mesh.triangles.len());
        let rest = torus.surface.vertex_count();
        let mut t = torus;
        assert_eq!(t.surface_positions().len(), 3 * rest);
        // A scene error names the file, line and column.
        let bad = JelloSim::try_scene("[simulation]\ncolour = 1\n", "bad.toml");
        assert!(bad.is_err());
    }

    #[test]
    fn pulls_and_pushes_are_checked_and_reach_the_core() {
        let mut s = JelloSim::try_load(STACK, "stack.toml").unwrap();
        assert!(s.try_set_pulls(&[0], &[0.0, 0.0], &[1.0], &[0.0]).is_err());
        assert!(s.try_set_pulls(&[9999], &[0.0; 3], &[1.0], &[0.0]).is_err());
        assert!(s
            .try_set_pulls(&[0], &[f64::NAN, 0.0, 0.0], &[1.0], &[0.0])
            .is_err());
        assert!(s.sim.control.pulls.is_empty());
        s.try_set_pulls(
            &[3, 4],
            &[0.0, 0.0, 1.0, 0.0, 0.0, 1.0],
            &[10.0, 5.0],
            &[1.0, 0.5],
        )
        .unwrap();
        assert_eq!(s.sim.control.pulls.len(), 2);
        assert_eq!(s.sim.control.pulls[1].target, Vec3::new(0.0, 0.0, 1.0));
        s.try_set_pulls(&[], &[], &[], &[]).unwrap();
        assert!(s.sim.control.pulls.is_empty());

        assert!(s.try_set_push(3, Vec3::new(1.0, 0.0, 0.0)).is_err());
        assert!(s
            .try_set_push(0, Vec3::new(f64::INFINITY, 0.0, 0.0))
            .is_err());
        s.try_set_push(1, Vec3::new(2.0, 0.0, 0.0)).unwrap();
        let f = &s.sim.control.forces;
        let m = s.sim.model.body(1).material.mass;
        assert_eq!(f[0], Vec3::ZERO);
        assert_eq!(f[130], Vec3::new(2.0 * m, 0.0, 0.0));
        assert_eq!(f[300], Vec3::ZERO);
        s.try_set_push(-1, Vec3::new(0.0, 0.0, 0.0)).unwrap();
        assert!(s.sim.control.forces.is_empty());
    }

    #[test]
    fn a_scene_saves_as_a_scene_that_reads_back() {
        let mut s = JelloSim::try_load(STACK, "stack.toml").unwrap();
        assert!(s.sim.to_world().is_err());
        s.step(50);
        s.set_parameters(
            "RK4",
            0.0005,
            s.stiffness(),
            s.damping(),
            s.mass(),
            s.tolerance(),
        )
        .unwrap();
        let text = s.try_scene_text().unwrap();
        let again = JelloSim::try_load(&text, "saved.toml").unwrap();
        assert_eq!(again.sim.state.pos, s.sim.state.pos);
        assert_eq!(again.sim.state.vel, s.sim.state.vel);
        assert_eq!(again.dt(), 0.0005);
        // The materials were not touched: the file keeps its modulus and density.
        assert!(text.contains("modulus"));
        assert!(sim().try_scene_text().is_err());
    }

    #[test]
    fn parameters_rebuild_the_model_and_keep_the_state() {
        let mut s = sim();
        assert_eq!(s.step(10), 10);
        let before = s.sim.state.clone();
        s.set_parameters("symplectic", 0.0002, 300.0, 0.5, 0.002, 1e-6)
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
        assert_eq!(s.tolerance(), 1e-6);
        assert!(m.plane.is_some() && m.field.is_some());
        s.reset();
        assert_eq!(s.sim.model.dt, 0.0005);
        assert_eq!(s.sim.state.steps, 0);
    }

    #[test]
    fn a_tolerance_out_of_range_changes_nothing() {
        let mut s = sim();
        s.set_parameters("BackwardEuler", 0.01, 200.0, 0.25, 1.0 / 512.0, 1e-5)
            .unwrap();
        let model = s.sim.model.clone();
        for bad in [0.0, -1e-6, 0.2, f64::NAN, f64::INFINITY] {
            let error = s.try_set_parameters("BackwardEuler", 0.02, 200.0, 0.25, 1.0 / 512.0, bad);
            assert!(error.unwrap_err().contains("tolerance"), "{bad}");
            assert_eq!(s.sim.model, model);
        }
        assert_eq!(s.tolerance(), 1e-5);
    }

    #[test]
    fn a_blow_up_stops_stepping_and_suggests_a_dt() {
        let mut s = sim();
        s.set_parameters("RK4", 0.01, 200.0, 0.25, 1.0 / 512.0, 1e-9)
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

    /// The banner says, after the failed step, how deep bodies were inside each other before it.
    #[test]
    fn a_blow_up_of_bodies_deep_inside_each_other_says_so() {
        let mut s = sim();
        s.set_parameters("RK4", 0.01, 200.0, 0.25, 1.0 / 512.0, 1e-9)
            .unwrap();
        s.step(10_000);
        let mut b = s.blow_up.clone().expect("RK4 at dt 0.01 blows up");
        assert!(!describe_blow_up(&b).contains("Before the step"));
        b.sunk = Some(Box::new(jello_core::diagnostics::Sunk {
            bodies: [0, 1],
            depth: 0.131,
            at: Vec3::ZERO,
            spacing: 0.05,
        }));
        let text = describe_blow_up(&b);
        assert!(text.contains("try dt ="), "{text}");
        assert!(
            text.ends_with(
                "s. Before the step bodies 1 and 2 were 13.1 cm inside each other, more than \
                 half of a 5 cm cell: a body crushed by its load or thrown through another, which \
                 a shorter step alone may not cure (a stiffer material, a lighter load or a \
                 stiffer contact may)."
            ),
            "{text}"
        );
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
