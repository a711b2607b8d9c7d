//! Test meshes made in code (no third-party models), their closed-form volumes, writers for OBJ,
//! ASCII STL and binary STL, and checks of what every parsed mesh must satisfy. Included by the
//! mesh tests with `#[path = "common/meshes.rs"] mod meshes;`.
#![allow(dead_code)]

use std::collections::{HashMap, HashSet};
use std::f64::consts::PI;
use std::fmt::Write as _;

use jello_core::{TriMesh, Vec3};

// ---------------------------------------------------------------------------------------------
// Shapes.

/// Quads `[a, b, c, d]` (counter-clockwise from outside) fanned into `(a, b, c), (a, c, d)`.
fn fan(quads: &[[u32; 4]]) -> Vec<[u32; 3]> {
    quads
        .iter()
        .flat_map(|&[a, b, c, d]| [[a, b, c], [a, c, d]])
        .collect()
}

/// The unit cube [0, 1]³: vertex `x + 2y + 4z` at `(x, y, z)`, 12 triangles wound outward.
pub fn cube() -> TriMesh {
    let vertices = (0..8)
        .map(|i| Vec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, ((i >> 2) & 1) as f64))
        .collect();
    TriMesh {
        vertices,
        triangles: fan(&CUBE_QUADS),
    }
}

/// The cube's six faces as quads, counter-clockwise seen from outside.
pub const CUBE_QUADS: [[u32; 4]; 6] = [
    [0, 2, 3, 1], // z = 0
    [4, 5, 7, 6], // z = 1
    [0, 1, 5, 4], // y = 0
    [2, 6, 7, 3], // y = 1
    [0, 4, 6, 2], // x = 0
    [1, 3, 7, 5], // x = 1
];

/// A box from `lo` to `hi`, made from the unit cube.
pub fn cuboid(lo: Vec3, hi: Vec3) -> TriMesh {
    let mut m = cube();
    for p in &mut m.vertices {
        *p = Vec3::new(
            lo.x + p.x * (hi.x - lo.x),
            lo.y + p.y * (hi.y - lo.y),
            lo.z + p.z * (hi.z - lo.z),
        );
    }
    m
}

/// The regular octahedron of radius `r` at the origin: vertices ±r on each axis, 8 triangles
/// wound outward. Volume 4/3·r³.
pub fn octahedron(r: f64) -> TriMesh {
    let vertices = vec![
        Vec3::new(r, 0.0, 0.0),
        Vec3::new(-r, 0.0, 0.0),
        Vec3::new(0.0, r, 0.0),
        Vec3::new(0.0, -r, 0.0),
        Vec3::new(0.0, 0.0, r),
        Vec3::new(0.0, 0.0, -r),
    ];
    // One triangle per octant, through the +x or -x, +y or -y and +z or -z vertices; an even
    // number of minus signs keeps (x, y, z) counter-clockwise from outside.
    let mut triangles = Vec::new();
    for octant in 0..8u32 {
        let (x, y, z) = (octant & 1, 2 + ((octant >> 1) & 1), 4 + ((octant >> 2) & 1));
        let minus = octant.count_ones();
        triangles.push(if minus % 2 == 0 { [x, y, z] } else { [x, z, y] });
    }
    TriMesh {
        vertices,
        triangles,
    }
}

/// A polygonal torus around the z axis: a regular `n`-gon of circumradius `r` centred at
/// distance `big_r` from the axis, swept in `m` steps. Vertex `i·n + j` at angle 2πi/m around
/// the axis and 2πj/n around the tube; 2·m·n triangles wound outward.
pub fn torus(big_r: f64, r: f64, m: u32, n: u32) -> TriMesh {
    let mut vertices = Vec::new();
    for i in 0..m {
        let theta = 2.0 * PI * i as f64 / m as f64;
        for j in 0..n {
            let phi = 2.0 * PI * j as f64 / n as f64;
            let rho = big_r + r * phi.cos();
            vertices.push(Vec3::new(
                rho * theta.cos(),
                rho * theta.sin(),
                r * phi.sin(),
            ));
        }
    }
    let at = |i: u32, j: u32| (i % m) * n + (j % n);
    let quads: Vec<[u32; 4]> = (0..m)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .map(|(i, j)| [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)])
        .collect();
    TriMesh {
        vertices,
        triangles: fan(&quads),
    }
}

/// The exact volume of [`torus`]: its quads are planar (isosceles trapezoids), so the part of
/// the solid between two neighbouring meridian half-planes, at angle Δ = 2π/m, is the image of
/// the cross-section polygon Q × [0, 1] under (ρ, z, t) ↦ (ρ·((1−t)e₀ + t·e₁), z), whose
/// Jacobian is ρ·sin Δ. Its volume is sin Δ · area(Q) · centroid ρ of Q, and Q is a regular
/// n-gon of area (n/2)·r²·sin(2π/n) centred at ρ = R:
/// V = m·sin(2π/m) · (n/2)·r²·sin(2π/n) · R, which tends to 2π²·R·r².
pub fn torus_volume(big_r: f64, r: f64, m: u32, n: u32) -> f64 {
    let (m, n) = (m as f64, n as f64);
    m * (2.0 * PI / m).sin() * (n / 2.0) * r * r * (2.0 * PI / n).sin() * big_r
}

/// A UV sphere of radius `r` about `centre`: two poles, `rings − 1` latitude circles of
/// `segments` vertices, triangles wound outward.
pub fn uv_sphere(centre: Vec3, r: f64, rings: u32, segments: u32) -> TriMesh {
    let mut vertices = vec![
        centre + Vec3::new(0.0, 0.0, r),
        centre - Vec3::new(0.0, 0.0, r),
    ];
    for i in 1..rings {
        let theta = PI * i as f64 / rings as f64;
        for j in 0..segments {
            let phi = 2.0 * PI * j as f64 / segments as f64;
            vertices.push(
                centre
                    + Vec3::new(
                        theta.sin() * phi.cos(),
                        theta.sin() * phi.sin(),
                        theta.cos(),
                    ) * r,
            );
        }
    }
    // Latitude i (1 at the north pole's side), longitude j.
    let at = |i: u32, j: u32| 2 + (i - 1) * segments + j % segments;
    let mut triangles = Vec::new();
    for j in 0..segments {
        triangles.push([0, at(1, j), at(1, j + 1)]);
        triangles.push([1, at(rings - 1, j + 1), at(rings - 1, j)]);
    }
    let quads: Vec<[u32; 4]> = (1..rings - 1)
        .flat_map(|i| (0..segments).map(move |j| (i, j)))
        .map(|(i, j)| [at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1)])
        .collect();
    triangles.extend(fan(&quads));
    TriMesh {
        vertices,
        triangles,
    }
}

/// A prism over the regular `n`-gon of circumradius 1 in z = 0, height `h`: the two caps are
/// each one polygon of `n` vertices (OBJ face lines `f 1 2 … n`), the sides quads. Returned as
/// polygons (1-based, for OBJ) with the mesh that fanning them gives.
pub fn prism(n: u32, h: f64) -> (Vec<Vec3>, Vec<Vec<u32>>) {
    let mut vertices = Vec::new();
    for z in [0.0, h] {
        for j in 0..n {
            let a = 2.0 * PI * j as f64 / n as f64;
            vertices.push(Vec3::new(a.cos(), a.sin(), z));
        }
    }
    let mut faces = Vec::new();
    faces.push((1..=n).rev().collect()); // bottom, seen from below
    faces.push((n + 1..=2 * n).collect()); // top
    for j in 0..n {
        let k = (j + 1) % n;
        faces.push(vec![j + 1, k + 1, n + k + 1, n + j + 1]);
    }
    (vertices, faces)
}

/// The volume of [`prism`]: the n-gon's area (n/2)·sin(2π/n) times the height.
pub fn prism_volume(n: u32, h: f64) -> f64 {
    n as f64 / 2.0 * (2.0 * PI / n as f64).sin() * h
}

/// Every triangle wound the other way.
pub fn flipped(m: &TriMesh) -> TriMesh {
    TriMesh {
        vertices: m.vertices.clone(),
        triangles: m.triangles.iter().map(|&[a, b, c]| [a, c, b]).collect(),
    }
}

/// Every vertex moved by `d`.
pub fn translated(m: &TriMesh, d: Vec3) -> TriMesh {
    TriMesh {
        vertices: m.vertices.iter().map(|&p| p + d).collect(),
        triangles: m.triangles.clone(),
    }
}

/// Every vertex scaled by `s`.
pub fn scaled(m: &TriMesh, s: f64) -> TriMesh {
    TriMesh {
        vertices: m.vertices.iter().map(|&p| p * s).collect(),
        triangles: m.triangles.clone(),
    }
}

/// Two meshes as one (the second's indices shifted).
pub fn union(a: &TriMesh, b: &TriMesh) -> TriMesh {
    let shift = a.vertices.len() as u32;
    TriMesh {
        vertices: a.vertices.iter().chain(&b.vertices).copied().collect(),
        triangles: a
            .triangles
            .iter()
            .copied()
            .chain(b.triangles.iter().map(|t| t.map(|i| i + shift)))
            .collect(),
    }
}

/// Coordinates rounded to `f32`, as binary STL stores them.
pub fn rounded_to_f32(m: &TriMesh) -> TriMesh {
    let r = |v: f64| v as f32 as f64;
    TriMesh {
        vertices: m
            .vertices
            .iter()
            .map(|p| Vec3::new(r(p.x), r(p.y), r(p.z)))
            .collect(),
        triangles: m.triangles.clone(),
    }
}

/// What STL's welding makes of `m` (whose vertices are all distinct): the same triangles, with
/// vertices renumbered in the order they are first used. Written independently of the reader:
/// a map from old to new numbers, filled as the triangles are walked.
pub fn renumbered_by_first_use(m: &TriMesh) -> TriMesh {
    let mut new_of: HashMap<u32, u32> = HashMap::new();
    let mut vertices = Vec::new();
    let triangles = m
        .triangles
        .iter()
        .map(|t| {
            t.map(|old| {
                *new_of.entry(old).or_insert_with(|| {
                    vertices.push(m.vertices[old as usize]);
                    vertices.len() as u32 - 1
                })
            })
        })
        .collect();
    TriMesh {
        vertices,
        triangles,
    }
}

// ---------------------------------------------------------------------------------------------
// Writers.

/// OBJ text: vertex i on line i + 1, then triangle t on line V + 1 + t.
pub fn to_obj(m: &TriMesh) -> String {
    let mut s = String::new();
    for p in &m.vertices {
        let _ = writeln!(s, "v {} {} {}", p.x, p.y, p.z);
    }
    for t in &m.triangles {
        let _ = writeln!(s, "f {} {} {}", t[0] + 1, t[1] + 1, t[2] + 1);
    }
    s
}

/// The line of triangle `t` in [`to_obj`]'s text.
pub fn obj_face_line(m: &TriMesh, t: usize) -> usize {
    m.vertices.len() + 1 + t
}

/// The unit normal of triangle `t` (what an exporter would write; the readers ignore it).
fn normal(m: &TriMesh, t: &[u32; 3]) -> Vec3 {
    let [a, b, c] = t.map(|i| m.vertices[i as usize]);
    let n = (b - a).cross(c - a);
    n / n.length()
}

/// ASCII STL: `solid name` on line 1, facet t on line 2 + 7t, its corner k on line 4 + 7t + k.
pub fn to_ascii_stl(m: &TriMesh, name: &str) -> String {
    let mut s = format!("solid {name}\n");
    for t in &m.triangles {
        let n = normal(m, t);
        let _ = writeln!(s, "  facet normal {:e} {:e} {:e}", n.x, n.y, n.z);
        s.push_str("    outer loop\n");
        for &i in t {
            let p = m.vertices[i as usize];
            let _ = writeln!(s, "      vertex {} {} {}", p.x, p.y, p.z);
        }
        s.push_str("    endloop\n  endfacet\n");
    }
    let _ = writeln!(s, "endsolid {name}");
    s
}

/// The line of facet `t` in [`to_ascii_stl`]'s text.
pub fn stl_facet_line(t: usize) -> usize {
    2 + 7 * t
}

/// The line of corner `k` of facet `t` in [`to_ascii_stl`]'s text.
pub fn stl_vertex_line(t: usize, k: usize) -> usize {
    4 + 7 * t + k
}

/// Binary STL: `header` (at most 80 bytes, padded with zeros), the count, 50 bytes a triangle.
pub fn to_binary_stl(m: &TriMesh, header: &[u8]) -> Vec<u8> {
    assert!(header.len() <= 80);
    let mut out = header.to_vec();
    out.resize(80, 0);
    out.extend((m.triangles.len() as u32).to_le_bytes());
    for t in &m.triangles {
        let n = normal(m, t);
        let corners = t.map(|i| m.vertices[i as usize]);
        for v in [n].iter().chain(&corners) {
            for c in v.to_array() {
                out.extend((c as f32).to_le_bytes());
            }
        }
        out.extend(0u16.to_le_bytes());
    }
    out
}

/// Offset of coordinate `axis` of corner `k` of triangle `t` in [`to_binary_stl`]'s bytes.
pub fn binary_offset(t: usize, k: usize, axis: usize) -> usize {
    84 + 50 * t + 12 + 12 * k + 4 * axis
}

// ---------------------------------------------------------------------------------------------
// Checks.

/// Unique undirected edges.
pub fn edges(m: &TriMesh) -> usize {
    let mut set = HashSet::new();
    for t in &m.triangles {
        for k in 0..3 {
            let (a, b) = (t[k], t[(k + 1) % 3]);
            set.insert((a.min(b), a.max(b)));
        }
    }
    set.len()
}

/// V − E + F: 2 for a sphere, 0 for a torus.
pub fn euler_characteristic(m: &TriMesh) -> i64 {
    m.vertices.len() as i64 - edges(m) as i64 + m.triangles.len() as i64
}

/// Asserts what every parsed mesh must satisfy: triangles, finite coordinates, indices in range
/// and distinct, every vertex used, every directed edge once and its reverse once, positive
/// finite volume.
pub fn assert_valid(m: &TriMesh, what: &str) {
    assert!(!m.triangles.is_empty(), "{what}: no triangles");
    for (i, p) in m.vertices.iter().enumerate() {
        assert!(p.is_finite(), "{what}: vertex {i} is {p:?}");
    }
    let mut used = vec![false; m.vertices.len()];
    let mut directed: HashMap<(u32, u32), usize> = HashMap::new();
    for (t, tri) in m.triangles.iter().enumerate() {
        for &i in tri {
            assert!(
                (i as usize) < m.vertices.len(),
                "{what}: triangle {t} {tri:?}"
            );
            used[i as usize] = true;
        }
        assert!(
            tri[0] != tri[1] && tri[1] != tri[2] && tri[0] != tri[2],
            "{what}: triangle {t} {tri:?}"
        );
        for k in 0..3 {
            *directed.entry((tri[k], tri[(k + 1) % 3])).or_default() += 1;
        }
    }
    assert!(used.iter().all(|&u| u), "{what}: unused vertices");
    for (&(a, b), &n) in &directed {
        assert_eq!(n, 1, "{what}: edge {a}→{b} used {n} times");
        assert_eq!(
            directed.get(&(b, a)),
            Some(&1),
            "{what}: edge {a}→{b} has no reverse"
        );
    }
    let v = m.volume();
    assert!(v.is_finite() && v > 0.0, "{what}: volume {v}");
}

/// Asserts every triangle of a convex mesh faces away from its vertices' centroid.
pub fn assert_outward_convex(m: &TriMesh) {
    let c = m.vertices.iter().fold(Vec3::ZERO, |s, &p| s + p) / m.vertices.len() as f64;
    for t in &m.triangles {
        let [a, b, d] = t.map(|i| m.vertices[i as usize]);
        let n = (b - a).cross(d - a);
        assert!(n.dot((a + b + d) / 3.0 - c) > 0.0, "{t:?} faces inward");
    }
}
