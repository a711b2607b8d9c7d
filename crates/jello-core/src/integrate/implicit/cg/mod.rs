//! The linear solves for the Newton direction: conjugate gradients (GMRES where a field swirls)
//! preconditioned by the multigrid cycle, with `A·x` in stencil order and the dot products
//! summed over fixed chunks on the step's team.

mod recycle;
pub(super) mod single;

use crate::compute::team;
use crate::vec3::Vec3;

use super::multigrid::{Multigrid, Operator};
use super::stencil::{Precision, SpringMatrix};
use super::sym::{sym_mul, Sym};
use super::{chunk_size, precision_for, ImplicitScratch, MAX_CG, MIN_CHUNK};

/// `A`'s parts that are not symmetric, each a 3×3 matrix (row by row) of one point's: a
/// field's at every point (where its swirl is taken), and friction's growth with depth at the
/// points listed with theirs.
pub(super) type Unsymmetric<'a> = (Option<&'a [[f64; 9]]>, &'a [(u32, [f64; 9])]);

/// `y = A·x` over the free points (others give 0), with `A`'s unsymmetric parts where given.
#[allow(clippy::too_many_arguments)]
pub(super) fn apply_to(
    springs: &mut SpringMatrix,
    free: &[f64],
    pair_rows: &[[u32; 2]],
    pair_blocks: &[Sym],
    (field_correction, growth): Unsymmetric,
    x: &[Vec3],
    y: &mut [Vec3],
    precision: Precision,
) {
    springs.apply(free, x, y, precision);
    for (&[a, c], b) in pair_rows.iter().zip(pair_blocks) {
        let (a, c) = (a as usize, c as usize);
        let f = sym_mul(b, x[a] - x[c]);
        y[a] += f * free[a];
        y[c] -= f * free[c];
    }
    for (((y, &x), c), &free) in y
        .iter_mut()
        .zip(x)
        .zip(field_correction.unwrap_or(&[]))
        .zip(free)
    {
        *y += times(c, x) * free;
    }
    for (p, c) in growth {
        let p = *p as usize;
        y[p] += times(c, x[p]) * free[p];
    }
}

/// `c·x`, `c` a 3×3 matrix row by row.
fn times(c: &[f64; 9], x: Vec3) -> Vec3 {
    let row = |i: usize| c[3 * i] * x.x + c[3 * i + 1] * x.y + c[3 * i + 2] * x.z;
    Vec3::new(row(0), row(1), row(2))
}

/// `s.ap = A·s.p` (`A` symmetric), the springs' part in `precision`; returns `p·A·p`, summed
/// as [`dot`] sums it: in the product's last pass where the springs make all of `A` (no
/// contacts between bodies at the iterate).
fn apply_dot(s: &mut ImplicitScratch, precision: Precision) -> f64 {
    if s.pair_rows.is_empty() {
        let (free, sums) = (&s.free[..], &mut s.dots[..]);
        return s.springs.apply_dot(free, &s.p, &mut s.ap, precision, sums);
    }
    let pairs = (&s.pair_rows[..], &s.pair_blocks[..]);
    apply_to(
        &mut s.springs,
        &s.free,
        pairs.0,
        pairs.1,
        (None, &[]),
        &s.p,
        &mut s.ap,
        precision,
    );
    dot(&s.p, &s.ap, &mut s.dots)
}

/// Points per chunk of the conjugate gradients' sums over `n` points: fixed by `n` alone (the
/// chunks decide the order of the additions: the same bits on any number of threads), at most
/// [`team::OWNED_ITEMS`] of them (so each stays on one thread from loop to loop), and no fewer
/// than [`MIN_CHUNK`] points each.
pub(super) fn sum_chunk(n: usize) -> usize {
    n.div_ceil(team::OWNED_ITEMS).max(MIN_CHUNK)
}

/// Chunks of [`sum_chunk`] points in `n` points.
pub(super) fn sum_chunks(n: usize) -> usize {
    n.div_ceil(sum_chunk(n))
}

/// `a·b`: each chunk of [`sum_chunk`] points summed in order on the team (into `sums`, one per
/// chunk), then the chunks' sums in order. Summed by the leader alone, the conjugate gradients'
/// products kept the other thread waiting (16³ benchmark, 2 threads).
pub(super) fn dot(a: &[Vec3], b: &[Vec3], sums: &mut [f64]) -> f64 {
    let size = sum_chunk(a.len());
    team::for_each_mut(sums, &|c, sum| {
        let chunk = c * size..((c + 1) * size).min(a.len());
        *sum = dot_chunk(&a[chunk.clone()], &b[chunk]);
    });
    sums.iter().sum()
}

crate::compute::simd::multiversion! {
    /// `a·b` over one chunk, in order, compiled per tier (the same bits on each).
    pub(super) fn dot_chunk(a: &[Vec3], b: &[Vec3]) -> f64 {
        a.iter().zip(b).map(|(a, b)| a.dot(*b)).sum()
    }
}

/// One step of the conjugate gradients, `Δv += α·p` and `r −= α·A·p`, on the team; returns
/// the new `r·r` (summed as [`dot`] sums) and whether `r` is within `m·s.within` at every point
/// (never when `s.within` is 0: then only the reduction stops a solve).
pub(super) fn advance(s: &mut ImplicitScratch, alpha: f64) -> (f64, bool) {
    let (p, ap, mass, bound) = (&s.p[..], &s.ap[..], &s.mass[..], s.within);
    let size = sum_chunk(p.len());
    let sums = &mut s.advanced[..];
    team::for_each_chunk_into([&mut s.dv, &mut s.r], size, sums, &|c, [dv, r]| {
        let at = c * size;
        let (p, ap, mass) = (&p[at..], &ap[at..], &mass[at..]);
        advance_chunk(p, ap, mass, alpha, bound, dv, r)
    });
    let rr = s.advanced.iter().map(|&(rr, _)| rr).sum();
    (rr, s.advanced.iter().all(|&(_, within)| within))
}

crate::compute::simd::multiversion! {
    /// One chunk of [`advance`]'s points, compiled per tier (the same bits on each).
    fn advance_chunk(
        p: &[Vec3],
        ap: &[Vec3],
        mass: &[f64],
        alpha: f64,
        bound: f64,
        dv: &mut [Vec3],
        r: &mut [Vec3],
    ) -> (f64, bool) {
        let n = dv.len();
        let (p, ap, mass, r) = (&p[..n], &ap[..n], &mass[..n], &mut r[..n]);
        let (mut rr, mut within) = (0.0, bound > 0.0);
        for i in 0..n {
            dv[i] += p[i] * alpha;
            r[i] -= ap[i] * alpha;
            let r2 = r[i].length_squared();
            rr += r2;
            within &= r2 <= (mass[i] * bound) * (mass[i] * bound);
        }
        (rr, within)
    }
}

crate::compute::simd::multiversion! {
    /// `p = z + β·p` (`p = z` without `β`), and `p` rounded to single precision into `single`
    /// (structure of arrays: the next product's input, see [`SpringMatrix::single_input`]);
    /// compiled per tier (the same bits on each).
    fn next_direction(z: &[Vec3], beta: Option<f64>, p: &mut [Vec3], single: [&mut [f32]; 3]) {
        let [s0, s1, s2] = single;
        let n = p.len();
        let (z, s0, s1, s2) = (&z[..n], &mut s0[..n], &mut s1[..n], &mut s2[..n]);
        for i in 0..n {
            p[i] = match beta {
                Some(beta) => z[i] + p[i] * beta,
                None => z[i],
            };
            (s0[i], s1[i], s2[i]) = (p[i].x as f32, p[i].y as f32, p[i].z as f32);
        }
    }
}

/// `p = z + β·p` (`p = z` without `β`) over the team, with `p` in single precision into the
/// springs' product input where the solve's products are in single precision: the product then
/// does not load it in a pass of its own.
fn set_direction(s: &mut ImplicitScratch, beta: Option<f64>, precision: Precision) {
    let (z, size) = (&s.z[..], chunk_size(s.z.len()));
    if precision == Precision::Double {
        team::for_each_chunk([&mut s.p[..]], size, &|c, [p]| {
            for (p, &z) in p.iter_mut().zip(&z[c * size..]) {
                *p = beta.map_or(z, |beta| z + *p * beta);
            }
        });
        return;
    }
    let parts = ([&mut s.p[..]], s.springs.single_input());
    team::for_each_chunk_pair(parts, size, &|c, ([p], single)| {
        next_direction(&z[c * size..], beta, p, single);
    });
}

/// The preconditioner of [`solve`].
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Preconditioner {
    /// A multigrid cycle ([`Multigrid::precondition`]).
    Multigrid,
    /// `A`'s diagonal blocks.
    Diagonal,
}

/// Solves `A·Δv = −M·g` into `s.dv` by conjugate gradients preconditioned by `preconditioner`,
/// from zero (a step's first solve, `s.recycling`, from the last steps' directions where they
/// help: [`recycle`]), until its residual has fallen by `reduction` from the right-hand side's
/// or is within `m·s.within` at every point; false when `A` turns out not to be positive
/// definite, or the preconditioner (then `s.multigrid_failed` says which).
pub(super) fn solve(
    s: &mut ImplicitScratch,
    reduction: f64,
    preconditioner: Preconditioner,
) -> bool {
    s.multigrid_failed = false;
    if s.unsymmetric() {
        return solve_unsymmetric(s, reduction, preconditioner);
    }
    let precision = precision_for(reduction);
    // Vectors in single precision too, where the products are (see `single`) and `A` has no
    // pairs found at the iterate (contacts between bodies, whose products take `Vec3`s).
    if precision == Precision::Single && s.pair_rows.is_empty() {
        return single::solve(s, reduction, preconditioner);
    }
    let mut double = Double {
        preconditioner,
        precision,
    };
    iterate(s, &mut double, reduction)
}

/// The passes of a conjugate-gradient iteration over its vectors, each on the team: in double
/// precision as `Vec3`s ([`Double`]) or in single precision as structure of arrays
/// ([`single`]). [`iterate`] is the loop that calls them.
trait Passes {
    /// The preconditioner `precondition` applies.
    fn preconditioner(&self) -> Preconditioner;
    /// `Δv = 0` and `r = −M·g` (zero at held points); or, for a step's first solve, the start
    /// the last steps' directions give where it lowers the residual (see [`recycle`]), and then
    /// `b·b` for `b = −M·g` and whether that start is within `m·s.within` at every point.
    fn start(&mut self, s: &mut ImplicitScratch) -> Option<(f64, bool)>;
    /// `z = P⁻¹·r`; returns `r·z`.
    fn precondition(&mut self, s: &mut ImplicitScratch) -> f64;
    /// `p = z + β·p` (`p = z` without `β`).
    fn set_direction(&mut self, s: &mut ImplicitScratch, beta: Option<f64>);
    /// `r·r`.
    fn rr(&mut self, s: &mut ImplicitScratch) -> f64;
    /// `A·p`; returns `p·A·p`.
    fn apply_dot(&mut self, s: &mut ImplicitScratch) -> f64;
    /// `Δv += α·p` and `r −= α·A·p`; returns the new `r·r` and whether `r` is within
    /// `m·s.within` at every point (never when `s.within` is 0).
    fn advance(&mut self, s: &mut ImplicitScratch, alpha: f64) -> (f64, bool);
}

/// The conjugate gradients over `passes`' vectors from the start `passes.start` gives (zero,
/// or the last steps' directions' best), until the residual has fallen by `reduction` from the
/// right-hand side's or is within `m·s.within` at every point (a start within it is the
/// solution); false when `A` turns out not to be positive definite, or the preconditioner
/// (then `s.multigrid_failed` says which).
fn iterate(s: &mut ImplicitScratch, passes: &mut impl Passes, reduction: f64) -> bool {
    // A negative `r·z` shows an indefinite preconditioner, `A` itself only with the diagonal.
    let multigrid = passes.preconditioner() == Preconditioner::Multigrid;
    let fail = |s: &mut ImplicitScratch| {
        s.multigrid_failed = multigrid;
        false
    };
    let started = passes.start(s);
    if started.is_some_and(|(_, within)| within) {
        return true;
    }
    let mut rz = passes.precondition(s);
    passes.set_direction(s, None);
    let mut rr = passes.rr(s);
    // The reduction is of the right-hand side's residual, wherever the solve starts.
    let target = started.map_or(rr, |(bb, _)| bb) * reduction * reduction;
    if !rz.is_finite() {
        return false;
    }
    if rz < 0.0 {
        return fail(s);
    }
    // Whether the residual is within its bound at every point (not judged before a first step).
    let mut within = false;
    for _ in 0..MAX_CG {
        if rr <= target || rz == 0.0 || within {
            break;
        }
        let pap = passes.apply_dot(s);
        s.stats.linear_iterations += 1;
        if pap <= 0.0 || !pap.is_finite() {
            return false;
        }
        (rr, within) = passes.advance(s, rz / pap);
        let rz_next = passes.precondition(s);
        if rz_next < 0.0 {
            return fail(s);
        }
        let beta = rz_next / rz;
        rz = rz_next;
        passes.set_direction(s, Some(beta));
    }
    true
}

/// The conjugate gradients' vectors in double precision (`Vec3`s in the scratch), the
/// products in `precision`.
struct Double {
    preconditioner: Preconditioner,
    precision: Precision,
}

impl Passes for Double {
    fn preconditioner(&self) -> Preconditioner {
        self.preconditioner
    }

    fn start(&mut self, s: &mut ImplicitScratch) -> Option<(f64, bool)> {
        s.dv.fill(Vec3::ZERO);
        set_right_hand_side(s);
        None
    }

    fn precondition(&mut self, s: &mut ImplicitScratch) -> f64 {
        let fine = fine_diagonal!(s);
        precondition_with(
            self.preconditioner,
            &mut s.multigrid,
            &fine,
            (&s.r, &mut s.z),
            self.precision,
            &mut s.dots,
        )
    }

    fn set_direction(&mut self, s: &mut ImplicitScratch, beta: Option<f64>) {
        set_direction(s, beta, self.precision);
    }

    fn rr(&mut self, s: &mut ImplicitScratch) -> f64 {
        dot(&s.r, &s.r, &mut s.dots)
    }

    fn apply_dot(&mut self, s: &mut ImplicitScratch) -> f64 {
        apply_dot(s, self.precision)
    }

    fn advance(&mut self, s: &mut ImplicitScratch, alpha: f64) -> (f64, bool) {
        advance(s, alpha)
    }
}

/// Solves `A·Δv = −M·g` into `s.dv` by GMRES when `A` holds a field's swirl or the growth of
/// sliding friction with depth (so is not symmetric), preconditioned as [`solve`] is, from `A`'s
/// symmetric part. True when the residual fell by `reduction`; with the diagonal
/// preconditioner, also when it fell by half at least, which is enough for a direction along
/// which `|g|²_M` falls.
fn solve_unsymmetric(
    s: &mut ImplicitScratch,
    reduction: f64,
    preconditioner: Preconditioner,
) -> bool {
    let precision = precision_for(reduction);
    let reached = if precision == Precision::Single
        && !s.swirl
        && s.pair_rows.is_empty()
        && s.single.gmres_fits(s.g.len())
    {
        single::solve_unsymmetric(s, reduction, preconditioner)
    } else {
        solve_unsymmetric_double(s, reduction, preconditioner)
    };
    s.stats.linear_iterations += reached.iterations as u64;
    if reached.relative_residual <= reduction {
        return true;
    }
    match preconditioner {
        Preconditioner::Multigrid => {
            s.multigrid_failed = true;
            false
        }
        Preconditioner::Diagonal => reached.relative_residual <= 0.5,
    }
}

/// [`solve_unsymmetric`]'s GMRES with `Vec3`s in double precision (a swirling field, pairs
/// found at the iterate, or an exact solve); what it reached.
fn solve_unsymmetric_double(
    s: &mut ImplicitScratch,
    reduction: f64,
    preconditioner: Preconditioner,
) -> super::gmres::Reached {
    set_right_hand_side(s);
    let mut gmres = std::mem::take(&mut s.gmres);
    let reached = {
        let fine = fine_diagonal!(s);
        let (springs, multigrid) = (&mut s.springs, &mut s.multigrid);
        let pairs = (&s.pair_rows[..], &s.pair_blocks[..]);
        let field = s.swirl.then_some(&s.field_correction[..]);
        let growth = if s.exact_friction {
            &s.friction_growth[..]
        } else {
            &[]
        };
        let precision = precision_for(reduction);
        let apply = |x: &Vec<Vec3>, y: &mut Vec<Vec3>| {
            let corrections = (field, growth);
            apply_to(
                springs,
                &s.free,
                pairs.0,
                pairs.1,
                corrections,
                x,
                y,
                precision,
            );
        };
        let mut sums = std::mem::take(&mut s.dots);
        let precondition = |r: &Vec<Vec3>, z: &mut Vec<Vec3>| {
            precondition_with(
                preconditioner,
                multigrid,
                &fine,
                (r, z),
                precision,
                &mut sums,
            );
        };
        let reached = gmres.solve(&s.r, &mut s.dv, reduction, MAX_CG, apply, precondition);
        s.dots = sums;
        reached
    };
    s.gmres = gmres;
    reached
}

/// `z = P⁻¹·r` for the preconditioner `preconditioner` of `A` (`fine`), the multigrid's coarse
/// products in `precision`; returns `r·z`, summed as [`dot`] sums it (into `sums`).
fn precondition_with(
    preconditioner: Preconditioner,
    multigrid: &mut Multigrid,
    fine: &Operator,
    (r, z): (&[Vec3], &mut [Vec3]),
    precision: Precision,
    sums: &mut [f64],
) -> f64 {
    match preconditioner {
        Preconditioner::Multigrid => multigrid.precondition(fine, r, z, precision, sums),
        Preconditioner::Diagonal => fine.jacobi_dot(r, 1.0, None, z, sums),
    }
}

/// The Newton system's right-hand side `−M·g` into `s.r` (zero at held points).
fn set_right_hand_side(s: &mut ImplicitScratch) {
    let (g, mass, free) = (&s.g[..], &s.mass[..], &s.free[..]);
    let size = chunk_size(g.len());
    team::for_each_chunk([&mut s.r[..]], size, &|c, [r]| {
        let at = c * size;
        let (g, mass, free) = (&g[at..], &mass[at..], &free[at..]);
        for (i, r) in r.iter_mut().enumerate() {
            *r = g[i] * (-mass[i] * free[i]);
        }
    });
}
