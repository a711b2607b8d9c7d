//! Scene files: what they read, what they write back, and the error for each kind of bad input
//! (file, line, column).

#[path = "common/meshes.rs"]
mod meshes;

use jello_core::scene_file::{BodySpec, CubeSpec, MeshSpec, ObstacleSpec, PinSpec, ShakeSpec};
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
    scene.simulation.gravity = [0.0, 0.0, -9.81];
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
        // The same rigid motion of the mesh: rotate about the rest box's middle, then move it.
        let body = made.model.body(0);
        let r = body.rotation;
        let lo = mesh
            .vertices
            .iter()
            .fold(Vec3::new(9.0, 9.0, 9.0), |a, &b| a.min(b));
        let local = |p: Vec3| p - lo;
        for (s, &v) in skin.iter().zip(&mesh.vertices) {
            let d = local(v);
            let want = body.origin + Vec3::new(r[0].dot(d), r[1].dot(d), r[2].dot(d));
            assert!((*s - want).max_abs() < 1e-12, "{s:?} vs {want:?}");
        }
    }
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
        0,
        0,
        "Verlet",
    );
    assert_error(
        &format!("{cube}mass = -1.0\n"),
        1,
        0,
        "mass must be finite and positive",
    );
    assert_error("[[body]\n", 1, 8, "expected `]`");
    // A mesh that is not closed.
    assert_error(
        "[[body]]\nmesh = { cells = 3, vertices = [[0,0,0],[1,0,0],[0,1,0]], triangles = [[0,1,2]] }\n",
        1,
        0,
        "s.toml: mesh",
    );
    // Bodies that start in each other, outside the box, or in an obstacle.
    let two = format!("{cube}centre = [0.0, 0.0, 0.0]\n{cube}centre = [0.2, 0.0, 0.0]\n");
    assert_error(&two, 0, 0, "bodies start interpenetrating");
    assert_error(
        &format!("{cube}centre = [1.9, 0.0, 0.0]\n"),
        0,
        0,
        "starts outside the box",
    );
    assert_error(
        &format!("[[obstacle]]\ntype = \"sphere\"\ncentre = [0.5, 0.5, 0.5]\nradius = 0.2\n{cube}"),
        0,
        0,
        "starts inside obstacle 1",
    );
    assert_error(
        &format!("{cube}pins = [{{ at = [5.0, 5.0, 5.0], radius = 0.1 }}]\n"),
        1,
        0,
        "pin 1 holds no point",
    );
    assert_error(
        &format!("[collision]\nfriction = -0.5\n{cube}"),
        0,
        0,
        "[collision] friction must be a finite number ≥ 0",
    );
    assert_error(
        &format!("{cube}pins = [{{ at = [0.5, 0.5, 0.5], radius = 0.0, shake = {{ amplitude = [0.1, 0.0, 0.0], frequency = -2.0 }} }}]\n"),
        1,
        0,
        "pin 1: a shake needs a finite amplitude and a finite frequency above 0",
    );
    // Not text.
    let e = SceneFile::parse(b"[[body]]\n\xff\xfe", "s.toml").unwrap_err();
    assert_eq!(e.line, 2);
}
