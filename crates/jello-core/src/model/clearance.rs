//! How far each lattice point of a body made from a mesh rests outside its skin: its
//! **clearance**.
//!
//! The walls, the inclined plane and the obstacles push lattice points, and a body's cage of
//! kept cells encloses its mesh, reaching up to a cell's diagonal past it. Unturned, a cage's
//! outer points lie on the mesh's bounding box, so a shape rests on its lowest point; turned, a
//! corner of the cage sticks out below the skin and the shape rested on it (a sphere of 6 cells
//! turned by 45° and 35° rested 7 cm above a plate). So a point's depth into a wall, the plane or
//! an obstacle counts only past its clearance: `depth − clearance` (never below 0). The nearest
//! point of the skin is that far from the lattice point, so no skin is held off a surface by a
//! point sticking out past it; a point whose nearest skin lies sideways goes a little deeper
//! before it pushes, while the skin around it carries the body.
//!
//! Points on or inside the skin have no clearance, and bodies without a skin (cubes, the
//! classic world) have none at all: their contacts are exactly docs/spec.md's.

use crate::model::body::Body;
use crate::model::contact_surface::signed_distances;
use crate::vec3::Vec3;

/// Per lattice point of `body`, `max(0, φ)` where `φ` is its signed distance at rest to the
/// body's skin (m; 0 for a point of no kept cell); empty when the body has no skin or no point
/// rests outside it.
pub(crate) fn rest_clearance(body: &Body) -> Vec<f64> {
    let Some(skin) = &body.skin else {
        return Vec::new();
    };
    // A body keeping every cell (a shape that fills its box) has no flags: all are kept.
    let kept = |c: usize| body.cells().is_none_or(|cells| cells[c]);
    let lattice = body.lattice();
    let [nx, ny, nz] = lattice.counts;
    if nx < 2 || ny < 2 || nz < 2 {
        return Vec::new();
    }
    let mut cells = Vec::new();
    for i in 0..nx - 1 {
        for j in 0..ny - 1 {
            for k in 0..nz - 1 {
                if kept((i * (ny - 1) + j) * (nz - 1) + k) {
                    cells.push(lattice.index(i, j, k) as u32);
                }
            }
        }
    }
    // The skin at rest in the lattice's own frame (placement turns and moves both alike).
    let rest = lattice.rest_positions();
    let mut vertices = vec![Vec3::ZERO; skin.len()];
    skin.positions(&rest, &mut vertices);
    let reach = 2.0 * lattice.spacing().length();
    let (_, distance) =
        signed_distances(lattice, &cells, &vertices, &skin.triangles, reach, 1, None);
    if distance.iter().all(|&d| d <= 0.0) {
        return Vec::new();
    }
    distance.into_iter().map(|d| d.max(0.0)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::body::{rotation_xyz, Material};
    use crate::model::test_meshes::octahedron;

    /// A lattice corner outside the skin is as far from it as the nearest face; points inside
    /// have none, and placement changes nothing.
    #[test]
    fn a_cage_corner_is_as_far_out_as_the_skin_is_away() {
        // An octahedron of "radius" 1 about (1, 1, 1).
        let (v, t) = octahedron(Vec3::new(1.0, 1.0, 1.0), 1.0);
        // Two cells a side: all eight hold some of it, so the body is a full box.
        let body = Body::from_mesh(&v, &t, 2, 1000, Material::classic()).unwrap();
        assert!(body.cells().is_none());
        let clearance = body.clearance();
        assert_eq!(clearance.len(), body.len());
        let lattice = body.lattice();
        // The corner (0, 0, 0) of the 2×2×2 cells: the face x + y + z = 2 is 2/√3 away.
        let corner = clearance[lattice.index(0, 0, 0)];
        assert!((corner - 2.0 / 3f64.sqrt()).abs() < 1e-12, "{corner}");
        // The middle and the octahedron's own corners (on the skin) have none.
        assert_eq!(clearance[lattice.index(1, 1, 1)], 0.0);
        assert!(clearance[lattice.index(1, 1, 0)] < 1e-12);
        // The same when the body is turned and moved.
        let placed = body
            .clone()
            .placed(Vec3::new(3.0, 0.0, 0.0), rotation_xyz([45.0, 35.0, 0.0]));
        assert_eq!(placed.clearance(), clearance);
    }

    /// Bodies without a skin have no clearance: their contacts are docs/spec.md's.
    #[test]
    fn a_cube_has_no_clearance() {
        let body = Body::lattice_box(
            crate::model::lattice::Lattice::classic(),
            Material::classic(),
        );
        assert!(body.clearance().is_empty());
    }
}
