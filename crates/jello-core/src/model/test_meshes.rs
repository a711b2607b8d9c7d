//! Meshes made in code for the crate's unit tests.

use crate::vec3::Vec3;

/// A regular octahedron of "radius" `r` (centre to tip) about `centre`, its tips along the axes
/// (vertices +x, −x, +y, −y, +z, −z), its eight triangles wound outward. Its tips touch the
/// faces of its bounding box, whose corners lie outside it.
pub(crate) fn octahedron(centre: Vec3, r: f64) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let tip = |x: f64, y: f64, z: f64| centre + Vec3::new(x, y, z) * r;
    let vertices = vec![
        tip(1.0, 0.0, 0.0),
        tip(-1.0, 0.0, 0.0),
        tip(0.0, 1.0, 0.0),
        tip(0.0, -1.0, 0.0),
        tip(0.0, 0.0, 1.0),
        tip(0.0, 0.0, -1.0),
    ];
    let mut triangles = Vec::new();
    for (x, sx) in [(0u32, 1.0), (1, -1.0)] {
        for (y, sy) in [(2u32, 1.0), (3, -1.0)] {
            for (z, sz) in [(4u32, 1.0), (5, -1.0)] {
                // (x, y, z) in a right-handed octant, reversed in the others.
                triangles.push(if sx * sy * sz > 0.0 {
                    [x, y, z]
                } else {
                    [x, z, y]
                });
            }
        }
    }
    (vertices, triangles)
}
