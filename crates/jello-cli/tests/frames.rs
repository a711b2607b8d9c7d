//! Frames written by `jello run --frames`, read back and checked against what they must be:
//! the surface mesh of the 8³ lattice (6 faces × 7 × 7 quads × 2 = 588 triangles, indices in
//! range, every edge shared by exactly two triangles, wound outward), the volume it encloses in
//! frame 0 equal to the initial cube's (divergence theorem over the triangles, computed here),
//! and the last frame equal to the `--save` state, bit for bit.
//!
//! Independent of the writer: the mesh is parsed from the files and measured in this file; the
//! expected volume is the cube's side cubed (`jello create --scale`), not anything the code
//! computes. Tolerance on the volume: 1e-12 relative (588 triple products of numbers below 2:
//! rounding ~1e-15; a missing, flipped or duplicated triangle changes it by ~1e-3 or more).

use std::collections::HashMap;
use std::fs;

use jello_core::{ReadOptions, Vec3, World};

mod common;

use common::TempDir;

impl TempDir {
    /// Runs `jello ARGS` in this folder; it must succeed.
    fn jello(&self, args: &[&str]) {
        self.succeeds(args);
    }

    fn text(&self, name: &str) -> String {
        fs::read_to_string(self.0.join(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
    }

    fn world(&self, name: &str) -> World {
        World::parse(self.text(name).as_bytes(), name, ReadOptions::default())
            .unwrap_or_else(|e| panic!("{e}"))
    }
}

/// A surface mesh read from a frame: vertices and triangles (0-based).
struct Mesh {
    vertices: Vec<Vec3>,
    triangles: Vec<[usize; 3]>,
}

fn number(s: &str) -> f64 {
    s.parse().unwrap_or_else(|e| panic!("{s:?}: {e}"))
}

fn vec3(words: &[&str]) -> Vec3 {
    assert_eq!(words.len(), 3, "{words:?}");
    Vec3::new(number(words[0]), number(words[1]), number(words[2]))
}

/// An ASCII PLY frame: the header's counts, then the vertices, then `3 a b c` faces.
fn read_ply(text: &str) -> Mesh {
    let (header, body) = text.split_once("end_header\n").expect("a PLY header");
    let count = |element: &str| -> usize {
        let line = header
            .lines()
            .find(|l| l.starts_with(&format!("element {element} ")))
            .unwrap_or_else(|| panic!("no element {element}"));
        line.split_whitespace().nth(2).unwrap().parse().unwrap()
    };
    let (nv, nf) = (count("vertex"), count("face"));
    let lines: Vec<&str> = body.lines().collect();
    assert_eq!(lines.len(), nv + nf, "body lines");
    let vertices = lines[..nv]
        .iter()
        .map(|l| vec3(&l.split(' ').collect::<Vec<_>>()))
        .collect();
    let triangles = lines[nv..]
        .iter()
        .map(|l| {
            let w: Vec<usize> = l.split(' ').map(|s| s.parse().unwrap()).collect();
            assert_eq!(w.len(), 4, "{l}");
            assert_eq!(w[0], 3, "{l}: not a triangle");
            [w[1], w[2], w[3]]
        })
        .collect();
    Mesh {
        vertices,
        triangles,
    }
}

/// A Wavefront OBJ frame: `v x y z` and `f a b c` (1-based).
fn read_obj(text: &str) -> Mesh {
    let (mut vertices, mut triangles) = (Vec::new(), Vec::new());
    let mut objects = Vec::new();
    for line in text.lines() {
        let w: Vec<&str> = line.split(' ').collect();
        match w[0] {
            "v" => vertices.push(vec3(&w[1..])),
            "o" => {
                // Each body's faces under its name, after all the vertices.
                assert!(
                    !vertices.is_empty(),
                    "{line}: an object before the vertices"
                );
                objects.push(w[1..].join(" "));
            }
            "f" => {
                assert_eq!(w.len(), 4, "{line}");
                let i = |s: &str| -> usize {
                    let i: usize = s.parse().unwrap();
                    assert!(i >= 1, "{line}: OBJ indices start at 1");
                    i - 1
                };
                triangles.push([i(w[1]), i(w[2]), i(w[3])]);
            }
            "#" => {}
            _ => panic!("unexpected OBJ line {line:?}"),
        }
    }
    assert!(
        !objects.is_empty() || triangles.is_empty(),
        "faces without an object"
    );
    Mesh {
        vertices,
        triangles,
    }
}

/// Positions and velocities of a CSV frame, checking the `body,i,j,k` columns against the row
/// order.
fn read_csv(text: &str) -> (Vec<Vec3>, Vec<Vec3>) {
    let mut lines = text.lines();
    assert_eq!(lines.next(), Some("body,i,j,k,x,y,z,vx,vy,vz"));
    let (mut pos, mut vel) = (Vec::new(), Vec::new());
    for (n, line) in lines.enumerate() {
        let w: Vec<&str> = line.split(',').collect();
        assert_eq!(w.len(), 10, "{line}");
        let ijk = [1, n / 64, (n / 8) % 8, n % 8].map(|c| c.to_string());
        assert_eq!(w[..4], ijk, "row {n}");
        pos.push(vec3(&w[4..7]));
        vel.push(vec3(&w[7..10]));
    }
    (pos, vel)
}

/// Volume enclosed by a closed triangle mesh wound outward: Σ a·(b × c) / 6.
fn volume(m: &Mesh) -> f64 {
    m.triangles
        .iter()
        .map(|&[a, b, c]| m.vertices[a].dot(m.vertices[b].cross(m.vertices[c])))
        .sum::<f64>()
        / 6.0
}

/// 588 triangles with indices in range, three distinct corners each, every edge in exactly two
/// triangles and used once in each direction (a closed, consistently wound surface), using exactly
/// the 8³ − 6³ = 296 surface points.
fn check_surface(m: &Mesh, what: &str) {
    assert_eq!(m.vertices.len(), 512, "{what}: vertices");
    assert_eq!(m.triangles.len(), 6 * 7 * 7 * 2, "{what}: triangles");
    let mut edges: HashMap<(usize, usize), usize> = HashMap::new();
    let mut used = vec![false; 512];
    for t in &m.triangles {
        assert!(
            t.iter().all(|&i| i < 512),
            "{what}: index out of range in {t:?}"
        );
        assert!(
            t[0] != t[1] && t[1] != t[2] && t[0] != t[2],
            "{what}: degenerate {t:?}"
        );
        for e in 0..3 {
            *edges.entry((t[e], t[(e + 1) % 3])).or_default() += 1;
            used[t[e]] = true;
        }
    }
    for (&(a, b), &n) in &edges {
        assert_eq!(n, 1, "{what}: directed edge {a}→{b} used {n} times");
        assert!(
            edges.contains_key(&(b, a)),
            "{what}: edge {a}→{b} has no twin"
        );
    }
    let surface = |p: usize| {
        let [i, j, k] = [p / 64, (p / 8) % 8, p % 8];
        [i, j, k].iter().any(|&c| c == 0 || c == 7)
    };
    for (p, &u) in used.iter().enumerate() {
        assert_eq!(u, surface(p), "{what}: point {p} used {u}");
    }
    assert_eq!(used.iter().filter(|&&u| u).count(), 296);
}

fn assert_bits_eq(a: &[Vec3], b: &[Vec3], what: &str) {
    assert_eq!(a.len(), b.len(), "{what}: count");
    for (n, (p, q)) in a.iter().zip(b).enumerate() {
        assert_eq!(
            p.to_array().map(f64::to_bits),
            q.to_array().map(f64::to_bits),
            "{what}: point {n}: {p:?} vs {q:?}"
        );
    }
}

/// An undeformed unit cube, and a cube of side 0.5 rotated and moved, both moving and falling:
/// for every format, frame 0 is the world's initial positions and (PLY, OBJ) encloses the
/// cube's volume; the last frame is the saved state.
#[test]
fn frames_mesh_volume_and_last_frame() {
    let t = TempDir::new("mesh");
    let (steps, every) = (60, 20);
    for (name, scale, extra) in [
        ("unit.w", 1.0, vec!["--velocity", "0.5,-0.25,1"]),
        (
            "turned.w",
            0.5,
            vec![
                "--scale",
                "0.5",
                "--rotate",
                "30,-20,45",
                "--offset",
                "-0.25,0.1,0.3",
                "--spin",
                "1,2,-3",
            ],
        ),
    ] {
        let mut args = vec!["create", name, "--field", "gravity"];
        args.extend(extra);
        t.jello(&args);
        let initial = t.world(name).positions;
        for format in ["ply", "obj", "csv"] {
            let dir = format!("{name}-{format}");
            let save = format!("{name}-{format}-saved.w");
            t.jello(&[
                "run",
                name,
                "--steps",
                &steps.to_string(),
                "--frames",
                &dir,
                "--every",
                &every.to_string(),
                "--format",
                format,
                "--save",
                &save,
                "-q",
            ]);
            let saved = t.world(&save);
            let frame = |n: usize| t.text(&format!("{dir}/frame_{n:06}.{format}"));
            let last = steps / every;
            let what = format!("{name}, {format}");
            if format == "csv" {
                let (first_pos, _) = read_csv(&frame(0));
                assert_bits_eq(&first_pos, &initial, &format!("{what}: frame 0"));
                let (pos, vel) = read_csv(&frame(last));
                assert_bits_eq(&pos, &saved.positions, &format!("{what}: last positions"));
                assert_bits_eq(&vel, &saved.velocities, &format!("{what}: last velocities"));
                continue;
            }
            let read = if format == "ply" { read_ply } else { read_obj };
            let first = read(&frame(0));
            check_surface(&first, &what);
            assert_bits_eq(&first.vertices, &initial, &format!("{what}: frame 0"));
            let v = volume(&first);
            let want = scale * scale * scale;
            assert!(
                (v - want).abs() <= 1e-12 * want,
                "{what}: frame 0 encloses {v} m³, the cube {want} m³"
            );
            let end = read(&frame(last));
            check_surface(&end, &what);
            assert_eq!(end.triangles, first.triangles, "{what}: the mesh changed");
            assert_bits_eq(
                &end.vertices,
                &saved.positions,
                &format!("{what}: last frame"),
            );
            // The cube moved: the last frame is not the first.
            assert_ne!(end.vertices, first.vertices, "{what}");
        }
    }
}

/// A body voxelised from a mesh keeps a whole lattice, whose points outside its cells never move:
/// CSV frames have a row for each active point only, as many as `jello info` counts, and every
/// row of the falling torus moves (a frozen placeholder row would stand still).
#[test]
fn csv_frames_of_a_mesh_body_have_its_active_points_only() {
    let t = TempDir::new("csv-active");
    let scene = concat!(env!("CARGO_MANIFEST_DIR"), "/../../examples/torus.toml");
    let info = t.succeeds(&["info", scene]);
    let line = info
        .lines()
        .find(|l| l.starts_with("body 1"))
        .unwrap_or_else(|| panic!("no body line in\n{info}"));
    let counted: usize = line
        .split(": ")
        .nth(1)
        .and_then(|rest| rest.split(" points").next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("no point count in {line:?}"));
    t.jello(&[
        "run", scene, "--steps", "20", "--every", "20", "--format", "csv", "--frames", "f", "-q",
    ]);
    let rows = |n: usize| -> Vec<(String, Vec3)> {
        t.text(&format!("f/frame_{n:06}.csv"))
            .lines()
            .skip(1)
            .map(|l| {
                let w: Vec<&str> = l.split(',').collect();
                (w[..4].join(","), vec3(&w[4..7]))
            })
            .collect()
    };
    let (first, last) = (rows(0), rows(1));
    assert_eq!(first.len(), counted, "rows of frame 0 against `jello info`");
    assert_eq!(last.len(), counted, "rows of frame 1 against `jello info`");
    for ((at, p0), (at1, p1)) in first.iter().zip(&last) {
        assert_eq!(at, at1);
        assert_ne!(p0, p1, "row {at} stood still while the torus fell");
    }
}
