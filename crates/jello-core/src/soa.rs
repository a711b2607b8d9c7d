//! Structure-of-arrays 3-vectors: the layout the force kernel and the integrators work in, so
//! that loops over points and springs run over contiguous `f64`s the compiler can vectorise.

use crate::vec3::Vec3;

/// Vectors per block when copying on several threads.
#[cfg(feature = "parallel")]
const BLOCK: usize = 8 * 1024;

crate::simd::multiversion! {
    /// `(x, y, z)[i] = aos[i]`.
    fn gather(x: &mut [f64], y: &mut [f64], z: &mut [f64], aos: &[Vec3]) {
        let n = aos.len();
        let (x, y, z) = (&mut x[..n], &mut y[..n], &mut z[..n]);
        for (i, v) in aos.iter().enumerate() {
            (x[i], y[i], z[i]) = (v.x, v.y, v.z);
        }
    }
}

crate::simd::multiversion! {
    /// `aos[i] = (x, y, z)[i]`.
    fn scatter(aos: &mut [Vec3], x: &[f64], y: &[f64], z: &[f64]) {
        let n = aos.len();
        let (x, y, z) = (&x[..n], &y[..n], &z[..n]);
        for (i, v) in aos.iter_mut().enumerate() {
            *v = Vec3::new(x[i], y[i], z[i]);
        }
    }
}

/// `n` 3-vectors as one buffer of `3n` numbers: all x components, then all y, then all z.
/// Element-wise arithmetic on whole vectors (the integrators' updates) is then one loop over the
/// buffer.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Soa {
    data: Vec<f64>,
    n: usize,
}

impl Soa {
    /// `n` zero vectors.
    pub fn zeros(n: usize) -> Self {
        Soa {
            data: vec![0.0; 3 * n],
            n,
        }
    }

    /// Number of vectors.
    pub fn len(&self) -> usize {
        self.n
    }

    /// True when there are no vectors.
    pub fn is_empty(&self) -> bool {
        self.n == 0
    }

    /// x components.
    #[inline]
    pub fn x(&self) -> &[f64] {
        &self.data[..self.n]
    }

    /// y components.
    #[inline]
    pub fn y(&self) -> &[f64] {
        &self.data[self.n..2 * self.n]
    }

    /// z components.
    #[inline]
    pub fn z(&self) -> &[f64] {
        &self.data[2 * self.n..]
    }

    /// The x, y and z components, mutable.
    #[inline]
    pub fn parts_mut(&mut self) -> [&mut [f64]; 3] {
        let (x, yz) = self.data.split_at_mut(self.n);
        let (y, z) = yz.split_at_mut(self.n);
        [x, y, z]
    }

    /// All `3n` numbers.
    #[inline]
    pub fn all(&self) -> &[f64] {
        &self.data
    }

    /// All `3n` numbers, mutable.
    #[inline]
    pub fn all_mut(&mut self) -> &mut [f64] {
        &mut self.data
    }

    /// Vector `i`.
    #[inline]
    pub fn get(&self, i: usize) -> Vec3 {
        let n = self.n;
        Vec3::new(self.data[i], self.data[n + i], self.data[2 * n + i])
    }

    /// Copies from an array of vectors of the same length.
    pub fn copy_from(&mut self, aos: &[Vec3]) {
        let [x, y, z] = self.parts_mut();
        gather(x, y, z, aos);
    }

    /// Copies into an array of vectors of the same length.
    pub fn copy_to(&self, aos: &mut [Vec3]) {
        scatter(aos, self.x(), self.y(), self.z());
    }

    /// [`Soa::copy_from`] in blocks on the rayon pool's threads.
    #[cfg(feature = "parallel")]
    pub fn par_copy_from(&mut self, aos: &[Vec3]) {
        use rayon::prelude::*;
        let [x, y, z] = self.parts_mut();
        let blocks = (
            x.par_chunks_mut(BLOCK),
            y.par_chunks_mut(BLOCK),
            z.par_chunks_mut(BLOCK),
            aos.par_chunks(BLOCK),
        );
        blocks
            .into_par_iter()
            .for_each(|(x, y, z, aos)| gather(x, y, z, aos));
    }

    /// [`Soa::copy_to`] in blocks on the rayon pool's threads.
    #[cfg(feature = "parallel")]
    pub fn par_copy_to(&self, aos: &mut [Vec3]) {
        use rayon::prelude::*;
        let blocks = (
            aos.par_chunks_mut(BLOCK),
            self.x().par_chunks(BLOCK),
            self.y().par_chunks(BLOCK),
            self.z().par_chunks(BLOCK),
        );
        blocks
            .into_par_iter()
            .for_each(|(aos, x, y, z)| scatter(aos, x, y, z));
    }

    /// A new structure of arrays holding `aos`.
    pub fn from_aos(aos: &[Vec3]) -> Self {
        let mut s = Soa::zeros(aos.len());
        s.copy_from(aos);
        s
    }

    /// Copies another structure of arrays of the same length, without allocating.
    pub fn copy_from_soa(&mut self, other: &Soa) {
        self.data.copy_from_slice(&other.data);
    }

    /// Sets every component to 0.
    pub fn fill_zero(&mut self) {
        self.data.fill(0.0);
    }
}
