//! The springs' kernel: every spring of a chunk of planes evaluated by the lattice stencil, one
//! contiguous, branch-free run of point pairs per stencil entry, compiled for each
//! instruction-set tier (see the module documentation of [`crate::forces`]).

use std::ops::Range;

use crate::compute::soa::{cache_aligned_zeros, Soa};
use crate::model::body::Body;
use crate::model::lattice::STENCIL;
use crate::model::springs::SpringTable;
use crate::vec3::Vec3;

/// Per stencil class `(dj, dk)` (index `(dj + 1)·4 + dk + 1`, both in −1..=2): for every point
/// `u` of a plane, 1 where the point at `(j + dj, k + dk)` exists, else 0; then repeated for one
/// row buffer's length, so that the mask of any block of a run starting at chunk offset `t` is
/// the slice from `t mod plane`. One plane, not a whole chunk, so the masks stay in cache. Each
/// starts on a cache line, like the runs it is read with.
#[derive(Clone, Debug, Default)]
pub(super) struct Masks {
    pub(super) data: Vec<f64>,
    /// Numbers per mask.
    pub(super) len: usize,
    /// Index in `data` of the first mask, and from one mask to the next.
    pub(super) first: usize,
    pub(super) stride: usize,
}

impl Masks {
    /// The masks of a lattice with `ny × nz` planes, for row buffers of `row_len`.
    pub(super) fn new(ny: usize, nz: usize, row_len: usize) -> Self {
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

/// Lattice dimensions and the spring constants per kind.
#[derive(Clone, Copy)]
pub(super) struct Grid {
    pub(super) nx: usize,
    pub(super) ny: usize,
    pub(super) nz: usize,
    pub(super) stiffness: [f64; 3],
    pub(super) damping: [f64; 3],
    /// Rest length of each stencil entry (m).
    pub(super) rest: [f64; 16],
}

impl Grid {
    pub(super) fn new(body: &Body) -> Self {
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
pub(super) struct Placement<'a> {
    pub(super) first: usize,
    pub(super) i0: usize,
    pub(super) planes: usize,
    pub(super) links: &'a [u16],
    /// The chunk's spans of set link bits, per block and stencil entry (empty for a full box).
    pub(super) spans: &'a [[u32; 2]],
    /// The body's per-spring factors, if it has any.
    pub(super) table: Option<&'a SpringTable>,
    /// Which dampers the springs have (see [`Dampers`]).
    pub(super) dampers: Dampers<'a>,
}

/// The springs' dampers in a force pass.
#[derive(Clone, Copy)]
pub(crate) enum Dampers<'a> {
    /// Along each spring's direction at the pass's positions, at the pass's velocities (every
    /// force evaluation of an explicit step).
    Current,
    /// Along each spring's direction where its ends were at `start`, at the velocities
    /// `velocity` (the implicit integrators' residuals: their dampers act along the directions
    /// at the step's start, at the iterate's velocities, while the pass's own velocities are
    /// zero). Computed in the springs' own loop, where a product of its own over the springs
    /// (its factors `d/|L₀|²` read by slot) cost more than the springs' forces themselves.
    AtStart { start: &'a Soa, velocity: &'a Soa },
    /// No dampers: every velocity is zero, where [`Dampers::AtStart`]'s would exert nothing (an
    /// implicit step's first residual from rest, at every step of a body resting on a floor).
    /// The springs' own forces alone read a third of the arrays, with one division a spring
    /// instead of two (a resting 16³ cube 2 % faster on one thread).
    AtRest,
}

crate::compute::simd::multiversion! {
    /// The springs whose first point lies in the chunk's planes `i0 .. i0 + planes` of a body
    /// and that reach the points `needed` (offsets from the chunk's first point; the halo's
    /// start on), into `own` (forces on those planes, zeroed here) and `halo` (forces on the
    /// two planes after them, zeroed here). Only the forces on the points `needed` are whole:
    /// those get the same bits whichever points are needed. With no `own`, `needed` must be
    /// the halo's points.
    #[allow(clippy::too_many_arguments)]
    pub(super) fn chunk_springs(
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
            let points = nx * plane;
            let factors = at
                .table
                .map(|table| table.run(points, s, i0 * plane + t, len));
            let uniform = |_| (spring.k, spring.d, spring.rest);
            // Eight variants, each a branch-free loop: with or without dampers, full box or
            // link bits, material values or per-spring factors on them.
            macro_rules! run {
                ($spring:expr, $mask:expr) => {
                    match at.dampers {
                        Dampers::Current => spring_run(p, v, a, b, len, $spring, $mask, row),
                        Dampers::AtStart { start, velocity } => {
                            let ends = [(p, a), (p, b), (start, a), (start, b)];
                            let speeds = [(velocity, a), (velocity, b)];
                            spring_run_at_start(ends, speeds, len, $spring, $mask, row)
                        }
                        Dampers::AtRest => spring_run_at_rest(p, a, b, len, $spring, $mask, row),
                    }
                };
            }
            if at.links.is_empty() {
                let m = t % plane;
                let mask = &masks.class(mask)[m..m + len];
                match factors {
                    None => run!(uniform, |t| mask[t]),
                    Some(f) => run!(spring.scaled(f), |t| mask[t]),
                }
            } else {
                let links = &at.links[i0 * plane + t..][..len];
                let link = |t: usize| (links[t] >> s & 1) as f64;
                match factors {
                    None => run!(uniform, link),
                    Some(f) => run!(spring.scaled(f), link),
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
    let ([xa, ya, za], [xb, yb, zb]) = (p.range(a..a + len), p.range(b..b + len));
    let ([ua, va, wa], [ub, vb, wb]) = (v.range(a..a + len), v.range(b..b + len));
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

/// [`spring_run`] with each damper along its spring at the step's start (see
/// [`Dampers::AtStart`]): `f = −k (|L| − R) L̂ − c (L₀·(vA − vB)) L₀`, `L` the spring at the
/// positions `ends[0..2]`, `L₀` at the start positions `ends[2..4]`, `c = d/|L₀|²` (zero for a
/// spring of zero length there), the velocities `speeds`; each array with its first index.
#[inline(always)]
fn spring_run_at_start<'a>(
    ends: [(&'a Soa, usize); 4],
    speeds: [(&'a Soa, usize); 2],
    len: usize,
    spring: impl Fn(usize) -> (f64, f64, f64),
    mask: impl Fn(usize) -> f64,
    row: &mut Soa,
) {
    let at = |(s, i): (&'a Soa, usize)| s.range(i..i + len);
    let [[xa, ya, za], [xb, yb, zb], [sa, ta, ua], [sb, tb, ub]] = ends.map(at);
    let [[va, wa, qa], [vb, wb, qb]] = speeds.map(at);
    let [fx, fy, fz] = row.parts_mut();
    let (fx, fy, fz) = (&mut fx[..len], &mut fy[..len], &mut fz[..len]);
    for t in 0..len {
        let (dx, dy, dz) = (xa[t] - xb[t], ya[t] - yb[t], za[t] - zb[t]);
        let (k, d, rest) = spring(t);
        let s = stretch([dx, dy, dz], k, rest) * mask(t);
        let (ex, ey, ez) = (sa[t] - sb[t], ta[t] - tb[t], ua[t] - ub[t]);
        let e2 = ex * ex + ey * ey + ez * ez;
        let closing = (va[t] - vb[t]) * ex + (wa[t] - wb[t]) * ey + (qa[t] - qb[t]) * ez;
        let c = if e2 > 0.0 {
            -d * closing / e2 * mask(t)
        } else {
            0.0
        };
        (fx[t], fy[t], fz[t]) = (dx * s + ex * c, dy * s + ey * c, dz * s + ez * c);
    }
}

/// [`spring_run_at_start`] at rest: `f = −k (|L| − R) L̂`, `L` the spring at the positions `p`
/// (`a` and `b` the first indices of its ends), the same bits as there with every velocity zero
/// (but for the sign of a zero).
#[inline(always)]
fn spring_run_at_rest(
    p: &Soa,
    a: usize,
    b: usize,
    len: usize,
    spring: impl Fn(usize) -> (f64, f64, f64),
    mask: impl Fn(usize) -> f64,
    row: &mut Soa,
) {
    let ([xa, ya, za], [xb, yb, zb]) = (p.range(a..a + len), p.range(b..b + len));
    let [fx, fy, fz] = row.parts_mut();
    let (fx, fy, fz) = (&mut fx[..len], &mut fy[..len], &mut fz[..len]);
    for t in 0..len {
        let (dx, dy, dz) = (xa[t] - xb[t], ya[t] - yb[t], za[t] - zb[t]);
        let (k, _, rest) = spring(t);
        let s = stretch([dx, dy, dz], k, rest) * mask(t);
        (fx[t], fy[t], fz[t]) = (dx * s, dy * s, dz * s);
    }
}

/// The spring force `−k (|L| − R) L̂` of [`spring_run_at_start`] and [`spring_run_at_rest`] as a
/// factor of `L` (`−k (|L| − R)/|L|`, zero for a spring of zero length): one square root and one
/// division.
#[inline(always)]
fn stretch([dx, dy, dz]: [f64; 3], k: f64, rest: f64) -> f64 {
    let l2 = dx * dx + dy * dy + dz * dz;
    let inv = if l2 > 0.0 { 1.0 / l2.sqrt() } else { 0.0 };
    let l = l2 * inv;
    -k * (l - rest) * inv
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
