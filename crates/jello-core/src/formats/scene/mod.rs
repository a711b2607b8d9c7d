//! Scene files: a whole simulation in TOML (settings, bodies, obstacles, field, pinned points),
//! self-contained (a body's mesh is embedded and voxelised again when the file is read, by the
//! same deterministic code), for the command line, the viewer and Python alike.
//!
//! ```toml
//! [simulation]
//! integrator = "RK4"          # Euler, RK2, RK4, SymplecticEuler, BackwardEuler, SDIRK2
//! dt = 0.0005                 # s
//! steps_per_frame = 1
//! gravity = [0.0, 0.0, -9.81] # m/s², on every point whatever its mass
//! cutbacks = 6                # implicit methods: halvings of a step that fails (0–20; see
//!                             # jello_core::cutback)
//! tolerance = 1e-9            # implicit methods: residual allowed per point (m/s, times the
//!                             # largest speed above 1 m/s; up to 0.1; see jello_core::implicit)
//!
//! [collision]                 # the penalty springs of walls, obstacles and contacts
//! stiffness = 400.0           # N/m
//! damping = 0.25              # N·s/m
//! friction = 0.5              # Coulomb coefficient of obstacles and contacts (not the walls)
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
//! centre = [0.0, 0.0, 0.5]    # where the middle of its rest bounding box goes
//! rotation = [0.0, 0.0, 30.0] # degrees about x, then y, then z
//! velocity = [0.0, 0.0, 0.0]  # m/s
//! spin = [0.0, 0.0, 0.0]      # rad/s, about its centre of mass
//! total_mass = 1.0            # kg; or mass (per point), or density (kg/m³)
//! stiffness = [200.0, 200.0, 200.0]  # N/m: structural, shear, bend; or modulus (Pa)
//! damping = [0.25, 0.25, 0.25]       # N·s/m; or viscosity (Pa·s)
//! pins = [{ at = [0.0, 0.0, 1.0], radius = 0.1 }]   # points within radius held (0: nearest)
//! # A pin may move (see jello_core::motion): shake = { amplitude = [0.1, 0.0, 0.0], frequency = 2.0 }
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

use serde::{Deserialize, Serialize};

use crate::formats::mesh::TriMesh;
use crate::model::body::{rotation_xyz, Body, Material, IDENTITY};
use crate::model::field::ForceField;
use crate::model::field_preset::FieldPreset;
use crate::model::integrator::Integrator;
use crate::model::lattice::Lattice;
use crate::model::motion::Motion;
use crate::model::obstacle::Sphere;
use crate::model::springs::SpringScale;
use crate::model::{defaults, Aabb, Model, ModelBuilder, ModelError, Obstacle, Plane};
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
    /// Where each body's table starts in the file it was read from, for errors found when the
    /// scene is made into a model.
    #[serde(skip)]
    origin: SourceLines,
}

/// Lines of the `[[body]]` headers in the text a scene was read from: where it came from, not
/// part of its value (two scenes with the same content are equal wherever they were read).
#[derive(Clone, Debug, Default)]
struct SourceLines(Vec<usize>);

impl PartialEq for SourceLines {
    fn eq(&self, _: &Self) -> bool {
        true
    }
}

/// `[simulation]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Settings {
    /// Euler, RK2, RK4 or SymplecticEuler (any case).
    pub integrator: String,
    /// Time step (s).
    pub dt: f64,
    /// Steps per displayed frame.
    pub steps_per_frame: u32,
    /// Acceleration of every point (m/s²).
    pub gravity: [f64; 3],
    /// How many times an implicit step that fails may be halved (see [`crate::integrate::cutback`]);
    /// written only when not the default.
    #[serde(skip_serializing_if = "is_default_cutbacks")]
    pub cutbacks: u32,
    /// The residual an implicit step is solved to (m/s; see [`crate::model::solver::Newton`]);
    /// written only when not the default.
    #[serde(skip_serializing_if = "is_default_tolerance")]
    pub tolerance: f64,
    /// Simulated time of the start state (s): 0 for a new scene, the run's end time in a saved
    /// one (so moving pins carry on in step with their paths).
    #[serde(skip_serializing_if = "is_zero")]
    pub time: f64,
}

fn is_zero(t: &f64) -> bool {
    *t == 0.0
}

fn is_default_cutbacks(n: &u32) -> bool {
    *n == crate::model::solver::CUTBACKS
}

fn is_default_tolerance(t: &f64) -> bool {
    *t == crate::model::solver::TOLERANCE
}

impl Default for Settings {
    fn default() -> Self {
        Settings {
            integrator: "RK4".into(),
            dt: defaults::DT,
            steps_per_frame: defaults::STEPS_PER_FRAME,
            gravity: [0.0; 3],
            cutbacks: crate::model::solver::CUTBACKS,
            tolerance: crate::model::solver::TOLERANCE,
            time: 0.0,
        }
    }
}

/// `[collision]`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Collision {
    /// N/m.
    pub stiffness: f64,
    /// N·s/m.
    pub damping: f64,
    /// Coulomb friction coefficient of obstacles and of contacts between bodies (see
    /// [`crate::contact::friction`]); the walls have none, as in SPEC.md.
    pub friction: f64,
}

/// Friction coefficient of a scene that does not give one: about rubbery jelly on a plate.
pub const DEFAULT_FRICTION: f64 = 0.5;

/// Cells along a mesh's longest side when a new scene does not say.
pub const DEFAULT_CELLS: usize = 10;

/// Gravity of a new scene given neither gravity nor a field (m/s²; z is up, as in the classic
/// worlds and the viewer).
pub const DEFAULT_GRAVITY: [f64; 3] = [0.0, 0.0, -9.81];

impl Default for Collision {
    fn default() -> Self {
        Collision {
            stiffness: defaults::K_COLLISION,
            damping: defaults::D_COLLISION,
            friction: DEFAULT_FRICTION,
        }
    }
}

/// An axis-aligned box: `[box]` or a box obstacle.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BoxSpec {
    /// Lower corner (m).
    pub min: [f64; 3],
    /// Upper corner (m).
    pub max: [f64; 3],
}

/// `[field]`: forces (N) at the nodes of a `resolution³` grid over the box, in the world file's
/// order (x slowest, z fastest).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FieldSpec {
    /// Nodes per axis.
    pub resolution: usize,
    /// One force per node.
    pub forces: Vec<[f64; 3]>,
}

/// `[[obstacle]]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum ObstacleSpec {
    /// Points are kept where `a x + b y + c z + d ≥ 0`.
    Plane {
        /// `[a, b, c, d]`.
        coeffs: [f64; 4],
    },
    /// A solid ball.
    Sphere {
        /// Centre (m).
        centre: [f64; 3],
        /// Radius (m).
        radius: f64,
    },
    /// A solid axis-aligned box.
    Box {
        /// Lower corner (m).
        min: [f64; 3],
        /// Upper corner (m).
        max: [f64; 3],
    },
}

/// `[[body]]`: a shape (exactly one of `cube` and `mesh`), its placement, motion and material.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BodySpec {
    /// A name for messages and exports.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub name: Option<String>,
    /// A box lattice.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub cube: Option<CubeSpec>,
    /// A closed triangle mesh, voxelised into `cells` cells along its longest side.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mesh: Option<MeshSpec>,
    /// Where the middle of the rest bounding box goes (m); default: a cube's lower corner at the
    /// origin, a mesh where it is.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub centre: Option<[f64; 3]>,
    /// Degrees about x, then y, then z, about the centre.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotation: Option<[f64; 3]>,
    /// Initial velocity (m/s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub velocity: Option<[f64; 3]>,
    /// Initial angular velocity about the centre of mass (rad/s).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub spin: Option<[f64; 3]>,
    /// Mass of each point (kg).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub mass: Option<f64>,
    /// Mass of the body (kg), spread over its points.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub total_mass: Option<f64>,
    /// Density (kg/m³) over the volume of its cells.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub density: Option<f64>,
    /// Stiffness of structural, shear and bend springs (N/m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stiffness: Option<[f64; 3]>,
    /// Damping of structural, shear and bend springs (N·s/m).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub damping: Option<[f64; 3]>,
    /// A stiffness that does not depend on the resolution (Pa): every spring `modulus · h`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub modulus: Option<f64>,
    /// A damping that does not depend on the resolution (Pa·s): every spring `viscosity · h`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub viscosity: Option<f64>,
    /// Pinned points.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub pins: Vec<PinSpec>,
    /// Regions of springs with their own stiffness, damping or rest length, applied in order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub region: Vec<RegionSpec>,
    /// A saved state: every lattice point's position and velocity (replaces placement and
    /// motion).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub state: Option<StateSpec>,
}

/// `[[body.region]]`: factors on the springs whose two ends rest in a box (m), in the body's rest
/// shape as placed (where it starts; as pins are found), boundaries included.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionSpec {
    /// Lower corner (m).
    pub min: [f64; 3],
    /// Upper corner (m).
    pub max: [f64; 3],
    /// Factor on the stiffness.
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub stiffness: f64,
    /// Factor on the damping.
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub damping: f64,
    /// Factor on the rest length.
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub rest: f64,
}

fn one() -> f64 {
    1.0
}

fn is_one(x: &f64) -> bool {
    *x == 1.0
}

impl RegionSpec {
    /// The factors.
    pub fn scale(&self) -> SpringScale {
        SpringScale {
            rest: self.rest,
            stiffness: self.stiffness,
            damping: self.damping,
        }
    }
}

/// `cube = { points, size }`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct CubeSpec {
    /// Points per axis.
    pub points: [usize; 3],
    /// Side lengths (m).
    pub size: [f64; 3],
}

/// `mesh = { vertices, triangles, cells }`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct MeshSpec {
    /// Cells along the longest side of its bounding box.
    pub cells: usize,
    /// Vertex positions (m).
    pub vertices: Vec<[f64; 3]>,
    /// Triangles, wound outward, indices from 0.
    pub triangles: Vec<[u32; 3]>,
}

/// `{ at, radius }`: the active points within `radius` of `at` at rest are held (radius 0: the
/// nearest one); with `shake` or `path`, moved (see [`crate::model::motion`]).
#[derive(Clone, Debug, PartialEq, Default, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PinSpec {
    /// Centre of the region (m), in the placed rest shape.
    pub at: [f64; 3],
    /// Radius of the region (m).
    pub radius: f64,
    /// Shaking: `amplitude · sin(2π · frequency · t)` from where the points start.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub shake: Option<ShakeSpec>,
    /// A path: keyframes `[t, dx, dy, dz]` (s, m) from where the points start.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub path: Option<Vec<[f64; 4]>>,
}

/// `shake = { amplitude, frequency }`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ShakeSpec {
    /// Largest offset along each axis (m).
    pub amplitude: [f64; 3],
    /// Hz.
    pub frequency: f64,
}

impl PinSpec {
    /// The motion the pin asks for, if any; an error when it asks for both a shake and a path.
    fn motion(&self) -> Result<Option<Motion>, String> {
        match (&self.shake, &self.path) {
            (Some(_), Some(_)) => Err("give a shake or a path, not both".into()),
            (Some(s), None) => Ok(Some(Motion::Shake {
                amplitude: v3(s.amplitude),
                frequency: s.frequency,
            })),
            (None, Some(keys)) => Ok(Some(Motion::Path(
                keys.iter()
                    .map(|&[t, x, y, z]| (t, Vec3::new(x, y, z)))
                    .collect(),
            ))),
            (None, None) => Ok(None),
        }
    }
}

/// A saved body state.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct StateSpec {
    /// Position of every lattice point (m).
    pub positions: Vec<[f64; 3]>,
    /// Velocity of every lattice point (m/s).
    pub velocities: Vec<[f64; 3]>,
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

fn v3(a: [f64; 3]) -> Vec3 {
    Vec3::new(a[0], a[1], a[2])
}

/// 1-based line and column of byte `offset` in `text`.
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
        self.simulation.gravity = gravity;
        self.field = field.map(|f| FieldSpec {
            resolution: res,
            forces: f.forces().iter().map(|v| v.to_array()).collect(),
        });
        Ok(())
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
            let (line, column) = e.span().map_or((0, 0), |s| line_column(text, s.start));
            error(line, column, e.message().trim_end().to_string())
        })?;
        // Semantic checks that serde cannot make, at the line of the body's header.
        if scene.bodies.is_empty() {
            return Err(error(0, 0, "expected at least one [[body]]".into()));
        }
        scene.origin = SourceLines(
            (0..scene.bodies.len())
                .map(|b| body_header_line(text, b))
                .collect(),
        );
        for (b, body) in scene.bodies.iter().enumerate() {
            body.check()
                .map_err(|m| error(scene.origin.0[b], 0, format!("body {}: {m}", b + 1)))?;
        }
        Ok(scene)
    }

    /// The scene as TOML text.
    pub fn to_toml(&self) -> String {
        let mut text =
            String::from("# A Jello scene (see `jello create --help` and the README).\n");
        text.push_str(&toml::to_string(self).expect("a scene always serialises"));
        text
    }

    /// The model and initial state this scene describes.
    pub fn to_scene(&self, name: &str) -> Result<Scene, SceneError> {
        let error = |message: String| SceneError {
            source_name: name.to_string(),
            line: 0,
            column: 0,
            message,
        };
        let integrator: Integrator = self
            .simulation
            .integrator
            .parse()
            .map_err(|e: crate::model::integrator::UnknownIntegrator| error(e.to_string()))?;
        let bounds = match self.bounds {
            Some(b) => Aabb::new(v3(b.min), v3(b.max)).map_err(|e| error(format!("box: {e}")))?,
            None => Aabb::classic(),
        };
        let field = match &self.field {
            Some(f) => Some(
                ForceField::new(
                    f.resolution,
                    bounds,
                    f.forces.iter().map(|&p| v3(p)).collect(),
                )
                .map_err(|e| error(format!("field: {e}")))?,
            ),
            None => None,
        };
        let mut obstacles = Vec::new();
        for (i, o) in self.obstacles.iter().enumerate() {
            let what = |e: ModelError| error(format!("obstacle {}: {e}", i + 1));
            obstacles.push(match *o {
                ObstacleSpec::Plane { coeffs } => {
                    Obstacle::Plane(Plane::new(coeffs).map_err(what)?)
                }
                ObstacleSpec::Sphere { centre, radius } => {
                    Obstacle::Sphere(Sphere::new(v3(centre), radius).map_err(what)?)
                }
                ObstacleSpec::Box { min, max } => {
                    Obstacle::Box(Aabb::new(v3(min), v3(max)).map_err(what)?)
                }
            });
        }
        let mut bodies = Vec::new();
        let names = self.body_names();
        let at_body = |b: usize, message: String| SceneError {
            source_name: name.to_string(),
            line: self.origin.0.get(b).copied().unwrap_or(0),
            column: 0,
            message: format!("body {}: {message}", b + 1),
        };
        for (b, spec) in self.bodies.iter().enumerate() {
            let body = spec.to_body(name).map_err(|e| at_body(b, e))?;
            bodies.push(body);
        }
        let c = &self.collision;
        if !(c.stiffness.is_finite() && c.stiffness > 0.0) {
            return Err(error(format!(
                "[collision] stiffness must be a finite number above 0 (got {})",
                c.stiffness
            )));
        }
        for (what, v) in [("damping", c.damping), ("friction", c.friction)] {
            if !(v.is_finite() && v >= 0.0) {
                return Err(error(format!(
                    "[collision] {what} must be a finite number ≥ 0 (got {v})"
                )));
            }
        }
        if self.simulation.cutbacks > crate::model::solver::MAX_CUTBACKS {
            return Err(error(format!(
                "[simulation] cutbacks must be at most {} (got {})",
                crate::model::solver::MAX_CUTBACKS,
                self.simulation.cutbacks
            )));
        }
        let tolerance = self.simulation.tolerance;
        if !(tolerance.is_finite()
            && tolerance > 0.0
            && tolerance <= crate::model::solver::MAX_TOLERANCE)
        {
            return Err(error(format!(
                "[simulation] tolerance must be a number above 0 and at most {} m/s (got {tolerance})",
                crate::model::solver::MAX_TOLERANCE,
            )));
        }
        let mut model = ModelBuilder::new()
            .bodies(bodies)
            .integrator(integrator)
            .dt(self.simulation.dt)
            .steps_per_frame(self.simulation.steps_per_frame)
            .gravity(v3(self.simulation.gravity))
            .collision(self.collision.stiffness, self.collision.damping)
            .friction(self.collision.friction)
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
            return Err(error("[simulation] time must be finite".into()));
        }
        state.time = self.simulation.time;
        let mut pins = Vec::new();
        let mut motions = Vec::new();
        for (b, spec) in self.bodies.iter().enumerate() {
            let body = model.body(b);
            let range = body.points();
            spec.initial_state(&model, b, &mut state)
                .map_err(|e| at_body(b, e))?;
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
                if !(pin.radius >= 0.0 && pin.radius.is_finite()) {
                    return Err(at_body(
                        b,
                        format!(
                            "pin {} needs a finite radius ≥ 0 (0: the nearest point)",
                            n + 1
                        ),
                    ));
                }
                if held.is_empty() {
                    return Err(at_body(
                        b,
                        format!(
                            "pin {} holds no point (none within {} m of {:?})",
                            n + 1,
                            pin.radius,
                            pin.at
                        ),
                    ));
                }
                let motion = pin
                    .motion()
                    .map_err(|e| at_body(b, format!("pin {}: {e}", n + 1)))?;
                if let Some(motion) = motion {
                    motion
                        .check()
                        .map_err(|e| at_body(b, format!("pin {}: {e}", n + 1)))?;
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
            check_start(&model, &state).map_err(error)?;
        }
        Ok(Scene {
            model,
            state,
            names,
        })
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

/// Line of the header of the `b`-th `[[body]]` (0 when not found).
fn body_header_line(text: &str, b: usize) -> usize {
    text.lines()
        .enumerate()
        .filter(|(_, l)| {
            let t = l.trim_start();
            t.starts_with("[[body]]") || t.starts_with("[[ body ]]")
        })
        .nth(b)
        .map_or(0, |(n, _)| n + 1)
}

/// Bodies must start inside the box, apart from each other, and outside the obstacles.
fn check_start(model: &Model, state: &State) -> Result<(), String> {
    let bounds = model.bounds;
    for (b, body) in model.bodies().iter().enumerate() {
        let r = body.points();
        for p in r.clone().filter(|&p| body.is_active(p - r.start)) {
            let q = state.pos[p];
            if bounds.excursion(q) > 0.0 {
                return Err(format!(
                    "body {} starts outside the box (a point at {:?} is outside {:?} to {:?})",
                    b + 1,
                    q.to_array(),
                    bounds.min.to_array(),
                    bounds.max.to_array()
                ));
            }
            if let Some(o) = model.obstacles.iter().position(|o| o.contact(q).is_some()) {
                return Err(format!(
                    "body {} starts inside obstacle {} (a point at {:?})",
                    b + 1,
                    o + 1,
                    q.to_array()
                ));
            }
        }
    }
    let (overlap, _) = crate::contact::overlap(model, &state.pos);
    if overlap > 0.0 {
        return Err(format!(
            "bodies start interpenetrating (by {overlap:.3e} m, counting each point as a ball of half its lattice spacing); move them apart"
        ));
    }
    Ok(())
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

    /// The body, placed, with its material.
    fn to_body(&self, file: &str) -> Result<Body, String> {
        let material = Material::classic();
        let mut body = match (&self.cube, &self.mesh) {
            (Some(c), None) => Body::lattice_box(Lattice::new(c.points, v3(c.size)), material),
            (None, Some(m)) => {
                let vertices: Vec<Vec3> = m.vertices.iter().map(|&p| v3(p)).collect();
                let mesh = TriMesh::from_parts(&vertices, &m.triangles, &format!("{file}: mesh"))
                    .map_err(|e| e.to_string())?;
                Body::from_mesh(
                    &mesh.vertices,
                    &mesh.triangles,
                    m.cells,
                    MAX_CELLS,
                    material,
                )
                .map_err(|e| e.to_string())?
            }
            _ => return Err("expected exactly one shape".into()),
        };
        // Placement: turn about the middle of the rest bounding box, then move it to `centre`.
        let size = body.lattice().size;
        let half = size * 0.5;
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
        // Material.
        let h = body.lattice().spacing();
        let cell_volume = h.x * h.y * h.z;
        let volume = body.cell_count() as f64 * cell_volume;
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
        m.check().map_err(|e| e.to_string())?;
        body.material = m;
        self.apply_regions(&mut body)?;
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
                    "needs finite corners with min ≤ max (got {:?} to {:?})",
                    region.min, region.max
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
                    "no spring has both ends in {:?} to {:?} (the body rests within {min:?} to \
                     {max:?} as placed)",
                    region.min, region.max
                )));
            }
        }
        Ok(())
    }

    /// Writes body `b`'s initial positions and velocities into the state.
    fn initial_state(&self, model: &Model, b: usize, state: &mut State) -> Result<(), String> {
        let body = model.body(b);
        let range = body.points();
        if let Some(s) = &self.state {
            let n = range.len();
            if s.positions.len() != n || s.velocities.len() != n {
                return Err(format!(
                    "state needs {n} positions and {n} velocities (one per lattice point), found {} and {}",
                    s.positions.len(),
                    s.velocities.len()
                ));
            }
            for (q, (p, v)) in range.zip(s.positions.iter().zip(&s.velocities)) {
                let (p, v) = (v3(*p), v3(*v));
                if !(p.is_finite() && v.is_finite()) {
                    return Err("state values must be finite".into());
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
        if !(v0.is_finite() && w.is_finite()) {
            return Err("velocity and spin must be finite".into());
        }
        for q in range.filter(active) {
            state.vel[q] = v0 + w.cross(state.pos[q] - com);
        }
        Ok(())
    }
}
