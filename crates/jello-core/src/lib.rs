//! # jello-core
//!
//! The physics of Jello: an elastic lattice of mass points joined by structural, shear and bend
//! springs (Hooke's law with spring damping), pushed by a force field sampled on a grid, held in a
//! box and above an inclined plane by penalty springs, and advanced by Euler, RK2, RK4 or
//! symplectic Euler. `SPEC.md` is the contract; this crate implements it exactly.
//!
//! The data model follows MuJoCo and Warp:
//! - [`Model`]: what does not change while stepping (lattice, springs, parameters, obstacles,
//!   field, options), made by a [`ModelBuilder`] or read from a classic world file ([`World`]);
//! - [`State`]: positions, velocities, time;
//! - [`Control`]: forces from outside (a user's drag);
//! - [`Scratch`]: the integrators' buffers, so that [`step()`] never allocates.
//!
//! ```
//! use jello_core::{step, Control, ModelBuilder, Scratch, State};
//! let model = ModelBuilder::new().build().unwrap();
//! let mut state = State::at_rest(&model);
//! let mut scratch = Scratch::new(&model);
//! for _ in 0..100 {
//!     step(&model, &mut state, &Control::none(), &mut scratch).unwrap();
//! }
//! assert_eq!(state.steps, 100);
//! ```
//!
//! Shapes of one's own come as a [`TriMesh`], the closed surface of a solid read from the bytes of
//! an OBJ or STL file ([`TriMesh::parse`]).
//!
//! The crate does no I/O: it parses and prints text (and bytes) it is handed.

#![warn(missing_docs)]

pub mod body;
pub mod contact;
pub mod cutback;
pub mod diagnostics;
pub mod field;
pub mod field_preset;
pub mod forces;
pub mod friction;
pub mod gltf;
pub mod implicit;
pub mod integrator;
pub mod lattice;
pub mod mesh;
pub mod model;
pub mod motion;
pub mod obstacle;
pub mod scene_file;
pub mod scenes;
pub mod simd;
pub mod skin;
pub mod soa;
pub mod split;
pub mod springs;
pub mod stability;
pub mod state;
pub mod step;
pub mod surface;
pub mod team;
pub mod vec3;
pub mod voxel;
pub mod world;

pub use body::{Body, Material};
pub use cutback::CutbackStats;
pub use diagnostics::Energy;
pub use field::ForceField;
pub use field_preset::FieldPreset;
pub use implicit::SolverStats;
pub use integrator::{Integrator, UnknownIntegrator};
pub use lattice::{Lattice, SpringKind};
pub use mesh::{MeshError, TriMesh};
pub use model::{defaults, Model, ModelBuilder, ModelError};
pub use obstacle::{Aabb, Contact, Obstacle, Plane, Sphere};
pub use scene_file::{Scene, SceneError, SceneFile};
pub use simd::Tier;
pub use springs::{Spring, SpringScale, SpringTable, Springs};
pub use state::{Control, Pull, State};
pub use step::{step, BlowUp, BlowUpCause, Scratch};
pub use vec3::Vec3;
pub use world::{ReadOptions, World, WorldError};

/// A model with its state, control and scratch: the convenient handle that the front ends (the
/// `jello` command line and the browser's `jello-wasm`) drive.
#[derive(Clone, Debug)]
pub struct Simulation {
    /// What does not change while stepping.
    pub model: Model,
    /// What stepping advances.
    pub state: State,
    /// Forces from outside.
    pub control: Control,
    scratch: Scratch,
}

impl Simulation {
    /// A simulation of `model` starting from `state`.
    pub fn new(model: Model, state: State) -> Self {
        let scratch = Scratch::new(&model);
        Simulation {
            model,
            state,
            control: Control::none(),
            scratch,
        }
    }

    /// The simulation a world file describes.
    pub fn from_world(world: &World) -> Result<Self, ModelError> {
        let (model, state) = world.to_simulation()?;
        Ok(Simulation::new(model, state))
    }

    /// One step; on a blow-up the state stays at the last good step.
    pub fn step(&mut self) -> Result<(), BlowUp> {
        step(
            &self.model,
            &mut self.state,
            &self.control,
            &mut self.scratch,
        )
    }

    /// How often implicit steps were taken in parts (see [`cutback`]) since this simulation
    /// was made.
    pub fn cutbacks(&self) -> CutbackStats {
        self.scratch.cutbacks()
    }

    /// The implicit solver's work since this simulation was made (see [`SolverStats`]).
    pub fn solver_stats(&self) -> SolverStats {
        self.scratch.solver_stats()
    }

    /// `n` steps, stopping at the first blow-up.
    ///
    /// On lattices large enough for threads the steps share one team of threads (see
    /// [`team`]): its threads wait for the next step's work spinning, and each keeps the same
    /// part of the lattice from step to step. The results are the same as `n` calls of
    /// [`Simulation::step`].
    pub fn advance(&mut self, n: u64) -> Result<(), BlowUp> {
        let steps = |sim: &mut Simulation| (0..n).try_for_each(|_| sim.step());
        if n > 1 && self.model.point_count() >= forces::PARALLEL_MIN_POINTS {
            return team::run(|| steps(self));
        }
        steps(self)
    }

    /// The current state as a world file, when the model fits the classic format.
    pub fn to_world(&self) -> Result<World, ModelError> {
        World::from_simulation(&self.model, &self.state)
    }
}
