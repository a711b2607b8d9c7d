//! A scene file made into a model and its initial state ([`SceneFile::to_scene`]): bodies built,
//! placed, given their materials, regions, pins and velocities; the whole checked (bodies inside
//! the box, apart, outside the obstacles), with errors at the body's line.

use super::tables::{v3, BodySpec, ObstacleSpec};
use super::{Scene, SceneError, SceneFile, MAX_CELLS};
use crate::formats::mesh::TriMesh;
use crate::model::body::{rotation_xyz, Body, Material, IDENTITY};
use crate::model::field::ForceField;
use crate::model::integrator::Integrator;
use crate::model::lattice::Lattice;
use crate::model::obstacle::Sphere;
use crate::model::springs::SpringScale;
use crate::model::{Aabb, Model, ModelBuilder, ModelError, Obstacle, Plane};
use crate::state::{rigid_velocity, State};
use crate::vec3::Vec3;

impl SceneFile {
    /// The model and initial state this scene describes.
    pub fn to_scene(&self, name: &str) -> Result<Scene, SceneError> {
        let error = |message: String| SceneError {
            source_name: name.to_string(),
            line: 0,
            column: 0,
            message,
        };
        // An error at the line of `path` in the file (see `SourceLines`; 0 when not from one).
        let error_at = |path: &str, message: String| SceneError {
            line: self.origin.line(path),
            ..error(message)
        };
        let integrator: Integrator = self.simulation.integrator.parse().map_err(
            |e: crate::model::integrator::UnknownIntegrator| {
                error_at("simulation.integrator", e.to_string())
            },
        )?;
        let dt = self.simulation.dt;
        if !(dt.is_finite() && dt > 0.0) {
            return Err(error_at(
                "simulation.dt",
                format!("[simulation] dt must be a finite number above 0 s (got {dt})"),
            ));
        }
        let bounds = match self.bounds {
            Some(b) => {
                Aabb::new(v3(b.min), v3(b.max)).map_err(|e| error_at("box", format!("box: {e}")))?
            }
            None => Aabb::classic(),
        };
        let field = match &self.field {
            Some(f) => Some(
                ForceField::new(
                    f.resolution,
                    bounds,
                    f.forces.iter().map(|&p| v3(p)).collect(),
                )
                .map_err(|e| error_at("field", format!("field: {e}")))?,
            ),
            None => None,
        };
        let mut obstacles = Vec::new();
        for (i, o) in self.obstacles.iter().enumerate() {
            let table = format!("obstacle.{i}");
            let what = |key: &str| {
                let line = self.origin.key_or_table(&table, Some(key));
                move |e: ModelError| SceneError {
                    line,
                    ..error(format!("obstacle {}: {e}", i + 1))
                }
            };
            obstacles.push(match *o {
                ObstacleSpec::Plane { coeffs } => {
                    Obstacle::Plane(Plane::new(coeffs).map_err(what("coeffs"))?)
                }
                ObstacleSpec::Sphere { centre, radius } => {
                    let key = if radius.is_finite() && radius > 0.0 {
                        "centre"
                    } else {
                        "radius"
                    };
                    Obstacle::Sphere(Sphere::new(v3(centre), radius).map_err(what(key))?)
                }
                ObstacleSpec::Box { min, max } => {
                    Obstacle::Box(Aabb::new(v3(min), v3(max)).map_err(what("min"))?)
                }
            });
        }
        let mut bodies = Vec::new();
        let names = self.body_names();
        // An error about body `b`, at the line of its `key` when the file gives one, else at its
        // header.
        let at_body_key = |b: usize, key: Option<&str>, message: String| SceneError {
            line: self.origin.key_or_table(&format!("body.{b}"), key),
            ..error(format!("body {}: {message}", b + 1))
        };
        for (b, spec) in self.bodies.iter().enumerate() {
            let body = spec
                .to_body(name)
                .map_err(|e| at_body_key(b, e.key, e.message))?;
            bodies.push(body);
        }
        let c = &self.collision;
        if !(c.stiffness.is_finite() && c.stiffness > 0.0) {
            return Err(error_at(
                "collision.stiffness",
                format!(
                    "[collision] stiffness must be a finite number above 0 (got {})",
                    c.stiffness
                ),
            ));
        }
        for (what, v) in [
            ("damping", c.damping),
            ("friction", c.friction),
            ("wall_friction", c.wall_friction),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(error_at(
                    &format!("collision.{what}"),
                    format!("[collision] {what} must be a finite number ≥ 0 (got {v})"),
                ));
            }
        }
        if self.simulation.cutbacks > crate::model::solver::MAX_CUTBACKS {
            return Err(error_at(
                "simulation.cutbacks",
                format!(
                    "[simulation] cutbacks must be at most {} (got {})",
                    crate::model::solver::MAX_CUTBACKS,
                    self.simulation.cutbacks
                ),
            ));
        }
        let tolerance = self.simulation.tolerance;
        if !(tolerance.is_finite()
            && tolerance > 0.0
            && tolerance <= crate::model::solver::MAX_TOLERANCE)
        {
            return Err(error_at("simulation.tolerance", format!(
                "[simulation] tolerance must be a number above 0 and at most {} m/s (got {tolerance})",
                crate::model::solver::MAX_TOLERANCE,
            )));
        }
        let mut model = ModelBuilder::new()
            .bodies(bodies)
            .integrator(integrator)
            .dt(self.simulation.dt)
            .steps_per_frame(self.simulation.steps_per_frame)
            .gravity(v3(self.gravity()))
            .collision(self.collision.stiffness, self.collision.damping)
            .friction(self.collision.friction)
            .wall_friction(self.collision.wall_friction)
            .self_contact(self.collision.self_contact)
            .bounds(bounds)
            .obstacles(obstacles)
            .field(field)
            .newton(crate::model::solver::Newton {
                cutbacks: self.simulation.cutbacks,
                tolerance,
                ..Default::default()
            })
            .build()
            .map_err(|e| error(e.to_string()))?;
        let mut state = State::at_rest(&model);
        if !self.simulation.time.is_finite() {
            return Err(error_at(
                "simulation.time",
                "[simulation] time must be finite".into(),
            ));
        }
        state.time = self.simulation.time;
        let mut pins = Vec::new();
        let mut motions = Vec::new();
        for (b, spec) in self.bodies.iter().enumerate() {
            let body = model.body(b);
            let range = body.points();
            spec.initial_state(&model, b, &mut state)
                .map_err(|e| at_body_key(b, e.key, e.message))?;
            // Pins are found in the placed rest shape (so a saved state finds the same points).
            let rest = body.rest_positions();
            for (n, pin) in spec.pins.iter().enumerate() {
                let at = v3(pin.at);
                let active = range.clone().filter(|&p| body.is_active(p - range.start));
                let distance = |p: &usize| (rest[*p - range.start] - at).length();
                let held: Vec<u32> = if pin.radius > 0.0 {
                    active
                        .filter(|p| distance(p) <= pin.radius)
                        .map(|p| p as u32)
                        .collect()
                } else {
                    // Radius 0: the nearest point (the first of equals).
                    active
                        .min_by(|a, b| distance(a).total_cmp(&distance(b)))
                        .map(|p| p as u32)
                        .into_iter()
                        .collect()
                };
                let at_pins = |message| at_body_key(b, Some("pins"), message);
                if !(pin.radius >= 0.0 && pin.radius.is_finite()) {
                    return Err(at_pins(format!(
                        "pin {} needs a finite radius ≥ 0 (0: the nearest point)",
                        n + 1
                    )));
                }
                if held.is_empty() {
                    return Err(at_pins(format!(
                        "pin {} holds no point (none within {} m of {})",
                        n + 1,
                        pin.radius,
                        v3(pin.at)
                    )));
                }
                let motion = pin
                    .motion()
                    .map_err(|e| at_pins(format!("pin {}: {e}", n + 1)))?;
                if let Some(motion) = motion {
                    motion
                        .check()
                        .map_err(|e| at_pins(format!("pin {}: {e}", n + 1)))?;
                    // A scene starts its moving pins at their path's velocity (a saved state
                    // keeps its own).
                    if spec.state.is_none() {
                        let v = motion.velocity(state.time);
                        held.iter().for_each(|&p| state.vel[p as usize] = v);
                    }
                    motions.push((held.clone(), motion));
                }
                pins.extend(held);
            }
        }
        if !pins.is_empty() {
            let mut builder = model.to_builder().pins(pins);
            for (points, motion) in motions {
                builder = builder.pin_motion(points, motion);
            }
            model = builder.build().map_err(|e| error(e.to_string()))?;
        }
        // A saved state (a run's end) may rest against anything; a scene's start must be clear.
        if self.bodies.iter().all(|b| b.state.is_none()) {
            check_start(&model, &state, &names).map_err(|(b, e)| SceneError {
                line: self.origin.line(&format!("body.{b}")),
                ..error(e)
            })?;
        }
        Ok(Scene {
            model,
            state,
            names,
        })
    }
}

/// How far a body may start past a wall or an obstacle's surface, or into another body, as a
/// fraction of its finest lattice spacing: a body placed on a plate or against a wall by
/// arithmetic (`0.3 − 0.2`) misses it by a rounding (1e-17 m), which is no overlap.
pub const START_TOLERANCE: f64 = 1e-9;

/// Bodies must start inside the box, apart from each other (their surfaces may touch, up to
/// [`START_TOLERANCE`]), and outside the obstacles; `names` are the bodies'. An error names the
/// body it is about (for its line) and where.
fn check_start(model: &Model, state: &State, names: &[String]) -> Result<(), (usize, String)> {
    let bounds = model.bounds;
    let named = |b: usize| format!("body {} ({})", b + 1, names[b]);
    for (b, body) in model.bodies().iter().enumerate() {
        let slack = START_TOLERANCE * body.min_spacing();
        let r = body.points();
        for p in r.clone().filter(|&p| body.is_active(p - r.start)) {
            let q = state.pos[p];
            if bounds.excursion(q) > slack {
                return Err((
                    b,
                    format!(
                        "{} starts outside the box (a point at {q:.6} is outside {:.6} to {:.6}, \
                         by {:.3e} m)",
                        named(b),
                        bounds.min,
                        bounds.max,
                        bounds.excursion(q)
                    ),
                ));
            }
            let inside = model
                .obstacles
                .iter()
                .enumerate()
                .find_map(|(o, obstacle)| {
                    obstacle
                        .contact(q)
                        .filter(|c| c.depth > slack)
                        .map(|c| (o, c.depth))
                });
            if let Some((o, depth)) = inside {
                return Err((
                    b,
                    format!(
                        "{} starts inside obstacle {} (a point at {q:.6}, {depth:.3e} m deep)",
                        named(b),
                        o + 1
                    ),
                ));
            }
        }
    }
    // Surfaces placed on each other touch but for a rounding. The check is the contact model's:
    // each body's skin (its surface mesh, or its lattice's boundary) against the others'.
    let finest = model
        .bodies()
        .iter()
        .map(|b| b.min_spacing())
        .fold(f64::INFINITY, f64::min);
    let pairs = crate::contact::closest(model, &state.pos);
    if let Some(c) = pairs.iter().find(|c| c.depth > START_TOLERANCE * finest) {
        let [a, b] = c.bodies;
        let what = if a == b {
            format!("{} starts inside itself", named(a))
        } else {
            format!("{} and {} start inside each other", named(a), named(b))
        };
        return Err((
            a,
            format!(
                "{what}: their surfaces overlap by {:.3e} m near {:.6}; move them apart",
                c.depth, c.at
            ),
        ));
    }
    Ok(())
}

/// An error about a body, with the key it is about when there is one (for its line).
pub(super) struct KeyError {
    /// The key at fault within the body's table; `None`: the body as a whole.
    pub(super) key: Option<&'static str>,
    /// What is wrong.
    pub(super) message: String,
}

impl KeyError {
    fn at(key: &'static str, message: String) -> Self {
        KeyError {
            key: Some(key),
            message,
        }
    }

    fn body(message: String) -> Self {
        KeyError { key: None, message }
    }
}

impl BodySpec {
    /// Checks the combination of keys (one shape; at most one way to give the mass, the
    /// stiffness and the damping). Reading a scene file checks this; so should a front end that
    /// builds bodies.
    pub fn check(&self) -> Result<(), String> {
        match (&self.cube, &self.mesh) {
            (Some(_), Some(_)) => return Err("give either cube or mesh, not both".into()),
            (None, None) => return Err("expected a shape: cube = { … } or mesh = { … }".into()),
            _ => {}
        }
        let masses = [self.mass, self.total_mass, self.density]
            .iter()
            .filter(|m| m.is_some())
            .count();
        if masses > 1 {
            return Err("give at most one of mass, total_mass and density".into());
        }
        if self.stiffness.is_some() && self.modulus.is_some() {
            return Err("give either stiffness or modulus, not both".into());
        }
        if self.damping.is_some() && self.viscosity.is_some() {
            return Err("give either damping or viscosity, not both".into());
        }
        Ok(())
    }

    /// The material keys as written: each number finite, and positive where it must be (a
    /// damping may be 0). Checked before they are turned into a mass and stiffnesses per point,
    /// so that the message names the key and the value the file gives.
    fn check_material_keys(&self) -> Result<(), KeyError> {
        let positive = [
            ("mass", self.mass),
            ("total_mass", self.total_mass),
            ("density", self.density),
            ("modulus", self.modulus),
        ];
        let at_least_zero = [("viscosity", self.viscosity)];
        let three = |key, values: Option<[f64; 3]>, positive: bool| {
            values.map_or(Ok(()), |v| {
                if v.iter()
                    .all(|&x| x.is_finite() && (x > 0.0 || !positive && x == 0.0))
                {
                    Ok(())
                } else {
                    let rule = if positive { "above 0" } else { "≥ 0" };
                    Err(KeyError::at(
                        key,
                        format!(
                            "{key} must be three finite numbers {rule} (got {})",
                            Vec3::from_array(v)
                        ),
                    ))
                }
            })
        };
        for (key, value) in positive {
            if let Some(v) = value.filter(|v| !(v.is_finite() && *v > 0.0)) {
                return Err(KeyError::at(
                    key,
                    format!("{key} must be a finite number above 0 (got {v})"),
                ));
            }
        }
        for (key, value) in at_least_zero {
            if let Some(v) = value.filter(|v| !(v.is_finite() && *v >= 0.0)) {
                return Err(KeyError::at(
                    key,
                    format!("{key} must be a finite number ≥ 0 (got {v})"),
                ));
            }
        }
        three("stiffness", self.stiffness, true)?;
        three("damping", self.damping, false)
    }

    /// The body, placed, with its material.
    fn to_body(&self, file: &str) -> Result<Body, KeyError> {
        self.check_material_keys()?;
        let material = Material::classic();
        // The middle of the shape's bounding box, from the lattice's point (0, 0, 0): what
        // `centre` places and `rotation` turns about. A mesh's lattice starts at the mesh's lower
        // corner but may reach up to a cell past its upper one (whole cells), so the lattice's
        // own box is not the shape's.
        let mut middle = None;
        let mut body = match (&self.cube, &self.mesh) {
            (Some(c), None) => Body::lattice_box(Lattice::new(c.points, v3(c.size)), material),
            (None, Some(m)) => {
                let vertices: Vec<Vec3> = m.vertices.iter().map(|&p| v3(p)).collect();
                let mesh = TriMesh::from_parts(&vertices, &m.triangles, &format!("{file}: mesh"))
                    .map_err(|e| KeyError::at("mesh", e.to_string()))?;
                let (lo, hi) = mesh.bounds();
                middle = Some((hi - lo) * 0.5);
                Body::from_mesh(
                    &mesh.vertices,
                    &mesh.triangles,
                    m.cells,
                    MAX_CELLS,
                    material,
                )
                .map_err(|e| KeyError::at("mesh", e.to_string()))?
            }
            _ => return Err(KeyError::body("expected exactly one shape".into())),
        };
        // Placement: turn about the middle of the shape's bounding box, then move it to `centre`.
        let half = middle.unwrap_or(body.lattice().size * 0.5);
        let rotation = self.rotation.map_or(IDENTITY, rotation_xyz);
        let turned_half = Vec3::new(
            rotation[0].dot(half),
            rotation[1].dot(half),
            rotation[2].dot(half),
        );
        let centre = match self.centre {
            Some(c) => v3(c),
            None => body.origin + half,
        };
        let origin = if self.rotation.is_none() && self.centre.is_none() {
            body.origin
        } else {
            centre - turned_half
        };
        body = body.placed(origin, rotation);
        // Material: a density gives the body the mass of its solid (a mesh's own volume, not
        // its cells').
        let volume = body.volume();
        let n = body.active_count() as f64;
        let mut m = body.material;
        if let Some(mass) = self.mass {
            m.mass = mass;
        } else if let Some(total) = self.total_mass {
            m.mass = total / n;
        } else if let Some(density) = self.density {
            m.mass = density * volume / n;
        }
        if let Some(k) = self.stiffness {
            m.stiffness = k;
        }
        if let Some(d) = self.damping {
            m.damping = d;
        }
        if let Some(e) = self.modulus {
            m.stiffness = [e * body.min_spacing(); 3];
        }
        if let Some(eta) = self.viscosity {
            m.damping = [eta * body.min_spacing(); 3];
        }
        m.check().map_err(|e| KeyError::body(e.to_string()))?;
        body.material = m;
        self.apply_regions(&mut body)
            .map_err(|e| KeyError::at("region", e))?;
        Ok(body)
    }

    /// Scales the springs of each region in turn.
    fn apply_regions(&self, body: &mut Body) -> Result<(), String> {
        if self.region.is_empty() {
            return Ok(());
        }
        let rest: Vec<[f64; 3]> = body.rest_positions().iter().map(|p| p.to_array()).collect();
        // Boundaries are included up to rounding: a point computed as `size · i / (n − 1)` may
        // miss a boundary written in decimal by an ulp or so.
        let slack = 1e-9 * body.lattice().size.max_abs();
        for (r, region) in self.region.iter().enumerate() {
            let what = |e: String| format!("region {}: {e}", r + 1);
            let (lo, hi) = (region.min, region.max);
            if !(v3(lo).is_finite() && v3(hi).is_finite()) || (0..3).any(|a| lo[a] > hi[a]) {
                return Err(what(format!(
                    "needs finite corners with min ≤ max (got {} to {})",
                    v3(region.min),
                    v3(region.max)
                )));
            }
            let scale = region.scale();
            scale.check().map_err(|e| what(e.to_string()))?;
            let inside: Vec<bool> = rest
                .iter()
                .map(|p| (0..3).all(|a| p[a] >= lo[a] - slack && p[a] <= hi[a] + slack))
                .collect();
            let mut caught = 0;
            body.scale_springs(|s| {
                if inside[s.a] && inside[s.b] {
                    caught += 1;
                    scale
                } else {
                    SpringScale::ONE
                }
            })
            .map_err(|e| what(e.to_string()))?;
            if caught == 0 {
                let (mut min, mut max) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
                for p in rest.iter().enumerate().filter(|(q, _)| body.is_active(*q)) {
                    for a in 0..3 {
                        (min[a], max[a]) = (min[a].min(p.1[a]), max[a].max(p.1[a]));
                    }
                }
                return Err(what(format!(
                    "no spring has both ends in {} to {} (the body rests within {:.6} to {:.6} as \
                     placed)",
                    v3(region.min),
                    v3(region.max),
                    v3(min),
                    v3(max)
                )));
            }
        }
        Ok(())
    }

    /// Writes body `b`'s initial positions and velocities into the state.
    fn initial_state(&self, model: &Model, b: usize, state: &mut State) -> Result<(), KeyError> {
        let body = model.body(b);
        let range = body.points();
        if let Some(s) = &self.state {
            let n = range.len();
            if s.positions.len() != n || s.velocities.len() != n {
                return Err(KeyError::at("state", format!(
                    "state needs {n} positions and {n} velocities (one per lattice point), found {} and {}",
                    s.positions.len(),
                    s.velocities.len()
                )));
            }
            for (q, (p, v)) in range.zip(s.positions.iter().zip(&s.velocities)) {
                let (p, v) = (v3(*p), v3(*v));
                if !(p.is_finite() && v.is_finite()) {
                    return Err(KeyError::at("state", "state values must be finite".into()));
                }
                (state.pos[q], state.vel[q]) = (p, v);
            }
            return Ok(());
        }
        let first = range.start;
        let active = |q: &usize| body.is_active(q - first);
        let com = crate::diagnostics::body_centre_of_mass(model, b, &state.pos);
        let v0 = self.velocity.map_or(Vec3::ZERO, v3);
        let w = self.spin.map_or(Vec3::ZERO, v3);
        if !v0.is_finite() {
            return Err(KeyError::at(
                "velocity",
                format!("velocity must be finite (got {v0})"),
            ));
        }
        if !w.is_finite() {
            return Err(KeyError::at(
                "spin",
                format!("spin must be finite (got {w})"),
            ));
        }
        for q in range.filter(active) {
            state.vel[q] = rigid_velocity(v0, w, com, state.pos[q]);
        }
        Ok(())
    }
}
