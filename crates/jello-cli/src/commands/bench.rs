//! `jello bench`: steps per second and spring evaluations per second on the benchmark scene.

use std::time::{Duration, Instant};

use clap::Args;
use jello_core::benchmark::{self, Job};
use jello_core::diagnostics::{max_penetration, model_centre_of_mass};
use jello_core::{compute::simd, Integrator, Model, Simulation, SolverStats, State};

use super::{
    parse_integrator, parse_positive, parse_tolerance, require_implicit, solver_work_per_step,
    Device,
};
use crate::error::CliError;
use crate::gpu::Gpu;

/// Arguments of `jello bench`.
// Negative numbers are values (`--dt -0.001`), so that our own checks answer them rather than
// clap taking them for flags.
#[derive(Args, Debug)]
#[command(allow_negative_numbers = true)]
pub struct BenchArgs {
    /// What to step: the benchmark scene (a cube thrown about the box, see BENCHMARKS.md), or
    /// the frame-rate job, a 1 m, 1 kg cube on a floor, resting or dropped from 0.5 m (the
    /// scene of `jello create --cube N --total-mass 1 --modulus 1400 --viscosity 1.75 --field
    /// gravity --plane 0,0,1,0`), measured over its simulated time (3 s up to 8³, 2 s up to
    /// 16³, 1 s beyond) unless `--seconds` or `--steps` says otherwise.
    #[arg(long, value_enum, default_value_t = BenchJob::Throw)]
    pub job: BenchJob,
    /// Points per side of the N×N×N lattice.
    #[arg(long, default_value_t = 8, value_parser = clap::value_parser!(u64).range(2..=512))]
    pub size: u64,
    /// Integrator (Euler, RK2, RK4, SymplecticEuler, BackwardEuler, SDIRK2).
    #[arg(long, value_parser = parse_integrator, default_value = "RK4")]
    pub integrator: Integrator,
    /// Time step (s) [default: the benchmark scene's 0.0005; for a job, 1/60 s for an implicit
    /// integrator and 90 % of the stable step for an explicit one].
    #[arg(long, value_parser = parse_positive)]
    pub dt: Option<f64>,
    /// Implicit integrators: the residual each step is solved to (m/s per point, times the
    /// fastest point's speed above 1 m/s; at most 0.1) [default: 1e-9].
    #[arg(long, value_name = "M/S", value_parser = parse_tolerance)]
    pub tolerance: Option<f64>,
    /// Worker threads (1 = the calling thread only).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u64).range(1..=256))]
    pub threads: u64,
    /// Measured time, after a warm-up (s) [default: 3; for a job, its simulated time].
    #[arg(long, value_parser = parse_positive)]
    pub seconds: Option<f64>,
    /// Measure exactly N steps instead of about `--seconds`, from the scene's start (on the GPU,
    /// explicit integrators only, after the warm-up's steps): the same work on every machine and
    /// build (an implicit integrator's steps cost more while the benchmark's cube is thrown
    /// about than once it slides on the floor).
    #[arg(long, value_name = "N", conflicts_with = "seconds",
          value_parser = clap::value_parser!(u64).range(1..))]
    pub steps: Option<u64>,
    /// Also report each measured step: its wall-clock time and, for an implicit integrator,
    /// its Newton and linear iterations and assemblies of `A` (the steps are taken one at a
    /// time; CPU only).
    #[arg(long)]
    pub per_step: bool,
    /// Print one JSON object instead of text.
    #[arg(long)]
    pub json: bool,
    /// Where to step: the f64 core on the CPU (`--threads` threads), or the f32 shaders on a
    /// GPU (the output names the adapter).
    #[arg(long, value_enum, default_value_t = Device::Cpu)]
    pub device: Device,
}

/// What `jello bench` steps.
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum BenchJob {
    /// The benchmark scene: a cube thrown about the box.
    Throw,
    /// A cube resting on a floor.
    Rest,
    /// A cube dropped onto a floor from 0.5 m.
    Drop,
}

impl BenchJob {
    /// The frame-rate job, if it is one.
    fn job(self) -> Option<Job> {
        match self {
            BenchJob::Throw => None,
            BenchJob::Rest => Some(Job::Rest),
            BenchJob::Drop => Some(Job::Drop),
        }
    }
}

/// The measured time when `--steps` does not say otherwise (s).
const DEFAULT_SECONDS: f64 = 3.0;

/// How long the measured run lasts.
#[derive(Clone, Copy, Debug)]
enum Span {
    /// About this many seconds (whole batches of steps).
    Seconds(f64),
    /// Exactly this many steps.
    Steps(u64),
    /// The steps of this much simulated time (s).
    Simulated(f64),
}

impl Span {
    /// The warm-up before the measured run: a tenth of the measured time (of the default time
    /// for a number of steps), within 0.05 to 1 s.
    fn warm_up(self) -> Duration {
        let seconds = match self {
            Span::Seconds(s) => s,
            Span::Steps(_) | Span::Simulated(_) => DEFAULT_SECONDS,
        };
        Duration::from_secs_f64((seconds * 0.1).clamp(0.05, 1.0))
    }

    /// The next batch of at most `batch` steps, `done` steps and `elapsed` into the measured
    /// run; `None` when the run is over.
    fn next_batch(self, batch: u64, done: u64, elapsed: Duration) -> Option<u64> {
        match self {
            Span::Seconds(s) => (elapsed.as_secs_f64() < s).then_some(batch),
            Span::Steps(n) => (done < n).then(|| batch.min(n - done)),
            Span::Simulated(_) => unreachable!("a simulated time is counted in steps first"),
        }
    }

    /// The span at time step `dt` (s): a simulated time as its steps (at least one).
    fn at_step(self, dt: f64) -> Span {
        match self {
            Span::Simulated(t) => Span::Steps(((t / dt).round() as u64).max(1)),
            span => span,
        }
    }
}

/// What one benchmark run measured.
struct Measurement {
    points: usize,
    springs: usize,
    /// Time step (s).
    dt: f64,
    steps: u64,
    wall: f64,
    /// Measured steps that an implicit integrator took in parts (see `jello_core::integrate::cutback`).
    split_steps: u64,
    /// The implicit integrator's tolerance (m/s); `None` for an explicit one.
    tolerance: Option<f64>,
    /// The implicit solver's work over the measured steps; `None` for an explicit integrator.
    solver: Option<SolverStats>,
    /// Where a frame-rate job ended; `None` for the benchmark scene.
    end: Option<End>,
    /// Each measured step, with `--per-step` (else empty).
    steps_each: Vec<StepRecord>,
}

/// One measured step of `--per-step`.
#[derive(Clone, Copy, Debug)]
struct StepRecord {
    /// Wall-clock time (s).
    wall: f64,
    /// The implicit solver's work in the step; `None` for an explicit integrator.
    solver: Option<SolverStats>,
}

/// Where a frame-rate job's cube is after the measured run: so that a table of speeds can say
/// that the run did the job (the cube rests on the floor rather than through it).
#[derive(Clone, Copy, Debug)]
struct End {
    /// Height of the centre of mass above the floor (m).
    centre: f64,
    /// Deepest penetration into the floor (m).
    depth: f64,
}

impl End {
    /// The end of `job` with the points at `pos` (`None` for the benchmark scene).
    fn of(job: Option<Job>, model: &Model, pos: &[jello_core::Vec3]) -> Option<End> {
        job.map(|_| End {
            centre: model_centre_of_mass(model, pos).z,
            depth: max_penetration(model, pos),
        })
    }
}

/// Runs the benchmark scene (see [`benchmark::scene`]) and prints the rates.
pub fn bench(args: BenchArgs) -> Result<(), CliError> {
    if args.tolerance.is_some() {
        require_implicit(args.integrator, "--tolerance")?;
    }
    let threads = args.threads as usize;
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| CliError::input(format!("cannot start {threads} threads: {e}")))?;
    if args.per_step && args.device == Device::Gpu {
        return Err(CliError::usage(
            "--per-step: the CPU's steps only (the GPU's are queued, not timed one by one)",
        ));
    }
    let job = args.job.job();
    let n = args.size as usize;
    let span = match (args.steps, args.seconds, job) {
        (Some(steps), _, _) => Span::Steps(steps),
        (None, Some(seconds), _) => Span::Seconds(seconds),
        (None, None, Some(_)) => Span::Simulated(Job::simulated_time(n)),
        (None, None, None) => Span::Seconds(DEFAULT_SECONDS),
    };
    let warm = span.warm_up();
    let (m, adapter, kernel) = match args.device {
        Device::Cpu => {
            let m = pool.install(|| {
                let setup = Setup {
                    job,
                    n,
                    integrator: args.integrator,
                    dt: args.dt,
                    tolerance: args.tolerance,
                };
                measure(setup, warm, span, args.per_step)
            })?;
            (m, None, None)
        }
        Device::Gpu => {
            let (m, adapter, kernel) = measure_gpu(job, n, args.integrator, args.dt, warm, span)?;
            (m, Some(adapter), Some(kernel))
        }
    };

    let steps_per_s = m.steps as f64 / m.wall;
    let real_time = steps_per_s * m.dt;
    // An implicit step evaluates the forces as often as its solver needs: no fixed count.
    let evals_per_s = args
        .integrator
        .force_evaluations()
        .map(|k| (m.springs * k) as f64 * steps_per_s);
    let peak = peak_rss_mib();
    let tier = simd::active_tier();
    let (device, precision) = match args.device {
        Device::Cpu => ("cpu", "f64"),
        Device::Gpu => ("gpu", "f32"),
    };
    if args.json {
        // The solver's work per measured step.
        let per_step = |count: u64| count as f64 / m.steps as f64;
        let solver_json = [
            (
                "newton_iterations_per_step",
                m.solver.map(|s| s.newton_iterations),
            ),
            (
                "linear_iterations_per_step",
                m.solver.map(|s| s.linear_iterations),
            ),
            ("assemblies_per_step", m.solver.map(|s| s.assemblies)),
        ]
        .map(|(key, count)| {
            let value = count.map_or("null".to_string(), |c| format!("{:.3}", per_step(c)));
            format!("\"{key}\": {value}")
        })
        .join(", ");
        let adapter_json = adapter.as_ref().map_or("null".to_string(), |a| {
            format!("\"{}\"", a.replace('\\', "\\\\").replace('"', "\\\""))
        });
        let kernel_json = kernel.map_or("null".to_string(), |k| format!("\"{k}\""));
        let per_step_json = if args.per_step {
            let each = m.steps_each.iter().map(|r| {
                let work = r.solver.map_or(String::new(), |w| {
                    format!(
                        ", \"newton_iterations\": {}, \"linear_iterations\": {}, \"assemblies\": {}",
                        w.newton_iterations, w.linear_iterations, w.assemblies
                    )
                });
                format!("{{\"seconds\": {:.6}{work}}}", r.wall)
            });
            format!("[{}]", each.collect::<Vec<_>>().join(", "))
        } else {
            "null".to_string()
        };
        println!(
            "{{\"impl\": \"jello\", \"job\": \"{}\", \"size\": {}, \"points\": {}, \"springs\": {}, \"integrator\": \"{}\", \"tolerance\": {}, \
             \"device\": \"{device}\", \"adapter\": {adapter_json}, \"gpu_kernel\": {kernel_json}, \"precision\": \"{precision}\", \
             \"threads\": {threads}, \"simd\": \"{tier}\", \"dt\": {}, \"steps\": {}, \"seconds\": {:.3}, \"steps_per_s\": {:.1}, \
             \"real_time\": {:.4}, \"split_steps\": {}, {solver_json}, \"spring_evals_per_s\": {}, \"end_centre_z\": {}, \"end_depth\": {}, \
             \"peak_rss_mib\": {}, \"per_step\": {per_step_json}, \"version\": \"{}\"}}",
            job.map_or("throw", Job::name),
            args.size,
            m.points,
            m.springs,
            args.integrator,
            m.tolerance.map_or("null".to_string(), |t| format!("{t:e}")),
            m.dt,
            m.steps,
            m.wall,
            steps_per_s,
            real_time,
            m.split_steps,
            evals_per_s.map_or("null".to_string(), |e| format!("{e:.1}")),
            m.end.map_or("null".to_string(), |e| format!("{:e}", e.centre)),
            m.end.map_or("null".to_string(), |e| format!("{:e}", e.depth)),
            peak.map_or("null".to_string(), |p| format!("{p:.1}")),
            env!("CARGO_PKG_VERSION")
        );
    } else {
        if args.per_step {
            print_steps(&m.steps_each);
        }
        let on = match &adapter {
            None => format!("{threads} thread(s), {tier}"),
            Some(a) => format!("GPU {a}, f32, {} kernel", kernel.unwrap_or_default()),
        };
        let what = match job {
            None => "lattice",
            Some(Job::Rest) => "cube resting on a floor",
            Some(Job::Drop) => "cube dropped onto a floor",
        };
        println!(
            "{n}³ {what} ({} points, {} springs), {}, dt {} s, {on}: {:.0} steps/s, {:.3}× real time{}{} \
             ({} steps in {:.2} s{}{}){}",
            m.points,
            m.springs,
            match m.tolerance {
                Some(t) => format!("{} (tolerance {t:e} m/s)", args.integrator),
                None => args.integrator.to_string(),
            },
            m.dt,
            steps_per_s,
            real_time,
            evals_per_s.map_or(String::new(), |e| format!(", {:.1} M spring evaluations/s", e / 1e6)),
            m.solver
                .map_or(String::new(), |s| solver_work_per_step(s, m.steps)),
            m.steps,
            m.wall,
            match m.split_steps {
                0 => String::new(),
                k => format!(", {k} of them taken in parts"),
            },
            peak.map_or(String::new(), |p| format!(", peak memory {p:.0} MiB")),
            m.end.map_or(String::new(), |e| format!(
                "; it ends with its centre of mass {:.4} m above the floor, {:.2e} m deep in it",
                e.centre, e.depth
            )),
        );
    }
    Ok(())
}

/// The benchmark scene (see [`benchmark::scene`]) or the frame-rate `job` (see [`Job`]) of `n³`
/// points, at `dt` and solved to `tolerance` if given.
fn scene(
    job: Option<Job>,
    n: usize,
    integrator: Integrator,
    dt: Option<f64>,
    tolerance: Option<f64>,
) -> Result<(Model, State), CliError> {
    if let Some(job) = job {
        let (mut model, state) = job
            .scene(n, integrator, dt)
            .map_err(|e| CliError::usage(format!("--job {}: {e}", job.name())))?;
        if let Some(tolerance) = tolerance {
            model.newton.tolerance = tolerance;
        }
        return Ok((model, state));
    }
    let (model, state) =
        benchmark::scene(n, integrator).map_err(|e| CliError::input(e.to_string()))?;
    let mut model = match dt {
        Some(dt) => model
            .to_builder()
            .dt(dt)
            .build()
            .map_err(|e| CliError::usage(format!("--dt: {e}")))?,
        None => model,
    };
    if let Some(tolerance) = tolerance {
        model.newton.tolerance = tolerance;
    }
    Ok((model, state))
}

/// Warms up on `setup`'s scene for `warm` (at least a few steps), then steps for the `span`,
/// one step at a time and each recorded with `per_step`. The measured run starts again from the
/// initial state. A blow-up (the scene never blows up at its dt) is an error.
fn measure(
    setup: Setup,
    warm: Duration,
    span: Span,
    per_step: bool,
) -> Result<Measurement, CliError> {
    let Setup {
        job,
        n,
        integrator,
        dt,
        tolerance,
    } = setup;
    let (model, state) = scene(job, n, integrator, dt, tolerance)?;
    let tolerance = integrator.is_implicit().then_some(model.newton.tolerance);
    let dt = model.dt;
    let span = span.at_step(dt);
    let (points, springs) = (model.point_count(), model.spring_count());
    let mut sim = Simulation::new(model, state);
    let advance = |sim: &mut Simulation, steps: u64| -> Result<(), CliError> {
        sim.advance(steps)
            .map_err(|e| CliError::blow_up(format!("benchmark scene blew up: {e}")))
    };

    // Warm-up: caches, page faults, thread start-up; also sizes the batches.
    let start = Instant::now();
    let mut warm_steps = 0u64;
    while start.elapsed() < warm || warm_steps < 3 {
        advance(&mut sim, 1)?;
        warm_steps += 1;
    }
    let step_time = start.elapsed().as_secs_f64() / warm_steps as f64;
    let batch = if per_step {
        1
    } else {
        ((0.05 / step_time) as u64).max(1)
    };

    // Back to the start, a simulation made anew rather than kept as a copy (at 128³ a copy
    // would be 96 MiB of the peak memory this reports; the old one goes first), and anew so
    // that an implicit solver's kept matrices do not depend on how many steps the warm-up
    // took: the measured run does the same work on every machine.
    drop(sim);
    let (model, state) = scene(job, n, integrator, Some(dt), tolerance)?;
    let mut sim = Simulation::new(model, state);
    let split_before = sim.cutback_stats().split_steps;
    let solver_before = sim.solver_stats();
    let implicit = integrator.is_implicit();
    let mut steps_each = Vec::new();
    let start = Instant::now();
    let mut steps = 0u64;
    while let Some(batch) = span.next_batch(batch, steps, start.elapsed()) {
        let (began, before) = (Instant::now(), sim.solver_stats());
        advance(&mut sim, batch)?;
        if per_step {
            steps_each.push(StepRecord {
                wall: began.elapsed().as_secs_f64(),
                solver: implicit.then(|| sim.solver_stats() - before),
            });
        }
        steps += batch;
    }
    Ok(Measurement {
        points,
        springs,
        dt,
        steps,
        wall: start.elapsed().as_secs_f64(),
        split_steps: sim.cutback_stats().split_steps - split_before,
        solver: implicit.then(|| sim.solver_stats() - solver_before),
        tolerance,
        end: End::of(job, &sim.model, &sim.state.pos),
        steps_each,
    })
}

/// What [`measure`] steps: the frame-rate `job` or the benchmark scene (`None`) of `n³` points,
/// by `integrator` at `dt` and to `tolerance` where given.
#[derive(Clone, Copy, Debug)]
struct Setup {
    job: Option<Job>,
    n: usize,
    integrator: Integrator,
    dt: Option<f64>,
    tolerance: Option<f64>,
}

/// [`measure`] on the GPU: after the warm-up (which also compiles the shaders' pipelines), the
/// measured run goes on from the warmed-up state. Returns the measurement, the adapter and the
/// kernel (`resident` or `stages`).
fn measure_gpu(
    job: Option<Job>,
    n: usize,
    integrator: Integrator,
    dt: Option<f64>,
    warm: Duration,
    span: Span,
) -> Result<(Measurement, String, String), CliError> {
    let (model, state) = scene(job, n, integrator, dt, None)?;
    let span = span.at_step(model.dt);
    let (points, springs) = (model.point_count(), model.spring_count());
    let name = match job {
        None => format!("the {n}³ benchmark scene"),
        Some(job) => format!("the {n}³ {} job", job.name()),
    };
    let mut gpu = Gpu::open(&model, &state, &Default::default(), &name)?;
    let start = Instant::now();
    let mut warm_steps = 0u64;
    let mut batch = 1u64;
    while start.elapsed() < warm || warm_steps < 3 {
        gpu.step(batch, &name)?;
        warm_steps += batch;
        batch = (batch * 2).min(4096);
    }
    let per_step = start.elapsed().as_secs_f64() / warm_steps as f64;
    let batch = ((0.05 / per_step) as u64).max(1);
    let start = Instant::now();
    let mut steps = 0u64;
    while let Some(batch) = span.next_batch(batch, steps, start.elapsed()) {
        gpu.step(batch, &name)?;
        steps += batch;
    }
    let wall = start.elapsed().as_secs_f64();
    let end = match job {
        Some(_) => End::of(job, &model, &gpu.read_state(&name)?.pos),
        None => None,
    };
    Ok((
        Measurement {
            points,
            springs,
            dt: model.dt,
            steps,
            wall,
            split_steps: 0,
            tolerance: None,
            solver: None,
            end,
            steps_each: Vec::new(),
        },
        gpu.adapter(),
        gpu.kernel(),
    ))
}

/// `--per-step`'s table: each measured step's wall-clock time and, for an implicit integrator,
/// its solver's work.
fn print_steps(steps: &[StepRecord]) {
    let implicit = steps.first().is_some_and(|r| r.solver.is_some());
    if implicit {
        println!("step  wall (ms)  Newton  linear  assemblies");
    } else {
        println!("step  wall (ms)");
    }
    for (k, r) in steps.iter().enumerate() {
        let ms = r.wall * 1e3;
        match r.solver {
            Some(w) => println!(
                "{k:>4}  {ms:>9.3}  {:>6}  {:>6}  {:>10}",
                w.newton_iterations, w.linear_iterations, w.assemblies
            ),
            None => println!("{k:>4}  {ms:>9.3}"),
        }
    }
}

/// Peak resident memory of this process (MiB), from /proc on Linux.
fn peak_rss_mib() -> Option<f64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kib: f64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib / 1024.0)
}
