//! Hostile input for the mesh readers, shapes that are not solids: files without triangles,
//! holes, non-manifold edges, flipped and degenerate triangles, sheets of no thickness each give
//! an error naming the file and the line (or, in binary STL, the triangle); never a panic or a
//! silently wrong mesh. An inside-out mesh is the one "error" that is accepted: it is flipped.
//! Bad numbers, bad bytes and sizes are in `mesh_hostile_bytes.rs`.

#[path = "common/alloc_watch.rs"]
mod alloc_watch;
#[path = "common/hostile_mesh.rs"]
mod hostile;
#[path = "common/meshes.rs"]
mod meshes;

use hostile::*;
use jello_core::{MeshError, TriMesh, Vec3};
use meshes::*;

// ---------------------------------------------------------------------------------------------
// Nothing to read.

#[test]
fn files_without_triangles_are_errors() {
    for text in [
        "",
        " \n\t\n",
        "# a comment\n",
        "v 0 0 0\nv 1 0 0\nv 0 1 0\n",
        "o x\ng y\n",
    ] {
        expect_err(
            obj(text.as_bytes()),
            OBJ,
            0,
            &["no triangles"],
            &format!("{text:?}"),
        );
    }
    expect_err(
        stl(b"solid x\nendsolid x\n"),
        STL,
        0,
        &["no triangles"],
        "empty solid",
    );
    expect_err(
        stl(&to_binary_stl(
            &TriMesh {
                vertices: vec![],
                triangles: vec![],
            },
            b"",
        )),
        STL,
        0,
        &["no triangles"],
        "count 0",
    );
    for (bytes, needles) in [
        (&b""[..], &["not an STL file", "0 bytes"][..]),
        (b"\n", &["not an STL file", "1 bytes"]),
        (b"x", &["expected an ASCII STL file", "\"x\""]),
        (b"solid", &["\"facet\" or \"endsolid\"", "ends here"]),
        (b"solid x\n", &["ends here"]),
    ] {
        expect_any_err(stl(bytes), STL, &format!("{:?}", bytes.escape_ascii()));
        let e = stl(bytes).unwrap_err();
        for n in needles {
            assert!(e.message.contains(n), "{e} does not mention {n}");
        }
    }
}

// ---------------------------------------------------------------------------------------------
// Not closed, not manifold, not consistently oriented.

/// The triangles sharing an undirected edge with triangle `t` of `m`, ascending.
fn neighbours(m: &TriMesh, t: usize) -> Vec<usize> {
    let edge = |tri: &[u32; 3], k: usize| {
        let (a, b) = (tri[k], tri[(k + 1) % 3]);
        (a.min(b), a.max(b))
    };
    let mine: Vec<_> = (0..3).map(|k| edge(&m.triangles[t], k)).collect();
    (0..m.triangles.len())
        .filter(|&u| u != t && (0..3).any(|k| mine.contains(&edge(&m.triangles[u], k))))
        .collect()
}

#[test]
fn a_hole_is_an_error_at_the_first_triangle_beside_it() {
    let cube = cube();
    for t in 0..12 {
        let open = without(&cube, t);
        // The three edges of the missing triangle are now used once, by its neighbours; the
        // first of them in the file reveals the hole first.
        let first = neighbours(&cube, t)[0];
        let first = if first > t { first - 1 } else { first };
        let what = format!("cube without triangle {t}");
        let e = expect_err(
            obj(to_obj(&open).as_bytes()),
            OBJ,
            obj_face_line(&open, first),
            &["one triangle only", "hole", "the edge from vertex"],
            &what,
        );
        // The edge is named by its OBJ vertex numbers (from 1) and positions, both corners of
        // the missing triangle.
        let [a, b, c] = cube.triangles[t];
        let named: Vec<u32> = [a, b, c]
            .into_iter()
            .filter(|&v| {
                let p = cube.vertices[v as usize];
                e.message
                    .contains(&format!("vertex {} ({}, {}, {})", v + 1, p.x, p.y, p.z))
            })
            .collect();
        assert_eq!(named.len(), 2, "{what}: {e}");

        expect_err(
            stl(to_ascii_stl(&open, "x").as_bytes()),
            STL,
            stl_facet_line(first),
            &["one triangle only", "welded vertex"],
            &what,
        );
        expect_err(
            stl(&to_binary_stl(&open, b"")),
            STL,
            0,
            &["one triangle only", &format!("(triangle {})", first + 1)],
            &what,
        );
    }
}

#[test]
fn an_edge_of_three_or_four_triangles_is_non_manifold() {
    // Two cubes sharing the edge from (1, 1, 0) to (1, 1, 1): four triangles there.
    let a = cube();
    let b = cuboid(Vec3::new(1.0, 1.0, 0.0), Vec3::new(2.0, 2.0, 1.0));
    let two = welded(&union(&a, &b));
    assert_eq!(two.vertices.len(), 14);
    let e = expect_any_err(obj(to_obj(&two).as_bytes()), OBJ, "two cubes on an edge");
    for n in [
        "shared by 4 triangles",
        "non-manifold",
        "(1, 1, 0)",
        "(1, 1, 1)",
    ] {
        assert!(e.message.contains(n), "{e} does not mention {n}");
    }
    let e = expect_any_err(
        stl(to_ascii_stl(&union(&a, &b), "x").as_bytes()),
        STL,
        "two cubes, ASCII",
    );
    assert!(e.message.contains("shared by 4 triangles"), "{e}");
    let e = expect_any_err(
        stl(&to_binary_stl(&union(&a, &b), b"")),
        STL,
        "two cubes, binary",
    );
    assert!(e.message.contains("shared by 4 triangles"), "{e}");

    // A fin: a triangle on a cube edge, its shared edge first.
    let mut fin = cube();
    fin.vertices.push(Vec3::new(0.5, -1.0, -1.0));
    let fin = with_triangle(&fin, [0, 1, 8]);
    expect_err(
        obj(to_obj(&fin).as_bytes()),
        OBJ,
        obj_face_line(&fin, 12),
        &[
            "shared by 3 triangles",
            "non-manifold",
            "vertex 1 (0, 0, 0)",
            "vertex 2 (1, 0, 0)",
            "lines 11, 14 and 22",
        ],
        "fin",
    );
    expect_err(
        stl(&to_binary_stl(&fin, b"")),
        STL,
        0,
        &["shared by 3 triangles", "triangles 2, 5 and 13"],
        "fin, binary",
    );

    // Many triangles on one edge: the message lists four and counts the rest.
    let mut fan = cube();
    for k in 0..50 {
        fan.vertices.push(Vec3::new(0.5, -1.0 - k as f64, -1.0));
        fan.triangles.push([0, 1, 8 + k]);
    }
    let e = expect_any_err(stl(to_ascii_stl(&fan, "x").as_bytes()), STL, "fan of fins");
    assert!(
        e.message.contains("shared by 52 triangles") && e.message.contains("and 48 more"),
        "{e}"
    );
}

#[test]
fn a_flipped_triangle_is_an_error_naming_it() {
    let cube = cube();
    for t in 0..12 {
        let bad = with_flipped(&cube, t);
        let what = format!("triangle {t} flipped");
        // Each of its edges is now used twice in one direction: revealed at whichever of it and
        // its neighbour comes second.
        // The two places named after "(by ": one of them is the flipped triangle.
        let named = |e: &MeshError, prefix: &str| -> Vec<usize> {
            let start = e
                .message
                .find(prefix)
                .unwrap_or_else(|| panic!("{what}: {e}"))
                + prefix.len();
            let list = e.message[start..].split(')').next().unwrap();
            list.split(" and ").map(|n| n.parse().unwrap()).collect()
        };
        let e = expect_any_err(obj(to_obj(&bad).as_bytes()), OBJ, &what);
        assert!(
            e.message.contains("same direction") && e.message.contains("flipped"),
            "{what}: {e}"
        );
        let lines = named(&e, "(by the faces on lines ");
        assert_eq!(lines.len(), 2, "{what}: {e}");
        assert!(lines.contains(&obj_face_line(&bad, t)), "{what}: {e}");
        assert_eq!(e.line, lines[1], "{what}: the second use reveals it: {e}");
        let e = expect_any_err(stl(&to_binary_stl(&bad, b"")), STL, &what);
        assert!(
            named(&e, "(by triangles ").contains(&(t + 1)),
            "{what}: {e}"
        );
    }
    // The first triangle flipped: its first edge is used next by triangle 1 (line 10), in the
    // same direction.
    expect_err(
        obj(to_obj(&with_flipped(&cube, 0)).as_bytes()),
        OBJ,
        10,
        &[
            "the edge from vertex 1 (0, 0, 0) to vertex 4 (1, 1, 0)",
            "the faces on lines 9 and 10",
        ],
        "triangle 0 flipped",
    );
    // A triangle repeated in the same direction.
    let e = expect_any_err(
        obj(to_obj(&with_triangle(&cube, cube.triangles[3])).as_bytes()),
        OBJ,
        "repeated",
    );
    assert!(e.message.contains("shared by 3 triangles"), "{e}");
}

#[test]
fn a_triangle_and_its_reverse_are_a_sheet_of_no_thickness() {
    let text = "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\nf 1 3 2\n";
    expect_err(
        obj(text.as_bytes()),
        OBJ,
        5,
        &[
            "the face on line 4 and the face on line 5",
            "facing both ways",
        ],
        "sheet",
    );
    let sheet = TriMesh {
        vertices: vec![
            Vec3::ZERO,
            Vec3::new(1.0, 0.0, 0.0),
            Vec3::new(0.0, 1.0, 0.0),
        ],
        triangles: vec![[0, 1, 2], [0, 2, 1]],
    };
    expect_err(
        stl(to_ascii_stl(&sheet, "s").as_bytes()),
        STL,
        9,
        &[
            "the facet on line 2 and the facet on line 9",
            "facing both ways",
        ],
        "sheet",
    );
    expect_err(
        stl(&to_binary_stl(&sheet, b"")),
        STL,
        0,
        &["triangle 1 and triangle 2", "facing both ways"],
        "sheet",
    );
    // A cube with a sheet beside it.
    let with_sheet = union(&cube(), &translated(&sheet, Vec3::new(5.0, 0.0, 0.0)));
    expect_err(
        obj(to_obj(&with_sheet).as_bytes()),
        OBJ,
        obj_face_line(&with_sheet, 13),
        &["facing both ways"],
        "cube and sheet",
    );
}

#[test]
fn nested_shells_and_shells_touching_at_a_corner_are_accepted() {
    // A cavity: a small cube inside a big one, wound inward. Volume 8 − 1.
    let big = cuboid(Vec3::new(-1.0, -1.0, -1.0), Vec3::new(1.0, 1.0, 1.0));
    let hollow = union(
        &big,
        &flipped(&cuboid(
            Vec3::new(-0.5, -0.5, -0.5),
            Vec3::new(0.5, 0.5, 0.5),
        )),
    );
    let got = obj(to_obj(&hollow).as_bytes()).unwrap();
    assert_eq!(got, hollow);
    assert_eq!(got.volume(), 7.0);
    assert_eq!(euler_characteristic(&got), 4);
    // The same, inside-out as a whole: flipped back.
    let got = stl(to_ascii_stl(&flipped(&hollow), "h").as_bytes()).unwrap();
    assert_eq!(got.volume(), 7.0);
    // Two cubes sharing only the corner (1, 1, 1): edges are fine, the vertex is not a disc,
    // but the two still bound a solid.
    let two = welded(&union(
        &cube(),
        &translated(&cube(), Vec3::new(1.0, 1.0, 1.0)),
    ));
    assert_eq!(two.vertices.len(), 15);
    let got = obj(to_obj(&two).as_bytes()).unwrap();
    assert_eq!(got.volume(), 2.0);
    // A shell and the same shell inside-out, side by side, cancel: no volume.
    let cancel = union(
        &cube(),
        &flipped(&translated(&cube(), Vec3::new(2.0, 0.0, 0.0))),
    );
    expect_err(
        obj(to_obj(&cancel).as_bytes()),
        OBJ,
        0,
        &["encloses no volume"],
        "cancelling shells",
    );
}

#[test]
fn an_inside_out_mesh_is_flipped_and_accepted() {
    for mesh in [cube(), octahedron(0.5), torus(3.0, 1.0, 10, 5)] {
        let inside_out = flipped(&mesh);
        assert!(inside_out.volume() < 0.0);
        let got = obj(to_obj(&inside_out).as_bytes()).unwrap();
        assert_eq!(got, mesh, "every triangle flipped back");
        assert!(got.volume() > 0.0);
        assert_valid(&got, "inside-out OBJ");
    }
}

// ---------------------------------------------------------------------------------------------
// Degenerate triangles.

#[test]
fn degenerate_triangles_are_errors_naming_them() {
    let v = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 2 0 0\nv 0 0 0\n";
    for (face, needles) in [
        (
            "f 1 1 2",
            &["uses vertex 1 twice", "degenerate", "(vertices 1, 1, 2)"][..],
        ),
        ("f 1 2 2", &["uses vertex 2 twice"]),
        ("f 3 2 3", &["uses vertex 3 twice"]),
        ("f 1 2 2 3", &["(vertices 1, 2, 2)", "uses vertex 2 twice"]),
        (
            "f 1 2 4",
            &["zero area", "(0, 0, 0), (1, 0, 0), (2, 0, 0)", "one line"],
        ),
        ("f 1 5 2", &["zero area"]),
        ("f -1 -5 -2", &["zero area"]),
    ] {
        let text = format!("{v}f 1 2 3\n{face}\n");
        expect_err(obj(text.as_bytes()), OBJ, 7, needles, face);
    }
    // STL: two corners at one point, or on one line.
    let mut cube = cube();
    cube.vertices.push(Vec3::new(2.0, 0.0, 0.0));
    let flat = with_triangle(&cube, [0, 1, 8]);
    let pinched = with_triangle(&cube, [0, 1, 0]);
    expect_err(
        stl(to_ascii_stl(&flat, "x").as_bytes()),
        STL,
        stl_facet_line(12),
        &["zero area"],
        "flat facet",
    );
    expect_err(
        stl(to_ascii_stl(&pinched, "x").as_bytes()),
        STL,
        stl_facet_line(12),
        &["the same point (0, 0, 0)"],
        "pinched facet",
    );
    expect_err(
        stl(&to_binary_stl(&flat, b"")),
        STL,
        0,
        &["triangle 13 is degenerate", "zero area"],
        "flat binary",
    );
    let mut pinched_bytes = to_binary_stl(&cube, b"");
    let (a, b) = (binary_offset(4, 1, 0), binary_offset(4, 2, 0));
    let corner: Vec<u8> = pinched_bytes[a..a + 12].to_vec();
    pinched_bytes[b..b + 12].copy_from_slice(&corner);
    expect_err(
        stl(&pinched_bytes),
        STL,
        0,
        &["triangle 5 is degenerate", "same point"],
        "pinched binary",
    );
}
