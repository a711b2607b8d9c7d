//! The external force field: forces sampled on a `res × res × res` grid over the bounding box,
//! read off by trilinear interpolation (docs/spec.md).

use crate::model::error::ModelError;
use crate::model::obstacle::Aabb;
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
    /// See [`ForceField::max_swirl`].
    max_swirl: f64,
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
        let max_swirl = if uniform.is_some() {
            0.0
        } else {
            max_swirl(res, &bounds, &forces)
        };
        Ok(ForceField {
            res,
            bounds,
            forces,
            uniform,
            max_swirl,
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

    /// The derivatives of [`sample`](Self::sample) along x, y and z at `p` (N/m): within a cell,
    /// those of its trilinear interpolation; zero along an axis where `p` is outside the box
    /// (the sample is constant there).
    pub fn gradient(&self, p: Vec3) -> [Vec3; 3] {
        if self.uniform.is_some() {
            return [Vec3::ZERO; 3];
        }
        let b = &self.bounds;
        let q = p.clamp(b.min, b.max);
        let cells = (self.res - 1) as f64;
        let (i, fx) = cell(q.x, b.min.x, b.max.x, cells);
        let (j, fy) = cell(q.y, b.min.y, b.max.y, cells);
        let (k, fz) = cell(q.z, b.min.z, b.max.z, cells);
        let r = self.res;
        let at =
            |di: usize, dj: usize, dk: usize| self.forces[((i + di) * r + j + dj) * r + k + dk];
        // The cell's eight corners weighted for the value, with one axis's weights replaced by
        // that axis's derivative (−1, +1 over the cell's width).
        let weight = |t: f64, d: usize, derivative: bool| match (derivative, d) {
            (false, 0) => 1.0 - t,
            (false, _) => t,
            (true, 0) => -1.0,
            (true, _) => 1.0,
        };
        let inside = |v: f64, lo: f64, hi: f64| if v > lo && v < hi { 1.0 } else { 0.0 };
        let scale = [
            inside(p.x, b.min.x, b.max.x) * cells / (b.max.x - b.min.x),
            inside(p.y, b.min.y, b.max.y) * cells / (b.max.y - b.min.y),
            inside(p.z, b.min.z, b.max.z) * cells / (b.max.z - b.min.z),
        ];
        let mut out = [Vec3::ZERO; 3];
        for (axis, o) in out.iter_mut().enumerate() {
            for (di, dj, dk) in (0..8).map(|c| (c >> 2, (c >> 1) & 1, c & 1)) {
                let w = weight(fx, di, axis == 0)
                    * weight(fy, dj, axis == 1)
                    * weight(fz, dk, axis == 2);
                *o += at(di, dj, dk) * w;
            }
            *o = *o * scale[axis];
        }
        out
    }

    /// The force everywhere, when every node holds the same one.
    pub fn uniform(&self) -> Option<Vec3> {
        self.uniform
    }

    /// A bound on the swirl of [`gradient`](Self::gradient) anywhere (N/m): on each
    /// antisymmetric entry `½|∂f_b/∂a − ∂f_a/∂b|`, and on `½|∂f_b/∂a|` alone (outside the box
    /// one derivative is zero). Within a cell each is multilinear in the position, so largest at
    /// a corner, where the derivatives are differences along the cell's edges at a node.
    pub fn max_swirl(&self) -> f64 {
        self.max_swirl
    }

    /// Largest node force magnitude (N).
    pub fn max_magnitude(&self) -> f64 {
        self.forces.iter().map(|f| f.length()).fold(0.0, f64::max)
    }
}

/// The size of the antisymmetric part of a field's gradient `[∂f/∂x, ∂f/∂y, ∂f/∂z]` (N/m): the
/// largest of its entries `½|∂f_b/∂a − ∂f_a/∂b|` (the implicit solver's measure of a swirl).
pub(crate) fn swirl(&[dx, dy, dz]: &[Vec3; 3]) -> f64 {
    let half = |a: f64, b: f64| 0.5 * (a - b).abs();
    half(dy.x, dx.y).max(half(dz.x, dx.z)).max(half(dz.y, dy.z))
}

/// See [`ForceField::max_swirl`]: at every node, over the edges on either side of it along
/// each pair of axes (every cell corner there).
fn max_swirl(res: usize, b: &Aabb, forces: &[Vec3]) -> f64 {
    let cells = (res - 1) as f64;
    let scale = [
        cells / (b.max.x - b.min.x),
        cells / (b.max.y - b.min.y),
        cells / (b.max.z - b.min.z),
    ];
    let step = [res * res, res, 1];
    let mut most: f64 = 0.0;
    for i in 0..res {
        for j in 0..res {
            for k in 0..res {
                let node = [i, j, k];
                let at = (i * res + j) * res + k;
                // Component `c`'s derivative along `axis` on the edge before (0) and after (1)
                // the node, where there is one.
                let derivative = |axis: usize, c: usize, side: usize| -> Option<f64> {
                    let (from, to) = match side {
                        0 if node[axis] > 0 => (at - step[axis], at),
                        1 if node[axis] + 1 < res => (at, at + step[axis]),
                        _ => return None,
                    };
                    Some((forces[to].to_array()[c] - forces[from].to_array()[c]) * scale[axis])
                };
                for (a, c) in [(0, 1), (0, 2), (1, 2)] {
                    for x in (0..2).filter_map(|side| derivative(a, c, side)) {
                        for y in (0..2).filter_map(|side| derivative(c, a, side)) {
                            most = most.max(0.5 * (x - y).abs().max(x.abs()).max(y.abs()));
                        }
                    }
                }
            }
        }
    }
    most
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

#[cfg(test)]
mod tests {
    use super::*;

    /// The gradient is the derivative of the trilinear sample: against central differences
    /// inside cells, on a field that is not linear.
    #[test]
    fn the_gradient_is_the_samples_derivative() {
        let field = ForceField::from_fn(4, Aabb::classic(), |p| {
            Vec3::new(p.x * p.y, p.z * p.z - p.x, (p.x + 2.0 * p.y).sin())
        })
        .unwrap();
        let e = 1e-6;
        for p in [
            Vec3::new(0.3, -0.7, 1.1),
            Vec3::new(-1.9, 1.2, 0.05),
            Vec3::new(1.5, 0.4, -1.3),
        ] {
            let gradient = field.gradient(p);
            for (axis, g) in gradient.iter().enumerate() {
                let mut d = Vec3::ZERO;
                match axis {
                    0 => d.x = e,
                    1 => d.y = e,
                    _ => d.z = e,
                }
                let numeric = (field.sample(p + d) - field.sample(p - d)) / (2.0 * e);
                assert!(
                    (*g - numeric).max_abs() < 1e-6,
                    "axis {axis} at {p:?}: {g:?} vs {numeric:?}"
                );
            }
        }
        // Outside the box the sample is constant along the clamped axis.
        let outside = field.gradient(Vec3::new(2.5, 0.0, 0.0));
        assert_eq!(outside[0], Vec3::ZERO);
        assert_ne!(outside[1], Vec3::ZERO);
    }

    /// `max_swirl` is the swirl of a turning field `c·(−y, x, 0)`, and bounds the swirl of a
    /// field that is not linear everywhere, inside the box and out; a uniform field has none.
    #[test]
    fn max_swirl_bounds_the_swirl_everywhere() {
        let turning = ForceField::from_fn(5, Aabb::classic(), |p| {
            Vec3::new(-3.0 * p.y, 3.0 * p.x, 0.0)
        })
        .unwrap();
        assert!(
            (turning.max_swirl() - 3.0).abs() < 1e-12,
            "{}",
            turning.max_swirl()
        );
        let field = ForceField::from_fn(4, Aabb::classic(), |p| {
            Vec3::new(p.x * p.y, p.z * p.z - p.x, (p.x + 2.0 * p.y).sin() * p.z)
        })
        .unwrap();
        let mut seen: f64 = 0.0;
        let steps = 37;
        for i in 0..=steps {
            for j in 0..=steps {
                for k in 0..=steps {
                    let at = |c: usize| -3.0 + 6.0 * c as f64 / steps as f64;
                    seen = seen.max(swirl(&field.gradient(Vec3::new(at(i), at(j), at(k)))));
                }
            }
        }
        assert!(
            seen <= field.max_swirl() * (1.0 + 1e-12),
            "{seen} > {}",
            field.max_swirl()
        );
        assert!(
            seen > 0.5 * field.max_swirl(),
            "{seen} ≪ {}",
            field.max_swirl()
        );
        let still =
            ForceField::from_fn(3, Aabb::classic(), |_| Vec3::new(0.0, 0.0, -9.81)).unwrap();
        assert_eq!(still.max_swirl(), 0.0);
    }
}
