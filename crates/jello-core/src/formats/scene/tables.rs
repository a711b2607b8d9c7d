//! The tables of a scene file as serde reads and writes them: `[simulation]`, `[collision]`,
//! `[box]`, `[field]`, `[[obstacle]]`, `[[body]]` with its shape, pins, regions and state, each
//! field with its default and units.

use serde::{Deserialize, Serialize};

use crate::model::defaults;
use crate::model::motion::Motion;
use crate::model::springs::SpringScale;
use crate::vec3::Vec3;

/// `[simulation]`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct Settings {
    /// Euler, RK2, RK4, SymplecticEuler, BackwardEuler or SDIRK2 (any case; aliases as on the
    /// command line).
    pub integrator: String,
    /// Time step (s).
    pub dt: f64,
    /// Steps per displayed frame.
    pub steps_per_frame: u32,
    /// Acceleration of every point (m/s²). Left out: [`DEFAULT_GRAVITY`] in a scene without a
    /// `[field]`, none in one with a field (the same rule as `jello create` and Python's
    /// `jello.create`); written whenever it is given.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub gravity: Option<[f64; 3]>,
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
            gravity: None,
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
    /// [`crate::contact::friction`]).
    pub friction: f64,
    /// Coulomb friction coefficient of the walls and the inclined plane, by the obstacles' law
    /// (the classic worlds' walls have none).
    pub wall_friction: f64,
    /// Whether each body's surface touches its own (see [`crate::Model::self_contact`]); off
    /// unless the scene asks, and not written when off.
    #[serde(skip_serializing_if = "is_false")]
    pub self_contact: bool,
}

fn is_false(b: &bool) -> bool {
    !*b
}

/// Friction coefficient of a scene that does not give one: about rubbery jelly on a plate.
pub const DEFAULT_FRICTION: f64 = 0.5;

/// Friction coefficient of the walls and the plane in a scene that does not give one: the
/// obstacles' (a floor is a plate too).
pub const DEFAULT_WALL_FRICTION: f64 = DEFAULT_FRICTION;

/// Cells along a mesh's longest side when a new scene does not say.
pub const DEFAULT_CELLS: usize = 10;

/// Gravity of a scene given neither gravity nor a field (m/s²; z is up, as in the classic worlds
/// and the viewer), in a file, from `jello create` and from Python alike.
pub const DEFAULT_GRAVITY: [f64; 3] = [0.0, 0.0, -9.81];

impl Default for Collision {
    fn default() -> Self {
        Collision {
            stiffness: defaults::K_COLLISION,
            damping: defaults::D_COLLISION,
            friction: DEFAULT_FRICTION,
            wall_friction: DEFAULT_WALL_FRICTION,
            self_contact: false,
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
    /// Where the middle of the shape's rest bounding box goes (m): a mesh's own box, not the
    /// lattice's of whole cells around it; default: a cube's lower corner at the origin, a mesh
    /// where it is.
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
    /// Density (kg/m³) over the body's volume ([`crate::model::body::Body::volume`]: a mesh's
    /// own, not its cells').
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
    pub(super) fn motion(&self) -> Result<Option<Motion>, String> {
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

/// The vector of three numbers as a table holds it.
pub(super) fn v3(a: [f64; 3]) -> Vec3 {
    Vec3::new(a[0], a[1], a[2])
}
