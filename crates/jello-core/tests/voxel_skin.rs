//! Voxelising closed meshes and embedding them as skins (README: "Reading and voxelising a
//! mesh").
//!
//! Meshes are made in code (`common/meshes.rs`, no third-party models): boxes, a UV sphere, a
//! torus, a thin slab. The checks: a box aligned with the grid fills exactly its cells; the kept
//! cells enclose the solid (their volume is never below the mesh's) and their excess volume
//! shrinks as cells get finer; every vertex lies in a kept cell; a torus keeps its hole open; a
//! slab thinner than a cell keeps a layer; the skin reproduces the mesh at rest to 1e-12 m and
//! follows an affine motion of the lattice exactly; bad input is an error.

use jello_core::model::skin::Skin;
use jello_core::model::voxel::{Voxels, ON_PLANE};
use jello_core::Vec3;

#[path = "common/meshes.rs"]
mod meshes;

use jello_core::TriMesh;
use meshes::{cuboid, rounded_to_f32, to_ascii_stl, to_binary_stl, to_obj, torus, uv_sphere};

const MAX_CELLS: usize = 1 << 24;

fn voxels(mesh: &TriMesh, cells: usize) -> Voxels {
    Voxels::from_mesh(&mesh.vertices, &mesh.triangles, cells, MAX_CELLS).unwrap()
}

/// Every vertex lies (closed) in a kept cell.
fn assert_vertices_in_kept_cells(mesh: &TriMesh, voxels: &Voxels, what: &str) {
    let h = voxels.cell;
    for (n, &v) in mesh.vertices.iter().enumerate() {
        let c = voxels.anchor_cell(v);
        assert!(
            voxels.occupied[voxels.index(c)],
            "{what}: vertex {n} at {v:?} is in cell {c:?}, which is not kept"
        );
        let lo = voxels.cell_min(c);
        // A vertex on a plane between cells may be carried by the cell beside it.
        let tol = ON_PLANE * h + 1e-12 * (1.0 + v.max_abs());
        for (p, l) in v.to_array().into_iter().zip(lo.to_array()) {
            assert!(
                p >= l - tol && p <= l + h + tol,
                "{what}: vertex {n} at {v:?} outside its cell {c:?}"
            );
        }
    }
}

#[test]
fn boxes_aligned_with_the_grid_fill_exactly_their_cells() {
    let unit = cuboid(Vec3::ZERO, Vec3::new(1.0, 1.0, 1.0));
    let v = voxels(&unit, 4);
    assert_eq!(v.cells, [4, 4, 4]);
    assert_eq!(v.occupied_count(), 64);
    assert_eq!(v.volume(), 1.0);
    let tall = cuboid(Vec3::new(0.3, 0.0, -1.0), Vec3::new(1.3, 2.0, 0.0));
    let v = voxels(&tall, 4);
    assert_eq!(v.cells, [2, 4, 2]);
    assert_eq!(v.occupied_count(), 16);
    assert_vertices_in_kept_cells(&tall, &v, "box");
}

#[test]
fn kept_cells_enclose_the_solid_and_converge_to_it() {
    let ball = uv_sphere(Vec3::new(0.1, -0.2, 0.3), 1.0, 48, 96);
    let exact = ball.volume();
    let mut last = f64::INFINITY;
    for cells in [4, 8, 16, 32, 64] {
        let v = voxels(&ball, cells);
        let excess = (v.volume() - exact) / exact;
        assert!(
            excess >= 0.0,
            "{cells} cells: {} below the mesh's {exact}",
            v.volume()
        );
        // The excess is a layer of cells around the surface: it shrinks about as 1/cells.
        assert!(
            excess < last * 0.75,
            "{cells} cells: excess {excess} after {last}"
        );
        assert!(
            excess < 7.0 / cells as f64,
            "{cells} cells: excess {excess}"
        );
        assert_vertices_in_kept_cells(&ball, &v, "sphere");
        last = excess;
    }
}

#[test]
fn a_torus_keeps_its_hole() {
    let ring = torus(1.0, 0.3, 64, 24);
    let v = voxels(&ring, 10);
    let h = v.cell;
    assert_vertices_in_kept_cells(&ring, &v, "torus");
    let [cx, cy, cz] = v.cells;
    let mut hole = 0;
    for i in 0..cx {
        for j in 0..cy {
            for k in 0..cz {
                let c = v.cell_min([i, j, k]) + Vec3::new(h, h, h) * 0.5;
                let from_axis = (c.x * c.x + c.y * c.y).sqrt();
                // Cells wholly inside the hole (radius 0.7): their centre is further than half a
                // cell diagonal from the tube.
                if from_axis + h * 0.75 < 0.7 {
                    assert!(!v.occupied[v.index([i, j, k])], "hole cell {:?}", [i, j, k]);
                    hole += 1;
                }
                // Cells wholly inside the tube are kept.
                let tube = ((from_axis - 1.0).powi(2) + c.z * c.z).sqrt();
                if tube + h * 0.9 < 0.3 {
                    assert!(v.occupied[v.index([i, j, k])], "tube cell {:?}", [i, j, k]);
                }
            }
        }
    }
    assert!(hole >= cz * 4, "only {hole} hole cells");
    // The hole goes through: every cell of the central column is empty, bottom to top.
    let centre = v.cell_of(Vec3::new(0.0, 0.0, 0.0));
    for k in 0..cz {
        assert!(!v.occupied[v.index([centre[0], centre[1], k])]);
    }
}

#[test]
fn a_part_thinner_than_a_cell_keeps_a_layer() {
    let slab = cuboid(Vec3::new(0.0, 0.0, 0.013), Vec3::new(1.0, 1.0, 0.033));
    let v = voxels(&slab, 10);
    assert_eq!(v.cells, [10, 10, 1]);
    assert_eq!(v.occupied_count(), 100);
    // Tilted, so that it cuts through cells of several layers.
    let mut tilted = cuboid(Vec3::new(0.0, 0.0, 0.0), Vec3::new(1.0, 1.0, 0.02));
    for p in &mut tilted.vertices {
        *p = Vec3::new(p.x, p.y * 0.8 - p.z * 0.6, p.y * 0.6 + p.z * 0.8);
    }
    let v = voxels(&tilted, 12);
    assert_vertices_in_kept_cells(&tilted, &v, "tilted slab");
    assert!(
        v.occupied_count() >= 12 * 12,
        "{} cells",
        v.occupied_count()
    );
}

#[test]
fn the_skin_reproduces_the_mesh_at_rest_and_follows_affine_motion() {
    for (mesh, cells) in [
        (uv_sphere(Vec3::new(0.5, 0.25, -0.75), 0.8, 16, 32), 7),
        (torus(1.0, 0.3, 32, 12), 10),
        (
            cuboid(Vec3::new(-0.5, 0.0, 0.0), Vec3::new(0.5, 0.5, 2.0)),
            5,
        ),
    ] {
        let v = voxels(&mesh, cells);
        let skin = Skin::embed(&v, &mesh.vertices, &mesh.triangles);
        assert_eq!(skin.len(), mesh.vertices.len());
        assert_eq!(skin.triangles, mesh.triangles);
        let rest = v.rest_points();
        let mut out = vec![Vec3::ZERO; skin.len()];
        skin.positions(&rest, &mut out);
        for (got, want) in out.iter().zip(&mesh.vertices) {
            assert!((*got - *want).max_abs() <= 1e-12, "{got:?} vs {want:?}");
        }
        // A trilinear map reproduces affine motion exactly: move the lattice by one and the skin
        // moves by the same.
        let affine = |p: Vec3| {
            Vec3::new(
                1.1 * p.x - 0.3 * p.y + 0.2 * p.z + 0.5,
                0.4 * p.x + 0.9 * p.y - 0.1 * p.z - 1.0,
                -0.2 * p.x + 0.5 * p.y + 1.3 * p.z + 0.25,
            )
        };
        let moved: Vec<Vec3> = rest.iter().map(|&p| affine(p)).collect();
        skin.positions(&moved, &mut out);
        for (got, v) in out.iter().zip(&mesh.vertices) {
            assert!(
                (*got - affine(*v)).max_abs() <= 1e-12,
                "{got:?} vs {:?}",
                affine(*v)
            );
        }
        // Every vertex's cell corners are active lattice points.
        let active = v.active_points();
        for &c in &skin.corner {
            assert!(active[c as usize]);
        }
    }
}

#[test]
fn skin_normals_point_outward() {
    let ball = uv_sphere(Vec3::ZERO, 1.0, 16, 32);
    let v = voxels(&ball, 6);
    let skin = Skin::embed(&v, &ball.vertices, &ball.triangles);
    let mut pos = vec![Vec3::ZERO; skin.len()];
    skin.positions(&v.rest_points(), &mut pos);
    let mut normals = vec![Vec3::ZERO; skin.len()];
    skin.normals(&pos, &mut normals);
    for (n, p) in normals.iter().zip(&pos) {
        assert!((n.length() - 1.0).abs() < 1e-12);
        assert!(n.dot(*p / p.length()) > 0.98, "normal {n:?} at {p:?}");
    }
}

#[test]
fn bad_input_is_an_error() {
    let unit = cuboid(Vec3::ZERO, Vec3::new(1.0, 1.0, 1.0));
    let err = |vertices: &[Vec3], triangles: &[[u32; 3]], cells: usize, max: usize| {
        Voxels::from_mesh(vertices, triangles, cells, max)
            .unwrap_err()
            .to_string()
    };
    assert!(err(&unit.vertices, &unit.triangles, 0, MAX_CELLS).contains("at least 1"));
    assert!(err(&unit.vertices, &[], 4, MAX_CELLS).contains("no triangles"));
    assert!(err(&unit.vertices, &[[0, 1, 8]], 4, MAX_CELLS).contains("does not exist"));
    let mut nan = unit.vertices.clone();
    nan[3].y = f64::NAN;
    assert!(err(&nan, &unit.triangles, 4, MAX_CELLS).contains("finite"));
    assert!(err(&unit.vertices, &unit.triangles, 100, 1000).contains("allowed"));
    let mut extra = unit.vertices.clone();
    extra.push(Vec3::new(9.0, 9.0, 9.0));
    assert!(err(&extra, &unit.triangles, 4, MAX_CELLS).contains("vertex 9 is used by no triangle"));
    let flat = [Vec3::ZERO; 3];
    assert!(err(&flat, &[[0, 1, 2]], 4, MAX_CELLS).contains("extent"));
}

/// End to end: a torus written as OBJ text, read back by the OBJ reader, voxelised, skinned.
#[test]
fn a_mesh_read_from_obj_voxelises_and_skins() {
    let ring = torus(1.0, 0.35, 40, 16);
    let obj = to_obj(&ring);
    let mesh = TriMesh::parse_obj(obj.as_bytes(), "torus.obj").unwrap();
    assert_eq!(mesh.vertices.len(), ring.vertices.len());
    let v = Voxels::from_mesh(&mesh.vertices, &mesh.triangles, 10, MAX_CELLS).unwrap();
    assert!(v.volume() >= mesh.volume());
    let skin = Skin::embed(&v, &mesh.vertices, &mesh.triangles);
    let mut out = vec![Vec3::ZERO; skin.len()];
    skin.positions(&v.rest_points(), &mut out);
    for (got, want) in out.iter().zip(&mesh.vertices) {
        assert!((*got - *want).max_abs() <= 1e-12);
    }
}

/// The closed surface of a union of cubes of side 0.2 m (`cells`, by lattice coordinates), one
/// quad per face between a cube and no cube, shifted by `offset` tenths of a metre. Coordinates
/// are `tenths / 10`, the double nearest the decimal a file would hold (`0.6`, not `3 × 0.2`).
fn cubes(cells: &[[i64; 3]], offset: [i64; 3]) -> TriMesh {
    let filled = |c: [i64; 3]| cells.contains(&c);
    let mut vertices: Vec<Vec3> = Vec::new();
    let mut number = std::collections::HashMap::new();
    let mut triangles = Vec::new();
    for &c in cells {
        for axis in 0..3 {
            for side in [0, 1] {
                let mut beside = c;
                beside[axis] += 2 * side - 1;
                if filled(beside) {
                    continue;
                }
                let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
                // Corners counter-clockwise about +axis (e_a × e_b = e_axis); reversed for −axis.
                let mut quad: Vec<[i64; 3]> = [(0, 0), (1, 0), (1, 1), (0, 1)]
                    .iter()
                    .map(|&(da, db)| {
                        let mut p = c;
                        p[axis] += side;
                        p[a] += da;
                        p[b] += db;
                        p
                    })
                    .collect();
                if side == 0 {
                    quad.reverse();
                }
                let ids: Vec<u32> = quad
                    .iter()
                    .map(|&p| {
                        *number.entry(p).or_insert_with(|| {
                            let at = |k: usize| (2 * p[k] + offset[k]) as f64 / 10.0;
                            vertices.push(Vec3::new(at(0), at(1), at(2)));
                            vertices.len() as u32 - 1
                        })
                    })
                    .collect();
                triangles.push([ids[0], ids[1], ids[2]]);
                triangles.push([ids[0], ids[2], ids[3]]);
            }
        }
    }
    TriMesh {
        vertices,
        triangles,
    }
}

/// Faces on the planes between cells: an L of five 0.2 m cubes (0.6 m long, so the cell side is
/// `0.6 / N`, which rounds below 0.2 for N = 3) keeps exactly its `5 (N/3)³` cells at every N
/// that puts its faces on cell planes, read from OBJ, ASCII STL and binary STL (32-bit floats)
/// alike, wherever it sits; and its cells' volume is the solid's. Before the vertices on a
/// plane chose the cell the solid keeps, the OBJ kept 8 cells at N = 3 and 50 at N = 6.
#[test]
fn the_same_solid_keeps_the_same_cells_in_every_format() {
    let ell = [[0, 0, 0], [1, 0, 0], [2, 0, 0], [0, 0, 1], [0, 0, 2]];
    for offset in [[0, 0, 0], [-7, 3, 11], [13, -29, 5]] {
        let mesh = cubes(&ell, offset);
        let files: [(&str, Vec<u8>); 3] = [
            ("ell.obj", to_obj(&mesh).into_bytes()),
            ("ell.stl", to_ascii_stl(&mesh, "ell").into_bytes()),
            (
                "ell-binary.stl",
                to_binary_stl(&rounded_to_f32(&mesh), b"ell"),
            ),
        ];
        for n in [3, 6, 9, 12, 15] {
            let mut kept: Option<Vec<bool>> = None;
            for (name, bytes) in &files {
                let read = TriMesh::parse(bytes, name).unwrap();
                let v = voxels(&read, n);
                let what = format!("{name} at {offset:?}, {n} cells");
                assert_eq!(v.cells, [n, n / 3, n], "{what}");
                let want = 5 * (n / 3).pow(3);
                assert_eq!(v.occupied_count(), want, "{what}");
                assert!((v.volume() - read.volume()).abs() < 1e-6, "{what}");
                assert_vertices_in_kept_cells(&read, &v, &what);
                match &kept {
                    None => kept = Some(v.occupied.clone()),
                    Some(first) => assert_eq!(&v.occupied, first, "{what}: other cells"),
                }
            }
        }
    }
}
