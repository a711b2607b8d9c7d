//! The STL reader on meshes made in code: a cube, an octahedron and a torus written as ASCII and
//! binary STL read back, welded, to the generated mesh (renumbered in order of first use), with
//! their closed-form volumes and Euler characteristics; the layouts ASCII files come in; and
//! telling ASCII from binary when a binary header starts with "solid".

#[path = "common/meshes.rs"]
mod meshes;

use jello_core::{MeshError, TriMesh, Vec3};
use meshes::*;

const NAME: &str = "shape.stl";

fn parse(bytes: &[u8]) -> Result<TriMesh, MeshError> {
    TriMesh::parse_stl(bytes, NAME)
}

/// Every shape the tests write: name, mesh, closed-form volume, Euler characteristic.
fn shapes() -> Vec<(&'static str, TriMesh, f64, i64)> {
    vec![
        ("cube", cube(), 1.0, 2),
        ("octahedron", octahedron(1.5), 4.0 / 3.0 * 1.5f64.powi(3), 2),
        ("small octahedron", octahedron(0.01), 4.0 / 3.0 * 1e-6, 2),
        (
            "torus",
            torus(2.0, 0.5, 24, 12),
            torus_volume(2.0, 0.5, 24, 12),
            0,
        ),
        (
            "thin torus",
            torus(1.0, 0.125, 40, 5),
            torus_volume(1.0, 0.125, 40, 5),
            0,
        ),
        (
            "box far away",
            cuboid(
                Vec3::new(1e5, 2e5, -3e5),
                Vec3::new(1e5 + 2.0, 2e5 + 0.5, -3e5 + 0.25),
            ),
            0.25,
            2,
        ),
    ]
}

fn assert_close(got: f64, expected: f64, rel: f64, what: &str) {
    assert!(
        (got - expected).abs() <= rel * expected.abs(),
        "{what}: {got} vs {expected} (relative error {:e})",
        (got - expected).abs() / expected.abs()
    );
}

#[test]
fn ascii_stl_reads_back_welded_with_closed_form_volumes() {
    for (what, mesh, volume, chi) in shapes() {
        let text = to_ascii_stl(&mesh, what);
        let got = parse(text.as_bytes()).unwrap_or_else(|e| panic!("{what}: {e}"));
        // Welding gives back one vertex per generated vertex, numbered by first use.
        assert_eq!(got, renumbered_by_first_use(&mesh), "{what}");
        assert_eq!(got.vertices.len(), mesh.vertices.len(), "{what}");
        assert_eq!(got.triangles.len(), mesh.triangles.len(), "{what}");
        assert_eq!(euler_characteristic(&got), chi, "{what}");
        assert_close(got.volume(), volume, 1e-13, what);
        assert_valid(&got, what);
    }
}

#[test]
fn binary_stl_reads_back_welded_with_closed_form_volumes() {
    for (what, mesh, volume, chi) in shapes() {
        let bytes = to_binary_stl(&mesh, what.as_bytes());
        assert_eq!(bytes.len(), 84 + 50 * mesh.triangles.len());
        let got = parse(&bytes).unwrap_or_else(|e| panic!("{what}: {e}"));
        // Binary STL holds f32: the expected mesh is the generated one rounded.
        let expected = renumbered_by_first_use(&rounded_to_f32(&mesh));
        assert_eq!(got, expected, "{what}");
        assert_eq!(euler_characteristic(&got), chi, "{what}");
        assert_eq!(got.volume(), expected.volume(), "{what}");
        // f32 rounds coordinates by up to 2⁻²⁴ relative (the far box is f32-exact).
        assert_close(got.volume(), volume, 1e-6, what);
        assert_valid(&got, what);
    }
}

#[test]
fn f32_exact_shapes_read_back_exactly_from_binary() {
    for mesh in [
        cube(),
        octahedron(1.5),
        cuboid(Vec3::new(-1.0, 0.5, 2.0), Vec3::ZERO),
    ] {
        let mesh = if mesh.volume() < 0.0 {
            flipped(&mesh)
        } else {
            mesh
        };
        let got = parse(&to_binary_stl(&mesh, b"")).unwrap();
        assert_eq!(got, renumbered_by_first_use(&mesh));
    }
    assert_eq!(parse(&to_binary_stl(&cube(), b"")).unwrap().volume(), 1.0);
}

#[test]
fn binary_files_whose_header_starts_with_solid_are_read_as_binary() {
    let cube = cube();
    let expected = renumbered_by_first_use(&cube);
    for header in [
        &b"solid"[..],
        b"solid cube",
        b"SOLID exported by a CAD program",
        b"  solid indented",
        b"solid cube\nfacet normal 0 0 1\nouter loop\nvertex 0 0 0\n",
        b"\xef\xbb\xbfsolid after a byte-order mark",
        &[b's', b'o', b'l', b'i', b'd', b' ', b'x', b' ', 0xff, 0xfe],
        &[b'x'; 80],
        &[b' '; 80],
    ] {
        let bytes = to_binary_stl(&cube, header);
        let got = parse(&bytes).unwrap_or_else(|e| panic!("{:?}: {e}", header.escape_ascii()));
        assert_eq!(got, expected);
    }
    // A header of spaces with "solid" whose count bytes are spaces too would be text: such a
    // count (0x20202020) needs 27 GB, so a small file like it is ASCII and reports an ASCII
    // error.
    let mut bytes = b"solid".to_vec();
    bytes.resize(84, b' ');
    let e = parse(&bytes).unwrap_err();
    assert!(e.message.contains("ends here"), "{e}");
}

#[test]
fn ascii_layouts_and_case_are_accepted_and_normals_ignored() {
    let cube = cube();
    let expected = renumbered_by_first_use(&cube);
    let text = to_ascii_stl(&cube, "cube");
    // Upper case keywords, CRLF, tabs, a byte-order mark, no names, extra blank lines.
    let variants = [
        text.to_uppercase(),
        text.replace('\n', "\r\n"),
        text.replace("  ", "\t"),
        format!("\u{feff}{text}"),
        text.replace("solid cube", "solid")
            .replace("endsolid cube", "endsolid"),
        text.replace('\n', "\n\n"),
        format!("\n\n   {text}\n\n  \t"),
        text.replace("solid cube", "solid a name with spaces and ünïcode"),
        text.replace("endsolid cube", "endsolid"),
        text.replace("    outer loop\n", "    outer\n loop\n"),
        text.replace("      vertex", "vertex")
            .replace("  facet", "facet"),
    ];
    for (n, v) in variants.iter().enumerate() {
        let got = parse(v.as_bytes()).unwrap_or_else(|e| panic!("variant {n}: {e}\n{v}"));
        assert_eq!(got, expected, "variant {n}");
    }
    // Normals of any value, even not finite: the winding decides.
    let mut wrong = String::new();
    for (k, line) in text.lines().enumerate() {
        if line.trim_start().starts_with("facet normal") {
            let n = [
                "0 0 0",
                "nan nan nan",
                "-1 -1 -1",
                "inf -inf 1e400",
                "1 2 3",
            ][k % 5];
            wrong.push_str(&format!("facet normal {n}\n"));
        } else {
            wrong.push_str(line);
            wrong.push('\n');
        }
    }
    assert_eq!(parse(wrong.as_bytes()).unwrap(), expected);
}

#[test]
fn several_solids_make_one_mesh() {
    let cube = cube();
    let (first, second) = cube.triangles.split_at(5);
    let part = |tris: &[[u32; 3]], name: &str| {
        to_ascii_stl(
            &TriMesh {
                vertices: cube.vertices.clone(),
                triangles: tris.to_vec(),
            },
            name,
        )
    };
    let text = part(first, "one") + &part(second, "two");
    assert_eq!(
        parse(text.as_bytes()).unwrap(),
        renumbered_by_first_use(&cube)
    );
    // Two separate cubes in two solids: 16 vertices, volume 2.
    let two =
        to_ascii_stl(&cube, "a") + &to_ascii_stl(&translated(&cube, Vec3::new(3.0, 0.0, 0.0)), "b");
    let got = parse(two.as_bytes()).unwrap();
    assert_eq!((got.vertices.len(), got.triangles.len()), (16, 24));
    assert_eq!(got.volume(), 2.0);
    assert_eq!(euler_characteristic(&got), 4);
}

#[test]
fn welding_is_by_exact_equality_and_minus_zero_is_zero() {
    // The cube with its zeros written as -0 in some corners: still 8 vertices.
    let cube = cube();
    let text = to_ascii_stl(&cube, "cube");
    let mut signed = String::new();
    for (k, line) in text.lines().enumerate() {
        if k % 3 == 0 {
            signed.push_str(&line.replace(" 0", " -0"));
        } else {
            signed.push_str(line);
        }
        signed.push('\n');
    }
    assert_ne!(signed, text);
    let got = parse(signed.as_bytes()).unwrap();
    assert_eq!(got, renumbered_by_first_use(&cube));
    assert!(got
        .vertices
        .iter()
        .all(|p| p.to_array().iter().all(|c| c.is_sign_positive())));
    // The same in binary.
    let mut bytes = to_binary_stl(&cube, b"");
    for t in 0..12 {
        for axis in 0..3 {
            let o = binary_offset(t, t % 3, axis);
            if bytes[o..o + 4] == 0f32.to_le_bytes() {
                bytes[o..o + 4].copy_from_slice(&(-0f32).to_le_bytes());
            }
        }
    }
    assert_eq!(parse(&bytes).unwrap(), renumbered_by_first_use(&cube));
    // Corners that differ in the last bit are different vertices: the cube with one corner
    // moved by an ulp in one facet is no longer closed.
    let nudged = text.replacen("vertex 1 1 1", "vertex 1.0000000000000002 1 1", 1);
    let e = parse(nudged.as_bytes()).unwrap_err();
    assert!(e.message.contains("one triangle only"), "{e}");
}

#[test]
fn an_inside_out_stl_is_flipped_and_accepted() {
    for mesh in [cube(), octahedron(2.0), torus(2.0, 0.5, 12, 6)] {
        let inside_out = flipped(&mesh);
        assert!(inside_out.volume() < 0.0);
        let expected = renumbered_by_first_use(&inside_out);
        let got = parse(to_ascii_stl(&inside_out, "x").as_bytes()).unwrap();
        assert_eq!(got, flipped(&expected));
        assert!(got.volume() > 0.0);
        assert_eq!(got.volume(), -expected.volume());
        let got = parse(&to_binary_stl(&inside_out, b"")).unwrap();
        assert!(got.volume() > 0.0);
        assert_valid(&got, "flipped binary");
    }
}
