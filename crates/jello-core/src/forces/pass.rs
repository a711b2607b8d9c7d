//! A force pass over one body cut for threads: contiguous ranges of planes, each walked chunk by
//! chunk (the springs of [`super::stencil`], then the points of [`super::points`] completed and
//! handed to the caller's update), with the same bits however the planes are cut.

use std::ops::Range;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

use super::points::{block_accelerations, PointInputs};
use super::stencil::{chunk_springs, Dampers, Grid, Masks, Placement};
use super::{CHUNK_PLANES, HALO_PLANES, MIN_RANGE_PLANES};
use crate::compute::soa::Soa;
use crate::compute::split::Split;
use crate::contact::friction::Anchors;
use crate::model::body::Body;
use crate::model::Model;
use crate::state::Control;

/// What every chunk of a [`force_pass`] shares.
pub(super) struct Pass<'a, U> {
    pub(super) model: &'a Model,
    pub(super) body: &'a Body,
    pub(super) grid: Grid,
    pub(super) masks: &'a Masks,
    pub(super) spans: &'a [[u32; 2]],
    pub(super) p: &'a Soa,
    pub(super) v: &'a Soa,
    /// The springs' dampers.
    pub(super) dampers: Dampers<'a>,
    pub(super) control: &'a Control,
    pub(super) contact: Option<&'a Soa>,
    pub(super) anchors: Option<&'a Anchors>,
    /// Whether friction acts (see [`PointInputs::friction`]).
    pub(super) friction: bool,
    pub(super) update: &'a U,
}

/// The buffers of a body's spring pass that a range of planes takes for its own.
pub(super) struct RangeBuffers<'a> {
    /// Spring forces on the points of a chunk.
    pub(super) own: &'a mut Soa,
    /// Two halos: the chunk before's and the chunk's own (see [`BodyScratch::halos`]).
    pub(super) halos: &'a mut [Soa],
    /// One block of springs' forces, then of accelerations.
    pub(super) row: &'a mut Soa,
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
    pub(super) fn ranges<'b, T>(
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
            dampers: self.dampers,
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
                clearance: (!self.body.clearance().is_empty())
                    .then(|| &self.model.clearance()[r.clone()]),
                anchors: self.anchors,
                friction: self.friction,
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
