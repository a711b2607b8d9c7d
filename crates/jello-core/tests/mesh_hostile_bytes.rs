//! Hostile input for the mesh readers, bytes that are not a mesh: non-finite and malformed
//! numbers, indices out of range, invalid UTF-8 and control characters, files cut at every
//! length, headers that lie about their size, garbage, huge and tiny coordinates: each an error
//! naming the file and the line (or, in binary STL, the triangle), never a panic, a hang or an
//! allocation beyond a bound linear in the input. Shapes that are not solids are in
//! `mesh_hostile.rs`.

#[path = "common/alloc_watch.rs"]
mod alloc_watch;
#[path = "common/hostile_mesh.rs"]
mod hostile;
#[path = "common/meshes.rs"]
mod meshes;

use alloc_watch::largest_allocation;
use hostile::*;
use jello_core::{TriMesh, Vec3};
use meshes::*;

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

/// Large inputs (a polygon of 200 000 vertices, the densest polygon, 100 000 continued lines, a
/// fan of 20 000 facets on one edge, a torus of 60 000 triangles) are refused at the right line
/// or read, each within the allocation bound linear in its size that every read here is held to
/// ([`ALLOCATION_PER_BYTE`] per byte). What is checked is memory, not time: no test measures time
/// (a reader gone quadratic on these sizes would show as a test running for minutes).
#[test]
fn large_inputs_are_read_within_the_allocation_bound() {
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
