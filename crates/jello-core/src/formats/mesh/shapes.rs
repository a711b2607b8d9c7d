//! Closed meshes the project makes itself: the shapes of the example scenes (and of tests that
//! need a mesh no one drew), each a smooth parametric surface triangulated on a grid, with no
//! third-party model involved.
//!
//! Every shape goes through [`TriMesh::from_parts`], so it meets the readers' contract (closed,
//! manifold, wound outwards), and writes out with [`TriMesh::to_obj`] as a file `jello create
//! --mesh` reads back exactly.

use std::f64::consts::{PI, TAU};
use std::fmt::Write as _;

use super::TriMesh;
use crate::vec3::Vec3;

/// The shapes [`TriMesh::shape`] makes, by name.
pub const SHAPES: [&str; 6] = ["torus", "blob", "mould", "sphere", "capsule", "ell"];

impl TriMesh {
    /// A ring doughnut about the z axis, centred on the origin: the tube of radius `minor`
    /// swept around the circle of radius `major` (`major > minor > 0`); `around` segments along
    /// the ring and `across` around the tube (each at least 3). Genus 1: the shape with a hole
    /// through it.
    pub fn torus(major: f64, minor: f64, around: usize, across: usize) -> TriMesh {
        assert!(
            major > minor && minor > 0.0,
            "a torus needs major > minor > 0"
        );
        assert!(
            around >= 3 && across >= 3,
            "a torus needs 3 or more segments each way"
        );
        let mut vertices = Vec::with_capacity(around * across);
        for i in 0..around {
            let (s, c) = (TAU * i as f64 / around as f64).sin_cos();
            for j in 0..across {
                let (sv, cv) = (TAU * j as f64 / across as f64).sin_cos();
                let r = major + minor * cv;
                vertices.push(Vec3::new(r * c, r * s, minor * sv));
            }
        }
        let index = |i: usize, j: usize| ((i % around) * across + j % across) as u32;
        let mut triangles = Vec::with_capacity(2 * around * across);
        for i in 0..around {
            for j in 0..across {
                quad(
                    &mut triangles,
                    [
                        index(i, j),
                        index(i + 1, j),
                        index(i + 1, j + 1),
                        index(i, j + 1),
                    ],
                );
            }
        }
        snap(&mut vertices);
        TriMesh::from_parts(&vertices, &triangles, "torus").expect("a torus is a closed surface")
    }

    /// A rounded, lumpy blob about 1 m across centred on the origin: a sphere whose radius
    /// varies smoothly with direction (each term a polynomial in x, y, z, so the surface is
    /// smooth at the poles too) and squashed a little along z. `rings` ≥ 2 rings from pole to
    /// pole, `segments` ≥ 3 around.
    pub fn blob(rings: usize, segments: usize) -> TriMesh {
        revolved(rings, segments, "blob", |theta, v| {
            let phi = PI * v;
            let (sp, cp) = phi.sin_cos();
            let r = 0.5
                * (1.0 + 0.15 * sp * sp * (2.0 * theta).cos() + 0.12 * sp * cp * theta.sin()
                    - 0.08 * (3.0 * phi).cos());
            Vec3::new(r * sp * theta.cos(), r * sp * theta.sin(), 0.8 * r * cp)
        })
    }

    /// A fluted jelly mould turned out on a plate: a flat base 1 m across at z = 0, three tiers
    /// stepping in as they rise and a domed top, the sides fluted with twelve ridges.
    /// `rings` ≥ 2 rings from the centre of the base to the top of the dome, `segments` ≥ 3
    /// around (a multiple of 12 follows the flutes best).
    pub fn mould(rings: usize, segments: usize) -> TriMesh {
        // The profile (radius, height) from the centre of the base to the top, walked at even
        // steps along its length.
        const PROFILE: [(f64, f64); 10] = [
            (0.0, 0.0),
            (0.5, 0.0),
            (0.5, 0.16),
            (0.42, 0.22),
            (0.42, 0.38),
            (0.33, 0.44),
            (0.33, 0.58),
            (0.22, 0.64),
            (0.12, 0.7),
            (0.0, 0.72),
        ];
        let lengths: Vec<f64> = PROFILE
            .windows(2)
            .map(|w| (w[1].0 - w[0].0).hypot(w[1].1 - w[0].1))
            .collect();
        let total: f64 = lengths.iter().sum();
        revolved(rings, segments, "mould", |theta, v| {
            let mut along = v * total;
            let mut k = 0;
            while k + 1 < lengths.len() && along > lengths[k] {
                along -= lengths[k];
                k += 1;
            }
            let f = (along / lengths[k]).min(1.0);
            let (r0, z0) = PROFILE[k];
            let (r1, z1) = PROFILE[k + 1];
            let r = (r0 + f * (r1 - r0)) * (1.0 + 0.06 * (12.0 * theta).cos());
            Vec3::new(r * theta.cos(), r * theta.sin(), z0 + f * (z1 - z0))
        })
    }

    /// A sphere of radius 0.5 m centred on the origin: `rings` ≥ 2 rings from pole to pole,
    /// `segments` ≥ 3 around.
    pub fn sphere(rings: usize, segments: usize) -> TriMesh {
        revolved(rings, segments, "sphere", |theta, v| {
            let (sp, cp) = (PI * v).sin_cos();
            Vec3::new(0.5 * sp * theta.cos(), 0.5 * sp * theta.sin(), -0.5 * cp)
        })
    }

    /// A capsule 1 m long along z and 0.5 m across, centred on the origin: a cylinder of radius
    /// 0.25 m capped by two half spheres, walked at even steps along its profile from the
    /// bottom pole to the top one (`rings` ≥ 2 steps, `segments` ≥ 3 around).
    pub fn capsule(rings: usize, segments: usize) -> TriMesh {
        const R: f64 = 0.25;
        let (arc, side) = (0.5 * PI * R, 1.0 - 2.0 * R);
        let total = 2.0 * arc + side;
        revolved(rings, segments, "capsule", |theta, v| {
            let along = v * total;
            let (r, z) = if along < arc {
                let a = along / R;
                (R * a.sin(), -0.5 + R * (1.0 - a.cos()))
            } else if along <= arc + side {
                (R, -0.5 + R + (along - arc))
            } else {
                let a = (total - along) / R;
                (R * a.sin(), 0.5 - R * (1.0 - a.cos()))
            };
            Vec3::new(r * theta.cos(), r * theta.sin(), z)
        })
    }

    /// An L: a block 1 m wide and 1 m tall in x and z, its arms 0.4 m thick, 0.4 m deep in y,
    /// its bounding box centred on the origin. Flat faces with sharp edges: twelve triangles on
    /// its two L-shaped faces and its six sides.
    pub fn ell() -> TriMesh {
        // The outline in (x, z), counter-clockwise seen with x right and z up.
        const OUTLINE: [(f64, f64); 6] = [
            (0.0, 0.0),
            (1.0, 0.0),
            (1.0, 0.4),
            (0.4, 0.4),
            (0.4, 1.0),
            (0.0, 1.0),
        ];
        let mut vertices = Vec::with_capacity(12);
        for y in [-0.2, 0.2] {
            for (x, z) in OUTLINE {
                vertices.push(Vec3::new(x - 0.5, y, z - 0.5));
            }
        }
        let back = |i: usize| (i + 6) as u32;
        // The L-shaped faces (front y = −0.2 faces −y, back faces +y), each four triangles
        // over the outline's corners; then a quad per side.
        let mut triangles = vec![[0, 1, 2], [0, 2, 3], [0, 3, 4], [0, 4, 5]];
        for k in 0..4 {
            let [a, b, c] = triangles[k];
            triangles.push([back(a as usize), back(c as usize), back(b as usize)]);
        }
        for i in 0..6 {
            let j = (i + 1) % 6;
            quad(&mut triangles, [i as u32, back(i), back(j), j as u32]);
        }
        TriMesh::from_parts(&vertices, &triangles, "ell").expect("an L is a closed surface")
    }

    /// The shape named `name` (one of [`SHAPES`]) at the resolution `detail` (≥ 3: segments
    /// around the z axis are `4·detail`, rings or tube segments `2·detail`), sized about 1 m.
    pub fn shape(name: &str, detail: usize) -> Option<TriMesh> {
        let detail = detail.max(3);
        match name {
            "torus" => Some(TriMesh::torus(0.35, 0.15, 4 * detail, 2 * detail)),
            "blob" => Some(TriMesh::blob(2 * detail, 4 * detail)),
            "mould" => Some(TriMesh::mould(2 * detail, 4 * detail)),
            "sphere" => Some(TriMesh::sphere(2 * detail, 4 * detail)),
            "capsule" => Some(TriMesh::capsule(2 * detail, 4 * detail)),
            "ell" => Some(TriMesh::ell()),
            _ => None,
        }
    }

    /// The mesh as Wavefront OBJ text: a comment line (`# …`, when `comment` is not empty), then
    /// `v x y z` per vertex (shortest round-trip decimals, so reading it back gives the same
    /// numbers) and `f a b c` per triangle, counted from 1.
    pub fn to_obj(&self, comment: &str) -> String {
        let mut out = String::new();
        for line in comment.lines() {
            let _ = writeln!(out, "# {line}");
        }
        for v in &self.vertices {
            let _ = writeln!(out, "v {:?} {:?} {:?}", v.x, v.y, v.z);
        }
        for [a, b, c] in &self.triangles {
            let _ = writeln!(out, "f {} {} {}", a + 1, b + 1, c + 1);
        }
        out
    }
}

/// Rounds to zero the coordinates that are zero but for the rounding of a sine or cosine (such
/// as `cos(π/2) ≈ 6e-17`), so that written files say `0.0`.
fn snap(vertices: &mut [Vec3]) {
    for v in vertices {
        for c in [&mut v.x, &mut v.y, &mut v.z] {
            if c.abs() < 1e-14 {
                *c = 0.0;
            }
        }
    }
}

/// Two triangles of the quad `a b c d` (in order around it).
fn quad(triangles: &mut Vec<[u32; 3]>, [a, b, c, d]: [u32; 4]) {
    triangles.push([a, b, c]);
    triangles.push([a, c, d]);
}

/// A closed surface about the z axis from the pole at `v = 0` to the pole at `v = 1`:
/// `point(theta, v)` for `rings − 1` rings of `segments` points strictly between them, and the two
/// poles (`point(0, 0)` and `point(0, 1)`), joined by fans.
fn revolved(
    rings: usize,
    segments: usize,
    name: &str,
    point: impl Fn(f64, f64) -> Vec3,
) -> TriMesh {
    assert!(
        rings >= 2 && segments >= 3,
        "a surface of revolution needs 2 rings and 3 segments"
    );
    let inner = rings - 1;
    let mut vertices = vec![point(0.0, 0.0)];
    for ring in 1..rings {
        let v = ring as f64 / rings as f64;
        for s in 0..segments {
            vertices.push(point(TAU * s as f64 / segments as f64, v));
        }
    }
    let top = vertices.len() as u32;
    vertices.push(point(0.0, 1.0));
    let at = |ring: usize, s: usize| (1 + ring * segments + s % segments) as u32;
    let mut triangles = Vec::with_capacity(2 * inner * segments);
    for s in 0..segments {
        triangles.push([0, at(0, s + 1), at(0, s)]);
        triangles.push([top, at(inner - 1, s), at(inner - 1, s + 1)]);
    }
    for ring in 0..inner - 1 {
        for s in 0..segments {
            quad(
                &mut triangles,
                [
                    at(ring, s),
                    at(ring, s + 1),
                    at(ring + 1, s + 1),
                    at(ring + 1, s),
                ],
            );
        }
    }
    snap(&mut vertices);
    TriMesh::from_parts(&vertices, &triangles, name)
        .unwrap_or_else(|e| panic!("the {name} is a closed surface: {e}"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_shape_is_a_closed_solid_that_reads_back_from_its_obj() {
        for name in SHAPES {
            for detail in [3, 8] {
                let mesh = TriMesh::shape(name, detail).unwrap();
                assert!(mesh.volume() > 0.0, "{name}");
                let again = TriMesh::parse_obj(mesh.to_obj("made by a test").as_bytes(), name)
                    .unwrap_or_else(|e| panic!("{e}"));
                assert_eq!(again, mesh, "{name}");
            }
        }
        assert!(TriMesh::shape("teapot", 8).is_none());
    }

    #[test]
    fn the_torus_has_its_closed_form_volume_and_no_vertex_on_the_axis() {
        // A polygonal torus inscribed in the true one: the volume converges to 2π²Rr² from below.
        let exact = 2.0 * PI * PI * 0.35 * 0.15 * 0.15;
        let coarse = TriMesh::torus(0.35, 0.15, 24, 12).volume();
        let fine = TriMesh::torus(0.35, 0.15, 96, 48).volume();
        assert!(coarse < fine && fine < exact);
        assert!((exact - fine) < 0.25 * (exact - coarse));
        let torus = TriMesh::torus(0.35, 0.15, 24, 12);
        assert!(torus.vertices.iter().all(|v| v.x.hypot(v.y) >= 0.2 - 1e-12));
        // Euler characteristic 0: V − E + F with E = 3F/2.
        let (v, f) = (torus.vertices.len() as i64, torus.triangles.len() as i64);
        assert_eq!(v - 3 * f / 2 + f, 0);
    }

    /// The sphere, the capsule and the L hold the volumes of their closed forms (the polygonal
    /// ones from below, within the faceting's error; the L exactly).
    #[test]
    fn the_sphere_capsule_and_ell_have_their_volumes() {
        let sphere = TriMesh::sphere(48, 96).volume();
        let exact = 4.0 / 3.0 * PI * 0.125;
        assert!(
            sphere < exact && sphere > 0.995 * exact,
            "{sphere} against {exact}"
        );
        let capsule = TriMesh::capsule(48, 96).volume();
        let exact = PI * 0.0625 * 0.5 + 4.0 / 3.0 * PI * 0.25f64.powi(3);
        assert!(
            capsule < exact && capsule > 0.995 * exact,
            "{capsule} against {exact}"
        );
        let ell = TriMesh::ell();
        assert!(
            (ell.volume() - 0.64 * 0.4).abs() < 1e-12,
            "{}",
            ell.volume()
        );
        let (lo, hi) = ell.bounds();
        assert_eq!(
            (lo, hi),
            (Vec3::new(-0.5, -0.2, -0.5), Vec3::new(0.5, 0.2, 0.5))
        );
    }

    #[test]
    fn the_mould_stands_on_its_flat_base() {
        let mould = TriMesh::shape("mould", 6).unwrap();
        let (lo, hi) = mould.bounds();
        assert_eq!(lo.z, 0.0);
        assert!((hi.z - 0.72).abs() < 1e-12);
        assert!((hi.x - 0.53).abs() < 1e-12, "the widest flute: {}", hi.x);
        // Genus 0.
        let (v, f) = (mould.vertices.len() as i64, mould.triangles.len() as i64);
        assert_eq!(v - 3 * f / 2 + f, 2);
    }
}
