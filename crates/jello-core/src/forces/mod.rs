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
//! Threads take contiguous ranges of planes, as the items of a [`crate::compute::team`] loop: the same
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

use std::ops::Range;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

use crate::compute::soa::{cache_aligned_zeros, Soa};
use crate::compute::split::Split;
use crate::contact::friction::{self, Anchors};
use crate::contact::obstacles::{penalty, wall_force};
use crate::contact::Contacts;
use crate::model::body::Body;
use crate::model::lattice::STENCIL;
use crate::model::obstacle::Obstacle;
use crate::model::springs::SpringTable;
use crate::model::Model;
use crate::state::{Control, Pull};
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

/// The same inside a step of a spinning team ([`crate::compute::team`]), whose threads wait for work
/// without sleeping: the implicit solver's residuals at 16³ (4 096 points) go in two ranges.
#[cfg(feature = "parallel")]
const TEAM_MIN_POINTS: usize = 2 * 1024;

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

/// Per stencil class `(dj, dk)` (index `(dj + 1)·4 + dk + 1`, both in −1..=2): for every point
/// `u` of a plane, 1 where the point at `(j + dj, k + dk)` exists, else 0; then repeated for one
/// row buffer's length, so that the mask of any block of a run starting at chunk offset `t` is
/// the slice from `t mod plane`. One plane, not a whole chunk, so the masks stay in cache. Each
/// starts on a cache line, like the runs it is read with.
#[derive(Clone, Debug, Default)]
struct Masks {
    data: Vec<f64>,
    /// Numbers per mask.
    len: usize,
    /// Index in `data` of the first mask, and from one mask to the next.
    first: usize,
    stride: usize,
}

impl Masks {
    /// The masks of a lattice with `ny × nz` planes, for row buffers of `row_len`.
    fn new(ny: usize, nz: usize, row_len: usize) -> Self {
        let plane = ny * nz;
        let len = plane + row_len;
        let stride = len.next_multiple_of(8);
        let (mut data, first) = cache_aligned_zeros(16 * stride);
        for c in 0..16 {
            let (dj, dk) = (c as isize / 4 - 1, c as isize % 4 - 1);
            let mask = &mut data[first + c * stride..][..len];
            for (u, m) in mask.iter_mut().enumerate() {
                let t = u % plane;
                let j = ((t / nz) % ny) as isize + dj;
                let k = (t % nz) as isize + dk;
                let inside = (0..ny as isize).contains(&j) && (0..nz as isize).contains(&k);
                *m = if inside { 1.0 } else { 0.0 };
            }
        }
        Masks {
            data,
            len,
            first,
            stride,
        }
    }

    /// The mask of class `c`.
    fn class(&self, c: usize) -> &[f64] {
        &self.data[self.first + c * self.stride..][..self.len]
    }
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
        self.anchors.update(model, pos);
    }

    /// Where the points touching obstacles are tied (empty without friction or obstacles).
    pub(crate) fn anchors(&self) -> &Anchors {
        &self.anchors
    }

    /// The contacts between bodies of the last force evaluation (their grid at its positions).
    pub(crate) fn contacts(&self) -> &Contacts {
        &self.contacts
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
/// team, see [`crate::compute::team`]), or two where each still gets two chunks (spare ranges balance the
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
/// (SPEC.md): the sum of its spring forces, plus the interpolated force field, plus one penalty
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

/// What the acceleration of a block of points depends on besides the model: their positions,
/// velocities, spring forces and control forces.
#[derive(Clone, Copy)]
pub struct PointInputs<'a> {
    /// Positions (m), x, y and z.
    pub pos: [&'a [f64]; 3],
    /// Velocities (m/s), x, y and z.
    pub vel: [&'a [f64]; 3],
    /// Sum of the spring forces (N), x, y and z.
    pub spring: [&'a [f64]; 3],
    /// Control force on each point (N), or `None` for no control forces.
    pub control: Option<&'a [Vec3]>,
    /// Flat index of the block's first point.
    pub first: usize,
    /// The control's pulls (all of them; those on the block's points act).
    pub pulls: &'a [Pull],
    /// Mass of each point of the block (kg).
    pub mass: f64,
    /// Per point of the block whether it takes part, or `None` when all do. The others (the
    /// unused corners of a lattice with holes) do not accelerate.
    pub active: Option<&'a [bool]>,
    /// Contact force from other bodies on each point (N), x, y and z, or `None` for none.
    pub contact: Option<[&'a [f64]; 3]>,
    /// The obstacles' friction anchors (of every point; see [`crate::contact::friction`]), or `None`
    /// when there are none (friction off, or a force evaluation outside a step).
    pub anchors: Option<&'a Anchors>,
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
/// Threads take contiguous ranges of chunks. Every chunk is computed the same way whichever
/// thread runs it, so results do not depend on the thread count. Returns whether every `update`
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

/// Whether a [`force_pass`] reads the obstacles' friction anchors.
#[derive(Clone, Copy, PartialEq, Eq)]
pub(crate) enum Ties {
    /// Points tied to an anchor feel its spring and damper (every force evaluation of a step).
    Held,
    /// As if no point had an anchor: at zero velocities the pass then has no friction at all
    /// (the implicit integrators add it themselves, at the iterate's velocities).
    Ignored,
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
    ties: Ties,
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
    let anchors = (!anchors.is_empty() && ties == Ties::Held).then_some(&*anchors);
    // Contacts between bodies first: every chunk's update reads them.
    let several = model.bodies().len() > 1;
    if several {
        contacts.compute(model, p, v);
    }
    let contact = several.then(|| contacts.forces());
    let mut outs = outs;
    let mut all = true;
    for (
        body,
        BodyScratch {
            owns,
            halos,
            rows,
            masks,
            spans,
        },
    ) in model.bodies().iter().zip(bodies)
    {
        let (body_outs, rest) = outs.split_at(body.len());
        outs = rest;
        let grid = Grid::new(body);
        let pass = Pass {
            model,
            body,
            grid,
            masks,
            spans,
            p,
            v,
            control,
            contact,
            anchors,
            update,
        };
        // As many ranges as the buffers allow (the pool may have grown since they were sized;
        // the ranges only decide which thread computes what, never the results).
        let ranges = range_count(body).min(owns.len());
        let buffers = owns
            .iter_mut()
            .zip(halos.chunks_exact_mut(2))
            .zip(rows.iter_mut());
        let buffers = buffers.map(|((own, halos), row)| RangeBuffers { own, halos, row });
        // On a team of threads: the caller's (an integrator's step), else one for this pass.
        let run = || pass.ranges(buffers, body_outs, ranges);
        all &= match ranges > 1 && crate::compute::team::threads() == 1 {
            true => crate::compute::team::run(run),
            false => run(),
        };
    }
    all
}

/// What every chunk of a [`force_pass`] shares.
struct Pass<'a, U> {
    model: &'a Model,
    body: &'a Body,
    grid: Grid,
    masks: &'a Masks,
    spans: &'a [[u32; 2]],
    p: &'a Soa,
    v: &'a Soa,
    control: &'a Control,
    contact: Option<&'a Soa>,
    anchors: Option<&'a Anchors>,
    update: &'a U,
}

/// The buffers of a body's spring pass that a range of planes takes for its own.
struct RangeBuffers<'a> {
    /// Spring forces on the points of a chunk.
    own: &'a mut Soa,
    /// Two halos: the chunk before's and the chunk's own (see [`BodyScratch::halos`]).
    halos: &'a mut [Soa],
    /// One block of springs' forces, then of accelerations.
    row: &'a mut Soa,
}

impl<U> Pass<'_, U> {
    /// Points per chunk (the last chunk may have fewer).
    fn chunk_len(&self) -> usize {
        CHUNK_PLANES * self.grid.ny * self.grid.nz
    }

    /// Points of chunk `c`.
    fn chunk_points(&self, c: usize) -> usize {
        let Grid { nx, ny, nz, .. } = self.grid;
        self.chunk_len().min(nx * ny * nz - c * self.chunk_len())
    }

    /// The body's planes, split into `ranges` contiguous ranges spread over the team this
    /// thread leads (see [`crate::compute::team`]), each with buffers of its own from `buffers`, with
    /// `outs` the outputs of their points. Returns whether every update returned true.
    ///
    /// Range `r` is always the same planes, and on a team the same thread takes it pass after
    /// pass (the team's blocks), so its points stay in that core's caches.
    fn ranges<'b, T>(
        &self,
        buffers: impl Iterator<Item = RangeBuffers<'b>>,
        outs: T,
        ranges: usize,
    ) -> bool
    where
        T: Split,
        U: Fn(usize, T, [&[f64]; 3]) -> bool + Sync,
    {
        let Grid { nx, ny, nz, .. } = self.grid;
        let mut buffers = buffers;
        // `range_count` keeps ranges of at least MIN_RANGE_PLANES planes, within the team's items.
        debug_assert!(
            ranges == 1
                || (ranges <= nx / MIN_RANGE_PLANES && ranges <= crate::compute::team::OWNED_ITEMS)
        );
        if ranges <= 1 {
            let buffers = buffers.next().expect("buffers for one range");
            return self.range(0..nx, buffers, outs);
        }
        // Each range's planes, buffers and outputs, cut here and taken by the item that runs it.
        type Part<'b, T> = Option<(Range<usize>, RangeBuffers<'b>, T)>;
        let parts: [Mutex<Part<'_, T>>; crate::compute::team::OWNED_ITEMS] =
            std::array::from_fn(|_| Mutex::new(None));
        let mut outs = outs;
        for (r, (part, range_buffers)) in parts.iter().zip(&mut buffers).take(ranges).enumerate() {
            let planes = r * nx / ranges..(r + 1) * nx / ranges;
            let (range_outs, rest) = outs.split_at(planes.len() * ny * nz);
            outs = rest;
            *part.lock().expect("unpoisoned") = Some((planes, range_buffers, range_outs));
        }
        let all = AtomicBool::new(true);
        crate::compute::team::for_each(ranges, &|r| {
            let part = parts[r].lock().expect("unpoisoned").take();
            let (planes, buffers, outs) = part.expect("each range runs once and has buffers");
            if !self.range(planes, buffers, outs) {
                all.store(false, Ordering::Relaxed);
            }
        });
        all.into_inner()
    }

    /// The planes `planes` on this thread, with `outs` the outputs of their points, chunk by
    /// chunk: the springs whose forces reach the range's points (in the chunk's own order, so
    /// its points get the same bits however the planes are cut into ranges), then the points
    /// completed. A range that starts in a chunk's first [`HALO_PLANES`] planes first computes
    /// the halo of the chunk before. Returns whether every update returned true.
    fn range<T>(&self, planes: Range<usize>, buffers: RangeBuffers<'_>, outs: T) -> bool
    where
        T: Split,
        U: Fn(usize, T, [&[f64]; 3]) -> bool + Sync,
    {
        let RangeBuffers { own, halos, row } = buffers;
        let (g, masks, p, v) = (&self.grid, self.masks, self.p, self.v);
        let plane = g.ny * g.nz;
        let [halo_before, halo_after] = halos else {
            unreachable!("two halos per range")
        };
        let (first, last) = (planes.start / CHUNK_PLANES, (planes.end - 1) / CHUNK_PLANES);
        let entry = planes.start - first * CHUNK_PLANES;
        let entry_halo = first > 0 && entry < HALO_PLANES;
        if entry_halo {
            let before = self.placement(first - 1);
            let halo_only = before.planes * plane..usize::MAX;
            chunk_springs(g, masks, p, v, before, None, halo_only, halo_before, row);
        }
        let (mut halo_before, mut halo_after) = (halo_before, halo_after);
        let mut outs_rest = outs;
        let mut all = true;
        for c in first..=last {
            let at = self.placement(c);
            let c0 = at.i0;
            // The chunk's points in the range (offsets in the chunk).
            let ends =
                (planes.start.max(c0) - c0) * plane..(planes.end.min(c0 + at.planes) - c0) * plane;
            let [fx, fy, fz] = own.range_mut(0..self.chunk_points(c));
            let forces = Some([&mut *fx, &mut *fy, &mut *fz]);
            chunk_springs(g, masks, p, v, at, forces, ends.clone(), halo_after, row);
            let before = (c > first || entry_halo).then_some(&*halo_before);
            let (outs_c, rest) = outs_rest.split_at(ends.len());
            outs_rest = rest;
            all &= self.complete(c, [fx, fy, fz], ends, before, row, outs_c);
            std::mem::swap(&mut halo_before, &mut halo_after);
        }
        all
    }

    /// Where chunk `c`'s springs are.
    fn placement(&self, c: usize) -> Placement<'_> {
        let per_chunk = self.spans.len() / self.grid.nx.div_ceil(CHUNK_PLANES).max(1);
        Placement {
            first: self.body.points().start,
            i0: c * CHUNK_PLANES,
            planes: CHUNK_PLANES.min(self.grid.nx - c * CHUNK_PLANES),
            links: self.body.links(),
            spans: &self.spans[c * per_chunk..(c + 1) * per_chunk],
            table: self.body.spring_table(),
        }
    }

    /// Completes the points `ends` (offsets in the chunk) of chunk `c`: adds the halo of the
    /// chunk before to their spring forces in `own`, then computes their accelerations block by
    /// block and hands them to the update with the block's part of `outs`.
    fn complete<T>(
        &self,
        c: usize,
        own: [&mut [f64]; 3],
        ends: Range<usize>,
        halo_before: Option<&Soa>,
        row: &mut Soa,
        outs: T,
    ) -> bool
    where
        T: Split,
        U: Fn(usize, T, [&[f64]; 3]) -> bool + Sync,
    {
        let [fx, fy, fz] = own;
        if let Some(h) = halo_before {
            for (f, h) in [&mut *fx, &mut *fy, &mut *fz]
                .into_iter()
                .zip([h.x(), h.y(), h.z()])
            {
                let end = ends.end.min(h.len());
                if ends.start < end {
                    add_into(&mut f[ends.start..end], &h[ends.start..end]);
                }
            }
        }
        let local = c * self.chunk_len();
        let base = self.body.points().start + local;
        let control = (!self.control.forces.is_empty()).then(|| &self.control.forces[..]);
        let active = self.body.active_mask();
        let mut outs = outs;
        let mut all = true;
        let mut t = ends.start;
        while t < ends.end {
            let n = row.len().min(ends.end - t);
            let (block_outs, rest) = outs.split_at(n);
            outs = rest;
            let r = base + t..base + t + n;
            let point = PointInputs {
                pos: self.p.range(r.clone()),
                vel: self.v.range(r.clone()),
                spring: [&fx[t..t + n], &fy[t..t + n], &fz[t..t + n]],
                control: control.map(|c| &c[r.clone()]),
                first: r.start,
                pulls: &self.control.pulls,
                mass: self.body.material.mass,
                active: (!active.is_empty()).then(|| &active[local + t..local + t + n]),
                contact: self.contact.map(|c| c.range(r.clone())),
                anchors: self.anchors,
            };
            // The row buffer is free once the chunk's springs are done.
            let [ax, ay, az] = row.parts_mut();
            let acc = [&mut ax[..n], &mut ay[..n], &mut az[..n]];
            block_accelerations(self.model, point, acc);
            let acc = [&row.x()[..n], &row.y()[..n], &row.z()[..n]];
            all &= (self.update)(r.start, block_outs, acc);
            t += n;
        }
        all
    }
}

crate::compute::simd::multiversion! {
    /// `f += h`, element by element.
    fn add_into(f: &mut [f64], h: &[f64]) {
        let h = &h[..f.len()];
        for i in 0..f.len() {
            f[i] += h[i];
        }
    }
}

/// Lattice dimensions and the spring constants per kind.
#[derive(Clone, Copy)]
struct Grid {
    nx: usize,
    ny: usize,
    nz: usize,
    stiffness: [f64; 3],
    damping: [f64; 3],
    /// Rest length of each stencil entry (m).
    rest: [f64; 16],
}

impl Grid {
    fn new(body: &Body) -> Self {
        let [nx, ny, nz] = body.lattice().counts;
        let h = body.lattice().spacing();
        let mut rest = [0.0; 16];
        for (r, (d, _)) in rest.iter_mut().zip(STENCIL) {
            // The same expression as Lattice::springs, so the rest lengths agree bit for bit.
            *r = Vec3::new(d[0] as f64 * h.x, d[1] as f64 * h.y, d[2] as f64 * h.z).length();
        }
        Grid {
            nx,
            ny,
            nz,
            stiffness: body.material.stiffness,
            damping: body.material.damping,
            rest,
        }
    }
}

/// Where a chunk's springs are: the body's first point in the model's arrays, the chunk's first
/// plane and its number of planes, and the body's link bits (empty for a full box).
#[derive(Clone, Copy)]
struct Placement<'a> {
    first: usize,
    i0: usize,
    planes: usize,
    links: &'a [u16],
    /// The chunk's spans of set link bits, per block and stencil entry (empty for a full box).
    spans: &'a [[u32; 2]],
    /// The body's per-spring factors, if it has any.
    table: Option<&'a SpringTable>,
}

crate::compute::simd::multiversion! {
    /// The springs whose first point lies in the chunk's planes `i0 .. i0 + planes` of a body
    /// and that reach the points `needed` (offsets from the chunk's first point; the halo's
    /// start on), into `own` (forces on those planes, zeroed here) and `halo` (forces on the
    /// two planes after them, zeroed here). Only the forces on the points `needed` are whole:
    /// those get the same bits whichever points are needed. With no `own`, `needed` must be
    /// the halo's points.
    #[allow(clippy::too_many_arguments)]
    fn chunk_springs(
        grid: &Grid,
        masks: &Masks,
        p: &Soa,
        v: &Soa,
        at: Placement<'_>,
        own: Option<[&mut [f64]; 3]>,
        needed: Range<usize>,
        halo: &mut Soa,
        row: &mut Soa,
    ) {
        chunk_springs_impl(grid, masks, p, v, at, own, needed, halo, row)
    }
}

/// Walks the springs of the chunk in blocks of the row buffer's length of first ends, each block
/// stencil entry by stencil entry. For one entry `(di, dj, dk)` the first points of its springs
/// form one contiguous run through the chunk's planes, and the second points the same run shifted
/// by a constant. The run also holds pairs that are no springs: in a full box those that wrap
/// from the end of a row or plane into the next, and their force is multiplied by 0 (the masks);
/// in a body with holes, every pair whose link bit is clear. That keeps the loop branch-free and
/// vectorised.
///
/// Every spring's force is computed from its own ends alone, and each point's sums are taken in
/// the order of the walk (block, then entry), so a walk over only the springs that reach some
/// points (the halo's, or a range's of the chunk), in the same order and the same blocks, gives
/// those points the same bits.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn chunk_springs_impl(
    grid: &Grid,
    masks: &Masks,
    p: &Soa,
    v: &Soa,
    at: Placement<'_>,
    mut own: Option<[&mut [f64]; 3]>,
    needed: Range<usize>,
    halo: &mut Soa,
    row: &mut Soa,
) {
    let Grid { nx, ny, nz, .. } = *grid;
    let i0 = at.i0;
    let plane = ny * nz;
    let own_planes = at.planes;
    let (base, halo_base) = (at.first + i0 * plane, at.first + (i0 + own_planes) * plane);
    if let Some(own) = &mut own {
        debug_assert!(own.iter().all(|f| f.len() == own_planes * plane));
        for f in own {
            f.fill(0.0);
        }
    }
    halo.fill_zero();
    let block = row.len();

    // Per stencil entry: the first ends of its springs in the whole chunk form one contiguous
    // run (from plane i0, row j_lo, column k_lo to the last plane with a partner, row j_hi − 1,
    // column k_hi − 1), and the second ends the same run shifted.
    let runs: [_; 16] = std::array::from_fn(|s| {
        let ([di, dj, dk], kind) = STENCIL[s];
        let i_end = (i0 + own_planes).min(nx.saturating_sub(di as usize));
        let (j_lo, j_hi) = (
            dj.min(0).unsigned_abs(),
            ny.saturating_sub(dj.max(0) as usize),
        );
        let (k_lo, k_hi) = (
            dk.min(0).unsigned_abs(),
            nz.saturating_sub(dk.max(0) as usize),
        );
        if i_end <= i0 || j_lo >= j_hi || k_lo >= k_hi {
            return None;
        }
        let t_start = j_lo * nz + k_lo;
        let t_end = (i_end - 1 - i0) * plane + (j_hi - 1) * nz + k_hi;
        let shift = ((di * ny as isize + dj) * nz as isize + dk) as usize;
        let mask = ((dj + 1) * 4 + dk + 1) as usize;
        let spring = SpringConst {
            k: grid.stiffness[kind as usize],
            d: grid.damping[kind as usize],
            rest: grid.rest[s],
        };
        Some((s, t_start, t_end, shift, mask, spring))
    });
    // Block by block of first ends, every entry's part of the block in turn: the points an entry
    // reaches from a block lie within two planes after it, so what the block works on stays in
    // the L2 cache however large the chunk.
    let chunk_end = runs.iter().flatten().map(|r| r.2).max().unwrap_or(0);
    let mut t0 = 0;
    while t0 < chunk_end {
        let t1 = t0 + block;
        for &(s, t_start, t_end, shift, mask, spring) in runs.iter().flatten() {
            let (mut t, mut e) = (t0.max(t_start), t1.min(t_end));
            if let Some(&[lo, hi]) = at.spans.get(t0 / block * 16 + s) {
                // A body with holes: only the stretch where this entry has springs.
                (t, e) = (t.max(lo as usize), e.min(hi as usize));
            }
            // Only the springs reaching the points needed: first ends up to the last of them,
            // second ends from the first of them.
            debug_assert!(own.is_some() || needed.start == halo_base - base);
            (t, e) = (t.max(needed.start.saturating_sub(shift)), e.min(needed.end));
            if t >= e {
                continue;
            }
            let len = e - t;
            let (a, b) = (base + t, base + t + shift);
            // Four variants, each a branch-free loop: full box or link bits, material values or
            // per-spring factors on them.
            let points = nx * plane;
            let factors = at
                .table
                .map(|table| table.run(points, s, i0 * plane + t, len));
            let uniform = |_| (spring.k, spring.d, spring.rest);
            if at.links.is_empty() {
                let m = t % plane;
                let mask = &masks.class(mask)[m..m + len];
                match factors {
                    None => spring_run(p, v, a, b, len, uniform, |t| mask[t], row),
                    Some(f) => spring_run(p, v, a, b, len, spring.scaled(f), |t| mask[t], row),
                }
            } else {
                let links = &at.links[i0 * plane + t..][..len];
                let link = |t: usize| (links[t] >> s & 1) as f64;
                match factors {
                    None => spring_run(p, v, a, b, len, uniform, link, row),
                    Some(f) => spring_run(p, v, a, b, len, spring.scaled(f), link, row),
                }
            }
            let cut = halo_base.saturating_sub(b).min(len);
            if let Some([ox, oy, oz]) = &mut own {
                add_run([ox, oy, oz], t, row.range(0..len), len, 1.0);
                if cut > 0 {
                    add_run([ox, oy, oz], b - base, row.range(0..len), cut, -1.0);
                }
            }
            if cut < len {
                let h = halo.parts_mut();
                add_run(
                    h,
                    (b + cut) - halo_base,
                    row.range(cut..len),
                    len - cut,
                    -1.0,
                );
            }
        }
        t0 = t1;
    }
}

/// Stiffness (N/m), damping (N·s/m) and rest length (m) of the springs of one stencil entry.
#[derive(Clone, Copy)]
struct SpringConst {
    k: f64,
    d: f64,
    rest: f64,
}

impl SpringConst {
    /// Per spring `t` of a run, these values times its factors (rest, stiffness, damping).
    #[inline(always)]
    fn scaled(self, [r, k, d]: [&[f64]; 3]) -> impl Fn(usize) -> (f64, f64, f64) + '_ {
        move |t| (self.k * k[t], self.d * d[t], self.rest * r[t])
    }
}

/// Forces on the points `a .. a + len` from the springs joining them to `b .. b + len`:
/// `f = −k (|L| − R) L̂ − d ((vA − vB)·L̂) L̂` with `L = pA − pB` and `(k, d, R) = spring(t)`,
/// computed with one square root and one division per spring, times `mask(t)` (1 for a spring, 0
/// for a pair that is none; multiplying by 1 changes nothing). A zero-length spring has no
/// direction and exerts no force.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn spring_run(
    p: &Soa,
    v: &Soa,
    a: usize,
    b: usize,
    len: usize,
    spring: impl Fn(usize) -> (f64, f64, f64),
    mask: impl Fn(usize) -> f64,
    row: &mut Soa,
) {
    let (xa, ya, za) = (&p.x()[a..a + len], &p.y()[a..a + len], &p.z()[a..a + len]);
    let (xb, yb, zb) = (&p.x()[b..b + len], &p.y()[b..b + len], &p.z()[b..b + len]);
    let (ua, va, wa) = (&v.x()[a..a + len], &v.y()[a..a + len], &v.z()[a..a + len]);
    let (ub, vb, wb) = (&v.x()[b..b + len], &v.y()[b..b + len], &v.z()[b..b + len]);
    let [fx, fy, fz] = row.parts_mut();
    let (fx, fy, fz) = (&mut fx[..len], &mut fy[..len], &mut fz[..len]);
    for t in 0..len {
        let (dx, dy, dz) = (xa[t] - xb[t], ya[t] - yb[t], za[t] - zb[t]);
        let l2 = dx * dx + dy * dy + dz * dz;
        let inv = if l2 > 0.0 { 1.0 / l2.sqrt() } else { 0.0 };
        let l = l2 * inv;
        let closing = ((ua[t] - ub[t]) * dx + (va[t] - vb[t]) * dy + (wa[t] - wb[t]) * dz) * inv;
        let (k, d, rest) = spring(t);
        // Magnitude along L̂, times L̂ = L·inv, times the mask.
        let s = (-k * (l - rest) - d * closing) * inv * mask(t);
        (fx[t], fy[t], fz[t]) = (dx * s, dy * s, dz * s);
    }
}

/// `f[at .. at + len] += sign · row[.. len]`, component by component.
#[inline(always)]
fn add_run(f: [&mut [f64]; 3], at: usize, row: [&[f64]; 3], len: usize, sign: f64) {
    for (f, r) in f.into_iter().zip(row) {
        let (f, r) = (&mut f[at..at + len], &r[..len]);
        // The first few one by one, so that the vector loop's stores start on a cache line
        // (a store that straddles two lines costs far more than such a load).
        let peel = f.as_ptr().align_offset(64).min(len);
        let ((f0, f), (r0, r)) = (f.split_at_mut(peel), r.split_at(peel));
        for (f, r) in f0.iter_mut().zip(r0) {
            *f += sign * r;
        }
        let len = f.len();
        if sign > 0.0 {
            for t in 0..len {
                f[t] += r[t];
            }
        } else {
            for t in 0..len {
                f[t] -= r[t];
            }
        }
    }
}

crate::compute::simd::multiversion! {
    /// Accelerations of a block of points once their spring forces are known: spring force plus
    /// field, walls, plane and control, over the mass. Compiled for AVX-512 too (floors and
    /// selects in vector registers).
    pub fn block_accelerations(model: &Model, point: PointInputs<'_>, acc: [&mut [f64]; 3]) {
        block_accelerations_impl(model, point, acc)
    }
}

#[inline(always)]
fn block_accelerations_impl(model: &Model, point: PointInputs<'_>, acc: [&mut [f64]; 3]) {
    let [ax, ay, az] = acc;
    let len = ax.len();
    let (ay, az) = (&mut ay[..len], &mut az[..len]);
    let [px, py, pz] = point.pos.map(|c| &c[..len]);
    let [vx, vy, vz] = point.vel.map(|c| &c[..len]);
    let [sx, sy, sz] = point.spring.map(|c| &c[..len]);
    let control = point.control.map(|c| &c[..len]);
    let (kc, dc, mass) = (model.k_collision, model.d_collision, point.mass);
    let (lo, hi) = (model.bounds.min, model.bounds.max);
    let obstacles =
        !model.obstacles.is_empty() || point.contact.is_some() || model.gravity != Vec3::ZERO;
    let block = point.first..point.first + len;
    let pulls = point
        .pulls
        .iter()
        .any(|p| block.contains(&(p.point as usize)));
    // With obstacles, contacts, gravity or pulls, the force is finished (and divided by the mass) after
    // the main loop.
    let deferred = obstacles || pulls;

    // Spring force plus field. A uniform field (or none) is a constant; any other is sampled
    // point by point first.
    let constant = match &model.field {
        None => Some(Vec3::ZERO),
        Some(field) => field.uniform(),
    };
    if let (None, Some(field)) = (constant, &model.field) {
        for t in 0..len {
            let f = Vec3::new(sx[t], sy[t], sz[t]) + field.sample(Vec3::new(px[t], py[t], pz[t]));
            (ax[t], ay[t], az[t]) = (f.x, f.y, f.z);
        }
    }
    // Then walls, plane and control, over the mass: each a branch-free pass over the block (in
    // the L1 cache), the walls and the mass component by component, so that the compiler
    // vectorises them. (One loop over points doing all of it stayed scalar on the AVX2 tier: the
    // compiler would not split it by its invariant options.)
    // Every point's sum is taken in the same order as ever: spring force plus field, the wall
    // (`kCollision·depth·n − dCollision (v·n) n` with n = ±axis), the plane, the control, then
    // over the mass.
    let walls = [(lo.x, hi.x), (lo.y, hi.y), (lo.z, hi.z)];
    let comps = [
        (&mut *ax, px, vx, sx),
        (&mut *ay, py, vy, sy),
        (&mut *az, pz, vz, sz),
    ];
    for (c, ((a, p, v, s), (lo, hi))) in comps.into_iter().zip(walls).enumerate() {
        let (a, p, v, s) = (&mut a[..len], &p[..len], &v[..len], &s[..len]);
        match constant {
            Some(field) => {
                let field = field.to_array()[c];
                for t in 0..len {
                    a[t] = (s[t] + field) + wall_force(p[t], v[t], lo, hi, kc, dc);
                }
            }
            None => {
                for t in 0..len {
                    a[t] += wall_force(p[t], v[t], lo, hi, kc, dc);
                }
            }
        }
    }
    if let Some(pl) = model.plane {
        let (norm, n) = (pl.normal_length(), pl.inward_normal());
        for t in 0..len {
            let (pi, vi) = (
                Vec3::new(px[t], py[t], pz[t]),
                Vec3::new(vx[t], vy[t], vz[t]),
            );
            let s = pl.value(pi);
            let depth = s.abs() / norm;
            let push = n * (kc * depth) - n * (dc * vi.dot(n));
            let push = if s * pl.side < 0.0 { push } else { Vec3::ZERO };
            (ax[t], ay[t], az[t]) = (ax[t] + push.x, ay[t] + push.y, az[t] + push.z);
        }
    }
    if let Some(control) = control {
        for (t, c) in control.iter().enumerate() {
            (ax[t], ay[t], az[t]) = (ax[t] + c.x, ay[t] + c.y, az[t] + c.z);
        }
    }
    if deferred {
        finish_forces(model, point, [&mut *ax, &mut *ay, &mut *az], &block);
    } else {
        for a in [&mut *ax, &mut *ay, &mut *az] {
            for a in a.iter_mut() {
                *a /= mass;
            }
        }
    }
    // Unused corners of a lattice with holes do not accelerate.
    if let Some(active) = point.active {
        let active = &active[..len];
        for a in [&mut *ax, &mut *ay, &mut *az] {
            for (a, &on) in a.iter_mut().zip(active) {
                *a = if on { *a } else { 0.0 };
            }
        }
    }
    // Pinned points do not accelerate.
    let pins = &model.pins;
    let from = pins.partition_point(|&p| (p as usize) < block.start);
    for &p in pins[from..]
        .iter()
        .take_while(|&&p| (p as usize) < block.end)
    {
        let t = p as usize - block.start;
        (ax[t], ay[t], az[t]) = (0.0, 0.0, 0.0);
    }
}

/// The rest of the force on a block (contacts with other bodies, obstacles, then pulls), then
/// over the mass, plus gravity.
#[inline(always)]
fn finish_forces(
    model: &Model,
    point: PointInputs<'_>,
    acc: [&mut [f64]; 3],
    block: &Range<usize>,
) {
    let [ax, ay, az] = acc;
    let (kc, dc, mass) = (model.k_collision, model.d_collision, point.mass);
    let law = [kc, dc, model.friction];
    let c_max = mass / model.dt;
    if let Some(contact) = point.contact {
        for (a, c) in [&mut *ax, &mut *ay, &mut *az].into_iter().zip(contact) {
            for (a, c) in a.iter_mut().zip(c) {
                *a += c;
            }
        }
    }
    // Obstacles, one loop each over the block (branch-free, so each vectorises).
    for (o, obstacle) in model.obstacles.iter().enumerate() {
        let anchors = point.anchors.map(|a| &a.of(o)[block.clone()]);
        let force = [&mut *ax, &mut *ay, &mut *az];
        match *obstacle {
            Obstacle::Plane(pl) => {
                let (norm, inward) = (pl.normal_length(), pl.inward_normal());
                add_contacts(point, force, anchors, law, c_max, |p| {
                    pl.depth_with(p, norm, inward)
                })
            }
            Obstacle::Sphere(sphere) => {
                add_contacts(point, force, anchors, law, c_max, |p| sphere.depth(p))
            }
            Obstacle::Box(b) => {
                add_contacts(point, force, anchors, law, c_max, |p| b.solid_depth(p))
            }
        }
    }
    // Pulls on the block's points, in the order given.
    for pull in point.pulls {
        let Some(t) = (pull.point as usize).checked_sub(block.start) else {
            continue;
        };
        if t >= ax.len() {
            continue;
        }
        let p = Vec3::new(point.pos[0][t], point.pos[1][t], point.pos[2][t]);
        let v = Vec3::new(point.vel[0][t], point.vel[1][t], point.vel[2][t]);
        let f = pull.force(p, v);
        (ax[t], ay[t], az[t]) = (ax[t] + f.x, ay[t] + f.y, az[t] + f.z);
    }
    let g = model.gravity.to_array();
    for (a, g) in [ax, ay, az].into_iter().zip(g) {
        for a in a.iter_mut() {
            *a = *a / mass + g;
        }
    }
}

/// `force += penalty` over a block for one obstacle given by `depth_normal(p)` (depth ≤ 0 for
/// none), with the block's friction `anchors` (none: no anchors); `law` and `c_max` as
/// [`penalty`] takes them.
#[inline(always)]
fn add_contacts(
    point: PointInputs<'_>,
    force: [&mut [f64]; 3],
    anchors: Option<&[Vec3]>,
    law: [f64; 3],
    c_max: f64,
    depth_normal: impl Fn(Vec3) -> (f64, Vec3),
) {
    let [fx, fy, fz] = force;
    let len = fx.len();
    let (fy, fz) = (&mut fy[..len], &mut fz[..len]);
    let [px, py, pz] = point.pos.map(|c| &c[..len]);
    let [vx, vy, vz] = point.vel.map(|c| &c[..len]);
    for t in 0..len {
        let p = Vec3::new(px[t], py[t], pz[t]);
        let (depth, n) = depth_normal(p);
        let anchor = anchors.map_or(friction::NONE, |a| a[t]);
        let f = penalty(
            depth,
            n,
            p,
            Vec3::new(vx[t], vy[t], vz[t]),
            anchor,
            law,
            c_max,
        );
        (fx[t], fy[t], fz[t]) = (fx[t] + f.x, fy[t] + f.y, fz[t] + f.z);
    }
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
