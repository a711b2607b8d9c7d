//! Structure-of-arrays 3-vectors: the layout the force kernel and the integrators work in, so
//! that loops over points and springs run over contiguous `f64`s the compiler can vectorise.

use crate::vec3::Vec3;

/// `n` 3-vectors as three arrays of `n` components each.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Soa {
    /// x components.
    pub x: Vec<f64>,
    /// y components.
    pub y: Vec<f64>,
    /// z components.
    pub z: Vec<f64>,
}

impl Soa {
    /// `n` zero vectors.
    pub fn zeros(n: usize) -> Self {
        Soa {
            x: vec![0.0; n],
            y: vec![0.0; n],
            z: vec![0.0; n],
        }
    }

    /// Number of vectors.
    pub fn len(&self) -> usize {
        self.x.len()
    }

    /// True when there are no vectors.
    pub fn is_empty(&self) -> bool {
        self.x.is_empty()
    }

    /// Vector `i`.
    #[inline]
    pub fn get(&self, i: usize) -> Vec3 {
        Vec3::new(self.x[i], self.y[i], self.z[i])
    }

    /// Sets vector `i`.
    #[inline]
    pub fn set(&mut self, i: usize, v: Vec3) {
        self.x[i] = v.x;
        self.y[i] = v.y;
        self.z[i] = v.z;
    }

    /// Copies from an array of vectors of the same length.
    pub fn copy_from(&mut self, aos: &[Vec3]) {
        let n = aos.len();
        let (x, y, z) = (&mut self.x[..n], &mut self.y[..n], &mut self.z[..n]);
        for (i, v) in aos.iter().enumerate() {
            (x[i], y[i], z[i]) = (v.x, v.y, v.z);
        }
    }

    /// Copies into an array of vectors of the same length.
    pub fn copy_to(&self, aos: &mut [Vec3]) {
        let n = aos.len();
        let (x, y, z) = (&self.x[..n], &self.y[..n], &self.z[..n]);
        for (i, v) in aos.iter_mut().enumerate() {
            *v = Vec3::new(x[i], y[i], z[i]);
        }
    }

    /// A new structure of arrays holding `aos`.
    pub fn from_aos(aos: &[Vec3]) -> Self {
        let mut s = Soa::zeros(aos.len());
        s.copy_from(aos);
        s
    }

    /// Copies another structure of arrays of the same length, without allocating.
    pub fn copy_from_soa(&mut self, other: &Soa) {
        self.x.copy_from_slice(&other.x);
        self.y.copy_from_slice(&other.y);
        self.z.copy_from_slice(&other.z);
    }

    /// Sets every component to 0.
    pub fn fill_zero(&mut self) {
        self.x.fill(0.0);
        self.y.fill(0.0);
        self.z.fill(0.0);
    }
}
