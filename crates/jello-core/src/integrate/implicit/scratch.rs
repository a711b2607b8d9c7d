//! [`ImplicitScratch`]: the implicit solver's buffers, sized on its first step for a model, and
//! what it loads into them at each step (the springs in slot order, the masses, the dampers at
//! the step's start).

use super::cg::sum_chunks;
use super::gmres::Gmres;
use super::matrix::{can_slide, can_swirl};
use super::multigrid::Multigrid;
use super::residual::fall_chunks;
use super::stencil::SpringMatrix;
use super::sym::{add_outer, Sym};
use super::SolverStats;
use crate::compute::soa::Soa;
use crate::compute::team;
use crate::contact::bodies::Touch;
use crate::contact::Contacts;
use crate::model::body::Body;
use crate::model::lattice::STENCIL;
use crate::model::Model;
use crate::vec3::Vec3;

/// One spring as the solver needs it: its ends (flat indices of the model), rest length,
/// stiffness and damping.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Row {
    pub(super) a: u32,
    pub(super) b: u32,
    pub(super) rest: f64,
    pub(super) k: f64,
    pub(super) d: f64,
}

/// The buffers of the implicit solver, sized on its first step for a model.
#[derive(Clone, Debug, Default)]
pub struct ImplicitScratch {
    /// The work done so far (kept when the buffers are sized anew).
    pub(super) stats: SolverStats,
    pub(super) rows: Vec<Row>,
    /// The bodies whose springs are listed (none before the first step).
    pub(super) loaded: Option<Vec<Body>>,
    /// The springs' ends (in slot order), the fine pairs of the multigrid's
    /// [`Operator`](multigrid::Operator).
    pub(super) spring_pairs: Vec<[u32; 2]>,
    /// Each spring's block of `A` at the iterate, `axial·ûûᵀ + transverse·(I − ûûᵀ)` of its
    /// stiffness plus `damping·û₀û₀ᵀ` of its damper along its direction at the step's start, by
    /// stencil slot: for `A·x`, and read by spring for the multigrid's coarse levels.
    pub(super) springs: SpringMatrix,
    /// Each spring's direction at the step's start (zero for a spring of zero length), for the
    /// line search's potential alone: found only when a step first evaluates that
    /// ([`ImplicitScratch::start_directions`]), which most steps do not.
    pub(super) start_dir: Vec<Vec3>,
    /// Whether `start_dir` is of this step's start.
    pub(super) start_dir_found: bool,
    /// The field's force on each point at the iterate's and the trial's end positions (for the
    /// line search; see `residual::field_work`).
    pub(super) field: Vec<Vec3>,
    pub(super) field_trial: Vec<Vec3>,
    /// Per point: mass (kg), and 1 for a point that moves, 0 for one pinned or unused.
    pub(super) mass: Vec<f64>,
    pub(super) free: Vec<f64>,
    /// The masses and moving points of the last step (an `A` kept from it has its masses).
    pub(super) last_mass: Vec<f64>,
    pub(super) last_free: Vec<f64>,
    /// Per point: the stiffness of its springs, summed (N/m); and the largest of that plus the
    /// contacts' over the mass among the moving points (1/s², see `newton::rounding_floor`).
    pub(super) point_stiffness: Vec<f64>,
    pub(super) stiffness_over_mass: f64,
    /// The contacts' stiffness `stiffness_over_mass` was found with (`None`: to be found).
    pub(super) stiffness_over_mass_of: Option<f64>,
    /// The shortest rest length of a spring of the model (m; zero when it has none): the scale
    /// of a move that changes `A` (see [`KEEP_MOVE`]).
    pub(super) shortest_spring: f64,
    /// The step size whose last Newton iteration left `A` fit to keep for the next step's first
    /// (see `newton::keeps_across_steps`); `None` once the model's springs, masses or held points
    /// change, and after a step that did not converge.
    pub(super) keep_across: Option<f64>,
    /// Newton iterations that kept the last one's `A`, and whether they may (tests only).
    #[cfg(test)]
    pub(super) kept: u32,
    #[cfg(test)]
    pub(super) may_keep: bool,
    /// Whether `A` may take friction's growth with depth (tests only; see `exact_friction`).
    #[cfg(test)]
    pub(super) may_grow: bool,
    /// Whether a body at rest on a surface may start Newton's method from rest (tests only; see
    /// `newton::first_iterate`).
    #[cfg(test)]
    pub(super) may_start_at_rest: bool,
    /// Whether friction's growth, once in `A`, stays there for the rest of the step (tests
    /// only; see `exact_friction`).
    #[cfg(test)]
    pub(super) growth_sticks: bool,
    /// Steps whose first Newton iteration kept the last step's `A` (tests only).
    #[cfg(test)]
    pub(super) kept_across: u32,
    /// Whether a step's first solve may start from the last steps' directions (tests only; see
    /// `cg/recycle.rs`).
    #[cfg(test)]
    pub(super) may_recycle: bool,
    /// Per point: the damping matrix `dCollision·Σ n nᵀ` of the walls, plane and obstacles it is
    /// in at the step's start.
    pub(super) start_damping: Vec<Sym>,
    /// Whether each point touches a wall, the plane, an obstacle or another body at the step's
    /// start.
    pub(super) touching: Vec<bool>,
    /// The dampers between bodies: the samples that touch another body at the step's start.
    pub(super) start_touches: Vec<Touch>,
    /// Where the points were when the touches were found (the start of a backward-Euler step,
    /// the predicted middle of an SDIRK2 step): the touches' depths are followed from there.
    pub(super) touched_at: Vec<Vec3>,
    /// Per point: the walls', plane's, obstacles' and pulls' part of `A`, then the inverse of the
    /// diagonal block.
    pub(super) extra: Vec<Sym>,
    pub(super) diag_inv: Vec<Sym>,
    /// The iterate and its trial along the Newton direction.
    pub(super) v: Vec<Vec3>,
    pub(super) trial: Vec<Vec3>,
    /// Where the solve's last Newton direction led at its full length, `v + Δv` before the line
    /// search cut it, and whether it did yet: the next `A` anticipates the contacts it reached
    /// (see [`assemble`](super::matrix::assemble)) while `anticipating` (until a line search
    /// finds no way down along a direction so found).
    pub(super) full_step: Vec<Vec3>,
    pub(super) full_step_taken: bool,
    pub(super) anticipating: bool,
    /// The single-precision conjugate gradients' vectors ([`super::cg::single`]).
    pub(super) single: super::cg::single::SingleVectors,
    /// Residuals of the iterate and the trial.
    pub(super) g: Vec<Vec3>,
    pub(super) g_trial: Vec<Vec3>,
    /// Conjugate gradients: the solution, residual, preconditioned residual, direction and
    /// `A` times the direction.
    pub(super) dv: Vec<Vec3>,
    pub(super) r: Vec<Vec3>,
    pub(super) z: Vec<Vec3>,
    pub(super) p: Vec<Vec3>,
    pub(super) ap: Vec<Vec3>,
    /// Whether the solve is a step's first (its first Newton iteration's), which may start from
    /// the last steps' directions (`cg/recycle.rs`).
    pub(super) recycling: bool,
    /// SDIRK2: the start of its second stage (positions, velocities).
    pub(super) base_x: Vec<Vec3>,
    pub(super) base_v: Vec<Vec3>,
    /// The force routine's inputs and output.
    pub(super) x_soa: Soa,
    /// Zero: the residual's force pass runs at zero velocity (never written).
    pub(super) v_soa: Soa,
    /// The iterate's (or trial's) velocities, for the springs' dampers in the residual's force
    /// pass (which act from the start positions the stencil matrix holds).
    pub(super) velocity_soa: Soa,
    pub(super) acc: Soa,
    /// Contacts between bodies at the iterate, for `A`: the pairs of points in contact and
    /// their blocks (a penalty spring's, as a spring's block is), found through a contact pass of
    /// their own.
    pub(super) contacts: Contacts,
    pub(super) pair_rows: Vec<[u32; 2]>,
    pub(super) pair_blocks: Vec<Sym>,
    /// The coarse levels of `A` for the conjugate gradients' preconditioner, and whether the
    /// last solve stopped because their cycle was not positive definite.
    pub(super) multigrid: Multigrid,
    pub(super) multigrid_failed: bool,
    /// Where a solve may stop however little its residual fell: once its residual `r = −M·g′`
    /// (the linear model's) is within `m·within` at every point (m/s; half the Newton
    /// iteration's target, 0 for none).
    pub(super) within: f64,
    /// A field that may swirl past the limit ([`can_swirl`]): per point, the part of `A` that
    /// its exact gradient adds to the symmetric, positive semi-definite stiffness in `extra` (a
    /// general 3×3, row-major); used when `swirl` is set.
    pub(super) field_correction: Vec<[f64; 9]>,
    /// True when the field's swirl at the iterate passes [`SWIRL_LIMIT`] and `swirl_allowed`
    /// (see [`newton`](fn@newton)): `A` is not symmetric then, and GMRES (with its basis here)
    /// solves in place of conjugate gradients.
    pub(super) swirl: bool,
    pub(super) swirl_allowed: bool,
    /// Per point, whether some friction on it slides at its full size at the iterate; and the
    /// unsymmetric part `h²·μ·kc·ê·nᵀ` of `A` that its limit's growth with depth adds there
    /// (row-major; see [`crate::contact::friction::limit_growth`]) for each such point, with room
    /// for every point where friction may slide ([`can_slide`]), so that no step allocates.
    pub(super) slides: Vec<bool>,
    pub(super) friction_growth: Vec<(u32, [f64; 9])>,
    /// True when `A` takes `friction_growth`, and GMRES solves with it (see
    /// [`newton`](fn@newton)).
    pub(super) exact_friction: bool,
    /// GMRES's basis, where a field may swirl or friction slide ([`can_slide`]).
    pub(super) gmres: Gmres,
    /// [`potential_fall`](fn@residual::potential_fall)'s sums over each chunk of
    /// `residual::FALL_CHUNK` points and springs.
    pub(super) falls: Vec<[f64; 3]>,
    /// The conjugate gradients' sums over each chunk of [`sum_chunk`](cg::sum_chunk) points: of a
    /// product ([`dot`](cg::dot)), and of `r·r` with whether `r` is within its bound there
    /// ([`advance`](cg::advance)).
    pub(super) dots: Vec<f64>,
    pub(super) advanced: Vec<(f64, bool)>,
}

impl ImplicitScratch {
    /// Whether `A` as assembled is not symmetric: a field's swirl, or friction's growth with
    /// depth where it is taken (GMRES solves then).
    pub(super) fn unsymmetric(&self) -> bool {
        self.swirl || (self.exact_friction && !self.friction_growth.is_empty())
    }

    /// The trial point `v + α·Δv`, on the team.
    pub(super) fn set_trial(&mut self, alpha: f64) {
        let (v, dv) = (&self.v[..], &self.dv[..]);
        let size = super::chunk_size(v.len());
        team::for_each_chunk([&mut self.trial[..]], size, &|c, [trial]| {
            let at = c * size;
            for ((t, &v), &dv) in trial.iter_mut().zip(&v[at..]).zip(&dv[at..]) {
                *t = v + dv * alpha;
            }
        });
    }

    /// [`set_trial`](Self::set_trial) at the whole Newton step, which it also keeps as the
    /// step's [`full_step`](Self::full_step), in the same pass (the copy on the leader alone
    /// kept the other thread waiting, about 0.3 ms a line search of a 64³ cube on two threads).
    pub(super) fn set_full_trial(&mut self) {
        let (v, dv) = (&self.v[..], &self.dv[..]);
        let size = super::chunk_size(v.len());
        let parts = [&mut self.trial[..], &mut self.full_step[..]];
        team::for_each_chunk(parts, size, &|c, [trial, full]| {
            let at = c * size;
            for (((t, f), &v), &dv) in trial.iter_mut().zip(full).zip(&v[at..]).zip(&dv[at..]) {
                *t = v + dv;
                *f = *t;
            }
        });
        self.full_step_taken = true;
    }

    /// The trial point (with its residual and field) becomes the iterate.
    pub(super) fn take_trial(&mut self) {
        std::mem::swap(&mut self.v, &mut self.trial);
        std::mem::swap(&mut self.g, &mut self.g_trial);
        std::mem::swap(&mut self.field, &mut self.field_trial);
    }

    /// The work done so far.
    pub(crate) fn stats(&self) -> SolverStats {
        self.stats
    }

    /// Wall-clock time its own contact pass took so far (see [`Contacts::time_spent`]).
    pub(crate) fn contact_time(&self) -> std::time::Duration {
        self.contacts.time_spent()
    }

    /// Its own contact pass's work so far (see [`Contacts::work`]).
    pub(crate) fn contact_work(&self) -> crate::contact::bodies::ContactWork {
        self.contacts.work()
    }

    pub(super) fn fits(&self, model: &Model) -> bool {
        let n = model.point_count();
        self.mass.len() == n
            && self.contacts.fits(model)
            && self.springs.fits(model)
            && (!can_swirl(model, model.dt)
                || (self.gmres.fits(n) && self.field_correction.len() == n))
            && (!can_slide(model)
                || (self.gmres.fits(n)
                    && self.single.gmres_fits(n)
                    && self.friction_growth.capacity() >= n))
    }

    pub(super) fn new(model: &Model) -> Self {
        let n = model.point_count();
        // A step cut back is shorter than `dt`, so swirls less.
        let swirls = can_swirl(model, model.dt);
        let slides = can_slide(model);
        let several = model.surfaces_touch();
        ImplicitScratch {
            stats: SolverStats::default(),
            rows: Vec::with_capacity(model.spring_count()),
            loaded: None,
            spring_pairs: Vec::with_capacity(model.spring_count()),
            // Its slot arrays zero pages until written (the assembly writes each block).
            springs: SpringMatrix::new(model),
            start_dir: Vec::with_capacity(model.spring_count()),
            start_dir_found: false,
            field: Vec3::zeros(n),
            field_trial: Vec3::zeros(n),
            mass: vec![0.0; n],
            last_mass: vec![0.0; n],
            last_free: vec![0.0; n],
            within: 0.0,
            free: vec![0.0; n],
            point_stiffness: vec![0.0; n],
            stiffness_over_mass: 0.0,
            stiffness_over_mass_of: None,
            shortest_spring: 0.0,
            #[cfg(test)]
            kept: 0,
            #[cfg(test)]
            may_keep: true,
            #[cfg(test)]
            may_grow: true,
            #[cfg(test)]
            may_start_at_rest: true,
            #[cfg(test)]
            may_recycle: true,
            #[cfg(test)]
            growth_sticks: true,
            #[cfg(test)]
            kept_across: 0,
            keep_across: None,
            start_damping: vec![[0.0; 6]; n],
            touching: vec![false; n],
            touched_at: Vec3::zeros(if several { n } else { 0 }),
            start_touches: Vec::with_capacity(if several {
                (model.bodies().iter())
                    .map(|b| b.contact_surface().sample_count())
                    .sum()
            } else {
                0
            }),
            extra: vec![[0.0; 6]; n],
            diag_inv: vec![[0.0; 6]; n],
            v: Vec3::zeros(n),
            trial: Vec3::zeros(n),
            full_step: Vec3::zeros(n),
            full_step_taken: false,
            anticipating: true,
            single: super::cg::single::SingleVectors::zeros(n, slides),
            g: Vec3::zeros(n),
            g_trial: Vec3::zeros(n),
            dv: Vec3::zeros(n),
            r: Vec3::zeros(n),
            z: Vec3::zeros(n),
            p: Vec3::zeros(n),
            ap: Vec3::zeros(n),
            recycling: false,
            base_x: Vec3::zeros(n),
            base_v: Vec3::zeros(n),
            x_soa: Soa::zeros(n),
            v_soa: Soa::zeros(n),
            velocity_soa: Soa::zeros(n),
            acc: Soa::zeros(n),
            contacts: Contacts::new(model),
            // Room for 8 contacts a point (two lattices of the same spacing touch at most 8
            // points of the other) at the iterate, and as many dampers from the step's start,
            // so stepping does not allocate.
            pair_rows: Vec::with_capacity(if several { 16 * n } else { 0 }),
            pair_blocks: Vec::with_capacity(if several { 16 * n } else { 0 }),
            multigrid: Multigrid::default(),
            multigrid_failed: false,
            field_correction: vec![[0.0; 9]; if swirls { n } else { 0 }],
            swirl: false,
            swirl_allowed: false,
            slides: vec![false; n],
            friction_growth: Vec::with_capacity(if slides { n } else { 0 }),
            exact_friction: false,
            gmres: if swirls || slides {
                Gmres::new(n)
            } else {
                Gmres::default()
            },
            // Sized with the springs, by `list_springs`.
            falls: Vec::new(),
            dots: vec![0.0; sum_chunks(n)],
            advanced: vec![(0.0, false); sum_chunks(n)],
        }
    }

    /// The model's springs, masses and free points, read every step (a model may change between
    /// steps without changing its size). The springs are listed again only when a body's
    /// springs may have changed (see [`Body::has_springs_of`]): listing them is a tenth of a
    /// step of the 16³ benchmark at 1/60 s and 1e-3 m/s.
    pub(super) fn load(&mut self, model: &Model) {
        let same = self.loaded.as_ref().is_some_and(|loaded| {
            loaded.len() == model.bodies().len()
                && loaded
                    .iter()
                    .zip(model.bodies())
                    .all(|(a, b)| a.has_springs_of(b))
        });
        if !same {
            self.list_springs(model);
            self.loaded = Some(model.bodies().to_vec());
        }
        std::mem::swap(&mut self.mass, &mut self.last_mass);
        std::mem::swap(&mut self.free, &mut self.last_free);
        for body in model.bodies() {
            let points = body.points();
            self.mass[points.clone()].fill(body.material.mass);
            let free = &mut self.free[points];
            match body.active_mask() {
                [] => free.fill(1.0),
                active => {
                    for (free, &active) in free.iter_mut().zip(active) {
                        *free = if active { 1.0 } else { 0.0 };
                    }
                }
            }
        }
        for &p in &model.pins {
            self.free[p as usize] = 0.0;
        }
        let changed = self.mass != self.last_mass || self.free != self.last_free;
        if changed {
            self.keep_across = None;
        }
        // Penalty springs: three walls, the plane and each obstacle at once, at most. Found
        // again only when the points, their springs or the penalty changed (a pass with a
        // division a point, on the leader alone, at every step until then).
        let contacts = (4 + model.obstacles.len()) as f64 * model.k_collision;
        if changed || !same || self.stiffness_over_mass_of != Some(contacts) {
            self.stiffness_over_mass = self
                .point_stiffness
                .iter()
                .zip(&self.mass)
                .zip(&self.free)
                .filter(|&(_, &free)| free != 0.0)
                .map(|((&k, &m), _)| (k + contacts) / m)
                .fold(0.0, f64::max);
            self.stiffness_over_mass_of = Some(contacts);
        }
    }

    /// The model's springs, stencil entry by entry and each entry's body by body: the springs'
    /// slot order (see `SpringMatrix`), which the solver keeps them in; with what follows from
    /// them: their pairs, each point's stiffness, the multigrid's levels.
    pub(super) fn list_springs(&mut self, model: &Model) {
        self.keep_across = None;
        self.rows.clear();
        self.springs.begin();
        for entry in 0..STENCIL.len() {
            for body in model.bodies() {
                let first = body.points().start;
                body.for_each_spring_of_entry(entry, |s| {
                    self.springs.push(first + s.a, entry);
                    self.rows.push(Row {
                        a: (first + s.a) as u32,
                        b: (first + s.b) as u32,
                        rest: s.rest,
                        k: s.stiffness,
                        d: s.damping,
                    })
                });
            }
        }
        self.spring_pairs.clear();
        self.spring_pairs
            .extend(self.rows.iter().map(|r| [r.a, r.b]));
        // The multigrid's levels on another thread where there is one, while this one sets
        // the springs' matrix and stiffnesses: 13 and 7 ms of a 32³ cube's first step, which
        // on 2 threads took 55 ms one after the other and 48 ms so (medians of 8 in turn).
        let ImplicitScratch {
            rows,
            springs,
            spring_pairs,
            multigrid,
            pair_rows,
            falls,
            mass,
            shortest_spring,
            point_stiffness,
            ..
        } = self;
        let more = pair_rows.capacity();
        team::join(
            || multigrid.build(model, spring_pairs, more),
            || {
                springs.finish();
                for (s, r) in rows.iter().enumerate() {
                    springs.set_spring(s, r.rest, r.k, r.d);
                }
                falls.resize(fall_chunks(mass.len(), rows.len()), [0.0; 3]);
                *shortest_spring = (rows.iter())
                    .map(|r| r.rest)
                    .filter(|&rest| rest > 0.0)
                    .fold(f64::INFINITY, f64::min);
                if *shortest_spring == f64::INFINITY {
                    *shortest_spring = 0.0;
                }
                point_stiffness.fill(0.0);
                for r in rows.iter() {
                    point_stiffness[r.a as usize] += r.k;
                    point_stiffness[r.b as usize] += r.k;
                }
            },
        );
    }

    /// The dampers at `x0` (the step's start): the springs' start positions and directions
    /// (into the stencil matrix, from whose start the residual's force pass takes the springs'
    /// dampers), the contacts each point is in, and the pairs of points of different bodies
    /// that overlap.
    pub(super) fn start_dampers(&mut self, model: &Model, x0: &[Vec3]) {
        self.springs.start_dampers(x0);
        self.start_dir_found = false;
        if model.surfaces_touch() {
            let (contacts, touches) = (&mut self.contacts, &mut self.start_touches);
            super::contacts::start_touches(model, contacts, self.springs.start(), touches);
            self.touched_at.copy_from_slice(x0);
        } else {
            self.start_touches.clear();
        }
        let size = super::chunk_size(x0.len());
        let free = &self.free[..];
        let parts = ([&mut self.start_damping[..]], [&mut self.touching[..]]);
        team::for_each_chunk_pair(parts, size, &|chunk, ([damping], [touching])| {
            // A wall touches no point of a chunk inside the box.
            let points = &x0[chunk * size..chunk * size + damping.len()];
            let walls = points.iter().any(|&p| model.bounds.excursion(p) > 0.0);
            for (j, (d, touches)) in damping.iter_mut().zip(touching).enumerate() {
                let i = chunk * size + j;
                (*d, *touches) = ([0.0; 6], false);
                if free[i] == 0.0 {
                    continue;
                }
                model.for_each_contact_of(i, x0[i], walls, |c| {
                    add_outer(d, c.normal, model.d_collision);
                    *touches = true;
                });
            }
        });
        for t in &self.start_touches {
            for (&p, &w) in t.points.iter().zip(&t.weights) {
                if w != 0.0 {
                    self.touching[p as usize] = true;
                }
            }
        }
    }

    /// The springs' directions at the step's start into `start_dir`, where not found yet this
    /// step: the line search's potential needs them (sized here, for a model that has one: 12
    /// MB at 32³). Found at each step's start, they had been 45 % of a 32³ cube's steps in free
    /// fall without friction (one thread), whose first residual solves them.
    pub(super) fn start_directions(&mut self) {
        if !std::mem::replace(&mut self.start_dir_found, true) {
            self.start_dir.resize(self.rows.len(), Vec3::ZERO);
            self.springs.start_directions(&mut self.start_dir);
        }
    }
}
