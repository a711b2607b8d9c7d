//! `jello run`: step a world headless, optionally writing frames and the final state.

use std::path::PathBuf;
use std::time::Instant;

use clap::Args;
use jello_core::contact::ContactWork;
use jello_core::diagnostics::{
    bodies_sunk, energy, max_penetration, obstacles_through, TunnelWatch,
};
use jello_core::Integrator;

use super::{
    cutbacks_range, parse_count, parse_integrator, parse_positive, parse_tolerance,
    require_implicit, Device,
};
use crate::error::CliError;
use crate::export::{steps_between_frames, GlbExport, DEFAULT_FPS};
use crate::frames::{FrameFormat, FrameWriter};
use crate::gpu::Gpu;
use crate::progress::Progress;
use jello_io::{check_writable_target, is_scene, load, write_atomic, Source};

/// Simulated time run when neither `--steps` nor `--time` is given (s).
const DEFAULT_TIME: f64 = 1.0;

/// Steps on the GPU between two readbacks of the state when no frame falls due sooner (the
/// progress bar is updated there), in a model without obstacles to watch for points passing
/// through.
const GPU_READBACK_STEPS: u64 = 2000;

/// Arguments of `jello run`.
// Negative numbers are values (`--dt -0.001`), so that our own checks answer them rather than
// clap taking them for flags.
#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
#[command(group(clap::ArgGroup::new("outputs").args(["frames", "export"]).multiple(true)))]
pub struct RunArgs {
    /// World file (.w) or scene file (.toml) to run.
    pub world: PathBuf,
    /// Number of steps to take [default: as many as 1 s of simulated time takes].
    #[arg(long, conflicts_with = "time", value_parser = parse_count(0))]
    pub steps: Option<u64>,
    /// Simulated time to run (s), rounded up to whole steps.
    #[arg(long, value_parser = parse_positive)]
    pub time: Option<f64>,
    /// Integrator to use instead of the file's (Euler, RK2, RK4, SymplecticEuler,
    /// BackwardEuler, SDIRK2; any case).
    #[arg(long, value_parser = parse_integrator)]
    pub integrator: Option<Integrator>,
    /// Time step to use instead of the file's (s).
    #[arg(long, value_parser = parse_positive)]
    pub dt: Option<f64>,
    /// Implicit integrators: how many times a step whose solve fails may be halved (taken again
    /// as 2, 4, … 2^N substeps of the same method) before the run stops; 0 stops at once
    /// [default: the scene file's `cutbacks`, else 6].
    #[arg(long, value_name = "N", value_parser = cutbacks_range())]
    pub cutbacks: Option<u32>,
    /// Implicit integrators: the residual each step is solved to, per point (m/s, times the
    /// fastest point's speed when that is above 1 m/s; at most 0.1). Looser is faster: 1e-5
    /// steps the 16³ benchmark scene about twice as fast as the default [default: the scene
    /// file's `tolerance`, else 1e-9].
    #[arg(long, value_name = "M/S", value_parser = parse_tolerance)]
    pub tolerance: Option<f64>,
    /// Let each body's surface touch its own (a bar bent over, a torus squashed flat), as a
    /// scene's `[collision] self_contact = true` does, for this run.
    #[arg(long)]
    pub self_contact: bool,
    /// After the summary, where the run's wall-clock time went: the contacts between bodies
    /// (finding them and their forces) against the rest of the run.
    #[arg(long)]
    pub timings: bool,
    /// Save the final state as a world file, or as a scene file when running a scene (written
    /// only if the run succeeds).
    #[arg(long, value_name = "OUT.w|OUT.toml")]
    pub save: Option<PathBuf>,
    /// Write frames into this folder (created when missing).
    #[arg(long, value_name = "DIR")]
    pub frames: Option<PathBuf>,
    /// Write a frame every K steps [default: --fps frames per simulated second, 30 unless given:
    /// a frame every round(1/(fps·dt)) steps, as --export].
    #[arg(long, value_name = "K", requires = "frames", value_parser = parse_count(1))]
    pub every: Option<u64>,
    /// Frame file format.
    #[arg(long, value_enum, default_value_t = FrameFormat::Ply, requires = "frames")]
    pub format: FrameFormat,
    /// Write the surface's motion (each body's skin, or its cage) as one animated binary glTF 2.0
    /// file (morph targets), for Blender, three.js and other glTF readers; written only if the
    /// run succeeds.
    #[arg(long, value_name = "OUT.glb")]
    pub export: Option<PathBuf>,
    /// Frames per simulated second of the --export file, and of --frames without --every (a
    /// frame every round(1/(fps·dt)) steps).
    #[arg(long, value_name = "F", default_value_t = DEFAULT_FPS, requires = "outputs", value_parser = parse_positive)]
    pub fps: f64,
    /// Where to step: the f64 core on the CPU, or the f32 shaders on a GPU (the explicit
    /// integrators, with several bodies, obstacles, friction, pins and pulls; docs/gpu.md).
    #[arg(long, value_enum, default_value_t = Device::Cpu)]
    pub device: Device,
    /// No progress bar.
    #[arg(long, short)]
    pub quiet: bool,
}

/// Runs the world and prints a one-line summary.
pub fn run(args: RunArgs) -> Result<(), CliError> {
    let (mut sim, source) = load(&args.world, args.integrator, args.dt)?;
    if let Some(n) = args.cutbacks {
        require_implicit(sim.model.integrator, "--cutbacks")?;
        sim.model.newton.cutbacks = n;
    }
    if let Some(tolerance) = args.tolerance {
        require_implicit(sim.model.integrator, "--tolerance")?;
        sim.model.newton.tolerance = tolerance;
    }
    if args.self_contact {
        sim.model.self_contact = true;
    }
    let name = args.world.display().to_string();
    if let Some(out) = &args.save {
        check_writable_target(out)?;
        let scene = matches!(source, Source::Scene(_));
        if scene != is_scene(out) {
            return Err(CliError::input(format!(
                "{}: a {} saves as {}",
                out.display(),
                if scene { "scene" } else { "world" },
                if scene { ".toml" } else { ".w" }
            )));
        }
    }

    let dt = sim.model.dt;
    let total = match (args.steps, args.time) {
        (Some(n), _) => n,
        (None, t) => steps_for(t.unwrap_or(DEFAULT_TIME), dt),
    };
    let every = args.every.unwrap_or(steps_between_frames(args.fps, dt));
    // On a GPU the state lives there; it is read back when a frame is due, and now and then.
    let mut gpu = match args.device {
        Device::Gpu => Some(Gpu::open(&sim.model, &sim.state, &sim.control, &name)?),
        Device::Cpu => None,
    };
    let mut frames = match &args.frames {
        Some(dir) => Some(FrameWriter::new(
            dir,
            args.format,
            &sim.model,
            body_names(&source, &sim.model),
        )?),
        None => None,
    };

    let mut export = match &args.export {
        Some(path) => Some(GlbExport::new(
            path,
            &sim.model,
            &body_names(&source, &sim.model),
            args.fps,
            total,
        )?),
        None => None,
    };

    // Step, reading the penetration off each new state (on a GPU, the shader tracks it) and
    // writing frames as due.
    let mut progress = Progress::new(total, args.quiet);
    let mut deepest = max_penetration(&sim.model, &sim.state.pos);
    if let Some(f) = frames.as_mut() {
        f.write(&sim.model, &sim.state)?;
    }
    if let Some(x) = export.as_mut() {
        x.record(&sim.model, &sim.state)?;
    }
    // Each state is compared with the last for points that passed through an obstacle: every
    // step on the CPU; on a GPU every state read back, the straight segment between two standing
    // for the points' paths, so then the state is read back after every submission of steps
    // (the GPU waits for its status there anyway).
    let mut watch =
        TunnelWatch::watches(&sim.model).then(|| TunnelWatch::new(&sim.model, &sim.state));
    let readback_steps = match (&gpu, &watch) {
        (Some(gpu), Some(_)) => gpu.batch_steps().min(GPU_READBACK_STEPS),
        _ => GPU_READBACK_STEPS,
    };
    let start = Instant::now();
    let mut done = 0;
    while done < total {
        let stepped = match gpu.as_mut() {
            None => sim
                .step()
                .map(|()| 1)
                .map_err(|blow_up| CliError::blow_up(format!("{name}: {blow_up}"))),
            Some(gpu) => {
                // Up to the next step where a frame or an export frame is due.
                let mut next = (done + readback_steps).min(total);
                if frames.is_some() {
                    next = next.min((done / every + 1) * every);
                }
                if let Some(x) = &export {
                    next = next.min((done / x.every() + 1) * x.every());
                }
                gpu.step(next - done, &name)
                    .and_then(|()| gpu.read_state(&name))
                    .map(|state| {
                        sim.state = state;
                        next - done
                    })
            }
        };
        let taken = match stepped {
            Ok(k) => k,
            Err(e) => {
                progress.finish();
                return Err(e);
            }
        };
        done += taken;
        if let Some(w) = watch.as_mut() {
            w.observe_apart(&sim.model, &sim.state, taken);
        }
        deepest = match &gpu {
            None => deepest.max(max_penetration(&sim.model, &sim.state.pos)),
            Some(gpu) => deepest.max(gpu.max_penetration()),
        };
        if let Some(f) = frames.as_mut() {
            if done % every == 0 {
                f.write(&sim.model, &sim.state)?;
            }
        }
        if let Some(x) = export.as_mut() {
            if done % x.every() == 0 {
                x.record(&sim.model, &sim.state)?;
            }
        }
        progress.update(done);
    }
    let wall = start.elapsed().as_secs_f64();
    progress.finish();
    // The export ends on the final state, whether or not a frame fell due there.
    if let Some(x) = export.as_mut() {
        if total % x.every() != 0 {
            x.record(&sim.model, &sim.state)?;
        }
    }

    // Both outputs made before either is written, so that neither is left alone by a failure
    // to make the other.
    let glb = match &export {
        Some(x) => {
            let stem = args
                .world
                .file_stem()
                .map_or("jello".into(), |s| s.to_string_lossy());
            Some(x.bytes(&stem)?)
        }
        None => None,
    };
    if let Some(out) = &args.save {
        let text = source
            .state_text(&sim)
            .map_err(|e| CliError::io(format!("{}: {e}", out.display())))?;
        write_atomic(out, text.as_bytes())?;
    }
    if let (Some(x), Some(bytes)) = (&export, &glb) {
        x.write(bytes)?;
    }

    let e = energy(&sim.model, &sim.state);
    if let Some(gpu) = &gpu {
        print!("GPU {}, f32: ", gpu.adapter());
    }
    let mut summary = format!(
        "{total} steps, t = {:.6} s, wall {:.3} s, {:.0} steps/s, max penetration {:.3e} m, \
         energy {:.6e} J (kinetic {:.3e}, spring {:.3e}, collision {:.3e})",
        sim.state.time,
        wall,
        total as f64 / wall.max(1e-9),
        deepest,
        e.total(),
        e.kinetic,
        e.spring,
        e.collision
    );
    let cut = sim.cutback_stats();
    if cut.split_steps > 0 {
        summary.push_str(&format!(
            ", {} steps taken in parts ({} substeps, the smallest dt/{})",
            cut.split_steps,
            cut.substeps,
            1u64 << cut.finest
        ));
    }
    if gpu.is_none() && sim.model.integrator.is_implicit() && total > 0 {
        summary.push_str(&super::solver_work_per_step(sim.solver_stats(), total));
    }
    if let Some(f) = &frames {
        summary.push_str(&format!(", {} frames", f.written()));
    }
    if let Some(x) = &export {
        summary.push_str(&format!(", {} frames exported", x.frames()));
    }
    println!("{summary}");
    if args.timings && gpu.is_some() {
        println!("timings: wall {wall:.3} s (the GPU's passes are not timed apart)");
    } else if args.timings {
        let contacts = sim.contact_time().as_secs_f64();
        println!(
            "timings: wall {wall:.3} s, of it contacts between bodies {contacts:.3} s ({:.1} %), \
             the rest {:.3} s",
            100.0 * contacts / wall.max(1e-9),
            (wall - contacts).max(0.0)
        );
        let work = sim.contact_work();
        if work.passes > 0 {
            println!("{}", contact_work_line(&work));
        }
    }
    // Warnings after the summary, on stderr: the run itself succeeded.
    let names = body_names(&source, &sim.model);
    let crossings = watch.as_ref().map_or(&[][..], |w| w.crossings());
    for c in crossings {
        eprintln!(
            "warning: {name}: {}",
            super::tunnelling::crossing_warning(&sim.model, c, &names)
        );
    }
    // An obstacle through a body at the end that no point was seen passing (it passed between
    // the body's points, or between two states read back from a GPU).
    for t in obstacles_through(&sim.model, &sim.state.pos) {
        if !crossings
            .iter()
            .any(|c| (c.body, c.obstacle) == (t.body, t.obstacle))
        {
            eprintln!(
                "warning: {name}: {}",
                jello_core::diagnostics::through_warning(&sim.model, &t, &names)
            );
        }
    }
    // Bodies that end deep inside each other (one thrown into another, or a contact too soft).
    for s in bodies_sunk(&sim.model, &sim.state.pos) {
        eprintln!(
            "warning: {name}: {}",
            super::tunnelling::sunk_warning(&sim.model, &s, &names)
        );
    }
    Ok(())
}

/// Whole steps covering `time` at `dt`: rounded to the nearest step when `time/dt` is within
/// rounding error of an integer, else rounded up.
fn steps_for(time: f64, dt: f64) -> u64 {
    let q = time / dt;
    let nearest = q.round();
    if (q - nearest).abs() <= 1e-9 * nearest.max(1.0) {
        nearest as u64
    } else {
        q.ceil() as u64
    }
}

/// The bodies' names: a scene's, else `body1`, `body2`, ...
pub(crate) fn body_names(source: &Source, model: &jello_core::Model) -> Vec<String> {
    match source {
        Source::Scene(scene) => scene.body_names(),
        Source::World(_) => (1..=model.bodies().len())
            .map(|b| format!("body{b}"))
            .collect(),
    }
}

/// The `--timings` line of the contact passes' work (see [`ContactWork`]): the same on any
/// machine and thread count, where the timings line's times drift.
fn contact_work_line(work: &ContactWork) -> String {
    let per = |n: u64, of: u64| n as f64 / of.max(1) as f64;
    format!(
        "contact work: {} passes, {} sorts of the grid; {:.0} samples listed a sort; a pass \
         placed {:.1} samples in {:.1} cells and found {:.1} touches",
        work.passes,
        work.sorts,
        per(work.listed, work.sorts),
        per(work.placed, work.passes),
        per(work.placings, work.passes),
        per(work.touches, work.passes),
    )
}

#[cfg(test)]
mod tests {
    use super::steps_for;

    #[test]
    fn time_to_steps_rounds_only_rounding_error() {
        assert_eq!(steps_for(1.0, 0.0005), 2000);
        assert_eq!(steps_for(0.3, 0.1), 3);
        assert_eq!(steps_for(0.35, 0.1), 4);
    }
}
