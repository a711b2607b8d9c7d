//! The one force routine: springs, force field, box, plane and obstacle penalties (their
//! contacts defined in [`crate::model::obstacle`]), control forces.
//!
//! Springs are evaluated once each, by the lattice stencil rather than from a spring list: for
//! each chunk of planes and each of the 16 half-stencil offsets, the springs join one contiguous
//! run of points to the same run shifted, so the loop runs over contiguous memory and vectorises
//! (pairs in the run that are no springs are masked to zero force). A block of forces goes to a
//! small buffer, then is added to the first points and subtracted from the second (Newton's third
//! law), each a plain vectorisable loop.
//!
//! The lattice is cut into fixed chunks of [`CHUNK_PLANES`] planes. A chunk writes the forces on
//! its own planes and a private halo for the (at most two) planes after it, which the next chunk
//! adds to its own before its points' accelerations are computed. That happens right after the
//! chunk's springs, fused with the caller's update ([`force_pass`]), while the chunk is in cache.
//! Threads take contiguous ranges of planes, as the items of a `compute/team.rs` loop: the same
//! thread takes the same range pass after pass while the team lasts (a step, or the steps of
//! [`crate::Simulation::advance`]), so each range's points stay in one core's caches. The
//! chunking does not depend on the thread count, and a range that starts or ends inside a chunk
//! walks only the chunk's springs that reach its own points, in the chunk's order and blocks, so
//! no sum depends on where the ranges are cut: results are bit for bit the same on 1 thread or
//! many.
//!
//! A range that starts in the first two planes of a chunk (not the lattice's first) computes
//! the halo of the chunk before it itself (the springs reaching across, in the same order, so the
//! same bits) rather than waiting for the thread that owns that chunk. So ranges share nothing
//! and never wait for each other: a pass costs its longest range, plus at most two planes of
//! springs.
//!
//! The parts: this file, the pass's entry points and buffers; `stencil.rs`, the springs' kernel
//! (compiled for each instruction-set tier of [`crate::compute::simd`]); `points.rs`, the rest of
//! a point's force (field, walls, plane, obstacles, contacts, control, pulls, pins) and its
//! acceleration; `pass.rs`, a pass cut into ranges of planes for threads and chunks for caches.

mod pass;
mod points;
mod stencil;

pub use points::{block_accelerations, PointInputs};

use pass::{Pass, RangeBuffers};
use stencil::{Dampers, Grid, Masks};

use crate::compute::soa::Soa;
use crate::compute::split::Split;
use crate::contact::friction::Anchors;
use crate::contact::Contacts;
use crate::model::body::Body;
use crate::model::Model;
use crate::state::Control;
use crate::vec3::Vec3;

/// Point planes (constant `i`) per chunk of spring work. Fixed, so results never depend on the
/// number of threads.
pub const CHUNK_PLANES: usize = 4;

/// Springs evaluated per block of a run: the block's forces stay in the L1 cache between being
/// computed and being added to the points. (Also the longest run of per-spring factors.)
const RUN_BLOCK: usize = crate::model::springs::MAX_RUN;

/// Planes a spring reaches beyond its first point's plane (bend springs reach 2).
const HALO_PLANES: usize = 2;

/// The fewest planes of a range of a spring pass run by one thread (see [`range_count`]).
const MIN_RANGE_PLANES: usize = 2;

/// Lattices with fewer points than this are stepped on the calling thread only (the work would
/// not pay for waking others). The results are the same either way.
pub const PARALLEL_MIN_POINTS: usize = 8 * 1024;

/// The same inside a step of a spinning team (`compute/team.rs`), whose threads wait for work
/// without sleeping: the implicit solver's residuals at 16³ (4 096 points) go in two ranges.
#[cfg(feature = "parallel")]
const TEAM_MIN_POINTS: usize = 2 * 1024;

/// Models of several bodies with at least this many points in all step on a team of threads
/// (each thread takes whole bodies, see `body_groups`, and a share of the contacts between
/// them); the results are the same either way.
const BODIES_TEAM_MIN_POINTS: usize = 2 * 1024;

/// True when a step of `model` pays for a team of threads (see [`PARALLEL_MIN_POINTS`] and
/// [`BODIES_TEAM_MIN_POINTS`]).
pub(crate) fn steps_on_team(model: &Model) -> bool {
    let points = model.point_count();
    points >= PARALLEL_MIN_POINTS || (model.bodies().len() > 1 && points >= BODIES_TEAM_MIN_POINTS)
}

/// Buffers of the force routine, sized once for a model.
#[derive(Clone, Debug, Default)]
pub struct ForceScratch {
    /// Per body, the buffers of its spring pass.
    bodies: Vec<BodyScratch>,
    /// The contact pass between bodies.
    contacts: Contacts,
    /// Where points touching obstacles are tied (see [`crate::contact::friction`]): moved between steps
    /// by [`ForceScratch::update_anchors`], read by every force evaluation of a step.
    anchors: Anchors,
}

/// The buffers of one body's spring pass.
#[derive(Clone, Debug, Default)]
struct BodyScratch {
    /// Spring forces (N) on the points of a chunk: one buffer per range of planes a thread
    /// takes, reused chunk after chunk, so it stays in cache.
    owns: Vec<Soa>,
    /// Two per range: forces on the [`HALO_PLANES`] planes after a chunk, written by the
    /// chunk's springs and read when the next chunk is completed (the first, before the range's
    /// first chunk, is the halo of the chunk before the range, computed by the range itself).
    halos: Vec<Soa>,
    /// Per range: the forces of one block of springs.
    rows: Vec<Soa>,
    /// Which pairs of a run are springs, per stencil class (see [`Masks`]), for a full box.
    masks: Masks,
    /// For a body with holes: per chunk, block of the row buffer's length and stencil entry
    /// (`(chunk · blocks + block) · 16 + entry`), the span `[lo, hi)` of first ends (chunk
    /// offsets) whose link bit is set, so that runs skip the empty stretches (outside the shape,
    /// and its holes). Empty for a full box.
    spans: Vec<[u32; 2]>,
}

impl ForceScratch {
    /// Buffers for `model`.
    pub fn new(model: &Model) -> Self {
        ForceScratch {
            bodies: model.bodies().iter().map(BodyScratch::new).collect(),
            contacts: Contacts::new(model),
            anchors: Anchors::new(model),
        }
    }

    /// After a step that left the points at `pos`: ties, moves and lets go the obstacles'
    /// friction anchors (see [`Anchors::update`]).
    pub fn update_anchors(&mut self, model: &Model, pos: &[Vec3]) {
        if !self.anchors.fits(model) {
            self.anchors = Anchors::new(model);
        }
        // After the step's team has gone: a team of its own where a step would have one (each
        // point's anchor is its own, so the same anchors on any number of threads; on the
        // leader alone, this was 1 % of a settled 32³ step on 2 threads).
        let anchors = &mut self.anchors;
        if !anchors.is_empty() && crate::compute::team::threads() == 1 && steps_on_team(model) {
            crate::compute::team::run(|| anchors.update(model, pos));
        } else {
            anchors.update(model, pos);
        }
    }

    /// Wall-clock time spent on contacts between bodies since these buffers were made (see
    /// [`Contacts::time_spent`]).
    pub fn contact_time(&self) -> std::time::Duration {
        self.contacts.time_spent()
    }

    /// The contact passes' work between bodies since these buffers were made (see
    /// [`Contacts::work`]).
    pub fn contact_work(&self) -> crate::contact::bodies::ContactWork {
        self.contacts.work()
    }

    /// Where the points touching obstacles are tied (empty without friction or obstacles).
    pub(crate) fn anchors(&self) -> &Anchors {
        &self.anchors
    }

    /// The anchors, to be put back after a step that is taken again (see [`crate::integrate::cutback`]).
    pub(crate) fn anchors_mut(&mut self) -> &mut Anchors {
        &mut self.anchors
    }

    fn fits(&self, model: &Model) -> bool {
        self.bodies.len() == model.bodies().len()
            && self
                .bodies
                .iter()
                .zip(model.bodies())
                .all(|(s, b)| s.fits(b))
            && self.contacts.fits(model)
            && self.anchors.fits(model)
    }
}

impl BodyScratch {
    fn new(body: &Body) -> Self {
        let [nx, ny, nz] = body.lattice().counts;
        let chunks = nx.div_ceil(CHUNK_PLANES);
        let plane = ny * nz;
        let row_len = RUN_BLOCK.min(CHUNK_PLANES.min(nx) * plane);
        let masks = Masks::new(ny, nz, row_len);
        let chunk_len = CHUNK_PLANES.min(nx) * plane;
        let ranges = range_count_on(body, true);
        BodyScratch {
            owns: vec![Soa::with_color(chunk_len, 2); ranges],
            halos: vec![Soa::with_color(HALO_PLANES * plane, 1); 2 * ranges],
            rows: vec![Soa::with_color(row_len, 3); ranges],
            masks,
            spans: link_spans(body.links(), chunks, chunk_len, row_len),
        }
    }

    fn fits(&self, body: &Body) -> bool {
        let [nx, ny, nz] = body.lattice().counts;
        let chunk_len = CHUNK_PLANES.min(nx) * ny * nz;
        let row_len = RUN_BLOCK.min(chunk_len);
        !self.owns.is_empty()
            && self.owns[0].len() == chunk_len
            && self.halos.len() == 2 * self.owns.len()
            && self.halos[0].len() == HALO_PLANES * ny * nz
            && self.rows.len() == self.owns.len()
            && self.rows[0].len() == row_len
            && self.masks.len == ny * nz + row_len
            && self.spans.len()
                == if body.links().is_empty() {
                    0
                } else {
                    nx.div_ceil(CHUNK_PLANES) * chunk_len.div_ceil(row_len) * 16
                }
    }
}

/// The spans of set link bits (see [`BodyScratch::spans`]) of a body with `links` (none for a
/// full box), in chunks of `chunk_len` points and blocks of `block`.
fn link_spans(links: &[u16], chunks: usize, chunk_len: usize, block: usize) -> Vec<[u32; 2]> {
    if links.is_empty() {
        return Vec::new();
    }
    let blocks = chunk_len.div_ceil(block);
    let mut spans = vec![[0u32; 2]; chunks * blocks * 16];
    for c in 0..chunks {
        for b in 0..blocks {
            let t0 = b * block;
            let t1 = (t0 + block).min(chunk_len);
            let span = &mut spans[(c * blocks + b) * 16..][..16];
            for t in t0..t1 {
                let Some(&bits) = links.get(c * chunk_len + t) else {
                    break;
                };
                for (s, span) in span.iter_mut().enumerate() {
                    if bits >> s & 1 == 1 {
                        if span[1] == 0 {
                            span[0] = t as u32;
                        }
                        span[1] = t as u32 + 1;
                    }
                }
            }
        }
    }
    spans
}

/// Contiguous ranges of planes a body's spring pass is split into for threads, on lattices large
/// enough to be worth it (else one): one per thread of the rayon pool (whose threads make the
/// team, see `compute/team.rs`), or two where each still gets two chunks (spare ranges balance the
/// threads that run slower); never fewer than [`MIN_RANGE_PLANES`] planes a range. Each range
/// recomputes the springs reaching into its first planes from the planes before it (about half
/// a plane of springs), which is why small ranges are avoided.
fn range_count(body: &Body) -> usize {
    range_count_on(body, crate::compute::team::threads() > 1)
}

/// [`range_count`] for a pass on a team's step (`on_team`) or on its own. A body's buffers
/// are sized for a team's (the larger): a scratch made outside a step, before any team ran,
/// had room for one range at 16³, and the implicit solver's residuals there ran on one thread.
fn range_count_on(body: &Body, on_team: bool) -> usize {
    #[cfg(feature = "parallel")]
    if body.len() >= PARALLEL_MIN_POINTS || (on_team && body.len() >= TEAM_MIN_POINTS) {
        let planes = body.lattice().counts[0];
        let threads = rayon::current_num_threads();
        let ranges = if planes >= 4 * CHUNK_PLANES * threads {
            2 * threads
        } else {
            threads.min(planes / MIN_RANGE_PLANES)
        };
        return ranges.clamp(1, crate::compute::team::OWNED_ITEMS);
    }
    let _ = (body, on_team);
    1
}

/// Acceleration of every point (m/s²) at positions `pos` and velocities `vel`, written to `acc`.
///
/// All slices have the model's point count. Total force over mass, where the force on a point is
/// (docs/spec.md): the sum of its spring forces, plus the interpolated force field, plus one penalty
/// spring per box wall it is strictly outside of, plus the plane penalty when it is on the
/// forbidden side, plus the control force, then the obstacles' penalties and the control's pulls;
/// a pinned point's acceleration is zero. This form allocates its buffers; the integrators use
/// [`force_pass`] with buffers of their own, fused with their updates.
pub fn accelerations(
    model: &Model,
    pos: &[Vec3],
    vel: &[Vec3],
    control: &Control,
    acc: &mut [Vec3],
) {
    let (p, v) = (Soa::from_aos(pos), Soa::from_aos(vel));
    let mut a = Soa::zeros(pos.len());
    accelerations_soa(
        model,
        &p,
        &v,
        control,
        &mut a,
        &mut ForceScratch::new(model),
    );
    a.copy_to(acc);
}

/// [`accelerations`] on structure-of-arrays buffers, allocating nothing.
pub fn accelerations_soa(
    model: &Model,
    p: &Soa,
    v: &Soa,
    control: &Control,
    acc: &mut Soa,
    scratch: &mut ForceScratch,
) {
    force_pass(
        model,
        p,
        v,
        control,
        scratch,
        acc.parts_mut(),
        &|_, out: [&mut [f64]; 3], a| {
            for (out, a) in out.into_iter().zip(a) {
                out.copy_from_slice(a);
            }
            true
        },
    );
}

/// One force evaluation at positions `p` and velocities `v`, fused with what the caller does
/// with the accelerations.
///
/// The spring pass runs chunk by chunk of [`CHUNK_PLANES`] planes. As soon as a chunk's spring
/// forces are complete (its own springs plus the halo of the chunk before it), the accelerations
/// of its points are computed, block by block, into the chunk's row buffer and handed to
/// `update(first_point, outs, acc)` with the block's part of `outs`. So the caller's per-point
/// outputs (an integrator's next stage) are written while the chunk is still in cache, and
/// accelerations never go through memory. `p` and `v` are read until the last chunk is done, so
/// `outs` must be other buffers (the borrow checker sees to it).
///
/// Threads take contiguous ranges of chunks, or whole bodies where every body is too small to
/// cut (see `body_groups`). Every chunk is computed the same way whichever thread runs it, so
/// results do not depend on the thread count. Returns whether every `update`
/// returned true.
pub fn force_pass<T, U>(
    model: &Model,
    p: &Soa,
    v: &Soa,
    control: &Control,
    scratch: &mut ForceScratch,
    outs: T,
    update: &U,
) -> bool
where
    T: Split,
    U: Fn(usize, T, [&[f64]; 3]) -> bool + Sync,
{
    force_pass_with(model, p, v, control, scratch, outs, update, Ties::Held)
}

/// Whether a [`force_pass`] reads the obstacles' friction anchors and computes the contacts
/// between bodies.
#[derive(Clone, Copy)]
pub(crate) enum Ties<'a> {
    /// Points tied to an anchor feel its spring and damper, and bodies touch (every force
    /// evaluation of an explicit step).
    Held,
    /// As if no point had an anchor, and without contacts between bodies, at zero velocities
    /// (the pass's `v` must be zero): the pass then has no friction at all, and no damper of a
    /// wall, plane or obstacle (the implicit integrators add friction themselves, at the
    /// iterate's velocities, those dampers from the step's start, and the contacts between
    /// bodies, at the touches found at the step's start). The springs' dampers act along their
    /// directions where their ends were at `start`, at the velocities `velocity`; with no
    /// `velocity`, at rest (every velocity zero), they exert nothing and are not computed.
    Ignored {
        start: &'a Soa,
        velocity: Option<&'a Soa>,
    },
}

/// [`force_pass`], with the obstacles' friction anchors read or not.
#[allow(clippy::too_many_arguments)]
pub(crate) fn force_pass_with<T, U>(
    model: &Model,
    p: &Soa,
    v: &Soa,
    control: &Control,
    scratch: &mut ForceScratch,
    outs: T,
    update: &U,
    ties: Ties<'_>,
) -> bool
where
    T: Split,
    U: Fn(usize, T, [&[f64]; 3]) -> bool + Sync,
{
    let n = model.point_count();
    assert!(
        p.len() == n && v.len() == n && outs.points() == n,
        "buffers must have the point count"
    );
    assert!(
        control.forces.is_empty() || control.forces.len() == n,
        "control forces must be empty or one per point"
    );
    assert!(
        control.pulls.iter().all(|p| (p.point as usize) < n),
        "every pull must name a point of the model"
    );
    debug_assert!(
        model.pins.windows(2).all(|w| w[0] < w[1]),
        "pins must be sorted without repeats (as ModelBuilder leaves them)"
    );
    if !scratch.fits(model) {
        *scratch = ForceScratch::new(model);
    }
    let ForceScratch {
        bodies,
        contacts,
        anchors,
    } = scratch;
    let held = matches!(ties, Ties::Held);
    let anchors = (!anchors.is_empty() && held).then_some(&*anchors);
    // Contacts between bodies first: every chunk's update reads them.
    let touching = model.surfaces_touch() && held;
    if touching {
        contacts.compute(model, p, v);
    }
    let contact = touching.then(|| contacts.forces());
    debug_assert!(
        held || [v.x(), v.y(), v.z()]
            .iter()
            .all(|c| c.iter().all(|&v| v == 0.0)),
        "a pass without ties is at zero velocities"
    );
    let shared = Shared {
        model,
        p,
        v,
        dampers: match ties {
            Ties::Held => Dampers::Current,
            Ties::Ignored {
                start,
                velocity: Some(velocity),
            } => Dampers::AtStart { start, velocity },
            Ties::Ignored { velocity: None, .. } => Dampers::AtRest,
        },
        control,
        contact,
        anchors,
        friction: held,
        update,
    };
    // Many bodies, none larger than a thread's share of the points, on a team: groups of whole
    // bodies, four per thread (a thread done with its own takes another's). Each body then runs
    // whole on one thread, though it might be cut: fifty shapes of 8 to 12 cells, the largest
    // above `TEAM_MIN_POINTS`, went body after body, cut where large enough (2 threads stepped
    // them no faster than 1).
    let threads = crate::compute::team::threads();
    let groups = (4 * threads)
        .min(crate::compute::team::OWNED_ITEMS)
        .min(model.bodies().len());
    let largest = model.bodies().iter().map(|b| b.len()).max().unwrap_or(0);
    if threads > 1 && groups > 1 && largest * threads <= model.point_count() {
        return body_groups(&shared, bodies, outs, groups);
    }
    let mut outs = outs;
    let mut all = true;
    for (body, scratch) in model.bodies().iter().zip(bodies) {
        let (body_outs, rest) = outs.split_at(body.len());
        outs = rest;
        // As many ranges as the buffers allow (the pool may have grown since they were sized;
        // the ranges only decide which thread computes what, never the results).
        let ranges = range_count(body).min(scratch.owns.len());
        // On a team of threads: the caller's (an integrator's step), else one for this pass.
        let run = || body_pass(&shared, body, scratch, body_outs, ranges);
        all &= match ranges > 1 && crate::compute::team::threads() == 1 {
            true => crate::compute::team::run(run),
            false => run(),
        };
    }
    all
}

/// What every body's part of a [`force_pass`] reads.
struct Shared<'a, U> {
    model: &'a Model,
    p: &'a Soa,
    v: &'a Soa,
    /// The springs' dampers (see [`Ties`]).
    dampers: Dampers<'a>,
    control: &'a Control,
    contact: Option<&'a Soa>,
    anchors: Option<&'a Anchors>,
    /// Whether friction acts: not in a pass without ties (see [`Ties::Ignored`]).
    friction: bool,
    update: &'a U,
}

/// The spring pass of `body` (with its buffers `scratch`) in `ranges` ranges of planes, `outs`
/// its points' outputs. Returns whether every update returned true.
fn body_pass<T, U>(
    shared: &Shared<'_, U>,
    body: &Body,
    scratch: &mut BodyScratch,
    outs: T,
    ranges: usize,
) -> bool
where
    T: Split,
    U: Fn(usize, T, [&[f64]; 3]) -> bool + Sync,
{
    let BodyScratch {
        owns,
        halos,
        rows,
        masks,
        spans,
    } = scratch;
    let pass = Pass {
        model: shared.model,
        body,
        grid: Grid::new(body),
        masks,
        spans,
        p: shared.p,
        v: shared.v,
        dampers: shared.dampers,
        control: shared.control,
        contact: shared.contact,
        anchors: shared.anchors,
        friction: shared.friction,
        update: shared.update,
    };
    let buffers = owns
        .iter_mut()
        .zip(halos.chunks_exact_mut(2))
        .zip(rows.iter_mut());
    let buffers = buffers.map(|((own, halos), row)| RangeBuffers { own, halos, row });
    pass.ranges(buffers, outs, ranges)
}

/// The bodies' spring passes (each one range) in `groups` runs of whole bodies, of about as many
/// points each, spread over the team this thread leads: a pile of small bodies, each too small
/// to cut, still steps on every thread. Each body's pass is the same whichever thread runs it,
/// so the results are those of the passes one after another. Returns whether every update
/// returned true.
fn body_groups<T, U>(
    shared: &Shared<'_, U>,
    scratches: &mut [BodyScratch],
    outs: T,
    groups: usize,
) -> bool
where
    T: Split,
    U: Fn(usize, T, [&[f64]; 3]) -> bool + Sync,
{
    let bodies = shared.model.bodies();
    let total = shared.model.point_count();
    // Each group's bodies, buffers and outputs, cut here and taken by the item that runs it.
    type Group<'b, T> = Option<(std::ops::Range<usize>, &'b mut [BodyScratch], T)>;
    let parts: [std::sync::Mutex<Group<'_, T>>; crate::compute::team::OWNED_ITEMS] =
        std::array::from_fn(|_| std::sync::Mutex::new(None));
    let (mut outs, mut scratches, mut start, mut done) = (outs, scratches, 0, 0);
    for (g, part) in parts.iter().enumerate().take(groups) {
        // The bodies up to the group's share of the points (the last group: the rest).
        let (mut end, mut points) = (start, 0);
        while end < bodies.len() && (g + 1 == groups || done + points < (g + 1) * total / groups) {
            points += bodies[end].len();
            end += 1;
        }
        let (group_outs, rest) = outs.split_at(points);
        outs = rest;
        let (group_scratches, rest) = std::mem::take(&mut scratches).split_at_mut(end - start);
        scratches = rest;
        *part.lock().expect("unpoisoned") = Some((start..end, group_scratches, group_outs));
        (start, done) = (end, done + points);
    }
    let all = std::sync::atomic::AtomicBool::new(true);
    crate::compute::team::for_each(groups, &|g| {
        let part = parts[g].lock().expect("unpoisoned").take();
        let (range, scratches, outs) = part.expect("each group runs once");
        let mut outs = outs;
        for (body, scratch) in bodies[range].iter().zip(scratches) {
            let (body_outs, rest) = outs.split_at(body.len());
            outs = rest;
            if !body_pass(shared, body, scratch, body_outs, 1) {
                all.store(false, std::sync::atomic::Ordering::Relaxed);
            }
        }
    });
    all.into_inner()
}

#[cfg(all(test, feature = "parallel"))]
mod tests {
    use super::*;
    use crate::model::integrator::Integrator;

    /// A scratch made outside any step (as a simulation makes it) has room for the ranges a
    /// team's step cuts a body into: sized for one range at 16³, the implicit solver's
    /// residuals ran on one thread of two.
    #[test]
    fn a_scratch_made_outside_a_team_has_room_for_a_teams_ranges() {
        let pool = rayon::ThreadPoolBuilder::new()
            .num_threads(2)
            .build()
            .unwrap();
        let (model, _) = crate::benchmark::scene(16, Integrator::BackwardEuler).unwrap();
        let body = &model.bodies()[0];
        let scratch = pool.install(|| ForceScratch::new(&model));
        let on_team = pool.install(|| crate::compute::team::run(|| range_count(body)));
        assert_eq!(pool.install(|| range_count_on(body, true)), 2);
        assert!(scratch.bodies[0].owns.len() >= on_team, "{on_team} ranges");
    }
}
