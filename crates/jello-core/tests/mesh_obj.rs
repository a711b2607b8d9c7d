//! The OBJ reader on meshes made in code: a cube, an octahedron and a torus written as OBJ text
//! read back exactly, with their closed-form volumes and Euler characteristics; the statement
//! forms the specification allows; and the mesh's own `volume`, `bounds` and `parse` by name.

#[path = "common/meshes.rs"]
mod meshes;

use jello_core::{MeshError, TriMesh, Vec3};
use meshes::*;

const NAME: &str = "shape.obj";

fn parse(text: &str) -> Result<TriMesh, MeshError> {
    TriMesh::parse_obj(text.as_bytes(), NAME)
}

// ---------------------------------------------------------------------------------------------
// The shapes read back exactly.

#[test]
fn cube_reads_back_exactly_with_volume_one() {
    let cube = cube();
    assert_outward_convex(&cube);
    let got = parse(&to_obj(&cube)).unwrap();
    assert_eq!(got, cube);
    assert_eq!((got.vertices.len(), got.triangles.len()), (8, 12));
    assert_eq!(got.volume(), 1.0);
    assert_eq!(euler_characteristic(&got), 2);
    assert_eq!(got.bounds(), (Vec3::ZERO, Vec3::new(1.0, 1.0, 1.0)));
    assert_valid(&got, "cube");
}

#[test]
fn octahedron_reads_back_exactly_with_volume_four_thirds_r_cubed() {
    for r in [1.0, 1.5, 0.1, 1e-3, 7e4] {
        let octa = octahedron(r);
        assert_outward_convex(&octa);
        let got = parse(&to_obj(&octa)).unwrap();
        assert_eq!(got, octa);
        assert_eq!((got.vertices.len(), got.triangles.len()), (6, 8));
        let expected = 4.0 / 3.0 * r * r * r;
        assert!(
            (got.volume() - expected).abs() <= 1e-15 * expected,
            "r = {r}: {} vs {expected}",
            got.volume()
        );
        assert_eq!(euler_characteristic(&got), 2);
    }
}

#[test]
fn torus_reads_back_exactly_with_its_exact_volume_and_genus_one() {
    for (big_r, r, m, n) in [(2.0, 0.5, 24, 12), (1.0, 0.25, 3, 3), (3.0, 1.0, 64, 7)] {
        let torus = torus(big_r, r, m, n);
        let text = to_obj(&torus);
        let got = parse(&text).unwrap();
        assert_eq!(got, torus, "coordinates must read back bit for bit");
        let v = (m * n) as usize;
        assert_eq!((got.vertices.len(), got.triangles.len()), (v, 2 * v));
        assert_eq!(edges(&got), 3 * v);
        assert_eq!(euler_characteristic(&got), 0, "a torus has genus 1");
        let exact = torus_volume(big_r, r, m, n);
        assert!(
            (got.volume() - exact).abs() <= 1e-13 * exact,
            "R = {big_r}, r = {r}, {m}×{n}: {} vs {exact}",
            got.volume()
        );
        assert_valid(&got, "torus");
    }
    // The polygonal volume tends to the smooth torus's 2π²Rr².
    let smooth = 2.0 * std::f64::consts::PI.powi(2) * 2.0 * 0.25;
    let fine = parse(&to_obj(&torus(2.0, 0.5, 400, 200))).unwrap().volume();
    // Inscribed polygons: a little less, by about ((2π/m)² + (2π/n)²)/6 = 2·10⁻⁴.
    assert!(
        fine < smooth && fine > smooth * (1.0 - 3e-4),
        "{fine} vs {smooth}"
    );
}

#[test]
fn volume_is_exact_far_from_the_origin() {
    // Measured about the bounding box's centre, a unit cube a million metres away still has
    // volume 1 to the last bit (about the origin, the terms would be 10¹⁸ and cancel).
    let far = translated(&cube(), Vec3::new(1e6, -2e6, 3e6));
    let got = parse(&to_obj(&far)).unwrap();
    assert_eq!(got.volume(), 1.0);
    assert_eq!(
        got.bounds(),
        (
            Vec3::new(1e6, -2e6, 3e6),
            Vec3::new(1e6 + 1.0, -2e6 + 1.0, 3e6 + 1.0)
        )
    );
    // Nor with offsets whose products are not exact: the volume is the product of the edges
    // (each 1 up to the rounding of the far coordinates) to 1e-9, where about the origin the
    // terms are 10¹⁹ and their rounding errors 10³.
    let odd = parse(&to_obj(&translated(
        &cube(),
        Vec3::new(1234567.891, -2345678.912, 3456789.123),
    )))
    .unwrap();
    let (lo, hi) = odd.bounds();
    let edges = (hi.x - lo.x) * (hi.y - lo.y) * (hi.z - lo.z);
    assert!((edges - 1.0).abs() < 1e-9);
    assert!(
        (odd.volume() - edges).abs() < 1e-9,
        "{} vs {edges}",
        odd.volume()
    );
    // Flipping negates the volume exactly.
    assert_eq!(flipped(&got).volume(), -1.0);
    let box_ = cuboid(Vec3::new(-1.0, -2.0, -3.0), Vec3::new(0.5, 0.25, 0.125));
    assert_eq!(box_.volume(), 1.5 * 2.25 * 3.125);
}

// ---------------------------------------------------------------------------------------------
// Statement forms.

/// The cube's text with each face line's references written by `reference(index)`, and `extra`
/// lines before the faces.
fn cube_with(extra: &str, reference: impl Fn(u32) -> String) -> String {
    let cube = cube();
    let mut s = String::new();
    for p in &cube.vertices {
        s.push_str(&format!("v {} {} {}\n", p.x, p.y, p.z));
    }
    s.push_str(extra);
    for t in &cube.triangles {
        let refs: Vec<String> = t.iter().map(|&i| reference(i)).collect();
        s.push_str(&format!("f {}\n", refs.join(" ")));
    }
    s
}

#[test]
fn texture_and_normal_references_are_accepted() {
    let vt_vn = "vt 0 0\nvt 1 0\nvt 1 1\nvn 0 0 1\nvn 0 1 0\n";
    /// Writes the reference to vertex `i` (0-based).
    type Reference = fn(u32) -> String;
    let cases: [(&str, Reference); 4] = [
        ("v/vt", |i| format!("{}/{}", i + 1, i % 3 + 1)),
        ("v//vn", |i| format!("{}//{}", i + 1, i % 2 + 1)),
        ("v/vt/vn", |i| format!("{}/{}/{}", i + 1, 3 - i % 3, 2)),
        ("negative vt", |i| format!("{}/-1/-2", i + 1)),
    ];
    for (what, reference) in cases {
        let got = parse(&cube_with(vt_vn, reference)).unwrap_or_else(|e| panic!("{what}: {e}"));
        assert_eq!(got, cube(), "{what}");
    }
}

#[test]
fn negative_indices_count_back_from_the_last_vertex() {
    // Each face written right after its own three vertices, all referred to as -3, -2, -1.
    let cube = cube();
    let mut s = String::new();
    for t in &cube.triangles {
        for &i in t {
            let p = cube.vertices[i as usize];
            s.push_str(&format!("v {} {} {}\n", p.x, p.y, p.z));
        }
        s.push_str("f -3 -2 -1\n");
    }
    // Unwelded, each face is its own island: read, the corners at the same position are
    // joined (as STL's are), which closes the cube (see `an_unwelded_obj_is_welded_as_stl_is`).
    let welded = parse(&s).unwrap();
    assert_eq!((welded.vertices.len(), welded.triangles.len()), (8, 12));
    assert_eq!(welded.volume(), 1.0);

    // Mixed: vertices first, faces by negative index from the end.
    let mixed = cube_with("", |i| format!("-{}", 8 - i));
    assert_eq!(parse(&mixed).unwrap(), cube);
}

#[test]
fn polygons_are_fanned_from_their_first_vertex() {
    // The cube as six quads: each (a, b, c, d) becomes (a, b, c), (a, c, d).
    let cube = cube();
    let mut s = to_obj(&TriMesh {
        vertices: cube.vertices.clone(),
        triangles: vec![],
    });
    for q in CUBE_QUADS {
        s.push_str(&format!(
            "f {} {} {} {}\n",
            q[0] + 1,
            q[1] + 1,
            q[2] + 1,
            q[3] + 1
        ));
    }
    assert_eq!(parse(&s).unwrap(), cube);

    // Prisms whose caps are single n-gons.
    for n in [3u32, 5, 6, 17, 100] {
        let (vertices, faces) = prism(n, 0.75);
        let mut s = String::new();
        for p in &vertices {
            s.push_str(&format!("v {} {} {}\n", p.x, p.y, p.z));
        }
        for f in &faces {
            let refs: Vec<String> = f.iter().map(u32::to_string).collect();
            s.push_str(&format!("f {}\n", refs.join(" ")));
        }
        let got = parse(&s).unwrap();
        assert_eq!(got.vertices, vertices);
        // Caps: n − 2 triangles each; sides: 2 each.
        assert_eq!(got.triangles.len(), 2 * (n as usize - 2) + 2 * n as usize);
        let top: Vec<u32> = faces[1].iter().map(|i| i - 1).collect();
        assert_eq!(got.triangles[n as usize - 2], [top[0], top[1], top[2]]);
        assert_eq!(
            got.triangles[2 * n as usize - 5],
            [top[0], top[top.len() - 2], top[top.len() - 1]]
        );
        let exact = prism_volume(n, 0.75);
        assert!(
            (got.volume() - exact).abs() < 1e-13 * exact,
            "{n}: {} vs {exact}",
            got.volume()
        );
        assert_eq!(euler_characteristic(&got), 2);
        assert_valid(&got, &format!("prism {n}"));
    }
}

#[test]
fn ignorable_statements_comments_and_layout_are_accepted() {
    let text = format!(
        "\u{feff}# made in the test\r\n\
         mtllib cube.mtl\r\n\
         o Cube\r\n\
         g side one\r\n\
         s off\r\n\
         usemtl red   # trailing comment\r\n\
         \r\n\
         \t  \r\n\
         vp 0.5 0.5\r\n\
         vn 0 0 1\r\n\
         vt 0.1 0.2\r\n\
         mg 1 0.5\r\n\
         bevel off\r\n\
         c_interp on\r\n\
         d_interp off\r\n\
         lod 1\r\n\
         usemap off\r\n\
         maplib a.map\r\n\
         shadow_obj s.obj\r\n\
         trace_obj t.obj\r\n\
         ctech cparm 1\r\n\
         stech cparm 1\r\n\
         {}",
        to_obj(&cube())
            .replace("v 1 1 1", "v 1 1 1 1.0") // w
            .replace("v 0 0 0", "v\t0  0 \\\n 0   0.5 0.25 1") // continued, with a colour
            .replace("f 1 3 4", "f 1 3 4 # a comment \\")
            .replace('\n', "\r\n")
            + "l 1 2 3\np 4\n# no newline at the end"
    );
    assert_eq!(parse(&text).unwrap(), cube());
}

#[test]
fn a_continued_statement_reports_its_first_line() {
    let e = parse("v 0 0 \\\n nan\n").unwrap_err();
    assert_eq!(e.line, 1, "{e}");
    assert!(e.message.contains("z coordinate"), "{e}");
}

#[test]
fn unused_vertices_are_dropped_keeping_the_order_of_the_others() {
    let cube = cube();
    let mut s = String::new();
    // A stray vertex before each real one, and two after: they must not change the bounds.
    for p in &cube.vertices {
        s.push_str("v 100 -100 5\n");
        s.push_str(&format!("v {} {} {}\n", p.x, p.y, p.z));
    }
    s.push_str("v -7 7 7\nv 1e300 0 0\n");
    for t in &cube.triangles {
        s.push_str(&format!(
            "f {} {} {}\n",
            2 * t[0] + 2,
            2 * t[1] + 2,
            2 * t[2] + 2
        ));
    }
    let got = parse(&s).unwrap();
    assert_eq!(got, cube);
    assert_eq!(got.bounds(), (Vec3::ZERO, Vec3::new(1.0, 1.0, 1.0)));
}

#[test]
fn unknown_and_free_form_statements_are_errors_naming_them() {
    let obj = to_obj(&cube());
    for (line, needles) in [
        ("vx 1 2 3", &["unknown statement", "\"vx\""][..]),
        ("F 1 2 3", &["unknown statement", "\"F\""]),
        ("face 1 2 3", &["\"face\""]),
        ("surf 0 1 0 1 1 2 3", &["free-form", "\"surf\""]),
        ("cstype bezier", &["free-form", "\"cstype\""]),
        ("call other.obj", &["unknown statement", "\"call\""]),
    ] {
        let text = format!("{obj}{line}\n");
        let e = parse(&text).unwrap_err();
        assert_eq!(e.line, 21, "{line}: {e}");
        for n in needles {
            assert!(e.message.contains(n), "{line}: {e} does not mention {n}");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Errors and parsing by name.

#[test]
fn errors_display_as_name_line_message() {
    let e = parse("v 0 0 0\nv 1 x 0\n").unwrap_err();
    assert_eq!(e.source_name, NAME);
    assert_eq!(e.line, 2);
    assert_eq!(e.to_string(), format!("{NAME}:2: {}", e.message));
    assert!(
        e.message.contains("y coordinate") && e.message.contains("\"x\""),
        "{e}"
    );
    let e = parse("# nothing\n").unwrap_err();
    assert_eq!(e.line, 0);
    assert_eq!(e.to_string(), format!("{NAME}: {}", e.message));
    assert!(e.message.contains("no triangles"), "{e}");
    let boxed: Box<dyn std::error::Error> = Box::new(e);
    assert!(boxed.to_string().starts_with(NAME));
}

#[test]
fn parse_chooses_the_reader_by_extension_in_any_case() {
    let cube = cube();
    let obj = to_obj(&cube);
    let stl = to_binary_stl(&cube, b"binary");
    for name in ["a.obj", "A.OBJ", "dir/b.Obj", "c:\\x\\d.oBj", "a.stl.obj"] {
        assert_eq!(
            TriMesh::parse(obj.as_bytes(), name).unwrap(),
            cube,
            "{name}"
        );
    }
    for name in ["a.stl", "B.STL", "dir.obj/c.Stl"] {
        let got = TriMesh::parse(&stl, name).unwrap();
        assert_eq!(got, renumbered_by_first_use(&cube), "{name}");
    }
    // The OBJ reader was used for ".obj": STL bytes are an OBJ error, and the other way round.
    assert!(TriMesh::parse(&stl, "x.obj").is_err());
    assert!(TriMesh::parse(obj.as_bytes(), "x.stl").is_err());
    for (name, needle) in [
        ("shape.ply", "\".ply\""),
        ("shape.obj.gz", "\".gz\""),
        ("shape", "no extension"),
        ("dir.obj/shape", "no extension"),
        ("shape.", "\".\""),
        ("", "no extension"),
    ] {
        let e = TriMesh::parse(obj.as_bytes(), name).unwrap_err();
        assert_eq!(e.source_name, name);
        assert_eq!(e.line, 0);
        for n in [needle, ".obj", ".stl"] {
            assert!(e.message.contains(n), "{name}: {e} does not mention {n}");
        }
    }
}

/// The cube with each triangle's own three vertices (as some exporters write OBJ, and as STL
/// always is): read with the corners at the same position joined, it is the same solid as the
/// welded cube, whose voxel body has the same cells and mass. A hole is still a hole, its message
/// saying the corners were joined.
#[test]
fn an_unwelded_obj_is_welded_as_stl_is() {
    use jello_core::formats::scene::{BodySpec, MeshSpec};
    let cube = cube();
    let mut unwelded = String::new();
    for (n, t) in cube.triangles.iter().enumerate() {
        for &i in t {
            let p = cube.vertices[i as usize];
            unwelded.push_str(&format!("v {} {} {}\n", p.x, p.y, p.z));
        }
        unwelded.push_str(&format!("f {} {} {}\n", 3 * n + 1, 3 * n + 2, 3 * n + 3));
    }
    let read = parse(&unwelded).unwrap();
    assert_eq!((read.vertices.len(), read.triangles.len()), (8, 12));
    assert_eq!(
        (read.volume(), read.bounds()),
        (cube.volume(), cube.bounds())
    );
    assert_eq!(euler_characteristic(&read), 2);
    assert_valid(&read, "unwelded cube");
    let body = |mesh: &TriMesh| {
        let spec = BodySpec {
            mesh: Some(MeshSpec {
                cells: 5,
                vertices: mesh.vertices.iter().map(|v| v.to_array()).collect(),
                triangles: mesh.triangles.clone(),
            }),
            density: Some(1000.0),
            ..BodySpec::default()
        };
        let scene = jello_core::SceneFile::new(vec![spec])
            .to_scene("s.toml")
            .unwrap();
        let b = scene.model.body(0).clone();
        (
            b.cells().map(<[bool]>::to_vec),
            b.cell_count(),
            b.material.mass,
        )
    };
    let (welded, unwelded_body) = (body(&cube), body(&read));
    assert_eq!(welded, unwelded_body);
    assert_eq!(welded.1, 125);

    // Without its last triangle: a hole, found after the corners are joined.
    let open: String = unwelded
        .lines()
        .take(4 * 11)
        .map(|l| format!("{l}\n"))
        .collect();
    let e = parse(&open).unwrap_err();
    assert!(e.message.contains("one triangle only"), "{e}");
    assert!(
        e.message
            .contains("vertices at the same position taken as one"),
        "{e}"
    );
}
