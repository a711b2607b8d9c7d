//! The conjugate gradients of the usual solves (those asking for a reduction no finer than
//! [`SINGLE_PRECISION_REDUCTION`], whose products with `A` are in single precision, `A`
//! symmetric and without pairs found at the iterate) with their vectors in single precision
//! too, as structure of arrays: `Δv`, `r`, `z` and `A·p` here, `p` in the springs' product input
//! ([`SpringMatrix::single_input`](super::SpringMatrix::single_input)), and the fine level's
//! `D⁻¹` (the preconditioner's smoother) from each assembly.
//!
//! Each iteration passes over these vectors several times (the product's output and its dot
//! product, the update of `Δv` and `r`, the preconditioner's restriction and smoothing, the new
//! direction): as arrays of `Vec3` in double precision they moved more memory than the
//! product's blocks, and did not vectorise across points. In single precision, as structure of
//! arrays, they move half as many bytes in loops that vectorise. Their sums (`r·r`, `r·z`,
//! `p·A·p`) are taken in double precision, over the fixed chunks of [`sum_chunk`] points (and
//! within a chunk in eight partial sums, point `i`'s into sum `i mod 8`): the same bits on any
//! number of threads and every SIMD tier. Such a solve only steers Newton's method, whose
//! residual stays in double precision, as the single-precision products already did; exact
//! solves keep their vectors in double precision ([`super::solve`]). GMRES's vectors are in
//! single precision too where friction's growth with depth alone makes `A` unsymmetric
//! ([`solve_unsymmetric`]; GMRES had been 10.7 % of a dropped 32³ cube's samples, for 13 % of
//! its linear iterations).
//!
//! [`SINGLE_PRECISION_REDUCTION`]: super::super::SINGLE_PRECISION_REDUCTION

use crate::compute::team;
use crate::vec3::Vec3;

use super::super::gmres::{Gmres, Reached};
use super::super::multigrid::precondition_single;
use super::super::stencil::{dot_single, Precision};
use super::super::{chunk_size, ImplicitScratch, MAX_CG};
use super::recycle::Recycled;
use super::{iterate, sum_chunk, sum_chunks, Passes, Preconditioner};

/// The single-precision conjugate gradients' vectors (structure of arrays) and the fine
/// level's `D⁻¹`, sized for the model's points.
#[derive(Clone, Debug, Default)]
pub(in crate::integrate::implicit) struct SingleVectors {
    dv: [Vec<f32>; 3],
    r: [Vec<f32>; 3],
    z: [Vec<f32>; 3],
    ap: [Vec<f32>; 3],
    /// `[xx, yy, zz, xy, xz, yz]` of each point's inverse diagonal block.
    diag_inv: [Vec<f32>; 6],
    /// The last steps' directions, for a step's first solve ([`Recycled`]).
    recycled: Recycled,
    /// GMRES in single precision, where friction may slide (its growth with depth makes `A`
    /// unsymmetric; see [`solve_unsymmetric`]), and the sums of its preconditioner.
    gmres: Gmres<[Vec<f32>; 3]>,
    sums: Vec<f64>,
}

impl SingleVectors {
    /// For `n` points, all zero; with GMRES's vectors where friction `slides`.
    pub fn zeros(n: usize, slides: bool) -> SingleVectors {
        let v = || std::array::from_fn(|_| vec![0.0; n]);
        SingleVectors {
            dv: v(),
            r: v(),
            z: v(),
            ap: v(),
            diag_inv: std::array::from_fn(|_| vec![0.0; n]),
            recycled: Recycled::new(n),
            gmres: if slides {
                Gmres::new(n)
            } else {
                Gmres::default()
            },
            sums: vec![0.0; sum_chunks(n)],
        }
    }

    /// Whether its GMRES has room for `n` points.
    pub fn gmres_fits(&self, n: usize) -> bool {
        self.gmres.fits(n)
    }

    /// The fine level's `D⁻¹` (each point's inverse diagonal block), rounded to single
    /// precision: at each assembly, after the blocks are inverted.
    pub fn set_diagonal(&mut self, diag_inv: &[[f64; 6]]) {
        let size = chunk_size(diag_inv.len());
        let [a, b, c, d, e, f] = &mut self.diag_inv;
        team::for_each_chunk([a, b, c, d, e, f], size, &|chunk, parts| {
            let blocks = &diag_inv[chunk * size..chunk * size + parts[0].len()];
            for (k, part) in parts.into_iter().enumerate() {
                for (out, block) in part.iter_mut().zip(blocks) {
                    *out = block[k] as f32;
                }
            }
        });
    }
}

/// [`super::solve`] with single-precision vectors: `A·Δv = −M·g` into `s.dv`, preconditioned
/// by `preconditioner`, from zero (a step's first solve from the last steps' directions where
/// they help, and its own direction kept for the next: [`Recycled`]), until the residual has
/// fallen by `reduction` or is within `m·s.within` at every point; false when `A` turns out not
/// to be positive definite, or the preconditioner (then `s.multigrid_failed` says which). `A`
/// symmetric, without pairs found at the iterate (contacts between bodies), its products in
/// single precision.
pub(super) fn solve(
    s: &mut ImplicitScratch,
    reduction: f64,
    preconditioner: Preconditioner,
) -> bool {
    let mut passes = Single {
        v: std::mem::take(&mut s.single),
        preconditioner,
    };
    let iterations = s.stats.linear_iterations;
    let solved = iterate(s, &mut passes, reduction);
    if solved {
        direction_out(s, &passes.v);
        // (A solve its start solved found nothing new: its direction is in their span.)
        if s.recycling && s.stats.linear_iterations > iterations {
            let v = &mut passes.v;
            let given = (&s.g[..], &s.mass[..], &s.free[..]);
            v.recycled.push(s.stats.assemblies, (&v.dv, &v.r), given);
        }
    }
    s.single = passes.v;
    solved
}

/// The conjugate gradients' passes over the single-precision vectors `v`.
struct Single {
    v: SingleVectors,
    preconditioner: Preconditioner,
}

impl Passes for Single {
    fn preconditioner(&self) -> Preconditioner {
        self.preconditioner
    }

    fn start(&mut self, s: &mut ImplicitScratch) -> Option<(f64, bool)> {
        right_hand_side(s, &mut self.v);
        if !s.recycling {
            return None;
        }
        let v = &mut self.v;
        v.recycled.start(
            s.stats.assemblies,
            (&mut v.dv, &mut v.r),
            (&mut v.ap, &mut v.z),
            (&s.mass, s.within),
        )
    }

    fn precondition(&mut self, s: &mut ImplicitScratch) -> f64 {
        let v = &mut self.v;
        let multigrid =
            (self.preconditioner == Preconditioner::Multigrid).then_some(&mut s.multigrid);
        let r = v.r.each_ref().map(|r| &r[..]);
        let z = v.z.each_mut().map(|z| &mut z[..]);
        let (free, precision) = (Some(&s.free[..]), Precision::Single);
        precondition_single(multigrid, free, &v.diag_inv, r, z, precision, &mut s.dots)
    }

    fn set_direction(&mut self, s: &mut ImplicitScratch, beta: Option<f64>) {
        set_direction(s, &self.v, beta);
    }

    fn rr(&mut self, s: &mut ImplicitScratch) -> f64 {
        let r = &self.v.r;
        sums(s.g.len(), &mut s.dots, &|at| {
            let r = r.each_ref().map(|r| &r[at.clone()]);
            dot_single(r, r)
        })
    }

    fn apply_dot(&mut self, s: &mut ImplicitScratch) -> f64 {
        let ap = self.v.ap.each_mut().map(|ap| &mut ap[..]);
        s.springs.apply_dot_single(&s.free, ap, &mut s.dots)
    }

    fn advance(&mut self, s: &mut ImplicitScratch, alpha: f64) -> (f64, bool) {
        advance(s, &mut self.v, alpha)
    }
}

/// The direction `v.dv` into the Newton step's buffer `s.dv`, in double precision.
fn direction_out(s: &mut ImplicitScratch, v: &SingleVectors) {
    let size = chunk_size(s.dv.len());
    let dv = &v.dv;
    team::for_each_chunk([&mut s.dv[..]], size, &|c, [out]| {
        let at = c * size;
        for (i, out) in out.iter_mut().enumerate() {
            let p = at + i;
            *out = Vec3::new(dv[0][p].into(), dv[1][p].into(), dv[2][p].into());
        }
    });
}

/// GMRES (see [`super::solve_unsymmetric`]) with single-precision vectors, for an `A` made
/// unsymmetric by friction's growth with depth alone (no swirl, no pairs found at the
/// iterate), its products in single precision: `A·Δv = −M·g` into `s.dv`; what it reached.
pub(super) fn solve_unsymmetric(
    s: &mut ImplicitScratch,
    reduction: f64,
    preconditioner: Preconditioner,
) -> Reached {
    let mut v = std::mem::take(&mut s.single);
    let mut gmres = std::mem::take(&mut v.gmres);
    let mut sums = std::mem::take(&mut v.sums);
    right_hand_side(s, &mut v);
    let reached = {
        let (springs, free) = (&mut s.springs, &s.free[..]);
        let multigrid = &mut s.multigrid;
        let growth = if s.exact_friction {
            &s.friction_growth[..]
        } else {
            &[]
        };
        let apply = |x: &[Vec<f32>; 3], y: &mut [Vec<f32>; 3]| {
            // `x` into the product's input, then `A·x` with friction's growth.
            let input = springs.single_input();
            let size = chunk_size(input[0].len());
            team::for_each_chunk(input, size, &|c, input| {
                for (input, x) in input.into_iter().zip(x) {
                    input.copy_from_slice(&x[c * size..c * size + input.len()]);
                }
            });
            springs.apply_single(free, y.each_mut().map(|y| &mut y[..]));
            for (p, c) in growth {
                let p = *p as usize;
                let x = [x[0][p], x[1][p], x[2][p]].map(f64::from);
                for (row, y) in y.iter_mut().enumerate() {
                    let c = &c[3 * row..3 * row + 3];
                    y[p] += ((c[0] * x[0] + c[1] * x[1] + c[2] * x[2]) * free[p]) as f32;
                }
            }
        };
        let diag_inv = &v.diag_inv;
        let precondition = |r: &[Vec<f32>; 3], z: &mut [Vec<f32>; 3]| {
            let multigrid =
                (preconditioner == Preconditioner::Multigrid).then_some(&mut *multigrid);
            let (r, z) = (
                r.each_ref().map(|r| &r[..]),
                z.each_mut().map(|z| &mut z[..]),
            );
            precondition_single(
                multigrid,
                Some(free),
                diag_inv,
                r,
                z,
                Precision::Single,
                &mut sums,
            );
        };
        gmres.solve(&v.r, &mut v.dv, reduction, MAX_CG, apply, precondition)
    };
    direction_out(s, &v);
    (v.gmres, v.sums) = (gmres, sums);
    s.single = v;
    reached
}

/// `Σ f(chunk)` over the chunks of [`sum_chunk`] points of `n`, each on the team into `sums`,
/// then in order.
fn sums(n: usize, sums: &mut [f64], f: &(dyn Fn(std::ops::Range<usize>) -> f64 + Sync)) -> f64 {
    let size = sum_chunk(n);
    team::for_each_mut(sums, &|c, sum| *sum = f(c * size..((c + 1) * size).min(n)));
    sums.iter().sum()
}

/// The Newton system's right-hand side `−M·g` into `r` (zero at held points), `Δv` zero.
fn right_hand_side(s: &ImplicitScratch, v: &mut SingleVectors) {
    let (g, mass, free) = (&s.g[..], &s.mass[..], &s.free[..]);
    let size = chunk_size(g.len());
    let [r0, r1, r2] = &mut v.r;
    let [d0, d1, d2] = &mut v.dv;
    team::for_each_chunk(
        [r0, r1, r2, d0, d1, d2],
        size,
        &|c, [r0, r1, r2, d0, d1, d2]| {
            let at = c * size;
            for i in 0..r0.len() {
                let r = g[at + i] * (-mass[at + i] * free[at + i]);
                (r0[i], r1[i], r2[i]) = (r.x as f32, r.y as f32, r.z as f32);
                (d0[i], d1[i], d2[i]) = (0.0, 0.0, 0.0);
            }
        },
    );
}

/// `p = z + β·p` (`p = z` without `β`) in the springs' product input, over the team.
fn set_direction(s: &mut ImplicitScratch, v: &SingleVectors, beta: Option<f64>) {
    let p = s.springs.single_input();
    let size = chunk_size(p[0].len());
    let beta = beta.map(|b| b as f32);
    let z = &v.z;
    team::for_each_chunk(p, size, &|c, p| {
        let at = c * size;
        let z = z.each_ref().map(|z| &z[at..at + p[0].len()]);
        next_direction(z, beta, p);
    });
}

crate::compute::simd::multiversion! {
    /// `p = z + β·p` (`p = z` without `β`), compiled per tier (the same bits on each).
    fn next_direction(z: [&[f32]; 3], beta: Option<f32>, p: [&mut [f32]; 3]) {
        for (z, p) in z.into_iter().zip(p) {
            let p = &mut p[..z.len()];
            match beta {
                Some(beta) => {
                    for (p, &z) in p.iter_mut().zip(z) {
                        *p = z + *p * beta;
                    }
                }
                None => p.copy_from_slice(z),
            }
        }
    }
}

/// `Δv += α·p` and `r −= α·A·p` on the team; returns the new `r·r` and whether `r` is within
/// `m·s.within` at every point (never when `s.within` is 0).
fn advance(s: &mut ImplicitScratch, v: &mut SingleVectors, alpha: f64) -> (f64, bool) {
    let (mass, bound, n) = (&s.mass[..], s.within, s.mass.len());
    let p = s.springs.single_input();
    let p = [&*p[0], &*p[1], &*p[2]];
    let ap = &v.ap;
    let size = sum_chunk(n);
    let [d0, d1, d2] = &mut v.dv;
    let [r0, r1, r2] = &mut v.r;
    let out = &mut s.advanced[..];
    team::for_each_chunk_into(
        [d0, d1, d2, r0, r1, r2],
        size,
        out,
        &|c, [d0, d1, d2, r0, r1, r2]| {
            let at = c * size..c * size + d0.len();
            let p = p.map(|p| &p[at.clone()]);
            let ap = ap.each_ref().map(|ap| &ap[at.clone()]);
            advance_chunk(
                p,
                ap,
                &mass[at],
                alpha as f32,
                bound,
                [d0, d1, d2],
                [r0, r1, r2],
            )
        },
    );
    let rr = s.advanced.iter().map(|&(rr, _)| rr).sum();
    (rr, s.advanced.iter().all(|&(_, within)| within))
}

crate::compute::simd::multiversion! {
    /// One chunk of [`advance`]'s points, compiled per tier (the same bits on each): `r·r` as
    /// [`dot_single`] takes it.
    fn advance_chunk(
        p: [&[f32]; 3],
        ap: [&[f32]; 3],
        mass: &[f64],
        alpha: f32,
        bound: f64,
        dv: [&mut [f32]; 3],
        r: [&mut [f32]; 3],
    ) -> (f64, bool) {
        let [d0, d1, d2] = dv;
        let [r0, r1, r2] = r;
        let n = d0.len();
        let (d1, d2) = (&mut d1[..n], &mut d2[..n]);
        let (r0, r1, r2) = (&mut r0[..n], &mut r1[..n], &mut r2[..n]);
        let [p0, p1, p2] = p.map(|p| &p[..n]);
        let [a0, a1, a2] = ap.map(|a| &a[..n]);
        let mass = &mass[..n];
        for i in 0..n {
            d0[i] += p0[i] * alpha;
            d1[i] += p1[i] * alpha;
            d2[i] += p2[i] * alpha;
            r0[i] -= a0[i] * alpha;
            r1[i] -= a1[i] * alpha;
            r2[i] -= a2[i] * alpha;
        }
        let (r0, r1, r2) = (&*r0, &*r1, &*r2);
        let mut within = bound > 0.0;
        for i in 0..n {
            let norm2 = f64::from(r0[i]) * f64::from(r0[i])
                + f64::from(r1[i]) * f64::from(r1[i])
                + f64::from(r2[i]) * f64::from(r2[i]);
            within &= norm2 <= (mass[i] * bound) * (mass[i] * bound);
        }
        (dot_single([r0, r1, r2], [r0, r1, r2]), within)
    }
}
