//! Structure-of-arrays 3-vectors: the layout the force kernel and the integrators work in, so
//! that loops over points and springs run over contiguous `f64`s the compiler can vectorise.

use std::ops::Range;

use crate::vec3::Vec3;

crate::compute::simd::multiversion! {
    /// `(x, y, z)[i] = aos[i]`.
    fn gather(x: &mut [f64], y: &mut [f64], z: &mut [f64], aos: &[Vec3]) {
        let n = aos.len();
        let (x, y, z) = (&mut x[..n], &mut y[..n], &mut z[..n]);
        for (i, v) in aos.iter().enumerate() {
            (x[i], y[i], z[i]) = (v.x, v.y, v.z);
        }
    }
}

crate::compute::simd::multiversion! {
    /// `aos[i] = (x, y, z)[i]`.
    fn scatter(aos: &mut [Vec3], x: &[f64], y: &[f64], z: &[f64]) {
        let n = aos.len();
        let (x, y, z) = (&x[..n], &y[..n], &z[..n]);
        for (i, v) in aos.iter_mut().enumerate() {
            *v = Vec3::new(x[i], y[i], z[i]);
        }
    }
}

/// `n` 3-vectors as one buffer: all x components, then all y, then all z, so that loops over
/// points run over contiguous numbers the compiler can vectorise.
///
/// Each component starts on a 64-byte boundary, so that AVX-512 loads and stores of aligned
/// runs do not straddle cache lines. On large buffers the components are not packed end to end:
/// each starts 512 bytes further along modulo 4 KiB than the one before, and each buffer of a
/// [`Soa::with_color`] another 128 bytes further. A power-of-two lattice would otherwise put the
/// x, y and z of a point, and of its neighbour a plane away, 4 KiB-multiples apart, where they
/// all fall into the same set of the L1 cache: the spring loop reads twelve such streams at once.
#[derive(Debug, Default)]
pub struct Soa {
    data: Vec<f64>,
    n: usize,
    color: usize,
    /// Index in `data` of the first x, y and z component.
    starts: [usize; 3],
}

impl Clone for Soa {
    /// A copy laid out anew (the copy's buffer has an alignment of its own).
    fn clone(&self) -> Self {
        let mut copy = Soa::with_color(self.n, self.color);
        for (to, from) in copy
            .parts_mut()
            .into_iter()
            .zip([self.x(), self.y(), self.z()])
        {
            to.copy_from_slice(from);
        }
        copy
    }
}

impl PartialEq for Soa {
    fn eq(&self, other: &Self) -> bool {
        (self.x(), self.y(), self.z()) == (other.x(), other.y(), other.z())
    }
}

/// `len` zeros starting on a cache line: a buffer with 7 numbers to spare, whatever the
/// allocation's alignment, and the index of the first number on a 64-byte boundary.
pub(crate) fn cache_aligned_zeros(len: usize) -> (Vec<f64>, usize) {
    let data = vec![0.0; len + 7];
    let first = data.as_ptr().align_offset(64).min(7);
    (data, first)
}

/// Buffers shorter than this are packed end to end (they stay in cache anyway).
const PAD_MIN: usize = 512;

impl Soa {
    /// `n` zero vectors.
    pub fn zeros(n: usize) -> Self {
        Soa::with_color(n, 0)
    }

    /// `n` zero vectors, laid out to fall into other cache sets than buffers of another `color`
    /// (0 to 3) used in the same loops.
    pub fn with_color(n: usize, color: usize) -> Self {
        // Strides in whole cache lines (8 numbers); on large buffers stride·8 ≡ 512 (mod 4096),
        // the components 8 cache sets apart, and a color 2 sets on.
        let (stride, lead) = if n < PAD_MIN {
            (n.next_multiple_of(8), 0)
        } else {
            (n.next_multiple_of(512) + 64, 16 * (color % 4))
        };
        let (data, first) = cache_aligned_zeros(lead + 2 * stride + n);
        let first = first + lead;
        Soa {
            data,
            n,
            color,
            starts: [first, first + stride, first + 2 * stride],
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
        &self.data[self.starts[0]..self.starts[0] + self.n]
    }

    /// y components.
    #[inline]
    pub fn y(&self) -> &[f64] {
        &self.data[self.starts[1]..self.starts[1] + self.n]
    }

    /// z components.
    #[inline]
    pub fn z(&self) -> &[f64] {
        &self.data[self.starts[2]..self.starts[2] + self.n]
    }

    /// The x, y and z components of the vectors `r`.
    #[inline]
    pub fn range(&self, r: Range<usize>) -> [&[f64]; 3] {
        [&self.x()[r.clone()], &self.y()[r.clone()], &self.z()[r]]
    }

    /// The x, y and z components of the vectors `r`, mutable.
    #[inline]
    pub fn range_mut(&mut self, r: Range<usize>) -> [&mut [f64]; 3] {
        self.parts_mut().map(|c| &mut c[r.clone()])
    }

    /// The x, y and z components, mutable.
    #[inline]
    pub fn parts_mut(&mut self) -> [&mut [f64]; 3] {
        let ([x0, y0, z0], n) = (self.starts, self.n);
        let (x, rest) = self.data[x0..].split_at_mut(y0 - x0);
        let (y, z) = rest.split_at_mut(z0 - y0);
        [&mut x[..n], &mut y[..n], &mut z[..n]]
    }

    /// Vector `i`.
    #[inline]
    pub fn get(&self, i: usize) -> Vec3 {
        let [x, y, z] = self.starts;
        Vec3::new(self.data[x + i], self.data[y + i], self.data[z + i])
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

    /// [`Soa::copy_from`] in one block per thread of the team this thread leads (see
    /// `compute/team.rs`), each thread the block of points it keeps from pass to pass.
    pub fn team_copy_from(&mut self, aos: &[Vec3]) {
        let size = crate::compute::team::chunk_size(aos.len(), 1);
        crate::compute::team::for_each_chunk(self.parts_mut(), size, &|i, [x, y, z]| {
            gather(x, y, z, &aos[i * size..i * size + x.len()]);
        });
    }

    /// A new structure of arrays holding `aos`.
    pub fn from_aos(aos: &[Vec3]) -> Self {
        let mut s = Soa::zeros(aos.len());
        s.copy_from(aos);
        s
    }

    /// Sets every component to 0.
    pub fn fill_zero(&mut self) {
        for c in self.parts_mut() {
            c.fill(0.0);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// What the layout decides, whatever the allocator: every component starts on a cache line;
    /// on large buffers, counted from the buffer's first cache line, each component starts 512
    /// bytes (8 cache sets) further along modulo 4 KiB than the one before, and a buffer of
    /// color `c` starts `128·c` bytes (2 sets per color) in. (Which sets they land in also
    /// depends on where the allocator puts the buffer, which no test should assume.)
    #[test]
    fn components_start_on_cache_lines_at_fixed_offsets() {
        for n in [0, 1, 7, 100, 511, 512, 4096, 32768, 40_000] {
            for color in 0..4 {
                let s = Soa::with_color(n, color);
                for c in [s.x(), s.y(), s.z()] {
                    assert_eq!(c.len(), n);
                    assert_eq!(c.as_ptr() as usize % 64, 0, "n = {n}, color {color}");
                }
                if n >= PAD_MIN {
                    // Offset (bytes, modulo 4 KiB) from the buffer's first cache line.
                    let line = (s.data.as_ptr() as usize).next_multiple_of(64);
                    let offset = |c: &[f64]| (c.as_ptr() as usize - line) % 4096;
                    let [x, y, z] = [s.x(), s.y(), s.z()].map(offset);
                    let what = format!("n = {n}, color {color}");
                    assert_eq!(x, 128 * color, "{what}");
                    assert_eq!((y + 4096 - x) % 4096, 512, "{what}");
                    assert_eq!((z + 4096 - y) % 4096, 512, "{what}");
                }
            }
        }
    }

    #[test]
    fn values_survive_the_layout_copies_and_clones() {
        let aos: Vec<Vec3> = (0..1000)
            .map(|i| Vec3::new(i as f64, -(i as f64), 0.5 * i as f64))
            .collect();
        let s = Soa::from_aos(&aos);
        assert_eq!(s.get(999), aos[999]);
        let copy = s.clone();
        assert_eq!(copy, s);
        let mut back = vec![Vec3::ZERO; aos.len()];
        copy.copy_to(&mut back);
        assert_eq!(back, aos);
        let mut z = copy;
        z.fill_zero();
        assert!(z.x().iter().chain(z.y()).chain(z.z()).all(|&c| c == 0.0));
    }
}
