//! # jello-core
//!
//! The physics of Jello: soft bodies as lattices of mass points joined by structural, shear and
//! bend springs (Hooke's law with spring damping), pushed by a force field sampled on a grid and
//! by gravity, held in a box, above an inclined plane and outside obstacles by penalty springs,
//! touching each other with friction, and advanced by Euler, RK2, RK4, symplectic Euler (the
//! explicit integrators of the classic assignment, exactly as its specification says) or by
//! backward Euler and SDIRK2 (implicit, stable at any time step). The project's
//! `docs/spec.md` is the contract for the classic world.
//!
//! The data model follows MuJoCo and Warp:
//! - [`Model`]: what does not change while stepping (bodies, springs, parameters, obstacles,
//!   field, options), made by a [`ModelBuilder`] or read from a file ([`World`], [`SceneFile`]);
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
//! The modules, from the bottom up (each uses only those above it in this list):
//! - [`vec3`], [`compute`]: 3-vectors; instruction-set tiers, data layout and threads;
//! - [`model`]: lattices, bodies, materials, skins, obstacles, fields, options;
//! - [`state`]: what stepping advances, and the control from outside;
//! - [`contact`]: walls, plane, obstacles and bodies touching, with friction;
//! - [`forces`]: the one force pass, with the stencil kernel of the springs;
//! - [`diagnostics`]: energies, momentum, penetration, read off a state;
//! - [`integrate`]: the explicit and implicit integrators, blow-ups, stability;
//! - [`formats`]: world files, scene files, OBJ and STL meshes, as text the caller hands in;
//! - [`surface`]: what is drawn and exported; [`benchmark`]: the benchmark scene;
//! - [`Simulation`]: a model with its state, for the front ends.
//!
//! The crate does no I/O: it parses and prints text (and bytes) it is handed.

#![warn(missing_docs)]

pub mod benchmark;
pub mod compute;
pub mod contact;
pub mod diagnostics;
pub mod forces;
pub mod formats;
pub mod integrate;
pub mod model;
mod simulation;
pub mod state;
pub mod surface;
pub mod vec3;

pub use compute::simd::Tier;
pub use diagnostics::Energy;
pub use formats::mesh::{MeshError, TriMesh};
pub use formats::scene::{Scene, SceneError, SceneFile};
pub use formats::world::{ReadOptions, World, WorldError};
pub use integrate::cutback::CutbackStats;
pub use integrate::implicit::SolverStats;
pub use integrate::{step, BlowUp, BlowUpCause, Scratch};
pub use model::body::{Body, Material};
pub use model::field::ForceField;
pub use model::field_preset::FieldPreset;
pub use model::integrator::{Integrator, UnknownIntegrator};
pub use model::lattice::{Lattice, SpringKind};
pub use model::obstacle::{Aabb, Obstacle, ObstacleContact, Plane, Sphere};
pub use model::solver::Newton;
pub use model::springs::{Spring, SpringScale, SpringTable, Springs};
pub use model::{defaults, Model, ModelBuilder, ModelError};
pub use simulation::Simulation;
pub use state::{Control, Pull, State};
pub use vec3::Vec3;
