//! Defaults of the classic jello world (the official `jello.w`), used wherever a value is not
//! given. One place for them: the builder and the command line both read these.

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
