//! A body's mass from a density is the density times the volume of its solid: the mesh's own
//! volume for a body made from a mesh (not its cells', which enclose the mesh and are larger),
//! spread evenly over its active points.
//!
//! Independent of the code: a box's volume is the product of its sides; an icosphere's is
//! computed here from its triangles (tetrahedra to the origin, its centre), and lies within 3 % of
//! the ball's `4/3 π r³`. Tolerance 1e-12 relative: a few hundred triple products, rounding
//! ~1e-15; the bug this guards against was +58 % for the icosphere.

#[path = "common/meshes.rs"]
mod meshes;

use std::collections::HashMap;

use jello_core::formats::scene::{BodySpec, MeshSpec};
use jello_core::model::body::Body;
use jello_core::{Material, SceneFile, TriMesh, Vec3};
use meshes::cuboid;

const DENSITY: f64 = 1000.0;

/// The mass of the one body of a scene made of `mesh` at `cells` cells and `DENSITY`, and the
/// volume of its cells.
fn scene_mass(mesh: &TriMesh, cells: usize) -> (f64, f64) {
    let spec = BodySpec {
        mesh: Some(MeshSpec {
            cells,
            vertices: mesh.vertices.iter().map(|v| v.to_array()).collect(),
            triangles: mesh.triangles.clone(),
        }),
        density: Some(DENSITY),
        ..BodySpec::default()
    };
    let scene = SceneFile::new(vec![spec]).to_scene("s.toml").unwrap();
    let body = scene.model.body(0);
    let h = body.lattice().spacing();
    (
        body.total_mass(),
        body.cell_count() as f64 * h.x * h.y * h.z,
    )
}

/// An icosahedron of radius `r` at the origin, each triangle split into four `levels` times,
/// every vertex pushed out to the sphere; wound outward.
fn icosphere(r: f64, levels: usize) -> TriMesh {
    let t = (1.0 + 5f64.sqrt()) / 2.0;
    let mut vertices: Vec<Vec3> = [
        [-1.0, t, 0.0],
        [1.0, t, 0.0],
        [-1.0, -t, 0.0],
        [1.0, -t, 0.0],
        [0.0, -1.0, t],
        [0.0, 1.0, t],
        [0.0, -1.0, -t],
        [0.0, 1.0, -t],
        [t, 0.0, -1.0],
        [t, 0.0, 1.0],
        [-t, 0.0, -1.0],
        [-t, 0.0, 1.0],
    ]
    .iter()
    .map(|&[x, y, z]| {
        let v = Vec3::new(x, y, z);
        v * (r / v.length())
    })
    .collect();
    let mut triangles: Vec<[u32; 3]> = vec![
        [0, 11, 5],
        [0, 5, 1],
        [0, 1, 7],
        [0, 7, 10],
        [0, 10, 11],
        [1, 5, 9],
        [5, 11, 4],
        [11, 10, 2],
        [10, 7, 6],
        [7, 1, 8],
        [3, 9, 4],
        [3, 4, 2],
        [3, 2, 6],
        [3, 6, 8],
        [3, 8, 9],
        [4, 9, 5],
        [2, 4, 11],
        [6, 2, 10],
        [8, 6, 7],
        [9, 8, 1],
    ];
    for _ in 0..levels {
        let mut middle: HashMap<(u32, u32), u32> = HashMap::new();
        let mut split = |a: u32, b: u32, vertices: &mut Vec<Vec3>| {
            *middle.entry((a.min(b), a.max(b))).or_insert_with(|| {
                let m = (vertices[a as usize] + vertices[b as usize]) * 0.5;
                vertices.push(m * (r / m.length()));
                vertices.len() as u32 - 1
            })
        };
        triangles = triangles
            .iter()
            .flat_map(|&[a, b, c]| {
                let (ab, bc, ca) = (
                    split(a, b, &mut vertices),
                    split(b, c, &mut vertices),
                    split(c, a, &mut vertices),
                );
                [[a, ab, ca], [b, bc, ab], [c, ca, bc], [ab, bc, ca]]
            })
            .collect();
    }
    TriMesh {
        vertices,
        triangles,
    }
}

/// Σ a·(b × c) / 6 over the triangles: the volume a closed, outward mesh around the origin
/// encloses.
fn volume_about_origin(m: &TriMesh) -> f64 {
    m.triangles
        .iter()
        .map(|t| {
            let [a, b, c] = t.map(|v| m.vertices[v as usize]);
            a.dot(b.cross(c))
        })
        .sum::<f64>()
        / 6.0
}

#[test]
fn a_box_mesh_weighs_its_density_times_its_sides() {
    for (lo, cells) in [
        (Vec3::new(0.0, 0.0, 0.0), 3),
        (Vec3::new(-1.3, 0.25, 1.0), 7),
        (Vec3::new(0.1, -0.4, 0.05), 10),
    ] {
        let mesh = cuboid(lo, lo + Vec3::new(0.3, 0.5, 0.7));
        let (mass, _) = scene_mass(&mesh, cells);
        let want = DENSITY * 0.3 * 0.5 * 0.7;
        assert!(
            (mass - want).abs() <= 1e-12 * want,
            "box at {lo:?}, {cells} cells: {mass} kg, want {want}"
        );
    }
}

#[test]
fn an_icosphere_weighs_its_density_times_the_volume_of_its_triangles() {
    let r = 0.3;
    let mesh = icosphere(r, 3);
    let volume = volume_about_origin(&mesh);
    let ball = 4.0 / 3.0 * std::f64::consts::PI * r.powi(3);
    assert!(
        volume < ball && volume > 0.97 * ball,
        "{volume} against {ball}"
    );
    for cells in [6, 10, 16] {
        let (mass, cells_volume) = scene_mass(&mesh, cells);
        let want = DENSITY * volume;
        assert!(
            (mass - want).abs() <= 1e-12 * want,
            "{cells} cells: {mass} kg, want {want} (the cells' volume weighs {})",
            DENSITY * cells_volume
        );
        // The cells enclose the mesh: weighing them was the error.
        assert!(cells_volume > 1.1 * volume, "{cells} cells: {cells_volume}");
    }
    // The same through the Rust builder's resolution-independent material.
    let body = Body::from_mesh(
        &mesh.vertices,
        &mesh.triangles,
        10,
        1 << 20,
        Material::classic(),
    )
    .unwrap()
    .with_modulus(2e5, 40.0, DENSITY);
    let want = DENSITY * volume;
    assert!((body.volume() - volume).abs() <= 1e-12 * volume);
    assert!((body.total_mass() - want).abs() <= 1e-12 * want);
}
