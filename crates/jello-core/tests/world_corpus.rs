//! Every world file collected from the wild (../shared/worlds): the readable ones run, the
//! unknown integrator is named, the nonstandard ones get a clear error.

mod common;

use std::path::Path;

use jello_core::{Integrator, ReadOptions, Simulation, World};

fn read(path: &Path) -> Result<World, jello_core::WorldError> {
    let bytes = std::fs::read(path).unwrap();
    World::parse(&bytes, &path.display().to_string(), ReadOptions::default())
}

fn world_files(dir: &Path) -> Vec<std::path::PathBuf> {
    let mut files: Vec<_> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.extension().is_some_and(|e| e == "w"))
        .collect();
    files.sort();
    files
}

/// The 112 files with a known integrator run 1000 steps. Every state reached is finite; a world
/// whose integrator diverges at its dt is stopped by the blow-up check with a suggested dt, and
/// following that advice (at most three times, as a user would) it runs its 1000 steps.
#[test]
#[cfg_attr(
    not(shared_worlds),
    ignore = "needs ../shared/worlds, absent when this crate was built"
)]
fn every_readable_world_runs_1000_steps() {
    let dir = common::shared_worlds();
    let (mut ran, mut stopped) = (0, Vec::new());
    for path in world_files(&dir) {
        if path.file_name().unwrap() == "custom-IPC.w" {
            continue;
        }
        let world = read(&path).unwrap_or_else(|e| panic!("{e}"));
        let mut sim = Simulation::from_world(&world).unwrap();
        match sim.advance(1000) {
            Ok(()) => ran += 1,
            Err(mut blow_up) => {
                let mut tries = 0;
                loop {
                    let dt = blow_up.suggested_dt.unwrap_or_else(|| {
                        panic!("{}: no dt suggested: {blow_up}", path.display())
                    });
                    let mut retry = Simulation::from_world(&World {
                        dt,
                        ..world.clone()
                    })
                    .unwrap();
                    match retry.advance(1000) {
                        Ok(()) => break,
                        Err(e) if tries < 2 => (blow_up, tries) = (e, tries + 1),
                        Err(e) => panic!("{}: still unstable at dt {dt}: {e}", path.display()),
                    }
                }
                stopped.push(path.file_name().unwrap().to_string_lossy().into_owned());
            }
        }
        assert!(sim
            .state
            .pos
            .iter()
            .chain(&sim.state.vel)
            .all(|v| v.is_finite()));
    }
    eprintln!("{ran} worlds ran 1000 steps; stopped by the blow-up check, then ran at the suggested dt: {stopped:?}");
    assert_eq!(ran + stopped.len(), 112);
    assert!(ran >= 100, "only {ran} worlds ran at their own dt");
}

/// The one world naming an unknown integrator gets an error that lists the known ones, and runs
/// when the integrator is given.
#[test]
#[cfg_attr(
    not(shared_worlds),
    ignore = "needs ../shared/worlds, absent when this crate was built"
)]
fn unknown_integrator_is_named_and_can_be_overridden() {
    let dir = common::shared_worlds();
    let path = dir.join("custom-IPC.w");
    let err = read(&path).unwrap_err().to_string();
    assert!(
        err.contains("custom-IPC.w:1:") && err.contains("\"IPC\""),
        "{err}"
    );
    for name in ["Euler", "RK2", "RK4", "SymplecticEuler"] {
        assert!(err.contains(name), "{err}");
    }
    let bytes = std::fs::read(&path).unwrap();
    let options = ReadOptions {
        integrator: Some(Integrator::Rk4),
    };
    let world = World::parse(&bytes, "custom-IPC.w", options).unwrap();
    assert_eq!(world.integrator, Integrator::Rk4);
}

/// Every file the original reader cannot read gets an error naming the file and a line.
#[test]
#[cfg_attr(
    not(shared_worlds),
    ignore = "needs ../shared/worlds, absent when this crate was built"
)]
fn nonstandard_worlds_get_a_clear_error() {
    let dir = common::shared_worlds();
    let files = world_files(&dir.join("nonstandard"));
    assert_eq!(files.len(), 24);
    for path in files {
        let name = path.display().to_string();
        let err = read(&path).expect_err(&name).to_string();
        assert!(err.starts_with(&format!("{name}:")), "{err}");
        let line: usize = err[name.len() + 1..]
            .split(':')
            .next()
            .unwrap()
            .parse()
            .unwrap_or(0);
        assert!(line > 0, "no line in: {err}");
        assert!(err.contains("expected"), "{err}");
    }
}
