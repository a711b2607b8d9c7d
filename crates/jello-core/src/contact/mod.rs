//! Contact: what keeps bodies out of the walls, the plane, the obstacles and each other.
//!
//! - [`obstacles`]: the penalty law of the walls, the plane and the obstacles (docs/spec.md), and the
//!   deepest penetration;
//! - [`bodies`]: contacts between bodies' surfaces (and of a body with itself), their penalty
//!   law and the overlap diagnostics;
//! - [`cell_guard`]: under self-contact, the penalty that keeps cells from turning inside out;
//! - [`broad_phase`]: the hashed uniform grid that finds the cells of bodies near a point;
//! - [`friction`]: Coulomb friction, on obstacles (anchored ties) and between bodies (sliding);
//! - [`tunnelling`]: points a step carried through an obstacle, read off two successive states;
//!   [`tunnel_warning`], the warning that says so and what to try.
//!
//! Contact reads the model; the force pass ([`crate::forces`]) and the implicit integrators
//! call it.

pub mod bodies;
pub mod broad_phase;
pub mod cell_guard;
pub mod friction;
pub mod obstacles;
pub mod tunnel_warning;
pub mod tunnelling;

pub use bodies::{closest, overlap, touch_force, Closest, ContactWork, Contacts};
pub use obstacles::max_penetration;
