//! Scene files: a whole simulation in TOML (settings, bodies, obstacles, field, pinned points),
//! self-contained (a body's mesh is embedded and voxelised again when the file is read, by the
//! same deterministic code), for the command line, the viewer and Python alike.
//!
//! ```toml
//! [simulation]
//! integrator = "RK4"          # Euler, RK2, RK4, SymplecticEuler, BackwardEuler, SDIRK2
//! dt = 0.0005                 # s
//! steps_per_frame = 1
//! gravity = [0.0, 0.0, -9.81] # m/s², on every point whatever its mass (left out: this, or none
//!                             # in a scene with a [field])
//! cutbacks = 6                # implicit methods: halvings of a step that fails (0–20; see
//!                             # jello_core::integrate::cutback)
//! tolerance = 1e-9            # implicit methods: residual allowed per point (m/s, times the
//!                             # largest speed above 1 m/s; up to 0.1; see jello_core::integrate::implicit)
//!
//! [collision]                 # the penalty springs of walls, obstacles and contacts
//! stiffness = 400.0           # N/m
//! damping = 0.25              # N·s/m
//! friction = 0.5              # Coulomb coefficient of obstacles and contacts
//! wall_friction = 0.5         # and of the walls and the inclined plane
//! self_contact = false        # whether a body's surface touches its own (a bar bent over)
//!
//! [box]                       # the walls
//! min = [-2.0, -2.0, -2.0]
//! max = [2.0, 2.0, 2.0]
//!
//! [[obstacle]]
//! type = "sphere"             # or "plane" (coeffs = [a, b, c, d], allowed where a x + b y + c z + d ≥ 0)
//! centre = [0.0, 0.0, -1.0]   # or "box" (min, max)
//! radius = 0.5
//!
//! [[body]]
//! name = "cube"
//! cube = { points = [8, 8, 8], size = [1.0, 1.0, 1.0] }   # or mesh = { vertices, triangles }, cells
//! centre = [0.0, 0.0, 0.5]    # where the middle of its shape's bounding box goes (a mesh's own)
//! rotation = [0.0, 0.0, 30.0] # degrees about x, then y, then z
//! velocity = [0.0, 0.0, 0.0]  # m/s
//! spin = [0.0, 0.0, 0.0]      # rad/s, about its centre of mass
//! total_mass = 1.0            # kg; or mass (per point), or density (kg/m³)
//! stiffness = [200.0, 200.0, 200.0]  # N/m: structural, shear, bend; or modulus (Pa)
//! damping = [0.25, 0.25, 0.25]       # N·s/m; or viscosity (Pa·s)
//! pins = [{ at = [0.0, 0.0, 1.0], radius = 0.1 }]   # points within radius held (0: nearest)
//! # A pin may move (see jello_core::model::motion): shake = { amplitude = [0.1, 0.0, 0.0], frequency = 2.0 }
//! # (m, Hz: amplitude · sin(2π f t)), or path = [[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.5]]
//! # ([t, dx, dy, dz] keyframes, s and m from where the points start, straight lines between).
//!
//! [[body.region]]             # factors on the springs with both ends in a box, where the body
//! min = [0.0, 0.0, 0.5]       # rests as placed (like pins), boundaries included; regions that
//! max = [1.0, 1.0, 1.0]       # overlap multiply
//! stiffness = 4.0             # × the material's stiffness (default 1)
//! damping = 1.0               # × the material's damping (default 1)
//! rest = 0.9                  # × the rest length (default 1): below 1 the region pulls together
//! ```
//!
//! Every key is checked: an unknown key, a wrong type or a missing value is an error naming the
//! file, line and column.

use std::fmt;

mod build;
mod source;
mod tables;

pub use tables::{
    BodySpec, BoxSpec, Collision, CubeSpec, FieldSpec, MeshSpec, ObstacleSpec, PinSpec, RegionSpec,
    Settings, ShakeSpec, StateSpec, DEFAULT_CELLS, DEFAULT_FRICTION, DEFAULT_GRAVITY,
    DEFAULT_WALL_FRICTION,
};

use serde::{Deserialize, Serialize};

use self::source::SourceLines;
use crate::model::body::Material;
use crate::model::field_preset::FieldPreset;
use crate::model::{Aabb, Model, Plane};
use crate::state::State;
use crate::vec3::Vec3;

/// The most cells a voxelised mesh may have (over its whole grid).
pub const MAX_CELLS: usize = 1 << 22;

/// A scene file that could not be read or made into a simulation: the file, the line and column
/// (1-based; 0 when unknown) and what was expected.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct SceneError {
    /// The file's name as given.
    pub source_name: String,
    /// Line (from 1), or 0 when the error belongs to no line.
    pub line: usize,
    /// Column (from 1), or 0.
    pub column: usize,
    /// What is wrong.
    pub message: String,
}

impl fmt::Display for SceneError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match (self.line, self.column) {
            (0, _) => write!(f, "{}: {}", self.source_name, self.message),
            (l, 0) => write!(f, "{}:{l}: {}", self.source_name, self.message),
            (l, c) => write!(f, "{}:{l}:{c}: {}", self.source_name, self.message),
        }
    }
}

impl std::error::Error for SceneError {}

/// A scene as written in its file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// Time stepping and gravity.
    #[serde(default)]
    pub simulation: Settings,
    /// The penalty springs of walls, obstacles and contacts between bodies.
    #[serde(default)]
    pub collision: Collision,
    /// The walls (default: the classic box `[−2, 2]³`).
    #[serde(default, rename = "box", skip_serializing_if = "Option::is_none")]
    pub bounds: Option<BoxSpec>,
    /// A force field sampled on a grid over the box.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub field: Option<FieldSpec>,
    /// Static obstacles.
    #[serde(default, rename = "obstacle", skip_serializing_if = "Vec::is_empty")]
    pub obstacles: Vec<ObstacleSpec>,
    /// The bodies (at least one).
    #[serde(default, rename = "body")]
    pub bodies: Vec<BodySpec>,
    /// Where each table and key is in the file it was read from, for errors found when the
    /// scene is made into a model.
    #[serde(skip)]
    origin: SourceLines,
}

/// A scene made ready to step: the model, its initial state, and per body its name.
#[derive(Clone, Debug)]
pub struct Scene {
    /// What does not change while stepping.
    pub model: Model,
    /// The initial state.
    pub state: State,
    /// Per body, its name.
    pub names: Vec<String>,
}

fn line_column(text: &str, offset: usize) -> (usize, usize) {
    let before = &text[..offset.min(text.len())];
    let line = before.matches('\n').count() + 1;
    let column = before.rsplit('\n').next().map_or(0, |l| l.chars().count()) + 1;
    (line, column)
}

impl SceneFile {
    /// A scene of these bodies with every other setting at its default.
    pub fn new(bodies: Vec<BodySpec>) -> Self {
        SceneFile {
            bodies,
            ..SceneFile::default()
        }
    }

    /// Sets a new scene's gravity and field from a preset and an optional gravity, as
    /// `jello create` and Python's `jello.create` do: the `gravity` preset is an acceleration
    /// (the same on light and heavy points) unless a gravity is given too, which is an error; any
    /// other field is sampled on a `res`³ grid over the walls and replaces the default gravity.
    pub fn set_gravity_and_field(
        &mut self,
        preset: FieldPreset,
        res: usize,
        gravity: Option<[f64; 3]>,
    ) -> Result<(), String> {
        let bounds = match self.bounds {
            Some(b) => Aabb::new(Vec3::from_array(b.min), Vec3::from_array(b.max))
                .map_err(|e| format!("box: {e}"))?,
            None => Aabb::classic(),
        };
        let (gravity, field) = match (preset, gravity) {
            (FieldPreset::Gravity(_), Some(_)) => {
                return Err("give either a gravity or the gravity field, not both".into())
            }
            (FieldPreset::Gravity(g), None) => ([0.0, 0.0, -g], None),
            (FieldPreset::None, g) => (g.unwrap_or(DEFAULT_GRAVITY), None),
            (spec, g) => {
                let f = spec
                    .sample(res, bounds, 0.0)
                    .map_err(|e| format!("field: {e}"))?;
                (g.unwrap_or([0.0; 3]), f)
            }
        };
        self.simulation.gravity = Some(gravity);
        self.field = field.map(|f| FieldSpec {
            resolution: res,
            forces: f.forces().iter().map(|v| v.to_array()).collect(),
        });
        Ok(())
    }

    /// The acceleration on every point (m/s²): `[simulation] gravity` when given, else
    /// [`DEFAULT_GRAVITY`] without a field and none with one.
    pub fn gravity(&self) -> [f64; 3] {
        match (self.simulation.gravity, &self.field) {
            (Some(g), _) => g,
            (None, None) => DEFAULT_GRAVITY,
            (None, Some(_)) => [0.0; 3],
        }
    }

    /// Adds the plane `a x + b y + c z + d = 0` as an obstacle that keeps the bodies on the side
    /// where the first body's centre of mass lies (as the classic worlds' plane does); `name`
    /// labels errors.
    pub fn add_plane_facing_first_body(
        &mut self,
        coeffs: [f64; 4],
        name: &str,
    ) -> Result<(), SceneError> {
        let made = self.to_scene(name)?;
        let centre = crate::diagnostics::body_centre_of_mass(&made.model, 0, &made.state.pos);
        let plane = Plane::facing(coeffs, centre).map_err(|e| SceneError {
            source_name: name.to_string(),
            line: 0,
            column: 0,
            message: format!("plane: {e}"),
        })?;
        let coeffs = coeffs.map(|c| c * plane.side);
        self.obstacles.push(ObstacleSpec::Plane { coeffs });
        Ok(())
    }

    /// Writes into the bodies the material of `model`'s bodies where it differs from `initial`
    /// (what the scene gave them when it was made): stiffness, damping and mass per point, in
    /// place of the ways the file gave them (total mass, density, modulus, viscosity). For saving
    /// a scene whose materials were changed while it ran.
    pub fn record_materials(&mut self, model: &Model, initial: &[Material]) {
        for (spec, (body, initial)) in self
            .bodies
            .iter_mut()
            .zip(model.bodies().iter().zip(initial))
        {
            if body.material != *initial {
                spec.stiffness = Some(body.material.stiffness);
                spec.damping = Some(body.material.damping);
                spec.mass = Some(body.material.mass);
                spec.total_mass = None;
                spec.density = None;
                spec.modulus = None;
                spec.viscosity = None;
            }
        }
        self.collision.stiffness = model.k_collision;
        self.collision.damping = model.d_collision;
    }

    /// Each body's name: its own, or `body1`, `body2`… by position.
    pub fn body_names(&self) -> Vec<String> {
        (self.bodies.iter().enumerate())
            .map(|(b, spec)| {
                spec.name
                    .clone()
                    .unwrap_or_else(|| format!("body{}", b + 1))
            })
            .collect()
    }

    /// Reads a scene from the bytes of a TOML file; `name` labels errors.
    pub fn parse(bytes: &[u8], name: &str) -> Result<SceneFile, SceneError> {
        let error = |line, column, message: String| SceneError {
            source_name: name.to_string(),
            line,
            column,
            message,
        };
        let text = std::str::from_utf8(bytes).map_err(|e| {
            let (line, column) = line_column(
                std::str::from_utf8(&bytes[..e.valid_up_to()]).unwrap_or(""),
                e.valid_up_to(),
            );
            error(line, column, "expected UTF-8 text".into())
        })?;
        let mut scene: SceneFile = toml::from_str(text).map_err(|e| {
            let message = e.message().trim_end().to_string();
            let Some(span) = e.span() else {
                return error(0, 0, message);
            };
            // An unknown key is reported at its table (an `[[array]]` table's header only):
            // point at the key itself, the first place it is written as a key from there on.
            let unknown = message
                .strip_prefix("unknown field `")
                .and_then(|rest| rest.split_once('`'))
                .and_then(|(key, _)| source::find_key(&text[span.start..], key));
            let (line, column) = line_column(text, span.start + unknown.unwrap_or(0));
            error(line, column, message)
        })?;
        // Semantic checks that serde cannot make, at the line of the body's header.
        if scene.bodies.is_empty() {
            return Err(error(0, 0, "expected at least one [[body]]".into()));
        }
        scene.origin = SourceLines::of(text);
        for (b, body) in scene.bodies.iter().enumerate() {
            let line = scene.origin.line(&format!("body.{b}"));
            body.check()
                .map_err(|m| error(line, 0, format!("body {}: {m}", b + 1)))?;
        }
        Ok(scene)
    }

    /// The scene as TOML text.
    pub fn to_toml(&self) -> String {
        let mut text =
            String::from("# A Jello scene (see docs/scenes.md and `jello create --help`).\n");
        text.push_str(&toml::to_string(self).expect("a scene always serialises"));
        text
    }

    /// This scene with every body's state replaced by `state`, and the model's integrator, time
    /// step, cutbacks and tolerance (for saving a run's end, which may have changed them).
    pub fn with_state(&self, model: &Model, state: &State) -> SceneFile {
        let mut scene = self.clone();
        scene.simulation.time = state.time;
        scene.simulation.integrator = model.integrator.name().to_string();
        scene.simulation.dt = model.dt;
        scene.simulation.cutbacks = model.newton.cutbacks;
        scene.simulation.tolerance = model.newton.tolerance;
        for (spec, body) in scene.bodies.iter_mut().zip(model.bodies()) {
            let r = body.points();
            spec.state = Some(StateSpec {
                positions: state.pos[r.clone()].iter().map(|p| p.to_array()).collect(),
                velocities: state.vel[r].iter().map(|v| v.to_array()).collect(),
            });
        }
        scene
    }
}
