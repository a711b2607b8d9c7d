//! [`Model`]: everything that does not change while stepping, and the builder that makes one.

use std::fmt;

use crate::field::ForceField;
use crate::integrator::Integrator;
use crate::lattice::{Lattice, SpringKind, Springs};
pub use crate::obstacle::{Aabb, Obstacle, Plane};

/// Defaults of the classic jello world (the official `jello.w`), used wherever a value is not
/// given. One place for them: the builder and the command line both read these.
pub mod defaults {
    /// Time step (s).
    pub const DT: f64 = 0.0005;
    /// Simulation steps per displayed frame.
    pub const STEPS_PER_FRAME: u32 = 1;
    /// Stiffness of every lattice spring (N/m).
    pub const K_ELASTIC: f64 = 200.0;
    /// Damping of every lattice spring (N·s/m).
    pub const D_ELASTIC: f64 = 0.25;
    /// Stiffness of the collision penalty springs (N/m).
    pub const K_COLLISION: f64 = 400.0;
    /// Damping of the collision penalty springs (N·s/m).
    pub const D_COLLISION: f64 = 0.25;
    /// Mass of each point (kg): the 1 kg cube over 512 points.
    pub const MASS: f64 = 1.0 / 512.0;
    /// Half-width of the bounding box `[−2, 2]³` (m).
    pub const BOX_HALF_WIDTH: f64 = 2.0;
    /// How far outside the box a point may go before the run counts as blown up (m).
    pub const ESCAPE_MARGIN: f64 = 10.0;
}

/// A model that could not be built, or a value outside its allowed range.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ModelError(pub String);

impl ModelError {
    /// An error with this message.
    pub fn new(msg: impl Into<String>) -> Self {
        ModelError(msg.into())
    }
}

impl fmt::Display for ModelError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::error::Error for ModelError {}

/// Everything about a simulation that stays fixed while it steps (MuJoCo's mjModel).
#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    /// Shape of the lattice.
    pub lattice: Lattice,
    /// Mass of every point (kg).
    pub mass: f64,
    /// Stiffness per spring kind (N/m), indexed by `SpringKind as usize`.
    pub stiffness: [f64; 3],
    /// Damping per spring kind (N·s/m), indexed by `SpringKind as usize`.
    pub damping: [f64; 3],
    /// Stiffness of the collision penalty springs (N/m).
    pub k_collision: f64,
    /// Damping of the collision penalty springs (N·s/m).
    pub d_collision: f64,
    /// The bounding box; points outside it are pushed back by penalty springs.
    pub bounds: Aabb,
    /// The inclined plane, when present.
    pub plane: Option<Plane>,
    /// Further static obstacles (planes, spheres, solid boxes), with the same penalty springs;
    /// [`ModelBuilder::obstacle`] checks their values.
    pub obstacles: Vec<Obstacle>,
    /// Pinned points (flat lattice indices, sorted, no repeats, as [`ModelBuilder::pins`] leaves
    /// them): their acceleration is always zero, so a pinned point at rest is held in place (one
    /// moving keeps its velocity). The springs to them still act on their neighbours.
    pub pins: Vec<u32>,
    /// The external force field, when present.
    pub field: Option<ForceField>,
    /// Time step (s).
    pub dt: f64,
    /// The time-stepping scheme.
    pub integrator: Integrator,
    /// Simulation steps per displayed frame (≥ 1).
    pub steps_per_frame: u32,
    /// A point further than this outside `bounds` (m) means the run has blown up.
    pub escape_margin: f64,
}

impl Model {
    /// Number of mass points.
    pub fn point_count(&self) -> usize {
        self.lattice.len()
    }

    /// The springs as flat arrays, derived from the lattice on demand (allocates; the force
    /// kernel walks the stencil instead, and [`Lattice::for_each_spring`] visits them without
    /// a list).
    pub fn springs(&self) -> Springs {
        self.lattice.springs()
    }

    /// Number of springs.
    pub fn spring_count(&self) -> usize {
        self.lattice.spring_count()
    }

    /// True when every spring kind shares one stiffness and one damping, as in world files.
    pub fn has_uniform_springs(&self) -> bool {
        self.stiffness.iter().all(|&k| k == self.stiffness[0])
            && self.damping.iter().all(|&d| d == self.damping[0])
    }

    /// Stiffness of a spring kind (N/m).
    pub fn stiffness_of(&self, kind: SpringKind) -> f64 {
        self.stiffness[kind as usize]
    }
}

/// Builds a [`Model`]; every value starts at the classic world's default ([`defaults`]).
#[derive(Clone, Debug)]
pub struct ModelBuilder {
    lattice: Lattice,
    mass: f64,
    stiffness: [f64; 3],
    damping: [f64; 3],
    k_collision: f64,
    d_collision: f64,
    bounds: Aabb,
    plane: Option<Plane>,
    obstacles: Vec<Obstacle>,
    pins: Vec<u32>,
    field: Option<ForceField>,
    dt: f64,
    integrator: Integrator,
    steps_per_frame: u32,
    escape_margin: f64,
}

impl Default for ModelBuilder {
    fn default() -> Self {
        ModelBuilder {
            lattice: Lattice::classic(),
            mass: defaults::MASS,
            stiffness: [defaults::K_ELASTIC; 3],
            damping: [defaults::D_ELASTIC; 3],
            k_collision: defaults::K_COLLISION,
            d_collision: defaults::D_COLLISION,
            bounds: Aabb::classic(),
            plane: None,
            obstacles: Vec::new(),
            pins: Vec::new(),
            field: None,
            dt: defaults::DT,
            integrator: Integrator::Rk4,
            steps_per_frame: defaults::STEPS_PER_FRAME,
            escape_margin: defaults::ESCAPE_MARGIN,
        }
    }
}

impl ModelBuilder {
    /// A builder holding the classic defaults.
    pub fn new() -> Self {
        Self::default()
    }

    /// Lattice shape (default: the classic 8×8×8 cube of side 1 m).
    pub fn lattice(mut self, lattice: Lattice) -> Self {
        self.lattice = lattice;
        self
    }

    /// Mass of each point in kg (default 1/512).
    pub fn mass(mut self, mass: f64) -> Self {
        self.mass = mass;
        self
    }

    /// One stiffness (N/m) and damping (N·s/m) for every spring kind (default 200 and 0.25).
    pub fn elastic(mut self, k: f64, d: f64) -> Self {
        self.stiffness = [k; 3];
        self.damping = [d; 3];
        self
    }

    /// Stiffness and damping of one spring kind.
    pub fn spring_kind(mut self, kind: SpringKind, k: f64, d: f64) -> Self {
        self.stiffness[kind as usize] = k;
        self.damping[kind as usize] = d;
        self
    }

    /// Collision penalty stiffness (N/m) and damping (N·s/m) (default 400 and 0.25).
    pub fn collision(mut self, k: f64, d: f64) -> Self {
        self.k_collision = k;
        self.d_collision = d;
        self
    }

    /// Bounding box (default `[−2, 2]³`).
    pub fn bounds(mut self, bounds: Aabb) -> Self {
        self.bounds = bounds;
        self
    }

    /// Inclined plane (default none).
    pub fn plane(mut self, plane: Option<Plane>) -> Self {
        self.plane = plane;
        self
    }

    /// Adds a static obstacle (default none).
    pub fn obstacle(mut self, obstacle: Obstacle) -> Self {
        self.obstacles.push(obstacle);
        self
    }

    /// Replaces the static obstacles (default none).
    pub fn obstacles(mut self, obstacles: Vec<Obstacle>) -> Self {
        self.obstacles = obstacles;
        self
    }

    /// Pins these points (flat lattice indices; default none): see [`Model::pins`].
    pub fn pins(mut self, points: impl IntoIterator<Item = u32>) -> Self {
        self.pins.extend(points);
        self
    }

    /// External force field (default none).
    pub fn field(mut self, field: Option<ForceField>) -> Self {
        self.field = field;
        self
    }

    /// Time step in seconds (default 0.0005).
    pub fn dt(mut self, dt: f64) -> Self {
        self.dt = dt;
        self
    }

    /// Integrator (default RK4).
    pub fn integrator(mut self, integrator: Integrator) -> Self {
        self.integrator = integrator;
        self
    }

    /// Simulation steps per displayed frame (default 1).
    pub fn steps_per_frame(mut self, n: u32) -> Self {
        self.steps_per_frame = n;
        self
    }

    /// Distance outside the box (m) that counts as a blow-up (default 10).
    pub fn escape_margin(mut self, margin: f64) -> Self {
        self.escape_margin = margin;
        self
    }

    /// Checks every value and builds the model with its springs.
    pub fn build(self) -> Result<Model, ModelError> {
        let [nx, ny, nz] = self.lattice.counts;
        if nx == 0 || ny == 0 || nz == 0 || nx * ny * nz < 2 {
            return Err(ModelError::new(format!(
                "lattice {nx}×{ny}×{nz} needs at least one point per axis and two in all"
            )));
        }
        if nx
            .checked_mul(ny)
            .and_then(|v| v.checked_mul(nz))
            .is_none_or(|n| n > u32::MAX as usize / 2)
        {
            return Err(ModelError::new(format!(
                "lattice {nx}×{ny}×{nz} is too large"
            )));
        }
        let s = self.lattice.size;
        if !(s.is_finite() && s.x > 0.0 && s.y > 0.0 && s.z > 0.0) {
            return Err(ModelError::new(
                "lattice side lengths must be finite and positive",
            ));
        }
        positive("mass", self.mass)?;
        positive("dt", self.dt)?;
        for kind in SpringKind::ALL {
            positive(
                &format!("{} stiffness", kind.name()),
                self.stiffness[kind as usize],
            )?;
            non_negative(
                &format!("{} damping", kind.name()),
                self.damping[kind as usize],
            )?;
        }
        positive("collision stiffness", self.k_collision)?;
        non_negative("collision damping", self.d_collision)?;
        positive("escape margin", self.escape_margin)?;
        if self.steps_per_frame == 0 {
            return Err(ModelError::new("steps per frame must be at least 1"));
        }
        self.bounds.check("bounding box")?;
        let points = self.lattice.len();
        if let Some(&p) = self.pins.iter().find(|&&p| p as usize >= points) {
            return Err(ModelError::new(format!(
                "pinned point {p} does not exist (the lattice has {points} points)"
            )));
        }
        let mut pins = self.pins;
        pins.sort_unstable();
        pins.dedup();
        for (i, obstacle) in self.obstacles.iter().enumerate() {
            obstacle
                .check()
                .map_err(|e| ModelError::new(format!("obstacle {}: {e}", i + 1)))?;
        }
        if let Some(field) = &self.field {
            if field.bounds() != self.bounds {
                return Err(ModelError::new(
                    "the force field must cover the bounding box exactly",
                ));
            }
        }
        Ok(Model {
            lattice: self.lattice,
            mass: self.mass,
            stiffness: self.stiffness,
            damping: self.damping,
            k_collision: self.k_collision,
            d_collision: self.d_collision,
            bounds: self.bounds,
            plane: self.plane,
            obstacles: self.obstacles,
            pins,
            field: self.field,
            dt: self.dt,
            integrator: self.integrator,
            steps_per_frame: self.steps_per_frame,
            escape_margin: self.escape_margin,
        })
    }
}

fn positive(what: &str, v: f64) -> Result<(), ModelError> {
    if v.is_finite() && v > 0.0 {
        Ok(())
    } else {
        Err(ModelError::new(format!(
            "{what} must be finite and positive (got {v})"
        )))
    }
}

fn non_negative(what: &str, v: f64) -> Result<(), ModelError> {
    if v.is_finite() && v >= 0.0 {
        Ok(())
    } else {
        Err(ModelError::new(format!(
            "{what} must be finite and at least 0 (got {v})"
        )))
    }
}
