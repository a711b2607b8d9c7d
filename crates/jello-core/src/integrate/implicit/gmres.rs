//! Restarted GMRES (Saad and Schultz 1986), right-preconditioned, for Newton systems that are
//! not symmetric: a force field whose gradient has a large antisymmetric part (a swirl) puts
//! that part into `A`, and conjugate gradients need `A` symmetric.
//!
//! Right preconditioning (`A·P⁻¹·u = b`, `x = P⁻¹·u`) makes the residual GMRES minimises the
//! true one, so the stopping test and the Newton step's descent both see `b − A·x` itself.
//! The loops over points run on the step's team, the dot products summed over fixed chunks (as
//! the conjugate gradients' are), so results do not depend on the thread count.

use super::cg::{dot, sum_chunk, sum_chunks};
use super::chunk_size;
use super::stencil::dot_single;
use crate::compute::team;
use crate::vec3::Vec3;

/// The vectors GMRES works in: `Vec3`s in double precision, or structure of arrays in single
/// precision (the usual solves', as the conjugate gradients' in `cg/single.rs`). Each loop runs
/// on the team, each dot product summed over the fixed chunks of [`sum_chunk`] points.
pub(super) trait Vectors: Default {
    /// `n` points' worth, zero.
    fn zeros(n: usize) -> Self;
    /// Bytes a point.
    const BYTES: usize;
    /// How many points.
    fn points(&self) -> usize;
    fn copy_from(&mut self, other: &Self);
    fn fill_zero(&mut self);
    /// `self·other`, each chunk's sum into `sums`, then those in order.
    fn dot(&self, other: &Self, sums: &mut [f64]) -> f64;
    /// `self += x·c`.
    fn add_scaled(&mut self, x: &Self, c: f64);
    /// `self = self·c`.
    fn scale(&mut self, c: f64);
    /// `self = b − ax`.
    fn difference(&mut self, b: &Self, ax: &Self);
}

impl Vectors for Vec<Vec3> {
    const BYTES: usize = std::mem::size_of::<Vec3>();
    fn zeros(n: usize) -> Self {
        Vec3::zeros(n)
    }
    fn points(&self) -> usize {
        self.len()
    }
    fn copy_from(&mut self, other: &Self) {
        self.copy_from_slice(other);
    }
    fn fill_zero(&mut self) {
        self.fill(Vec3::ZERO);
    }
    fn dot(&self, other: &Self, sums: &mut [f64]) -> f64 {
        dot(self, other, sums)
    }
    fn add_scaled(&mut self, x: &Self, c: f64) {
        let size = chunk_size(self.len());
        team::for_each_chunk([&mut self[..]], size, &|chunk, [y]| {
            for (y, &x) in y.iter_mut().zip(&x[chunk * size..]) {
                *y += x * c;
            }
        });
    }
    fn scale(&mut self, c: f64) {
        let size = chunk_size(self.len());
        team::for_each_chunk([&mut self[..]], size, &|_, [y]| {
            for y in y.iter_mut() {
                *y = *y * c;
            }
        });
    }
    fn difference(&mut self, b: &Self, ax: &Self) {
        let size = chunk_size(b.len());
        team::for_each_chunk([&mut self[..]], size, &|c, [r]| {
            let at = c * size;
            for ((r, &b), &ax) in r.iter_mut().zip(&b[at..]).zip(&ax[at..]) {
                *r = b - ax;
            }
        });
    }
}

/// Structure of arrays in single precision: the components' arrays.
impl Vectors for [Vec<f32>; 3] {
    const BYTES: usize = 3 * std::mem::size_of::<f32>();
    fn zeros(n: usize) -> Self {
        std::array::from_fn(|_| vec![0.0; n])
    }
    fn points(&self) -> usize {
        self[0].len()
    }
    fn copy_from(&mut self, other: &Self) {
        for (a, b) in self.iter_mut().zip(other) {
            a.copy_from_slice(b);
        }
    }
    fn fill_zero(&mut self) {
        self.iter_mut().for_each(|a| a.fill(0.0));
    }
    fn dot(&self, other: &Self, sums: &mut [f64]) -> f64 {
        let (n, size) = (self.points(), sum_chunk(self.points()));
        team::for_each_mut(sums, &|c, sum| {
            let at = c * size..((c + 1) * size).min(n);
            let (a, b) = (&self[..], &other[..]);
            let a = [&a[0][at.clone()], &a[1][at.clone()], &a[2][at.clone()]];
            let b = [&b[0][at.clone()], &b[1][at.clone()], &b[2][at.clone()]];
            *sum = dot_single(a, b);
        });
        sums.iter().sum()
    }
    fn add_scaled(&mut self, x: &Self, c: f64) {
        let (size, c) = (chunk_size(self.points()), c as f32);
        let [y0, y1, y2] = self.each_mut().map(|y| &mut y[..]);
        team::for_each_chunk([y0, y1, y2], size, &|chunk, ys| {
            for (y, x) in ys.into_iter().zip(x) {
                for (y, &x) in y.iter_mut().zip(&x[chunk * size..]) {
                    *y += x * c;
                }
            }
        });
    }
    fn scale(&mut self, c: f64) {
        let (size, c) = (chunk_size(self.points()), c as f32);
        let [y0, y1, y2] = self.each_mut().map(|y| &mut y[..]);
        team::for_each_chunk([y0, y1, y2], size, &|_, ys| {
            for y in ys {
                y.iter_mut().for_each(|y| *y *= c);
            }
        });
    }
    fn difference(&mut self, b: &Self, ax: &Self) {
        let size = chunk_size(self.points());
        let [r0, r1, r2] = self.each_mut().map(|r| &mut r[..]);
        team::for_each_chunk([r0, r1, r2], size, &|chunk, rs| {
            for ((r, b), ax) in rs.into_iter().zip(b).zip(ax) {
                let at = chunk * size;
                for ((r, &b), &ax) in r.iter_mut().zip(&b[at..]).zip(&ax[at..]) {
                    *r = b - ax;
                }
            }
        });
    }
}

/// Krylov vectors kept before a restart, at most.
const RESTART: usize = 30;

/// Memory the Krylov basis may take (bytes): large lattices restart sooner.
const BASIS_BYTES: usize = 1 << 27;

/// The Krylov basis and the small Hessenberg least-squares problem, sized once per model.
#[derive(Clone, Debug, Default)]
pub(super) struct Gmres<V = Vec<Vec3>> {
    /// `m + 1` orthonormal vectors.
    basis: Vec<V>,
    /// The Hessenberg matrix, column `j` at `j·(m + 1)`, rotated into upper triangular form.
    hessenberg: Vec<f64>,
    /// The Givens rotations (cosine, sine) that do it, and the rotated right-hand side.
    rotations: Vec<(f64, f64)>,
    rhs: Vec<f64>,
    /// The least-squares solution, and two vectors of scratch.
    y: Vec<f64>,
    work: V,
    correction: V,
    /// The dot products' sums by chunk of points.
    sums: Vec<f64>,
}

/// What a solve reached.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) struct Reached {
    /// `|b − A·x| / |b|` at the end (0 when `b` is zero).
    pub relative_residual: f64,
    /// Products with `A`.
    pub iterations: usize,
}

impl<V: Vectors> Gmres<V> {
    /// Room for systems of `n` points.
    pub fn new(n: usize) -> Self {
        let per_vector = (n * V::BYTES).max(1);
        let m = (BASIS_BYTES / per_vector).clamp(4, RESTART);
        Gmres {
            basis: (0..=m).map(|_| V::zeros(n)).collect(),
            hessenberg: vec![0.0; (m + 1) * m],
            rotations: vec![(0.0, 0.0); m],
            rhs: vec![0.0; m + 1],
            y: vec![0.0; m],
            work: V::zeros(n),
            correction: V::zeros(n),
            sums: vec![0.0; sum_chunks(n)],
        }
    }

    /// True when sized for systems of `n` points.
    pub fn fits(&self, n: usize) -> bool {
        self.work.points() == n && !self.basis.is_empty()
    }

    /// Solves `A·x = b` from `x = 0` until `|b − A·x| ≤ reduction·|b|` or `max_iterations`
    /// products with `A` (`apply(x, y)` sets `y = A·x`; `precondition(r, z)` sets `z ≈ A⁻¹·r`).
    pub fn solve(
        &mut self,
        b: &V,
        x: &mut V,
        reduction: f64,
        max_iterations: usize,
        mut apply: impl FnMut(&V, &mut V),
        mut precondition: impl FnMut(&V, &mut V),
    ) -> Reached {
        let m = self.basis.len() - 1;
        let sums = &mut self.sums[..];
        x.fill_zero();
        let b_norm = b.dot(b, sums).sqrt();
        let target = reduction * b_norm;
        let mut beta = b_norm;
        let mut iterations = 0;
        self.basis[0].copy_from(b);
        let relative = |r: f64| if b_norm > 0.0 { r / b_norm } else { 0.0 };
        while beta > target && beta.is_finite() && iterations < max_iterations {
            self.basis[0].scale(1.0 / beta);
            self.rhs.fill(0.0);
            self.rhs[0] = beta;
            let mut columns = 0;
            let mut residual;
            while columns < m && iterations < max_iterations {
                let j = columns;
                precondition(&self.basis[j], &mut self.work);
                {
                    let (done, next) = self.basis.split_at_mut(j + 1);
                    let w = &mut next[0];
                    apply(&self.work, w);
                    let column = &mut self.hessenberg[j * (m + 1)..(j + 1) * (m + 1)];
                    // Modified Gram–Schmidt against the basis so far.
                    for (i, v) in done.iter().enumerate() {
                        let c = w.dot(v, sums);
                        column[i] = c;
                        w.add_scaled(v, -c);
                    }
                    let length = w.dot(w, sums).sqrt();
                    column[j + 1] = length;
                    if length > 0.0 {
                        w.scale(1.0 / length);
                    }
                    // The earlier rotations, then one that zeroes the new subdiagonal entry.
                    for (i, &(c, s)) in self.rotations[..j].iter().enumerate() {
                        let (a, b) = (column[i], column[i + 1]);
                        column[i] = c * a + s * b;
                        column[i + 1] = -s * a + c * b;
                    }
                    let (a, b) = (column[j], column[j + 1]);
                    let r = a.hypot(b);
                    let (c, s) = if r > 0.0 { (a / r, b / r) } else { (1.0, 0.0) };
                    self.rotations[j] = (c, s);
                    column[j] = r;
                    column[j + 1] = 0.0;
                    self.rhs[j + 1] = -s * self.rhs[j];
                    self.rhs[j] *= c;
                    residual = self.rhs[j + 1].abs();
                    iterations += 1;
                    columns += 1;
                    // A zero new vector: the Krylov space holds the solution.
                    if length == 0.0 || !residual.is_finite() {
                        break;
                    }
                }
                if residual <= target {
                    break;
                }
            }
            // The least-squares coefficients by back substitution; the step P⁻¹·(V·y).
            for i in (0..columns).rev() {
                let mut sum = self.rhs[i];
                for k in i + 1..columns {
                    sum -= self.hessenberg[k * (m + 1) + i] * self.y[k];
                }
                let diagonal = self.hessenberg[i * (m + 1) + i];
                self.y[i] = if diagonal != 0.0 { sum / diagonal } else { 0.0 };
            }
            self.work.fill_zero();
            for (v, &y) in self.basis[..columns].iter().zip(&self.y) {
                self.work.add_scaled(v, y);
            }
            precondition(&self.work, &mut self.correction);
            x.add_scaled(&self.correction, 1.0);
            // The true residual, as the next cycle's start.
            apply(x, &mut self.work);
            self.basis[0].difference(b, &self.work);
            let true_residual = self.basis[0].dot(&self.basis[0], sums).sqrt();
            // (A NaN residual counts as none.)
            if true_residual.partial_cmp(&beta) != Some(std::cmp::Ordering::Less) {
                // No progress in a whole cycle (or a breakdown): more cycles would repeat it.
                beta = true_residual;
                break;
            }
            beta = true_residual;
        }
        Reached {
            relative_residual: relative(beta),
            iterations,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrate::implicit::test_models::values;

    /// A banded matrix that is far from symmetric, over `n` points.
    fn skewed(n: usize) -> impl Fn(&[Vec3], &mut [Vec3]) {
        move |x: &[Vec3], y: &mut [Vec3]| {
            for p in 0..n {
                let mut out = x[p] * 4.0 + Vec3::new(x[p].y, -x[p].x, 0.0) * 30.0;
                if p + 1 < n {
                    out += x[p + 1] * -1.0;
                }
                if p > 0 {
                    out += x[p - 1] * -0.5;
                }
                y[p] = out;
            }
        }
    }

    /// [`skewed`]'s right-hand side over `n` points.
    fn skewed_right_hand_side(n: usize) -> Vec<Vec3> {
        let mut next = values(3);
        (0..n).map(|_| Vec3::new(next(), next(), next())).collect()
    }

    /// `|A·x − b| / |b|` for [`skewed`]'s `A`, in double precision.
    fn skewed_residual(x: &[Vec3], b: &[Vec3]) -> f64 {
        let mut ax = vec![Vec3::ZERO; b.len()];
        skewed(b.len())(x, &mut ax);
        let error: f64 = ax
            .iter()
            .zip(b)
            .map(|(a, b)| (*a - *b).length_squared())
            .sum();
        let scale: f64 = b.iter().map(|b| b.length_squared()).sum();
        (error / scale).sqrt()
    }

    #[test]
    fn solves_a_nonsymmetric_system_to_the_asked_reduction() {
        let n = 200;
        let apply = skewed(n);
        let b = skewed_right_hand_side(n);
        let mut x = vec![Vec3::ZERO; n];
        let mut gmres = Gmres::new(n);
        let identity = |r: &Vec<Vec3>, z: &mut Vec<Vec3>| z.copy_from_slice(r);
        let product = |x: &Vec<Vec3>, y: &mut Vec<Vec3>| apply(x, y);
        let reached = gmres.solve(&b, &mut x, 1e-10, 2000, product, identity);
        assert!(reached.relative_residual <= 1e-10, "{reached:?}");
        assert!(skewed_residual(&x, &b) <= 1.1e-10);
        // Restarts were needed: the basis holds 30 vectors.
        assert!(reached.iterations > 30, "{reached:?}");
    }

    #[test]
    fn a_preconditioner_that_is_the_inverse_solves_in_one_iteration() {
        // A = diag(d) with a rotation in each block; P⁻¹ its exact inverse.
        let n = 50;
        let (c, s) = (0.6, 0.8);
        let apply = |x: &Vec<Vec3>, y: &mut Vec<Vec3>| {
            for (p, (x, y)) in x.iter().zip(y.iter_mut()).enumerate() {
                let d = 1.0 + p as f64;
                *y = Vec3::new(c * x.x - s * x.y, s * x.x + c * x.y, x.z) * d;
            }
        };
        let inverse = |r: &Vec<Vec3>, z: &mut Vec<Vec3>| {
            for (p, (r, z)) in r.iter().zip(z.iter_mut()).enumerate() {
                let d = 1.0 + p as f64;
                *z = Vec3::new(c * r.x + s * r.y, -s * r.x + c * r.y, r.z) / d;
            }
        };
        let b: Vec<Vec3> = (0..n).map(|p| Vec3::new(1.0, p as f64, -2.0)).collect();
        let mut x = vec![Vec3::ZERO; n];
        let reached = Gmres::new(n).solve(&b, &mut x, 1e-12, 100, apply, inverse);
        assert_eq!(reached.iterations, 1, "{reached:?}");
        assert!(reached.relative_residual <= 1e-12);
    }

    #[test]
    fn stops_at_the_iteration_budget_with_the_residual_reached() {
        let n = 300;
        let apply = skewed(n);
        let b = vec![Vec3::new(1.0, 0.0, 0.0); n];
        let mut x = vec![Vec3::ZERO; n];
        let identity = |r: &Vec<Vec3>, z: &mut Vec<Vec3>| z.copy_from_slice(r);
        let product = |x: &Vec<Vec3>, y: &mut Vec<Vec3>| apply(x, y);
        let reached = Gmres::new(n).solve(&b, &mut x, 1e-14, 5, product, identity);
        assert_eq!(reached.iterations, 5);
        assert!(reached.relative_residual < 1.0 && reached.relative_residual > 1e-14);
    }

    /// In single precision, as structure of arrays (the usual solves' GMRES): the same
    /// system to the reductions those ask for, the residual judged afresh in double precision.
    #[test]
    fn solves_in_single_precision_to_the_usual_reductions() {
        let n = 200;
        let apply = skewed(n);
        let b = skewed_right_hand_side(n);
        let soa = |v: &[Vec3]| -> [Vec<f32>; 3] {
            [
                v.iter().map(|v| v.x as f32).collect(),
                v.iter().map(|v| v.y as f32).collect(),
                v.iter().map(|v| v.z as f32).collect(),
            ]
        };
        let wide = |v: &[Vec<f32>; 3]| -> Vec<Vec3> {
            (0..n)
                .map(|p| Vec3::new(v[0][p].into(), v[1][p].into(), v[2][p].into()))
                .collect()
        };
        let product = |x: &[Vec<f32>; 3], y: &mut [Vec<f32>; 3]| {
            let mut out = vec![Vec3::ZERO; n];
            apply(&wide(x), &mut out);
            *y = soa(&out);
        };
        let identity = |r: &[Vec<f32>; 3], z: &mut [Vec<f32>; 3]| z.copy_from(r);
        for reduction in [1e-2, 1e-4] {
            let mut x = <[Vec<f32>; 3]>::zeros(n);
            let mut gmres = Gmres::<[Vec<f32>; 3]>::new(n);
            let reached = gmres.solve(&soa(&b), &mut x, reduction, 2000, product, identity);
            assert!(reached.relative_residual <= reduction, "{reached:?}");
            let fell = skewed_residual(&wide(&x), &b);
            assert!(fell <= 1.01 * reduction, "{reduction}: {fell}");
        }
    }
}
