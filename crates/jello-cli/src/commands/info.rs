//! `jello info`: what a world or scene file holds (per body: points, springs, cells, skin,
//! mass), its energies and the stable time step per integrator.

use std::path::PathBuf;

use clap::Args;
use jello_core::diagnostics::{energy, max_penetration, model_centre_of_mass, momentum};
use jello_core::integrate::stability::{spectral_radius, ModeBounds};
use jello_core::{Integrator, Model, SpringKind, SpringScale};

use super::parse_integrator;
use crate::error::CliError;
use jello_io::{load, Source};

/// Arguments of `jello info`.
// Negative numbers are values (`--dt -0.001`), so that our own checks answer them rather than
// clap taking them for flags.
#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct InfoArgs {
    /// World file (.w) or scene file (.toml) to describe.
    pub world: PathBuf,
    /// Read the file as if it named this integrator (for files with an unknown one).
    #[arg(long, value_parser = parse_integrator)]
    pub integrator: Option<Integrator>,
}

/// Prints the header, counts, energies and stability estimates.
pub fn info(args: InfoArgs) -> Result<(), CliError> {
    let (sim, source) = load(&args.world, args.integrator, None)?;
    let name = args.world.display().to_string();
    let (m, s) = (&sim.model, &sim.state);

    let world = match &source {
        Source::World(world) => {
            println!("world          {name}");
            Some(world)
        }
        Source::Scene(_) => {
            println!("scene          {name}");
            None
        }
    };
    println!(
        "integrator     {}, dt = {} s, {} step(s) per frame",
        m.integrator, m.dt, m.steps_per_frame
    );
    if let Some(world) = world {
        println!(
            "springs        kElastic = {} N/m, dElastic = {} N·s/m; collision kCollision = {} N/m, dCollision = {} N·s/m",
            world.k_elastic, world.d_elastic, world.k_collision, world.d_collision
        );
        println!(
            "mass           {} kg per point, {} kg in all",
            m.body(0).material.mass,
            m.body(0).material.mass * m.point_count() as f64
        );
    } else {
        println!(
            "collision      stiffness = {} N/m, damping = {} N·s/m; friction {} (walls and plane {}); gravity ({}, {}, {}) m/s²",
            m.k_collision, m.d_collision, m.friction, m.wall_friction, m.gravity.x, m.gravity.y, m.gravity.z
        );
        let b = m.bounds;
        println!(
            "box            ({}, {}, {}) to ({}, {}, {}) m; {} obstacle(s), {} pinned point(s)",
            b.min.x,
            b.min.y,
            b.min.z,
            b.max.x,
            b.max.y,
            b.max.z,
            m.obstacles.len(),
            m.pins.len()
        );
        if let Source::Scene(scene) = &source {
            for (b, spec) in scene.bodies.iter().enumerate() {
                let name = spec
                    .name
                    .clone()
                    .unwrap_or_else(|| format!("body{}", b + 1));
                print_body(m, b, &name);
            }
        }
    }
    match &m.plane {
        Some(p) => {
            let [a, b, c, d] = p.coeffs;
            let side = if p.side > 0.0 { "positive" } else { "negative" };
            println!("plane          {a} x + {b} y + {c} z + {d} = 0; allowed side: {side} (holds the centre of mass)");
        }
        None => println!("plane          none"),
    }
    match &m.field {
        Some(f) => println!(
            "force field    {0}×{0}×{0} nodes over the box, largest force {1:.6e} N",
            f.res(),
            f.max_magnitude()
        ),
        None => println!("force field    none"),
    }
    if world.is_some() {
        let [nx, ny, nz] = m.body(0).lattice().counts;
        let by_kind = m.body(0).lattice().spring_count_by_kind();
        println!(
            "lattice        {nx}×{ny}×{nz} = {} points, {} springs ({} {}, {} {}, {} {})",
            m.point_count(),
            m.spring_count(),
            by_kind[0],
            SpringKind::Structural.name(),
            by_kind[1],
            SpringKind::Shear.name(),
            by_kind[2],
            SpringKind::Bend.name()
        );
    }
    let e = energy(m, s);
    println!(
        "energy         {:.6e} J: kinetic {:.6e}, spring {:.6e}, collision {:.6e}",
        e.total(),
        e.kinetic,
        e.spring,
        e.collision
    );
    let c = model_centre_of_mass(m, &s.pos);
    let p = momentum(m, &s.vel);
    println!("centre of mass ({:.6}, {:.6}, {:.6}) m", c.x, c.y, c.z);
    println!("momentum       ({:.6}, {:.6}, {:.6}) kg·m/s", p.x, p.y, p.z);
    println!(
        "penetration    {:.6e} m (deepest point into a wall or the plane)",
        max_penetration(m, &s.pos)
    );
    print_contacts(m, &s.pos, &source);
    println!("stable dt      estimate per integrator (stiffest lattice mode at rest, and in this world's initial shape; see docs/cli.md):");
    let (at_rest, initial) = (ModeBounds::at_rest(m), ModeBounds::at(m, &s.pos));
    for integrator in Integrator::ALL {
        let h = at_rest
            .stable_dt(integrator)
            .min(initial.stable_dt(integrator));
        let verdict = if integrator.is_implicit() {
            implicit_verdict(integrator, at_rest.omega2.max(initial.omega2), m.dt)
        } else if h <= 0.0 {
            "unstable at every dt (no damping)".to_string()
        } else if m.dt <= h {
            format!("{h:.3e} s  (dt {} is within it)", m.dt)
        } else {
            format!("{h:.3e} s  (dt {} exceeds it)", m.dt)
        };
        let marker = if integrator == m.integrator { "*" } else { " " };
        println!("             {marker} {:<16} {verdict}", integrator.name());
    }
    Ok(())
}

/// An implicit integrator has no stability limit; what it costs is damping of its own: the
/// energy an undamped oscillation loses per second at `dt`, for the stiffest lattice mode
/// (`omega2`, 1/s²) and for a slow 1 Hz one.
fn implicit_verdict(integrator: Integrator, omega2: f64, dt: f64) -> String {
    let lost_per_second = |w2: f64| {
        let rho = spectral_radius(integrator, w2, 0.0, dt);
        100.0 * (1.0 - rho.powf(2.0 / dt))
    };
    let one_hz = (2.0 * std::f64::consts::PI).powi(2);
    format!(
        "no stability limit; at dt {dt} s the method itself takes {:.3}% of the energy of a 1 Hz \
         oscillation per second, {:.3}% of the stiffest mode's ({:.0} Hz)",
        lost_per_second(one_hz),
        lost_per_second(omega2),
        omega2.sqrt() / (2.0 * std::f64::consts::PI)
    )
}

/// One body's line: points, springs, cells, skin, volume (a mesh's own, `Body::volume`)
/// and mass.
fn print_body(m: &Model, b: usize, name: &str) {
    let body = m.body(b);
    let [nx, ny, nz] = body.lattice().counts;
    let by_kind = body.spring_count_by_kind();
    let skin = match &body.skin {
        Some(skin) => {
            // How far the cage's points rest outside the skin at most: the walls, the plane and
            // the obstacles take it off their depth (docs/scenes.md, "Skins, not cages").
            let clearance = body.clearance().iter().copied().fold(0.0, f64::max);
            format!(
                "skin {} vertices, {} triangles (cage up to {:.4} m outside it)",
                skin.len(),
                skin.triangles.len(),
                clearance
            )
        }
        None => "no skin (the cage is drawn)".to_string(),
    };
    // Stiffness and mass per point are worked out (modulus × spacing, density × volume / points):
    // shown to 6 significant digits, not with the rounding of the arithmetic (15000.000596046448).
    let shown = |x: f64| jello_core::formats::world::significant(x, 6);
    let k = body.material.stiffness.map(shown);
    println!(
        "body {:<9} {name}: {} points (lattice {nx}×{ny}×{nz}), {} springs ({} {}, {} {}, {} {}), \
         {} cells of {:.4} m, {skin}, volume {:.6} m³, mass {:.6} kg ({} kg per point), \
         stiffness {}/{}/{} N/m",
        b + 1,
        body.active_count(),
        body.spring_count(),
        by_kind[0],
        SpringKind::Structural.name(),
        by_kind[1],
        SpringKind::Shear.name(),
        by_kind[2],
        SpringKind::Bend.name(),
        body.cell_count(),
        body.min_spacing(),
        body.volume(),
        body.total_mass(),
        shown(body.material.mass),
        k[0],
        k[1],
        k[2]
    );
    if body.spring_table().is_some() {
        println!("{}", describe_scaled_springs(body));
    }
}

/// The springs of a body that have their own values: how many, and the range of each factor.
fn describe_scaled_springs(body: &jello_core::Body) -> String {
    let mut count = 0;
    let mut range = [[f64::INFINITY, f64::NEG_INFINITY]; 3];
    body.for_each_spring_scale(|_, s| {
        if s != SpringScale::ONE {
            count += 1;
            for (r, f) in range.iter_mut().zip([s.stiffness, s.damping, s.rest]) {
                *r = [r[0].min(f), r[1].max(f)];
            }
        }
    });
    let factors: Vec<String> = ["stiffness", "damping", "rest length"]
        .iter()
        .zip(range)
        .filter(|(_, [lo, hi])| !(*lo == 1.0 && *hi == 1.0))
        .map(|(what, [lo, hi])| {
            if lo == hi {
                format!("{what} ×{lo}")
            } else {
                format!("{what} ×{lo} to ×{hi}")
            }
        })
        .collect();
    format!(
        "               {count} springs with their own values: {}",
        factors.join(", ")
    )
}

/// The pairs of bodies within a cell of each other, with how deep they overlap or how far apart
/// they are, and the deepest overlap and the largest gap of them all.
fn print_contacts(m: &Model, pos: &[jello_core::Vec3], source: &Source) {
    if !m.surfaces_touch() {
        return;
    }
    let names = super::run::body_names(source, m);
    let name = |b: usize| &names[b];
    let pairs = jello_core::contact::closest(m, pos);
    if pairs.is_empty() {
        println!(
            "bodies         none within a cell of another{}",
            if m.self_contact { " or of itself" } else { "" }
        );
        return;
    }
    let deepest = pairs.iter().map(|c| c.depth).fold(0.0f64, f64::max);
    let widest = pairs.iter().map(|c| -c.depth).fold(0.0f64, f64::max);
    println!(
        "bodies         {} pair(s) within a cell of each other: deepest overlap {deepest:.3e} m, largest gap {widest:.3e} m",
        pairs.len()
    );
    for c in &pairs {
        let [a, b] = c.bodies;
        let what = if c.depth > 0.0 {
            format!("overlap {:.3e} m", c.depth)
        } else {
            format!("gap {:.3e} m", -c.depth)
        };
        if a == b {
            println!("               {} with itself: {what}", name(a));
        } else {
            println!("               {} and {}: {what}", name(a), name(b));
        }
    }
}
