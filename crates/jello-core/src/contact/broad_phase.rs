//! The broad phase of contacts between bodies, in two levels. First each body's box (of its
//! points as they are now) and which bodies' boxes meet: a body near no other is passed over
//! whole, and a surface point outside every neighbour's box is not looked up. Then the kept
//! cells that meet a neighbour's box, as they are deformed now, sorted into a hashed uniform grid
//! by the grid cells their bounding boxes overlap (a counting sort, in the order of the bodies
//! and their cells), so that a point finds the few cells it may be inside by looking in its own
//! grid cell. Buffers are sized once (and grow only for a cell stretched over more grid cells
//! than was room for); the sort and the visits run in a fixed order, so the forces summed over
//! them are bit for bit the same whatever the thread count.
//!
//! **Reuse.** A sort is kept while no point has moved further than a slack `d` (a tenth of the
//! longest cell side) along any axis since it (`BroadPhase::refresh`); its boxes are grown by
//! `2d`. (A body near no other may move `d` and half its distance to the nearest: two bodies
//! apart stay apart while neither moves further, so bodies falling free do not sort the rest.) Then every cell's box now lies inside its box as sorted, and a surface point that is
//! in a cell now was, at the sort, in that cell's box as sorted (it and the cell each moved at
//! most `d`). So the contact pass lists, at each sort, the surface points that are in some
//! box and the cells whose boxes they are in, and until the next sort looks only at those
//! (see [`crate::contact::bodies`]): a step's stages and the next few steps share one sort and
//! one list. The cells looked at for a point are a superset of those a fresh sort gives, in the
//! same order, and a point's contact is decided by the first of them (in that order) that holds
//! it: the forces do not depend on when the grid was sorted.

use crate::model::contact_surface::map3;
use crate::model::Model;
use crate::vec3::Vec3;

/// Room for this many grid cells per cell, on average, before the buffers grow.
const ROOM_PER_CELL: usize = 8;

/// The most grid cells along an axis one cell may overlap: a cell stretched further is torn.
const MAX_SPAN: i32 = 16;

/// The distance any point may move before the sort is redone, as a fraction of the longest side
/// of the bodies' cells (boxes are sorted grown by twice it). Larger slack sorts less often but
/// visits more cells (0.1 was the quickest on a pile of 50 shapes; 0.05 and 0.2 were 10–15 %
/// slower in contact).
const SLACK: f64 = 0.1;

/// The side of a grid cell, times the longest side of the bodies' cells: so that a cell's box,
/// grown by twice the slack, overlaps two grid cells along an axis, seldom three.
const GRID: f64 = 1.5;

/// The cells of a model's bodies in a hashed uniform grid.
#[derive(Clone, Debug, Default)]
pub(crate) struct BroadPhase {
    /// Per cell (all bodies', in order): its body and the flat model index of its lower corner.
    pub cell_body: Vec<u32>,
    pub cell_corner: Vec<u32>,
    /// Per cell: the grid cells it overlaps and its bounding box at the last sort (none, and
    /// empty, for a cell no other surface can reach).
    placed: Vec<([[i32; 3]; 2], [Vec3; 2])>,
    /// Bucket starts of the hashed grid (`buckets + 1` entries).
    starts: Vec<u32>,
    /// Cells sorted by bucket (as indices of `cell_body`), with the grid cell each entry is for.
    entries: Vec<u32>,
    entry_keys: Vec<[i32; 3]>,
    /// Each entry's cell's body, beside it, so that a body's own cells are passed over unread.
    entry_bodies: Vec<u32>,
    /// Side of a grid cell (m).
    side: f64,
    /// The longest side of the bodies' cells (m).
    cell: f64,
    /// Per body: the box of its points at the last sort (grown), and the bodies whose boxes
    /// meet it (each list sorted; itself too under self-contact).
    body_boxes: Vec<[Vec3; 2]>,
    neighbours: Vec<Vec<u32>>,
    /// The points' positions at the last sort and the margin its boxes were grown by (none
    /// before the first sort).
    sorted_at: [Vec<f64>; 3],
    sorted_margin: Option<f64>,
    /// How many sorts there have been.
    sorts: usize,
    /// Per body: how far (along any axis) each of its points may move before the grid is
    /// sorted again.
    allowed: Vec<f64>,
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
            entries: Vec::with_capacity(ROOM_PER_CELL * cells),
            entry_keys: Vec::with_capacity(ROOM_PER_CELL * cells),
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
            allowed: vec![0.0; model.bodies().len()],
        }
    }

    /// Makes the grid hold, for positions `p`, every cell whose box grown by `margin` (m) may
    /// hold a point, and every such cell whose box at the last sort may have held it then (see
    /// the module's notes): sorts again, with boxes grown by `margin` and twice the slack,
    /// unless every point has moved less than the slack along every axis since the last sort
    /// (that sort's margin at least `margin`). True when it sorted.
    pub(crate) fn refresh(&mut self, model: &Model, p: [&[f64]; 3], margin: f64) -> bool {
        let slack = SLACK * self.cell;
        if let Some(sorted) = self.sorted_margin {
            // A position that is not a number sorts again (and is left out).
            let moved = |body: &crate::model::body::Body, allowed: f64| {
                let points = body.points();
                (0..3).any(|axis| {
                    (p[axis][points.clone()].iter())
                        .zip(&self.sorted_at[axis][points.clone()])
                        .map(|(x, x0)| (x - x0).abs())
                        .any(|d| d > allowed || d.is_nan())
                })
            };
            let bodies = model.bodies();
            if sorted >= margin + 2.0 * slack
                && !(bodies.iter().zip(&self.allowed)).any(|(body, &allowed)| moved(body, allowed))
            {
                return false;
            }
        }
        let grown = margin + 2.0 * slack;
        self.sort(model, p, grown);
        for (at, now) in self.sorted_at.iter_mut().zip(p) {
            at.copy_from_slice(now);
        }
        // A body near others may move the slack; one near none, half its distance to the
        // nearest more: two bodies apart stay apart while neither moves further.
        for (a, allowed) in self.allowed.iter_mut().enumerate() {
            *allowed = if self.neighbours[a].is_empty() {
                let gap = (0..self.body_boxes.len())
                    .filter(|&b| b != a)
                    .map(|b| separation(self.body_boxes[a], self.body_boxes[b]))
                    .fold(f64::INFINITY, f64::min);
                slack + 0.5 * gap
            } else {
                slack
            };
        }
        self.sorted_margin = Some(grown);
        self.sorts += 1;
        true
    }

    /// Sorts the cells, at positions `[px, py, pz]`, into the grid, each by its box grown by
    /// `margin` (m) on every side: those of them that may hold a sample of another body (or of
    /// their own under self-contact), as the bodies' boxes tell.
    fn sort(&mut self, model: &Model, [px, py, pz]: [&[f64]; 3], margin: f64) {
        let inv = 1.0 / self.side;
        let grid = |c: Vec3| map3((c * inv).to_array(), |x| x.floor() as i32);
        let mask = self.starts.len() - 2;
        let bodies = model.bodies();
        let grow = Vec3::new(margin, margin, margin);
        // Each body's box (of all its points, so that it holds its cells' boxes), and which
        // bodies' boxes meet.
        for (body, bounds) in bodies.iter().zip(&mut self.body_boxes) {
            *bounds = EMPTY;
            let [lo, hi] = bounds;
            for q in body.points() {
                let p = Vec3::new(px[q], py[q], pz[q]);
                (*lo, *hi) = (lo.min(p), hi.max(p));
            }
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
        // Each cell's box and span (on the team's threads: cells are independent), only for
        // cells that meet a box a sample may come from; then how many entries each bucket gets.
        let (cell_body, cell_corner) = (&self.cell_body, &self.cell_corner);
        let (neighbours, body_boxes) = (&self.neighbours, &self.body_boxes);
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
            let (lo, hi) = (lo - grow, hi + grow);
            let span = [grid(lo), grid(hi)];
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
        self.starts.fill(0);
        let mut total = 0;
        for &(span, _) in &self.placed {
            for_each_key(span, |key| {
                self.starts[hash(key) & mask] += 1;
                total += 1;
            });
        }
        // Starts by a prefix sum; then each cell into the buckets of its span, in order.
        let mut sum = 0;
        for s in self.starts.iter_mut() {
            let count = *s;
            *s = sum;
            sum += count;
        }
        self.entries.resize(total, 0);
        self.entry_keys.resize(total, [0; 3]);
        self.entry_bodies.resize(total, 0);
        for (g, &(span, _)) in self.placed.iter().enumerate() {
            for_each_key(span, |key| {
                let slot = &mut self.starts[hash(key) & mask];
                let e = *slot as usize;
                (self.entries[e], self.entry_keys[e]) = (g as u32, key);
                self.entry_bodies[e] = self.cell_body[g];
                *slot += 1;
            });
        }
        // Each bucket's start is now the next one's; shift back.
        for b in (1..self.starts.len()).rev() {
            self.starts[b] = self.starts[b - 1];
        }
        self.starts[0] = 0;
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

    /// Cell `g` with its box (grown) at the last sort, to keep in a list of cells a point may be
    /// in until the next sort (see `visit`).
    #[inline]
    pub(crate) fn near_cell(&self, g: usize) -> NearCell {
        NearCell {
            cell: g as u32,
            bounds: self.placed[g].1,
        }
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

    /// Calls `near(cell)` for every cell whose box (grown) at the last sort holds `p`, in a fixed
    /// order (the cells' order), until it returns true; cells of body `skip` are passed over.
    #[inline]
    pub(crate) fn find_near(
        &self,
        p: Vec3,
        skip: Option<u32>,
        mut near: impl FnMut(usize) -> bool,
    ) {
        let key = map3((p * (1.0 / self.side)).to_array(), |x| x.floor() as i32);
        let bucket = hash(key) & (self.starts.len() - 2);
        let range = self.starts[bucket] as usize..self.starts[bucket + 1] as usize;
        let skip = skip.unwrap_or(u32::MAX);
        for ((&g, &k), &b) in (self.entries[range.clone()].iter())
            .zip(&self.entry_keys[range.clone()])
            .zip(&self.entry_bodies[range])
        {
            if b == skip {
                continue;
            }
            let [lo, hi] = self.placed[g as usize].1;
            let inside = p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y;
            if k != key || !(inside && p.z >= lo.z && p.z <= hi.z) {
                continue;
            }
            if near(g as usize) {
                return;
            }
        }
    }
}

/// A cell of the broad phase (its index) and its box (grown) at the last sort.
#[derive(Clone, Copy, Debug)]
pub(crate) struct NearCell {
    pub cell: u32,
    pub bounds: [Vec3; 2],
}

/// Calls `near(cell)` for each of `cells` whose box (grown) at the last sort holds `p`, in
/// order, until it returns true. The boxes are kept beside the cells so that the lists are read
/// in order.
#[inline]
pub(crate) fn visit(cells: &[NearCell], p: Vec3, mut near: impl FnMut(usize) -> bool) {
    for c in cells {
        let [lo, hi] = c.bounds;
        let inside = p.x >= lo.x && p.x <= hi.x && p.y >= lo.y && p.y <= hi.y;
        if inside && p.z >= lo.z && p.z <= hi.z && near(c.cell as usize) {
            return;
        }
    }
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

/// Calls `f` with every grid cell of `span` (inclusive), x outermost.
#[inline]
fn for_each_key([lo, hi]: [[i32; 3]; 2], mut f: impl FnMut([i32; 3])) {
    for x in lo[0]..=hi[0] {
        for y in lo[1]..=hi[1] {
            for z in lo[2]..=hi[2] {
                f([x, y, z]);
            }
        }
    }
}

/// A hash of a grid cell (the three large primes of Teschner et al. 2003).
#[inline]
fn hash(c: [i32; 3]) -> usize {
    ((c[0] as u32).wrapping_mul(73_856_093)
        ^ (c[1] as u32).wrapping_mul(19_349_663)
        ^ (c[2] as u32).wrapping_mul(83_492_791)) as usize
}
