//! The external force field: forces sampled on a `res × res × res` grid over the bounding box,
//! read off by trilinear interpolation (SPEC.md).

use crate::model::{Aabb, ModelError};
use crate::vec3::Vec3;

/// Smallest and largest grid resolution a world file may give (0 means "no field").
pub const RES_RANGE: std::ops::RangeInclusive<usize> = 2..=30;

/// Forces (N) at the nodes of a regular grid covering a box.
///
/// Node `(i, j, k)` sits at `min + (max − min)·(i, j, k)/(res − 1)` and its force is stored at
/// `i*res*res + j*res + k`.
#[derive(Clone, Debug, PartialEq)]
pub struct ForceField {
    res: usize,
    bounds: Aabb,
    /// `res³` forces (N), `i` outermost, `k` innermost.
    forces: Vec<Vec3>,
    /// The force when every node holds the same one (gravity, wind): interpolating equal values
    /// gives that value, so [`ForceField::sample`] returns it without the arithmetic.
    uniform: Option<Vec3>,
}

impl ForceField {
    /// A field over `bounds` from `res³` node forces. Fails when `res < 2`, the count is wrong or a
    /// force is not finite.
    pub fn new(res: usize, bounds: Aabb, forces: Vec<Vec3>) -> Result<Self, ModelError> {
        if res < 2 {
            return Err(ModelError::new(format!(
                "force field resolution {res} is below 2"
            )));
        }
        let expected = res.checked_pow(3).unwrap_or(usize::MAX);
        if forces.len() != expected {
            return Err(ModelError::new(format!(
                "force field of resolution {res} needs {expected} forces, got {}",
                forces.len()
            )));
        }
        if let Some(n) = forces.iter().position(|f| !f.is_finite()) {
            return Err(ModelError::new(format!(
                "force field node {n} is not finite"
            )));
        }
        let first = forces[0].to_array().map(f64::to_bits);
        let uniform = forces
            .iter()
            .all(|f| f.to_array().map(f64::to_bits) == first)
            .then_some(forces[0]);
        Ok(ForceField {
            res,
            bounds,
            forces,
            uniform,
        })
    }

    /// A field whose node forces are `f(node position)`.
    pub fn from_fn(
        res: usize,
        bounds: Aabb,
        mut f: impl FnMut(Vec3) -> Vec3,
    ) -> Result<Self, ModelError> {
        if res < 2 {
            return Err(ModelError::new(format!(
                "force field resolution {res} is below 2"
            )));
        }
        let mut forces = Vec::with_capacity(res * res * res);
        for i in 0..res {
            for j in 0..res {
                for k in 0..res {
                    forces.push(f(node_position(&bounds, res, [i, j, k])));
                }
            }
        }
        ForceField::new(res, bounds, forces)
    }

    /// Grid resolution (nodes per axis).
    pub fn res(&self) -> usize {
        self.res
    }

    /// The box the grid covers.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Node forces (N), `i*res*res + j*res + k`.
    pub fn forces(&self) -> &[Vec3] {
        &self.forces
    }

    /// Position of node `(i, j, k)`.
    pub fn node_position(&self, ijk: [usize; 3]) -> Vec3 {
        node_position(&self.bounds, self.res, ijk)
    }

    /// The force at `p`: trilinear interpolation of the 8 nodes of its cell; a point outside the
    /// box uses the point clamped into the box.
    #[inline(always)]
    pub fn sample(&self, p: Vec3) -> Vec3 {
        if let Some(f) = self.uniform {
            return f;
        }
        let b = &self.bounds;
        let q = p.clamp(b.min, b.max);
        let cells = (self.res - 1) as f64;
        let (i, fx) = cell(q.x, b.min.x, b.max.x, cells);
        let (j, fy) = cell(q.y, b.min.y, b.max.y, cells);
        let (k, fz) = cell(q.z, b.min.z, b.max.z, cells);
        let r = self.res;
        debug_assert!(i + 1 < r && j + 1 < r && k + 1 < r);
        // SAFETY: `cell` clamps each index to 0..=res−2, so every corner is inside the grid.
        let at = |di: usize, dj: usize, dk: usize| unsafe {
            *self
                .forces
                .get_unchecked(((i + di) * r + j + dj) * r + k + dk)
        };
        // Interpolate along z, then y, then x.
        let lerp = |a: Vec3, b: Vec3, t: f64| a * (1.0 - t) + b * t;
        let c00 = lerp(at(0, 0, 0), at(0, 0, 1), fz);
        let c01 = lerp(at(0, 1, 0), at(0, 1, 1), fz);
        let c10 = lerp(at(1, 0, 0), at(1, 0, 1), fz);
        let c11 = lerp(at(1, 1, 0), at(1, 1, 1), fz);
        let c0 = lerp(c00, c01, fy);
        let c1 = lerp(c10, c11, fy);
        lerp(c0, c1, fx)
    }

    /// The force everywhere, when every node holds the same one.
    pub fn uniform(&self) -> Option<Vec3> {
        self.uniform
    }

    /// Largest node force magnitude (N).
    pub fn max_magnitude(&self) -> f64 {
        self.forces.iter().map(|f| f.length()).fold(0.0, f64::max)
    }
}

fn node_position(b: &Aabb, res: usize, [i, j, k]: [usize; 3]) -> Vec3 {
    let cells = (res - 1) as f64;
    let at = |lo: f64, hi: f64, c: usize| lo + (hi - lo) * c as f64 / cells;
    Vec3::new(
        at(b.min.x, b.max.x, i),
        at(b.min.y, b.max.y, j),
        at(b.min.z, b.max.z, k),
    )
}

/// Cell index along one axis (`0..cells−1`) and the fraction of the way across it, for a
/// coordinate already clamped into `[lo, hi]`. The upper boundary belongs to the last cell.
#[inline(always)]
fn cell(v: f64, lo: f64, hi: f64, cells: f64) -> (usize, f64) {
    let u = (v - lo) / (hi - lo) * cells;
    let i = (u.floor()).clamp(0.0, cells - 1.0);
    (i as usize, u - i)
}
