//! Obstacles: the box that holds the jello, the classic inclined plane, and any number of static
//! planes, spheres and solid boxes, all acting through the same zero-rest-length penalty spring
//! (docs/spec.md): `kCollision·depth·n − dCollision (v·n) n`, `n` the unit normal pointing back to
//! where the point may be.
//!
//! Every shape answers here, and only here, where a point touches it: the depth and the normal of
//! each [`ObstacleContact`]. The force kernel, the energy, the deepest penetration and the blow-up check
//! all read them from these functions (the kernel through their branch-free forms, so its point
//! loop vectorises).

use crate::model::defaults;
use crate::model::error::ModelError;
use crate::vec3::Vec3;

/// Where a point touches an obstacle: how deep it is, and which way it is pushed.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ObstacleContact {
    /// Depth (m), greater than 0.
    pub depth: f64,
    /// Unit normal pointing out of the obstacle (into the side the point may be on).
    pub normal: Vec3,
}

impl ObstacleContact {
    /// This contact with `clearance` (m) taken off its depth, or `None` when that leaves none
    /// (see [`crate::model::clearance`]).
    #[inline]
    pub fn less(self, clearance: f64) -> Option<Self> {
        let depth = self.depth - clearance;
        (depth > 0.0).then_some(ObstacleContact {
            depth,
            normal: self.normal,
        })
    }

    /// The penalty spring's force (N) on a point moving at `v`, with stiffness `k` (N/m) and
    /// damping `d` (N·s/m): `k·depth·n − d (v·n) n`.
    #[inline]
    pub fn force(&self, v: Vec3, k: f64, d: f64) -> Vec3 {
        let n = self.normal;
        n * (k * self.depth) - n * (d * v.dot(n))
    }
}

/// An axis-aligned box: the box that holds the jello (its walls push points back in), or a solid
/// box obstacle (its faces push points out).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Lower corner (m).
    pub min: Vec3,
    /// Upper corner (m).
    pub max: Vec3,
}

impl Aabb {
    /// The classic bounding box `[−2, 2]³`.
    pub fn classic() -> Self {
        let h = defaults::BOX_HALF_WIDTH;
        Aabb {
            min: Vec3::new(-h, -h, -h),
            max: Vec3::new(h, h, h),
        }
    }

    /// A box from `min` to `max`; fails unless both are finite and `min < max` on every axis.
    pub fn new(min: Vec3, max: Vec3) -> Result<Aabb, ModelError> {
        let b = Aabb { min, max };
        b.check("box")?;
        Ok(b)
    }

    /// Fails unless the corners are finite and `min < max` on every axis.
    pub(crate) fn check(&self, what: &str) -> Result<(), ModelError> {
        let (lo, hi) = (self.min, self.max);
        if lo.is_finite() && hi.is_finite() && lo.x < hi.x && lo.y < hi.y && lo.z < hi.z {
            Ok(())
        } else {
            Err(ModelError::new(format!(
                "{what} must be finite with min < max on every axis (min {lo}, max {hi})"
            )))
        }
    }

    /// Distance from `p` to the box (0 inside), measured per axis as the largest excursion: the
    /// deepest of its [`Aabb::wall_contacts`].
    pub fn excursion(&self, p: Vec3) -> f64 {
        let out = |v: f64, lo: f64, hi: f64| (lo - v).max(v - hi).max(0.0);
        out(p.x, self.min.x, self.max.x)
            .max(out(p.y, self.min.y, self.max.y))
            .max(out(p.z, self.min.z, self.max.z))
    }

    /// Whether the box `[lo, hi]` lies inside this one (walls included): no point of it touches a
    /// wall ([`Aabb::wall_contacts`]).
    pub(crate) fn holds(&self, lo: Vec3, hi: Vec3) -> bool {
        lo.x >= self.min.x
            && lo.y >= self.min.y
            && lo.z >= self.min.z
            && hi.x <= self.max.x
            && hi.y <= self.max.y
            && hi.z <= self.max.z
    }

    /// The walls' contacts with a point, as the box that holds the jello: one per wall the point
    /// is strictly outside of (past an edge or a corner, one per wall crossed), in the order x,
    /// y, z; each toward the point's projection on that wall.
    pub fn wall_contacts(&self, p: Vec3) -> impl Iterator<Item = ObstacleContact> {
        let (lo, hi) = (self.min.to_array(), self.max.to_array());
        let p = p.to_array();
        (0..3).filter_map(move |axis| {
            let mut n = [0.0; 3];
            if p[axis] < lo[axis] {
                n[axis] = 1.0;
                Some(ObstacleContact {
                    depth: lo[axis] - p[axis],
                    normal: Vec3::from_array(n),
                })
            } else if p[axis] > hi[axis] {
                n[axis] = -1.0;
                Some(ObstacleContact {
                    depth: p[axis] - hi[axis],
                    normal: Vec3::from_array(n),
                })
            } else {
                None
            }
        })
    }

    /// The contact of wall `w` (0 to 5: −x, +x, −y, +y, −z, +z, the wall at the box's minimum
    /// or maximum along each axis) with a point strictly outside it: the one of
    /// [`Aabb::wall_contacts`] that belongs to that wall.
    pub fn wall_contact(&self, p: Vec3, w: usize) -> Option<ObstacleContact> {
        let (axis, max) = (w / 2, w % 2 == 1);
        let (c, lo, hi) = (
            p.to_array()[axis],
            self.min.to_array()[axis],
            self.max.to_array()[axis],
        );
        let mut n = [0.0; 3];
        let depth = if max {
            n[axis] = -1.0;
            c - hi
        } else {
            n[axis] = 1.0;
            lo - c
        };
        (depth > 0.0).then(|| ObstacleContact {
            depth,
            normal: Vec3::from_array(n),
        })
    }

    /// As a solid box: the contact of a point strictly inside, through the nearest face (ties go
    /// to the first of −x, +x, −y, +y, −z, +z); `None` outside or on the surface.
    pub fn solid_contact(&self, p: Vec3) -> Option<ObstacleContact> {
        let (depth, normal) = self.solid_depth(p);
        (depth > 0.0).then_some(ObstacleContact { depth, normal })
    }

    /// Branch-free form of [`Aabb::solid_contact`]: the depth to the nearest face (≤ 0 when the
    /// point is not strictly inside) and that face's outward normal.
    #[inline(always)]
    pub(crate) fn solid_depth(&self, p: Vec3) -> (f64, Vec3) {
        let faces = [
            (p.x - self.min.x, Vec3::new(-1.0, 0.0, 0.0)),
            (self.max.x - p.x, Vec3::new(1.0, 0.0, 0.0)),
            (p.y - self.min.y, Vec3::new(0.0, -1.0, 0.0)),
            (self.max.y - p.y, Vec3::new(0.0, 1.0, 0.0)),
            (p.z - self.min.z, Vec3::new(0.0, 0.0, -1.0)),
            (self.max.z - p.z, Vec3::new(0.0, 0.0, 1.0)),
        ];
        let mut best = faces[0];
        for face in &faces[1..] {
            best = if face.0 < best.0 { *face } else { best };
        }
        best
    }
}

/// A plane `a x + b y + c z + d = 0` with the side points are allowed on: the classic inclined
/// plane, or a plane obstacle.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// `[a, b, c, d]` as in the world file.
    pub coeffs: [f64; 4],
    /// `+1.0` when the allowed side is where `a x + b y + c z + d > 0`, else `−1.0`.
    pub side: f64,
}

impl Plane {
    /// The plane whose allowed side holds `reference` (docs/spec.md: the centre of mass of the initial
    /// positions). A reference exactly on the plane gets the positive side, the side every
    /// official world uses. Fails when a coefficient is not finite or the length of `(a, b, c)`
    /// is zero or overflows.
    pub fn facing(coeffs: [f64; 4], reference: Vec3) -> Result<Plane, ModelError> {
        let plane = Plane::new(coeffs)?;
        let side = if plane.value(reference) < 0.0 {
            -1.0
        } else {
            1.0
        };
        Ok(Plane { coeffs, side })
    }

    /// The plane whose allowed side is where `a x + b y + c z + d > 0` (the normal `(a, b, c)`
    /// points into it). Fails like [`Plane::facing`].
    pub fn new(coeffs: [f64; 4]) -> Result<Plane, ModelError> {
        if coeffs.iter().any(|c| !c.is_finite()) {
            return Err(ModelError::new("plane coefficients must be finite"));
        }
        let plane = Plane { coeffs, side: 1.0 };
        let norm = plane.normal_length();
        if !(norm.is_finite() && norm > 0.0) {
            return Err(ModelError::new(format!(
                "plane normal (a, b, c) must have a finite, non-zero length (it has {norm})"
            )));
        }
        Ok(plane)
    }

    /// `a x + b y + c z + d` at `p`.
    #[inline]
    pub fn value(&self, p: Vec3) -> f64 {
        let [a, b, c, d] = self.coeffs;
        a * p.x + b * p.y + c * p.z + d
    }

    /// Whether `p` is strictly on the forbidden side: the sign of [`Plane::value`] alone, a
    /// test that [`Plane::contact`] passes before it finds a contact.
    #[inline]
    pub fn on_forbidden_side(&self, p: Vec3) -> bool {
        self.value(p) * self.side < 0.0
    }

    /// Whether no point of the box `[lo, hi]` is on the forbidden side: its nearest corner is
    /// on the allowed side by more than `1e-9` of the terms' sizes, far past any rounding of
    /// [`Plane::value`] at a point inside.
    pub(crate) fn clears_box(&self, lo: Vec3, hi: Vec3) -> bool {
        let [a, b, c, d] = self.coeffs.map(|k| k * self.side);
        let (lo, hi) = (lo.to_array(), hi.to_array());
        let (mut least, mut size) = (d, d.abs());
        for (k, (lo, hi)) in [a, b, c].into_iter().zip(lo.into_iter().zip(hi)) {
            least += (k * lo).min(k * hi);
            size += k.abs() * lo.abs().max(hi.abs());
        }
        least > 1e-9 * size
    }

    /// `|(a, b, c)|`.
    #[inline]
    pub fn normal_length(&self) -> f64 {
        let [a, b, c, _] = self.coeffs;
        Vec3::new(a, b, c).length()
    }

    /// Unit normal pointing into the allowed side.
    #[inline]
    pub fn inward_normal(&self) -> Vec3 {
        let [a, b, c, _] = self.coeffs;
        Vec3::new(a, b, c) * (self.side / self.normal_length())
    }

    /// The contact of a point on the forbidden side: depth `|a x + b y + c z + d| / |(a, b, c)|`,
    /// normal into the allowed side; `None` on the allowed side or on the plane.
    #[inline]
    pub fn contact(&self, p: Vec3) -> Option<ObstacleContact> {
        // The sign first: most points asked are on the allowed side, and the normal costs a
        // square root and a division.
        if !self.on_forbidden_side(p) {
            return None;
        }
        let (depth, normal) = self.depth(p);
        (depth > 0.0).then_some(ObstacleContact { depth, normal })
    }

    /// Branch-free form of [`Plane::contact`]: the depth (0 on the allowed side or the plane)
    /// and the normal into the allowed side.
    #[inline(always)]
    pub(crate) fn depth(&self, p: Vec3) -> (f64, Vec3) {
        self.depth_with(p, self.normal_length(), self.inward_normal())
    }

    /// [`Plane::depth`] with `|(a, b, c)|` and the inward normal computed once by the caller
    /// (for a loop over many points).
    #[inline(always)]
    pub(crate) fn depth_with(&self, p: Vec3, norm: f64, inward: Vec3) -> (f64, Vec3) {
        let s = self.value(p);
        let depth = if s * self.side < 0.0 {
            s.abs() / norm
        } else {
            0.0
        };
        (depth, inward)
    }
}

/// A solid ball.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sphere {
    /// Centre (m).
    pub centre: Vec3,
    /// Radius (m), finite and positive.
    pub radius: f64,
}

impl Sphere {
    /// A ball of `radius` about `centre`; fails unless both are finite and the radius positive.
    pub fn new(centre: Vec3, radius: f64) -> Result<Sphere, ModelError> {
        let s = Sphere { centre, radius };
        s.check()?;
        Ok(s)
    }

    fn check(&self) -> Result<(), ModelError> {
        if self.centre.is_finite() && self.radius.is_finite() && self.radius > 0.0 {
            Ok(())
        } else {
            Err(ModelError::new(format!(
                "sphere needs a finite centre and a finite, positive radius (centre {}, radius {})",
                self.centre, self.radius
            )))
        }
    }

    /// The contact of a point strictly inside: depth `radius − |p − centre|`, normal along
    /// `p − centre`; a point exactly at the centre is pushed along +z. `None` outside or on the
    /// surface.
    pub fn contact(&self, p: Vec3) -> Option<ObstacleContact> {
        let (depth, normal) = self.depth(p);
        (depth > 0.0).then_some(ObstacleContact { depth, normal })
    }

    /// Branch-free form of [`Sphere::contact`]: the depth (≤ 0 when not strictly inside) and the
    /// outward normal.
    #[inline(always)]
    pub(crate) fn depth(&self, p: Vec3) -> (f64, Vec3) {
        let d = p - self.centre;
        let l = d.length();
        let normal = if l > 0.0 {
            d / l
        } else {
            Vec3::new(0.0, 0.0, 1.0)
        };
        (self.radius - l, normal)
    }
}

/// A static obstacle points are kept out of, in addition to the box and the classic plane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Obstacle {
    /// A plane: points on its forbidden side are pushed back (as the classic inclined plane).
    Plane(Plane),
    /// A solid ball: points inside are pushed out along the radius.
    Sphere(Sphere),
    /// A solid axis-aligned box: points inside are pushed out through the nearest face.
    Box(Aabb),
}

impl Obstacle {
    /// Whether no point of the box `[lo, hi]` touches the obstacle ([`Obstacle::contact`] finds
    /// nothing there): a plane's allowed side holds the box ([`Plane::clears_box`]); a ball's
    /// centre is farther from the box than its radius, by more than `1e-9` of it; a solid box
    /// shares no inside with it (the box's surface touches nothing).
    pub(crate) fn clears_box(&self, lo: Vec3, hi: Vec3) -> bool {
        match self {
            Obstacle::Plane(plane) => plane.clears_box(lo, hi),
            Obstacle::Sphere(sphere) => {
                let c = sphere.centre;
                let gap = |c: f64, lo: f64, hi: f64| (lo - c).max(c - hi).max(0.0);
                let d = Vec3::new(
                    gap(c.x, lo.x, hi.x),
                    gap(c.y, lo.y, hi.y),
                    gap(c.z, lo.z, hi.z),
                );
                d.length() > sphere.radius * (1.0 + 1e-9)
            }
            Obstacle::Box(b) => {
                hi.x <= b.min.x
                    || lo.x >= b.max.x
                    || hi.y <= b.min.y
                    || lo.y >= b.max.y
                    || hi.z <= b.min.z
                    || lo.z >= b.max.z
            }
        }
    }

    /// Where a point touches the obstacle, if it does.
    #[inline]
    pub fn contact(&self, p: Vec3) -> Option<ObstacleContact> {
        match self {
            Obstacle::Plane(plane) => plane.contact(p),
            Obstacle::Sphere(sphere) => sphere.contact(p),
            Obstacle::Box(b) => b.solid_contact(p),
        }
    }

    /// Fails when a value is out of range (the constructors check the same).
    pub(crate) fn check(&self) -> Result<(), ModelError> {
        match self {
            Obstacle::Plane(plane) => Plane::new(plane.coeffs).and_then(|_| {
                if plane.side == 1.0 || plane.side == -1.0 {
                    Ok(())
                } else {
                    Err(ModelError::new("plane side must be +1 or −1"))
                }
            }),
            Obstacle::Sphere(sphere) => sphere.check(),
            Obstacle::Box(b) => b.check("box obstacle"),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrate::implicit::test_models::values;

    /// A box judged clear of a surface holds no point that touches it (its corners, a grid
    /// through it and points drawn inside): for each obstacle, the walls and the inclined plane,
    /// on boxes of all sizes near and across their surfaces; both answers come up.
    #[test]
    fn a_box_clear_of_a_surface_holds_no_point_touching_it() {
        let plane = Plane::facing([0.3, -1.0, 0.5, 0.2], Vec3::new(0.0, 2.0, 0.0)).unwrap();
        let ball = Sphere::new(Vec3::new(0.2, -0.1, 0.3), 0.7).unwrap();
        let solid = Aabb::new(Vec3::new(-0.5, -0.2, 0.1), Vec3::new(0.4, 0.6, 0.9)).unwrap();
        let walls = Aabb::new(Vec3::new(-1.0, -1.2, -0.8), Vec3::new(1.1, 0.9, 1.0)).unwrap();
        type Clears = Box<dyn Fn(Vec3, Vec3) -> bool>;
        type Touches = Box<dyn Fn(Vec3) -> bool>;
        let surfaces: [(&str, Clears, Touches); 4] = [
            (
                "plane",
                Box::new(move |lo, hi| Obstacle::Plane(plane).clears_box(lo, hi)),
                Box::new(move |p| Obstacle::Plane(plane).contact(p).is_some()),
            ),
            (
                "ball",
                Box::new(move |lo, hi| Obstacle::Sphere(ball).clears_box(lo, hi)),
                Box::new(move |p| Obstacle::Sphere(ball).contact(p).is_some()),
            ),
            (
                "solid box",
                Box::new(move |lo, hi| Obstacle::Box(solid).clears_box(lo, hi)),
                Box::new(move |p| Obstacle::Box(solid).contact(p).is_some()),
            ),
            (
                "walls",
                Box::new(move |lo, hi| walls.holds(lo, hi)),
                Box::new(move |p| walls.wall_contacts(p).next().is_some()),
            ),
        ];
        let mut next = values(3);
        for (name, clears, touches) in &surfaces {
            let (mut clear, mut not) = (0, 0);
            for _ in 0..4000 {
                let size = 0.6 * (next() + 1.0).powi(3);
                let lo = Vec3::new(1.5 * next(), 1.5 * next(), 1.5 * next());
                let hi = lo + Vec3::new(next() + 1.0, next() + 1.0, next() + 1.0) * size;
                let at = |t: [f64; 3]| {
                    Vec3::new(
                        lo.x + t[0] * (hi.x - lo.x),
                        lo.y + t[1] * (hi.y - lo.y),
                        lo.z + t[2] * (hi.z - lo.z),
                    )
                };
                let grid = [0.0, 0.5, 1.0];
                let mut points: Vec<Vec3> = (grid.iter())
                    .flat_map(|&a| grid.iter().flat_map(move |&b| grid.map(|c| [a, b, c])))
                    .map(at)
                    .collect();
                for _ in 0..20 {
                    let t = [next(), next(), next()].map(|v| 0.5 * (v + 1.0));
                    points.push(at(t));
                }
                let touching = points.iter().any(|&p| touches(p));
                if clears(lo, hi) {
                    clear += 1;
                    assert!(!touching, "{name}: box {lo:?}–{hi:?} judged clear");
                } else {
                    not += 1;
                }
            }
            assert!(clear > 100 && not > 100, "{name}: {clear} clear, {not} not");
        }
    }
}
