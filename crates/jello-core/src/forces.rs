//! The one force routine: springs, force field, box and plane penalties, control forces.
//!
//! Springs are evaluated once each, by the lattice stencil rather than from a spring list: for
//! each chunk of planes and each of the 16 half-stencil offsets, the springs join one contiguous
//! run of points to the same run shifted, so the loop runs over contiguous memory and vectorises
//! (pairs in the run that are no springs are masked to zero force). A block of forces goes to a
//! small buffer, then is added to the first points and subtracted from the second (Newton's third
//! law), each a plain vectorisable loop.
//!
//! Threads work on fixed chunks of [`CHUNK_PLANES`] planes. A chunk writes its own planes and a
//! private halo for the (at most two) planes after it, which is added once every chunk is done.
//! The chunking does not depend on the thread count, so neither does any sum: results are bit
//! for bit the same on 1 thread or many.

use crate::model::Model;
use crate::soa::Soa;
use crate::state::Control;
use crate::vec3::Vec3;

#[cfg(feature = "parallel")]
use rayon::prelude::*;

/// Point planes (constant `i`) per chunk of spring work. Fixed, so results never depend on the
/// number of threads.
pub const CHUNK_PLANES: usize = 4;

/// Springs evaluated per block of a run: the block's forces stay in the L1 cache between being
/// computed and being added to the points.
const RUN_BLOCK: usize = 512;

/// Planes a spring reaches beyond its first point's plane (bend springs reach 2).
const HALO_PLANES: usize = 2;

/// Lattices with fewer points than this are stepped on the calling thread only (the work would
/// not pay for waking others). The results are the same either way.
pub const PARALLEL_MIN_POINTS: usize = 8 * 1024;

/// The half stencil: offsets `(di, dj, dk)` whose first non-zero component is positive, with
/// the spring kind (0 structural, 1 shear, 2 bend). Same entries and order as
/// [`crate::lattice::Lattice::springs`].
const STENCIL: [([isize; 3], usize); 16] = [
    ([1, 0, 0], 0),
    ([0, 1, 0], 0),
    ([0, 0, 1], 0),
    ([1, 1, 0], 1),
    ([1, -1, 0], 1),
    ([1, 0, 1], 1),
    ([1, 0, -1], 1),
    ([0, 1, 1], 1),
    ([0, 1, -1], 1),
    ([1, 1, 1], 1),
    ([1, 1, -1], 1),
    ([1, -1, 1], 1),
    ([1, -1, -1], 1),
    ([2, 0, 0], 2),
    ([0, 2, 0], 2),
    ([0, 0, 2], 2),
];

/// Buffers of the force routine, sized once for a model.
#[derive(Clone, Debug, Default)]
pub struct ForceScratch {
    /// Spring forces (N) per point.
    spring: Soa,
    /// Per chunk: forces on the [`HALO_PLANES`] planes after the chunk.
    halos: Vec<Soa>,
    /// Per chunk: the forces of one block of springs.
    rows: Vec<Soa>,
    /// Per `dk + 1` (dk = −1, 0, 1, 2): 1 where a point's column `k` has a partner at `k + dk`,
    /// else 0, for every point of a plane.
    masks: Masks,
}

/// Per stencil class `(dj, dk)` (index `(dj + 1)·4 + dk + 1`, both in −1..=2): for every point
/// of a chunk of [`CHUNK_PLANES`] planes, 1 where the point at `(j + dj, k + dk)` exists, else 0.
type Masks = Vec<Vec<f64>>;

impl ForceScratch {
    /// Buffers for `model`.
    pub fn new(model: &Model) -> Self {
        let [nx, ny, nz] = model.lattice.counts;
        let chunks = nx.div_ceil(CHUNK_PLANES);
        let chunk = CHUNK_PLANES.min(nx) * ny * nz;
        let mask = |dj: isize, dk: isize| -> Vec<f64> {
            (0..chunk)
                .map(|t| {
                    let j = ((t / nz) % ny) as isize + dj;
                    let k = (t % nz) as isize + dk;
                    let inside = (0..ny as isize).contains(&j) && (0..nz as isize).contains(&k);
                    if inside {
                        1.0
                    } else {
                        0.0
                    }
                })
                .collect()
        };
        let masks = (0..16).map(|c| mask(c / 4 - 1, c % 4 - 1)).collect();
        ForceScratch {
            spring: Soa::zeros(model.point_count()),
            halos: vec![Soa::zeros(HALO_PLANES * ny * nz); chunks],
            rows: vec![Soa::zeros(RUN_BLOCK.min(CHUNK_PLANES.min(nx) * ny * nz)); chunks],
            masks,
        }
    }

    fn fits(&self, model: &Model) -> bool {
        let [nx, ny, nz] = model.lattice.counts;
        self.spring.len() == model.point_count()
            && self.halos.len() == nx.div_ceil(CHUNK_PLANES)
            && self
                .halos
                .first()
                .is_none_or(|h| h.len() == HALO_PLANES * ny * nz)
            && self
                .rows
                .first()
                .is_none_or(|r| r.len() == RUN_BLOCK.min(CHUNK_PLANES.min(nx) * ny * nz))
            && self.masks[0].len() == CHUNK_PLANES.min(nx) * ny * nz
    }
}

/// Acceleration of every point (m/s²) at positions `pos` and velocities `vel`, written to `acc`.
///
/// All slices have the model's point count. Total force over mass, where the force on a point is
/// (SPEC.md): the sum of its spring forces, plus the interpolated force field, plus one penalty
/// spring per box wall it is strictly outside of, plus the plane penalty when it is on the
/// forbidden side, plus the control force. This form allocates its buffers; the integrators use
/// [`accelerations_soa`] with buffers of their own.
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
    let n = model.point_count();
    assert!(
        p.len() == n && v.len() == n && acc.len() == n,
        "buffers must have the point count"
    );
    assert!(
        control.forces.is_empty() || control.forces.len() == n,
        "control forces must be empty or one per point"
    );
    if !scratch.fits(model) {
        *scratch = ForceScratch::new(model);
    }
    spring_forces(model, p, v, scratch);
    point_forces(model, p, v, control, &scratch.spring, acc);
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
    fn new(model: &Model) -> Self {
        let [nx, ny, nz] = model.lattice.counts;
        let h = model.lattice.spacing();
        let mut rest = [0.0; 16];
        for (r, (d, _)) in rest.iter_mut().zip(STENCIL) {
            // The same expression as Lattice::springs, so the rest lengths agree bit for bit.
            *r = Vec3::new(d[0] as f64 * h.x, d[1] as f64 * h.y, d[2] as f64 * h.z).length();
        }
        Grid {
            nx,
            ny,
            nz,
            stiffness: model.stiffness,
            damping: model.damping,
            rest,
        }
    }
}

/// One chunk's share of the spring pass: its index, its slices of the x, y and z forces, its
/// halo and its row buffer.
type ChunkWork<'a> = (
    usize,
    (
        ((&'a mut [f64], &'a mut [f64]), &'a mut [f64]),
        (&'a mut Soa, &'a mut Soa),
    ),
);

/// All spring forces into `scratch.spring`.
fn spring_forces(model: &Model, p: &Soa, v: &Soa, scratch: &mut ForceScratch) {
    let grid = Grid::new(model);
    let plane = grid.ny * grid.nz;
    let chunk_len = CHUNK_PLANES * plane;
    let ForceScratch {
        spring,
        halos,
        rows,
        masks,
    } = scratch;
    let masks = &*masks;
    let work = |(c, (((fx, fy), fz), (halo, row))): ChunkWork<'_>| {
        chunk_springs(
            &grid,
            masks,
            p,
            v,
            c * CHUNK_PLANES,
            [fx, fy, fz],
            halo,
            row,
        );
    };

    #[cfg(feature = "parallel")]
    if model.point_count() >= PARALLEL_MIN_POINTS {
        let [sx, sy, sz] = spring.parts_mut();
        sx.par_chunks_mut(chunk_len)
            .zip(sy.par_chunks_mut(chunk_len))
            .zip(sz.par_chunks_mut(chunk_len))
            .zip(halos.par_iter_mut().zip(rows.par_iter_mut()))
            .enumerate()
            .for_each(work);
        add_halos(&grid, spring, halos);
        return;
    }
    let [sx, sy, sz] = spring.parts_mut();
    sx.chunks_mut(chunk_len)
        .zip(sy.chunks_mut(chunk_len))
        .zip(sz.chunks_mut(chunk_len))
        .zip(halos.iter_mut().zip(rows.iter_mut()))
        .enumerate()
        .for_each(work);
    add_halos(&grid, spring, halos);
}

/// Adds each chunk's halo to the planes after it, in chunk order.
fn add_halos(grid: &Grid, spring: &mut Soa, halos: &[Soa]) {
    let plane = grid.ny * grid.nz;
    for (c, halo) in halos.iter().enumerate() {
        let start = (c + 1) * CHUNK_PLANES * plane;
        let end = (start + HALO_PLANES * plane).min(spring.len());
        if start >= end {
            continue;
        }
        let len = end - start;
        for (f, h) in spring
            .parts_mut()
            .into_iter()
            .zip([halo.x(), halo.y(), halo.z()])
        {
            for (a, b) in f[start..end].iter_mut().zip(&h[..len]) {
                *a += *b;
            }
        }
    }
}

crate::simd::multiversion! {
    /// The springs whose first point lies in planes `i0 .. i0 + CHUNK_PLANES`, into `own` (forces
    /// on those planes, zeroed here) and `halo` (forces on the two planes after them).
    fn chunk_springs(
        grid: &Grid,
        masks: &Masks,
        p: &Soa,
        v: &Soa,
        i0: usize,
        own: [&mut [f64]; 3],
        halo: &mut Soa,
        row: &mut Soa,
    ) {
        chunk_springs_impl(grid, masks, p, v, i0, own, halo, row)
    }
}

/// Walks the springs of the chunk stencil entry by stencil entry, in blocks of the row buffer's
/// length. For one entry `(di, dj, dk)` the first points of its springs form one contiguous run
/// through the chunk's planes, and the second points the same run shifted by a constant. The run
/// also holds pairs that wrap from the end of a row or plane into the next: those are no springs,
/// and their force is multiplied by 0 (the masks), which keeps the loop branch-free and vectorised.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn chunk_springs_impl(
    grid: &Grid,
    masks: &Masks,
    p: &Soa,
    v: &Soa,
    i0: usize,
    own: [&mut [f64]; 3],
    halo: &mut Soa,
    row: &mut Soa,
) {
    let Grid { nx, ny, nz, .. } = *grid;
    let plane = ny * nz;
    let [ox, oy, oz] = own;
    let own_planes = ox.len() / plane;
    let (base, halo_base) = (i0 * plane, (i0 + own_planes) * plane);
    for f in [&mut *ox, &mut *oy, &mut *oz] {
        f.fill(0.0);
    }
    halo.fill_zero();
    let block = row.len();

    // Stencil entry by entry: the first ends of an entry's springs in the whole chunk form one
    // contiguous run (from plane i0, row j_lo, column k_lo to the last plane with a partner,
    // row j_hi − 1, column k_hi − 1), and the second ends the same run shifted. Pairs in the run
    // that are no springs (a row or plane wrapping into the next) get force 0 from the masks.
    for (s, &([di, dj, dk], kind)) in STENCIL.iter().enumerate() {
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
            continue;
        }
        let t_start = j_lo * nz + k_lo;
        let t_end = (i_end - 1 - i0) * plane + (j_hi - 1) * nz + k_hi;
        let shift = ((di * ny as isize + dj) * nz as isize + dk) as usize;
        let mask = &masks[((dj + 1) * 4 + dk + 1) as usize];
        let spring = SpringConst {
            k: grid.stiffness[kind],
            d: grid.damping[kind],
            rest: grid.rest[s],
        };
        let mut t = t_start;
        while t < t_end {
            let len = block.min(t_end - t);
            let (a, b) = (base + t, base + t + shift);
            // Forces to the row buffer, then added to the first points and subtracted from the
            // second (Newton's third law). Two plain loops vectorise where one loop writing both
            // would not: the two runs may overlap.
            spring_run(p, v, a, b, len, spring, &mask[t..t + len], row);
            add_run([&mut *ox, &mut *oy, &mut *oz], t, tail(row, 0), len, 1.0);
            let cut = halo_base.saturating_sub(b).min(len);
            if cut > 0 {
                add_run(
                    [&mut *ox, &mut *oy, &mut *oz],
                    b - base,
                    tail(row, 0),
                    cut,
                    -1.0,
                );
            }
            if cut < len {
                // The rest of the run lies in the planes after the chunk.
                let h = halo.parts_mut();
                add_run(h, (b + cut) - halo_base, tail(row, cut), len - cut, -1.0);
            }
            t += len;
        }
    }
}

/// Stiffness (N/m), damping (N·s/m) and rest length (m) of the springs of one stencil entry.
#[derive(Clone, Copy)]
struct SpringConst {
    k: f64,
    d: f64,
    rest: f64,
}

/// The components of `row` from element `from` on.
fn tail(row: &Soa, from: usize) -> [&[f64]; 3] {
    [&row.x()[from..], &row.y()[from..], &row.z()[from..]]
}

/// Forces on the points `a .. a + len` from the springs joining them to `b .. b + len`:
/// `f = −k (|L| − R) L̂ − d ((vA − vB)·L̂) L̂` with `L = pA − pB`, computed with one square root
/// and one division per spring, times `mask` (1 for a spring, 0 for a pair that is none;
/// multiplying by 1 changes nothing). A zero-length spring has no direction and exerts no force.
#[inline(always)]
#[allow(clippy::too_many_arguments)]
fn spring_run(
    p: &Soa,
    v: &Soa,
    a: usize,
    b: usize,
    len: usize,
    c: SpringConst,
    mask: &[f64],
    row: &mut Soa,
) {
    let (xa, ya, za) = (&p.x()[a..a + len], &p.y()[a..a + len], &p.z()[a..a + len]);
    let (xb, yb, zb) = (&p.x()[b..b + len], &p.y()[b..b + len], &p.z()[b..b + len]);
    let (ua, va, wa) = (&v.x()[a..a + len], &v.y()[a..a + len], &v.z()[a..a + len]);
    let (ub, vb, wb) = (&v.x()[b..b + len], &v.y()[b..b + len], &v.z()[b..b + len]);
    let mask = &mask[..len];
    let [fx, fy, fz] = row.parts_mut();
    let (fx, fy, fz) = (&mut fx[..len], &mut fy[..len], &mut fz[..len]);
    for t in 0..len {
        let (dx, dy, dz) = (xa[t] - xb[t], ya[t] - yb[t], za[t] - zb[t]);
        let l2 = dx * dx + dy * dy + dz * dz;
        let inv = if l2 > 0.0 { 1.0 / l2.sqrt() } else { 0.0 };
        let l = l2 * inv;
        let closing = ((ua[t] - ub[t]) * dx + (va[t] - vb[t]) * dy + (wa[t] - wb[t]) * dz) * inv;
        // Magnitude along L̂, times L̂ = L·inv, times the mask.
        let s = (-c.k * (l - c.rest) - c.d * closing) * inv * mask[t];
        (fx[t], fy[t], fz[t]) = (dx * s, dy * s, dz * s);
    }
}

/// `f[at .. at + len] += sign · row[.. len]`, component by component.
#[inline(always)]
fn add_run(f: [&mut [f64]; 3], at: usize, row: [&[f64]; 3], len: usize, sign: f64) {
    for (f, r) in f.into_iter().zip(row) {
        let (f, r) = (&mut f[at..at + len], &r[..len]);
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

/// Per point: spring force plus field, walls, plane and control, over the mass.
fn point_forces(model: &Model, p: &Soa, v: &Soa, control: &Control, spring: &Soa, acc: &mut Soa) {
    const BLOCK: usize = 4096;
    let work = |start: usize, a: [&mut [f64]; 3]| {
        point_forces_block(model, p, v, control, spring, start, a)
    };
    #[cfg(feature = "parallel")]
    if model.point_count() >= PARALLEL_MIN_POINTS {
        let [ax, ay, az] = acc.parts_mut();
        ax.par_chunks_mut(BLOCK)
            .zip(ay.par_chunks_mut(BLOCK))
            .zip(az.par_chunks_mut(BLOCK))
            .enumerate()
            .for_each(|(c, ((x, y), z))| work(c * BLOCK, [x, y, z]));
        return;
    }
    work(0, acc.parts_mut());
}

crate::simd::multiversion! {
    /// [`point_forces_impl`], compiled for AVX-512 too (floors and selects in vector registers).
    fn point_forces_block(
        model: &Model,
        p: &Soa,
        v: &Soa,
        control: &Control,
        spring: &Soa,
        start: usize,
        acc: [&mut [f64]; 3],
    ) {
        point_forces_impl(model, p, v, control, spring, start, acc)
    }
}

/// Accelerations of the points `start .. start + acc[0].len()`.
#[inline(always)]
fn point_forces_impl(
    model: &Model,
    p: &Soa,
    v: &Soa,
    control: &Control,
    spring: &Soa,
    start: usize,
    acc: [&mut [f64]; 3],
) {
    let [ax, ay, az] = acc;
    let len = ax.len();
    let (ay, az) = (&mut ay[..len], &mut az[..len]);
    let r = start..start + len;
    let (px, py, pz) = (&p.x()[r.clone()], &p.y()[r.clone()], &p.z()[r.clone()]);
    let (vx, vy, vz) = (&v.x()[r.clone()], &v.y()[r.clone()], &v.z()[r.clone()]);
    let (sx, sy, sz) = (
        &spring.x()[r.clone()],
        &spring.y()[r.clone()],
        &spring.z()[r.clone()],
    );
    let (kc, dc, mass) = (model.k_collision, model.d_collision, model.mass);
    let (lo, hi) = (model.bounds.min, model.bounds.max);

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
    // Then walls, plane and control, over the mass: branch-free, so it vectorises.
    let plane = model
        .plane
        .map(|pl| (pl, pl.normal_length(), pl.inward_normal()));
    let control = (!control.forces.is_empty()).then(|| &control.forces[r.clone()]);
    for t in 0..len {
        let mut f = match constant {
            Some(c) => Vec3::new(sx[t], sy[t], sz[t]) + c,
            None => Vec3::new(ax[t], ay[t], az[t]),
        };
        let (pi, vi) = (
            Vec3::new(px[t], py[t], pz[t]),
            Vec3::new(vx[t], vy[t], vz[t]),
        );
        // Walls: `kCollision·depth·n − dCollision (v·n) n` with n = ±axis.
        f.x += wall(pi.x, vi.x, lo.x, hi.x, kc, dc);
        f.y += wall(pi.y, vi.y, lo.y, hi.y, kc, dc);
        f.z += wall(pi.z, vi.z, lo.z, hi.z, kc, dc);
        if let Some((pl, norm, n)) = plane {
            let s = pl.value(pi);
            let depth = s.abs() / norm;
            let push = n * (kc * depth) - n * (dc * vi.dot(n));
            f += if s * pl.side < 0.0 { push } else { Vec3::ZERO };
        }
        if let Some(c) = control {
            f += c[t];
        }
        let a = f / mass;
        (ax[t], ay[t], az[t]) = (a.x, a.y, a.z);
    }
}

/// The force along one axis of the walls at `lo` and `hi` on a point at `c` moving at `v`.
#[inline(always)]
fn wall(c: f64, v: f64, lo: f64, hi: f64, kc: f64, dc: f64) -> f64 {
    if c < lo {
        kc * (lo - c) - dc * v
    } else if c > hi {
        -(kc * (c - hi)) - dc * v
    } else {
        0.0
    }
}

/// Depth (m) of the deepest penetration of any point into a box wall or the plane (0 if none).
pub fn max_penetration(model: &Model, pos: &[Vec3]) -> f64 {
    pos.iter()
        .map(|&p| {
            let wall = model.bounds.excursion(p);
            let plane = model
                .plane
                .and_then(|pl| pl.penetration(p))
                .map_or(0.0, |(depth, _)| depth);
            wall.max(plane)
        })
        .fold(0.0, f64::max)
}
