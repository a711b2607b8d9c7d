//! [`Scratch`]: the buffers every integrator works in, and what every step does with its result
//! ([`accept`]).

use crate::compute::soa::Soa;
use crate::forces::ForceScratch;
use crate::integrate::cutback::Cutback;
use crate::integrate::implicit::ImplicitScratch;
use crate::model::Model;
use crate::state::State;
use crate::vec3::Vec3;

/// Buffers the integrators work in, sized once for a model: stepping never allocates. The
/// integrators work in structures of arrays (see [`crate::compute::soa`]) and write the step's result as
/// arrays of vectors, which are swapped into the state.
#[derive(Clone, Debug, Default)]
pub struct Scratch {
    pub(crate) force: ForceScratch,
    pub(super) pos: Soa,
    pub(super) vel: Soa,
    /// Positions of the intermediate stages: RK2's midpoint; RK4's stages 2 and 4 in the first,
    /// stage 3 in the second.
    pub(super) stage_pos: [Soa; 2],
    /// Velocities of RK4's stages 2, 3 and 4 (RK2's midpoint in the first): all three are the
    /// position slopes the end of the step sums, so none is overwritten.
    pub(super) stage_vel: [Soa; 3],
    /// RK4's sum of the velocity slopes `k1 + 2k2 + 2k3` (accelerations).
    pub(super) sum_vel: Soa,
    /// The step's result, swapped into the state when it is sound.
    pub(crate) next_pos: Vec<Vec3>,
    pub(crate) next_vel: Vec<Vec3>,
    /// The implicit solver's buffers (sized on its first step).
    pub(crate) implicit: ImplicitScratch,
    /// How implicit steps are being cut back, and the state to go back to.
    pub(crate) cutback: Cutback,
}

impl Scratch {
    /// How often implicit steps were taken in parts (see [`crate::integrate::cutback`]) since these
    /// buffers were made.
    pub fn cutback_stats(&self) -> crate::integrate::cutback::CutbackStats {
        self.cutback.stats()
    }

    /// Wall-clock time spent on contacts between bodies (finding them, and their forces) since
    /// these buffers were made, by the force routine's contact pass and the implicit step's own
    /// (which holds a step's touches for its matrix); zero for a model whose surfaces cannot
    /// touch, and in the browser.
    pub fn contact_time(&self) -> std::time::Duration {
        self.force.contact_time() + self.implicit.contact_time()
    }

    /// The work of the contact passes between bodies since these buffers were made (both
    /// passes', as [`Scratch::contact_time`]).
    pub fn contact_work(&self) -> crate::contact::bodies::ContactWork {
        self.force.contact_work() + self.implicit.contact_work()
    }

    /// The implicit solver's work (solves, Newton and conjugate-gradient iterations,
    /// assemblies of its matrix) since these buffers were made; zero under explicit integrators.
    pub fn solver_stats(&self) -> crate::integrate::implicit::SolverStats {
        self.implicit.stats()
    }

    /// Buffers for a model's point count.
    pub fn new(model: &Model) -> Self {
        // Buffers read in the same loops get different colors (cache sets, see Soa).
        let z = |color| Soa::with_color(model.point_count(), color);
        Scratch {
            force: ForceScratch::new(model),
            pos: z(0),
            vel: z(1),
            stage_pos: [z(2), z(0)],
            stage_vel: [z(3), z(1), z(3)],
            sum_vel: z(2),
            next_pos: vec![Vec3::ZERO; model.point_count()],
            next_vel: vec![Vec3::ZERO; model.point_count()],
            implicit: ImplicitScratch::default(),
            cutback: Cutback::default(),
        }
    }
}

/// The sound result of a step from `t0` to `t1`, in the scratch's buffers, becomes the state's
/// positions and velocities (its time and step count are the caller's): swapped in (the old
/// ones are overwritten by the next step), then the moving pins put where their paths say, and
/// the obstacles' friction anchors dragged or let go.
pub(crate) fn accept(model: &Model, state: &mut State, s: &mut Scratch, t0: f64, t1: f64) {
    std::mem::swap(&mut state.pos, &mut s.next_pos);
    std::mem::swap(&mut state.vel, &mut s.next_vel);
    // From the positions at the step's start, now in the scratch's buffer.
    for m in &model.pin_motions {
        m.apply(t0, t1, &s.next_pos, &mut state.pos, &mut state.vel);
    }
    s.force.update_anchors(model, &state.pos);
}
