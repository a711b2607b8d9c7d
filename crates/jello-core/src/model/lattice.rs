//! The lattice of mass points and the spring stencil that connects them.
//!
//! Point `(i, j, k)` of an `nx × ny × nz` lattice has flat index `(i*ny + j)*nz + k` (i is x, j is
//! y, k is z; k varies fastest, as in the world file). The classic jello cube is the 8×8×8 lattice
//! of side 1: point `(i, j, k)` rests at `(i/7, j/7, k/7)`.
//!
//! Springs connect each unordered pair of points once (docs/spec.md): structural springs to the axis
//! neighbours at index distance 1, shear springs along the 12 face diagonals and 8 body diagonals,
//! bend springs to the axis neighbours at index distance 2. For 8³ that is 6220 springs.

use crate::vec3::Vec3;

/// The kind of a spring; each kind may have its own stiffness and damping.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
#[repr(u8)]
pub enum SpringKind {
    /// Axis neighbours at index distance 1.
    Structural = 0,
    /// Face and body diagonals of a lattice cell.
    Shear = 1,
    /// Axis neighbours at index distance 2.
    Bend = 2,
}

impl SpringKind {
    /// All kinds, in index order.
    pub const ALL: [SpringKind; 3] = [SpringKind::Structural, SpringKind::Shear, SpringKind::Bend];

    /// Lower-case name, as used in command-line output.
    pub fn name(self) -> &'static str {
        match self {
            SpringKind::Structural => "structural",
            SpringKind::Shear => "shear",
            SpringKind::Bend => "bend",
        }
    }
}

/// Index offsets `(di, dj, dk)` of the half stencil, with the kind of spring each joins (docs/spec.md):
/// every offset whose first non-zero component is positive, so that each unordered pair of
/// points is visited exactly once. Its order is the order of the kernel's walk.
pub const STENCIL: [([isize; 3], SpringKind); 16] = [
    ([1, 0, 0], SpringKind::Structural),
    ([0, 1, 0], SpringKind::Structural),
    ([0, 0, 1], SpringKind::Structural),
    // Face diagonals: two per coordinate plane.
    ([1, 1, 0], SpringKind::Shear),
    ([1, -1, 0], SpringKind::Shear),
    ([1, 0, 1], SpringKind::Shear),
    ([1, 0, -1], SpringKind::Shear),
    ([0, 1, 1], SpringKind::Shear),
    ([0, 1, -1], SpringKind::Shear),
    // Body diagonals.
    ([1, 1, 1], SpringKind::Shear),
    ([1, 1, -1], SpringKind::Shear),
    ([1, -1, 1], SpringKind::Shear),
    ([1, -1, -1], SpringKind::Shear),
    ([2, 0, 0], SpringKind::Bend),
    ([0, 2, 0], SpringKind::Bend),
    ([0, 0, 2], SpringKind::Bend),
];

/// Shape of the lattice: counts per axis and the side lengths of its rest configuration.
#[derive(Clone, Debug, PartialEq)]
pub struct Lattice {
    /// Points along x, y and z (each ≥ 1, at least 2 points in all).
    pub counts: [usize; 3],
    /// Side lengths of the rest shape along x, y and z (m). The classic cube: 1 m each.
    pub size: Vec3,
}

impl Lattice {
    /// The classic 8×8×8 lattice of side 1 m.
    pub fn classic() -> Self {
        Lattice::new([8, 8, 8], Vec3::new(1.0, 1.0, 1.0))
    }

    /// A lattice with `counts` points per axis and rest side lengths `size` (m).
    pub fn new(counts: [usize; 3], size: Vec3) -> Self {
        Lattice { counts, size }
    }

    /// True for the 8×8×8 lattice of side 1 m that the world file describes.
    pub fn is_classic(&self) -> bool {
        *self == Lattice::classic()
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.counts[0] * self.counts[1] * self.counts[2]
    }

    /// True when the lattice has no points.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Flat index of point `(i, j, k)`.
    #[inline]
    pub fn index(&self, i: usize, j: usize, k: usize) -> usize {
        (i * self.counts[1] + j) * self.counts[2] + k
    }

    /// Lattice coordinates `(i, j, k)` of flat index `p`.
    #[inline]
    pub fn coords(&self, p: usize) -> [usize; 3] {
        let k = p % self.counts[2];
        let j = (p / self.counts[2]) % self.counts[1];
        let i = p / (self.counts[1] * self.counts[2]);
        [i, j, k]
    }

    /// Rest position of point `(i, j, k)`: `size · i/(nx−1)` per axis, so the classic cube gives
    /// exactly `i/7` as docs/spec.md says. An axis with one point sits at 0.
    pub fn rest_position(&self, i: usize, j: usize, k: usize) -> Vec3 {
        let axis = |n: usize, s: f64, c: usize| {
            if n > 1 {
                s * c as f64 / (n - 1) as f64
            } else {
                0.0
            }
        };
        Vec3::new(
            axis(self.counts[0], self.size.x, i),
            axis(self.counts[1], self.size.y, j),
            axis(self.counts[2], self.size.z, k),
        )
    }

    /// Rest positions of all points, in flat-index order.
    pub fn rest_positions(&self) -> Vec<Vec3> {
        (0..self.len())
            .map(|p| {
                let [i, j, k] = self.coords(p);
                self.rest_position(i, j, k)
            })
            .collect()
    }

    /// Spacing between neighbouring points along each axis (m); 0 on an axis with one point.
    pub fn spacing(&self) -> Vec3 {
        let h = |n: usize, s: f64| if n > 1 { s / (n - 1) as f64 } else { 0.0 };
        Vec3::new(
            h(self.counts[0], self.size.x),
            h(self.counts[1], self.size.y),
            h(self.counts[2], self.size.z),
        )
    }

    /// Calls `f(a, b, rest_len, kind)` for every spring of the stencil, in a fixed
    /// order: first points `a` in flat-index order, and for each the stencil
    /// entries in order. Rest lengths (m) come from the rest grid, never from positions.
    pub fn for_each_spring(&self, mut f: impl FnMut(usize, usize, f64, SpringKind)) {
        self.for_each_stencil_spring(|a, b, rest, kind, _| f(a, b, rest, kind));
    }

    /// [`Lattice::for_each_spring`], also passing each spring's stencil entry (0..16).
    pub(crate) fn for_each_stencil_spring(
        &self,
        mut f: impl FnMut(usize, usize, f64, SpringKind, usize),
    ) {
        let [nx, ny, nz] = self.counts;
        let rest = self.stencil_rest_lengths();
        for i in 0..nx {
            for j in 0..ny {
                for k in 0..nz {
                    for (s, (&(d, kind), &rest)) in STENCIL.iter().zip(&rest).enumerate() {
                        let (Some(i2), Some(j2), Some(k2)) = (
                            offset(i, d[0], nx),
                            offset(j, d[1], ny),
                            offset(k, d[2], nz),
                        ) else {
                            continue;
                        };
                        f(self.index(i, j, k), self.index(i2, j2, k2), rest, kind, s);
                    }
                }
            }
        }
    }

    /// The springs of stencil entry `entry` alone, as [`Lattice::for_each_stencil_spring`]
    /// lists them (`f(a, b, rest_len, kind)`), in the order of their first point `a`.
    pub(crate) fn for_each_spring_of_entry(
        &self,
        entry: usize,
        mut f: impl FnMut(usize, usize, f64, SpringKind),
    ) {
        let [nx, ny, nz] = self.counts;
        let (d, kind) = STENCIL[entry];
        let rest = self.stencil_rest_lengths()[entry];
        // The first points whose partner is in the lattice: a range along each axis.
        let along = |n: usize, d: isize| {
            let lo = if d < 0 { d.unsigned_abs().min(n) } else { 0 };
            let hi = if d > 0 {
                n.saturating_sub(d as usize)
            } else {
                n
            };
            lo..hi.max(lo)
        };
        let (di, dj, dk) = (along(nx, d[0]), along(ny, d[1]), along(nz, d[2]));
        let step = (d[0] * ny as isize + d[1]) * nz as isize + d[2];
        for i in di {
            for j in dj.clone() {
                for k in dk.clone() {
                    let a = self.index(i, j, k);
                    f(a, a.wrapping_add_signed(step), rest, kind);
                }
            }
        }
    }

    /// The rest length of each stencil entry's springs on this lattice.
    fn stencil_rest_lengths(&self) -> [f64; 16] {
        let h = self.spacing();
        std::array::from_fn(|s| {
            let (d, _) = STENCIL[s];
            Vec3::new(d[0] as f64 * h.x, d[1] as f64 * h.y, d[2] as f64 * h.z).length()
        })
    }

    /// Number of springs of each kind, indexed by `SpringKind as usize`, without listing them:
    /// a stencil entry `(di, dj, dk)` joins `Π (n − |d|)` pairs (none on an axis too short).
    pub fn spring_count_by_kind(&self) -> [usize; 3] {
        let mut counts = [0; 3];
        for (d, kind) in STENCIL {
            let pairs: usize = (0..3)
                .map(|axis| self.counts[axis].saturating_sub(d[axis].unsigned_abs()))
                .product();
            counts[kind as usize] += pairs;
        }
        counts
    }

    /// Number of springs.
    pub fn spring_count(&self) -> usize {
        self.spring_count_by_kind().iter().sum()
    }

    /// Indices of the points on the lattice surface, in flat-index order.
    pub fn surface_points(&self) -> Vec<usize> {
        let [nx, ny, nz] = self.counts;
        (0..self.len())
            .filter(|&p| {
                let [i, j, k] = self.coords(p);
                i == 0 || j == 0 || k == 0 || i + 1 == nx || j + 1 == ny || k + 1 == nz
            })
            .collect()
    }

    /// Triangles of the lattice surface (two per boundary face of a cell), wound so their normals
    /// point out of the rest shape. Empty for a lattice that is flat along some axis.
    pub fn surface_triangles(&self) -> Vec<[u32; 3]> {
        let [nx, ny, nz] = self.counts;
        let mut tris = Vec::new();
        if nx < 2 || ny < 2 || nz < 2 {
            return tris;
        }
        let idx = |i: usize, j: usize, k: usize| self.index(i, j, k) as u32;
        let mut quad = |a: u32, b: u32, c: u32, d: u32| {
            tris.push([a, b, c]);
            tris.push([a, c, d]);
        };
        for j in 0..ny - 1 {
            for k in 0..nz - 1 {
                // x = min face (normal −x) and x = max face (normal +x).
                quad(
                    idx(0, j, k),
                    idx(0, j, k + 1),
                    idx(0, j + 1, k + 1),
                    idx(0, j + 1, k),
                );
                let i = nx - 1;
                quad(
                    idx(i, j, k),
                    idx(i, j + 1, k),
                    idx(i, j + 1, k + 1),
                    idx(i, j, k + 1),
                );
            }
        }
        for i in 0..nx - 1 {
            for k in 0..nz - 1 {
                quad(
                    idx(i, 0, k),
                    idx(i + 1, 0, k),
                    idx(i + 1, 0, k + 1),
                    idx(i, 0, k + 1),
                );
                let j = ny - 1;
                quad(
                    idx(i, j, k),
                    idx(i, j, k + 1),
                    idx(i + 1, j, k + 1),
                    idx(i + 1, j, k),
                );
            }
        }
        for i in 0..nx - 1 {
            for j in 0..ny - 1 {
                quad(
                    idx(i, j, 0),
                    idx(i, j + 1, 0),
                    idx(i + 1, j + 1, 0),
                    idx(i + 1, j, 0),
                );
                let k = nz - 1;
                quad(
                    idx(i, j, k),
                    idx(i + 1, j, k),
                    idx(i + 1, j + 1, k),
                    idx(i, j + 1, k),
                );
            }
        }
        tris
    }
}

/// `c + d` when it lies in `0..n`.
#[inline]
fn offset(c: usize, d: isize, n: usize) -> Option<usize> {
    let v = c.checked_add_signed(d)?;
    (v < n).then_some(v)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Lattice shapes with short axes too (one and two points, where the bend springs of an
    /// axis are missing).
    const SHAPES: [[usize; 3]; 6] = [
        [8, 8, 8],
        [2, 1, 1],
        [1, 1, 9],
        [3, 3, 3],
        [5, 2, 7],
        [1, 6, 2],
    ];

    /// The closed-form counts agree with the listed springs, on shapes with short axes too.
    #[test]
    fn counts_without_listing_match_the_list() {
        for counts in SHAPES {
            let lattice = Lattice::new(counts, Vec3::new(1.0, 2.0, 3.0));
            let mut listed = [0; 3];
            lattice.for_each_spring(|_, _, _, kind| listed[kind as usize] += 1);
            assert_eq!(lattice.spring_count_by_kind(), listed, "{counts:?}");
        }
        assert_eq!(
            Lattice::classic().spring_count_by_kind(),
            [1344, 3724, 1152]
        );
    }

    /// Each entry's springs listed alone are the springs of that entry in the full list, in the
    /// same order, with the same rest lengths to the bit, on shapes with short axes too.
    #[test]
    fn an_entrys_springs_are_its_springs_in_the_full_list() {
        for counts in SHAPES {
            let lattice = Lattice::new(counts, Vec3::new(1.0, 2.0, 3.0));
            let mut full = vec![Vec::new(); STENCIL.len()];
            lattice.for_each_stencil_spring(|a, b, rest, kind, entry| {
                full[entry].push((a, b, rest.to_bits(), kind));
            });
            for (entry, full) in full.iter().enumerate() {
                let mut alone = Vec::new();
                lattice.for_each_spring_of_entry(entry, |a, b, rest, kind| {
                    alone.push((a, b, rest.to_bits(), kind));
                });
                assert_eq!(&alone, full, "{counts:?}, entry {entry}");
            }
        }
    }
}
