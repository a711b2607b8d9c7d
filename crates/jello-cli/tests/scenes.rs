//! Scenes from the command line, as a user meets them: `jello create OUT.toml` from meshes the
//! project has never seen (a lumpy closed shape as binary STL), `jello run` with frames and a
//! saved end state, two stacked bodies, and every kind of bad input.

use std::fs;

use jello_core::{SceneFile, Vec3};

mod common;

use common::TempDir;

impl TempDir {
    /// Runs `jello ARGS`; it must succeed. Returns stdout.
    fn jello(&self, args: &[&str]) -> String {
        self.succeeds(args)
    }

    /// Runs `jello ARGS`; it must fail with `code` and a message holding `says`.
    fn fails(&self, args: &[&str], code: i32, says: &str) {
        let out = self.run(args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(
            out.status.code(),
            Some(code),
            "jello {}: {err}",
            args.join(" ")
        );
        assert!(
            err.contains(says),
            "jello {}: {err} lacks \"{says}\"",
            args.join(" ")
        );
    }

    fn scene(&self, name: &str) -> SceneFile {
        let bytes = fs::read(self.path(name)).unwrap();
        SceneFile::parse(&bytes, name).unwrap_or_else(|e| panic!("{e}"))
    }
}

/// A lumpy closed shape: a flattened sphere (a bumpy pancake, radius about 0.5, 0.3 thick) as a
/// UV mesh (poles welded), centred at `centre`; vertices as f32 (what binary STL holds).
fn lumpy(centre: Vec3) -> (Vec<Vec3>, Vec<[u32; 3]>) {
    let (rings, segments) = (10u32, 16u32);
    let radius = |t: f64, p: f64| 0.4 * (1.0 + 0.15 * (4.0 * p).sin() * (2.0 * t).sin());
    let mut v = vec![centre + Vec3::new(0.0, 0.0, 0.15)];
    for i in 1..rings {
        let t = std::f64::consts::PI * i as f64 / rings as f64;
        for j in 0..segments {
            let p = 2.0 * std::f64::consts::PI * j as f64 / segments as f64;
            let r = radius(t, p);
            v.push(
                centre
                    + Vec3::new(
                        1.25 * r * t.sin() * p.cos(),
                        1.25 * r * t.sin() * p.sin(),
                        0.375 * r * t.cos(),
                    ),
            );
        }
    }
    v.push(centre - Vec3::new(0.0, 0.0, 0.15));
    let v: Vec<Vec3> = v
        .into_iter()
        .map(|p| p.to_array().map(|c| c as f32 as f64))
        .map(Vec3::from_array)
        .collect();
    let ring = |i: u32, j: u32| 1 + (i - 1) * segments + j % segments;
    let south = v.len() as u32 - 1;
    let mut t = Vec::new();
    for j in 0..segments {
        t.push([0, ring(1, j), ring(1, j + 1)]);
        t.push([south, ring(rings - 1, j + 1), ring(rings - 1, j)]);
    }
    for i in 1..rings - 1 {
        for j in 0..segments {
            let (a, b, c, d) = (
                ring(i, j),
                ring(i + 1, j),
                ring(i + 1, j + 1),
                ring(i, j + 1),
            );
            t.push([a, b, c]);
            t.push([a, c, d]);
        }
    }
    (v, t)
}

fn binary_stl(v: &[Vec3], t: &[[u32; 3]]) -> Vec<u8> {
    let mut out = vec![0u8; 80];
    out.extend((t.len() as u32).to_le_bytes());
    for tri in t {
        out.extend([0u8; 12]);
        for &i in tri {
            for c in v[i as usize].to_array() {
                out.extend((c as f32).to_le_bytes());
            }
        }
        out.extend([0u8; 2]);
    }
    out
}

fn obj_vertices(text: &str) -> Vec<Vec3> {
    text.lines()
        .filter_map(|l| l.strip_prefix("v "))
        .map(|l| {
            let c: Vec<f64> = l.split(' ').map(|x| x.parse().unwrap()).collect();
            Vec3::new(c[0], c[1], c[2])
        })
        .collect()
}

/// A binary STL of a lumpy shape dropped on a sphere: the frames hold the mesh (its vertex and
/// triangle counts, its vertices at t = 0), the sphere holds it out, and friction keeps it on
/// top until it comes to rest.
#[test]
fn a_binary_stl_becomes_a_body_that_a_sphere_holds_out() {
    let t = TempDir::new("stl");
    let (vertices, triangles) = lumpy(Vec3::new(0.0, 0.0, 0.7));
    fs::write(t.path("lumpy.stl"), binary_stl(&vertices, &triangles)).unwrap();
    let created = t.jello(&[
        "create",
        "lumpy.toml",
        "--mesh",
        "lumpy.stl",
        "--cells",
        "10",
        "--density",
        "100",
        "--modulus",
        "20000",
        "--viscosity",
        "100",
        "--sphere",
        "0,0,0,0.3",
        "--gravity",
        "0,0,-9.81",
        "--k-collision",
        "5000",
        "--d-collision",
        "5",
        "--dt",
        "0.0002",
        "--integrator",
        "SymplecticEuler",
    ]);
    assert!(created.contains("wrote lumpy.toml: 1 body"), "{created}");
    let info = t.jello(&["info", "lumpy.toml"]);
    assert!(
        info.contains(&format!(
            "skin {} vertices, {} triangles",
            vertices.len(),
            triangles.len()
        )),
        "{info}"
    );
    t.jello(&[
        "run",
        "lumpy.toml",
        "--time",
        "6",
        "--frames",
        "frames",
        "--every",
        "10000",
        "--format",
        "obj",
        "--save",
        "end.toml",
        "-q",
    ]);
    let first = fs::read_to_string(t.path("frames/frame_000000.obj")).unwrap();
    let skin = obj_vertices(&first);
    assert_eq!(skin.len(), vertices.len());
    assert_eq!(
        first.lines().filter(|l| l.starts_with("f ")).count(),
        triangles.len()
    );
    // STL welds vertices in order of first appearance: compare as sets.
    for v in &vertices {
        let nearest = skin
            .iter()
            .map(|s| (*s - *v).length())
            .fold(f64::MAX, f64::min);
        assert!(nearest < 1e-12, "vertex {v:?} is {nearest} m from the skin");
    }
    // It fell onto the sphere and was held out of it: no point sank in by half a cell.
    let end = t.scene("end.toml");
    let state = end.bodies[0].state.as_ref().unwrap();
    let made = end.to_scene("end.toml").unwrap();
    let body = made.model.body(0);
    let deepest = (0..body.len())
        .filter(|&p| body.is_active(p))
        .map(|p| 0.3 - Vec3::from_array(state.positions[p]).length())
        .fold(f64::MIN, f64::max);
    assert!(
        deepest < 0.5 * body.min_spacing(),
        "sank {deepest} m into the sphere"
    );
    // And rests on it, held by friction (the scene's default μ = 0.5): on top, and still.
    let active: Vec<usize> = (0..body.len()).filter(|&p| body.is_active(p)).collect();
    let centre = active
        .iter()
        .map(|&p| Vec3::from_array(state.positions[p]))
        .fold(Vec3::ZERO, |s, p| s + p)
        / active.len() as f64;
    assert!(
        centre.z > 0.2 && centre.x.hypot(centre.y) < 0.1,
        "rests on top of the sphere: {centre:?}"
    );
    let fastest = active
        .iter()
        .map(|&p| Vec3::from_array(state.velocities[p]).length())
        .fold(0.0, f64::max);
    assert!(fastest < 0.05, "still moving at {fastest} m/s");
    let summary = t.jello(&["run", "lumpy.toml", "--time", "1", "-q"]);
    let penetration: f64 = summary
        .split("max penetration ")
        .nth(1)
        .and_then(|s| s.split(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap();
    // On impact, less than a cell.
    assert!(
        penetration > 0.0 && penetration < body.min_spacing(),
        "{summary}"
    );
}

/// Two cubes stacked on the floor: after 2 s the upper is still on top of the lower.
#[test]
fn the_upper_of_two_stacked_cubes_stays_on_top() {
    let t = TempDir::new("stack");
    t.jello(&[
        "create",
        "stack.toml",
        "--bounds",
        "-2,-2,0,2,2,4",
        "--gravity",
        "0,0,-9.81",
        "--k-collision",
        "2000",
        "--d-collision",
        "2",
        "--dt",
        "0.0002",
        "--cube",
        "5",
        "--size",
        "0.5",
        "--at",
        "0,0,0.25",
        "--total-mass",
        "1",
        "--k-elastic",
        "400",
        "--d-elastic",
        "1",
        "--cube",
        "5",
        "--size",
        "0.4",
        "--at",
        "0,0,0.9",
        "--total-mass",
        "0.5",
        "--k-elastic",
        "400",
        "--d-elastic",
        "1",
    ]);
    let scene = t.scene("stack.toml");
    assert_eq!(scene.bodies.len(), 2);
    assert_eq!(
        scene.bodies[1].total_mass,
        Some(0.5),
        "options apply to the body they follow"
    );
    t.jello(&[
        "run",
        "stack.toml",
        "--time",
        "2",
        "--save",
        "end.toml",
        "-q",
    ]);
    let end = t.scene("end.toml");
    let z = |b: usize| {
        end.bodies[b]
            .state
            .as_ref()
            .unwrap()
            .positions
            .iter()
            .map(|p| p[2])
    };
    let top_of_lower = z(0).fold(f64::MIN, f64::max);
    let bottom_of_upper = z(1).fold(f64::MAX, f64::min);
    // Skin on skin: neither a lattice spacing of air (0.1 m here) nor sunk in, a penalty
    // contact's overlap of well under a millimetre.
    let gap = bottom_of_upper - top_of_lower;
    assert!(
        gap.abs() < 0.005,
        "the upper body rests {gap} m above the lower"
    );
    let centre = |b: usize| z(b).sum::<f64>() / 125.0;
    assert!(centre(1) > top_of_lower, "the upper stays on top");
    assert!(
        z(0).fold(f64::MAX, f64::min) > -0.05,
        "the lower rests on the floor"
    );
    // Where the run's time went: the contacts between the two bodies are a part of it.
    let out = t.jello(&["run", "stack.toml", "--steps", "200", "--timings", "-q"]);
    let line = (out.lines())
        .find(|l| l.starts_with("timings: wall "))
        .unwrap_or_else(|| panic!("no timings in {out}"));
    let share: f64 = line
        .split_once(" s (")
        .and_then(|(_, rest)| rest.split_once(" %)"))
        .and_then(|(share, _)| share.parse().ok())
        .unwrap_or_else(|| panic!("no share of the contacts in {line}"));
    assert!(share > 0.0 && share < 100.0, "{line}");
    // And the contact passes' work, counted: 200 steps of RK4 are 800 passes.
    let work = (out.lines())
        .find(|l| l.starts_with("contact work: "))
        .unwrap_or_else(|| panic!("no contact work in {out}"));
    assert!(work.starts_with("contact work: 800 passes, "), "{work}");
}

#[test]
fn bad_scene_input_is_a_clear_error_and_leaves_no_file() {
    let t = TempDir::new("bad");
    // An open mesh: exit 1, naming the mesh file.
    fs::write(
        t.path("open.obj"),
        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 2 3\nf 1 2 4\nf 1 3 4\n",
    )
    .unwrap();
    t.fails(&["create", "x.toml", "--mesh", "open.obj"], 1, "open.obj");
    // Garbage and an STL header claiming four billion triangles.
    let mut huge = vec![0u8; 80];
    huge.extend(u32::MAX.to_le_bytes());
    fs::write(t.path("huge.stl"), huge).unwrap();
    t.fails(&["create", "x.toml", "--mesh", "huge.stl"], 1, "huge.stl");
    t.fails(
        &["create", "x.toml", "--mesh", "missing.obj"],
        1,
        "missing.obj",
    );
    // Per-body options must follow a body; scene options need a .toml output.
    t.fails(
        &["create", "x.toml", "--velocity", "1,0,0", "--cube", "3"],
        2,
        "comes before any --mesh or --cube",
    );
    t.fails(
        &["create", "x.toml", "--cube", "3", "--cells", "4"],
        2,
        "--cells is for a --mesh",
    );
    t.fails(
        &["create", "x.w", "--cube", "3"],
        2,
        "name the output file .toml",
    );
    // Bodies in each other, or outside the box.
    t.fails(
        &[
            "create", "x.toml", "--cube", "4", "--at", "0,0,0", "--cube", "4", "--at", "0.1,0,0",
        ],
        1,
        "body 1 (cube1) and body 2 (cube2) start inside each other",
    );
    t.fails(
        &["create", "x.toml", "--cube", "4", "--at", "1.9,0,0"],
        1,
        "outside the box",
    );
    assert!(!t.path("x.toml").exists() && !t.path("x.w").exists());
    // A scene with an unknown key, a wrong type, a missing field: file:line:column.
    let body = "[[body]]\ncube = { points = [3, 3, 3], size = [1.0, 1.0, 1.0] }\n";
    fs::write(t.path("unknown.toml"), format!("{body}colour = 1\n")).unwrap();
    t.fails(
        &["run", "unknown.toml", "--export", "u.glb"],
        1,
        "unknown.toml:3:1: unknown field `colour`",
    );
    fs::write(
        t.path("type.toml"),
        format!("[simulation]\ndt = \"x\"\n{body}"),
    )
    .unwrap();
    t.fails(&["info", "type.toml"], 1, "type.toml:2:6:");
    fs::write(
        t.path("missing.toml"),
        "[[body]]\ncube = { points = [3, 3, 3] }\n",
    )
    .unwrap();
    t.fails(
        &["run", "missing.toml"],
        1,
        "missing.toml:2:8: missing field `size`",
    );
    assert!(!t.path("u.glb").exists());
    // A world saves as .w, a scene as .toml.
    fs::write(t.path("ok.toml"), body).unwrap();
    t.fails(
        &["run", "ok.toml", "--steps", "1", "--save", "end.w"],
        1,
        "a scene saves as .toml",
    );
}

/// `jello shape` writes a mesh `jello create --mesh` takes, whose skin is that mesh; it keeps an
/// existing file unless told, and an unknown shape is a usage error.
#[test]
fn a_shape_becomes_a_scene_with_its_mesh_as_the_skin() {
    let dir = TempDir::new("shape");
    let said = dir.jello(&["shape", "torus", "ring.obj", "--detail", "4"]);
    assert!(said.contains("torus made by"), "{said}");
    let ring = fs::read_to_string(dir.path("ring.obj")).unwrap();
    assert_eq!(obj_vertices(&ring).len(), 16 * 8);
    dir.fails(&["shape", "torus", "ring.obj"], 1, "already exists");
    dir.fails(&["shape", "teapot", "t.obj"], 2, "torus");
    assert!(!dir.path("t.obj").exists());
    dir.jello(&["create", "ring.toml", "--mesh", "ring.obj", "--cells", "8"]);
    let info = dir.jello(&["info", "ring.toml"]);
    assert!(info.contains("skin 128 vertices, 256 triangles"), "{info}");
}

/// `jello info` shows a mesh body's own volume, and `--density` gives it that volume's mass: a
/// 0.3 × 0.5 × 0.7 m box in 3 cells along its length (2 × 3 × 3 cells of 0.233 m, 0.229 m³)
/// weighs 105 kg at 1000 kg/m³, its own 0.105 m³, not its cells' 229 kg.
#[test]
fn info_shows_a_mesh_bodys_volume_and_density_gives_its_mass() {
    let dir = TempDir::new("volume");
    let corners = |i: usize| {
        [
            0.3 * (i & 1) as f64,
            0.5 * ((i >> 1) & 1) as f64,
            0.7 * ((i >> 2) & 1) as f64,
        ]
    };
    let mut obj: String = (0..8)
        .map(|i| {
            let [x, y, z] = corners(i);
            format!("v {x} {y} {z}\n")
        })
        .collect();
    // The faces as quads, counter-clockwise seen from outside (vertex x + 2y + 4z, from 1).
    for [a, b, c, d] in [
        [1, 3, 4, 2],
        [5, 6, 8, 7],
        [1, 2, 6, 5],
        [3, 7, 8, 4],
        [1, 5, 7, 3],
        [2, 4, 8, 6],
    ] {
        obj.push_str(&format!("f {a} {b} {c} {d}\n"));
    }
    fs::write(dir.path("box.obj"), obj).unwrap();
    dir.jello(&[
        "create",
        "box.toml",
        "--mesh",
        "box.obj",
        "--cells",
        "3",
        "--density",
        "1000",
    ]);
    let info = dir.jello(&["info", "box.toml"]);
    assert!(
        info.contains("volume 0.105000 m³, mass 105.000000 kg"),
        "{info}"
    );
}

/// `--shake` moves a body's pins along a sine: the scene holds it and `jello run` follows it;
/// without `--pin` it is a usage error.
#[test]
fn pins_shake_from_the_command_line() {
    let dir = TempDir::new("shake");
    dir.jello(&[
        "create",
        "shake.toml",
        "--cube",
        "4",
        "--at",
        "0,0,0",
        "--pin",
        "0,0,0.5,0.3",
        "--shake",
        "0.1,0,0,2",
        "--gravity",
        "0,0,0",
    ]);
    let scene = dir.scene("shake.toml");
    let shake = scene.bodies[0].pins[0].shake.expect("the pin shakes");
    assert_eq!((shake.amplitude, shake.frequency), ([0.1, 0.0, 0.0], 2.0));
    // A quarter period: the top has moved by the amplitude.
    dir.jello(&[
        "run",
        "shake.toml",
        "--time",
        "0.125",
        "--save",
        "end.toml",
        "-q",
    ]);
    let end = dir.scene("end.toml");
    let made = end.to_scene("end.toml").unwrap();
    let p = made.model.pin_motions[0].points[0] as usize;
    let start = scene.to_scene("shake.toml").unwrap().state.pos[p];
    let moved = made.state.pos[p] - start;
    assert!(
        (moved - Vec3::new(0.1, 0.0, 0.0)).max_abs() < 1e-9,
        "{moved:?}"
    );
    dir.fails(
        &["create", "s.toml", "--cube", "4", "--shake", "0.1,0,0,2"],
        2,
        "no --pin",
    );
    dir.fails(
        &[
            "create",
            "s.toml",
            "--cube",
            "4",
            "--pin",
            "0,0,0,0.3",
            "--shake",
            "0.1,0,0,0",
        ],
        1,
        "frequency above 0",
    );
    assert!(!dir.path("s.toml").exists());
}

/// `--region` gives a box of springs factors on stiffness, damping and rest length: the scene
/// holds them per body, `jello info` reports them, and bad regions are usage errors or clear
/// input errors that leave no file.
#[test]
fn regions_of_springs_from_the_command_line() {
    let dir = TempDir::new("region");
    dir.jello(&[
        "create",
        "strip.toml",
        "--cube",
        "5",
        "--size",
        "1",
        "--at",
        "0,0,0",
        "--region",
        "-0.5,-0.5,0,0.5,0.5,0.5,rest=0.9,stiffness=2",
        "--region",
        "-0.5,-0.5,-0.5,0,0.5,0.5,damping=3",
        "--cube",
        "3",
        "--size",
        "0.4",
        "--at",
        "0,0,1.2",
    ]);
    let scene = dir.scene("strip.toml");
    let regions = &scene.bodies[0].region;
    assert_eq!(regions.len(), 2);
    assert_eq!(
        (
            regions[0].min,
            regions[0].max,
            regions[0].rest,
            regions[0].stiffness
        ),
        ([-0.5, -0.5, 0.0], [0.5, 0.5, 0.5], 0.9, 2.0)
    );
    assert_eq!((regions[1].damping, regions[1].rest), (3.0, 1.0));
    assert!(scene.bodies[1].region.is_empty());
    let info = dir.jello(&["info", "strip.toml"]);
    // The springs of a box of points are those of its own lattice: the first region holds the
    // upper three of five planes (5 × 5 × 3 points), the second the three lower planes in x.
    let springs = |counts| {
        jello_core::Lattice::new(counts, Vec3::new(1.0, 1.0, 1.0))
            .spring_count_by_kind()
            .iter()
            .sum::<usize>()
    };
    let scaled = springs([5, 5, 3]) + springs([3, 5, 5]) - springs([3, 5, 3]);
    assert!(
        info.contains(&format!(
            "{scaled} springs with their own values: stiffness ×1 to ×2, damping ×1 to ×3, \
             rest length ×0.9 to ×1"
        )),
        "{info}"
    );
    assert_eq!(info.matches("with their own values").count(), 1, "{info}");

    for (region, says) in [
        ("0,0,0,1,1,1", "at least one"),
        ("0,0,0,1,1,1,hardness=2", "unknown factor \"hardness\""),
        (
            "0,0,0,1,1,1,rest=-1",
            "rest length factor must be finite and positive",
        ),
    ] {
        dir.fails(
            &["create", "s.toml", "--cube", "4", "--region", region],
            2,
            says,
        );
    }
    dir.fails(
        &[
            "create",
            "s.toml",
            "--region",
            "0,0,0,1,1,1,rest=2",
            "--cube",
            "4",
        ],
        2,
        "comes before any --mesh or --cube",
    );
    dir.fails(
        &[
            "create",
            "s.toml",
            "--cube",
            "4",
            "--region",
            "5,5,5,6,6,6,rest=2",
        ],
        1,
        "region 1: no spring has both ends in",
    );
    assert!(!dir.path("s.toml").exists());
}

/// Writes `c.toml`: a 3³ cube stepped by backward Euler at 0.01 s.
fn implicit_cube(t: &TempDir) {
    t.jello(&[
        "create",
        "c.toml",
        "--cube",
        "3",
        "--integrator",
        "BackwardEuler",
        "--dt",
        "0.01",
    ]);
}

/// `--cutbacks` on a scene: saved into the scene's `[simulation]`, and the saved value is what a
/// later run of that file uses when the flag is not given; refused for an explicit integrator.
#[test]
fn cutbacks_given_to_a_scene_run_are_saved_and_kept() {
    let t = TempDir::new("cutbacks");
    implicit_cube(&t);
    assert_eq!(t.scene("c.toml").simulation.cutbacks, 6);
    t.jello(&[
        "run",
        "c.toml",
        "--steps",
        "2",
        "--cutbacks",
        "0",
        "--save",
        "a.toml",
        "-q",
    ]);
    assert_eq!(t.scene("a.toml").simulation.cutbacks, 0);
    t.jello(&["run", "a.toml", "--steps", "2", "--save", "b.toml", "-q"]);
    assert_eq!(t.scene("b.toml").simulation.cutbacks, 0);
    t.jello(&[
        "run",
        "b.toml",
        "--steps",
        "2",
        "--cutbacks",
        "3",
        "--save",
        "c2.toml",
        "-q",
    ]);
    assert_eq!(t.scene("c2.toml").simulation.cutbacks, 3);
    // Only implicit methods cut steps back: refused for an explicit one, nothing saved.
    t.fails(
        &[
            "run",
            "c.toml",
            "--steps",
            "2",
            "--integrator",
            "RK4",
            "--cutbacks",
            "3",
            "--save",
            "e.toml",
        ],
        2,
        "--cutbacks: RK4 is explicit",
    );
    assert!(!t.path("e.toml").exists());
}

/// `--tolerance` on a scene: saved into the scene's `[simulation]` and kept by a later run of
/// that file; refused (exit 2, nothing saved) for an explicit integrator and outside (0, 0.1].
#[test]
fn tolerance_given_to_a_scene_run_is_saved_and_kept() {
    let t = TempDir::new("tolerance");
    implicit_cube(&t);
    assert_eq!(t.scene("c.toml").simulation.tolerance, 1e-9);
    let run = ["run", "c.toml", "--steps", "2", "-q"];
    t.jello(&[&run[..], &["--tolerance", "1e-5", "--save", "a.toml"]].concat());
    assert_eq!(t.scene("a.toml").simulation.tolerance, 1e-5);
    t.jello(&["run", "a.toml", "--steps", "2", "--save", "b.toml", "-q"]);
    assert_eq!(t.scene("b.toml").simulation.tolerance, 1e-5);
    for bad in ["0", "-1e-6", "0.2", "nan"] {
        let flag = format!("--tolerance={bad}");
        t.fails(&[&run[..], &[&flag]].concat(), 2, "at most 0.1 m/s");
    }
    t.fails(
        &[
            &run[..],
            &[
                "--tolerance",
                "1e-5",
                "--integrator",
                "RK4",
                "--save",
                "e.toml",
            ],
        ]
        .concat(),
        2,
        "--tolerance: RK4 is explicit",
    );
    assert!(!t.path("e.toml").exists());
}

/// `jello create` writes `--tolerance` and `--cutbacks` into a scene's `[simulation]`, where a
/// run takes them; it refuses them for an explicit integrator, out of range, and for a `.w`
/// world (which has no place for them), writing nothing.
#[test]
fn create_writes_the_tolerance_and_cutbacks_of_a_scene() {
    let t = TempDir::new("create-tolerance");
    let cube = [
        "create",
        "c.toml",
        "--cube",
        "3",
        "--integrator",
        "SDIRK2",
        "--dt",
        "0.01",
    ];
    t.jello(&[&cube[..], &["--tolerance", "1e-4", "--cutbacks", "2"]].concat());
    let scene = t.scene("c.toml");
    assert_eq!(scene.simulation.tolerance, 1e-4);
    assert_eq!(scene.simulation.cutbacks, 2);
    let text = fs::read_to_string(t.path("c.toml")).unwrap();
    assert!(text.contains("tolerance = 0.0001"), "{text}");
    assert!(text.contains("cutbacks = 2"), "{text}");
    // A run of the file keeps them (and saves them again).
    t.jello(&["run", "c.toml", "--steps", "2", "--save", "d.toml", "-q"]);
    let saved = t.scene("d.toml");
    assert_eq!(saved.simulation.tolerance, 1e-4);
    assert_eq!(saved.simulation.cutbacks, 2);

    let refused: [(&[&str], &str); 5] = [
        (
            &["create", "e.toml", "--cube", "3", "--tolerance", "1e-4"],
            "--tolerance: RK4 is explicit",
        ),
        (
            &["create", "e.toml", "--cube", "3", "--cutbacks", "2"],
            "--cutbacks: RK4 is explicit",
        ),
        (
            &["create", "e.toml", "--cube", "3", "--tolerance", "0.5"],
            "at most 0.1 m/s",
        ),
        (
            &["create", "e.toml", "--cube", "3", "--cutbacks", "21"],
            "--cutbacks",
        ),
        (
            &[
                "create",
                "e.w",
                "--integrator",
                "BackwardEuler",
                "--tolerance",
                "1e-4",
            ],
            "--tolerance makes a scene",
        ),
    ];
    for (args, message) in refused {
        t.fails(args, 2, message);
    }
    assert!(!t.path("e.toml").exists() && !t.path("e.w").exists());
}

/// One name per quantity (docs/scenes.md): the canonical options and their older names write the
/// same scene, and a scene file that leaves gravity out falls as `jello create`'s default does.
#[test]
fn older_option_names_are_aliases_of_the_canonical_ones() {
    let t = TempDir::new("aliases");
    t.jello(&[
        "create",
        "new.toml",
        "--cube",
        "3",
        "--centre",
        "0,0,0.5",
        "--rotation",
        "0,0,30",
        "--stiffness",
        "300",
        "--damping",
        "0.5",
        "--collision-stiffness",
        "900",
        "--collision-damping",
        "0.7",
    ]);
    t.jello(&[
        "create",
        "old.toml",
        "--cube",
        "3",
        "--at",
        "0,0,0.5",
        "--rotate",
        "0,0,30",
        "--k-elastic",
        "300",
        "--d-elastic",
        "0.5",
        "--k-collision",
        "900",
        "--d-collision",
        "0.7",
    ]);
    assert_eq!(
        fs::read_to_string(t.path("new.toml")).unwrap(),
        fs::read_to_string(t.path("old.toml")).unwrap()
    );
    let written = t.scene("new.toml");
    assert_eq!(written.simulation.gravity, Some([0.0, 0.0, -9.81]));
    // Left out of a file: the same default.
    let mut bare = written.clone();
    bare.simulation.gravity = None;
    assert_eq!(bare.gravity(), [0.0, 0.0, -9.81]);
}
