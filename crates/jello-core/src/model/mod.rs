//! The model: everything that does not change while stepping (MuJoCo's mjModel). [`Model`]
//! holds the bodies (each a lattice of mass points, possibly with holes, its springs, material,
//! placement and skin), the walls and the inclined plane, the obstacles, the force field,
//! gravity, pinned points and the options (integrator, dt, how closely implicit steps are
//! solved); [`ModelBuilder`] makes one and checks it.
//!
//! Nothing here depends on the rest of the crate: forces and contacts read the model,
//! integrators advance a [`State`](crate::State) under it, file formats build one.
//!
//! - [`lattice`]: lattice points and the spring stencil;
//! - [`body`]: a body (its cells, springs, material, placement); [`springs`]: per-spring values;
//! - [`voxel`]: a closed mesh's cells; [`skin`]: the mesh carried by a body's cells;
//!   [`clearance`]: how far its lattice points rest outside that mesh;
//! - [`obstacle`]: the box, planes, spheres and solid boxes, with their contact geometry;
//! - [`field`]: the force field sampled on a grid; [`field_preset`]: the fields `--field` names;
//! - [`motion`]: pinned points moved along paths;
//! - [`integrator`]: the integrators' names; [`solver`]: how closely implicit steps are solved;
//! - [`defaults`]: the classic world's values; [`error`]: [`ModelError`] and shared checks.

pub mod body;
pub mod clearance;
pub mod contact_surface;
pub mod defaults;
pub mod error;
pub mod field;
pub mod field_preset;
pub mod integrator;
pub mod lattice;
pub mod motion;
pub mod obstacle;
pub mod skin;
pub mod solver;
pub mod springs;
#[cfg(test)]
pub(crate) mod test_meshes;
pub mod voxel;

pub use error::ModelError;

use crate::model::body::{Body, Material};
use crate::model::error::{non_negative, positive};
use crate::model::field::ForceField;
use crate::model::integrator::Integrator;
use crate::model::lattice::{Lattice, SpringKind};
use crate::model::motion::{Motion, PinMotion};
pub use crate::model::obstacle::{Aabb, Obstacle, Plane};
use crate::model::springs::Springs;
use crate::vec3::Vec3;

/// Everything about a simulation that stays fixed while it steps (MuJoCo's mjModel).
#[derive(Clone, Debug, PartialEq)]
pub struct Model {
    /// The soft bodies, their points one after the other in the state's arrays (see
    /// [`Model::bodies`]).
    bodies: Vec<Body>,
    /// Stiffness of the collision penalty springs (N/m): the collision stiffness of scenes, the
    /// command line and Python (docs/scenes.md, "One name per quantity").
    #[doc(alias = "collision_stiffness")]
    pub k_collision: f64,
    /// Damping of the collision penalty springs (N·s/m): the collision damping.
    #[doc(alias = "collision_damping")]
    pub d_collision: f64,
    /// Coulomb friction coefficient of obstacles and of contacts between bodies (at least 0;
    /// 0 in world files). See [`crate::contact::friction`].
    pub friction: f64,
    /// Coulomb friction coefficient of the box's walls and the inclined plane (at least 0; 0 in
    /// world files, whose walls and plane docs/spec.md gives none), by the same law as the
    /// obstacles'.
    pub wall_friction: f64,
    /// Whether a body's surface touches its own cells, at places more than half a cell from
    /// its sample at rest (a bar bent over, a torus squashed flat, a skin folded across
    /// neighbouring cells), by the law of contacts between bodies (see
    /// [`crate::contact::bodies`]). Off by default: it costs a search per sample for a model of
    /// one body.
    pub self_contact: bool,
    /// The bounding box; points outside it are pushed back by penalty springs.
    pub bounds: Aabb,
    /// The inclined plane, when present.
    pub plane: Option<Plane>,
    /// Further static obstacles (planes, spheres, solid boxes), with the same penalty springs;
    /// [`ModelBuilder::obstacle`] checks their values.
    pub obstacles: Vec<Obstacle>,
    /// Pinned points (flat indices into the model's points, sorted, no repeats, as [`ModelBuilder::pins`] leaves
    /// them): their acceleration is always zero, so a pinned point at rest is held in place (one
    /// moving keeps its velocity). The springs to them still act on their neighbours.
    pub pins: Vec<u32>,
    /// Pinned points moved along paths (each point also in `pins`; see [`crate::model::motion`]).
    pub pin_motions: Vec<PinMotion>,
    /// The external force field, when present.
    pub field: Option<ForceField>,
    /// Uniform acceleration of every active point (m/s²), on top of the field (which is a
    /// force, the same on a light point as on a heavy one); zero in classic worlds.
    pub gravity: Vec3,
    /// Time step (s).
    pub dt: f64,
    /// The time-stepping scheme.
    pub integrator: Integrator,
    /// Simulation steps per displayed frame (≥ 1).
    pub steps_per_frame: u32,
    /// A point further than this outside `bounds` (m) means the run has blown up.
    pub escape_margin: f64,
    /// How closely the implicit integrator solves each step (see [`crate::integrate::implicit`]).
    pub newton: crate::model::solver::Newton,
    /// Per point (flat index), its body's [`Body::clearance`]: how far it rests outside its
    /// skin, taken off its depth into the walls, the plane and the obstacles. Empty when no
    /// point has any (every model without a mesh body).
    clearance: Vec<f64>,
}

impl Model {
    /// The soft bodies. Body `b`'s points are the flat indices [`Body::points`] of every
    /// per-point array (state, control forces, pins); a model read from a world file has one.
    pub fn bodies(&self) -> &[Body] {
        &self.bodies
    }

    /// Body `b`.
    pub fn body(&self, b: usize) -> &Body {
        &self.bodies[b]
    }

    /// Number of mass points, over all bodies (inactive lattice points of bodies with holes
    /// included: they are placeholders that never move).
    pub fn point_count(&self) -> usize {
        self.bodies.iter().map(Body::len).sum()
    }

    /// The contacts of a point at `p` with the walls, the inclined plane and the obstacles, in
    /// that order (each [`ObstacleContact`](crate::ObstacleContact) with its depth and normal).
    pub fn contacts(
        &self,
        p: Vec3,
    ) -> impl Iterator<Item = crate::model::obstacle::ObstacleContact> + '_ {
        self.bounds
            .wall_contacts(p)
            .chain(self.plane.and_then(|pl| pl.contact(p)))
            .chain(self.obstacles.iter().filter_map(move |o| o.contact(p)))
    }

    /// Per point (flat index), how far it rests outside its body's skin (m), taken off its depth
    /// into the walls, the plane and the obstacles (see [`crate::model::clearance`]); empty when
    /// no point has any.
    pub fn clearance(&self) -> &[f64] {
        &self.clearance
    }

    /// Point `i`'s clearance (m; see [`Model::clearance`]).
    #[inline]
    pub fn clearance_of(&self, i: usize) -> f64 {
        self.clearance.get(i).copied().unwrap_or(0.0)
    }

    /// The contacts of point `i` at `p` with the walls, the inclined plane and the obstacles,
    /// as [`Model::contacts`] gives them, each with the point's clearance taken off its depth
    /// (and left out when that leaves none).
    pub fn contacts_of(
        &self,
        i: usize,
        p: Vec3,
    ) -> impl Iterator<Item = crate::model::obstacle::ObstacleContact> + '_ {
        let clearance = self.clearance_of(i);
        self.contacts(p).filter_map(move |c| c.less(clearance))
    }

    /// Calls `f` with each of [`Model::contacts_of`]'s contacts, in its order, leaving out the
    /// walls' where `walls` is false (the caller knows that `p` is inside the box): a plain loop,
    /// where the iterators' chain cost a resting 16³ cube's steps at 1/60 s 3 % (asked for
    /// every point at each step's start).
    #[inline]
    pub(crate) fn for_each_contact_of(
        &self,
        i: usize,
        p: Vec3,
        walls: bool,
        mut f: impl FnMut(crate::model::obstacle::ObstacleContact),
    ) {
        let clearance = self.clearance_of(i);
        let mut add = |c: Option<crate::model::obstacle::ObstacleContact>| {
            if let Some(c) = c.and_then(|c| c.less(clearance)) {
                f(c);
            }
        };
        if walls {
            self.bounds.wall_contacts(p).for_each(|c| add(Some(c)));
        }
        add(self.plane.and_then(|pl| pl.contact(p)));
        for o in &self.obstacles {
            add(o.contact(p));
        }
    }

    /// Whether no point of the box `[lo, hi]` can touch a wall, the inclined plane or an obstacle
    /// ([`Model::for_each_contact_of`] finds nothing there, whatever the clearance): the box
    /// inside the walls and clear of the plane and of each obstacle.
    pub(crate) fn touches_nothing_in(&self, lo: Vec3, hi: Vec3) -> bool {
        self.bounds.holds(lo, hi)
            && self.plane.is_none_or(|plane| plane.clears_box(lo, hi))
            && self.obstacles.iter().all(|o| o.clears_box(lo, hi))
    }

    /// True when surfaces may touch: the model has several bodies, or self-contact on (see
    /// [`crate::contact::bodies`]).
    pub fn surfaces_touch(&self) -> bool {
        self.bodies.len() > 1 || self.self_contact
    }

    /// The body that point `p` (flat index) belongs to, and its lattice coordinates there.
    pub fn locate(&self, p: usize) -> (usize, [usize; 3]) {
        let b = self
            .bodies
            .partition_point(|body| body.points().end <= p)
            .min(self.bodies.len() - 1);
        let body = &self.bodies[b];
        (b, body.lattice().coords(p - body.first))
    }

    /// The springs of every body as flat arrays (flat point indices of the model), derived on
    /// demand (allocates; the force kernel walks the stencil instead).
    pub fn springs(&self) -> Springs {
        let mut springs = Springs::default();
        for body in &self.bodies {
            body.for_each_spring(|s| springs.push(s, body.first));
        }
        springs
    }

    /// Number of springs, over all bodies.
    pub fn spring_count(&self) -> usize {
        self.bodies.iter().map(Body::spring_count).sum()
    }

    /// A builder holding every value of this model, to change a few and build anew.
    pub fn to_builder(&self) -> ModelBuilder {
        ModelBuilder {
            bodies: self.bodies.clone(),
            k_collision: self.k_collision,
            d_collision: self.d_collision,
            friction: self.friction,
            wall_friction: self.wall_friction,
            self_contact: self.self_contact,
            bounds: self.bounds,
            plane: self.plane,
            obstacles: self.obstacles.clone(),
            pins: self.pins.clone(),
            pin_motions: self.pin_motions.clone(),
            field: self.field.clone(),
            gravity: self.gravity,
            dt: self.dt,
            integrator: self.integrator,
            steps_per_frame: self.steps_per_frame,
            escape_margin: self.escape_margin,
            newton: self.newton,
        }
    }
}

/// Builds a [`Model`]; every value starts at the classic world's default ([`defaults`]).
#[derive(Clone, Debug)]
pub struct ModelBuilder {
    bodies: Vec<Body>,
    k_collision: f64,
    d_collision: f64,
    friction: f64,
    wall_friction: f64,
    self_contact: bool,
    bounds: Aabb,
    plane: Option<Plane>,
    obstacles: Vec<Obstacle>,
    pins: Vec<u32>,
    pin_motions: Vec<PinMotion>,
    field: Option<ForceField>,
    gravity: Vec3,
    dt: f64,
    integrator: Integrator,
    steps_per_frame: u32,
    escape_margin: f64,
    newton: crate::model::solver::Newton,
}

impl Default for ModelBuilder {
    fn default() -> Self {
        ModelBuilder {
            bodies: vec![Body::lattice_box(Lattice::classic(), Material::classic())],
            k_collision: defaults::K_COLLISION,
            d_collision: defaults::D_COLLISION,
            friction: 0.0,
            wall_friction: 0.0,
            self_contact: false,
            bounds: Aabb::classic(),
            plane: None,
            obstacles: Vec::new(),
            pins: Vec::new(),
            pin_motions: Vec::new(),
            field: None,
            gravity: Vec3::ZERO,
            dt: defaults::DT,
            integrator: Integrator::Rk4,
            steps_per_frame: defaults::STEPS_PER_FRAME,
            escape_margin: defaults::ESCAPE_MARGIN,
            newton: crate::model::solver::Newton::default(),
        }
    }
}

impl ModelBuilder {
    /// A builder holding the classic defaults.
    pub fn new() -> Self {
        Self::default()
    }

    /// How closely the implicit integrator solves each step (default [`Newton::default`]);
    /// checked by [`build`](Self::build).
    ///
    /// [`Newton::default`]: crate::model::solver::Newton
    pub fn newton(mut self, newton: crate::model::solver::Newton) -> Self {
        self.newton = newton;
        self
    }

    /// The bodies (default: one, the classic 8×8×8 cube of side 1 m of classic jello). The
    /// setters below that name no body ([`lattice`](Self::lattice), [`mass`](Self::mass),
    /// [`elastic`](Self::elastic), [`spring_kind`](Self::spring_kind)) change the first.
    pub fn bodies(mut self, bodies: Vec<Body>) -> Self {
        self.bodies = bodies;
        self
    }

    /// Adds a body after the others.
    pub fn add_body(mut self, body: Body) -> Self {
        self.bodies.push(body);
        self
    }

    fn first_body(&mut self) -> &mut Body {
        if self.bodies.is_empty() {
            let classic = Body::lattice_box(Lattice::classic(), Material::classic());
            self.bodies.push(classic);
        }
        &mut self.bodies[0]
    }

    /// Makes the first body a full box lattice of this shape, keeping its material and placement
    /// (default: the classic 8×8×8 cube of side 1 m).
    pub fn lattice(mut self, lattice: Lattice) -> Self {
        let body = self.first_body();
        let boxed = Body::lattice_box(lattice, body.material).placed(body.origin, body.rotation);
        *body = boxed;
        self
    }

    /// Mass of each point of the first body in kg (default 1/512).
    pub fn mass(mut self, mass: f64) -> Self {
        self.first_body().material.mass = mass;
        self
    }

    /// One stiffness (N/m) and damping (N·s/m) for every spring kind of the first body (default
    /// 200 and 0.25: the classic world's kElastic and dElastic).
    #[doc(alias = "stiffness")]
    pub fn elastic(mut self, k: f64, d: f64) -> Self {
        let m = &mut self.first_body().material;
        m.stiffness = [k; 3];
        m.damping = [d; 3];
        self
    }

    /// Stiffness and damping of one spring kind of the first body.
    pub fn spring_kind(mut self, kind: SpringKind, k: f64, d: f64) -> Self {
        let m = &mut self.first_body().material;
        m.stiffness[kind as usize] = k;
        m.damping[kind as usize] = d;
        self
    }

    /// Collision penalty stiffness (N/m) and damping (N·s/m) (default 400 and 0.25: the classic
    /// world's kCollision and dCollision).
    #[doc(alias = "collision_stiffness")]
    pub fn collision(mut self, k: f64, d: f64) -> Self {
        self.k_collision = k;
        self.d_collision = d;
        self
    }

    /// Coulomb friction coefficient of obstacles and body contacts (default 0): see
    /// [`Model::friction`].
    pub fn friction(mut self, mu: f64) -> Self {
        self.friction = mu;
        self
    }

    /// Coulomb friction coefficient of the walls and the inclined plane (default 0, as in the
    /// classic world): see [`Model::wall_friction`].
    pub fn wall_friction(mut self, mu: f64) -> Self {
        self.wall_friction = mu;
        self
    }

    /// Self-contact of each body's surface (default off): see [`Model::self_contact`].
    pub fn self_contact(mut self, on: bool) -> Self {
        self.self_contact = on;
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

    /// Pins `points` and moves them along `motion` (see [`crate::model::motion`]).
    pub fn pin_motion(mut self, points: Vec<u32>, motion: Motion) -> Self {
        self.pins.extend(&points);
        self.pin_motions.push(PinMotion { points, motion });
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

    /// Uniform acceleration (m/s², default zero): see [`Model::gravity`].
    pub fn gravity(mut self, g: Vec3) -> Self {
        self.gravity = g;
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
    pub fn build(mut self) -> Result<Model, ModelError> {
        if self.bodies.is_empty() {
            return Err(ModelError::new("a model needs at least one body"));
        }
        let several = self.bodies.len() > 1;
        let mut points = 0usize;
        for (b, body) in self.bodies.iter_mut().enumerate() {
            let name = |e: ModelError| {
                if several {
                    ModelError::new(format!("body {}: {e}", b + 1))
                } else {
                    e
                }
            };
            check_lattice(body.lattice()).map_err(name)?;
            body.material.check().map_err(name)?;
            if !(body.origin.is_finite() && body.rotation.iter().all(|r| r.is_finite())) {
                return Err(name(ModelError::new("placement must be finite")));
            }
            body.first = points;
            points = points
                .checked_add(body.len())
                .filter(|&n| n <= u32::MAX as usize / 2)
                .ok_or_else(|| ModelError::new("the bodies have too many points in all"))?;
        }
        positive("dt", self.dt)?;
        if !self.gravity.is_finite() {
            return Err(ModelError::new("gravity must be finite"));
        }
        positive("collision stiffness", self.k_collision)?;
        non_negative("collision damping", self.d_collision)?;
        non_negative("friction", self.friction)?;
        non_negative("wall friction", self.wall_friction)?;
        positive("escape margin", self.escape_margin)?;
        if self.steps_per_frame == 0 {
            return Err(ModelError::new("steps per frame must be at least 1"));
        }
        self.bounds.check("bounding box")?;
        if let Some(&p) = self.pins.iter().find(|&&p| p as usize >= points) {
            return Err(ModelError::new(format!(
                "pinned point {p} does not exist (the model has {points} points)"
            )));
        }
        let mut pins = self.pins;
        pins.sort_unstable();
        pins.dedup();
        for (i, m) in self.pin_motions.iter().enumerate() {
            m.motion
                .check()
                .map_err(|e| ModelError::new(format!("pin motion {}: {e}", i + 1)))?;
            if let Some(&p) = m.points.iter().find(|p| pins.binary_search(p).is_err()) {
                return Err(ModelError::new(format!(
                    "pin motion {}: point {p} is not pinned",
                    i + 1
                )));
            }
        }
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
        positive("Newton tolerance", self.newton.tolerance)?;
        if self.newton.tolerance > crate::model::solver::MAX_TOLERANCE {
            return Err(ModelError::new(format!(
                "Newton tolerance must be at most {} m/s (got {})",
                crate::model::solver::MAX_TOLERANCE,
                self.newton.tolerance
            )));
        }
        if self.newton.max_iterations == 0 {
            return Err(ModelError::new("Newton iterations must be at least 1"));
        }
        if self.newton.cutbacks > crate::model::solver::MAX_CUTBACKS {
            return Err(ModelError::new(format!(
                "a step may be halved at most {} times, not {}",
                crate::model::solver::MAX_CUTBACKS,
                self.newton.cutbacks
            )));
        }
        let clearance = flat_clearance(&self.bodies);
        Ok(Model {
            clearance,
            bodies: self.bodies,
            k_collision: self.k_collision,
            d_collision: self.d_collision,
            friction: self.friction,
            wall_friction: self.wall_friction,
            self_contact: self.self_contact,
            bounds: self.bounds,
            plane: self.plane,
            obstacles: self.obstacles,
            pins,
            pin_motions: self.pin_motions,
            field: self.field,
            gravity: self.gravity,
            dt: self.dt,
            integrator: self.integrator,
            steps_per_frame: self.steps_per_frame,
            escape_margin: self.escape_margin,
            newton: self.newton,
        })
    }
}

/// Every body's [`Body::clearance`] one after the other (0 for a body without), or nothing when
/// no point has any.
fn flat_clearance(bodies: &[Body]) -> Vec<f64> {
    if bodies.iter().all(|b| b.clearance().is_empty()) {
        return Vec::new();
    }
    let mut flat = Vec::new();
    for body in bodies {
        match body.clearance() {
            [] => flat.resize(flat.len() + body.len(), 0.0),
            own => flat.extend_from_slice(own),
        }
    }
    flat
}

/// The most points one lattice may have: 2²⁷ (512³, the finest `jello create --mesh --cells`
/// makes), about 10 GB of state and scratch with RK4. More is refused with an error rather than
/// left to fail allocating, which would abort the process (a Python interpreter with it).
pub const MAX_LATTICE_POINTS: usize = 1 << 27;

/// A lattice with at least one point per axis, two in all, at most [`MAX_LATTICE_POINTS`], and
/// finite positive sides.
fn check_lattice(lattice: &Lattice) -> Result<(), ModelError> {
    let [nx, ny, nz] = lattice.counts;
    let total = nx.checked_mul(ny).and_then(|v| v.checked_mul(nz));
    if nx == 0 || ny == 0 || nz == 0 || total.is_some_and(|n| n < 2) {
        return Err(ModelError::new(format!(
            "lattice {nx}×{ny}×{nz} needs at least one point per axis and two in all"
        )));
    }
    if total.is_none_or(|n| n > MAX_LATTICE_POINTS) {
        return Err(ModelError::new(format!(
            "lattice {nx}×{ny}×{nz} is too large: at most {MAX_LATTICE_POINTS} points"
        )));
    }
    let s = lattice.size;
    if !(s.is_finite() && s.x > 0.0 && s.y > 0.0 && s.z > 0.0) {
        return Err(ModelError::new(
            "lattice side lengths must be finite and positive",
        ));
    }
    Ok(())
}
