//! Per-point buffers that can be cut at a point index, so that a pass can hand each chunk or
//! block of points its own part of several output buffers at once, without allocating.

use crate::vec3::Vec3;

/// Per-point buffers that can be cut in two at a point index: a slice of numbers or vectors, the
/// x, y and z parts of a structure-of-arrays buffer, or a pair of these.
pub trait Split: Sized + Send {
    /// Number of points.
    fn points(&self) -> usize;
    /// The points before `at` and the points from `at` on.
    fn split_at(self, at: usize) -> (Self, Self);
}

impl Split for &mut [f64] {
    fn points(&self) -> usize {
        self.len()
    }
    fn split_at(self, at: usize) -> (Self, Self) {
        self.split_at_mut(at)
    }
}

impl Split for &mut [Vec3] {
    fn points(&self) -> usize {
        self.len()
    }
    fn split_at(self, at: usize) -> (Self, Self) {
        self.split_at_mut(at)
    }
}

/// The x, y and z components of one structure-of-arrays buffer.
impl<T: Split> Split for [T; 3] {
    fn points(&self) -> usize {
        self[0].points()
    }
    fn split_at(self, at: usize) -> (Self, Self) {
        let [x, y, z] = self;
        let ((x0, x1), (y0, y1), (z0, z1)) = (x.split_at(at), y.split_at(at), z.split_at(at));
        ([x0, y0, z0], [x1, y1, z1])
    }
}

impl<A: Split, B: Split> Split for (A, B) {
    fn points(&self) -> usize {
        self.0.points()
    }
    fn split_at(self, at: usize) -> (Self, Self) {
        let ((a0, a1), (b0, b1)) = (self.0.split_at(at), self.1.split_at(at));
        ((a0, b0), (a1, b1))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn splitting_cuts_every_buffer_at_the_same_point() {
        let mut a = [0.0; 5];
        let (mut x, mut y, mut z) = ([1.0; 5], [2.0; 5], [3.0; 5]);
        let both = (&mut a[..], [&mut x[..], &mut y[..], &mut z[..]]);
        assert_eq!(both.points(), 5);
        let ((a0, [x0, y0, z0]), (a1, [x1, y1, z1])) = both.split_at(2);
        assert_eq!([a0.len(), x0.len(), y0.len(), z0.len()], [2; 4]);
        assert_eq!([a1.len(), x1.len(), y1.len(), z1.len()], [3; 4]);
        a1[0] = 7.0;
        z1[2] = 9.0;
        assert_eq!(a, [0.0, 0.0, 7.0, 0.0, 0.0]);
        assert_eq!(z, [3.0, 3.0, 3.0, 3.0, 9.0]);
    }
}
