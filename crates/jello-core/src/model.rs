//! [`Model`]: everything that does not change while stepping, and the builder that makes one.

use std::fmt;

use crate::field::ForceField;
use crate::integrator::Integrator;
use crate::lattice::{Lattice, SpringKind, Springs};
use crate::vec3::Vec3;

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

/// An axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner (m).
    pub min: Vec3,
    /// Upper corner (m).
    pub max: Vec3,
}

impl Aabb {
    /// The classic bounding box `[−2, 2]³`.
    pub fn classic() -> Self {
        let h = defaults::BOX_HALF_WIDTH;
        Aabb {
            min: Vec3::new(-h, -h, -h),
            max: Vec3::new(h, h, h),
        }
    }

    /// Distance from `p` to the box (0 inside), measured per axis as the largest excursion.
    pub fn excursion(&self, p: Vec3) -> f64 {
        let out = |v: f64, lo: f64, hi: f64| (lo - v).max(v - hi).max(0.0);
        out(p.x, self.min.x, self.max.x)
            .max(out(p.y, self.min.y, self.max.y))
            .max(out(p.z, self.min.z, self.max.z))
    }
}

/// The inclined plane `a x + b y + c z + d = 0` with the side points are allowed on.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// `[a, b, c, d]` as in the world file.
    pub coeffs: [f64; 4],
    /// `+1.0` when the allowed side is where `a x + b y + c z + d > 0`, else `−1.0`.
    pub side: f64,
}

impl Plane {
    /// The plane whose allowed side holds `reference` (SPEC.md: the centre of mass of the initial
    /// positions). A reference exactly on the plane gets the positive side, the side every
    /// official world uses. Fails when a coefficient is not finite or the length of `(a, b, c)`
    /// is zero or overflows.
    pub fn facing(coeffs: [f64; 4], reference: Vec3) -> Result<Plane, ModelError> {
        if coeffs.iter().any(|c| !c.is_finite()) {
            return Err(ModelError::new("plane coefficients must be finite"));
        }
        let plane = Plane { coeffs, side: 1.0 };
        let norm = plane.normal_length();
        if !(norm.is_finite() && norm > 0.0) {
            return Err(ModelError::new(format!(
                "plane normal (a, b, c) must have a finite, non-zero length (it has {norm})"
            )));
        }
        let side = if plane.value(reference) < 0.0 {
            -1.0
        } else {
            1.0
        };
        Ok(Plane { coeffs, side })
    }

    /// `a x + b y + c z + d` at `p`.
    #[inline]
    pub fn value(&self, p: Vec3) -> f64 {
        let [a, b, c, d] = self.coeffs;
        a * p.x + b * p.y + c * p.z + d
    }

    /// `|(a, b, c)|`.
    #[inline]
    pub fn normal_length(&self) -> f64 {
        let [a, b, c, _] = self.coeffs;
        Vec3::new(a, b, c).length()
    }

    /// Unit normal pointing into the allowed side.
    pub fn inward_normal(&self) -> Vec3 {
        let [a, b, c, _] = self.coeffs;
        Vec3::new(a, b, c) * (self.side / self.normal_length())
    }

    /// Depth (m) of `p` on the forbidden side, and the unit normal into the allowed side; `None`
    /// when `p` is on the allowed side or on the plane.
    #[inline]
    pub fn penetration(&self, p: Vec3) -> Option<(f64, Vec3)> {
        let s = self.value(p);
        if s * self.side < 0.0 {
            let norm = self.normal_length();
            Some((s.abs() / norm, self.inward_normal()))
        } else {
            None
        }
    }
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
        let b = self.bounds;
        if !(b.min.is_finite()
            && b.max.is_finite()
            && b.min.x < b.max.x
            && b.min.y < b.max.y
            && b.min.z < b.max.z)
        {
            return Err(ModelError::new(
                "bounding box must be finite with min < max on every axis",
            ));
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
