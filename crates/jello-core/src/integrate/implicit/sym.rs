//! Symmetric 3×3 blocks, the entries of the Newton matrix `A` and of its coarse copies.

use crate::vec3::Vec3;

/// A symmetric 3×3 matrix: `[xx, yy, zz, xy, xz, yz]`.
pub(super) type Sym = [f64; 6];

pub(super) fn sym_mul(m: &Sym, v: Vec3) -> Vec3 {
    Vec3::new(
        m[0] * v.x + m[3] * v.y + m[4] * v.z,
        m[3] * v.x + m[1] * v.y + m[5] * v.z,
        m[4] * v.x + m[5] * v.y + m[2] * v.z,
    )
}

/// `m += c·n·nᵀ`.
pub(super) fn add_outer(m: &mut Sym, n: Vec3, c: f64) {
    m[0] += c * n.x * n.x;
    m[1] += c * n.y * n.y;
    m[2] += c * n.z * n.z;
    m[3] += c * n.x * n.y;
    m[4] += c * n.x * n.z;
    m[5] += c * n.y * n.z;
}

/// `m += b`.
pub(super) fn add_sym(m: &mut Sym, b: &Sym) {
    for (m, b) in m.iter_mut().zip(b) {
        *m += b;
    }
}

/// The inverse of a symmetric positive definite 3×3 matrix; zero for the zero matrix (a node
/// with nothing in it: an aggregate of pinned points).
pub(super) fn sym_inverse(m: &Sym) -> Sym {
    if *m == [0.0; 6] {
        return [0.0; 6];
    }
    let [a, d, f, b, c, e] = *m;
    // [[a b c] [b d e] [c e f]]
    let (c00, c01, c02) = (d * f - e * e, c * e - b * f, b * e - c * d);
    let det = a * c00 + b * c01 + c * c02;
    let inv = 1.0 / det;
    [
        c00 * inv,
        (a * f - c * c) * inv,
        (a * d - b * b) * inv,
        c01 * inv,
        c02 * inv,
        (b * c - a * e) * inv,
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_inverse_of_a_symmetric_matrix() {
        let m: Sym = [4.0, 5.0, 6.0, 1.0, 0.5, -0.7];
        let inv = sym_inverse(&m);
        for v in [Vec3::new(1.0, 0.0, 0.0), Vec3::new(0.3, -2.0, 1.5)] {
            let back = sym_mul(&m, sym_mul(&inv, v));
            assert!((back - v).max_abs() < 1e-14, "{back:?}");
        }
        assert_eq!(sym_inverse(&[0.0; 6]), [0.0; 6]);
    }
}
