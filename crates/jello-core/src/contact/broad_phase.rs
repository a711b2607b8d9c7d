//! The broad phase of contacts between bodies, in two levels. First each body's box (of its
//! points as they are now) and which bodies' boxes meet: a body near no other is passed over
//! whole, and a surface point outside every neighbour's box is not looked up. Then the kept
//! cells that meet a neighbour's box, as they are deformed now, sorted into a hashed uniform grid
//! by the grid cells their bounding boxes overlap (a counting sort on the team's threads, each
//! bucket in the order of the bodies and their cells), so that a point finds the few cells it
//! may be inside by looking in its own grid cell. Buffers are sized once (and grow only for a
//! cell stretched over more grid cells than was room for); the sort and the visits run in a
//! fixed order, so the forces summed over them are bit for bit the same whatever the thread
//! count.
//!
//! **Reuse.** A sort is kept while no point of a body `b` has moved further than its reach
//! `d_b` along any axis since it (`BroadPhase::refresh`). A cell of body `B` is sorted with its
//! box grown by `d_B`, and a point of body `A` is looked up in it grown by `d_A` more. (A body
//! near no other may move `d_b` and half its distance to the nearest: two bodies apart stay
//! apart while neither moves further, so bodies falling free do not sort the rest.) Then a
//! surface point of `A` that is in a cell of `B` now was, at the sort, in that cell's box grown
//! by `d_A + d_B` (it moved at most `d_A`, the cell's corners at most `d_B`). So the contact
//! pass lists, at each sort, the surface points that are in some box and the cells whose boxes
//! they are in, and until the next sort looks only at those (see [`crate::contact::bodies`]): a
//! step's stages and the next few steps share one sort and one list.
//!
//! Each body's reach is set at each sort from how far it moved since the one before: 3 % of the
//! longest cell side for a body at rest or slow, up to 20 % for a body moving fast, which would
//! otherwise call for a sort every step or two while the rest of a pile lies still. Larger
//! boxes cost visits only for the pairs of bodies the fast ones are in.
//!
//! A cell's box is far larger than the cell when the cell is turned or sheared, so the listing
//! also keeps, with each cell, how far the point was beyond the hull of the cell's corners at
//! the sort (along the line from their middle), and each contact pass skips the cell while the
//! point and the cell's body have not moved, together, far enough to close that distance
//! (`NearCell::clear`, each body's `moved` since the sort).
//!
//! Each refresh also adds to each body's *path* how far its points and those of the bodies it
//! may touch moved (each along any axis) since the refresh before: a point of the body and a
//! point of a neighbour have moved, together, no further since any earlier refresh than the
//! path grew since (the triangle inequality, pass after pass). A surface point found clear of
//! every cell by some distance is passed over until the path has grown that far (see
//! [`crate::contact::bodies`]): in a pile that still stirs, each pass moves the bodies a few
//! micrometres, while their points have moved since the sort nearly as far as their reach.
//! Each body's own part of it (the sum of its steps, its *travel*) is kept too: a point of `a`
//! and one of `b` have moved, together, no further than the growth of the two travels. A point
//! whose cells are all of one body waits on that: its body's path adds the largest step of
//! every neighbour, and the fastest of them, falling onto a pile, may be far from it.
//!
//! The cells looked at for a point are a superset of those a fresh sort gives that may hold it,
//! in the same order, and a point's contact is decided by the first of them (in that order)
//! that holds it: the forces do not depend on when the grid was sorted.

use crate::model::contact_surface::map3;
use crate::model::Model;
use crate::vec3::Vec3;

/// Room for this many grid cells per cell, on average, before the buffers grow.
const ROOM_PER_CELL: usize = 8;

/// The most grid cells along an axis one cell may overlap: a cell stretched further is torn.
const MAX_SPAN: i32 = 16;

/// The least reach of a body (how far its points may move before the sort is redone), as a
/// fraction of the longest side of the bodies' cells: that of a body at rest. A larger reach
/// sorts less often but visits more cells. On fifty shapes of 8–12 cells dropped into a box
/// (AMD EPYC, 1 thread, `perf`), one reach of 0.1 for every body (0.05 and 0.2 were 10–15 %
/// slower in contact) against reaches from 0.03 to 0.2 growing 1.5 times, together with the
/// cheaper [`crate::model::contact_surface`] placing: contact 49.5 → 42.4 % of a step as the
/// shapes settle (2.5–2.6 s), 44.5 → 42.3 % as they fall (0.5–0.6 s).
const MIN_REACH: f64 = 0.03;

/// The most reach of a body, as a fraction of the longest cell side.
const MAX_REACH: f64 = 0.2;

/// A body's reach at a sort, times how far it moved since the sort before (within
/// [`MIN_REACH`]`..`[`MAX_REACH`]): one that set off the sort reaches further the next time.
const REACH_PER_MOVE: f64 = 1.5;

/// The side of a grid cell, times the longest side of the bodies' cells: so that a cell's box,
/// grown by the reaches, overlaps two grid cells along an axis, seldom three.
const GRID: f64 = 1.5;

/// The cells of a model's bodies in a hashed uniform grid.
#[derive(Clone, Debug, Default)]
pub(crate) struct BroadPhase {
    /// Per cell (all bodies', in order): its body and the flat model index of its lower corner.
    pub cell_body: Vec<u32>,
    pub cell_corner: Vec<u32>,
    /// Per cell: the grid cells it overlaps and its bounding box at the last sort, grown by its
    /// body's reach and the margin (none, and empty, for a cell no other surface can reach).
    placed: Vec<([[i32; 3]; 2], [Vec3; 2])>,
    /// Bucket starts of the hashed grid (`buckets + 1` entries).
    starts: Vec<u32>,
    /// The sort's counts per bucket, a row for each thread's run of cells (a buffer).
    counts: Vec<u32>,
    /// Cells sorted by bucket (as indices of `cell_body`), with the grid cell each entry is for.
    entries: Vec<(u32, [i32; 3])>,
    /// Each entry's cell's body, beside it, so that a body's own cells are passed over unread.
    entry_bodies: Vec<u32>,
    /// Side of a grid cell (m).
    side: f64,
    /// The longest side of the bodies' cells (m).
    cell: f64,
    /// Per body: the box of its points at the last sort (grown by the margin, its reach and
    /// the largest reach), and the bodies whose boxes meet it (each list sorted; itself too under
    /// self-contact).
    body_boxes: Vec<[Vec3; 2]>,
    neighbours: Vec<Vec<u32>>,
    /// The points' positions at the last sort and the margin its boxes were grown by (none
    /// before the first sort).
    sorted_at: [Vec<f64>; 3],
    sorted_margin: Option<f64>,
    /// How many sorts there have been.
    sorts: usize,
    /// Per body: its reach (m; see the module's notes) at the last sort, and the largest reach of
    /// the bodies whose samples may be in its cells.
    reach: Vec<f64>,
    farthest: Vec<f64>,
    /// Per body: how far (along any axis) each of its points may move before the grid is
    /// sorted again (its reach, or more for a body near no other).
    allowed: Vec<f64>,
    /// Per body: how far its points have moved, as of the last [`BroadPhase::refresh`].
    moves: Vec<Moves>,
    /// The points' positions at the last [`BroadPhase::refresh`].
    refreshed_at: [Vec<f64>; 3],
    /// Per body `a`: the sum, over the refreshes, of how far its points and those of the bodies
    /// its samples may touch moved from one to the next (`a`'s step and the largest of its
    /// neighbours'). A point of `a` and a point of a neighbour have moved, together, at most the
    /// growth of this since any earlier refresh of the same sort: see [`BroadPhase::path`].
    path: Vec<f64>,
    /// Per body: the sum, over the refreshes, of how far its points moved from one to the
    /// next (its own part of the paths): a point of `a` and a point of `b` have moved, together,
    /// at most the growth of `travel[a] + travel[b]` since any earlier refresh of the same sort.
    travel: Vec<f64>,
}

impl BroadPhase {
    /// Buffers for the cells of `model`'s bodies, in a grid of cells the size of the largest
    /// cell's longest side.
    pub(crate) fn new(model: &Model) -> Self {
        let (mut cell_body, mut cell_corner) = (Vec::new(), Vec::new());
        let mut side: f64 = 0.0;
        for (b, body) in model.bodies().iter().enumerate() {
            let surface = body.contact_surface();
            let first = body.points().start as u32;
            for &c in &surface.cells {
                cell_body.push(b as u32);
                cell_corner.push(first + c);
            }
            let h = body.lattice().spacing();
            side = side.max(h.x).max(h.y).max(h.z);
        }
        let cells = cell_body.len();
        let buckets = (2 * cells).next_power_of_two();
        BroadPhase {
            cell_body,
            cell_corner,
            placed: vec![([[0; 3], [-1; 3]], EMPTY); cells],
            starts: vec![0; buckets + 1],
            counts: Vec::new(),
            entries: Vec::with_capacity(ROOM_PER_CELL * cells),
            entry_bodies: Vec::with_capacity(ROOM_PER_CELL * cells),
            cell: if side > 0.0 { side } else { 1.0 },
            side: if side > 0.0 { GRID * side } else { 1.0 },
            body_boxes: vec![EMPTY; model.bodies().len()],
            neighbours: model
                .bodies()
                .iter()
                .map(|_| Vec::with_capacity(model.bodies().len()))
                .collect(),
            sorted_at: [0; 3].map(|_| vec![0.0; model.point_count()]),
            sorted_margin: None,
            sorts: 0,
            reach: vec![0.0; model.bodies().len()],
            farthest: vec![0.0; model.bodies().len()],
            allowed: vec![0.0; model.bodies().len()],
            moves: vec![Moves::default(); model.bodies().len()],
            refreshed_at: [0; 3].map(|_| vec![0.0; model.point_count()]),
            path: vec![0.0; model.bodies().len()],
            travel: vec![0.0; model.bodies().len()],
        }
    }

    /// Makes the grid hold, for positions `p`, every cell whose box grown by `margin` (m) may
    /// hold a point, and every such cell whose box at the last sort may have held it then (see
    /// the module's notes): sorts again, with boxes grown by `margin` and the bodies' reaches,
    /// unless every point has moved less than its body may along every axis since the last sort
    /// (that sort's margin at least `margin`). True when it sorted.
    pub(crate) fn refresh(&mut self, model: &Model, p: [&[f64]; 3], margin: f64) -> bool {
        let sorted = self.refresh_grid(model, p, margin);
        // Each body's path grows by its step and the largest of its neighbours' (as they are
        // after a sort: the paths are compared only within a sort). A step that is not a number
        // (positions, now or at the last refresh, that are not) adds nothing: it sorted the grid
        // (the points moved from the sort's positions by as much), which forgets every path.
        for (a, path) in self.path.iter_mut().enumerate() {
            let stepped = |b: usize| self.moves[b].since_refresh;
            let near =
                (self.neighbours[a].iter()).fold(0.0, |m: f64, &b| m.max(stepped(b as usize)));
            let step = stepped(a) + near;
            if step.is_finite() {
                *path += step;
                self.travel[a] += stepped(a);
            }
        }
        sorted
    }

    /// [`BroadPhase::refresh`] but the paths' growth (each body's step is found here, and the
    /// positions kept for the next).
    fn refresh_grid(&mut self, model: &Model, p: [&[f64]; 3], margin: f64) -> bool {
        let bodies = model.bodies();
        let refreshed = self.sorted_margin.is_some();
        // Each body's points' moves, and their positions kept, in one pass on the team (a
        // serial copy of every position after was a tenth of a pass on 2 threads).
        let at = &self.sorted_at;
        let [x, y, z] = self.refreshed_at.each_mut().map(|c| &mut c[..]);
        crate::compute::team::for_each_mut_with_runs(
            &mut self.moves,
            [x, y, z],
            &|b| bodies[b].points(),
            &|b, moves, mut kept| {
                let found = moves_and_keep(p, at, &mut kept, bodies[b].points());
                *moves = if refreshed { found } else { Moves::default() };
            },
        );
        match self.sorted_margin {
            Some(sorted)
                if sorted >= margin
                    && (self.moves.iter().zip(&self.allowed))
                        .all(|(moves, &allowed)| moves.since_sort <= allowed) =>
            {
                return false
            }
            // The reaches from how far each body moved since the last sort.
            Some(_) => {
                for (moves, reach) in self.moves.iter().zip(&mut self.reach) {
                    *reach = (REACH_PER_MOVE * moves.since_sort)
                        .min(MAX_REACH * self.cell)
                        .max(MIN_REACH * self.cell);
                }
            }
            None => self.reach.fill(MIN_REACH * self.cell),
        }
        for moves in &mut self.moves {
            moves.since_sort = 0.0;
        }
        self.sort(model, p, margin);
        for (at, now) in self.sorted_at.iter_mut().zip(p) {
            at.copy_from_slice(now);
        }
        // A body near others may move its reach; one near none, half its distance to the
        // nearest more: two bodies apart stay apart while neither moves further.
        for (a, allowed) in self.allowed.iter_mut().enumerate() {
            *allowed = if self.neighbours[a].is_empty() {
                let gap = (0..self.body_boxes.len())
                    .filter(|&b| b != a)
                    .map(|b| separation(self.body_boxes[a], self.body_boxes[b]))
                    .fold(f64::INFINITY, f64::min);
                self.reach[a] + 0.5 * gap
            } else {
                self.reach[a]
            };
        }
        self.sorted_margin = Some(margin);
        self.sorts += 1;
        true
    }

    /// Sorts the cells, at positions `[px, py, pz]`, into the grid: those of them that may hold
    /// a sample of another body (or of their own under self-contact), as the bodies' boxes
    /// tell, each with its box grown by `margin` (m) and its body's reach, entered in the grid
    /// cells that box overlaps grown by the largest reach of the bodies whose samples may come.
    fn sort(&mut self, model: &Model, [px, py, pz]: [&[f64]; 3], margin: f64) {
        let inv = 1.0 / self.side;
        let grid = |c: Vec3| map3((c * inv).to_array(), floor_i32);
        let mask = self.starts.len() - 2;
        let bodies = model.bodies();
        let even = |d: f64| Vec3::new(d, d, d);
        // Each body's box (of all its points, so that it holds its cells' boxes), grown by its
        // reach and the largest (a point of any body that may come into its cells is in it),
        // and which bodies' boxes meet.
        let largest = self.reach.iter().fold(0.0, |m: f64, &r| m.max(r));
        for ((body, bounds), &reach) in bodies.iter().zip(&mut self.body_boxes).zip(&self.reach) {
            *bounds = EMPTY;
            let [lo, hi] = bounds;
            for q in body.points() {
                let p = Vec3::new(px[q], py[q], pz[q]);
                (*lo, *hi) = (lo.min(p), hi.max(p));
            }
            let grow = even(margin + reach + largest);
            (*lo, *hi) = (*lo - grow, *hi + grow);
        }
        for (a, list) in self.neighbours.iter_mut().enumerate() {
            list.clear();
            for b in 0..bodies.len() {
                if (b != a || model.self_contact) && meets(self.body_boxes[a], self.body_boxes[b]) {
                    list.push(b as u32);
                }
            }
        }
        // Per body: the largest reach of the bodies whose samples may be in its cells.
        for (farthest, list) in self.farthest.iter_mut().zip(&self.neighbours) {
            *farthest = (list.iter()).fold(0.0, |m: f64, &a| m.max(self.reach[a as usize]));
        }
        let (cell_body, cell_corner) = (&self.cell_body, &self.cell_corner);
        let (neighbours, body_boxes, reach) = (&self.neighbours, &self.body_boxes, &self.reach);
        let farthest = &self.farthest;
        // Each cell's box and span (on the team's threads: cells are independent), only for
        // cells that meet a box a sample may come from.
        let size = crate::compute::team::chunk_size(cell_body.len(), 512);
        let place = |g: usize| -> Option<([[i32; 3]; 2], [Vec3; 2])> {
            let b = cell_body[g] as usize;
            // The bodies whose samples may be in body b's cells are its neighbours too.
            if neighbours[b].is_empty() {
                return None;
            }
            let (mut lo, mut hi) = (EMPTY[0], EMPTY[1]);
            for &o in &bodies[b].contact_surface().offsets {
                let q = cell_corner[g] as usize + o;
                let p = Vec3::new(px[q], py[q], pz[q]);
                (lo, hi) = (lo.min(p), hi.max(p));
            }
            let grow = even(margin + reach[b]);
            let (lo, hi) = (lo - grow, hi + grow);
            let span = [grid(lo - even(farthest[b])), grid(hi + even(farthest[b]))];
            // A cell torn across the box (a step blowing up, which the step then rejects) is
            // left out rather than entered in thousands of buckets.
            if !(lo.is_finite() && hi.is_finite())
                || (0..3).any(|a| span[1][a] - span[0][a] > MAX_SPAN)
            {
                return None;
            }
            let cell = [lo, hi];
            (neighbours[b].iter())
                .any(|&a| meets(cell, body_boxes[a as usize]))
                .then_some((span, cell))
        };
        crate::compute::team::for_each_chunk([&mut self.placed[..]], size, &|i, [part]| {
            for (k, placed) in part.iter_mut().enumerate() {
                *placed = place(i * size + k).unwrap_or(([[0; 3], [-1; 3]], EMPTY));
            }
        });
        // Each cell into the buckets of its span, in order, on the team; each entry's body
        // beside it.
        let cells = CellKeys {
            placed: &self.placed,
            mask,
        };
        crate::compute::team::bucket_sort(
            self.placed.len(),
            &cells,
            &mut self.starts,
            &mut self.counts,
            &mut self.entries,
        );
        self.entry_bodies.resize(self.entries.len(), 0);
        let (entries, cell_body) = (&self.entries, &self.cell_body);
        let size = crate::compute::team::chunk_size(entries.len(), 4096);
        crate::compute::team::for_each_chunk([&mut self.entry_bodies[..]], size, &|i, [part]| {
            for (k, body) in part.iter_mut().enumerate() {
                *body = cell_body[entries[i * size + k].0 as usize];
            }
        });
    }

    /// How many times the grid has been sorted.
    #[cfg(test)]
    pub(crate) fn sorts(&self) -> usize {
        self.sorts
    }

    /// Cell `g`'s body and the flat model index of its lower corner.
    #[inline]
    pub(crate) fn cell(&self, g: usize) -> (usize, usize) {
        (self.cell_body[g] as usize, self.cell_corner[g] as usize)
    }

    /// Cell `g` with its box (grown) at the last sort, grown by `reach` (m) more (that of the
    /// body of the point that may come), and how far its points and the point must move
    /// together before they may meet (`clear`, m: see [`NearCell`]), to keep in a list of cells
    /// a point may be in until the next sort (see `visit`).
    #[inline]
    pub(crate) fn near_cell(&self, g: usize, reach: f64, clear: f64) -> NearCell {
        let [lo, hi] = self.placed[g].1;
        let grow = Vec3::new(reach, reach, reach);
        NearCell {
            cell: g as u32,
            body: self.cell_body[g],
            clear,
            bounds: [lo - grow, hi + grow],
        }
    }

    /// How far (along any axis) body `b`'s points have moved since the last sort, at most (as
    /// of the last [`BroadPhase::refresh`]).
    #[inline]
    pub(crate) fn moved(&self, b: usize) -> f64 {
        self.moves[b].since_sort
    }

    /// Body `a`'s path (m; see the module's notes) as of the last [`BroadPhase::refresh`]: a
    /// point of `a` and a point of a body its samples may touch (itself too under self-contact)
    /// have moved, together (each along any axis), from where they were at an earlier refresh
    /// since the last sort, at most the growth of `a`'s path since then.
    #[inline]
    pub(crate) fn path(&self, a: usize) -> f64 {
        self.path[a]
    }

    /// The path of bodies `a` and `b` together (m) as of the last [`BroadPhase::refresh`]: a
    /// point of `a` and a point of `b` have moved, together (each along any axis), from where
    /// they were at an earlier refresh since the last sort, at most its growth since then. It
    /// grows no faster than `a`'s path where `b` is one of `a`'s neighbours, and slower where a
    /// faster body is.
    #[inline]
    pub(crate) fn pair_path(&self, a: usize, b: usize) -> f64 {
        self.travel[a] + self.travel[b]
    }

    /// Body `a`'s reach at the last sort (m; see the module's notes).
    #[inline]
    pub(crate) fn reach(&self, a: usize) -> f64 {
        self.reach[a]
    }

    /// The bodies whose box (of their points, grown) at the last sort meets body `a`'s (itself
    /// too under self-contact), in order: the only ones its samples may touch, and the only
    /// ones whose samples may be in its cells.
    pub(crate) fn neighbours(&self, a: usize) -> &[u32] {
        &self.neighbours[a]
    }

    /// True when `p` is inside body `b`'s box at the last sort (see [`Self::neighbours`]).
    #[inline]
    pub(crate) fn in_body_box(&self, b: usize, p: Vec3) -> bool {
        let [lo, hi] = self.body_boxes[b];
        p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y && p.z >= lo.z && p.z <= hi.z
    }

    /// Calls `near(cell)` for every cell whose box (grown) at the last sort, grown by `reach`
    /// (m) more, holds `p`, in a fixed order (the cells' order), until it returns true; cells of
    /// body `skip` are passed over. `reach` is at most that of a body whose samples may come
    /// into the cells looked for (the grid holds each cell that far around its box).
    #[inline]
    pub(crate) fn find_near(
        &self,
        p: Vec3,
        skip: Option<u32>,
        reach: f64,
        mut near: impl FnMut(usize) -> bool,
    ) {
        let key = map3((p * (1.0 / self.side)).to_array(), floor_i32);
        let bucket = hash(key) & (self.starts.len() - 2);
        let (start, end) = (
            self.starts[bucket] as usize,
            self.starts[bucket + 1] as usize,
        );
        // A bucket's entries are in the cells' order, so by body: those of `skip` (a point's own
        // body's cells, most of a bucket about it) are one run, passed over unread.
        let (first, last) = match skip {
            Some(skip) => {
                let bodies = &self.entry_bodies[start..end];
                let from = bodies.partition_point(|&b| b < skip);
                (
                    start + from,
                    start + from + bodies[from..].partition_point(|&b| b == skip),
                )
            }
            None => (end, end),
        };
        // The boxes grown by `reach` hold `p` where they meet the box around `p` of that size.
        let (p_lo, p_hi) = (
            p - Vec3::new(reach, reach, reach),
            p + Vec3::new(reach, reach, reach),
        );
        for e in (start..first).chain(last..end) {
            let (g, k) = self.entries[e];
            let [lo, hi] = self.placed[g as usize].1;
            let inside = p_hi.x >= lo.x && p_lo.x <= hi.x && p_hi.y >= lo.y && p_lo.y <= hi.y;
            if k != key || !(inside && p_hi.z >= lo.z && p_lo.z <= hi.z) {
                continue;
            }
            if near(g as usize) {
                return;
            }
        }
    }
}

/// A cell of the broad phase (its index and its body) and its box (grown) at the last sort,
/// with how far a point that may come into it was from it then: `clear` (m) is the most the
/// point and the cell's points may have moved since, together (each along any axis), while it
/// still cannot be in it (nor within the margin of the sort: see `contact::bodies`).
#[derive(Clone, Copy, Debug)]
pub(crate) struct NearCell {
    pub cell: u32,
    pub body: u32,
    pub clear: f64,
    pub bounds: [Vec3; 2],
}

/// Calls `near(k, cell)` for each of `cells` (`k` its place in them) that may hold `p`, in
/// order, until it returns true:
/// those whose point and cell have moved since the sort further than the cell was clear of the
/// point (`moved` of the point's body, and `grid`'s of each cell's), and whose box (grown) at
/// the sort holds `p`. The boxes are kept beside the cells so that the lists are read in order.
///
/// Returns, for the cells it passed over itself, how far the point and the cells' bodies may
/// move more since the sort, together, each along any axis, while each of those cells is
/// still passed over: the least of their `clear`, and of how far `p` is outside the boxes that
/// do not hold it less `moved` (the point may have moved that far since the sort already, and
/// as far again); and how far they may move more from where they are now: the least of their
/// `clear` less how far they may have moved since the sort, and of how far `p` is outside the
/// boxes. Negative infinity (both) when `near` returned true.
#[inline]
pub(crate) fn visit(
    grid: &BroadPhase,
    cells: &[NearCell],
    p: Vec3,
    moved: f64,
    mut near: impl FnMut(usize, usize) -> bool,
) -> [f64; 2] {
    let (mut quiet, mut room) = (f64::INFINITY, f64::INFINITY);
    for (k, c) in cells.iter().enumerate() {
        let since = moved + grid.moved(c.body as usize);
        if c.clear > since {
            quiet = quiet.min(c.clear);
            room = room.min(c.clear - since);
            continue;
        }
        let [lo, hi] = c.bounds;
        let inside = p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y;
        if inside && p.z >= lo.z && p.z <= hi.z {
            if near(k, c.cell as usize) {
                return [f64::NEG_INFINITY; 2];
            }
        } else if p.x.is_nan() || p.y.is_nan() || p.z.is_nan() {
            (quiet, room) = (f64::NEG_INFINITY, f64::NEG_INFINITY);
        } else {
            let out = (lo - p).max(p - hi);
            let out = out.x.max(out.y).max(out.z);
            quiet = quiet.min(out - moved);
            room = room.min(out);
        }
    }
    [quiet, room]
}

crate::compute::simd::multiversion! {
    /// How far (along any axis) the farthest of `points` is at `p` from where it was at `at`,
    /// and from where it was in `kept` (each infinite when a position is not a number); `kept`
    /// (one position per point of `points`) is then set to `p`. Branch-free in lanes, so that
    /// it vectorises: a maximum taken point after point waits on the one before, and a
    /// not-a-number test per point kept it scalar (a twentieth of the fifty shapes' run on one
    /// thread went here). The largest is the same whatever the order; a NaN, which `d > most`
    /// passes over, shows in the lanes' sums of the moves instead.
    fn moves_and_keep(
        p: [&[f64]; 3],
        at: &[Vec<f64>; 3],
        kept: &mut [&mut [f64]; 3],
        points: std::ops::Range<usize>,
    ) -> Moves {
        const LANES: usize = 8;
        type Lanes = [f64; LANES];
        // The largest move and the sum of the moves in each lane, since the sort and since the
        // last refresh.
        let ([mut most0, mut most1], [mut sum0, mut sum1]) = ([[0.0; LANES]; 2], [[0.0; LANES]; 2]);
        #[inline(always)]
        fn add(most: &mut Lanes, sum: &mut Lanes, d: &Lanes) {
            for l in 0..LANES {
                most[l] = if d[l] > most[l] { d[l] } else { most[l] };
                sum[l] += d[l];
            }
        }
        for ((now, then), kept) in p.iter().zip(at).zip(kept.iter_mut()) {
            let (now, then) = (&now[points.clone()], &then[points.clone()]);
            let mut now8 = now.chunks_exact(LANES);
            let mut then8 = then.chunks_exact(LANES);
            let mut kept8 = kept.chunks_exact_mut(LANES);
            for ((x, x0), xk) in (&mut now8).zip(&mut then8).zip(&mut kept8) {
                let d0: Lanes = std::array::from_fn(|l| (x[l] - x0[l]).abs());
                let d1: Lanes = std::array::from_fn(|l| (x[l] - xk[l]).abs());
                xk.copy_from_slice(x);
                add(&mut most0, &mut sum0, &d0);
                add(&mut most1, &mut sum1, &d1);
            }
            let rest = (now8.remainder().iter())
                .zip(then8.remainder())
                .zip(kept8.into_remainder());
            let (mut d0, mut d1) = ([0.0; LANES], [0.0; LANES]);
            for (l, ((x, x0), xk)) in rest.enumerate() {
                (d0[l], d1[l]) = ((x - x0).abs(), (x - *xk).abs());
                *xk = *x;
            }
            add(&mut most0, &mut sum0, &d0);
            add(&mut most1, &mut sum1, &d1);
        }
        let (most, sums) = ([most0, most1], [sum0, sum1]);
        let [since_sort, since_refresh] = [0, 1].map(|n| {
            if sums[n].iter().any(|s| s.is_nan()) {
                f64::INFINITY
            } else {
                most[n].into_iter().fold(0.0, f64::max)
            }
        });
        Moves {
            since_sort,
            since_refresh,
        }
    }
}

/// How far (along any axis) a body's points have moved at most, since the last sort and since
/// the refresh before the last.
#[derive(Clone, Copy, Debug, Default)]
struct Moves {
    since_sort: f64,
    since_refresh: f64,
}

/// A box holding nothing.
const EMPTY: [Vec3; 2] = [
    Vec3::new(f64::INFINITY, f64::INFINITY, f64::INFINITY),
    Vec3::new(f64::NEG_INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY),
];

/// True when boxes `a` and `b` (each `[lo, hi]`) overlap; an empty box meets nothing.
#[inline]
fn meets([alo, ahi]: [Vec3; 2], [blo, bhi]: [Vec3; 2]) -> bool {
    alo.x <= bhi.x
        && blo.x <= ahi.x
        && alo.y <= bhi.y
        && blo.y <= ahi.y
        && alo.z <= bhi.z
        && blo.z <= ahi.z
}

/// How far apart boxes `a` and `b` are along the axis they are furthest apart on (0 when they
/// meet).
#[inline]
fn separation([alo, ahi]: [Vec3; 2], [blo, bhi]: [Vec3; 2]) -> f64 {
    let apart = (alo - bhi).max(blo - ahi).max(Vec3::ZERO);
    apart.x.max(apart.y).max(apart.z)
}

/// The cells as the grid's sort has them: each entered in the buckets of the grid cells its
/// span overlaps (`mask` the buckets less one), as its index and the grid cell, x outermost.
struct CellKeys<'a> {
    placed: &'a [([[i32; 3]; 2], [Vec3; 2])],
    mask: usize,
}

impl crate::compute::team::Bucketed for CellKeys<'_> {
    type Entry = (u32, [i32; 3]);

    #[inline]
    fn entries(&self, g: usize, mut emit: impl FnMut(usize, (u32, [i32; 3]))) {
        let [lo, hi] = self.placed[g].0;
        for x in lo[0]..=hi[0] {
            for y in lo[1]..=hi[1] {
                for z in lo[2]..=hi[2] {
                    emit(hash([x, y, z]) & self.mask, (g as u32, [x, y, z]));
                }
            }
        }
    }
}

/// `x.floor() as i32` (saturating, 0 for a NaN) without the library call `floor` is on the
/// baseline target (SSE2 has no rounding instruction): a cast truncates towards zero, one
/// below it where that rounded a negative number up.
#[inline]
fn floor_i32(x: f64) -> i32 {
    let t = x as i32;
    if t as f64 > x {
        t.saturating_sub(1)
    } else {
        t
    }
}

/// A hash of a grid cell (the three large primes of Teschner et al. 2003).
#[inline]
fn hash(c: [i32; 3]) -> usize {
    ((c[0] as u32).wrapping_mul(73_856_093)
        ^ (c[1] as u32).wrapping_mul(19_349_663)
        ^ (c[2] as u32).wrapping_mul(83_492_791)) as usize
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::body::{Body, Material, IDENTITY};
    use crate::model::lattice::Lattice;
    use crate::model::{Aabb, ModelBuilder};
    use crate::state::State;

    /// Two boxes side by side, the first moved far between sorts and the second still, so that
    /// their reaches differ: a point of the first finds every cell of the second whose box, grown
    /// by the two reaches, holds it (whichever grid cell it falls in), and no other.
    #[test]
    fn a_fast_body_finds_a_still_ones_cells_as_far_as_the_two_reach() {
        let lattice = Lattice::new([4, 4, 4], Vec3::new(0.3, 0.3, 0.3));
        let bodies = [-0.35, 0.01].map(|x| {
            Body::lattice_box(lattice.clone(), Material::classic())
                .placed(Vec3::new(x, 0.0, 0.0), IDENTITY)
        });
        let model = ModelBuilder::new()
            .bodies(bodies.to_vec())
            .bounds(Aabb::new(Vec3::new(-9.0, -9.0, -9.0), Vec3::new(9.0, 9.0, 9.0)).unwrap())
            .build()
            .unwrap();
        let mut pos = State::at_rest(&model).pos;
        let mut grid = BroadPhase::new(&model);
        let axes = |pos: &[Vec3]| {
            [0, 1, 2].map(|a| pos.iter().map(|p| p.to_array()[a]).collect::<Vec<f64>>())
        };
        let sorted = |grid: &mut BroadPhase, pos: &[Vec3]| {
            let [x, y, z] = axes(pos);
            grid.refresh(&model, [&x, &y, &z], 0.0)
        };
        assert!(sorted(&mut grid, &pos));
        // The first box moves 0.05 (half a cell) towards the second: sorted again, with the
        // first reaching the most (0.02) and the second the least (0.003).
        for q in model.bodies()[0].points() {
            pos[q] += Vec3::new(0.05, 0.0, 0.0);
        }
        assert!(sorted(&mut grid, &pos));
        let (fast, still) = (grid.reach(0), grid.reach(1));
        assert!(
            (fast - MAX_REACH * 0.1).abs() < 1e-12 && (still - MIN_REACH * 0.1).abs() < 1e-12,
            "reaches {fast}, {still}"
        );
        let second = &model.bodies()[1];
        let offsets = second.contact_surface().offsets;
        let mut found_some = 0;
        for i in 0..=50 {
            for j in 0..=16 {
                // Points where the first box's may be until the next sort (it ends at x = 0,
                // the second starts at 0.01), across the second's edge at y = 0.3.
                let p = Vec3::new(-0.03 + i as f64 * 0.001, 0.25 + j as f64 * 0.005, 0.12);
                let mut want = Vec::new();
                for g in 0..grid.cell_body.len() {
                    let (b, corner) = grid.cell(g);
                    if b != 1 {
                        continue;
                    }
                    let [mut lo, mut hi] = EMPTY;
                    for &o in &offsets {
                        (lo, hi) = (lo.min(pos[corner + o]), hi.max(pos[corner + o]));
                    }
                    let grow = Vec3::new(fast + still, fast + still, fast + still);
                    if meets([lo - grow, hi + grow], [p, p]) {
                        want.push(g);
                    }
                }
                let mut got = Vec::new();
                grid.find_near(p, Some(0), fast, |g| {
                    got.push(g);
                    false
                });
                assert_eq!(got, want, "at {p:?}");
                // And the still body's box holds it, so that the point is looked up at all.
                assert!(want.is_empty() || grid.in_body_box(1, p), "at {p:?}");
                found_some += usize::from(!got.is_empty());
            }
        }
        assert!(found_some > 200, "{found_some} points near a cell");
    }

    /// The moves are the largest along any axis, since the sort and since the last refresh,
    /// wherever the farthest point is (in the lanes or the remainder), and infinite when a
    /// position is not a number; the kept positions become the new ones.
    #[test]
    fn moves_are_the_largest_and_infinite_past_a_nan() {
        let n = 29;
        let wave = |scale: f64, phase: f64| -> Vec<f64> {
            (0..n)
                .map(|i| scale * (i as f64 * 0.7 + phase).sin())
                .collect()
        };
        let at = [wave(1.0, 0.0), wave(1.0, 1.0), wave(1.0, 2.0)];
        let kept0 = [wave(1.1, 0.1), wave(0.9, 1.1), wave(1.0, 2.2)];
        for points in [0..n, 3..n, 0..24, 5..11] {
            for farthest in points.clone() {
                for nan in [None, Some(points.start), Some(points.end - 1)] {
                    let mut now = [wave(1.0, 0.01), wave(1.0, 1.02), wave(1.0, 2.03)];
                    now[1][farthest] += 3.0;
                    if let Some(q) = nan {
                        now[2][q] = f64::NAN;
                    }
                    let mut kept = kept0.clone();
                    let moves = {
                        // (`kept` holds the points' own run, as the team hands it out.)
                        let [x, y, z] = kept.each_mut().map(|c| &mut c[points.clone()]);
                        let p = [&now[0][..], &now[1][..], &now[2][..]];
                        moves_and_keep(p, &at, &mut [x, y, z], points.clone())
                    };
                    let most = |from: &[Vec<f64>; 3]| {
                        (0..3)
                            .flat_map(|a| points.clone().map(move |q| (a, q)))
                            .map(|(a, q)| (now[a][q] - from[a][q]).abs())
                            .fold(0.0, f64::max)
                    };
                    let want = match nan {
                        Some(_) => [f64::INFINITY; 2],
                        None => [most(&at), most(&kept0)],
                    };
                    assert_eq!([moves.since_sort, moves.since_refresh], want, "{points:?}");
                    for a in 0..3 {
                        for q in 0..n {
                            let want = if points.contains(&q) {
                                now[a][q]
                            } else {
                                kept0[a][q]
                            };
                            assert!(kept[a][q].to_bits() == want.to_bits(), "kept {a} {q}");
                        }
                    }
                }
            }
        }
    }

    /// The grid's floor is `f64::floor`'s, cast: at and around integers of either sign, far
    /// past the range of `i32`, at infinities and for a NaN.
    #[test]
    fn floor_i32_is_the_floor_cast() {
        let mut xs = vec![
            0.0,
            -0.0,
            f64::NAN,
            f64::INFINITY,
            f64::NEG_INFINITY,
            1e300,
            -1e300,
        ];
        for k in -5..=5 {
            for d in [-0.5, -1e-12, 0.0, 1e-12, 0.5] {
                xs.push(k as f64 + d);
            }
        }
        for m in [i32::MIN as f64, i32::MAX as f64] {
            xs.extend([m - 1.5, m - 0.5, m, m + 0.5, m + 1.5]);
        }
        for x in xs {
            assert_eq!(floor_i32(x), x.floor() as i32, "{x}");
        }
    }
}
