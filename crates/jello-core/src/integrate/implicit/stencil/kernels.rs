//! The loops of the stencil-ordered products, compiled for each instruction-set tier: a range's
//! rows summed entry by entry ([`rows`]), in `f64` or `f32` ([`Lane`]), and the per-slot
//! kernels (spring forces, blocks).

#[cfg(doc)]
use super::TILE;
use super::{RowRange, Span};
use crate::vec3::Vec3;

/// The numbers of a product's rows: `f64` or `f32` (see [`Precision`]).
pub(super) trait Lane: Copy + Send + Sync {
    /// `v` rounded to this precision.
    fn of(v: f64) -> Self;
    /// This number in double precision.
    fn wide(self) -> f64;
    /// `y += f` element by element.
    fn add(y: [&mut [Self]; 3], f: [&[Self]; 3]);
    /// `y −= f` element by element.
    fn subtract(y: [&mut [Self]; 3], f: [&[Self]; 3]);
    /// A range's rows and forces buffer in this precision.
    fn buffers(range: &mut RowRange) -> (&mut [Vec<Self>; 3], &mut [Vec<Self>; 3]);
    /// `x` (as many as `soa` holds) into `soa`, rounded to this precision.
    fn load(x: &[Vec3], soa: [&mut [Self]; 3]);
    /// `out[·][i] = own(start + i)`, rounded to this precision.
    fn own_rows(start: usize, own: &impl Fn(usize) -> Vec3, out: [&mut [Self]; 3]);
    /// `y[i] = out(start + i, rows[·][i])`: a range's rows of a product out.
    fn out_rows(
        start: usize,
        rows: [&[Self]; 3],
        out: &impl Fn(usize, Vec3) -> Vec3,
        y: &mut [Vec3],
    );
}

impl Lane for f64 {
    fn of(v: f64) -> Self {
        v
    }
    fn wide(self) -> f64 {
        self
    }
    fn add(y: [&mut [f64]; 3], f: [&[f64]; 3]) {
        add_forces(y, f);
    }
    fn subtract(y: [&mut [f64]; 3], f: [&[f64]; 3]) {
        subtract_forces(y, f);
    }
    fn buffers(range: &mut RowRange) -> (&mut [Vec<f64>; 3], &mut [Vec<f64>; 3]) {
        (&mut range.y, &mut range.forces)
    }
    fn load(x: &[Vec3], soa: [&mut [f64]; 3]) {
        load_double(x, soa);
    }
    fn own_rows(start: usize, own: &impl Fn(usize) -> Vec3, out: [&mut [f64]; 3]) {
        own_rows_double(start, own, out);
    }
    fn out_rows(
        start: usize,
        rows: [&[f64]; 3],
        out: &impl Fn(usize, Vec3) -> Vec3,
        y: &mut [Vec3],
    ) {
        out_rows_double(start, rows, out, y);
    }
}

impl Lane for f32 {
    fn of(v: f64) -> Self {
        v as f32
    }
    fn wide(self) -> f64 {
        f64::from(self)
    }
    fn add(y: [&mut [f32]; 3], f: [&[f32]; 3]) {
        add_forces_single(y, f);
    }
    fn subtract(y: [&mut [f32]; 3], f: [&[f32]; 3]) {
        subtract_forces_single(y, f);
    }
    fn buffers(range: &mut RowRange) -> (&mut [Vec<f32>; 3], &mut [Vec<f32>; 3]) {
        (&mut range.y_single, &mut range.forces_single)
    }
    fn load(x: &[Vec3], soa: [&mut [f32]; 3]) {
        load_single(x, soa);
    }
    fn own_rows(start: usize, own: &impl Fn(usize) -> Vec3, out: [&mut [f32]; 3]) {
        own_rows_single(start, own, out);
    }
    fn out_rows(
        start: usize,
        rows: [&[f32]; 3],
        out: &impl Fn(usize, Vec3) -> Vec3,
        y: &mut [Vec3],
    ) {
        out_rows_single(start, rows, out, y);
    }
}

/// `x` into `soa` (as many points as it holds), rounded to `T`'s precision (inlined into each
/// tier's copy of the callers below).
#[inline(always)]
fn load_each<T: Lane>(x: &[Vec3], [x0, x1, x2]: [&mut [T]; 3]) {
    let n = x0.len();
    let (x, x1, x2) = (&x[..n], &mut x1[..n], &mut x2[..n]);
    for i in 0..n {
        (x0[i], x1[i], x2[i]) = (T::of(x[i].x), T::of(x[i].y), T::of(x[i].z));
    }
}

/// `out[·][i] = own(start + i)` rounded to `T`'s precision (inlined as [`load_each`] is).
#[inline(always)]
fn own_each<T: Lane>(start: usize, own: &impl Fn(usize) -> Vec3, [o0, o1, o2]: [&mut [T]; 3]) {
    let n = o0.len();
    let (o1, o2) = (&mut o1[..n], &mut o2[..n]);
    for i in 0..n {
        let v = own(start + i);
        (o0[i], o1[i], o2[i]) = (T::of(v.x), T::of(v.y), T::of(v.z));
    }
}

/// `y[i] = out(start + i, rows[·][i])` (inlined as [`load_each`] is).
#[inline(always)]
fn out_each<T: Lane>(
    start: usize,
    rows: [&[T]; 3],
    out: &impl Fn(usize, Vec3) -> Vec3,
    y: &mut [Vec3],
) {
    let n = y.len();
    let [y0, y1, y2] = rows.map(|r| &r[..n]);
    for i in 0..n {
        y[i] = out(
            start + i,
            Vec3::new(y0[i].wide(), y1[i].wide(), y2[i].wide()),
        );
    }
}

crate::compute::simd::multiversion! {
    /// [`out_each`] in double precision.
    fn out_rows_double(
        start: usize,
        rows: [&[f64]; 3],
        out: &impl Fn(usize, Vec3) -> Vec3,
        y: &mut [Vec3],
    ) {
        out_each(start, rows, out, y)
    }
}

crate::compute::simd::multiversion! {
    /// [`out_each`] from single precision.
    fn out_rows_single(
        start: usize,
        rows: [&[f32]; 3],
        out: &impl Fn(usize, Vec3) -> Vec3,
        y: &mut [Vec3],
    ) {
        out_each(start, rows, out, y)
    }
}

crate::compute::simd::multiversion! {
    /// `out = rows·free` point by point, in single precision.
    pub(super) fn out_rows_free(rows: [&[f32]; 3], free: &[f64], out: [&mut [f32]; 3]) {
        let n = free.len();
        for (out, rows) in out.into_iter().zip(rows) {
            let (out, rows) = (&mut out[..n], &rows[..n]);
            for i in 0..n {
                out[i] = rows[i] * free[i] as f32;
            }
        }
    }
}

crate::compute::simd::multiversion! {
    /// `x·y` in double precision over single-precision vectors (structure of arrays): point
    /// `i`'s term into partial sum `i mod 8`, then those in order.
    pub(in crate::integrate::implicit) fn dot_single(x: [&[f32]; 3], y: [&[f32]; 3]) -> f64 {
        let n = x[0].len();
        let [x0, x1, x2] = x.map(|x| &x[..n]);
        let [y0, y1, y2] = y.map(|y| &y[..n]);
        type Three<'a> = (&'a [f32], &'a [f32], &'a [f32]);
        let term = |i: usize, (a0, a1, a2): Three, (b0, b1, b2): Three| {
            f64::from(a0[i]) * f64::from(b0[i])
                + f64::from(a1[i]) * f64::from(b1[i])
                + f64::from(a2[i]) * f64::from(b2[i])
        };
        // Eight points at a time, each into its own sum (slices of a known length: no bounds
        // checks, and the eight sums one vector).
        let mut sums = [0.0f64; 8];
        let eights = (x0.chunks_exact(8).zip(x1.chunks_exact(8)).zip(x2.chunks_exact(8)))
            .zip(y0.chunks_exact(8).zip(y1.chunks_exact(8)).zip(y2.chunks_exact(8)));
        for (((a0, a1), a2), ((b0, b1), b2)) in eights {
            let (a, b) = ((&a0[..8], &a1[..8], &a2[..8]), (&b0[..8], &b1[..8], &b2[..8]));
            for (k, sum) in sums.iter_mut().enumerate() {
                *sum += term(k, a, b);
            }
        }
        let whole = n - n % 8;
        let (a, b) = (
            (&x0[whole..], &x1[whole..], &x2[whole..]),
            (&y0[whole..], &y1[whole..], &y2[whole..]),
        );
        for (k, sum) in sums.iter_mut().enumerate().take(n - whole) {
            *sum += term(k, a, b);
        }
        sums.iter().sum()
    }
}

crate::compute::simd::multiversion! {
    /// `out = own·x` point by point, `own` the points' blocks (`[xx, yy, zz, xy, xz, yz]`) and
    /// `x` in single precision, as structure of arrays.
    pub(super) fn own_rows_soa(own: [&[f32]; 6], x: [&[f32]; 3], out: [&mut [f32]; 3]) {
        let [o0, o1, o2] = out;
        let n = o0.len();
        let (o1, o2) = (&mut o1[..n], &mut o2[..n]);
        let [xx, yy, zz, xy, xz, yz] = own.map(|o| &o[..n]);
        let [x0, x1, x2] = x.map(|x| &x[..n]);
        for i in 0..n {
            o0[i] = xx[i] * x0[i] + xy[i] * x1[i] + xz[i] * x2[i];
            o1[i] = xy[i] * x0[i] + yy[i] * x1[i] + yz[i] * x2[i];
            o2[i] = xz[i] * x0[i] + yz[i] * x1[i] + zz[i] * x2[i];
        }
    }
}

crate::compute::simd::multiversion! {
    /// [`own_each`] in double precision.
    fn own_rows_double(start: usize, own: &impl Fn(usize) -> Vec3, out: [&mut [f64]; 3]) {
        own_each(start, own, out)
    }
}

crate::compute::simd::multiversion! {
    /// [`own_each`] in single precision.
    fn own_rows_single(start: usize, own: &impl Fn(usize) -> Vec3, out: [&mut [f32]; 3]) {
        own_each(start, own, out)
    }
}

crate::compute::simd::multiversion! {
    /// [`load_each`] in double precision.
    fn load_double(x: &[Vec3], soa: [&mut [f64]; 3]) {
        load_each(x, soa)
    }
}

crate::compute::simd::multiversion! {
    /// [`load_each`] in single precision.
    fn load_single(x: &[Vec3], soa: [&mut [f32]; 3]) {
        load_each(x, soa)
    }
}

/// Rows `start .. start + out.len()` of `own·x + springs·x` into `out` (`init(start, out)`
/// puts the rows of `own·x` there), with `forces` (at least `tile` long) for the
/// spring forces of one stencil entry in one tile: `entry_forces(at, q, o, f, x, xn)` puts the
/// forces `B·(x − xn)` of the springs at slots `at .. at + f.len()` into `f` (their first ends
/// `q ..`, their second `q + o ..`).
///
/// Each spring's force `B·(x[q] − x[q + o])` is computed once, into `forces`, and added to its
/// first end's row and taken from its second end's: `−(B·(a − b))` is `B·(b − a)` to the bit,
/// and each block is read once rather than once from each end. The springs are taken by tiles
/// of their first ends, `k·tile .. (k + 1)·tile` counted from point 0 whatever the range,
/// every entry of one tile before the next tile: a tile's forces stay in the L1 cache between
/// their computing and their two uses, where a whole range's forces of one entry did not. So
/// each row sums `own`, then the forces of its springs tile by tile (its second ends' tiles
/// come before its own), within a tile entry by entry, an entry's force from the row as first
/// end before that as second end: the same order whoever computes the row, as long as `tile` is
/// the same ([`TILE`] in every product).
#[allow(clippy::too_many_arguments)]
pub(super) fn rows<T: Lane>(
    spans: &[Span],
    n: usize,
    init: impl Fn(usize, [&mut [T]; 3]),
    x: &[Vec<T>; 3],
    start: usize,
    out: [&mut [T]; 3],
    forces: &mut [Vec<T>; 3],
    tile: usize,
    entry_forces: impl Fn(usize, usize, usize, [&mut [T]; 3], [&[T]; 3], [&[T]; 3]),
) {
    let end = start + out[0].len();
    let [o0, o1, o2] = out;
    init(start, [&mut *o0, &mut *o1, &mut *o2]);
    let xs = |at: usize, len: usize| -> [&[T]; 3] { std::array::from_fn(|c| &x[c][at..at + len]) };
    let [f0, f1, f2] = forces;
    for span in spans {
        // This range's rows within the body.
        let (lo, hi) = (start.max(span.first), end.min(span.first + span.len));
        if lo >= hi {
            continue;
        }
        let entries = span.offset.iter().enumerate();
        let entries = entries.filter(|&(_, &o)| o != 0 && o < span.len);
        // The first ends of the springs with either end a row here: from the body's first
        // point (or the longest offset before the first row) to below the range's end.
        let reach = entries.clone().map(|(_, &o)| o).max().unwrap_or(0);
        let first = lo.saturating_sub(reach).max(span.first);
        for t in first / tile..hi.div_ceil(tile) {
            let (t0, t1) = (t * tile, (t + 1) * tile);
            for (e, &o) in entries.clone() {
                // This tile's springs from q to q + o with either end a row here: q from the
                // body's first point (or o before the first row) to below the first row past
                // the range or past the body's end minus o.
                let q0 = t0.max(lo.saturating_sub(o)).max(span.first);
                let q1 = t1.min(hi).min(span.first + span.len - o);
                if q0 >= q1 {
                    continue;
                }
                let len = q1 - q0;
                let f = [&mut f0[..len], &mut f1[..len], &mut f2[..len]];
                let (x, xn, at) = (xs(q0, len), xs(q0 + o, len), e * n + q0);
                entry_forces(at, q0, o, f, x, xn);
                // Their first ends among the rows…
                let a = q0.max(lo);
                if a < q1 {
                    let y = [
                        &mut o0[a - start..q1 - start],
                        &mut o1[a - start..q1 - start],
                        &mut o2[a - start..q1 - start],
                    ];
                    let f = [&f0[a - q0..len], &f1[a - q0..len], &f2[a - q0..len]];
                    T::add(y, f);
                }
                // …and their second ends (q + o below the range's end).
                let b = q1.min(hi.saturating_sub(o));
                if q0 < b {
                    let y = [
                        &mut o0[q0 + o - start..b + o - start],
                        &mut o1[q0 + o - start..b + o - start],
                        &mut o2[q0 + o - start..b + o - start],
                    ];
                    let f = [&f0[..b - q0], &f1[..b - q0], &f2[..b - q0]];
                    T::subtract(y, f);
                }
            }
        }
    }
}

/// `f = B·(x − xn)` element by element, `B` a symmetric block per element (inlined into each
/// tier's copy of the callers below).
#[inline(always)]
fn block_forces<T>(f: [&mut [T]; 3], x: [&[T]; 3], xn: [&[T]; 3], b: [&[T]; 6])
where
    T: Copy + std::ops::Add<Output = T> + std::ops::Sub<Output = T> + std::ops::Mul<Output = T>,
{
    let [f0, f1, f2] = f;
    let n = f0.len();
    let (f1, f2) = (&mut f1[..n], &mut f2[..n]);
    let (x0, x1, x2) = (&x[0][..n], &x[1][..n], &x[2][..n]);
    let (n0, n1, n2) = (&xn[0][..n], &xn[1][..n], &xn[2][..n]);
    let (bxx, byy, bzz) = (&b[0][..n], &b[1][..n], &b[2][..n]);
    let (bxy, bxz, byz) = (&b[3][..n], &b[4][..n], &b[5][..n]);
    for i in 0..n {
        let (dx, dy, dz) = (x0[i] - n0[i], x1[i] - n1[i], x2[i] - n2[i]);
        f0[i] = bxx[i] * dx + bxy[i] * dy + bxz[i] * dz;
        f1[i] = bxy[i] * dx + byy[i] * dy + byz[i] * dz;
        f2[i] = bxz[i] * dx + byz[i] * dy + bzz[i] * dz;
    }
}

crate::compute::simd::multiversion! {
    /// [`block_forces`] in double precision.
    pub(super) fn spring_forces(f: [&mut [f64]; 3], x: [&[f64]; 3], xn: [&[f64]; 3], b: [&[f64]; 6]) {
        block_forces(f, x, xn, b)
    }
}

crate::compute::simd::multiversion! {
    /// [`block_forces`] in single precision.
    pub(super) fn spring_forces_single(
        f: [&mut [f32]; 3],
        x: [&[f32]; 3],
        xn: [&[f32]; 3],
        b: [&[f32]; 6],
    ) {
        block_forces(f, x, xn, b)
    }
}

crate::compute::simd::multiversion! {
    /// [`block_forces`] with the blocks in 16 bits (see [`pack_tile`]): `f = B·(step·(x − xn))`,
    /// `B` the blocks' whole numbers of `step`, converted exactly to single precision.
    pub(super) fn spring_forces_packed(
        f: [&mut [f32]; 3],
        x: [&[f32]; 3],
        xn: [&[f32]; 3],
        b: [&[i16]; 6],
        step: f32,
    ) {
        let [f0, f1, f2] = f;
        let n = f0.len();
        let (f1, f2) = (&mut f1[..n], &mut f2[..n]);
        let (x0, x1, x2) = (&x[0][..n], &x[1][..n], &x[2][..n]);
        let (n0, n1, n2) = (&xn[0][..n], &xn[1][..n], &xn[2][..n]);
        let (bxx, byy, bzz) = (&b[0][..n], &b[1][..n], &b[2][..n]);
        let (bxy, bxz, byz) = (&b[3][..n], &b[4][..n], &b[5][..n]);
        for i in 0..n {
            let dx = (x0[i] - n0[i]) * step;
            let dy = (x1[i] - n1[i]) * step;
            let dz = (x2[i] - n2[i]) * step;
            let (xx, yy, zz) = (f32::from(bxx[i]), f32::from(byy[i]), f32::from(bzz[i]));
            let (xy, xz, yz) = (f32::from(bxy[i]), f32::from(bxz[i]), f32::from(byz[i]));
            f0[i] = xx * dx + xy * dy + xz * dz;
            f1[i] = xy * dx + yy * dy + yz * dz;
            f2[i] = xz * dx + yz * dy + zz * dz;
        }
    }
}

/// The largest whole number a packed block's component holds: `i16::MAX`, so that every
/// component's magnitude, at most the tile's largest, rounds into range.
pub(super) const PACKED_MAX: f32 = i16::MAX as f32;

crate::compute::simd::multiversion! {
    /// One tile of one stencil entry's single-precision blocks `b` (each component's run, of one
    /// length) into 16 bits in `packed` (as long, or longer: the rest zeroed): each component
    /// in whole steps of the tile's largest magnitude over [`PACKED_MAX`], rounded to the
    /// nearest; returns that step (zero for a tile without a block).
    pub(super) fn pack_tile(b: [&[f32]; 6], packed: [&mut [i16]; 6]) -> f32 {
        let n = b[0].len();
        // The largest magnitude in 32 lanes (four vectors of AVX2's, each its own chain of
        // maxima), each a plain comparison: NaN counts as none.
        let mut lanes = [0.0f32; 32];
        let larger = |lane: &mut f32, v: &f32| {
            let v = v.abs();
            *lane = if v > *lane { v } else { *lane };
        };
        for b in &b {
            let mut runs = b[..n].chunks_exact(32);
            for run in &mut runs {
                lanes.iter_mut().zip(run).for_each(|(lane, v)| larger(lane, v));
            }
            lanes.iter_mut().zip(runs.remainder()).for_each(|(lane, v)| larger(lane, v));
        }
        let largest = lanes.into_iter().fold(0.0f32, f32::max);
        let (step, scale) = if largest > 0.0 {
            (largest / PACKED_MAX, PACKED_MAX / largest)
        } else {
            (0.0, 0.0)
        };
        for (b, packed) in b.iter().zip(packed) {
            let (b, (packed, rest)) = (&b[..n], packed.split_at_mut(n));
            for (p, &v) in packed.iter_mut().zip(b) {
                // Clamped into `i16`'s range, where the conversion is exact, NaN to the lowest
                // (`clamp` would keep it); rounded first, as the conversion truncates.
                #[allow(clippy::manual_clamp)]
                let q = (v * scale).round_ties_even().max(-PACKED_MAX).min(PACKED_MAX);
                // SAFETY: `q` is a whole number within `±PACKED_MAX`, not NaN.
                *p = unsafe { q.to_int_unchecked::<i32>() } as i16;
            }
            rest.fill(0);
        }
        step
    }
}

/// Each spring's block of `A` (`[xx, yy, zz, xy, xz, yz]`), its ends at `x` and `xn`:
/// `axial·ûûᵀ + transverse·(I − ûûᵀ)`, `axial = h²·k`,
/// `transverse = axial·max(1 − rest/l, floor)` (zero for a spring of zero length), plus its
/// damper `h·d·u₀u₀ᵀ` as `h·c·L₀L₀ᵀ`, `c = d/|L₀|²` (zero for a spring of zero length there:
/// no square root and no division by a length), its ends at the step's start at `start`
/// (`springs = [rest, k, d]`, `hf = [h, floor]`). Zero where there is no spring (`k` and `d`
/// zero). Computed in double precision, stored in `T`'s.
#[inline(always)]
fn blocks_into<T: Lane>(
    b: [&mut [T]; 6],
    ends: ([&[f64]; 3], [&[f64]; 3]),
    start: ([&[f64]; 3], [&[f64]; 3]),
    springs: [&[f64]; 3],
    hf: [f64; 2],
) {
    let [b0, b1, b2, b3, b4, b5] = b;
    let n = b0.len();
    let (b1, b2, b3) = (&mut b1[..n], &mut b2[..n], &mut b3[..n]);
    let (b4, b5) = (&mut b4[..n], &mut b5[..n]);
    let (x, xn) = ends;
    let (x0, x1, x2) = (&x[0][..n], &x[1][..n], &x[2][..n]);
    let (n0, n1, n2) = (&xn[0][..n], &xn[1][..n], &xn[2][..n]);
    let (s0, s1, s2) = (&start.0[0][..n], &start.0[1][..n], &start.0[2][..n]);
    let (t0, t1, t2) = (&start.1[0][..n], &start.1[1][..n], &start.1[2][..n]);
    let (rest, k, damping) = (&springs[0][..n], &springs[1][..n], &springs[2][..n]);
    let [h, floor] = hf;
    let h2 = h * h;
    for i in 0..n {
        let (dx, dy, dz) = (x0[i] - n0[i], x1[i] - n1[i], x2[i] - n2[i]);
        let l = (dx * dx + dy * dy + dz * dz).sqrt();
        let axial = h2 * k[i];
        let transverse = axial * (1.0 - rest[i] / l).max(floor);
        let (ux, uy, uz) = (dx / l, dy / l, dz / l);
        let c = axial - transverse;
        let mut m = if l > 0.0 {
            [
                transverse + c * ux * ux,
                transverse + c * uy * uy,
                transverse + c * uz * uz,
                0.0 + c * ux * uy,
                0.0 + c * ux * uz,
                0.0 + c * uy * uz,
            ]
        } else {
            [0.0; 6]
        };
        // The damper along the spring at the start, `L₀`.
        let (l0, l1, l2) = (s0[i] - t0[i], s1[i] - t1[i], s2[i] - t2[i]);
        let length2 = l0 * l0 + l1 * l1 + l2 * l2;
        let cd = h * if length2 > 0.0 {
            damping[i] / length2
        } else {
            0.0
        };
        m[0] += cd * l0 * l0;
        m[1] += cd * l1 * l1;
        m[2] += cd * l2 * l2;
        m[3] += cd * l0 * l1;
        m[4] += cd * l0 * l2;
        m[5] += cd * l1 * l2;
        (b0[i], b1[i], b2[i]) = (T::of(m[0]), T::of(m[1]), T::of(m[2]));
        (b3[i], b4[i], b5[i]) = (T::of(m[3]), T::of(m[4]), T::of(m[5]));
    }
}

crate::compute::simd::multiversion! {
    /// [`blocks_into`] in double precision.
    pub(super) fn spring_blocks(
        b: [&mut [f64]; 6],
        ends: ([&[f64]; 3], [&[f64]; 3]),
        start: ([&[f64]; 3], [&[f64]; 3]),
        springs: [&[f64]; 3],
        hf: [f64; 2],
    ) {
        blocks_into(b, ends, start, springs, hf)
    }
}

crate::compute::simd::multiversion! {
    /// [`blocks_into`], rounded to single precision.
    pub(super) fn spring_blocks_single(
        b: [&mut [f32]; 6],
        ends: ([&[f64]; 3], [&[f64]; 3]),
        start: ([&[f64]; 3], [&[f64]; 3]),
        springs: [&[f64]; 3],
        hf: [f64; 2],
    ) {
        blocks_into(b, ends, start, springs, hf)
    }
}

/// `y += f` element by element (inlined into each tier's copy of the callers below).
#[inline(always)]
fn add_each<T: Copy + std::ops::AddAssign>(y: [&mut [T]; 3], f: [&[T]; 3]) {
    for (y, f) in y.into_iter().zip(f) {
        for (y, &f) in y.iter_mut().zip(f) {
            *y += f;
        }
    }
}

/// `y −= f` element by element (inlined as [`add_each`] is).
#[inline(always)]
fn subtract_each<T: Copy + std::ops::SubAssign>(y: [&mut [T]; 3], f: [&[T]; 3]) {
    for (y, f) in y.into_iter().zip(f) {
        for (y, &f) in y.iter_mut().zip(f) {
            *y -= f;
        }
    }
}

crate::compute::simd::multiversion! {
    /// `y += f` element by element.
    fn add_forces(y: [&mut [f64]; 3], f: [&[f64]; 3]) {
        add_each(y, f)
    }
}

crate::compute::simd::multiversion! {
    /// `y −= f` element by element.
    fn subtract_forces(y: [&mut [f64]; 3], f: [&[f64]; 3]) {
        subtract_each(y, f)
    }
}

crate::compute::simd::multiversion! {
    /// `y += f` element by element, in single precision.
    fn add_forces_single(y: [&mut [f32]; 3], f: [&[f32]; 3]) {
        add_each(y, f)
    }
}

crate::compute::simd::multiversion! {
    /// `y −= f` element by element, in single precision.
    fn subtract_forces_single(y: [&mut [f32]; 3], f: [&[f32]; 3]) {
        subtract_each(y, f)
    }
}
