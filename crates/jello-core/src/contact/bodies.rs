//! Contacts between bodies, surface to surface.
//!
//! **Method.** Each body carries its contact surface (see
//! [`crate::model::contact_surface`]): the points of its surface embedded in its cells
//! (samples), and the signed distance at rest of its lattice points to its surface,
//! interpolated over each cell as the cell deforms. A sample of body A that lies inside a kept
//! cell of another body B where B's interpolated distance `φ` is negative touches B: it is
//! `depth = −φ/max(|∇φ|, ½)` inside B's surface (see `MIN_GRADIENT`), whose outward normal
//! there is `n = ∇φ/|∇φ|`. It is
//! pushed out by a penalty spring with the model's collision stiffness and damped with its
//! collision damping, `(kCollision·depth − dCollision (vA − vB)·n)·n`, with `vA − vB` the
//! velocity of the sample relative to the point of B's cell it is at; across `n` acts Coulomb
//! friction with the model's coefficient (see [`crate::contact::friction`]; its cap uses the
//! two bodies' reduced point mass). The force on the sample goes to the corners of its cell in
//! A by its trilinear weights, exactly the opposite to the corners of B's cell by the weights
//! of the point it is at: contacts conserve linear momentum. Every body's samples are tested
//! against every other body's cells, so two bodies touch on both sides.
//!
//! **Self-contact** ([`Model::self_contact`]): a body's samples are also tested against its
//! own cells but the one they are embedded in (and those sharing the face, edge or corner a
//! sample lies on, which hold it at its own place whatever their shapes), by the same law, so a
//! bar bent over or a torus squashed flat meets itself. A sample found in one of its own cells
//! counts only at a point that lay, at rest, more than half a cell from it (`SELF_APART`):
//! nearer, it is the same piece of surface (a sample on a face its cell shares with the next is
//! in both). Cells that share no corner with the sample's are always that far; cells next to it
//! hold the sample only where the body folds over itself (their corners pass each other), and
//! the fold is pushed apart as any other touch. Under self-contact the cells are also kept
//! from turning inside out ([`super::cell_guard`]), whose forces the contact pass adds: an
//! inverted cell's distance field is meaningless.
//!
//! So skins touch: at rest a body sinks into the one under it by its weight over the collision
//! stiffness of its touching samples, and stands no gap above it. Its limits: a sample moving
//! through a whole cell of another body in one step can pass through it; edges of one body can
//! pass between the samples of another (a coarse cage's points are a cell apart); a body
//! without volume (points, a row, a sheet one point thick) presses on others with each of its
//! points but has no inside, so nothing touches it.
//!
//! The cells a sample may be in are found by the broad phase ([`super::broad_phase`]): at
//! each of its sorts, which samples are in the box of a cell they may touch and which cells
//! (the active samples, see `mark_active`); until the next sort only those samples are placed
//! and only those cells looked at. A cell is looked at by its box first: Newton's method
//! (`locate`) runs only for a sample inside the box of the cell as it is now. Between sorts, a
//! sample found out of a cell keeps how far it was out of it (`SampleChunk::apart`, from
//! `locate_or_apart`), and one found in a cell of another body but outside that body's surface
//! how far it was outside (`SampleChunk::outside`, see `outside_for`): the cell, or every cell
//! of that body, is passed over while the two bodies have moved since the sort too little to
//! close that distance; and a sample whose every cell was passed over so (or by the broad
//! phase's tests) keeps the least of those distances (`SampleChunk::quiet`) and is not even
//! placed until its bodies have moved that far. Movement since the sort counts a body's back
//! and forth once, but counts twice what it moved before the sample was placed: a sample a
//! fraction of a millimetre from a surface in a pile that still stirs would be placed at every
//! pass. So it also keeps how far its body and its cells' bodies may move from where they were
//! when it was placed, as a mark on its body's path (`SampleChunk::calm`, see
//! `BroadPhase::path`: the sum of each pass's largest move of the body and of its
//! neighbours'), and is not placed until the path passes the mark. Where the cells on its list
//! are all of one body, the mark is on the path of its own body and that one alone
//! (`BroadPhase::pair_path`): a body coming down on a pile does not wake the points between
//! two bodies resting on each other a metre away. A sample placed again (its mark passed as
//! its body or another moved) keeps each cell it was found out of passed over too, while the
//! path of the two bodies has not grown by the distance (`SampleChunk::apart_mark`): on fifty
//! shapes dropped into a box, a quarter fewer cells placed. Skipped so, they would have
//! given no touch: the forces are those of looking at every cell, bit for bit (a settled pile of
//! fifty shapes: 2.5× less time in contact from the distances since the sort, 1.3–1.5× less
//! again from the path).

use super::broad_phase::{visit, BroadPhase, NearCell};
use crate::compute::soa::Soa;
use crate::model::body::Body;
use crate::model::contact_surface::{
    beyond_hull, cell_map, in_space, locate, locate_near, locate_or_apart, map3, map8, weights,
    ContactSurface, DistanceCache, Sample,
};
use crate::model::Model;
use crate::vec3::Vec3;

/// The buffers of the contact pass, sized once for a model.
#[derive(Clone, Debug, Default)]
pub struct Contacts {
    /// Contact force on every point (N).
    forces: Soa,
    /// The bodies' cells in a hashed grid.
    grid: BroadPhase,
    /// Per body: the mass of a point (kg), for the friction's cap.
    mass: Vec<f64>,
    /// The samples that touched another body in the last [`Contacts::compute`].
    touches: Vec<Touch>,
    /// The points the cells' guard pushed in the last [`Contacts::compute`] (under
    /// self-contact, see [`super::cell_guard`]), with repeats.
    guarded: Vec<u32>,
    /// The samples cut into chunks of one body's, searched on the team's threads; each chunk's
    /// touches are summed in order after, so the forces do not depend on the thread count.
    chunks: Vec<SampleChunk>,
    /// Wall-clock time spent in [`Contacts::compute`] and [`Contacts::near`] (none counted in
    /// the browser, whose wasm has no clock here).
    spent: std::time::Duration,
    /// The passes, sorts and touches counted so far (the chunks count the rest: see
    /// [`Contacts::work`]).
    work: ContactWork,
}

/// The contact pass's work, counted (`jello run --timings`): unlike its time, the same on any
/// machine and thread count, so that a change to the pass can be judged by it where timings
/// drift. Sums over the passes since the buffers were made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ContactWork {
    /// Contact passes on a model whose surfaces may touch: [`Contacts::compute`] calls, and
    /// the implicit step's own passes (which find the touches it holds a step to).
    pub passes: u64,
    /// Sorts of the broad phase's grid (each lists the samples that may touch anew).
    pub sorts: u64,
    /// Samples listed, summed over the sorts: those in some cell's box, with the cells they
    /// may touch until the next sort.
    pub listed: u64,
    /// Samples placed, summed over the passes: listed samples not passed over as too far from
    /// every cell on their lists, each looked for in those cells.
    pub placed: u64,
    /// Cells a sample was sought in (by the test of its box and hull, then Newton's method),
    /// summed over the passes.
    pub placings: u64,
    /// Touches found (samples inside another body, or within the implicit step's margin),
    /// summed over the passes.
    pub touches: u64,
}

impl std::ops::Add for ContactWork {
    type Output = ContactWork;

    fn add(self, o: ContactWork) -> ContactWork {
        ContactWork {
            passes: self.passes + o.passes,
            sorts: self.sorts + o.sorts,
            listed: self.listed + o.listed,
            placed: self.placed + o.placed,
            placings: self.placings + o.placings,
            touches: self.touches + o.touches,
        }
    }
}

/// A clock's reading to time the contact pass by, where `std` has a clock (not in the browser's
/// wasm, where the time spent stays zero).
#[derive(Clone, Copy)]
struct Started(#[cfg(not(target_arch = "wasm32"))] std::time::Instant);

impl Started {
    fn now() -> Self {
        Started(
            #[cfg(not(target_arch = "wasm32"))]
            std::time::Instant::now(),
        )
    }

    fn elapsed(self) -> std::time::Duration {
        #[cfg(not(target_arch = "wasm32"))]
        return self.0.elapsed();
        #[cfg(target_arch = "wasm32")]
        std::time::Duration::ZERO
    }
}

/// Samples a chunk holds at most.
const CHUNK: usize = 256;

/// A run of one body's samples and the touches found for them, with their forces.
#[derive(Clone, Debug)]
struct SampleChunk {
    body: usize,
    samples: std::ops::Range<usize>,
    /// Those of its samples that were in the box of a cell they may touch at the broad phase's
    /// last sort (as indices into the body's samples, in order): the only ones that may touch
    /// until the next sort. With each, where its list of those cells ends in `cells`.
    active: Vec<(u32, u32)>,
    /// The cells each active sample may touch, in order, with their boxes as sorted.
    cells: Vec<NearCell>,
    /// Beside each of `cells`: the distances at the corners of the sub-cell of its body's
    /// distance grid the sample was last found in (see [`ContactSurface::distance_cached`]).
    distances: Vec<DistanceCache>,
    /// Beside each of `cells`: how far the sample and that cell's body may have moved since the
    /// sort (together, each along any axis) while the sample is still outside that body's
    /// surface, as last found in this cell (see [`outside_for`]); −∞ where not known.
    outside: Vec<f64>,
    /// Beside each of `cells`: how far the sample and the cell may have moved since the sort
    /// (together, each along any axis) while the sample is still out of the cell, as last found
    /// (see [`locate_or_apart`]); −∞ where not known.
    apart: Vec<f64>,
    /// Beside each of `cells`: the same as a mark on the path of the sample's body and the
    /// cell's (see [`BroadPhase::pair_path`]): while the path has not passed it, the sample is
    /// still out of the cell. Movement since the sort counts twice what the bodies moved before
    /// the sample was placed, and bodies falling onto a pile move further between sorts than
    /// most samples are from the cells next to theirs; the path counts only what they moved
    /// since (on fifty shapes dropped into a box, a quarter fewer cells placed).
    apart_mark: Vec<f64>,
    /// Beside each of `active`: how far its sample and every body may have moved since the
    /// sort (together, each along any axis) while every cell on its list is still passed over,
    /// as last found: the least of what passed each over; −∞ where not known.
    quiet: Vec<f64>,
    /// Beside each of `active`: the broad phase's path (that of the chunk's body, see
    /// [`BroadPhase::path`], or of it and one other: see `pair`) below which every cell on its
    /// sample's list is still passed over, as last found: the path then and the least room any
    /// of them had; −∞ where not known.
    calm: Vec<f64>,
    /// Beside each of `active`: the one body whose cells are on its sample's list, whose path
    /// with the chunk's body `calm` is a mark on (see [`BroadPhase::pair_path`]); `u32::MAX`
    /// where the list holds cells of several bodies, and `calm` is a mark on the chunk's body's
    /// path.
    pair: Vec<u32>,
    found: Vec<(Touch, Vec3)>,
    /// Its part of [`ContactWork`]: `listed`, `placed` and `placings`.
    work: ContactWork,
}

/// Each active sample of a chunk (its index into the body's samples) and where the cells it may
/// touch are in the chunk's `cells`, from its `active`.
fn each_active(
    active: &[(u32, u32)],
) -> impl Iterator<Item = (usize, std::ops::Range<usize>)> + '_ {
    let mut start = 0;
    active.iter().map(move |&(s, end)| {
        let these = start..end as usize;
        start = end as usize;
        (s as usize, these)
    })
}

/// A sample of one body inside another: the points its force goes to and their weights (those
/// of the sample's cell, then those of the other body's cell at the sample, each 8, the second
/// 8 weights negated), its depth (m), the other body's outward normal there, and the two
/// bodies' reduced point mass (kg: the friction's cap is that over the time step).
#[derive(Clone, Copy, Debug)]
pub(crate) struct Touch {
    pub points: [u32; 16],
    pub weights: [f64; 16],
    pub depth: f64,
    pub normal: Vec3,
    pub reduced: f64,
}

impl Touch {
    /// The velocity of the sample relative to the other body at it, from velocities `v` (the
    /// weights' sum of theirs).
    #[inline]
    pub(crate) fn relative(&self, v: impl Fn(usize) -> Vec3) -> Vec3 {
        self.points
            .iter()
            .zip(&self.weights)
            .fold(Vec3::ZERO, |s, (&p, &w)| s + v(p as usize) * w)
    }
}

impl Contacts {
    /// Buffers for `model`; empty (and never used) when its surfaces cannot touch (one body
    /// without self-contact).
    pub fn new(model: &Model) -> Self {
        let bodies = model.bodies();
        if !model.surfaces_touch() {
            return Contacts::default();
        }
        // The bodies' surfaces (built once, when first asked for), on the team's threads.
        crate::compute::team::run(|| {
            crate::compute::team::for_each(bodies.len(), &|b| {
                bodies[b].contact_surface();
            })
        });
        let samples: usize = bodies
            .iter()
            .map(|b| b.contact_surface().samples.len())
            .sum();
        let mut chunks = Vec::new();
        for (body, b) in bodies.iter().enumerate() {
            let count = b.contact_surface().samples.len();
            for start in (0..count).step_by(CHUNK) {
                let samples = start..(start + CHUNK).min(count);
                // Room for every sample to touch, so that stepping does not allocate.
                let found = Vec::with_capacity(samples.len());
                chunks.push(SampleChunk {
                    body,
                    active: Vec::with_capacity(samples.len()),
                    cells: Vec::new(),
                    distances: Vec::new(),
                    outside: Vec::new(),
                    apart: Vec::new(),
                    apart_mark: Vec::new(),
                    quiet: Vec::new(),
                    calm: Vec::new(),
                    pair: Vec::new(),
                    samples,
                    found,
                    work: ContactWork::default(),
                });
            }
        }
        // Room for every corner of every cell to be squeezed, so that stepping does not
        // allocate.
        let corners = match model.self_contact {
            true => bodies
                .iter()
                .map(|b| 32 * b.contact_surface().cells().len())
                .sum(),
            false => 0,
        };
        Contacts {
            forces: Soa::zeros(model.point_count()),
            grid: BroadPhase::new(model),
            mass: bodies.iter().map(|b| b.material.mass).collect(),
            touches: Vec::with_capacity(samples),
            guarded: Vec::with_capacity(corners),
            chunks,
            spent: std::time::Duration::ZERO,
            work: ContactWork::default(),
        }
    }

    /// True when the buffers fit `model`.
    pub(crate) fn fits(&self, model: &Model) -> bool {
        if !model.surfaces_touch() {
            return true;
        }
        self.forces.len() == model.point_count() && self.mass.len() == model.bodies().len()
    }

    /// The contact forces of the last [`Contacts::compute`].
    pub fn forces(&self) -> &Soa {
        &self.forces
    }

    /// Wall-clock time spent finding contacts between bodies and their forces since these
    /// buffers were made (zero in the browser).
    pub fn time_spent(&self) -> std::time::Duration {
        self.spent
    }

    /// The work of the contact passes since these buffers were made (see [`ContactWork`]).
    pub fn work(&self) -> ContactWork {
        let chunks = self.chunks.iter().map(|c| c.work);
        chunks.fold(self.work, |sum, w| sum + w)
    }

    /// The contact forces between the bodies of `model` at positions `p` and velocities `v`.
    pub fn compute(&mut self, model: &Model, p: &Soa, v: &Soa) {
        let start = Started::now();
        self.compute_untimed(model, p, v);
        self.spent += start.elapsed();
    }

    /// [`Contacts::compute`], not timed.
    fn compute_untimed(&mut self, model: &Model, p: &Soa, v: &Soa) {
        let Contacts {
            forces,
            grid,
            mass,
            touches,
            guarded,
            chunks,
            work,
            ..
        } = self;
        // Only the points of the last pass's touches and guard hold forces (a dense fill was a
        // serial tenth of a pass on 2 threads).
        let [fx, fy, fz] = forces.parts_mut();
        let last = touches
            .iter()
            .flat_map(|t| t.points.iter())
            .chain(guarded.iter());
        for &q in last {
            let q = q as usize;
            (fx[q], fy[q], fz[q]) = (0.0, 0.0, 0.0);
        }
        touches.clear();
        guarded.clear();
        if !model.surfaces_touch() {
            return;
        }
        let (px, py, pz) = (p.x(), p.y(), p.z());
        let sorted = grid.refresh(model, [px, py, pz], 0.0);
        work.passes += 1;
        work.sorts += u64::from(sorted);
        let (grid, mass) = (&*grid, &*mass);
        crate::compute::team::for_each_mut(chunks, &|_, chunk| {
            if sorted {
                mark_active(model, grid, p, 0.0, chunk);
            }
            chunk.found.clear();
            find_touches(model, grid, mass, p, v, chunk);
        });
        // The forces summed in the samples' order, whichever thread found them.
        let [fx, fy, fz] = forces.parts_mut();
        for chunk in chunks.iter() {
            for (touch, f) in &chunk.found {
                for (&q, &wq) in touch.points.iter().zip(&touch.weights) {
                    let q = q as usize;
                    (fx[q], fy[q], fz[q]) = (fx[q] + f.x * wq, fy[q] + f.y * wq, fz[q] + f.z * wq);
                }
                touches.push(*touch);
            }
        }
        work.touches += touches.len() as u64;
        // Under self-contact, the cells kept right side out (in the cells' order).
        let at = |q: usize| Vec3::new(px[q], py[q], pz[q]);
        super::cell_guard::for_each_squeezed(model, at, |s| {
            for (q, f) in s.forces() {
                (fx[q], fy[q], fz[q]) = (fx[q] + f.x, fy[q] + f.y, fz[q] + f.z);
                guarded.push(q as u32);
            }
        });
    }

    /// The samples of each body inside another at positions `p`, or outside it by less than
    /// `margin` (m), with their depths (negative: the gap) and the other body's normal and
    /// weights there, each sample once, into `out`: the touches the implicit integrators hold a
    /// step's contacts to (see [`crate::integrate::implicit`]). A sample outside the other
    /// body's cells is judged by the nearest of them: its distance there, carried on to the
    /// sample along its gradient, and its reaction goes to that nearest point.
    pub(crate) fn near(&mut self, model: &Model, p: &Soa, margin: f64, out: &mut Vec<Touch>) {
        let start = Started::now();
        self.near_untimed(model, p, margin, out);
        self.spent += start.elapsed();
    }

    /// [`Contacts::near`], not timed.
    fn near_untimed(&mut self, model: &Model, p: &Soa, margin: f64, out: &mut Vec<Touch>) {
        out.clear();
        let bodies = model.bodies();
        if !model.surfaces_touch() {
            return;
        }
        let (px, py, pz) = (p.x(), p.y(), p.z());
        let grid = &mut self.grid;
        let sorted = grid.refresh(model, [px, py, pz], margin);
        self.work.passes += 1;
        self.work.sorts += u64::from(sorted);
        if sorted {
            let grid = &*grid;
            crate::compute::team::for_each_mut(&mut self.chunks, &|_, chunk| {
                mark_active(model, grid, p, margin, chunk);
            });
        }
        let grid = &self.grid;
        let at = |q: usize| Vec3::new(px[q], py[q], pz[q]);
        for chunk in &mut self.chunks {
            let a = chunk.body;
            let body = &bodies[a];
            let surface = body.contact_surface();
            let first = body.points().start;
            chunk.work.placed += chunk.active.len() as u64;
            for (s, these) in each_active(&chunk.active) {
                let cells = &chunk.cells[these];
                let sample = &surface.samples[s];
                let (points, w, ps) = sample_place(surface, first, sample, at);
                let placings = &mut chunk.work.placings;
                let own = body.lattice().coords(sample.corner as usize);
                // The cell that holds the sample inside its body's surface; else, of the cells
                // that hold it outside their body's surface by less than the margin, the one
                // it is least outside of (another body's cell may hold it inside, as in
                // `find_touches`); else the nearest cell: the one whose nearest point is
                // closest to it.
                let mut found: Option<(f64, Option<Touch>)> = None;
                let mut clear_of = usize::MAX;
                let _ = visit(grid, cells, ps, grid.moved(a), |_, g| {
                    let (b, corner) = grid.cell(g);
                    if b == clear_of {
                        return false;
                    }
                    let other = bodies[b].contact_surface();
                    let h = bodies[b].min_spacing();
                    let corners = map8(other.offsets, |o| at(corner + o));
                    let cell = bodies[b]
                        .lattice()
                        .coords(corner - bodies[b].points().start);
                    let start = start_in(b == a, sample, own, cell);
                    *placings += 1;
                    let Some((uvw, rows)) = locate_near(&corners, ps, margin / h, start) else {
                        return false;
                    };
                    let inside = uvw.iter().all(|u| (0.0..=1.0).contains(u));
                    // Outside the cell: apart from it by the distance to its nearest point (the
                    // surface is inside the cells), along the line to that point.
                    let (uvw, rows, offset) = if inside {
                        (uvw, rows, Vec3::ZERO)
                    } else {
                        let nearest = map3(uvw, |u| u.clamp(0.0, 1.0));
                        (nearest, rows, ps - cell_map(&corners, nearest))
                    };
                    let far = offset.length();
                    // A cell that holds the sample is always looked at (it may hold it inside
                    // its body); one apart from it only when nearer than the nearest so far.
                    if !inside && found.as_ref().is_some_and(|(nearest, _)| *nearest <= far) {
                        return false;
                    }
                    // Of its own body's cells, one next to its own that does not hold the sample
                    // is its own surface's neighbourhood, not a part of the body coming near.
                    if b == a
                        && (!apart_at_rest(body, sample, own, cell, uvw)
                            || (!inside && !share_no_corner(own, cell)))
                    {
                        return false;
                    }
                    let (phi, gu) = other.distance_in(cell, uvw);
                    let (depth, normal) = if inside {
                        let gradient = in_space(gu, &rows);
                        let length = gradient.length();
                        (-phi / length.max(MIN_GRADIENT), gradient / length)
                    } else {
                        (-(phi.max(0.0) + far), offset / far)
                    };
                    if !normal.is_finite() || depth.is_nan() || depth <= -margin {
                        if !inside {
                            found = Some((far, None));
                        } else if b != a {
                            // (A body folded over itself has cells that overlap: the sample's
                            // own body's other cells are looked at still.)
                            clear_of = b;
                        }
                        return false;
                    }
                    // Held outside this body's surface: kept unless a touch as near is deeper.
                    let held = inside && depth <= 0.0;
                    if held && b != a {
                        clear_of = b;
                    }
                    if held {
                        let deeper =
                            |t: &Option<Touch>| t.as_ref().is_some_and(|t| t.depth >= depth);
                        if found
                            .as_ref()
                            .is_some_and(|(nearest, t)| *nearest == 0.0 && deeper(t))
                        {
                            return false;
                        }
                    }
                    let mut touch_points = points;
                    let mut touch_weights = w;
                    for (k, (&o, wb)) in other.offsets.iter().zip(weights(uvw)).enumerate() {
                        (touch_points[8 + k], touch_weights[8 + k]) = ((corner + o) as u32, -wb);
                    }
                    let (ma, mb) = (self.mass[a], self.mass[b]);
                    let touch = Touch {
                        points: touch_points,
                        weights: touch_weights,
                        depth,
                        normal,
                        reduced: ma * mb / (ma + mb),
                    };
                    found = Some((far, Some(touch)));
                    inside && !held
                });
                out.extend(found.and_then(|(_, touch)| touch));
            }
        }
        self.work.touches += out.len() as u64;
    }
}

/// The least gradient of the distance (in space) a depth is taken over: the distance over its
/// gradient's length is the depth to first order as a cell deforms, but at a sharp edge of a
/// surface the interpolated gradient vanishes with the distance, and where both are roundings
/// their ratio would be noise.
const MIN_GRADIENT: f64 = 0.5;

/// The touches of `chunk`'s samples at positions `p` and velocities `v`, with their forces, into
/// its `found`, in the samples' order.
fn find_touches(
    model: &Model,
    grid: &BroadPhase,
    mass: &[f64],
    p: &Soa,
    v: &Soa,
    chunk: &mut SampleChunk,
) {
    let bodies = model.bodies();
    let (a, body) = (chunk.body, &model.bodies()[chunk.body]);
    let neighbours = grid.neighbours(a);
    if neighbours.is_empty() {
        return;
    }
    let (px, py, pz) = (p.x(), p.y(), p.z());
    let (vx, vy, vz) = (v.x(), v.y(), v.z());
    let at = |q: usize| Vec3::new(px[q], py[q], pz[q]);
    let speed = |q: usize| Vec3::new(vx[q], vy[q], vz[q]);
    let (kc, dc, mu) = (model.k_collision, model.d_collision, model.friction);
    let surface = body.contact_surface();
    let first = body.points().start;
    let moved = grid.moved(a);
    let SampleChunk {
        active,
        cells,
        distances,
        outside,
        apart,
        apart_mark,
        quiet,
        calm,
        pair,
        found,
        work,
        ..
    } = chunk;
    let body_path = grid.path(a);
    for ((((s, these), quiet), calm), &pair) in each_active(active)
        .zip(quiet.iter_mut())
        .zip(calm.iter_mut())
        .zip(pair.iter())
    {
        // A sample whose every cell is passed over, as its body and theirs have moved too little
        // since it was last placed, or since the sort, were each of their bodies to have moved
        // as far as the fastest of them, is not placed at all.
        let path = match pair {
            u32::MAX => body_path,
            b => grid.pair_path(a, b as usize),
        };
        if *calm > path {
            continue;
        }
        let cells = &cells[these.clone()];
        if *quiet > moved {
            let fastest = (cells.iter()).fold(0.0, |m: f64, c| m.max(grid.moved(c.body as usize)));
            if *quiet > moved + fastest {
                // So until the path has grown by the room left (each body moves on from where
                // it is now by no more than that).
                *calm = path + (*quiet - (moved + fastest));
                continue;
            }
        }
        let distances = &mut distances[these.clone()];
        let (outside, apart) = (&mut outside[these.clone()], &mut apart[these.clone()]);
        let apart_mark = &mut apart_mark[these];
        work.placed += 1;
        let placings = &mut work.placings;
        let sample = &surface.samples[s];
        let (mut points, mut w, ps) = sample_place(surface, first, sample, at);
        let own = body.lattice().coords(sample.corner as usize);
        // The other bodies the sample is still outside of, as found in earlier passes: none of
        // their cells can hold it inside their surface, and none is looked at (the touches are
        // those of looking at every cell: see `outside_for`).
        let mut known = Outside::default();
        for (c, &still) in cells.iter().zip(&*outside) {
            if still > moved + grid.moved(c.body as usize) {
                known.add(c.body, still);
            }
        }
        // The body last found to hold the sample in a cell but outside its surface.
        let mut clear_of = usize::MAX;
        // How far, of the cells looked at, the nearest to being looked at again is (as
        // `quiet`; those `visit` passes over itself are in what it returns), and how far the
        // sample and their bodies may move from where they are now, together, before it is
        // (as `calm` has it).
        let (mut least, mut room) = (f64::INFINITY, f64::INFINITY);
        let [passed, passed_room] = visit(grid, cells, ps, moved, |k, g| {
            let (b, corner) = grid.cell(g);
            // (How far the sample is outside `clear_of` is in `least` already.)
            if b == clear_of {
                return false;
            }
            // How far the sample and this cell's body have moved since the sort, together: the
            // remembered distances are kept less this, and compared with it.
            let since = moved + grid.moved(b);
            if let Some(still) = known.get(b) {
                least = least.min(still);
                room = room.min(still - since);
                return false;
            }
            let travelled = grid.pair_path(a, b);
            if apart[k] > since || apart_mark[k] > travelled {
                // (Each of the two is room enough; the larger is.)
                least = least.min(apart[k]);
                room = room.min((apart[k] - since).max(apart_mark[k] - travelled));
                return false;
            }
            let other = bodies[b].contact_surface();
            let corners = map8(other.offsets, |o| at(corner + o));
            let cell = || {
                bodies[b]
                    .lattice()
                    .coords(corner - bodies[b].points().start)
            };
            let start = if b == a {
                start_in(true, sample, own, cell())
            } else {
                [0.5; 3]
            };
            *placings += 1;
            let (uvw, rows) = match locate_or_apart(&corners, ps, start) {
                Ok(found) => found,
                Err(clear) => {
                    apart[k] = clear - since;
                    apart_mark[k] = travelled + clear;
                    least = least.min(apart[k]);
                    room = room.min(clear);
                    return false;
                }
            };
            let cell = cell();
            // The first cell that holds the sample inside its body's surface decides. A cell
            // that holds it outside that surface (a cage reaches past its skin) does not: the
            // body's other cells hold it only on a shared face, with the same distance, but
            // another body's may hold it inside.
            if b == a && !apart_at_rest(body, sample, own, cell, uvw) {
                (least, room) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
                return false;
            }
            let (phi, gu) = other.distance_cached(cell, uvw, &mut distances[k]);
            let gradient = in_space(gu, &rows);
            let length = gradient.length();
            if !(phi < 0.0 && length > 0.0) {
                // (A body folded over itself has cells that overlap: the sample's own body's
                // other cells are looked at still.)
                if b != a {
                    clear_of = b;
                    outside[k] = outside_for(phi, &rows, &bodies[b]) - since;
                    least = least.min(outside[k]);
                    room = room.min(outside[k] + since);
                } else {
                    (least, room) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
                }
                return false;
            }
            let (depth, n) = (-phi / length.max(MIN_GRADIENT), gradient / length);
            for (k, (&o, wb)) in other.offsets.iter().zip(weights(uvw)).enumerate() {
                (points[8 + k], w[8 + k]) = ((corner + o) as u32, -wb);
            }
            let (ma, mb) = (mass[a], mass[b]);
            let reduced = ma * mb / (ma + mb);
            let touch = Touch {
                points,
                weights: w,
                depth,
                normal: n,
                reduced,
            };
            let c_max = if mu > 0.0 { reduced / model.dt } else { 0.0 };
            let f = touch_force(n, touch.relative(speed), depth, [kc, dc, mu, c_max]);
            found.push((touch, f));
            true
        });
        *quiet = passed.min(least);
        // (Where nothing is known, the room is −∞ and stays so.)
        *calm = path + passed_room.min(room);
    }
}

/// Finds which of `chunk`'s samples may touch a cell until the grid's next sort, at positions
/// `p` (those of the sort), and which cells: those whose box (as sorted) holds the sample, of
/// the bodies it may touch, and that the sample may come within `margin` (m) of before the
/// next sort (see [`clearance`]), into its `active` and `cells`.
fn mark_active(model: &Model, grid: &BroadPhase, p: &Soa, margin: f64, chunk: &mut SampleChunk) {
    let SampleChunk {
        body: a,
        samples,
        active,
        cells,
        distances,
        outside,
        apart,
        apart_mark,
        quiet,
        calm,
        pair,
        work: chunk_work,
        ..
    } = chunk;
    let a = *a;
    active.clear();
    cells.clear();
    distances.clear();
    outside.clear();
    apart.clear();
    apart_mark.clear();
    quiet.clear();
    calm.clear();
    pair.clear();
    let neighbours = grid.neighbours(a);
    if neighbours.is_empty() {
        return;
    }
    let body = &model.bodies()[a];
    let (px, py, pz) = (p.x(), p.y(), p.z());
    let at = |q: usize| Vec3::new(px[q], py[q], pz[q]);
    let surface = body.contact_surface();
    let first = body.points().start;
    let skip = (!model.self_contact).then_some(a as u32);
    let reach = grid.reach(a);
    let path = grid.path(a);
    for s in samples.clone() {
        let sample = &surface.samples[s];
        let (_, _, ps) = sample_place(surface, first, sample, at);
        if !neighbours.iter().any(|&b| grid.in_body_box(b as usize, ps)) {
            continue;
        }
        let before = cells.len();
        // The least of its cells' `clear`: every cell is passed over until the bodies have moved
        // that far since the sort (now), which their paths' growth bounds.
        let mut clearest = f64::INFINITY;
        grid.find_near(ps, skip, reach, |g| {
            if candidate(model, grid, a, sample, g) {
                let clear = clearance(model, grid, at, ps, margin, g);
                // Passed over when the sample and the cell cannot meet before the next sort.
                if clear <= reach + grid.reach(grid.cell(g).0) {
                    cells.push(grid.near_cell(g, reach, clear));
                    clearest = clearest.min(clear);
                }
            }
            false
        });
        if cells.len() > before {
            active.push((s as u32, cells.len() as u32));
            quiet.push(clearest);
            let b = cells[before].body;
            let one = cells[before..].iter().all(|c| c.body == b);
            let (path, b) = match one {
                true => (grid.pair_path(a, b as usize), b),
                false => (path, u32::MAX),
            };
            calm.push(path + clearest);
            pair.push(b);
        }
    }
    chunk_work.listed += active.len() as u64;
    distances.resize(cells.len(), DistanceCache::EMPTY);
    outside.resize(cells.len(), f64::NEG_INFINITY);
    apart.resize(cells.len(), f64::NEG_INFINITY);
    apart_mark.resize(cells.len(), f64::NEG_INFINITY);
}

/// How far (m) a sample found `phi` (m, at rest: the body's distance there, `≥ 0`) outside the
/// surface of another body, in one of its cells whose map's inverse derivative there has rows
/// `rows`, and the points of that body may move, together, each along any axis, while the
/// sample stays outside that surface: half the distance from the sample to the surface in
/// space, bounded below through the map's stretch (`φ`, a distance at rest, changes by at most
/// `|F⁻¹|` per metre in space, `F` the map's derivative over the body's rest positions; the
/// Frobenius norm bounds it), capped at half a cell (the map is the cell's, the surface may be
/// in the next), over `√3` (a move of `d` along each axis is at most `√3·d` long). The surface
/// is carried by the body's points, the sample by its own body's points: a sample that starts
/// that far outside cannot reach the surface before they have moved further than that. The
/// half is the room left for the map's change between cells: a sample moved through a cage to
/// a skin is caught with 1.4 in its place, and missed with 2 (the test
/// `a_body_coming_through_a_cage_to_a_skin_is_found_as_it_touches`). Negative infinity where
/// nothing is known.
fn outside_for(phi: f64, rows: &[Vec3; 3], body: &Body) -> f64 {
    let h = body.lattice().spacing();
    let stretch =
        h.x.max(h.y).max(h.z) * rows.iter().map(|r| r.length_squared()).sum::<f64>().sqrt();
    let gap = (phi / stretch).min(0.5 * body.min_spacing());
    let still = 0.5 * gap / 3f64.sqrt();
    if still > 0.0 {
        still
    } else {
        f64::NEG_INFINITY
    }
}

/// The bodies a sample is known to be outside of, each with how far it and the body may have
/// moved since the sort while it is (a few: a sample nears a few bodies at once; beyond those,
/// bodies are looked at as usual).
#[derive(Default)]
struct Outside {
    bodies: [(u32, f64); 4],
    count: usize,
}

impl Outside {
    /// Body `b`, known to be outside of while the bodies have moved less than `still`; where it
    /// is known already, the larger.
    #[inline]
    fn add(&mut self, b: u32, still: f64) {
        let room = self.count < self.bodies.len();
        match self.bodies[..self.count].iter_mut().find(|(c, _)| *c == b) {
            Some((_, known)) => *known = known.max(still),
            None if room => {
                self.bodies[self.count] = (b, still);
                self.count += 1;
            }
            None => {}
        }
    }

    /// How far body `b` is known to be outside of (see `add`), if it is.
    #[inline]
    fn get(&self, b: usize) -> Option<f64> {
        let b = b as u32;
        (self.bodies[..self.count].iter())
            .find(|(c, _)| *c == b)
            .map(|&(_, still)| still)
    }
}

/// Where `sample` of a body (its surface, its first point `first`) is, by `at(point)`: its
/// cell's corners with their weights (the first 8 of 16; the other body's go after), and the
/// place.
#[inline]
fn sample_place(
    surface: &ContactSurface,
    first: usize,
    sample: &Sample,
    at: impl Fn(usize) -> Vec3,
) -> ([u32; 16], [f64; 16], Vec3) {
    let base = first + sample.corner as usize;
    let mut points = [0u32; 16];
    let mut w = [0.0; 16];
    let mut ps = Vec3::ZERO;
    for (k, (&o, wk)) in surface
        .offsets
        .iter()
        .zip(weights(sample.local))
        .enumerate()
    {
        (points[k], w[k]) = ((base + o) as u32, wk);
        ps += at(base + o) * wk;
    }
    (points, w, ps)
}

/// True when `sample` of body `a` (in its cell at lattice coordinates `own`) may touch cell `g`
/// of the broad phase: a cell of another body, or under self-contact one of body `a`'s own but
/// the sample's (where it is, at rest and always, is its own surface) and those that share the
/// face, edge or corner it lies on. Such a cell holds the sample at its own place whatever the
/// cells' shapes (the two maps agree on what they share), which is where Newton's method starts
/// in it (`start_in`) and stops at once: never a point apart from the sample at rest.
#[inline]
fn candidate(model: &Model, grid: &BroadPhase, a: usize, sample: &Sample, g: usize) -> bool {
    let (b, corner) = grid.cell(g);
    if b != a {
        return true;
    }
    let body = &model.bodies()[b];
    let own = body.lattice().coords(sample.corner as usize);
    let cell = body.lattice().coords(corner - body.points().start);
    model.self_contact && own != cell && !holds_at_rest(sample, own, cell)
}

/// True when the cell at lattice coordinates `cell` holds, at rest, `sample` (in the cell at
/// `own` of the same body): on a face, edge or corner the two cells share.
#[inline]
fn holds_at_rest(sample: &Sample, own: [usize; 3], cell: [usize; 3]) -> bool {
    (0..3).all(|k| {
        let u = (own[k] as f64 - cell[k] as f64) + sample.local[k];
        (0.0..=1.0).contains(&u)
    })
}

/// How far a point at `ps` now (at a sort) and the points of cell `g` of the broad phase must
/// move, together (each along any axis), before the point may come within `margin` (m) of the
/// cell: its distance beyond the hull of the cell's corners, along the line from their middle,
/// less the margin, over how far a move of 1 along each axis goes along that line. (A cell lies
/// in the hull of its corners; a point and the corners moving up to `d` along each axis close
/// that distance by at most `d·|n|₁` along the unit direction `n`.) A cell's box, which the
/// grid sorts by, is far larger than its hull when it is turned or sheared, and holds many
/// points its hull does not; and the points move far less than the reaches between most sorts.
/// Negative where the point is within the margin already.
#[inline]
fn clearance(
    model: &Model,
    grid: &BroadPhase,
    at: impl Fn(usize) -> Vec3,
    ps: Vec3,
    margin: f64,
    g: usize,
) -> f64 {
    let (b, corner) = grid.cell(g);
    let corners = map8(model.bodies()[b].contact_surface().offsets, |o| {
        at(corner + o)
    });
    let Some((beyond, n)) = beyond_hull(&corners, ps) else {
        return f64::NEG_INFINITY;
    };
    // (With a rounding's room: `locate` takes points outside a cell by a rounding as in it.)
    let rounding = 1e-9 * (ps - corners[0]).length();
    let clear = (beyond - margin - rounding) / (n.x.abs() + n.y.abs() + n.z.abs());
    if clear.is_nan() {
        f64::NEG_INFINITY
    } else {
        clear
    }
}

/// Where Newton's method starts to look for a sample (in the cell at lattice coordinates `own`
/// of its body) in the cell at `cell`: for a cell of its own body (`own_body`) next to its own,
/// where it lay at rest in that cell's coordinates (on a face they share it is there still,
/// unless the body has folded, and Newton's method has nothing to do); else the cell's middle.
#[inline]
fn start_in(own_body: bool, sample: &Sample, own: [usize; 3], cell: [usize; 3]) -> [f64; 3] {
    let rest = [0, 1, 2].map(|k| (own[k] as f64 - cell[k] as f64) + sample.local[k]);
    if own_body && rest.iter().all(|u| (-1.0..=2.0).contains(u)) {
        rest
    } else {
        [0.5; 3]
    }
}

/// True when cells at lattice coordinates `a` and `b` of one body share no corner.
#[inline]
fn share_no_corner(a: [usize; 3], b: [usize; 3]) -> bool {
    a.iter().zip(b).any(|(&a, b)| a.abs_diff(b) > 1)
}

/// How far apart at rest a sample and a point of its own body must lie for self-contact to
/// push them apart, times the body's smallest lattice spacing (see the module's notes). A
/// sample on a face, edge or corner its cell shares with others is found in those at its own
/// point (0 apart); where a body folds, the skin comes through a cell next to it at points up
/// to two cells away. Below a whole cell, so that cells sharing no corner with the sample's
/// (a cell or more away) always count.
const SELF_APART: f64 = 0.5;

/// True when the point at `uvw` of the cell at lattice coordinates `cell` of `body` lay, at
/// rest, more than [`SELF_APART`] from `sample` (of the same body, in the cell at `own`).
#[inline]
fn apart_at_rest(
    body: &Body,
    sample: &Sample,
    own: [usize; 3],
    cell: [usize; 3],
    uvw: [f64; 3],
) -> bool {
    let h = body.lattice().spacing().to_array();
    let apart = (0..3).fold(0.0, |sum, k| {
        let d = ((cell[k] as f64 - own[k] as f64) + (uvw[k] - sample.local[k])) * h[k];
        sum + d * d
    });
    let least = SELF_APART * body.min_spacing();
    apart > least * least
}

/// The force on a sample `depth` (m) inside another body whose outward normal there is `n`,
/// moving at `w` relative to it: `(kc·depth − dc·(w·n))·n` plus Coulomb friction across `n`,
/// of size `μ·kc·depth` but at most `c_max·|w across n|`. `[kc, dc, mu, c_max]`: collision
/// stiffness and damping, friction coefficient and its cap (see [`crate::contact::friction`]).
/// The other body feels exactly the opposite.
#[inline]
pub fn touch_force(n: Vec3, w: Vec3, depth: f64, [kc, dc, mu, c_max]: [f64; 4]) -> Vec3 {
    if depth.is_nan() || depth <= 0.0 {
        return Vec3::ZERO;
    }
    let normal = kc * depth;
    let mut f = n * (normal - dc * w.dot(n));
    if mu > 0.0 {
        f += crate::contact::friction::sliding(n, w, mu * normal, c_max);
    }
    f
}

/// The deepest a sample of one body is inside another (m), and the penalty energy
/// `Σ ½ kCollision depth²` over the samples that touch (J), at positions `pos`: a diagnostic,
/// never part of stepping.
pub fn overlap(model: &Model, pos: &[Vec3]) -> (f64, f64) {
    if !model.surfaces_touch() {
        return (0.0, 0.0);
    }
    let mut contacts = Contacts::new(model);
    let p = Soa::from_aos(pos);
    contacts.compute(model, &p, &Soa::zeros(pos.len()));
    contacts
        .touches
        .iter()
        .fold((0.0f64, 0.0), |(deepest, energy), t| {
            (
                deepest.max(t.depth),
                energy + 0.5 * model.k_collision * t.depth * t.depth,
            )
        })
}

/// How close two bodies' surfaces come (or one body's to itself, under self-contact): a
/// diagnostic, never part of stepping.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Closest {
    /// The bodies (indices into the model's; equal for a body touching itself).
    pub bodies: [usize; 2],
    /// The deepest any sample of one is inside the other (m), or, when none is inside, minus
    /// the smallest gap between them: negative is a gap.
    pub depth: f64,
    /// Where: the sample (a point of the surface of the first body that reveals it, or the middle
    /// of one of its cells) that is deepest, or nearest the other when they are apart (m).
    pub at: Vec3,
}

/// The pairs of bodies at positions `pos` whose surfaces come within a cell of each other (the
/// larger cell of the model), or where the middle of a cell of one is inside the other, each
/// once, in order, with how deep they overlap or how far apart they are (see [`Closest`]);
/// under self-contact, a body inside itself too.
pub fn closest(model: &Model, pos: &[Vec3]) -> Vec<Closest> {
    if !model.surfaces_touch() {
        return Vec::new();
    }
    let cell = model
        .bodies()
        .iter()
        .map(|b| b.min_spacing())
        .fold(0.0, f64::max);
    let mut contacts = Contacts::new(model);
    let mut touches = Vec::new();
    contacts.near(model, &Soa::from_aos(pos), cell, &mut touches);
    let mut pairs: Vec<Closest> = Vec::new();
    for t in &touches {
        let (a, b) = (
            model.locate(t.points[0] as usize).0,
            model.locate(t.points[8] as usize).0,
        );
        // A body near its own far cells is only news when it is inside them.
        if a == b && t.depth <= 0.0 {
            continue;
        }
        let bodies = [a.min(b), a.max(b)];
        // The sample: its own cell's corners (the first eight) weighted.
        let at = (t.points[..8].iter().zip(&t.weights[..8]))
            .fold(Vec3::ZERO, |s, (&p, &w)| s + pos[p as usize] * w);
        let deepest = Closest {
            bodies,
            depth: t.depth,
            at,
        };
        match pairs.iter_mut().find(|c| c.bodies == bodies) {
            Some(c) if c.depth < t.depth => *c = deepest,
            Some(_) => {}
            None => pairs.push(deepest),
        }
    }
    // Bodies sunk into each other further than their surfaces show (one inside the other, or
    // the two in the same place): the middles of each body's cells inside another body, as
    // deep as they are inside both (a cell on the surface has its middle outside its own skin
    // as often as not, and that is no overlap).
    let bodies = model.bodies();
    let grid = &contacts.grid;
    let at = |q: usize| pos[q];
    for (a, body) in bodies.iter().enumerate() {
        let surface = body.contact_surface();
        for &c in &surface.cells {
            let corner = body.points().start + c as usize;
            let middle = surface
                .offsets
                .iter()
                .fold(Vec3::ZERO, |s, &o| s + at(corner + o) * 0.125);
            let own = -surface
                .distance_in(body.lattice().coords(c as usize), [0.5; 3])
                .0;
            if own <= 0.0 {
                continue;
            }
            grid.find_near(middle, Some(a as u32), 0.0, |g| {
                let b = grid.cell_body[g] as usize;
                let other_corner = grid.cell_corner[g] as usize;
                let other = bodies[b].contact_surface();
                let corners = other.offsets.map(|o| at(other_corner + o));
                let Some((uvw, _)) = locate(&corners, middle) else {
                    return false;
                };
                let cell = (bodies[b].lattice()).coords(other_corner - bodies[b].points().start);
                // Deep inside, the distance at rest (its gradient has kinks there).
                let depth = (-other.distance_in(cell, uvw).0).min(own);
                if depth > 0.0 {
                    let pair = [a.min(b), a.max(b)];
                    let deepest = Closest {
                        bodies: pair,
                        depth,
                        at: middle,
                    };
                    match pairs.iter_mut().find(|c| c.bodies == pair) {
                        Some(c) if c.depth < depth => *c = deepest,
                        Some(_) => {}
                        None => pairs.push(deepest),
                    }
                }
                true
            });
        }
    }
    pairs.sort_by_key(|c| c.bodies);
    pairs
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrate::implicit::test_models::values;
    use crate::model::body::{Body, Material, IDENTITY};
    use crate::model::contact_surface::locate_from;
    use crate::model::lattice::Lattice;
    use crate::model::{Aabb, ModelBuilder};
    use crate::state::State;

    /// A model builder for bodies in a box far larger than they are (its walls touch none),
    /// with collision stiffness 400 N/m and damping 0.3.
    fn open_box() -> ModelBuilder {
        ModelBuilder::new()
            .bounds(Aabb::new(Vec3::new(-9.0, -9.0, -9.0), Vec3::new(9.0, 9.0, 9.0)).unwrap())
            .collision(400.0, 0.3)
    }

    /// Every touch by a search over every kept cell of every other body, in the cells' order,
    /// the first cell that holds a sample inside its body's surface deciding (one that holds it
    /// outside passes the search on to the next body), and under self-contact the cells' guard:
    /// the forces the grid's visits must give.
    fn by_every_cell(model: &Model, pos: &[Vec3], vel: &[Vec3]) -> Vec<Vec3> {
        let mut force = vec![Vec3::ZERO; pos.len()];
        let bodies = model.bodies();
        let (kc, dc, mu) = (model.k_collision, model.d_collision, model.friction);
        for (a, body) in bodies.iter().enumerate() {
            let surface = body.contact_surface();
            let first = body.points().start;
            for sample in &surface.samples {
                let wa = weights(sample.local);
                let corners_a = surface.offsets.map(|o| first + sample.corner as usize + o);
                let ps = corners_a
                    .iter()
                    .zip(wa)
                    .fold(Vec3::ZERO, |s, (&q, w)| s + pos[q] * w);
                let va = corners_a
                    .iter()
                    .zip(wa)
                    .fold(Vec3::ZERO, |s, (&q, w)| s + vel[q] * w);
                let own = body.lattice().coords(sample.corner as usize);
                'cells: for (b, other) in bodies.iter().enumerate() {
                    let os = other.contact_surface();
                    for &c in &os.cells {
                        let cell = other.lattice().coords(c as usize);
                        if b == a && !(model.self_contact && cell != own) {
                            continue;
                        }
                        let corner = other.points().start + c as usize;
                        let corners = os.offsets.map(|o| pos[corner + o]);
                        let start = start_in(b == a, sample, own, cell);
                        let Some((uvw, rows)) = locate_from(&corners, ps, start) else {
                            continue;
                        };
                        if b == a && !apart_at_rest(body, sample, own, cell, uvw) {
                            continue;
                        }
                        let (phi, gu) = os.distance_in(cell, uvw);
                        let g = in_space(gu, &rows);
                        if phi < 0.0 && g.length() > 0.0 {
                            let (depth, n) = (-phi / g.length().max(MIN_GRADIENT), g / g.length());
                            let wb = weights(uvw);
                            let vb = (os.offsets.iter().zip(wb))
                                .fold(Vec3::ZERO, |s, (&o, w)| s + vel[corner + o] * w);
                            let (ma, mb) = (body.material.mass, other.material.mass);
                            let c_max = ma * mb / (ma + mb) / model.dt;
                            let f = touch_force(n, va - vb, depth, [kc, dc, mu, c_max]);
                            for (&q, w) in corners_a.iter().zip(wa) {
                                force[q] += f * w;
                            }
                            for (&o, w) in os.offsets.iter().zip(wb) {
                                force[corner + o] -= f * w;
                            }
                            break 'cells;
                        }
                        if b != a {
                            continue 'cells;
                        }
                    }
                }
            }
        }
        // And under self-contact the cells' guard, which the contact pass adds.
        super::super::cell_guard::for_each_squeezed(
            model,
            |p| pos[p],
            |s| s.forces().for_each(|(p, f)| force[p] += f),
        );
        force
    }

    /// Computes the contacts at `pos`, `vel` with `contacts` (its grid as it stands, reused or
    /// sorted again) and asserts each point's force is the search over every cell's; returns
    /// how many points that search pushes. `label` names the case in a failure.
    fn grid_matches_every_cell(
        model: &Model,
        contacts: &mut Contacts,
        pos: &[Vec3],
        vel: &[Vec3],
        label: &str,
    ) -> usize {
        let want = by_every_cell(model, pos, vel);
        contacts.compute(model, &Soa::from_aos(pos), &Soa::from_aos(vel));
        let mut touching = 0;
        for (p, w) in want.iter().enumerate() {
            let g = contacts.forces().get(p);
            assert!(
                (g - *w).max_abs() <= 1e-12 * (1.0 + w.max_abs()),
                "{label}, point {p}: grid {g:?}, every cell {w:?}"
            );
            touching += usize::from(w.max_abs() > 0.0);
        }
        touching
    }

    /// Two boxes far apart thrown at each other, a long way a step while apart (bodies near
    /// none may move up to half their distance before the grid is sorted again), then pressed
    /// into each other: the reused grid finds every touch the search over every cell finds.
    #[test]
    fn bodies_thrown_from_afar_are_found_when_they_meet() {
        let lattice = Lattice::new([4, 4, 4], Vec3::new(0.3, 0.3, 0.3));
        let bodies = [-1.5, 1.5].map(|x| {
            Body::lattice_box(lattice.clone(), Material::classic())
                .placed(Vec3::new(x, 0.05 * x, 0.0), IDENTITY)
        });
        let model = open_box().bodies(bodies.to_vec()).build().unwrap();
        let mut pos = State::at_rest(&model).pos;
        let vel = vec![Vec3::ZERO; pos.len()];
        let mut contacts = Contacts::new(&model);
        let (mut touching, mut rounds) = (0, 0);
        // Each round, each body moves 0.3 of the way to the other's middle.
        while rounds < 40 {
            let middle = |b: usize| {
                let points = model.bodies()[b].points();
                let n = points.len() as f64;
                points.fold(Vec3::ZERO, |s, q| s + pos[q]) * (1.0 / n)
            };
            let (a, b) = (middle(0), middle(1));
            let step = ((b - a) * 0.3)
                .max(Vec3::new(0.02, -0.02, -0.02))
                .min(Vec3::new(9.0, 9.0, 9.0));
            // The first at full speed, the other slower: their reaches differ.
            for (body, d) in model.bodies().iter().zip([step * 1.6, step * -0.4]) {
                for q in body.points() {
                    pos[q] += d;
                }
            }
            touching += grid_matches_every_cell(
                &model,
                &mut contacts,
                &pos,
                &vel,
                &format!("round {rounds}"),
            );
            rounds += 1;
        }
        assert!(touching > 100, "only {touching} points pushed");
        assert!(
            contacts.grid.sorts() < rounds,
            "{} sorts in {rounds} rounds",
            contacts.grid.sorts()
        );
    }

    /// A small cube inside a third body's corner where that body's cage reaches past its skin
    /// (an octahedron's box of cells) and inside a cube there: it touches the cube, and the
    /// octahedron not at all. (The first cell to hold a sample decided whatever the distance
    /// there, so a cage's corner hid the cube.)
    #[test]
    fn a_sample_outside_one_skin_inside_its_cage_still_touches_a_body_there() {
        let (vertices, triangles) = crate::model::test_meshes::octahedron(Vec3::ZERO, 0.3);
        // Two cells a side: the cage is the box [−0.3, 0.3]³; its corner (0.3, 0.3, 0.3) is
        // 0.35 m from the skin (the face x + y + z = 0.3).
        let octahedron =
            Body::from_mesh(&vertices, &triangles, 2, 1000, Material::classic()).unwrap();
        let cube = |n: usize, side: f64, at: f64| {
            Body::lattice_box(
                Lattice::new([n; 3], Vec3::new(side, side, side)),
                Material::classic(),
            )
            .placed(Vec3::new(at, at, at), IDENTITY)
        };
        // The small cube [0.2, 0.25]³ inside the cube [0.15, 0.35]³, both in the octahedron's
        // corner cell [0, 0.3]³ and outside its skin.
        let model = ModelBuilder::new()
            .bodies(vec![cube(2, 0.05, 0.2), octahedron, cube(3, 0.2, 0.15)])
            .collision(400.0, 0.3)
            .build()
            .unwrap();
        let pos = State::at_rest(&model).pos;
        let vel = vec![Vec3::ZERO; pos.len()];
        let mut contacts = Contacts::new(&model);
        grid_matches_every_cell(&model, &mut contacts, &pos, &vel, "cube in a corner");
        let forces = contacts.forces();
        let on = |b: usize| (model.bodies()[b].points()).fold(Vec3::ZERO, |s, q| s + forces.get(q));
        // The small cube is 5 to 10 cm inside the big one, nearer its faces at 0.15: pushed out
        // toward them, with the opposite force on the big cube.
        let push = on(0);
        assert!(
            push.x < -10.0 && push.y < -10.0 && push.z < -10.0,
            "{push:?}"
        );
        assert!((on(0) + on(2)).max_abs() < 1e-9, "{:?} {:?}", on(0), on(2));
        assert_eq!(on(1), Vec3::ZERO);
    }

    /// A small cube moved a millimetre at a time from inside an octahedron's corner cell, outside
    /// its skin, through the skin: while outside, the passes skip the octahedron (the sample is
    /// known to be outside it), and every pass still finds every touch the search over every
    /// cell finds, from the round it crosses the skin.
    #[test]
    fn a_body_coming_through_a_cage_to_a_skin_is_found_as_it_touches() {
        let (vertices, triangles) = crate::model::test_meshes::octahedron(Vec3::ZERO, 0.3);
        let octahedron =
            Body::from_mesh(&vertices, &triangles, 2, 1000, Material::classic()).unwrap();
        let cube = Body::lattice_box(
            Lattice::new([2; 3], Vec3::new(0.05, 0.05, 0.05)),
            Material::classic(),
        )
        .placed(Vec3::new(0.2, 0.2, 0.2), IDENTITY);
        let model = ModelBuilder::new()
            .bodies(vec![octahedron, cube])
            .collision(400.0, 0.3)
            .build()
            .unwrap();
        let mut pos = State::at_rest(&model).pos;
        let vel = vec![Vec3::ZERO; pos.len()];
        let mut contacts = Contacts::new(&model);
        let (mut touching, mut first) = (0, None);
        for round in 0..150 {
            for q in model.bodies()[1].points() {
                pos[q] -= Vec3::new(0.001, 0.001, 0.001);
            }
            let pushed = grid_matches_every_cell(
                &model,
                &mut contacts,
                &pos,
                &vel,
                &format!("round {round}"),
            );
            if pushed > 0 && first.is_none() {
                first = Some(round);
            }
            touching += pushed;
        }
        // The cube's nearest corner, at x + y + z = 0.6 − 0.003·round, reaches the skin
        // (x + y + z = 0.3) at round 100; the sort was reused in between.
        assert!(first.is_some_and(|r| (95..=101).contains(&r)), "{first:?}");
        assert!(touching > 100, "only {touching} points pushed");
        assert!(
            contacts.grid.sorts() < 100,
            "{} sorts",
            contacts.grid.sorts()
        );
    }

    /// Two bodies still, pressed into each other, and a third coming at them: a point of the
    /// still ones that may touch both the other still one and the one coming is placed as the
    /// one coming moves (were it to wait on the still pair's path, the touches as it comes would
    /// be missed), and the grid finds every touch the search over every cell finds.
    #[test]
    fn a_point_near_a_still_body_and_a_coming_one_wakes_as_the_one_coming_moves() {
        let mut next = values(5);
        let mut touching = 0;
        for scene in 0..30 {
            let bodies: Vec<Body> = (0..3)
                .map(|b| {
                    let lattice = Lattice::new([4, 4, 4], Vec3::new(0.3, 0.3, 0.3));
                    let at = match b {
                        0 => Vec3::ZERO,
                        1 => Vec3::new(0.28, next() * 0.1, next() * 0.1),
                        _ => Vec3::new(0.2 + next() * 0.1, 0.45, next() * 0.1),
                    };
                    Body::lattice_box(lattice, Material::classic()).placed(at, IDENTITY)
                })
                .collect();
            let model = open_box().bodies(bodies).friction(0.5).build().unwrap();
            let mut pos = State::at_rest(&model).pos;
            let vel: Vec<Vec3> = pos
                .iter()
                .map(|_| Vec3::new(next(), next(), next()))
                .collect();
            let mut contacts = Contacts::new(&model);
            // The third comes at the others along y, a little faster each scene.
            let step = Vec3::new(0.0, -0.002 * (1.0 + (scene % 3) as f64), 0.0);
            for round in 0..40 {
                for q in model.bodies()[2].points() {
                    pos[q] += step;
                }
                touching += grid_matches_every_cell(
                    &model,
                    &mut contacts,
                    &pos,
                    &vel,
                    &format!("scene {scene}, round {round}"),
                );
            }
        }
        assert!(touching > 1000, "only {touching} points pushed");
    }

    /// Heaps of 3 to 5 bodies, boxes and lattices with holes of different spacings, deformed
    /// and moving at random, some with self-contact: the grid finds every touch the search over
    /// every cell finds, sorted afresh or reused after small moves.
    #[test]
    fn the_grid_finds_what_a_search_over_every_cell_finds() {
        const ROUNDS: usize = 20;
        const STEP: f64 = 0.003;
        let (mut next, mut touching, mut sorts) = (values(17), 0, 0);
        for scene in 0..30 {
            let bodies: Vec<Body> = (0..3 + scene % 3)
                .map(|b| {
                    let counts = [0; 3].map(|_| 3 + ((next() + 1.0) * 1.5) as usize);
                    let h = 0.1 + 0.05 * (next() + 1.0);
                    let size = Vec3::new(
                        h * (counts[0] - 1) as f64,
                        h * (counts[1] - 1) as f64,
                        h * (counts[2] - 1) as f64,
                    );
                    let lattice = Lattice::new(counts, size);
                    let at = Vec3::new(next(), next(), next()) * 0.3;
                    let body = if b % 2 == 1 {
                        let cells = (counts[0] - 1) * (counts[1] - 1) * (counts[2] - 1);
                        let mut kept: Vec<bool> = (0..cells).map(|_| next() > -0.5).collect();
                        kept[0] = true;
                        Body::from_cells(lattice, kept, Material::classic()).unwrap()
                    } else {
                        Body::lattice_box(lattice, Material::classic())
                    };
                    body.placed(at, IDENTITY)
                })
                .collect();
            let model = open_box()
                .bodies(bodies)
                .friction(if scene % 2 == 0 { 0.5 } else { 0.0 })
                .self_contact(scene % 3 == 1)
                .build()
                .unwrap();
            let mut pos = State::at_rest(&model).pos;
            // Every third scene with self-contact, its bodies crumpled so that they meet
            // themselves.
            let shake = if scene % 3 == 1 { 0.12 } else { 0.02 };
            for p in &mut pos {
                *p += Vec3::new(next(), next(), next()) * shake;
            }
            let vel: Vec<Vec3> = pos
                .iter()
                .map(|_| Vec3::new(next(), next(), next()))
                .collect();
            // Then moved a little at a time, each body along a step of its own (up to 0.005 to
            // 0.015 along each axis, by body, so that their reaches differ) and each point
            // jiggled a little, so that the grid (whose reaches are 0.03 to 0.2 of the largest
            // cell, 0.003 to 0.04 here) is now reused, now sorted again.
            let mut contacts = Contacts::new(&model);
            for round in 0..ROUNDS {
                for (b, body) in model.bodies().iter().enumerate() {
                    let step = Vec3::new(next(), next(), next()) * (STEP * (1 + b % 3) as f64);
                    for q in body.points() {
                        pos[q] += step + Vec3::new(next(), next(), next()) * 0.001;
                    }
                }
                touching += grid_matches_every_cell(
                    &model,
                    &mut contacts,
                    &pos,
                    &vel,
                    &format!("scene {scene}, round {round}"),
                );
            }
            sorts += contacts.grid.sorts();
        }
        assert!(touching > 1800, "only {touching} points pushed");
        // Some rounds reused a sort, some sorted again.
        assert!(
            (100..=500).contains(&sorts),
            "{sorts} sorts in {} rounds",
            30 * ROUNDS
        );
    }
}
