//! A minimal 3-vector of `f64`, the only linear algebra the core needs.
//!
//! Every operation is plain IEEE arithmetic in a fixed order (x, then y, then z), so results are
//! reproducible bit for bit across platforms and thread counts.

use std::fmt;
use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub, SubAssign};

/// A point, velocity or force in 3-D (metres, metres per second or newtons). Laid out as three
/// `f64` in order (see [`Vec3::zeros`]).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C)]
pub struct Vec3 {
    /// x component.
    pub x: f64,
    /// y component.
    pub y: f64,
    /// z component.
    pub z: f64,
}

/// `(x, y, z)` for messages. Plain `{}` writes each number in its shortest form that reads back
/// to the same `f64` (what a file gave is shown as written: `(0, 0, -1)`); a precision, `{:.4}`,
/// rounds each to that many significant digits, for computed positions whose last bits are
/// rounding (`0.09999999999999998` shows as `0.1`).
impl fmt::Display for Vec3 {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let show = |x: f64| match f.precision() {
            Some(digits) => significant(x, digits),
            None => shortest(x),
        };
        write!(f, "({}, {}, {})", show(self.x), show(self.y), show(self.z))
    }
}

/// `x` in the shortest decimal form that reads back to the same `f64`, as
/// `formats::world::Num` writes it (which the layers keep this module from using): plain for
/// moderate magnitudes, scientific otherwise.
fn shortest(x: f64) -> String {
    let a = x.abs();
    if a == 0.0 || (1e-5..1e16).contains(&a) {
        format!("{x}")
    } else {
        format!("{x:e}")
    }
}

/// `x` rounded to `digits` significant digits (at least 1), then written in its shortest form:
/// for showing a computed value whose last bits are rounding (a time summed step by step,
/// `2.9999999999997806`, shows as `3` to 12 digits; a stiffness `modulus × spacing`,
/// `15000.000596046448`, as `15000` to 6). Data that must read back exactly keeps every digit
/// (`formats::world::Num`).
pub fn significant(x: f64, digits: usize) -> String {
    if !x.is_finite() {
        return x.to_string();
    }
    shortest(round_significant(x, digits))
}

/// `x` rounded to `digits` significant digits (at least 1), as [`significant`] shows it.
pub fn round_significant(x: f64, digits: usize) -> f64 {
    if !x.is_finite() {
        return x;
    }
    format!("{:.*e}", digits.max(1) - 1, x).parse().unwrap_or(x)
}

impl Vec3 {
    /// The zero vector.
    pub const ZERO: Vec3 = Vec3::new(0.0, 0.0, 0.0);

    /// `n` zero vectors in memory allocated zeroed, which the system hands out as zero pages
    /// mapped when first written (`vec![Vec3::ZERO; n]` writes every one at once): the implicit
    /// solver's buffers, some of which a run never touches (the double-precision GMRES basis,
    /// 26 MB at 32³, took 10 ms of the first step's 60 on its leading thread).
    pub fn zeros(n: usize) -> Vec<Vec3> {
        let mut floats = std::mem::ManuallyDrop::new(vec![0.0f64; 3 * n]);
        let (ptr, len, capacity) = (floats.as_mut_ptr(), floats.len(), floats.capacity());
        assert!(len == 3 * n && capacity == 3 * n);
        // SAFETY: `Vec3` is `repr(C)` over three `f64` (size 24, alignment 8: an array of `3·n`
        // `f64` has the layout of `n` of them, the allocator's layout included), all-zero
        // bytes are `0.0`, and the buffer is handed over whole, never freed as `f64`s.
        unsafe { Vec::from_raw_parts(ptr.cast::<Vec3>(), n, n) }
    }

    /// A vector from its components.
    #[inline]
    pub const fn new(x: f64, y: f64, z: f64) -> Self {
        Vec3 { x, y, z }
    }

    /// The components as an array `[x, y, z]`.
    #[inline]
    pub const fn to_array(self) -> [f64; 3] {
        [self.x, self.y, self.z]
    }

    /// A vector from an array `[x, y, z]`.
    #[inline]
    pub const fn from_array(a: [f64; 3]) -> Self {
        Vec3::new(a[0], a[1], a[2])
    }

    /// Dot product.
    #[inline]
    pub fn dot(self, o: Vec3) -> f64 {
        self.x * o.x + self.y * o.y + self.z * o.z
    }

    /// Cross product.
    #[inline]
    pub fn cross(self, o: Vec3) -> Vec3 {
        Vec3::new(
            self.y * o.z - self.z * o.y,
            self.z * o.x - self.x * o.z,
            self.x * o.y - self.y * o.x,
        )
    }

    /// Squared Euclidean length.
    #[inline]
    pub fn length_squared(self) -> f64 {
        self.dot(self)
    }

    /// Euclidean length.
    #[inline]
    pub fn length(self) -> f64 {
        self.length_squared().sqrt()
    }

    /// True when all three components are finite (not NaN, not infinite).
    #[inline]
    pub fn is_finite(self) -> bool {
        self.x.is_finite() && self.y.is_finite() && self.z.is_finite()
    }

    /// Component-wise clamp into `[lo, hi]`.
    #[inline]
    pub fn clamp(self, lo: Vec3, hi: Vec3) -> Vec3 {
        Vec3::new(
            self.x.clamp(lo.x, hi.x),
            self.y.clamp(lo.y, hi.y),
            self.z.clamp(lo.z, hi.z),
        )
    }

    /// Component-wise minimum.
    #[inline]
    pub fn min(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x.min(o.x), self.y.min(o.y), self.z.min(o.z))
    }

    /// Component-wise maximum.
    #[inline]
    pub fn max(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x.max(o.x), self.y.max(o.y), self.z.max(o.z))
    }

    /// Largest absolute component.
    #[inline]
    pub fn max_abs(self) -> f64 {
        self.x.abs().max(self.y.abs()).max(self.z.abs())
    }
}

impl Add for Vec3 {
    type Output = Vec3;
    #[inline]
    fn add(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x + o.x, self.y + o.y, self.z + o.z)
    }
}

impl Sub for Vec3 {
    type Output = Vec3;
    #[inline]
    fn sub(self, o: Vec3) -> Vec3 {
        Vec3::new(self.x - o.x, self.y - o.y, self.z - o.z)
    }
}

impl Mul<f64> for Vec3 {
    type Output = Vec3;
    #[inline]
    fn mul(self, s: f64) -> Vec3 {
        Vec3::new(self.x * s, self.y * s, self.z * s)
    }
}

impl Mul<Vec3> for f64 {
    type Output = Vec3;
    #[inline]
    fn mul(self, v: Vec3) -> Vec3 {
        v * self
    }
}

impl Div<f64> for Vec3 {
    type Output = Vec3;
    #[inline]
    fn div(self, s: f64) -> Vec3 {
        Vec3::new(self.x / s, self.y / s, self.z / s)
    }
}

impl Neg for Vec3 {
    type Output = Vec3;
    #[inline]
    fn neg(self) -> Vec3 {
        Vec3::new(-self.x, -self.y, -self.z)
    }
}

impl AddAssign for Vec3 {
    #[inline]
    fn add_assign(&mut self, o: Vec3) {
        *self = *self + o;
    }
}

impl SubAssign for Vec3 {
    #[inline]
    fn sub_assign(&mut self, o: Vec3) {
        *self = *self - o;
    }
}

#[cfg(test)]
mod display_tests {
    use super::Vec3;

    #[test]
    fn vectors_print_as_a_triple_exactly_or_to_significant_digits() {
        let v = Vec3::new(0.0, -1.0, 0.1 + 0.2);
        assert_eq!(v.to_string(), "(0, -1, 0.30000000000000004)");
        assert_eq!(format!("{v:.6}"), "(0, -1, 0.3)");
        assert_eq!(
            format!("{:.3}", Vec3::new(1234.5678, 1e-9, f64::NAN)),
            "(1230, 1e-9, NaN)"
        );
    }
}
