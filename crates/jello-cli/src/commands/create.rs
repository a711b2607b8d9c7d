//! `jello create`: write a new world file, everything the original createWorld does and more;
//! or, for an `OUT.toml`, a scene of bodies from meshes and lattices (see [`super::create_scene`]).

use std::path::PathBuf;
use std::str::FromStr;

use clap::Args;
use jello_core::diagnostics::centre_of_mass;
use jello_core::formats::scene::RegionSpec;
use jello_core::model::body::rotation_xyz;
use jello_core::model::field::RES_RANGE;
use jello_core::model::field_preset::{parse_numbers, DEFAULT_RESOLUTION};
use jello_core::state::rigid_velocity;
use jello_core::{defaults, Aabb, FieldPreset, Integrator, Lattice, Vec3, World};

use super::{
    cutbacks_range, parse_integrator, parse_non_negative, parse_positive, parse_tolerance,
};
use crate::error::CliError;
use jello_io::{check_new_output, is_scene, write_atomic};

/// Arguments of `jello create`.
///
/// Options marked "per body" follow the `--mesh` or `--cube` they apply to in a scene; for a
/// world file they are given at most once.
// Negative numbers are values (`--dt -0.001`), so that our own checks answer them rather than
// clap taking them for flags.
#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct CreateArgs {
    /// The file to write: a world file (.w), or a scene file (.toml) of bodies and obstacles.
    #[arg(value_name = "OUT.w|OUT.toml")]
    pub out: PathBuf,
    /// Integrator (Euler, RK2, RK4, SymplecticEuler, BackwardEuler, SDIRK2; any case).
    #[arg(long, value_parser = parse_integrator, default_value = "RK4")]
    pub integrator: Integrator,
    /// Time step (s).
    #[arg(long, value_parser = parse_positive, default_value_t = defaults::DT)]
    pub dt: f64,
    /// Scene, implicit integrators: the residual each step is solved to (m/s per point, times
    /// the fastest point's speed when that is above 1 m/s; at most 0.1) [default: 1e-9].
    #[arg(long, value_name = "M/S", value_parser = parse_tolerance)]
    pub tolerance: Option<f64>,
    /// Scene, implicit integrators: how many times a step whose solve fails may be halved
    /// before the run stops [default: 6].
    #[arg(long, value_name = "N", value_parser = cutbacks_range())]
    pub cutbacks: Option<u32>,
    /// Simulation steps per displayed frame (the `n` of the file).
    #[arg(short = 'n', long, default_value_t = defaults::STEPS_PER_FRAME, value_parser = clap::value_parser!(u32).range(1..))]
    pub steps_per_frame: u32,
    /// Stiffness of every lattice spring (N/m; the classic world's kElastic) [default: 200]; per
    /// body.
    #[arg(long = "stiffness", visible_alias = "k-elastic", value_name = "K", value_parser = parse_positive)]
    pub k_elastic: Vec<f64>,
    /// Damping of every lattice spring (N·s/m; dElastic) [default: 0.25]; per body.
    #[arg(long = "damping", visible_alias = "d-elastic", value_name = "D", value_parser = parse_non_negative)]
    pub d_elastic: Vec<f64>,
    /// Stiffness of the collision penalty springs (N/m; kCollision).
    #[arg(long = "collision-stiffness", visible_alias = "k-collision", value_name = "K", value_parser = parse_positive, default_value_t = defaults::K_COLLISION)]
    pub k_collision: f64,
    /// Damping of the collision penalty springs (N·s/m; dCollision).
    #[arg(long = "collision-damping", visible_alias = "d-collision", value_name = "D", value_parser = parse_non_negative, default_value_t = defaults::D_COLLISION)]
    pub d_collision: f64,
    /// Scene: Coulomb friction coefficient of obstacles and of contacts between bodies (the walls'
    /// is --wall-friction) [default: 0.5].
    #[arg(long, value_parser = parse_non_negative)]
    pub friction: Option<f64>,
    /// Scene: Coulomb friction coefficient of the walls and the inclined plane [default: 0.5].
    #[arg(long, value_name = "MU", value_parser = parse_non_negative)]
    pub wall_friction: Option<f64>,
    /// Scene: let each body's surface touch its own (a bar bent over, a torus squashed flat).
    #[arg(long)]
    pub self_contact: bool,
    /// Mass of each point (kg) [default: 1/512]; per body.
    #[arg(long, value_parser = parse_positive)]
    pub mass: Vec<f64>,
    /// Mass of the whole body (kg), spread over its points; per body.
    #[arg(long, value_parser = parse_positive)]
    pub total_mass: Vec<f64>,
    /// Inclined plane a x + b y + c z + d = 0, given as A,B,C,D [default: none]; points are kept
    /// on the side of the (first) body's centre of mass.
    #[arg(long, value_name = "A,B,C,D", allow_hyphen_values = true)]
    pub plane: Option<Numbers<4>>,
    #[arg(
        long,
        default_value = "none",
        allow_hyphen_values = true,
        help = "Force field: none | uniform:FX,FY,FZ | gravity[:G] | vortex:S[:x|y|z] | radial:S | tornado:S"
    )]
    pub field: FieldPreset,
    /// Force field grid resolution: nodes per axis (2 to 30).
    #[arg(long = "resolution", visible_alias = "res", value_name = "R", default_value_t = DEFAULT_RESOLUTION as u32, value_parser = clap::value_parser!(u32).range(2..=30))]
    pub res: u32,
    /// Side length of the initial cube (m); its rest shape stays the 1 m cube (world files).
    #[arg(long, value_parser = parse_positive, default_value_t = 1.0)]
    pub scale: f64,
    /// Rotation about the body's centre, in degrees about x, then y, then z; per body.
    #[arg(
        long = "rotation",
        visible_alias = "rotate",
        value_name = "RX,RY,RZ",
        allow_hyphen_values = true
    )]
    pub rotate: Vec<Numbers<3>>,
    /// Where lattice point (0,0,0) sits after scaling and rotation (m); the default keeps the
    /// original cube, 0 to 1 on each axis (world files).
    #[arg(
        long,
        value_name = "X,Y,Z",
        allow_hyphen_values = true,
        default_value = "0,0,0"
    )]
    pub offset: Numbers<3>,
    /// Move one point after placing the cube: I,J,K:DX,DY,DZ (repeatable), e.g. the dragged
    /// corner of the official jello.w is 7,7,7:0.142857,0.142857,0.142857 (world files).
    #[arg(long, value_name = "I,J,K:DX,DY,DZ", allow_hyphen_values = true)]
    pub drag: Vec<Drag>,
    /// Initial velocity of every point (m/s) [default: 0,0,0]; per body.
    #[arg(long, value_name = "VX,VY,VZ", allow_hyphen_values = true)]
    pub velocity: Vec<Numbers<3>>,
    /// Initial spin: angular velocity about the body's centre of mass (rad/s), added to
    /// --velocity; per body.
    #[arg(long, value_name = "WX,WY,WZ", allow_hyphen_values = true)]
    pub spin: Vec<Numbers<3>>,
    /// Scene: a body voxelised from a closed mesh (.obj, or .stl in ASCII or binary),
    /// embedded in the scene; repeatable.
    #[arg(long, value_name = "FILE.obj|FILE.stl")]
    pub mesh: Vec<PathBuf>,
    /// Scene: a body that is a full lattice of N×N×N points; repeatable.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(2..=256))]
    pub cube: Vec<u32>,
    /// Cells along the longest side of a --mesh [default: 10]; per body.
    #[arg(long, value_name = "N", value_parser = clap::value_parser!(u32).range(1..=512))]
    pub cells: Vec<u32>,
    /// Side length of a --cube (m) [default: 1]; per body.
    #[arg(long, value_parser = parse_positive)]
    pub size: Vec<f64>,
    /// Where the centre of the body's shape's bounding box goes (m; a mesh's own box, not the
    /// lattice's of whole cells around it) [default: a mesh stays where it is, a cube has its
    /// corner at the origin]; per body.
    #[arg(
        long = "centre",
        visible_alias = "at",
        value_name = "X,Y,Z",
        allow_hyphen_values = true
    )]
    pub at: Vec<Numbers<3>>,
    /// A name for the body; per body.
    #[arg(long)]
    pub name: Vec<String>,
    /// Density (kg/m³) over the body's volume (a mesh's own, not its cells'), instead of --mass; per body.
    #[arg(long, value_parser = parse_positive)]
    pub density: Vec<f64>,
    /// Stiffness independent of the resolution (Pa): every spring gets modulus × spacing,
    /// instead of --stiffness; per body.
    #[arg(long, value_parser = parse_positive)]
    pub modulus: Vec<f64>,
    /// Damping independent of the resolution (Pa·s): every spring gets viscosity × spacing,
    /// instead of --damping; per body.
    #[arg(long, value_parser = parse_non_negative)]
    pub viscosity: Vec<f64>,
    /// Pin the body's points within R m of X,Y,Z (at rest, after placing it); without R, the
    /// nearest point; per body, repeatable.
    #[arg(long, value_name = "X,Y,Z[,R]", allow_hyphen_values = true)]
    pub pin: Vec<PinArg>,
    /// Shake the body's pinned points by AX,AY,AZ metres at F Hz (amplitude · sin(2π F t));
    /// per body, with --pin.
    #[arg(long, value_name = "AX,AY,AZ,F", allow_hyphen_values = true)]
    pub shake: Vec<Numbers<4>>,
    /// Give the springs with both ends in the box (X0,Y0,Z0)–(X1,Y1,Z1) (at rest, after placing
    /// the body) factors on their stiffness, damping and rest length, e.g.
    /// 0,0,0.5,1,1,1,stiffness=4,rest=0.9; per body, repeatable (overlaps multiply).
    #[arg(
        long,
        value_name = "X0,Y0,Z0,X1,Y1,Z1,KEY=F…",
        allow_hyphen_values = true
    )]
    pub region: Vec<RegionArg>,
    /// Scene: a solid sphere obstacle; repeatable.
    #[arg(long, value_name = "X,Y,Z,R", allow_hyphen_values = true)]
    pub sphere: Vec<Numbers<4>>,
    /// Scene: a solid box obstacle from (X0,Y0,Z0) to (X1,Y1,Z1); repeatable.
    #[arg(
        long = "box",
        value_name = "X0,Y0,Z0,X1,Y1,Z1",
        allow_hyphen_values = true
    )]
    pub solid_box: Vec<Numbers<6>>,
    /// Scene: acceleration of every point (m/s²) [default: 0,0,-9.81, z is up; 0,0,0 for none].
    #[arg(long, value_name = "GX,GY,GZ", allow_hyphen_values = true)]
    pub gravity: Option<Numbers<3>>,
    /// Scene: the walls, from (X0,Y0,Z0) to (X1,Y1,Z1) [default: -2,-2,-2,2,2,2].
    #[arg(long, value_name = "X0,Y0,Z0,X1,Y1,Z1", allow_hyphen_values = true)]
    pub bounds: Option<Numbers<6>>,
    /// Overwrite OUT if it exists.
    #[arg(long)]
    pub force: bool,
}

/// `X,Y,Z[,R]`: a region of points to pin.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PinArg {
    /// Centre (m).
    pub at: [f64; 3],
    /// Radius (m); 0 for the nearest point.
    pub radius: f64,
}

impl FromStr for PinArg {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let parts = s.split(',').count();
        match parts {
            3 => Ok(PinArg {
                at: s.parse::<Numbers<3>>()?.0,
                radius: 0.0,
            }),
            4 => {
                let [x, y, z, r] = s.parse::<Numbers<4>>()?.0;
                if r < 0.0 {
                    return Err(format!("expected a radius ≥ 0, found {r} in \"{s}\""));
                }
                Ok(PinArg {
                    at: [x, y, z],
                    radius: r,
                })
            }
            _ => Err(format!("expected X,Y,Z or X,Y,Z,R, found \"{s}\"")),
        }
    }
}

/// `X0,Y0,Z0,X1,Y1,Z1,KEY=F[,KEY=F…]`: a box of springs and their factors.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RegionArg {
    /// The region as a scene file holds it.
    pub spec: RegionSpec,
}

impl FromStr for RegionArg {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let parts: Vec<&str> = s.split(',').map(str::trim).collect();
        let expected = || {
            format!(
                "expected X0,Y0,Z0,X1,Y1,Z1 then stiffness=F, damping=F or rest=F (at least \
                 one), found \"{s}\""
            )
        };
        if parts.len() < 7 {
            return Err(expected());
        }
        let [x0, y0, z0, x1, y1, z1] = parts[..6].join(",").parse::<Numbers<6>>()?.0;
        let mut spec = RegionSpec {
            min: [x0, y0, z0],
            max: [x1, y1, z1],
            stiffness: 1.0,
            damping: 1.0,
            rest: 1.0,
        };
        for part in &parts[6..] {
            let (key, value) = part.split_once('=').ok_or_else(expected)?;
            let value: f64 = value
                .trim()
                .parse()
                .ok()
                .filter(|v: &f64| v.is_finite())
                .ok_or_else(|| {
                    format!("expected a finite number after {key}=, found \"{part}\"")
                })?;
            match key.trim() {
                "stiffness" => spec.stiffness = value,
                "damping" => spec.damping = value,
                "rest" => spec.rest = value,
                other => return Err(unknown_factor(other, s)),
            }
        }
        spec.scale()
            .check()
            .map_err(|e| format!("{e} in \"{s}\""))?;
        Ok(RegionArg { spec })
    }
}

/// The error for a region's factor that is not stiffness, damping or rest.
fn unknown_factor(key: &str, arg: &str) -> String {
    format!("unknown factor \"{key}\" (expected stiffness, damping or rest) in \"{arg}\"")
}

/// `N` comma-separated finite numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Numbers<const N: usize>(pub [f64; N]);

impl<const N: usize> FromStr for Numbers<N> {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        parse_numbers::<N>(s).map(Numbers)
    }
}

impl Numbers<3> {
    pub(crate) fn vec3(self) -> Vec3 {
        Vec3::from_array(self.0)
    }
}

/// A point to move: its lattice coordinates and the displacement (m).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Drag {
    ijk: [usize; 3],
    by: Vec3,
}

impl FromStr for Drag {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        let (point, by) = s
            .split_once(':')
            .ok_or_else(|| format!("expected I,J,K:DX,DY,DZ, found \"{s}\""))?;
        let ijk: Vec<usize> = point
            .split(',')
            .map(|c| c.trim().parse::<usize>().ok().filter(|&c| c < 8))
            .collect::<Option<_>>()
            .filter(|v: &Vec<usize>| v.len() == 3)
            .ok_or_else(|| {
                format!("expected three lattice indices 0 to 7 before ':', found \"{point}\"")
            })?;
        let by = by.parse::<Numbers<3>>()?.vec3();
        Ok(Drag {
            ijk: [ijk[0], ijk[1], ijk[2]],
            by,
        })
    }
}

/// The one value of a per-body option in a world file (which holds one body).
fn one<T: Copy>(values: &[T], flag: &str) -> Result<Option<T>, CliError> {
    match values {
        [] => Ok(None),
        [v] => Ok(Some(*v)),
        _ => Err(CliError::usage(format!(
            "{flag} is given {} times; a world file holds one body (write a .toml scene for several)",
            values.len()
        ))),
    }
}

/// Writes the world or scene the options describe.
pub fn create(args: CreateArgs, matches: &clap::ArgMatches) -> Result<(), CliError> {
    let out = &args.out;
    check_new_output(out, args.force)?;
    if is_scene(out) {
        return super::create_scene::create_scene(&args, matches);
    }
    let scene_only = [
        ("--mesh", !args.mesh.is_empty()),
        ("--cube", !args.cube.is_empty()),
        ("--friction", args.friction.is_some()),
        ("--wall-friction", args.wall_friction.is_some()),
        ("--self-contact", args.self_contact),
        ("--shake", !args.shake.is_empty()),
        ("--region", !args.region.is_empty()),
        ("--cells", !args.cells.is_empty()),
        ("--size", !args.size.is_empty()),
        ("--centre", !args.at.is_empty()),
        ("--name", !args.name.is_empty()),
        ("--density", !args.density.is_empty()),
        ("--modulus", !args.modulus.is_empty()),
        ("--viscosity", !args.viscosity.is_empty()),
        ("--pin", !args.pin.is_empty()),
        ("--sphere", !args.sphere.is_empty()),
        ("--box", !args.solid_box.is_empty()),
        ("--gravity", args.gravity.is_some()),
        ("--bounds", args.bounds.is_some()),
        ("--tolerance", args.tolerance.is_some()),
        ("--cutbacks", args.cutbacks.is_some()),
    ];
    if let Some((flag, _)) = scene_only.iter().find(|(_, given)| *given) {
        return Err(CliError::usage(format!(
            "{flag} makes a scene: name the output file .toml (a .w world holds the classic cube only)"
        )));
    }
    let mass = match (
        one(&args.mass, "--mass")?,
        one(&args.total_mass, "--total-mass")?,
    ) {
        (Some(_), Some(_)) => {
            return Err(CliError::usage(
                "give either --mass or --total-mass, not both",
            ))
        }
        (Some(m), _) => m,
        (None, Some(total)) => total / 512.0,
        (None, None) => defaults::MASS,
    };
    let k_elastic = one(&args.k_elastic, "--stiffness")?.unwrap_or(defaults::K_ELASTIC);
    let d_elastic = one(&args.d_elastic, "--damping")?.unwrap_or(defaults::D_ELASTIC);
    let rotate = one(&args.rotate, "--rotation")?;
    let velocity = one(&args.velocity, "--velocity")?.unwrap_or(Numbers([0.0; 3]));
    let spin = one(&args.spin, "--spin")?;

    // Place the cube: scale about its centre, rotate about its centre, move its corner, drag.
    let lattice = Lattice::classic();
    let rest = lattice.rest_positions();
    let centre = Vec3::new(0.5, 0.5, 0.5);
    let rotation = rotate.map(|r| rotation_xyz(r.0));
    let corner = transform(Vec3::ZERO, centre, args.scale, rotation.as_ref());
    let offset = args.offset.vec3() - corner;
    let mut positions: Vec<Vec3> = rest
        .iter()
        .map(|&p| transform(p, centre, args.scale, rotation.as_ref()) + offset)
        .collect();
    for d in &args.drag {
        let [i, j, k] = d.ijk;
        positions[lattice.index(i, j, k)] += d.by;
    }

    // Velocities: uniform plus rigid spin about the centre of mass.
    let com = centre_of_mass(&positions);
    let v0 = velocity.vec3();
    let velocities: Vec<Vec3> = positions
        .iter()
        .map(|&p| match spin {
            Some(w) => rigid_velocity(v0, w.vec3(), com, p),
            None => v0,
        })
        .collect();

    let res = args.res as usize;
    debug_assert!(RES_RANGE.contains(&res));
    let field = args
        .field
        .sample(res, Aabb::classic(), mass)
        .map_err(|e| CliError::input(format!("--field: {e}")))?
        .map(|f| (res, f.forces().to_vec()));
    if let Some(p) = args.plane {
        if p.0[..3].iter().all(|&c| c == 0.0) {
            return Err(CliError::input(
                "--plane: the normal (a, b, c) must not be zero",
            ));
        }
    }

    let world = World {
        integrator: args.integrator,
        dt: args.dt,
        steps_per_frame: args.steps_per_frame,
        k_elastic,
        d_elastic,
        k_collision: args.k_collision,
        d_collision: args.d_collision,
        mass,
        plane: args.plane.map(|p| p.0),
        field,
        positions,
        velocities,
    };
    // The world must make a valid simulation before it is written.
    world
        .to_simulation()
        .map_err(|e| CliError::input(format!("{}: {e}", out.display())))?;
    write_atomic(out, world.to_text().as_bytes())?;
    println!("wrote {}", out.display());
    Ok(())
}

/// `p` scaled by `scale` and rotated about `centre`.
fn transform(p: Vec3, centre: Vec3, scale: f64, rotation: Option<&[Vec3; 3]>) -> Vec3 {
    let d = (p - centre) * scale;
    let d = match rotation {
        Some(rows) => Vec3::new(rows[0].dot(d), rows[1].dot(d), rows[2].dot(d)),
        None => d,
    };
    centre + d
}
