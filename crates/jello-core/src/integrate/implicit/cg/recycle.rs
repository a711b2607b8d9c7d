//! A step's first solve started from the directions of the last steps' first solves.
//!
//! Where a step passes its `A` on to the next (Newton's fast regime, see `keeps_across_steps`),
//! the first solves of consecutive steps share their matrix, and their right-hand sides are
//! alike: a body settling on a floor rings down in its few slowest modes, and each step's
//! change of velocity lies close to the span of the last few. Conjugate gradients from zero
//! find that span again at every step, at several iterations a decade. Started instead from the
//! best point of that span in `A`'s norm, `x₀ = Σ (uᵢ·b)·uᵢ` for directions `uᵢ` made
//! `A`-orthonormal, they only remove what it misses (a Krylov space "recycled" from solve to
//! solve, as in deflated and augmented conjugate gradients).
//!
//! It costs no product with `A`: a solve's direction `Δv` comes with `A·Δv = b − r`, its
//! right-hand side less its last residual, and the start's residual is `b − Σ (uᵢ·b)·A·uᵢ`. The
//! directions hold for the `A` they were found with only (they are forgotten when `A` is
//! assembled again), and a start whose residual is not smaller than `b` is not taken (the
//! solve then starts from zero as before). The stopping rule is unchanged: the residual
//! against `b`'s, and every point within its bound.
//!
//! Each pass runs over the fixed chunks of [`sum_chunk`] points on the team, and its sums are
//! added chunk by chunk in order: the same bits on any number of threads.

use crate::compute::team;
use crate::vec3::Vec3;

use super::sum_chunk;

/// Directions kept: the last steps' first solves, the oldest dropped for a new one. More did
/// not help the frame-rate job (its 32³ cube settling on a floor): `A` is assembled again
/// every few steps until the cube has settled.
pub(super) const RECYCLED: usize = 4;

/// A direction whose part `A`-orthogonal to the others has less than this fraction of its
/// `A`-norm² is left out (it adds nothing that single precision can hold).
const INDEPENDENT: f64 = 1e-9;

/// The directions, in single precision as structure of arrays (the conjugate gradients'
/// vectors, see [`super::single`]), sized by [`Recycled::new`] (the default holds no buffers:
/// the placeholder of vectors taken out of the scratch).
#[derive(Clone, Debug, Default)]
pub(in crate::integrate::implicit) struct Recycled {
    /// The assembly of `A` (its count, `SolverStats::assemblies`) they were found with.
    assembly: u64,
    /// Directions `wᵢ` and their products `A·wᵢ`, oldest first, [`RECYCLED`] buffers of each
    /// ([`Recycled::new`]); `uᵢ = wᵢ·scaleᵢ` are `A`-orthonormal. Buffers beyond
    /// `scales.len()` are spare.
    directions: Vec<[Vec<f32>; 3]>,
    products: Vec<[Vec<f32>; 3]>,
    scales: Vec<f64>,
    /// Each chunk's sums of a pass, and of the passes that write.
    sums: Vec<[f64; RECYCLED + 1]>,
    found: Vec<(f64, bool)>,
    norms: Vec<f64>,
}

/// The right-hand side `b = −M·g` at point `p` (zero where held).
#[inline(always)]
fn rhs(g: &[Vec3], mass: &[f64], free: &[f64], p: usize) -> [f64; 3] {
    let b = g[p] * (-mass[p] * free[p]);
    [b.x, b.y, b.z]
}

impl Recycled {
    /// Room for [`RECYCLED`] directions of `n` points, none held (allocated with the solver's
    /// buffers, so that later steps do not allocate).
    pub fn new(n: usize) -> Recycled {
        let zeros = || std::array::from_fn(|_| vec![0.0f32; n]);
        let chunks = n.div_ceil(sum_chunk(n));
        Recycled {
            assembly: 0,
            directions: (0..RECYCLED).map(|_| zeros()).collect(),
            products: (0..RECYCLED).map(|_| zeros()).collect(),
            scales: Vec::with_capacity(RECYCLED),
            sums: vec![[0.0; RECYCLED + 1]; chunks],
            found: vec![(0.0, true); chunks],
            norms: vec![0.0; chunks],
        }
    }

    /// How many directions it holds.
    pub fn len(&self) -> usize {
        self.scales.len()
    }

    /// The start for a solve with the `A` of `assembly` whose right-hand side `b` is in `r`
    /// (and `Δv` zero): where it holds directions for that `A` and their best combination
    /// lowers the residual, `Δv` and `r` become that start and its residual (through `spare`,
    /// two vectors free until the solve's first product) and it returns `b·b` and whether the
    /// start is within `mass·bound` at every point; else it changes nothing.
    pub fn start(
        &mut self,
        assembly: u64,
        (dv, r): (&mut [Vec<f32>; 3], &mut [Vec<f32>; 3]),
        spare: (&mut [Vec<f32>; 3], &mut [Vec<f32>; 3]),
        (mass, bound): (&[f64], f64),
    ) -> Option<(f64, bool)> {
        if assembly != self.assembly {
            self.scales.clear();
        }
        let k = self.len();
        if k == 0 {
            return None;
        }
        let n = r[0].len();
        let size = sum_chunk(n);
        // `wᵢ·b` and `b·b`.
        let (directions, b) = (&self.directions[..k], &*r);
        team::for_each_mut(&mut self.sums, &|c, sums| {
            let at = c * size..((c + 1) * size).min(n);
            *sums = [0.0; RECYCLED + 1];
            for p in at {
                let b = [b[0][p], b[1][p], b[2][p]].map(f64::from);
                for (sum, w) in sums.iter_mut().zip(directions) {
                    *sum += b[0] * f64::from(w[0][p])
                        + b[1] * f64::from(w[1][p])
                        + b[2] * f64::from(w[2][p]);
                }
                sums[RECYCLED] += b[0] * b[0] + b[1] * b[1] + b[2] * b[2];
            }
        });
        let total = |i: usize, sums: &[[f64; RECYCLED + 1]]| sums.iter().map(|s| s[i]).sum::<f64>();
        let bb = total(RECYCLED, &self.sums);
        // `x₀ = Σ cᵢ·wᵢ` with `cᵢ = scaleᵢ²·(wᵢ·b)`.
        let mut c = [0.0; RECYCLED];
        for (i, c) in c[..k].iter_mut().enumerate() {
            *c = self.scales[i] * self.scales[i] * total(i, &self.sums);
        }
        if !c.iter().all(|c| c.is_finite()) || bb == 0.0 {
            return None;
        }
        // The start into `spare` (`Δv`, then `r = b − Σ cᵢ·A·wᵢ`), with its `r·r` and whether it
        // is within its bound.
        let (spare_dv, spare_r) = spare;
        let [x0, x1, x2] = spare_dv.each_mut().map(|x| &mut x[..]);
        let [r0, r1, r2] = spare_r.each_mut().map(|r| &mut r[..]);
        let products = &self.products[..k];
        team::for_each_chunk_into(
            [x0, x1, x2, r0, r1, r2],
            size,
            &mut self.found,
            &|chunk, [x0, x1, x2, r0, r1, r2]| {
                let at = chunk * size;
                let (mut rr, mut within) = (0.0, bound > 0.0);
                for i in 0..x0.len() {
                    let p = at + i;
                    let (mut x, mut rp) = ([0.0; 3], [b[0][p], b[1][p], b[2][p]].map(f64::from));
                    for ((w, aw), &c) in directions.iter().zip(products).zip(&c) {
                        for d in 0..3 {
                            x[d] += c * f64::from(w[d][p]);
                            rp[d] -= c * f64::from(aw[d][p]);
                        }
                    }
                    (x0[i], x1[i], x2[i]) = (x[0] as f32, x[1] as f32, x[2] as f32);
                    (r0[i], r1[i], r2[i]) = (rp[0] as f32, rp[1] as f32, rp[2] as f32);
                    let norm2 = [r0[i], r1[i], r2[i]]
                        .map(|v| f64::from(v) * f64::from(v))
                        .iter()
                        .sum::<f64>();
                    rr += norm2;
                    within &= norm2 <= (mass[p] * bound) * (mass[p] * bound);
                }
                (rr, within)
            },
        );
        let rr: f64 = self.found.iter().map(|f| f.0).sum();
        if rr.is_nan() || rr >= bb {
            return None;
        }
        std::mem::swap(dv, spare_dv);
        std::mem::swap(r, spare_r);
        Some((bb, self.found.iter().all(|f| f.1)))
    }

    /// Keeps the direction `dv` a solve with the `A` of `assembly` found for the right-hand
    /// side `−M·g` (zero where held), its last residual `r`: `A·dv = b − r`, made
    /// `A`-orthogonal to the directions held (dropping the oldest when they are
    /// [`RECYCLED`]), unless it adds nothing to them.
    pub fn push(
        &mut self,
        assembly: u64,
        (dv, r): (&[Vec<f32>; 3], &[Vec<f32>; 3]),
        (g, mass, free): (&[Vec3], &[f64], &[f64]),
    ) {
        if assembly != self.assembly {
            self.scales.clear();
            self.assembly = assembly;
        }
        // The oldest's buffers become the new one's.
        if self.len() == RECYCLED {
            self.directions.rotate_left(1);
            self.products.rotate_left(1);
            self.scales.remove(0);
        }
        let k = self.len();
        // Its parts along the directions held (the first needs no pass for them).
        let (whole, c) = match k {
            0 => (None, [0.0; RECYCLED]),
            _ => match self.parts_along(k, (dv, r), (g, mass, free)) {
                Some((whole, c)) => (Some(whole), c),
                None => return,
            },
        };
        // The new direction less those parts, and its product, into the spare buffers; with its
        // `A`-norm².
        let n = dv[0].len();
        let size = sum_chunk(n);
        let (held, new) = self.directions.split_at_mut(k);
        let (held_products, new_products) = self.products.split_at_mut(k);
        let [w0, w1, w2] = new[0].each_mut().map(|w| &mut w[..]);
        let [a0, a1, a2] = new_products[0].each_mut().map(|a| &mut a[..]);
        let (held, held_products) = (&*held, &*held_products);
        team::for_each_chunk_into(
            [w0, w1, w2, a0, a1, a2],
            size,
            &mut self.norms,
            &|chunk, [w0, w1, w2, a0, a1, a2]| {
                let at = chunk * size;
                let mut norm = 0.0;
                for i in 0..w0.len() {
                    let p = at + i;
                    let b = rhs(g, mass, free, p);
                    let mut w = [0, 1, 2].map(|d| f64::from(dv[d][p]));
                    let mut a = [0, 1, 2].map(|d| b[d] - f64::from(r[d][p]));
                    for ((u, au), &c) in held.iter().zip(held_products).zip(&c) {
                        for d in 0..3 {
                            w[d] -= c * f64::from(u[d][p]);
                            a[d] -= c * f64::from(au[d][p]);
                        }
                    }
                    let (w, a) = (w.map(|v| v as f32), a.map(|v| v as f32));
                    (w0[i], w1[i], w2[i]) = (w[0], w[1], w[2]);
                    (a0[i], a1[i], a2[i]) = (a[0], a[1], a[2]);
                    norm += (0..3)
                        .map(|d| f64::from(w[d]) * f64::from(a[d]))
                        .sum::<f64>();
                }
                norm
            },
        );
        let norm: f64 = self.norms.iter().sum();
        if norm > 0.0 && norm.is_finite() && whole.is_none_or(|whole| norm > INDEPENDENT * whole) {
            self.scales.push(1.0 / norm.sqrt());
        }
    }

    /// For a new direction `dv` (`A·dv = b − r`, `b = −M·g`): its `A`-norm², and its
    /// coefficients along the first `k` directions held, `scaleᵢ²·wᵢ·A·dv`; `None` where these
    /// are not finite or that norm is not positive.
    fn parts_along(
        &mut self,
        k: usize,
        (dv, r): (&[Vec<f32>; 3], &[Vec<f32>; 3]),
        (g, mass, free): (&[Vec3], &[f64], &[f64]),
    ) -> Option<(f64, [f64; RECYCLED])> {
        let n = dv[0].len();
        let size = sum_chunk(n);
        let directions = &self.directions[..k];
        team::for_each_mut(&mut self.sums, &|c, sums| {
            let at = c * size..((c + 1) * size).min(n);
            *sums = [0.0; RECYCLED + 1];
            for p in at {
                let b = rhs(g, mass, free, p);
                let a = [0, 1, 2].map(|d| b[d] - f64::from(r[d][p]));
                for (sum, w) in sums.iter_mut().zip(directions) {
                    *sum += (0..3).map(|d| a[d] * f64::from(w[d][p])).sum::<f64>();
                }
                sums[RECYCLED] += (0..3).map(|d| a[d] * f64::from(dv[d][p])).sum::<f64>();
            }
        });
        let total = |i: usize| self.sums.iter().map(|s| s[i]).sum::<f64>();
        let whole = total(RECYCLED);
        let mut c = [0.0; RECYCLED];
        for (i, c) in c[..k].iter_mut().enumerate() {
            *c = self.scales[i] * self.scales[i] * total(i);
        }
        (whole > 0.0 && whole.is_finite() && c.iter().all(|c| c.is_finite())).then_some((whole, c))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// `A·x` for a symmetric positive definite `A` coupling each point to the next, with a
    /// different stiffness per component (a chain of springs with masses).
    fn apply(x: &[Vec3]) -> Vec<Vec3> {
        let n = x.len();
        let k = Vec3::new(40.0, 55.0, 70.0);
        (0..n)
            .map(|p| {
                let mut y = x[p] * 1.5;
                for q in [p.wrapping_sub(1), p + 1] {
                    if q < n {
                        let d = x[p] - x[q];
                        y += Vec3::new(k.x * d.x, k.y * d.y, k.z * d.z);
                    }
                }
                y
            })
            .collect()
    }

    fn pattern(n: usize, seed: usize) -> Vec<Vec3> {
        let f = |i: usize| ((i * 7 + seed * 13) as f64 * 0.618_033_988_749_895).fract() - 0.5;
        (0..n)
            .map(|p| Vec3::new(f(3 * p), f(3 * p + 1), f(3 * p + 2)))
            .collect()
    }

    fn soa(v: &[Vec3]) -> [Vec<f32>; 3] {
        [
            v.iter().map(|v| v.x as f32).collect(),
            v.iter().map(|v| v.y as f32).collect(),
            v.iter().map(|v| v.z as f32).collect(),
        ]
    }

    fn aos(v: &[Vec<f32>; 3]) -> Vec<Vec3> {
        (0..v[0].len())
            .map(|p| Vec3::new(v[0][p].into(), v[1][p].into(), v[2][p].into()))
            .collect()
    }

    fn dot(a: &[Vec3], b: &[Vec3]) -> f64 {
        a.iter().zip(b).map(|(a, b)| a.dot(*b)).sum()
    }

    /// Keeps `dv` as a solve with `A` of `assembly` for `b = A·dv + r` would leave it.
    fn push(recycled: &mut Recycled, assembly: u64, dv: &[Vec3], r: &[Vec3]) {
        let n = dv.len();
        let (mass, free) = (vec![2.0; n], vec![1.0; n]);
        let g: Vec<Vec3> = (apply(dv).iter().zip(r))
            .map(|(a, r)| (*a + *r) * (-1.0 / 2.0))
            .collect();
        recycled.push(assembly, (&soa(dv), &soa(r)), (&g, &mass, &free));
    }

    /// The start for the right-hand side `b`: `Δv`, `r`, and what `start` returned.
    fn start(
        recycled: &mut Recycled,
        assembly: u64,
        b: &[Vec3],
        bound: f64,
    ) -> (Vec<Vec3>, Vec<Vec3>, Option<(f64, bool)>) {
        let n = b.len();
        let (mut dv, mut r) = (soa(&vec![Vec3::ZERO; n]), soa(b));
        let (mut spare_dv, mut spare_r) = (soa(&vec![Vec3::ZERO; n]), soa(&vec![Vec3::ZERO; n]));
        let mass = vec![2.0; n];
        let found = recycled.start(
            assembly,
            (&mut dv, &mut r),
            (&mut spare_dv, &mut spare_r),
            (&mass, bound),
        );
        (aos(&dv), aos(&r), found)
    }

    /// The start is the best point of the directions' span in `A`'s norm: its residual is
    /// orthogonal to every direction (Galerkin), and a right-hand side in `A` times that span
    /// is solved by it to single precision, within its bound; directions of another `A` are
    /// forgotten, and at most [`RECYCLED`] are held.
    #[test]
    fn the_start_is_the_best_in_the_directions_span() {
        let n = 3000;
        let directions: Vec<Vec<Vec3>> = (0..3).map(|i| pattern(n, i)).collect();
        let mut recycled = Recycled::new(n);
        for (i, d) in directions.iter().enumerate() {
            let r: Vec<Vec3> = pattern(n, 10 + i).iter().map(|&v| v * 1e-3).collect();
            push(&mut recycled, 7, d, &r);
        }
        assert_eq!(recycled.len(), 3);
        // In the span: solved.
        let x: Vec<Vec3> = (0..n)
            .map(|p| directions[0][p] * 0.3 - directions[1][p] * 2.0 + directions[2][p])
            .collect();
        let b = apply(&x);
        let (dv, r, found) = start(&mut recycled, 7, &b, 1e-3);
        let (bb, within) = found.expect("a start");
        assert!((bb - dot(&b, &b)).abs() <= 1e-9 * bb);
        assert!(within, "|r| / |b| = {}", (dot(&r, &r) / bb).sqrt());
        let error: Vec<Vec3> = dv.iter().zip(&x).map(|(a, b)| *a - *b).collect();
        assert!(dot(&error, &error) < 1e-10 * dot(&x, &x));
        // Off the span: the residual is orthogonal to each direction.
        let b: Vec<Vec3> = (b.iter().zip(pattern(n, 99)))
            .map(|(b, y)| *b + y * 10.0)
            .collect();
        let (_, r, found) = start(&mut recycled, 7, &b, 1e-3);
        let (bb, within) = found.expect("a start");
        assert!(!within && dot(&r, &r) < bb);
        for d in &directions {
            let along = dot(d, &r) / (dot(d, d) * bb).sqrt();
            assert!(along.abs() < 1e-5, "residual along a direction: {along}");
        }
        // Another `A`: nothing to start from, nothing held.
        let (dv, _, found) = start(&mut recycled, 8, &b, 1e-3);
        assert!(found.is_none() && recycled.len() == 0);
        assert!(dv.iter().all(|v| *v == Vec3::ZERO));
        // The oldest dropped for a new one; a direction in the span of those held not kept.
        for i in 0..RECYCLED + 2 {
            push(&mut recycled, 9, &pattern(n, 20 + i), &vec![Vec3::ZERO; n]);
        }
        assert_eq!(recycled.len(), RECYCLED);
        let sum: Vec<Vec3> = (0..n)
            .map(|p| pattern(n, 22)[p] + pattern(n, 25)[p])
            .collect();
        push(&mut recycled, 9, &sum, &vec![Vec3::ZERO; n]);
        assert_eq!(recycled.len(), RECYCLED);
        let (_, r, _) = start(&mut recycled, 9, &apply(&pattern(n, 21)), 0.0);
        assert!(dot(&r, &r) > 1e-6 * dot(&apply(&pattern(n, 21)), &apply(&pattern(n, 21))));
    }
}
