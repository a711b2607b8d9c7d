//! Hostile input for the mesh readers: every malformed file, and every mesh that is not the
//! closed surface of a solid, gives an error naming the file and the line (or, in binary STL,
//! the triangle); never a panic, a hang, an allocation beyond a bound linear in the input, or a
//! silently wrong mesh. An inside-out mesh is the one "error" that is accepted: it is flipped.

#[path = "common/alloc_watch.rs"]
mod alloc_watch;
#[path = "common/meshes.rs"]
mod meshes;

use alloc_watch::{largest_allocation, total_allocation};
use jello_core::{MeshError, TriMesh, Vec3};
use meshes::*;

// ---------------------------------------------------------------------------------------------
// Helpers.

const OBJ: &str = "hostile.obj";
const STL: &str = "hostile.stl";

/// Bytes any parse may allocate in all: [`ALLOCATION_PER_BYTE`] per byte of input plus
/// [`ALLOCATION_SLACK`]. The densest input is an OBJ polygon, one triangle per 2 bytes
/// (`f 1 2 3 4 …`), each triangle taking 12 bytes, its line 8, its vertex in the face 4 and its
/// three half-edges 48 in the edge check, vectors growing by doubling (so up to 3.5 times their
/// final size allocated in all): measured, 68 bytes per byte (`large_inputs_stay_linear`); binary
/// STL, under 10. A reader that made words for a message before knowing there is an error (it
/// measured 114), copied the rest of the input per statement, or otherwise allocated more than
/// linearly, exceeds the bound. (Time is never measured: a hang shows as a test that never ends.)
const ALLOCATION_PER_BYTE: usize = 80;
const ALLOCATION_SLACK: usize = 64 << 10;

fn bounded(
    bytes: &[u8],
    read: impl FnOnce() -> Result<TriMesh, MeshError>,
) -> Result<TriMesh, MeshError> {
    let (r, total) = total_allocation(read);
    assert!(
        total <= ALLOCATION_PER_BYTE * bytes.len() + ALLOCATION_SLACK,
        "parsing {} bytes allocated {total} bytes",
        bytes.len()
    );
    r
}

fn obj(bytes: &[u8]) -> Result<TriMesh, MeshError> {
    bounded(bytes, || TriMesh::parse_obj(bytes, OBJ))
}

fn stl(bytes: &[u8]) -> Result<TriMesh, MeshError> {
    bounded(bytes, || TriMesh::parse_stl(bytes, STL))
}

/// Asserts `r` is an error from `name` at `line` (0: none) whose message contains every one of
/// `needles`; returns it.
fn expect_err(
    r: Result<TriMesh, MeshError>,
    name: &str,
    line: usize,
    needles: &[&str],
    what: &str,
) -> MeshError {
    let e = match r {
        Ok(m) => panic!(
            "{what}: parsed ({} triangles), expected an error",
            m.triangles.len()
        ),
        Err(e) => e,
    };
    let shown = e.to_string();
    assert_eq!(e.source_name, name, "{what}: {shown}");
    assert_eq!(e.line, line, "{what}: wrong line in {shown}");
    let prefix = if line > 0 {
        format!("{name}:{line}: ")
    } else {
        format!("{name}: ")
    };
    assert!(shown.starts_with(&prefix), "{what}: {shown:?}");
    for n in needles {
        assert!(
            e.message.contains(n),
            "{what}: {shown} does not mention {n:?}"
        );
    }
    e
}

/// Asserts `r` is an error naming `name`, whatever the line; returns it.
fn expect_any_err(r: Result<TriMesh, MeshError>, name: &str, what: &str) -> MeshError {
    match r {
        Ok(m) => panic!(
            "{what}: parsed ({} triangles), expected an error",
            m.triangles.len()
        ),
        Err(e) => {
            assert_eq!(e.source_name, name, "{what}: {e}");
            assert!(!e.message.is_empty(), "{what}");
            assert!(e.to_string().starts_with(name), "{what}: {e}");
            e
        }
    }
}

/// `m` with equal positions merged into their first vertex (for OBJ, which does not weld).
fn welded(m: &TriMesh) -> TriMesh {
    let mut vertices: Vec<Vec3> = Vec::new();
    let map: Vec<u32> = m
        .vertices
        .iter()
        .map(|p| match vertices.iter().position(|q| q == p) {
            Some(i) => i as u32,
            None => {
                vertices.push(*p);
                vertices.len() as u32 - 1
            }
        })
        .collect();
    TriMesh {
        vertices,
        triangles: m
            .triangles
            .iter()
            .map(|t| t.map(|i| map[i as usize]))
            .collect(),
    }
}

/// `m` without triangle `t`.
fn without(m: &TriMesh, t: usize) -> TriMesh {
    let mut out = m.clone();
    out.triangles.remove(t);
    out
}

/// `m` with triangle `t` wound the other way.
fn with_flipped(m: &TriMesh, t: usize) -> TriMesh {
    let mut out = m.clone();
    out.triangles[t].swap(1, 2);
    out
}

/// `m` with triangle `t` added at the end.
fn with_triangle(m: &TriMesh, t: [u32; 3]) -> TriMesh {
    let mut out = m.clone();
    out.triangles.push(t);
    out
}

/// A fixed-seed 64-bit LCG (Knuth's MMIX constants); the high bits are the output.
struct Lcg(u64);

impl Lcg {
    fn next(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        self.0
    }
    fn byte(&mut self) -> u8 {
        (self.next() >> 56) as u8
    }
    fn below(&mut self, n: u64) -> u64 {
        (self.next() >> 33) % n
    }
}

const NON_FINITE: &[&str] = &[
    "nan",
    "NaN",
    "-nan",
    "inf",
    "-inf",
    "+inf",
    "infinity",
    "-Infinity",
    "1e400",
    "-1e400",
    "1e99999999999",
];

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

// ---------------------------------------------------------------------------------------------
// Numbers and indices.

#[test]
fn non_finite_coordinates_are_errors_at_their_line() {
    let cube = cube();
    let text = to_obj(&cube);
    let lines: Vec<&str> = text.lines().collect();
    for (k, axis) in ["x", "y", "z"].iter().enumerate() {
        for bad in NON_FINITE {
            let vertex = 3 + k;
            let mut tokens: Vec<&str> = lines[vertex].split(' ').collect();
            tokens[1 + k] = bad;
            let mut edited = lines.clone();
            let replaced = tokens.join(" ");
            edited[vertex] = &replaced;
            let e = expect_err(
                obj(edited.join("\n").as_bytes()),
                OBJ,
                vertex + 1,
                &[axis, "not a finite number"],
                bad,
            );
            assert!(e.message.contains(&format!("\"{bad}\"")), "{e}");
        }
    }
    for bad in ["nan", "inf"] {
        expect_err(
            obj(format!("v 0 0 0 {bad}\n").as_bytes()),
            OBJ,
            1,
            &["number 4 of the vertex"],
            bad,
        );
        expect_err(
            obj(format!("v 0 0 0 1 1 {bad}\n").as_bytes()),
            OBJ,
            1,
            &["number 6"],
            bad,
        );
    }

    let text = to_ascii_stl(&cube, "c");
    for bad in NON_FINITE {
        for (t, k, axis) in [(0, 0, 0), (5, 1, 1), (11, 2, 2)] {
            let line = stl_vertex_line(t, k);
            let edited: Vec<String> = text
                .lines()
                .enumerate()
                .map(|(n, l)| {
                    if n + 1 == line {
                        let mut tokens: Vec<&str> = l.split_whitespace().collect();
                        tokens[1 + axis] = bad;
                        tokens.join(" ")
                    } else {
                        l.to_string()
                    }
                })
                .collect();
            expect_err(
                stl(edited.join("\n").as_bytes()),
                STL,
                line,
                &["not a finite number", ["x", "y", "z"][axis]],
                bad,
            );
        }
    }

    for (bits, shown) in [
        (f32::NAN, "NaN"),
        (f32::INFINITY, "inf"),
        (f32::NEG_INFINITY, "-inf"),
    ] {
        for (t, k, axis) in [(0, 0, 0), (6, 1, 2), (11, 2, 1)] {
            let mut bytes = to_binary_stl(&cube, b"");
            let o = binary_offset(t, k, axis);
            bytes[o..o + 4].copy_from_slice(&bits.to_le_bytes());
            expect_err(
                stl(&bytes),
                STL,
                0,
                &[
                    &format!("triangle {}: corner {}", t + 1, k + 1),
                    shown,
                    "not finite",
                ],
                shown,
            );
        }
    }
    // A non-finite normal is ignored.
    let mut bytes = to_binary_stl(&cube, b"");
    bytes[84..88].copy_from_slice(&f32::NAN.to_le_bytes());
    assert!(stl(&bytes).is_ok());
}

#[test]
fn face_indices_out_of_range_zero_or_malformed_are_errors() {
    let v = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nvt 0 0\nvn 0 0 1\n";
    for (face, needles) in [
        (
            "f 1 2 5",
            &[
                "vertex index 5 is out of range",
                "defines 4 vertices before this line",
            ][..],
        ),
        ("f 1 2 0", &["vertex index 0 is invalid", "from 1"]),
        (
            "f -5 1 2",
            &["vertex index -5 is out of range", "counts back"],
        ),
        ("f 1 2 -0", &["vertex index 0 is invalid"]),
        (
            "f 1 2 99999999999999999999",
            &["out of range", "99999999999999999999"],
        ),
        (
            "f 1 2 -99999999999999999999",
            &["out of range", "counts back"],
        ),
        ("f 1 2 3x", &["expected a vertex reference", "\"3x\""]),
        ("f 1 2 3.0", &["\"3.0\""]),
        ("f 1 2 +", &["\"+\""]),
        ("f 1 2 /3", &["\"/3\""]),
        ("f 1 2 3/", &["\"3/\""]),
        ("f 1 2 3//", &["\"3//\""]),
        ("f 1 2 3/1/1/1", &["\"3/1/1/1\""]),
        (
            "f 1 2 3/2",
            &[
                "texture coordinate index 2 is out of range",
                "1 texture coordinate before",
            ],
        ),
        (
            "f 1 2 3//2",
            &["normal index 2 is out of range", "1 normal before"],
        ),
        ("f 1 2 3/0/1", &["texture coordinate index 0 is invalid"]),
        ("f 1 2 3/1/-2", &["normal index -2 is out of range"]),
        ("f 1 2", &["at least 3 vertices", "found 2 vertices"]),
        ("f 1", &["found 1 vertex"]),
        ("f", &["found 0 vertices"]),
        ("f 1 2 3 # 4", &["one triangle only"]),
    ] {
        let text = format!("{v}{face}\n");
        expect_err(obj(text.as_bytes()), OBJ, 7, needles, face);
    }
    // A face before the vertices it names (forward references are not allowed).
    expect_err(
        obj(b"f 1 2 3\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"),
        OBJ,
        1,
        &["defines 0 vertices"],
        "forward",
    );
    // The shortened token in a message.
    let e = expect_any_err(
        obj(format!("{v}f 1 2 {}\n", "9".repeat(10_000)).as_bytes()),
        OBJ,
        "long index",
    );
    assert!(e.message.len() < 300, "{}", e.message.len());
}

#[test]
fn malformed_vertices_are_errors() {
    for (line, needles) in [
        ("v", &["needs x, y and z", "found 0 numbers"][..]),
        ("v 1 2", &["found 2 numbers"]),
        ("v 1", &["found 1 number"]),
        ("v 1 2 x", &["z coordinate", "\"x\""]),
        ("v 1,2,3", &["x coordinate", "\"1,2,3\""]),
        ("v 0 0 0 1 1 1 1 1", &["at most 7 numbers"]),
        ("v 0x10 0 0", &["\"0x10\""]),
    ] {
        expect_err(
            obj(format!("# c\n{line}\n").as_bytes()),
            OBJ,
            2,
            needles,
            line,
        );
    }
}

#[test]
fn malformed_ascii_stl_is_an_error_at_its_line() {
    let text = to_ascii_stl(&cube(), "cube");
    let lines: Vec<&str> = text.lines().collect();
    let edit = |line: usize, new: &str| -> String {
        let mut l = lines.clone();
        l[line - 1] = new;
        l.join("\n") + "\n"
    };
    let facet = stl_facet_line(3);
    for (line, new, at, needles) in [
        (1, "solidx", 1, &["expected \"solid\""][..]),
        (facet, "facet", facet + 1, &["expected \"normal\""]),
        (
            facet,
            "facet normal 0 0",
            facet + 1,
            &["facet normal's z", "\"outer\""],
        ),
        (
            facet,
            "facet normal 0 0 x",
            facet,
            &["facet normal's z", "\"x\""],
        ),
        (
            facet,
            "facet normal 0 0 1 1",
            facet,
            &["expected \"outer\"", "\"1\""],
        ),
        (facet + 1, "outer", facet + 2, &["expected \"loop\""]),
        (facet + 1, "loop", facet + 1, &["expected \"outer\""]),
        (
            facet + 2,
            "vertex 0 0",
            facet + 3,
            &["vertex 1's z coordinate", "\"vertex\""],
        ),
        (
            facet + 2,
            "vertx 0 0 0",
            facet + 2,
            &["expected \"vertex\" (a facet has 3)", "\"vertx\""],
        ),
        (
            facet + 4,
            "",
            facet + 5,
            &["expected \"vertex\" (a facet has 3)", "\"endloop\""],
        ),
        (
            facet + 4,
            "vertex 0 0 0\nvertex 0 0 0",
            facet + 5,
            &[
                "expected \"endloop\" (a facet has exactly 3 vertices)",
                "\"vertex\"",
            ],
        ),
        (
            facet + 5,
            "",
            facet + 6,
            &["expected \"endloop\"", "\"endfacet\""],
        ),
        (
            facet + 6,
            "",
            facet + 7,
            &["expected \"endfacet\"", "\"facet\""],
        ),
        (
            facet + 6,
            "endfacet x",
            facet + 6,
            &["expected \"facet\" or \"endsolid\"", "\"x\""],
        ),
        (
            lines.len(),
            "",
            lines.len() + 1,
            &["expected \"facet\" or \"endsolid\"", "ends here"],
        ),
        (
            lines.len(),
            "endsolid cube\nfacet",
            lines.len() + 1,
            &["another \"solid\" or the end of the file", "\"facet\""],
        ),
        (
            lines.len(),
            "endsolid cube\n\n\0",
            lines.len() + 2,
            &["control character 0x00"],
        ),
    ] {
        let bad = edit(line, new);
        expect_err(
            stl(bad.as_bytes()),
            STL,
            at,
            needles,
            &format!("line {line} = {new:?}"),
        );
    }
    // Two solids with nothing between; trailing white space: fine.
    let other = to_ascii_stl(&translated(&cube(), Vec3::new(0.0, 0.0, 5.0)), "other");
    assert_eq!(
        stl(format!("{text}{other}  \n\t\n").as_bytes())
            .unwrap()
            .volume(),
        2.0
    );
}

// ---------------------------------------------------------------------------------------------
// Not text.

#[test]
fn invalid_utf8_and_control_characters_are_errors_at_their_line() {
    let text = to_obj(&cube());
    for (bad, needle) in [
        (&b"\xff"[..], "invalid byte sequence \"\\xff\""),
        (b"\xc3", "\"\\xc3"),
        (b"\xed\xa0\x80", "\\xed"),
        (b"\0", "control character 0x00"),
        (b"\x1b", "0x1b"),
        (b"\x7f", "0x7f"),
    ] {
        // Into a vertex (line 5), a face (line 9) and a comment: a comment must be text too.
        let text = format!("{text}# a comment\n");
        for line in [5, 9, 21] {
            let at = text.match_indices('\n').nth(line - 2).unwrap().0 + 3;
            let mut bytes = text.clone().into_bytes();
            for (k, &b) in bad.iter().enumerate() {
                bytes.insert(at + k, b);
            }
            expect_err(
                obj(&bytes),
                OBJ,
                line,
                &["not", needle],
                &format!("{needle} on line {line}"),
            );
        }
    }
    // ASCII STL: a bad byte beyond the first 84 bytes is an error at its line.
    let text = to_ascii_stl(&cube(), "cube");
    for line in [7, 40, 86] {
        let at = text.match_indices('\n').nth(line - 2).unwrap().0 + 4;
        let mut bytes = text.clone().into_bytes();
        bytes.insert(at, 0xff);
        expect_err(
            stl(&bytes),
            STL,
            line,
            &["not UTF-8 text"],
            &format!("0xff on line {line}"),
        );
        bytes[at] = 0;
        expect_err(
            stl(&bytes),
            STL,
            line,
            &["control character 0x00"],
            &format!("NUL on line {line}"),
        );
    }
    // Within the first 84 bytes it could be a binary header: both readers' complaints are given.
    let mut bytes = text.clone().into_bytes();
    bytes.insert(30, 0xff);
    let e = expect_err(
        stl(&bytes),
        STL,
        0,
        &[
            "binary STL: the header claims",
            "not ASCII STL either (line 2: the file is not UTF-8 text",
        ],
        "0xff at byte 30",
    );
    assert!(e.message.len() < 600, "{e}");
    // Short files: the ASCII complaint.
    expect_err(
        stl(b"solid x\xff\n"),
        STL,
        1,
        &["not UTF-8 text"],
        "short, not text",
    );
}

// ---------------------------------------------------------------------------------------------
// Truncation, size and garbage.

#[test]
fn binary_stl_cut_at_every_length_is_an_error() {
    let cube = cube();
    for header in [&b""[..], b"solid cube", b"solid cube\nfacet normal 0 0 1\n"] {
        let bytes = to_binary_stl(&cube, header);
        assert_eq!(bytes.len(), 684);
        for cut in 0..bytes.len() {
            let what = format!("{:?} cut at {cut}", header.escape_ascii());
            let e = expect_any_err(stl(&bytes[..cut]), STL, &what);
            if cut >= 84 && header.is_empty() {
                assert!(
                    e.message
                        .contains("claims 12 triangles, which take 684 bytes"),
                    "{what}: {e}"
                );
                assert!(
                    e.message.contains(&format!("has {cut} bytes")),
                    "{what}: {e}"
                );
            }
        }
        assert_eq!(stl(&bytes).unwrap(), renumbered_by_first_use(&cube));
        // Longer than the count says, by one byte or one triangle.
        let mut longer = bytes.clone();
        longer.push(0);
        expect_err(
            stl(&longer),
            STL,
            0,
            &["claims 12 triangles", "has 685 bytes"],
            "one byte more",
        );
        longer.extend([0; 49]);
        expect_err(
            stl(&longer),
            STL,
            0,
            &["claims 12 triangles", "has 734 bytes"],
            "one triangle more",
        );
        // Or a count that is one off.
        let mut wrong = bytes.clone();
        wrong[80] = 11;
        expect_err(
            stl(&wrong),
            STL,
            0,
            &["claims 11 triangles, which take 634 bytes"],
            "count 11",
        );
    }
}

#[test]
fn text_files_cut_at_every_length_never_panic() {
    let octa = octahedron(1.0);
    for (name, bytes) in [
        (OBJ, to_obj(&octa).into_bytes()),
        (STL, to_ascii_stl(&octa, "o").into_bytes()),
    ] {
        let mut oks = 0;
        for cut in 0..=bytes.len() {
            let part = &bytes[..cut];
            let r = if name == OBJ { obj(part) } else { stl(part) };
            match r {
                Ok(m) => {
                    assert_valid(&m, &format!("{name} cut at {cut}"));
                    oks += 1;
                }
                Err(e) => {
                    expect_any_err(Err(e.clone()), name, &format!("{name} cut at {cut}"));
                    let lines = part.iter().filter(|&&b| b == b'\n').count() + 1;
                    assert!(
                        e.line <= lines,
                        "{name} cut at {cut}: line {} of {lines}: {e}",
                        e.line
                    );
                }
            }
        }
        // Only cuts in the final newline (OBJ) or the last line's name (STL) leave a mesh.
        assert!((1..=8).contains(&oks), "{name}: {oks} cuts parsed");
    }
}

#[test]
fn a_header_claiming_four_billion_triangles_allocates_nothing_large() {
    for count in [u32::MAX, 0x8000_0000, 1_000_000_000, 100_000_000, 13] {
        for (header, extra) in [
            (&b""[..], 0),
            (b"solid big", 0),
            (b"", 50),
            (b"solid", 50 * 12),
        ] {
            let mut bytes = header.to_vec();
            bytes.resize(80, 0);
            bytes.extend(count.to_le_bytes());
            bytes.extend(std::iter::repeat_n(0u8, extra));
            let what = format!("count {count}, {} bytes", bytes.len());
            let (r, largest) = largest_allocation(|| stl(&bytes));
            let e = expect_err(
                r,
                STL,
                0,
                &[
                    &format!("claims {count} triangles"),
                    &format!("has {} bytes", bytes.len()),
                ],
                &what,
            );
            assert!(
                largest < 4096,
                "{what}: allocated {largest} bytes at once ({e})"
            );
        }
    }
}

#[test]
fn random_garbage_is_an_error() {
    let mut rng = Lcg(0x6d65_7368_0000_0001);
    for n in 0..300 {
        let len = rng.below(4096) as usize;
        let bytes: Vec<u8> = (0..len).map(|_| rng.byte()).collect();
        let what = format!("garbage #{n} ({len} bytes)");
        expect_any_err(obj(&bytes), OBJ, &what);
        expect_any_err(stl(&bytes), STL, &what);
        // The same behind a "solid" header, and as text.
        let mut solid = b"solid ".to_vec();
        solid.extend(&bytes);
        expect_any_err(stl(&solid), STL, &what);
        let printable: Vec<u8> = bytes
            .iter()
            .map(|b| b" \nvf0123456789-/.#"[*b as usize % 18])
            .collect();
        if let Ok(m) = obj(&printable) {
            assert_valid(&m, &what);
        }
    }
}

#[test]
fn random_meshes_parse_only_to_valid_meshes() {
    // Tetrahedra over 4 of 5 points (no 4 coplanar), each triangle rotated at random, often
    // broken by one mutation; and triangles at random. Every result must be valid or an error.
    let mut rng = Lcg(7);
    let points = vec![
        Vec3::ZERO,
        Vec3::new(1.0, 0.0, 0.0),
        Vec3::new(0.0, 1.0, 0.0),
        Vec3::new(0.0, 0.0, 1.0),
        Vec3::new(1.0, 1.0, 1.0),
    ];
    let (mut oks, mut errors) = (0, 0);
    for n in 0..2000 {
        let what = format!("mesh #{n}");
        let mut m = TriMesh {
            vertices: points.clone(),
            triangles: vec![],
        };
        if rng.below(4) == 0 {
            for _ in 0..1 + rng.below(8) {
                m.triangles.push([0; 3].map(|_| rng.below(5) as u32));
            }
        } else {
            let skip = rng.below(5) as u32;
            let [a, b, c, d] = {
                let v: Vec<u32> = (0..5).filter(|&i| i != skip).collect();
                [v[0], v[1], v[2], v[3]]
            };
            m.triangles = vec![[a, b, c], [a, c, d], [a, d, b], [b, d, c]];
            for t in &mut m.triangles {
                t.rotate_left(rng.below(3) as usize);
            }
            let t = rng.below(4) as usize;
            match rng.below(8) {
                0 => m.triangles[t].swap(0, 1),
                1 => {
                    m.triangles.remove(t);
                }
                2 => m.triangles.push(m.triangles[t]),
                3 => m.triangles[t][rng.below(3) as usize] = rng.below(5) as u32,
                4 => m.triangles = m.triangles.iter().map(|&[a, b, c]| [a, c, b]).collect(),
                _ => {}
            }
        }
        for r in [
            obj(to_obj(&m).as_bytes()),
            stl(to_ascii_stl(&m, "soup").as_bytes()),
            stl(&to_binary_stl(&m, b"")),
        ] {
            match r {
                Ok(got) => {
                    assert_valid(&got, &what);
                    assert_eq!(got.triangles.len(), 4, "{what}");
                    oks += 1;
                }
                Err(e) => {
                    assert!(e.to_string().starts_with("hostile."), "{what}: {e}");
                    errors += 1;
                }
            }
        }
    }
    assert!(oks > 1000 && errors > 1000, "{oks} parsed, {errors} errors");
}

// ---------------------------------------------------------------------------------------------
// Sizes and layouts that could blow up.

#[test]
fn huge_and_tiny_coordinates() {
    let cube = cube();
    let at_scale = |s: f64| obj(to_obj(&scaled(&cube, s)).as_bytes());
    // Volumes up to about 10³⁰⁰ are measured.
    let v = at_scale(1e100).unwrap().volume();
    assert!((v / 1e300 - 1.0).abs() < 1e-12, "{v:e}");
    // Beyond, the volume overflows: an error, not an infinite volume.
    for s in [1e103, 1e150, 1e200, 1e300, f64::MAX] {
        let what = format!("scale {s:e}");
        if s == f64::MAX {
            // max − 0 is fine, but the cross products overflow.
            expect_any_err(at_scale(s), OBJ, &what);
        } else {
            expect_err(
                at_scale(s),
                OBJ,
                0,
                &["volume is not a finite number", "too large"],
                &what,
            );
        }
    }
    // Tiny: the cross products underflow (zero area), or the volume does.
    expect_err(
        at_scale(1e-200),
        OBJ,
        obj_face_line(&cube, 0),
        &["zero area"],
        "scale 1e-200",
    );
    expect_err(
        at_scale(1e-110),
        OBJ,
        0,
        &["encloses no volume"],
        "scale 1e-110",
    );
    assert!(at_scale(1e-100).unwrap().volume() > 0.0);
    // Subnormal and extreme but finite coordinates in binary.
    let mut bytes = to_binary_stl(&cube, b"");
    bytes[binary_offset(0, 0, 0)..][..4].copy_from_slice(&f32::MAX.to_le_bytes());
    expect_any_err(stl(&bytes), STL, "f32::MAX corner");
}

#[test]
fn long_tokens_are_shortened_and_control_bytes_escaped_in_messages() {
    let long = "9".repeat(100_000) + "x";
    let e = expect_err(
        obj(format!("v 0 0 {long}\n").as_bytes()),
        OBJ,
        1,
        &["…"],
        "long token",
    );
    assert!(
        e.message.len() < 300,
        "message is {} bytes",
        e.message.len()
    );
    let e = expect_err(
        obj(format!("{long}\n").as_bytes()),
        OBJ,
        1,
        &["unknown statement"],
        "long keyword",
    );
    assert!(
        e.message.len() < 300,
        "message is {} bytes",
        e.message.len()
    );
    let e = expect_err(
        stl(format!("solid x\nfacet normal 0 0 {long}\n").as_bytes()),
        STL,
        2,
        &["…"],
        "long STL token",
    );
    assert!(
        e.message.len() < 300,
        "message is {} bytes",
        e.message.len()
    );
    let e = expect_any_err(obj("v 0 0 ☃\u{202e}x\n".as_bytes()), OBJ, "unicode");
    assert!(e.message.is_ascii(), "{e}");
}

#[test]
fn large_inputs_stay_linear() {
    // A polygon of 200 000 vertices: fanned into 199 998 triangles, then found open.
    let n = 200_000;
    let mut text = String::new();
    for k in 0..n {
        let a = k as f64 / n as f64 * std::f64::consts::TAU;
        text.push_str(&format!("v {} {} 0\n", a.cos(), a.sin()));
    }
    text.push('f');
    for k in 1..=n {
        text.push_str(&format!(" {k}"));
    }
    text.push('\n');
    let e = expect_err(
        obj(text.as_bytes()),
        OBJ,
        n + 1,
        &["one triangle only"],
        "big polygon",
    );
    assert!(e.message.len() < 400);
    // The densest polygon: one triangle per 2 bytes.
    let mut dense =
        "v 0 0 1\nv 1 0 0\nv 0 1 0\nv 1 1 0\nv 2 0 0\nv 2 1 0\nv 3 0 0\nv 3 1 0\nv 4 0 0\nf 1"
            .to_string();
    for k in 0..300_000 {
        dense.push_str([" 2", " 3", " 4", " 5", " 6", " 7", " 8", " 9"][k % 8]);
    }
    expect_any_err(obj(dense.as_bytes()), OBJ, "dense polygon");
    // 100 000 continued lines make one statement.
    let continued = "v \\\n".to_string() + &"0 \\\n".repeat(100_000);
    expect_err(
        obj(continued.as_bytes()),
        OBJ,
        1,
        &["at most 7 numbers"],
        "continued",
    );
    // Many facets, all on one edge.
    let mut fan = cube();
    for k in 0..20_000 {
        fan.vertices.push(Vec3::new(0.5, -1.0 - k as f64, -1.0));
        fan.triangles.push([0, 1, 8 + k]);
    }
    let bytes = to_binary_stl(&fan, b"");
    expect_err(
        stl(&bytes),
        STL,
        0,
        &["shared by 20002 triangles", "and 19998 more"],
        "big fan",
    );
    // A big closed mesh reads, within the allocation bound.
    let big = torus(2.0, 0.5, 300, 100);
    assert_valid(&stl(&to_binary_stl(&big, b"")).unwrap(), "big torus");
    assert_valid(&obj(to_obj(&big).as_bytes()).unwrap(), "big torus");
}
