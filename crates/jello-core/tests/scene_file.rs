//! Scene files: what they read, what they write back, and the error for each kind of bad input
//! (file, line, column).

#[path = "common/meshes.rs"]
mod meshes;

use jello_core::formats::scene::{BodySpec, CubeSpec, MeshSpec, ObstacleSpec, PinSpec, ShakeSpec};
use jello_core::model::body::rotation_xyz;
use jello_core::surface::{CageVertices, Surface};
use jello_core::{SceneFile, Vec3};
use meshes::torus;

fn torus_spec(cells: usize) -> BodySpec {
    let mesh = torus(0.5, 0.2, 24, 12);
    BodySpec {
        name: Some("ring".into()),
        mesh: Some(MeshSpec {
            cells,
            vertices: mesh.vertices.iter().map(|v| v.to_array()).collect(),
            triangles: mesh.triangles.clone(),
        }),
        ..BodySpec::default()
    }
}

fn cube_spec(n: usize, side: f64, centre: [f64; 3]) -> BodySpec {
    BodySpec {
        cube: Some(CubeSpec {
            points: [n; 3],
            size: [side; 3],
        }),
        centre: Some(centre),
        ..BodySpec::default()
    }
}

fn parse(text: &str) -> Result<SceneFile, jello_core::SceneError> {
    SceneFile::parse(text.as_bytes(), "s.toml")
}

#[test]
fn a_scene_writes_and_reads_back_the_same() {
    let mut ring = torus_spec(8);
    ring.centre = Some([0.0, 0.0, 1.0]);
    ring.rotation = Some([90.0, 0.0, 15.0]);
    ring.spin = Some([0.0, 0.0, 2.0]);
    ring.density = Some(300.0);
    ring.modulus = Some(5000.0);
    ring.pins = vec![PinSpec {
        at: [0.0, 0.0, 1.7],
        radius: 0.0,
        ..PinSpec::default()
    }];
    let mut scene = SceneFile::new(vec![ring, cube_spec(4, 0.5, [0.0, 0.0, -1.0])]);
    scene.simulation.gravity = Some([0.0, 0.0, -9.81]);
    scene.obstacles.push(ObstacleSpec::Sphere {
        centre: [1.5, 1.5, 1.5],
        radius: 0.25,
    });
    let text = scene.to_toml();
    assert_eq!(parse(&text).unwrap(), scene);
    let made = scene.to_scene("s.toml").unwrap();
    assert_eq!(made.model.bodies().len(), 2);
    assert_eq!(made.model.pins.len(), 1);
    assert_eq!(made.names, ["ring", "body2"]);
    // A run's end saved into the scene reads back as that state.
    let saved = scene.with_state(&made.model, &made.state).to_toml();
    let again = parse(&saved).unwrap().to_scene("s.toml").unwrap();
    assert_eq!(again.state.pos, made.state.pos);
    assert_eq!(again.state.vel, made.state.vel);
}

/// `[simulation] cutbacks` reaches the model, is written only when not the default, and a run's
/// end saved keeps the model's; more than the core allows is an error naming the key, and a
/// negative count is a wrong type at its line.
#[test]
fn cutbacks_read_write_and_check() {
    let cube = "[[body]]\ncube = { points = [3, 3, 3], size = [1.0, 1.0, 1.0] }\n";
    let read = |text: &str| parse(text).unwrap().to_scene("s.toml").unwrap();
    assert_eq!(read(cube).model.newton.cutbacks, 6);
    let file = parse(&format!("[simulation]\ncutbacks = 2\n{cube}")).unwrap();
    let scene = file.to_scene("s.toml").unwrap();
    assert_eq!(scene.model.newton.cutbacks, 2);
    assert!(file.to_toml().contains("cutbacks = 2"));
    assert!(!parse(cube).unwrap().to_toml().contains("cutbacks"));
    let mut model = scene.model.clone();
    model.newton.cutbacks = 0;
    let saved = file.with_state(&model, &scene.state).to_toml();
    assert_eq!(read(&saved).model.newton.cutbacks, 0);
    assert_error(
        &format!("[simulation]\ncutbacks = 21\n{cube}"),
        2,
        0,
        "[simulation] cutbacks must be at most 20 (got 21)",
    );
    assert_error(
        &format!("[simulation]\ncutbacks = -1\n{cube}"),
        2,
        12,
        "invalid value",
    );
}

/// `[simulation] tolerance` reaches the model, is written only when not the default, and a run's
/// end saved keeps the model's; zero, a negative or a tolerance above the core's limit is an
/// error naming the key.
#[test]
fn tolerance_read_write_and_check() {
    let cube = "[[body]]\ncube = { points = [3, 3, 3], size = [1.0, 1.0, 1.0] }\n";
    let read = |text: &str| parse(text).unwrap().to_scene("s.toml").unwrap();
    assert_eq!(read(cube).model.newton.tolerance, 1e-9);
    let file = parse(&format!("[simulation]\ntolerance = 1e-5\n{cube}")).unwrap();
    let scene = file.to_scene("s.toml").unwrap();
    assert_eq!(scene.model.newton.tolerance, 1e-5);
    assert!(file.to_toml().contains("tolerance = "));
    assert_eq!(read(&file.to_toml()).model.newton.tolerance, 1e-5);
    assert!(!parse(cube).unwrap().to_toml().contains("tolerance"));
    let mut model = scene.model.clone();
    model.newton.tolerance = 2e-7;
    let saved = file.with_state(&model, &scene.state).to_toml();
    assert_eq!(read(&saved).model.newton.tolerance, 2e-7);
    for bad in ["0.0", "-1e-6", "0.5", "nan"] {
        assert_error(
            &format!("[simulation]\ntolerance = {bad}\n{cube}"),
            2,
            0,
            "[simulation] tolerance must be a number above 0 and at most 0.1 m/s",
        );
    }
}

/// A shaken pin and a pin on a path read and write back; the scene starts them at their path's
/// velocity, and a run's end saved into the scene carries its time, so the pins resume in step.
#[test]
fn moving_pins_read_back_and_resume_in_step() {
    let mut cube = cube_spec(4, 0.6, [0.0, 0.0, 0.0]);
    cube.pins = vec![
        PinSpec {
            at: [0.3, 0.3, 0.3],
            radius: 0.05,
            shake: Some(ShakeSpec {
                amplitude: [0.0, 0.1, 0.0],
                frequency: 3.0,
            }),
            path: None,
        },
        PinSpec {
            at: [-0.3, -0.3, -0.3],
            radius: 0.0,
            shake: None,
            path: Some(vec![[0.0, 0.0, 0.0, 0.0], [1.0, 0.0, 0.0, 0.4]]),
        },
    ];
    let scene = SceneFile::new(vec![cube]);
    let text = scene.to_toml();
    assert!(text.contains("shake") && text.contains("path"), "{text}");
    assert_eq!(parse(&text).unwrap(), scene);
    let made = scene.to_scene("s.toml").unwrap();
    assert_eq!(made.model.pin_motions.len(), 2);
    let shaken = made.model.pin_motions[0].points[0] as usize;
    let w = std::f64::consts::TAU * 3.0;
    assert_eq!(made.state.vel[shaken], Vec3::new(0.0, 0.1 * w, 0.0));

    let mut sim = jello_core::Simulation::new(made.model.clone(), made.state.clone());
    sim.advance(700).unwrap();
    let saved = parse(&scene.with_state(&sim.model, &sim.state).to_toml()).unwrap();
    assert_eq!(saved.simulation.time, sim.state.time);
    let resumed = saved.to_scene("s.toml").unwrap();
    assert_eq!(resumed.state.time, sim.state.time);
    let mut again = jello_core::Simulation::new(resumed.model, resumed.state);
    sim.advance(300).unwrap();
    again.advance(300).unwrap();
    assert_eq!(
        again.state.pos, sim.state.pos,
        "the resumed run is the same run"
    );

    // Both a shake and a path on one pin, or a path going back in time: errors on the body.
    let mut both = scene.clone();
    both.bodies[0].pins[0].path = Some(vec![[0.0; 4]]);
    let e = both.to_scene("s.toml").unwrap_err().to_string();
    assert!(e.contains("pin 1: give a shake or a path, not both"), "{e}");
    let mut backwards = scene.clone();
    backwards.bodies[0].pins[1].path = Some(vec![[1.0, 0.0, 0.0, 0.0], [0.5, 0.0, 0.0, 0.0]]);
    let e = backwards.to_scene("s.toml").unwrap_err().to_string();
    assert!(
        e.contains("pin 2: path keyframe times must increase"),
        "{e}"
    );
}

/// The skin of a placed and turned mesh body reproduces the mesh, placed and turned, at rest.
#[test]
fn the_skin_reproduces_the_placed_mesh_at_rest() {
    let mesh = torus(0.5, 0.2, 24, 12);
    for (centre, rotation) in [
        (None, None),
        (Some([0.3, -0.2, 0.9]), Some([30.0, -45.0, 60.0])),
    ] {
        let mut ring = torus_spec(9);
        ring.centre = centre;
        ring.rotation = rotation;
        let scene = SceneFile::new(vec![ring]);
        let made = scene.to_scene("s.toml").unwrap();
        let surface = Surface::new(&made.model, CageVertices::Used);
        assert_eq!(surface.vertex_count(), mesh.vertices.len());
        assert_eq!(surface.triangles(), &mesh.triangles[..]);
        let mut skin = Vec::new();
        surface.positions(&made.model, &made.state, &mut skin);
        // The same rigid motion of the mesh: turned by `rotation` (x, then y, then z: tested in
        // placement.rs) about the middle of the mesh's bounding box, which goes to `centre`
        // (not the lattice's, which reaches past the mesh to whole cells).
        let r = rotation_xyz(rotation.unwrap_or([0.0; 3]));
        let (lo, hi) = mesh.bounds();
        let middle = (lo + hi) * 0.5;
        let centre = centre.map_or(middle, |c| Vec3::new(c[0], c[1], c[2]));
        for (s, &v) in skin.iter().zip(&mesh.vertices) {
            let d = v - middle;
            let want = centre + Vec3::new(r[0].dot(d), r[1].dot(d), r[2].dot(d));
            assert!((*s - want).max_abs() < 1e-12, "{s:?} vs {want:?}");
        }
    }
}

/// A bilayer strip: the top layer's springs shorter at rest than the bottom's. The region holds
/// exactly the springs with both ends in it, the scene reads back the same, and the free strip
/// curls with its ends rising toward the shorter side, about as far as Timoshenko's bimetal
/// gives for a continuum: two equal layers of thickness h/2 and a mismatch ε curl with curvature
/// κ = 3ε/(2h) (here 0.375 /m), so a strip of length L rises by about L²κ/8 = 0.12 m at its ends.
/// (The lattice is no continuum: its mid-plane springs belong to the short layer, and its shear
/// and bend springs add their own stiffness: it settles at 0.0958 m.)
#[test]
fn a_region_of_shorter_springs_curls_a_strip() {
    let text = "[simulation]\ndt = 0.0005\n\
                [[body]]\ncube = { points = [17, 3, 5], size = [1.6, 0.2, 0.4] }\n\
                centre = [0.0, 0.0, 0.0]\nmass = 0.01\ndamping = [2.0, 2.0, 2.0]\n\
                [[body.region]]\nmin = [-0.8, -0.1, 0.0]\nmax = [0.8, 0.1, 0.2]\nrest = 0.9\n";
    let file = parse(text).unwrap();
    assert_eq!(parse(&file.to_toml()).unwrap(), file);
    let scene = file.to_scene("s.toml").unwrap();
    let body = scene.model.body(0);
    let rest = body.rest_positions();
    let plain = jello_core::Body::lattice_box(body.lattice().clone(), body.material);
    let mut lattice_rest = Vec::new();
    plain.for_each_spring(|s| lattice_rest.push(s.rest));
    let mut n = 0;
    let mut in_region = 0;
    body.for_each_spring(|s| {
        let upper = rest[s.a].z >= -1e-12 && rest[s.b].z >= -1e-12;
        let want = if upper {
            0.9 * lattice_rest[n]
        } else {
            lattice_rest[n]
        };
        assert_eq!(s.rest, want, "{s:?}");
        in_region += upper as usize;
        n += 1;
    });
    // The top three of five layers: 17 × 3 × 3 points.
    assert_eq!(
        in_region,
        jello_core::Body::lattice_box(
            jello_core::Lattice::new([17, 3, 3], Vec3::new(1.6, 0.2, 0.2)),
            body.material,
        )
        .spring_count()
    );
    let mut state = scene.state.clone();
    let mut scratch = jello_core::Scratch::new(&scene.model);
    for _ in 0..4000 {
        jello_core::step(
            &scene.model,
            &mut state,
            &jello_core::Control::none(),
            &mut scratch,
        )
        .unwrap();
    }
    let z = |i: usize| {
        let p = body.lattice().index(i, 1, 2);
        state.pos[body.points().start + p].z
    };
    let rise = 0.5 * (z(0) + z(16)) - z(8);
    let timoshenko = 1.6f64.powi(2) * (3.0 * 0.1 / (2.0 * 0.4)) / 8.0;
    assert!(
        (rise / timoshenko - 1.0).abs() < 0.3,
        "the ends rise toward the short side by {rise} m, Timoshenko {timoshenko} m"
    );
}

/// One hostile scene: the error's line and column, and a piece of its message.
fn assert_error(text: &str, line: usize, column: usize, says: &str) {
    let e = parse(text)
        .and_then(|s| s.to_scene("s.toml").map(|_| s))
        .expect_err(text);
    assert_eq!((e.line, e.column), (line, column), "{e}");
    assert!(e.to_string().starts_with("s.toml"), "{e}");
    assert!(e.message.contains(says), "{e} lacks \"{says}\"");
}

#[test]
fn bad_scenes_are_errors_naming_the_line_and_column() {
    let cube = "[[body]]\ncube = { points = [3, 3, 3], size = [1.0, 1.0, 1.0] }\n";
    // Unknown key, wrong type, missing field.
    assert_error(
        &format!("{cube}colour = \"red\"\n"),
        3,
        1,
        "unknown field `colour`",
    );
    assert_error(
        "[simulation]\ndt = \"fast\"\n[[body]]\ncube = { points = [3, 3, 3], size = [1.0, 1.0, 1.0] }\n",
        2,
        6,
        "invalid type",
    );
    assert_error(
        "[[body]]\ncube = { points = [3, 3, 3] }\n",
        2,
        8,
        "missing field `size`",
    );
    assert_error(
        "[simulation]\ndt = 0.001\n",
        0,
        0,
        "expected at least one [[body]]",
    );
    assert_error("[[body]]\nname = \"x\"\n", 1, 0, "expected a shape");
    assert_error(
        &format!("[simulation]\nintegrator = \"Verlet\"\n{cube}"),
        2,
        0,
        "unknown integrator \"Verlet\"; known integrators: Euler, RK2",
    );
    assert_error(
        &format!("{cube}mass = -1.0\n"),
        3,
        0,
        "body 1: mass must be a finite number above 0 (got -1)",
    );
    assert_error("[[body]\n", 1, 8, "expected `]`");
    // A mesh that is not closed.
    assert_error(
        "[[body]]\nmesh = { cells = 3, vertices = [[0,0,0],[1,0,0],[0,1,0]], triangles = [[0,1,2]] }\n",
        2,
        0,
        "s.toml: mesh",
    );
    // Bodies that start in each other, outside the box, or in an obstacle.
    let two = format!("{cube}centre = [0.0, 0.0, 0.0]\n{cube}centre = [0.2, 0.0, 0.0]\n");
    assert_error(
        &two,
        1,
        0,
        "body 1 (body1) and body 2 (body2) start inside each other: their surfaces overlap by \
         2.500e-1 m near (0.25, -0.25, -0.25); move them apart",
    );
    assert_error(
        &format!("{cube}centre = [1.9, 0.0, 0.0]\n"),
        1,
        0,
        "body 1 (body1) starts outside the box (a point at (2.4, -0.5, -0.5) is outside (-2, -2, \
         -2) to (2, 2, 2), by 4.000e-1 m)",
    );
    assert_error(
        &format!("[[obstacle]]\ntype = \"sphere\"\ncentre = [0.5, 0.5, 0.5]\nradius = 0.2\n{cube}"),
        5,
        0,
        "body 1 (body1) starts inside obstacle 1 (a point at (0.5, 0.5, 0.5), 2.000e-1 m deep)",
    );
    assert_error(
        &format!("{cube}pins = [{{ at = [5.0, 5.0, 5.0], radius = 0.1 }}]\n"),
        3,
        0,
        "pin 1 holds no point (none within 0.1 m of (5, 5, 5))",
    );
    assert_error(
        &format!("[collision]\nfriction = -0.5\n{cube}"),
        2,
        0,
        "[collision] friction must be a finite number ≥ 0",
    );
    assert_error(
        &format!("{cube}pins = [{{ at = [0.5, 0.5, 0.5], radius = 0.0, shake = {{ amplitude = [0.1, 0.0, 0.0], frequency = -2.0 }} }}]\n"),
        3,
        0,
        "pin 1: a shake needs a finite amplitude and a finite frequency above 0",
    );
    // Regions of springs: an empty box, corners the wrong way round, a bad factor, a stray key.
    let region = |body: &str| format!("{cube}[[body.region]]\n{body}");
    assert_error(
        &region("min = [2.0, 2.0, 2.0]\nmax = [3.0, 3.0, 3.0]\nstiffness = 2.0\n"),
        3,
        0,
        "region 1: no spring has both ends in (2, 2, 2) to (3, 3, 3) (the body rests within (0, 0, 0) to (1, 1, 1) as placed)",
    );
    assert_error(
        &region("min = [0.0, 0.0, 1.0]\nmax = [1.0, 1.0, 0.0]\n"),
        3,
        0,
        "region 1: needs finite corners with min ≤ max",
    );
    assert_error(
        &region("min = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]\nrest = 0.0\n"),
        3,
        0,
        "region 1: rest length factor must be finite and positive",
    );
    assert_error(
        &region("min = [0.0, 0.0, 0.0]\nmax = [1.0, 1.0, 1.0]\nsoftness = 2.0\n"),
        6,
        1,
        "unknown field `softness`",
    );
    // Not text.
    let e = SceneFile::parse(b"[[body]]\n\xff\xfe", "s.toml").unwrap_err();
    assert_eq!(e.line, 2);
}

/// Gravity left out of a scene file: 0, 0, −9.81 m/s² (as `jello create` and Python's
/// `jello.create` give a new scene), but none in a scene with a force field; given, as given.
#[test]
fn gravity_left_out_is_the_new_scenes_default() {
    let body = "[[body]]\ncube = { points = [2, 2, 2], size = [0.5, 0.5, 0.5] }\n";
    let gravity = |text: &str| {
        parse(text)
            .unwrap()
            .to_scene("s.toml")
            .unwrap()
            .model
            .gravity
    };
    assert_eq!(gravity(body), Vec3::new(0.0, 0.0, -9.81));
    let field = "[field]\nresolution = 2\nforces = [".to_string()
        + &["[0.0, 0.0, 0.0]"; 8].join(", ")
        + "]\n";
    assert_eq!(gravity(&(field + body)), Vec3::ZERO);
    let given = "[simulation]\ngravity = [1.0, 2.0, 3.0]\n".to_string() + body;
    assert_eq!(gravity(&given), Vec3::new(1.0, 2.0, 3.0));
}

/// Errors found after the file is read point at the key at fault, not at its table's header:
/// a misspelt key in an `[[obstacle]]`, a negative density (named as written, not as the mass
/// per point it becomes), an unknown integrator.
#[test]
fn errors_name_the_line_of_the_key_at_fault() {
    let text = "[simulation]\nintegrator = \"RK4\"\n\n[[obstacle]]\ntype = \"sphere\"\n\
                centre = [0.0, 0.0, -1.0]\nraduis = 0.5\n\n[[body]]\nname = \"cube1\"\n\
                centre = [0.0, 0.0, 0.0]\ndensity = -1000\n\
                cube = { points = [4, 4, 4], size = [0.4, 0.4, 0.4] }\n";
    assert_error(
        text,
        7,
        1,
        "unknown field `raduis`, expected `centre` or `radius`",
    );
    let text = text.replace("raduis", "radius");
    assert_error(
        &text,
        12,
        0,
        "body 1: density must be a finite number above 0 (got -1000)",
    );
    let text = text.replace("density = -1000", "density = 1000");
    assert_error(
        &text.replace("\"RK4\"", "\"RK5\""),
        2,
        0,
        "unknown integrator \"RK5\"",
    );
    assert_error(
        &text.replace("radius = 0.5", "radius = -0.5"),
        7,
        0,
        "obstacle 1: sphere needs a finite centre and a finite, positive radius (centre (0, 0, -1), \
         radius -0.5)",
    );
    assert_error(
        &text
            .replace("dt = ", "x = ")
            .replace("[simulation]\n", "[simulation]\ndt = -0.001\n"),
        2,
        0,
        "[simulation] dt must be a finite number above 0 s (got -0.001)",
    );
}

/// A body placed on a plate by arithmetic (its lowest points at `0.3 − 0.2`, a rounding below
/// the plate's top at 0.1) starts on it, not in it; a centimetre into it is still refused.
#[test]
fn a_body_placed_on_a_plate_up_to_a_rounding_starts_on_it() {
    let scene = |z: f64| {
        format!(
            "[[obstacle]]\ntype = \"box\"\nmin = [-1.0, -1.0, -1.0]\nmax = [1.0, 1.0, 0.1]\n\
             [[body]]\ncentre = [0.0, 0.0, {z}]\n\
             cube = {{ points = [4, 4, 4], size = [0.4, 0.4, 0.4] }}\n"
        )
    };
    let made = parse(&scene(0.3)).unwrap().to_scene("s.toml").unwrap();
    let lowest = made
        .state
        .pos
        .iter()
        .map(|p| p.z)
        .fold(f64::INFINITY, f64::min);
    assert!(lowest < 0.1);
    assert_error(&scene(0.29), 5, 0, "starts inside obstacle 1");
}

/// A mesh body 5 cm above a cube starts apart from it, whatever the lattice around the mesh
/// (which reaches up past the mesh to whole cells, and would, centred, push the mesh down into
/// the cube): `centre` places the mesh's bounding box, and the check is the skins'. Moved 10 cm
/// closer, they overlap and are refused.
#[test]
fn a_mesh_apart_from_a_cube_starts_apart_whatever_its_lattice() {
    let mesh = torus(0.5, 0.2, 24, 12);
    let (lo, hi) = mesh.bounds();
    let height = hi.z - lo.z;
    let cube = cube_spec(4, 0.6, [0.0, 0.0, 0.0]);
    for cells in [4, 7, 10] {
        let ring = |z: f64| {
            let mut ring = torus_spec(cells);
            ring.centre = Some([0.0, 0.0, z]);
            ring
        };
        let apart = SceneFile::new(vec![cube.clone(), ring(0.3 + height / 2.0 + 0.05)]);
        apart
            .to_scene("s.toml")
            .unwrap_or_else(|e| panic!("{cells} cells: {e}"));
        let into = SceneFile::new(vec![cube.clone(), ring(0.3 + height / 2.0 - 0.05)]);
        let e = into.to_scene("s.toml").unwrap_err().to_string();
        assert!(e.contains("start inside each other"), "{e}");
    }
}
