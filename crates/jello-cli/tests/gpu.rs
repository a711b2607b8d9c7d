//! `--device gpu` of `jello run` and `jello bench`, in a build with the GPU backend
//! (`cargo test -p jello-cli --features gpu --test gpu`; `make test` runs it). They need a Vulkan
//! adapter: on machines without a GPU, Mesa's lavapipe, which scripts/setup.sh installs.
#![cfg(feature = "gpu")]

mod common;

use std::path::{Path, PathBuf};

use common::TempDir;

fn example(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../../examples")
        .join(name)
}

/// The number after `label` in a run's summary line.
fn number_after(summary: &str, label: &str) -> f64 {
    let rest = &summary[summary.find(label).expect(label) + label.len()..];
    rest.split_whitespace().next().unwrap().parse().unwrap()
}

/// The same outcome in two runs' summaries: energy within 1 %, the same deepest penetration to a
/// millimetre.
fn assert_same_outcome(gpu: &str, cpu: &str) {
    let (e_gpu, e_cpu) = (number_after(gpu, "energy"), number_after(cpu, "energy"));
    assert!((e_gpu - e_cpu).abs() <= 0.01 * e_cpu, "{gpu}\n{cpu}");
    let (d_gpu, d_cpu) = (
        number_after(gpu, "max penetration"),
        number_after(cpu, "max penetration"),
    );
    assert!((d_gpu - d_cpu).abs() < 1e-3, "{gpu}\n{cpu}");
}

#[test]
fn a_world_runs_on_the_gpu_and_ends_where_the_core_does() {
    let dir = TempDir::new("gpu-run");
    let world = example("jello.w");
    let world = world.to_str().unwrap();
    let gpu = dir.succeeds(&[
        "run", world, "--device", "gpu", "--steps", "2000", "-q", "--save", "gpu.w",
    ]);
    let cpu = dir.succeeds(&["run", world, "--steps", "2000", "-q"]);
    assert!(gpu.starts_with("GPU "), "{gpu}");
    assert!(gpu.contains("f32"), "{gpu}");
    assert_same_outcome(&gpu, &cpu);
    // The saved state is a world the CPU reads and goes on from.
    dir.succeeds(&["run", "gpu.w", "--steps", "10", "-q"]);
}

#[test]
fn bench_on_the_gpu_names_its_adapter_and_kernel() {
    let dir = TempDir::new("gpu-bench");
    let out = dir.succeeds(&[
        "bench",
        "--device",
        "gpu",
        "--size",
        "8",
        "--seconds",
        "0.3",
        "--json",
    ]);
    for key in [
        "\"device\": \"gpu\"",
        "\"precision\": \"f32\"",
        "\"adapter\": \"",
    ] {
        assert!(out.contains(key), "{key} missing: {out}");
    }
    // The classic cube fits one workgroup, which a GPU steps resident; lavapipe per stage.
    assert!(
        out.contains("\"gpu_kernel\": \"resident\"") || out.contains("\"gpu_kernel\": \"stages\""),
        "no kernel named: {out}"
    );
}

#[test]
fn several_bodies_and_an_obstacle_run_on_the_gpu_as_on_the_core() {
    // The stack: three cubes on a ball, with friction between them and on the ball.
    let dir = TempDir::new("gpu-stack");
    let stack = example("stack.toml");
    let stack = stack.to_str().unwrap();
    let gpu = dir.succeeds(&["run", stack, "--device", "gpu", "--steps", "500", "-q"]);
    let cpu = dir.succeeds(&["run", stack, "--steps", "500", "-q"]);
    assert_same_outcome(&gpu, &cpu);
}

/// A cube with a shaken pin (as `jello create --shake` writes one).
const SHAKEN: &str = "[[body]]\ncube = { points = [4, 4, 4], size = [1.0, 1.0, 1.0] }\n\
    pins = [{ at = [0.0, 0.0, 0.5], radius = 0.0, shake = { amplitude = [0.1, 0.0, 0.0], \
    frequency = 2.0 } }]\n";

#[test]
fn a_shaken_pin_runs_on_the_gpu_as_on_the_core() {
    let dir = TempDir::new("gpu-shaken");
    std::fs::write(dir.path("shaken.toml"), SHAKEN).unwrap();
    let gpu = dir.succeeds(&[
        "run",
        "shaken.toml",
        "--device",
        "gpu",
        "--steps",
        "600",
        "-q",
    ]);
    let cpu = dir.succeeds(&["run", "shaken.toml", "--steps", "600", "-q"]);
    assert_same_outcome(&gpu, &cpu);
}

#[test]
fn what_the_gpu_does_not_cover_is_refused_with_a_reason() {
    let dir = TempDir::new("gpu-refused");
    std::fs::write(
        dir.path("implicit.toml"),
        format!("[simulation]\nintegrator = \"BackwardEuler\"\n\n{SHAKEN}"),
    )
    .unwrap();
    let out = dir.run(&["run", "implicit.toml", "--device", "gpu", "--steps", "5"]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(
        err.contains("implicit.toml") && err.contains("implicit integrator BackwardEuler"),
        "{err}"
    );
    let out = dir.run(&[
        "run",
        "implicit.toml",
        "--device",
        "gpu",
        "--integrator",
        "RK4",
        "--self-contact",
        "--steps",
        "5",
    ]);
    assert_eq!(out.status.code(), Some(1));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("self-contact"), "{err}");
    let world = example("jello.w");
    let out = dir.run(&[
        "run",
        world.to_str().unwrap(),
        "--device",
        "gpu",
        "--integrator",
        "BackwardEuler",
    ]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stderr).contains("implicit"));
}

#[test]
fn a_blow_up_on_the_gpu_is_reported_like_the_cores() {
    let dir = TempDir::new("gpu-blow-up");
    let world = example("jello.w");
    let out = dir.run(&[
        "run",
        world.to_str().unwrap(),
        "--device",
        "gpu",
        "--integrator",
        "Euler",
        "--dt",
        "0.01",
        "--steps",
        "5000",
        "-q",
        "--save",
        "never.w",
    ]);
    assert_eq!(out.status.code(), Some(3));
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(err.contains("blew up at step"), "{err}");
    assert!(!dir.path("never.w").exists(), "no file from a failed run");
}

/// The warnings of a successful run (its stderr, without the Vulkan loader's complaints).
fn run_warnings(dir: &TempDir, args: &[&str]) -> String {
    let out = dir.run(args);
    let err = String::from_utf8_lossy(&out.stderr).into_owned();
    assert!(out.status.success(), "{err}");
    err.lines()
        .filter(|l| l.starts_with("warning:"))
        .collect::<Vec<_>>()
        .join("\n")
}

/// A cube thrown at 60 m/s at a 5 cm plate with a soft contact ends impaled on it: its bottom
/// layer goes through. On the GPU the states read back (once a submission of steps) are
/// compared, and the run warns as on the CPU, with the same advice; a cube resting on the plate
/// is not reported.
#[test]
fn a_cube_impaled_on_a_plate_on_the_gpu_is_reported_as_on_the_core() {
    let dir = TempDir::new("gpu-tunnel");
    dir.succeeds(&[
        "create",
        "thrown.toml",
        "--cube",
        "3",
        "--size",
        "0.2",
        "--centre",
        "0,0,0.5",
        "--velocity",
        "0,0,-60",
        "--name",
        "cube",
        "--collision-stiffness",
        "1e3",
        "--collision-damping",
        "5",
        "--box=-1,-1,-0.05,1,1,0",
        "--integrator",
        "SymplecticEuler",
        "--dt",
        "0.0005",
    ]);
    let run = |device: &str| {
        run_warnings(
            &dir,
            &[
                "run",
                "thrown.toml",
                "--time",
                "1",
                "-q",
                "--device",
                device,
            ],
        )
    };
    let (gpu, cpu) = (run("gpu"), run("cpu"));
    let through = "warning: thrown.toml: 9 points of body 'cube' passed through obstacle 1 (box, \
                   5 cm thick there) between t = ";
    assert!(
        gpu.starts_with(through) && cpu.starts_with(through),
        "{gpu}\n{cpu}"
    );
    assert!(
        gpu.contains("between states read back up to 512 steps apart they went past its middle"),
        "{gpu}"
    );
    // The body's speed is read off the states' velocities: the advice is the CPU's.
    let advice = |w: &str| w[w.find("; try").expect(w)..].to_string();
    assert_eq!(advice(&gpu), advice(&cpu));
    assert!(gpu.contains("try --dt 0.00021 or less"), "{gpu}");

    dir.succeeds(common::CUBE_RESTING_ON_A_PLATE);
    let rest = run_warnings(
        &dir,
        &["run", "rest.toml", "--time", "2", "-q", "--device", "gpu"],
    );
    assert!(rest.is_empty(), "{rest}");

    // A blade thinner than a coarse cube's lattice spacing passes between its points: the end
    // state read back shows it through the cube.
    dir.succeeds(&[
        "create",
        "blade.toml",
        "--cube",
        "4",
        "--size",
        "0.4",
        "--centre",
        "0,0,0.5",
        "--name",
        "cube",
        "--collision-stiffness",
        "1e4",
        "--collision-damping",
        "5",
        "--box=-0.025,-1,-2,0.025,1,0",
    ]);
    let cut = run_warnings(
        &dir,
        &[
            "run",
            "blade.toml",
            "--time",
            "1.5",
            "-q",
            "--device",
            "gpu",
        ],
    );
    assert!(
        cut.starts_with(
            "warning: blade.toml: body 'cube' ends with obstacle 1 (box, 5 cm thick there) \
             through it"
        ),
        "{cut}"
    );
}
