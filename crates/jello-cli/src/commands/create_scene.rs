//! `jello create OUT.toml`: a scene of bodies (voxelised meshes and lattice cubes), obstacles and
//! pinned points, written as one self-contained TOML file (see [`jello_core::formats::scene`]).
//!
//! Per-body options apply to the `--mesh` or `--cube` they follow on the command line, so
//! `--mesh a.obj --cells 8 --centre 0,0,1 --cube 5 --velocity 0,0,-1` makes two bodies with their
//! own settings.

use clap::ArgMatches;
use jello_core::formats::scene::{
    BodySpec, BoxSpec, Collision, CubeSpec, MeshSpec, ObstacleSpec, PinSpec, SceneFile, Settings,
    ShakeSpec, DEFAULT_CELLS, DEFAULT_FRICTION, DEFAULT_WALL_FRICTION,
};
use jello_core::{Aabb, TriMesh, Vec3};

use super::create::CreateArgs;
use super::require_implicit;
use crate::error::CliError;
use jello_io::{read_bounded, write_atomic};

/// Which body each value of a per-body option belongs to: the last `--mesh` or `--cube` before
/// it. `starts` are the bodies' positions on the command line, in order.
fn owners(
    matches: &ArgMatches,
    id: &str,
    flag: &str,
    starts: &[usize],
) -> Result<Vec<usize>, CliError> {
    let Some(indices) = matches.indices_of(id) else {
        return Ok(Vec::new());
    };
    let mut seen = vec![false; starts.len()];
    let mut owners = Vec::new();
    for i in indices {
        let body = starts.partition_point(|&s| s < i);
        if body == 0 {
            return Err(CliError::usage(format!(
                "{flag} comes before any --mesh or --cube: per-body options follow the body they apply to"
            )));
        }
        let b = body - 1;
        if seen[b] && id != "pin" && id != "region" {
            return Err(CliError::usage(format!(
                "{flag} is given twice for body {}",
                b + 1
            )));
        }
        seen[b] = true;
        owners.push(b);
    }
    Ok(owners)
}

/// For each body, the value of a per-body option (or `None`).
fn per_body<T: Clone>(
    matches: &ArgMatches,
    id: &str,
    flag: &str,
    starts: &[usize],
    values: &[T],
) -> Result<Vec<Option<T>>, CliError> {
    let mut out = vec![None; starts.len()];
    for (b, v) in owners(matches, id, flag, starts)?.into_iter().zip(values) {
        out[b] = Some(v.clone());
    }
    Ok(out)
}

/// Writes the scene the options describe.
pub fn create_scene(args: &CreateArgs, matches: &ArgMatches) -> Result<(), CliError> {
    let out = &args.out;
    let out_name = out.display().to_string();
    // Only implicit methods solve their steps to a tolerance (and cut them back).
    for (flag, given) in [
        ("--tolerance", args.tolerance.is_some()),
        ("--cutbacks", args.cutbacks.is_some()),
    ] {
        if given {
            require_implicit(args.integrator, flag)?;
        }
    }
    if !args.drag.is_empty() || args.scale != 1.0 {
        return Err(CliError::usage(
            "--drag and --scale shape the classic world's cube; in a scene use --cube N --size S",
        ));
    }
    if matches.contains_id("offset")
        && matches.value_source("offset") == Some(clap::parser::ValueSource::CommandLine)
    {
        return Err(CliError::usage(
            "--offset places the classic world's cube; in a scene use --centre",
        ));
    }
    // The bodies, in command-line order.
    let mut starts: Vec<(usize, Shape)> = Vec::new();
    if let Some(ix) = matches.indices_of("mesh") {
        starts.extend(ix.zip(&args.mesh).map(|(i, p)| (i, Shape::Mesh(p.clone()))));
    }
    if let Some(ix) = matches.indices_of("cube") {
        starts.extend(
            ix.zip(&args.cube)
                .map(|(i, &n)| (i, Shape::Cube(n as usize))),
        );
    }
    starts.sort_by_key(|(i, _)| *i);
    if starts.is_empty() {
        return Err(CliError::usage(
            "a scene needs at least one body: --mesh FILE.obj|FILE.stl or --cube N",
        ));
    }
    let at: Vec<usize> = starts.iter().map(|(i, _)| *i).collect();
    let cells = per_body(matches, "cells", "--cells", &at, &args.cells)?;
    let size = per_body(matches, "size", "--size", &at, &args.size)?;
    let centre = per_body(matches, "at", "--centre", &at, &args.at)?;
    let name = per_body(matches, "name", "--name", &at, &args.name)?;
    let rotate = per_body(matches, "rotate", "--rotation", &at, &args.rotate)?;
    let velocity = per_body(matches, "velocity", "--velocity", &at, &args.velocity)?;
    let spin = per_body(matches, "spin", "--spin", &at, &args.spin)?;
    let mass = per_body(matches, "mass", "--mass", &at, &args.mass)?;
    let total_mass = per_body(matches, "total_mass", "--total-mass", &at, &args.total_mass)?;
    let density = per_body(matches, "density", "--density", &at, &args.density)?;
    let k = per_body(matches, "k_elastic", "--stiffness", &at, &args.k_elastic)?;
    let d = per_body(matches, "d_elastic", "--damping", &at, &args.d_elastic)?;
    let modulus = per_body(matches, "modulus", "--modulus", &at, &args.modulus)?;
    let viscosity = per_body(matches, "viscosity", "--viscosity", &at, &args.viscosity)?;
    let pin_owners = owners(matches, "pin", "--pin", &at)?;
    let shake = per_body(matches, "shake", "--shake", &at, &args.shake)?;
    let region_owners = owners(matches, "region", "--region", &at)?;

    let mut bodies = Vec::new();
    for (b, (_, shape)) in starts.iter().enumerate() {
        let mut spec = BodySpec::default();
        match shape {
            Shape::Mesh(path) => {
                if size[b].is_some() {
                    return Err(CliError::usage(format!(
                        "--size is for a --cube; body {} is a mesh (use --cells)",
                        b + 1
                    )));
                }
                let mesh_name = path.display().to_string();
                let bytes = read_bounded(path)?;
                let mesh = TriMesh::parse(&bytes, &mesh_name)
                    .map_err(|e| CliError::input(e.to_string()))?;
                spec.mesh = Some(MeshSpec {
                    cells: cells[b].map_or(DEFAULT_CELLS, |c| c as usize),
                    vertices: mesh.vertices.iter().map(|v| v.to_array()).collect(),
                    triangles: mesh.triangles.clone(),
                });
                spec.name = Some(
                    path.file_stem()
                        .map_or("mesh".into(), |s| s.to_string_lossy().into_owned()),
                );
            }
            Shape::Cube(n) => {
                if cells[b].is_some() {
                    return Err(CliError::usage(format!(
                        "--cells is for a --mesh; body {} is a cube (its points are --cube N)",
                        b + 1
                    )));
                }
                let side = size[b].unwrap_or(1.0);
                spec.cube = Some(CubeSpec {
                    points: [*n; 3],
                    size: [side; 3],
                });
                spec.name = Some(format!("cube{}", b + 1));
            }
        }
        if let Some(n) = &name[b] {
            spec.name = Some(n.clone());
        }
        spec.centre = centre[b].map(|c| c.0);
        spec.rotation = rotate[b].map(|r| r.0);
        spec.velocity = velocity[b].map(|v| v.0);
        spec.spin = spin[b].map(|w| w.0);
        spec.mass = mass[b];
        spec.total_mass = total_mass[b];
        spec.density = density[b];
        spec.stiffness = k[b].map(|k| [k; 3]);
        spec.damping = d[b].map(|d| [d; 3]);
        spec.modulus = modulus[b];
        spec.viscosity = viscosity[b];
        spec.pins = pin_owners
            .iter()
            .zip(&args.pin)
            .filter(|(&o, _)| o == b)
            .map(|(_, p)| PinSpec {
                at: p.at,
                radius: p.radius,
                shake: shake[b].map(|s| {
                    let [ax, ay, az, frequency] = s.0;
                    ShakeSpec {
                        amplitude: [ax, ay, az],
                        frequency,
                    }
                }),
                path: None,
            })
            .collect();
        spec.region = region_owners
            .iter()
            .zip(&args.region)
            .filter(|(&o, _)| o == b)
            .map(|(_, r)| r.spec)
            .collect();
        if shake[b].is_some() && spec.pins.is_empty() {
            return Err(CliError::usage(format!(
                "--shake moves a body's pinned points: body {} has no --pin",
                b + 1
            )));
        }
        bodies.push(spec);
    }

    let bounds = match args.bounds {
        Some(b) => {
            let [x0, y0, z0, x1, y1, z1] = b.0;
            Aabb::new(Vec3::new(x0, y0, z0), Vec3::new(x1, y1, z1))
                .map_err(|e| CliError::usage(format!("--bounds: {e}")))?
        }
        None => Aabb::classic(),
    };
    let mut obstacles: Vec<ObstacleSpec> = args
        .sphere
        .iter()
        .map(|s| {
            let [x, y, z, r] = s.0;
            ObstacleSpec::Sphere {
                centre: [x, y, z],
                radius: r,
            }
        })
        .collect();
    obstacles.extend(args.solid_box.iter().map(|b| {
        let [x0, y0, z0, x1, y1, z1] = b.0;
        ObstacleSpec::Box {
            min: [x0, y0, z0],
            max: [x1, y1, z1],
        }
    }));
    let mut scene = SceneFile::new(bodies);
    let defaults = Settings::default();
    scene.simulation = Settings {
        integrator: args.integrator.name().to_string(),
        dt: args.dt,
        steps_per_frame: args.steps_per_frame,
        tolerance: args.tolerance.unwrap_or(defaults.tolerance),
        cutbacks: args.cutbacks.unwrap_or(defaults.cutbacks),
        ..defaults
    };
    scene.collision = Collision {
        stiffness: args.k_collision,
        damping: args.d_collision,
        friction: args.friction.unwrap_or(DEFAULT_FRICTION),
        wall_friction: args.wall_friction.unwrap_or(DEFAULT_WALL_FRICTION),
        self_contact: args.self_contact,
    };
    scene.bounds = Some(BoxSpec {
        min: bounds.min.to_array(),
        max: bounds.max.to_array(),
    });
    scene
        .set_gravity_and_field(args.field, args.res as usize, args.gravity.map(|g| g.0))
        .map_err(|e| CliError::usage(format!("--field: {e}")))?;
    scene.obstacles = obstacles;
    if let Some(p) = args.plane {
        scene
            .add_plane_facing_first_body(p.0, &out_name)
            .map_err(|e| CliError::usage(format!("--plane: {e}")))?;
    }
    let made = scene
        .to_scene(&out_name)
        .map_err(|e| CliError::input(e.to_string()))?;
    let text = scene.to_toml();
    // What is written must read back as the same scene.
    let again = SceneFile::parse(text.as_bytes(), &out_name).map_err(|e| {
        CliError::io(format!(
            "internal error: the written scene does not read back: {e}"
        ))
    })?;
    debug_assert_eq!(again, scene);
    write_atomic(out, text.as_bytes())?;
    let m = &made.model;
    println!(
        "wrote {out_name}: {} bod{}, {} points, {} springs, {} obstacle(s), {} pinned point(s)",
        m.bodies().len(),
        if m.bodies().len() == 1 { "y" } else { "ies" },
        m.bodies().iter().map(|b| b.active_count()).sum::<usize>(),
        m.spring_count(),
        m.obstacles.len(),
        m.pins.len()
    );
    Ok(())
}

/// A body's shape as given on the command line.
enum Shape {
    Mesh(std::path::PathBuf),
    Cube(usize),
}
