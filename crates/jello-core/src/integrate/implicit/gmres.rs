//! Restarted GMRES (Saad and Schultz 1986), right-preconditioned, for Newton systems that are
//! not symmetric: a force field whose gradient has a large antisymmetric part (a swirl) puts
//! that part into `A`, and conjugate gradients need `A` symmetric.
//!
//! Right preconditioning (`A·P⁻¹·u = b`, `x = P⁻¹·u`) makes the residual GMRES minimises the
//! true one, so the stopping test and the Newton step's descent both see `b − A·x` itself.
//! The loops over points run on the step's team, the dot products summed over fixed chunks (as
//! the conjugate gradients' are), so results do not depend on the thread count.

use super::cg::{dot, sum_chunks};
use super::chunk_size;
use crate::compute::team;
use crate::vec3::Vec3;

/// Krylov vectors kept before a restart, at most.
const RESTART: usize = 30;

/// Memory the Krylov basis may take (bytes): large lattices restart sooner.
const BASIS_BYTES: usize = 1 << 27;

/// The Krylov basis and the small Hessenberg least-squares problem, sized once per model.
#[derive(Clone, Debug, Default)]
pub(super) struct Gmres {
    /// `m + 1` orthonormal vectors.
    basis: Vec<Vec<Vec3>>,
    /// The Hessenberg matrix, column `j` at `j·(m + 1)`, rotated into upper triangular form.
    hessenberg: Vec<f64>,
    /// The Givens rotations (cosine, sine) that do it, and the rotated right-hand side.
    rotations: Vec<(f64, f64)>,
    rhs: Vec<f64>,
    /// The least-squares solution, and two vectors of scratch.
    y: Vec<f64>,
    work: Vec<Vec3>,
    correction: Vec<Vec3>,
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

impl Gmres {
    /// Room for systems of `n` points.
    pub fn new(n: usize) -> Self {
        let per_vector = (n * std::mem::size_of::<Vec3>()).max(1);
        let m = (BASIS_BYTES / per_vector).clamp(4, RESTART);
        Gmres {
            basis: vec![vec![Vec3::ZERO; n]; m + 1],
            hessenberg: vec![0.0; (m + 1) * m],
            rotations: vec![(0.0, 0.0); m],
            rhs: vec![0.0; m + 1],
            y: vec![0.0; m],
            work: vec![Vec3::ZERO; n],
            correction: vec![Vec3::ZERO; n],
            sums: vec![0.0; sum_chunks(n)],
        }
    }

    /// True when sized for systems of `n` points.
    pub fn fits(&self, n: usize) -> bool {
        self.work.len() == n && !self.basis.is_empty()
    }

    /// Solves `A·x = b` from `x = 0` until `|b − A·x| ≤ reduction·|b|` or `max_iterations`
    /// products with `A` (`apply(x, y)` sets `y = A·x`; `precondition(r, z)` sets `z ≈ A⁻¹·r`).
    pub fn solve(
        &mut self,
        b: &[Vec3],
        x: &mut [Vec3],
        reduction: f64,
        max_iterations: usize,
        mut apply: impl FnMut(&[Vec3], &mut [Vec3]),
        mut precondition: impl FnMut(&[Vec3], &mut [Vec3]),
    ) -> Reached {
        let m = self.basis.len() - 1;
        let sums = &mut self.sums[..];
        x.fill(Vec3::ZERO);
        let b_norm = norm(b, sums);
        let target = reduction * b_norm;
        let mut beta = b_norm;
        let mut iterations = 0;
        self.basis[0].copy_from_slice(b);
        let relative = |r: f64| if b_norm > 0.0 { r / b_norm } else { 0.0 };
        while beta > target && beta.is_finite() && iterations < max_iterations {
            scale(&mut self.basis[0], 1.0 / beta);
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
                        let c = dot(w, v, sums);
                        column[i] = c;
                        add_scaled(w, v, -c);
                    }
                    let length = norm(w, sums);
                    column[j + 1] = length;
                    if length > 0.0 {
                        scale(w, 1.0 / length);
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
            self.work.fill(Vec3::ZERO);
            for (v, &y) in self.basis[..columns].iter().zip(&self.y) {
                add_scaled(&mut self.work, v, y);
            }
            precondition(&self.work, &mut self.correction);
            add_scaled(x, &self.correction, 1.0);
            // The true residual, as the next cycle's start.
            apply(x, &mut self.work);
            let (r, ax) = (&mut self.basis[0], &self.work);
            let size = chunk_size(b.len());
            team::for_each_chunk([&mut r[..]], size, &|c, [r]| {
                let at = c * size;
                for ((r, &b), &ax) in r.iter_mut().zip(&b[at..]).zip(&ax[at..]) {
                    *r = b - ax;
                }
            });
            let true_residual = norm(&self.basis[0], sums);
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

/// `|a|`, summed as [`dot`] sums (into `sums`).
fn norm(a: &[Vec3], sums: &mut [f64]) -> f64 {
    dot(a, a, sums).sqrt()
}

/// `y += x·c`, on the team.
fn add_scaled(y: &mut [Vec3], x: &[Vec3], c: f64) {
    let size = chunk_size(y.len());
    team::for_each_chunk([y], size, &|chunk, [y]| {
        for (y, &x) in y.iter_mut().zip(&x[chunk * size..]) {
            *y += x * c;
        }
    });
}

/// `y = y·c`, on the team.
fn scale(y: &mut [Vec3], c: f64) {
    let size = chunk_size(y.len());
    team::for_each_chunk([y], size, &|_, [y]| {
        for y in y.iter_mut() {
            *y = *y * c;
        }
    });
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

    #[test]
    fn solves_a_nonsymmetric_system_to_the_asked_reduction() {
        let n = 200;
        let apply = skewed(n);
        let mut next = values(3);
        let b: Vec<Vec3> = (0..n).map(|_| Vec3::new(next(), next(), next())).collect();
        let mut x = vec![Vec3::ZERO; n];
        let mut gmres = Gmres::new(n);
        let identity = |r: &[Vec3], z: &mut [Vec3]| z.copy_from_slice(r);
        let reached = gmres.solve(&b, &mut x, 1e-10, 2000, &apply, identity);
        assert!(reached.relative_residual <= 1e-10, "{reached:?}");
        let mut ax = vec![Vec3::ZERO; n];
        apply(&x, &mut ax);
        let error: f64 = ax
            .iter()
            .zip(&b)
            .map(|(a, b)| (*a - *b).length_squared())
            .sum();
        let scale: f64 = b.iter().map(|b| b.length_squared()).sum();
        assert!((error / scale).sqrt() <= 1.1e-10);
        // Restarts were needed: the basis holds 30 vectors.
        assert!(reached.iterations > 30, "{reached:?}");
    }

    #[test]
    fn a_preconditioner_that_is_the_inverse_solves_in_one_iteration() {
        // A = diag(d) with a rotation in each block; P⁻¹ its exact inverse.
        let n = 50;
        let (c, s) = (0.6, 0.8);
        let apply = |x: &[Vec3], y: &mut [Vec3]| {
            for (p, (x, y)) in x.iter().zip(y.iter_mut()).enumerate() {
                let d = 1.0 + p as f64;
                *y = Vec3::new(c * x.x - s * x.y, s * x.x + c * x.y, x.z) * d;
            }
        };
        let inverse = |r: &[Vec3], z: &mut [Vec3]| {
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
        let identity = |r: &[Vec3], z: &mut [Vec3]| z.copy_from_slice(r);
        let reached = Gmres::new(n).solve(&b, &mut x, 1e-14, 5, &apply, identity);
        assert_eq!(reached.iterations, 5);
        assert!(reached.relative_residual < 1.0 && reached.relative_residual > 1e-14);
    }
}
