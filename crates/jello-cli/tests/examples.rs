//! The example worlds the project ships: made by `jello create` (scripts/make-examples.sh), and
//! the official five equal to the original assignment's files up to their six decimals.

use std::path::{Path, PathBuf};

use jello_core::{ReadOptions, Simulation, Vec3, World};

fn root() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../..")
}

fn read(path: &Path) -> World {
    let bytes = std::fs::read(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    World::parse(&bytes, &path.display().to_string(), ReadOptions::default()).unwrap()
}

/// Every number of `a` within `tol` of `b`'s, every count and name equal.
fn assert_close(name: &str, a: &World, b: &World, tol: f64) {
    let close = |what: &str, x: f64, y: f64| {
        assert!((x - y).abs() <= tol, "{name}: {what} {x} vs {y}");
    };
    let close3 = |what: &str, x: &[Vec3], y: &[Vec3]| {
        assert_eq!(x.len(), y.len(), "{name}: {what} count");
        for (i, (p, q)) in x.iter().zip(y).enumerate() {
            assert!(
                (*p - *q).max_abs() <= tol,
                "{name}: {what} {i}: {p:?} vs {q:?}"
            );
        }
    };
    assert_eq!(a.integrator, b.integrator, "{name}");
    assert_eq!(a.steps_per_frame, b.steps_per_frame, "{name}");
    close("dt", a.dt, b.dt);
    close("kElastic", a.k_elastic, b.k_elastic);
    close("dElastic", a.d_elastic, b.d_elastic);
    close("kCollision", a.k_collision, b.k_collision);
    close("dCollision", a.d_collision, b.d_collision);
    close("mass", a.mass, b.mass);
    assert_eq!(a.plane.is_some(), b.plane.is_some(), "{name}: plane");
    if let (Some(p), Some(q)) = (a.plane, b.plane) {
        (0..4).for_each(|i| close("plane", p[i], q[i]));
    }
    match (&a.field, &b.field) {
        (Some((ra, fa)), Some((rb, fb))) => {
            assert_eq!(ra, rb, "{name}: res");
            close3("force", fa, fb);
        }
        (None, None) => {}
        _ => panic!("{name}: one has a force field, the other none"),
    }
    close3("position", &a.positions, &b.positions);
    close3("velocity", &a.velocities, &b.velocities);
}

#[test]
#[cfg_attr(
    not(shared_worlds),
    ignore = "needs ../shared/worlds, absent when this crate was built"
)]
fn official_examples_equal_the_official_worlds() {
    let shared = root().join("../shared/worlds");
    for name in [
        "jello.w",
        "gravity.w",
        "moveLeft.w",
        "rotate.w",
        "skewedCorner.w",
    ] {
        let ours = read(&root().join("examples").join(name));
        let theirs = read(&shared.join(name));
        // The original writer prints six decimals: differences up to half a unit in the last.
        assert_close(name, &ours, &theirs, 5e-7 + 1e-12);
    }
}

#[test]
fn every_example_loads_and_runs() {
    let mut count = 0;
    for entry in std::fs::read_dir(root().join("examples")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "w") {
            let mut sim = Simulation::from_world(&read(&path)).unwrap();
            sim.advance(200)
                .unwrap_or_else(|e| panic!("{}: {e}", path.display()));
            count += 1;
        }
    }
    assert!(count >= 5, "only {count} examples");
}

/// The example scenes (`examples/*.toml`): each loads, runs a second without blowing up, and
/// the shapes' skins are the meshes `jello shape` makes.
#[test]
fn every_example_scene_loads_and_runs_a_second() {
    use jello_core::formats::scene::SceneFile;
    use jello_core::TriMesh;

    let mut seen = Vec::new();
    for entry in std::fs::read_dir(root().join("examples")).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_none_or(|e| e != "toml") {
            continue;
        }
        let name = path.display().to_string();
        let bytes = std::fs::read(&path).unwrap();
        let scene = SceneFile::parse(&bytes, &name)
            .and_then(|f| f.to_scene(&name))
            .unwrap_or_else(|e| panic!("{e}"));
        let stem = path.file_stem().unwrap().to_string_lossy().into_owned();
        if let Some(mesh) = TriMesh::shape(&stem, 8) {
            let skin = scene
                .model
                .body(0)
                .skin
                .as_ref()
                .expect("a mesh body has a skin");
            assert_eq!(skin.len(), mesh.vertices.len(), "{name}");
            assert_eq!(skin.triangles, mesh.triangles, "{name}");
        }
        let steps = (1.0 / scene.model.dt).round() as u64;
        let mut sim = Simulation::new(scene.model, scene.state);
        sim.advance(steps).unwrap_or_else(|e| panic!("{name}: {e}"));
        let (deepest, _) = jello_core::contact::overlap(&sim.model, &sim.state.pos);
        // Penalty contacts give a little, still moving: less than a tenth of the finest cell.
        let cell = (sim.model.bodies().iter())
            .map(|b| b.min_spacing())
            .fold(f64::INFINITY, f64::min);
        assert!(
            deepest < 0.1 * cell,
            "{name}: bodies overlap by {deepest} m, cells of {cell} m"
        );
        eprintln!(
            "{name}: deepest overlap {deepest:.3e} m, {:.2} % of a cell",
            100.0 * deepest / cell
        );
        seen.push(stem);
    }
    seen.sort();
    assert_eq!(
        seen,
        ["blob", "mould", "pile", "ring", "stack", "torus", "tower"]
    );
}
