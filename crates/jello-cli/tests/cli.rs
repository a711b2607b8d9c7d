//! End-to-end tests of the `jello` binary: each test runs it in a fresh temporary folder.

use std::fs;
use std::path::{Path, PathBuf};
use std::process::Output;

use jello_core::{Integrator, ReadOptions, World};

mod common;

use common::TempDir;

impl TempDir {
    /// Runs `jello ARGS` in this folder.
    fn jello(&self, args: &[&str]) -> Run {
        Run::new(args, self.run(args))
    }

    /// Names of the files in the folder (not recursive), sorted.
    fn files(&self) -> Vec<String> {
        let mut names: Vec<String> = fs::read_dir(&self.0)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        names.sort();
        names
    }

    fn assert_no_temp_files(&self) {
        let stray: Vec<String> = self
            .files()
            .into_iter()
            .filter(|n| n.contains(".tmp-"))
            .collect();
        assert!(stray.is_empty(), "stray temporary files: {stray:?}");
    }

    fn write(&self, name: &str, bytes: impl AsRef<[u8]>) {
        fs::write(self.path(name), bytes).unwrap();
    }

    fn read(&self, name: &str) -> Vec<u8> {
        fs::read(self.path(name)).unwrap_or_else(|e| panic!("{name}: {e}"))
    }

    /// `jello create NAME EXTRA...`, which must succeed.
    fn create(&self, name: &str, extra: &[&str]) {
        let mut args = vec!["create", name];
        args.extend_from_slice(extra);
        self.jello(&args).success();
        assert!(self.path(name).is_file());
    }
}

/// A finished run of the binary.
struct Run {
    args: String,
    code: Option<i32>,
    stdout: String,
    stderr: String,
}

impl Run {
    fn new(args: &[&str], out: Output) -> Self {
        Run {
            args: args.join(" "),
            code: out.status.code(),
            stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
            stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
        }
    }

    fn context(&self) -> String {
        format!(
            "jello {}\n--- exit {:?}\n--- stdout\n{}--- stderr\n{}",
            self.args, self.code, self.stdout, self.stderr
        )
    }

    fn success(&self) -> &Self {
        assert_eq!(self.code, Some(0), "{}", self.context());
        self.no_panic()
    }

    fn code(&self, code: i32) -> &Self {
        assert_eq!(self.code, Some(code), "{}", self.context());
        self.no_panic()
    }

    fn no_panic(&self) -> &Self {
        for text in [&self.stdout, &self.stderr] {
            assert!(!text.contains("panicked"), "{}", self.context());
            assert!(!text.contains("RUST_BACKTRACE"), "{}", self.context());
        }
        self
    }

    fn stdout_has(&self, needle: &str) -> &Self {
        assert!(
            self.stdout.contains(needle),
            "stdout lacks {needle:?}\n{}",
            self.context()
        );
        self
    }

    fn stderr_has(&self, needle: &str) -> &Self {
        assert!(
            self.stderr.contains(needle),
            "stderr lacks {needle:?}\n{}",
            self.context()
        );
        self
    }

    /// The line number in `FILE:LINE:` on stderr; fails when there is none.
    fn stderr_line_of(&self, file: &str) -> usize {
        line_after(&self.stderr, file)
            .unwrap_or_else(|| panic!("stderr lacks \"{file}:<line>:\"\n{}", self.context()))
    }
}

/// The `N` of the first `FILE:N:` in `text`.
fn line_after(text: &str, file: &str) -> Option<usize> {
    let pat = format!("{file}:");
    text.match_indices(&pat).find_map(|(i, _)| {
        let rest = &text[i + pat.len()..];
        let digits: String = rest.chars().take_while(char::is_ascii_digit).collect();
        let after = rest[digits.len()..].chars().next();
        match (digits.parse::<usize>(), after) {
            (Ok(n), Some(':')) if n > 0 => Some(n),
            _ => None,
        }
    })
}

fn parse_world(bytes: &[u8], name: &str) -> World {
    World::parse(bytes, name, ReadOptions::default()).unwrap_or_else(|e| panic!("{e}"))
}

// ---------------------------------------------------------------------------------------------

#[test]
fn create_then_info() {
    let t = TempDir::new("info");
    let r = t.jello(&["create", "OUT.w"]);
    r.success();
    let text = t.read("OUT.w");
    let w = parse_world(&text, "OUT.w");
    assert_eq!(w.integrator, Integrator::Rk4);
    t.jello(&["info", "OUT.w"])
        .success()
        .stdout_has("RK4")
        .stdout_has("6220 springs")
        .stdout_has("OUT.w");
    t.assert_no_temp_files();
}

#[test]
fn run_saves_a_world_that_parses() {
    let t = TempDir::new("save");
    t.create("OUT.w", &[]);
    t.jello(&["run", "OUT.w", "--steps", "50", "--save", "S.w", "-q"])
        .success()
        .stdout_has("50 steps");
    let saved = parse_world(&t.read("S.w"), "S.w");
    let start = parse_world(&t.read("OUT.w"), "OUT.w");
    assert_eq!(saved.integrator, start.integrator);
    assert_eq!(saved.dt, start.dt);
    assert_eq!(saved.positions.len(), 512);
    t.assert_no_temp_files();
    // The saved file runs on.
    t.jello(&["run", "S.w", "--steps", "5", "-q"]).success();
}

#[test]
fn run_for_a_simulated_time() {
    let t = TempDir::new("time");
    t.create("OUT.w", &[]);
    t.jello(&["run", "OUT.w", "--time", "0.01", "-q"])
        .success()
        .stdout_has("20 steps")
        .stdout_has("t = 0.010000 s");
    // --steps and --time conflict.
    let r = t.jello(&["run", "OUT.w", "--time", "0.01", "--steps", "3"]);
    assert_ne!(r.code, Some(0), "{}", r.context());
    r.no_panic();
}

#[test]
fn integrator_and_dt_overrides_apply() {
    let t = TempDir::new("override");
    t.create("OUT.w", &[]);
    t.jello(&[
        "run",
        "OUT.w",
        "--integrator",
        "euler",
        "--dt",
        "0.0001",
        "--steps",
        "10",
        "--save",
        "S.w",
        "-q",
    ])
    .success()
    .stdout_has("t = 0.001000 s");
    let saved = parse_world(&t.read("S.w"), "S.w");
    assert_eq!(saved.integrator, Integrator::Euler);
    assert_eq!(saved.dt, 0.0001);
    t.jello(&["info", "S.w"])
        .success()
        .stdout_has("Euler, dt = 0.0001 s");
    // The input is untouched.
    let start = parse_world(&t.read("OUT.w"), "OUT.w");
    assert_eq!(start.integrator, Integrator::Rk4);
    assert_eq!(start.dt, 0.0005);
}

fn frame_names(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect();
    names.sort();
    names
}

#[test]
fn frames_in_every_format() {
    let t = TempDir::new("frames");
    t.create("OUT.w", &["--field", "gravity"]);
    let (steps, every) = (50, 10);
    for format in ["ply", "obj", "csv"] {
        let dir = format!("frames-{format}");
        t.jello(&[
            "run",
            "OUT.w",
            "--steps",
            &steps.to_string(),
            "--frames",
            &dir,
            "--every",
            &every.to_string(),
            "--format",
            format,
            "-q",
        ])
        .success()
        .stdout_has(&format!("{} frames", steps / every + 1));
        let names = frame_names(&t.path(&dir));
        let expected: Vec<String> = (0..=steps / every)
            .map(|n| format!("frame_{n:06}.{format}"))
            .collect();
        assert_eq!(names, expected, "{format}");
        for name in &names {
            let text = String::from_utf8(t.read(&format!("{dir}/{name}"))).unwrap();
            match format {
                "ply" => {
                    assert!(text.starts_with("ply\n"), "{name}");
                    assert!(text.contains("element vertex 512\n"), "{name}");
                    assert!(text.contains("end_header\n"), "{name}");
                    let body = text.split_once("end_header\n").unwrap().1;
                    let vertices: Vec<&str> = body.lines().take(512).collect();
                    assert_eq!(vertices.len(), 512);
                    for v in vertices {
                        let xyz: Vec<f64> = v.split(' ').map(|s| s.parse().unwrap()).collect();
                        assert_eq!(xyz.len(), 3, "{name}: {v}");
                        assert!(xyz.iter().all(|c| c.is_finite() && c.abs() < 3.0));
                    }
                }
                "obj" => {
                    let v = text.lines().filter(|l| l.starts_with("v ")).count();
                    assert_eq!(v, 512, "{name}");
                    assert!(text.lines().any(|l| l.starts_with("f ")), "{name}");
                }
                "csv" => {
                    let lines: Vec<&str> = text.lines().collect();
                    assert_eq!(lines.len(), 513, "{name}");
                    assert_eq!(lines[0], "body,i,j,k,x,y,z,vx,vy,vz");
                    assert!(lines[1..].iter().all(|l| l.split(',').count() == 10));
                    assert!(lines[1].starts_with("1,0,0,0,"));
                }
                _ => unreachable!(),
            }
        }
        let dir_path = t.path(&dir);
        let stray = frame_names(&dir_path)
            .into_iter()
            .filter(|n| n.contains(".tmp-"))
            .count();
        assert_eq!(stray, 0);
    }
    // Under gravity the cube falls: the last frame differs from the first.
    let first = t.read("frames-csv/frame_000000.csv");
    let last = t.read(&format!("frames-csv/frame_{:06}.csv", steps / every));
    assert_ne!(first, last);
}

#[test]
fn blow_up_exits_3_and_saves_nothing() {
    let t = TempDir::new("blowup");
    t.create("B.w", &["--dt", "0.05", "--k-elastic", "20000"]);
    let r = t.jello(&["run", "B.w", "--steps", "50", "--save", "S.w", "-q"]);
    r.code(3)
        .stderr_has("B.w")
        .stderr_has("blew up")
        .stderr_has("--dt");
    assert!(!t.path("S.w").exists(), "a blown-up run left S.w");
    t.assert_no_temp_files();
    // The same world with a small enough step runs: the blow-up was the step size.
    t.jello(&["run", "B.w", "--steps", "50", "--dt", "0.0001", "-q"])
        .success();
}

/// `leapfrog.w` under SDIRK2 at 0.05 s: its first step does not converge whole within 200
/// Newton iterations and is taken in halves, which the summary says; with `--cutbacks 0` the run
/// stops there, saving nothing. More halvings than the core allows are refused.
#[test]
#[cfg_attr(
    not(shared_worlds),
    ignore = "needs ../shared/worlds, absent when this crate was built"
)]
fn implicit_steps_that_fail_are_cut_back_and_said() {
    let world = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/worlds/leapfrog.w");
    let t = TempDir::new("cutbacks");
    let world = world.to_str().unwrap();
    let args = [
        "run",
        world,
        "--integrator",
        "SDIRK2",
        "--dt",
        "0.05",
        "--steps",
        "2",
    ];
    t.jello(&[&args[..], &["-q", "--save", "S.w"]].concat())
        .success()
        .stdout_has("steps taken in parts (")
        .stdout_has("the smallest dt/2)");
    assert!(t.path("S.w").exists());
    let r = t.jello(&[&args[..], &["-q", "--cutbacks", "0", "--save", "T.w"]].concat());
    r.code(3)
        .stderr_has("did not converge at step 1")
        .stderr_has(" Newton iterations (the tolerance is 1e-9 m/s)");
    // How many iterations Newton's method took before it gave up: at most its limit, 200.
    let taken = r.stderr.split(" Newton iterations").next().unwrap();
    let taken: u32 = taken.rsplit("after ").next().unwrap().parse().unwrap();
    assert!((1..=200).contains(&taken), "{}", r.stderr);
    assert!(!t.path("T.w").exists(), "a stopped run left T.w");
    let r = t.jello(&[&args[..], &["--cutbacks", "21"]].concat());
    r.code(2).stderr_has("--cutbacks");
    t.assert_no_temp_files();
}

/// Writes `bytes` as `name`, runs it with `--save`, and checks the clean failure: exit 1, the
/// file and a line named, no output file.
fn assert_rejected(t: &TempDir, name: &str, bytes: &[u8]) -> Run {
    t.write(name, bytes);
    let r = t.jello(&["run", name, "--steps", "3", "--save", "X.w", "-q"]);
    r.code(1).stderr_has(name);
    r.stderr_line_of(name);
    assert!(!t.path("X.w").exists(), "{name}: left X.w behind");
    t.assert_no_temp_files();
    // `info` refuses it the same way.
    let i = t.jello(&["info", name]);
    i.code(1).stderr_has(name);
    r
}

#[test]
fn hostile_files_fail_cleanly() {
    let t = TempDir::new("hostile");
    t.create("good.w", &["--field", "vortex:0.01"]);
    let good = t.read("good.w");

    let r = assert_rejected(&t, "empty.w", b"");
    r.stderr_has("empty");

    assert_rejected(&t, "blank.w", b"  \n\n\t \r\n");

    // Binary garbage from a fixed-seed LCG.
    let mut x: u64 = 0x1234_5678_9abc_def0;
    let garbage: Vec<u8> = (0..5000)
        .map(|_| {
            x = x
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (x >> 56) as u8
        })
        .collect();
    assert_rejected(&t, "garbage.w", &garbage);
    assert_rejected(&t, "nul.w", &[0u8; 100]);

    // Truncated at several places.
    for (n, cut) in [3, 20, good.len() / 3, good.len() / 2, good.len() - 3]
        .into_iter()
        .enumerate()
    {
        let name = format!("truncated-{n}.w");
        let r = assert_rejected(&t, &name, &good[..cut]);
        let line = r.stderr_line_of(&name);
        let lines = good[..cut].iter().filter(|&&b| b == b'\n').count() + 1;
        assert!(line <= lines, "{}", r.context());
    }

    // NaN (and friends) in the mass, on line 4.
    let text = String::from_utf8(good.clone()).unwrap();
    let mut lines: Vec<&str> = text.lines().collect();
    for (n, bad) in ["nan", "inf", "-1e400", "-0.5"].into_iter().enumerate() {
        lines[3] = bad;
        let name = format!("mass-{n}.w");
        let r = assert_rejected(&t, &name, lines.join("\n").as_bytes());
        assert_eq!(r.stderr_line_of(&name), 4, "{}", r.context());
    }

    // Trailing data after the velocities.
    let mut trailing = good.clone();
    trailing.extend_from_slice(b"extra\n");
    let r = assert_rejected(&t, "trailing.w", &trailing);
    let total_lines = good.iter().filter(|&&b| b == b'\n').count();
    assert_eq!(r.stderr_line_of("trailing.w"), total_lines + 1);

    // None of that touched the good file, which still runs.
    assert_eq!(t.read("good.w"), good);
    t.jello(&["run", "good.w", "--steps", "2", "-q"]).success();
}

#[test]
fn a_failed_run_keeps_an_existing_save_file() {
    let t = TempDir::new("keep");
    t.create("good.w", &[]);
    t.write("X.w", b"precious");
    t.write("bad.w", b"RK4\n0.0005 nan\n");
    t.jello(&["run", "bad.w", "--steps", "3", "--save", "X.w", "-q"])
        .code(1)
        .stderr_has("bad.w:2:");
    assert_eq!(t.read("X.w"), b"precious");
    t.assert_no_temp_files();
}

#[test]
fn nonexistent_input_file() {
    let t = TempDir::new("missing");
    t.jello(&["run", "missing.w", "--steps", "1", "--save", "X.w"])
        .code(1)
        .stderr_has("missing.w");
    assert!(!t.path("X.w").exists());
    t.jello(&["info", "missing.w"])
        .code(1)
        .stderr_has("missing.w");
    // A folder is not a world file either.
    fs::create_dir(t.path("dir.w")).unwrap();
    t.jello(&["run", "dir.w", "--steps", "1"])
        .code(1)
        .stderr_has("dir.w");
}

#[test]
fn create_refuses_to_overwrite_without_force() {
    let t = TempDir::new("overwrite");
    t.create("OUT.w", &[]);
    t.write("OUT.w", b"mine");
    t.jello(&["create", "OUT.w"])
        .code(1)
        .stderr_has("OUT.w")
        .stderr_has("--force");
    assert_eq!(t.read("OUT.w"), b"mine");
    t.jello(&["create", "OUT.w", "--force"]).success();
    parse_world(&t.read("OUT.w"), "OUT.w");
    t.assert_no_temp_files();
}

#[test]
fn unknown_integrator_is_listed_and_overridable() {
    let t = TempDir::new("ipc");
    t.create("OUT.w", &[]);
    let text = String::from_utf8(t.read("OUT.w")).unwrap();
    let (first, rest) = text.split_once('\n').unwrap();
    assert_eq!(first, "RK4");
    t.write("ipc.w", format!("IPC\n{rest}"));
    let r = t.jello(&["run", "ipc.w", "--steps", "5", "--save", "S.w", "-q"]);
    r.code(1)
        .stderr_has("ipc.w:1:")
        .stderr_has("IPC")
        .stderr_has("Euler")
        .stderr_has("RK2")
        .stderr_has("RK4");
    assert!(!t.path("S.w").exists());
    t.jello(&[
        "run",
        "ipc.w",
        "--steps",
        "5",
        "--integrator",
        "rk4",
        "--save",
        "S.w",
        "-q",
    ])
    .success();
    let saved = parse_world(&t.read("S.w"), "S.w");
    assert_eq!(saved.integrator, Integrator::Rk4);
    t.jello(&["info", "ipc.w"]).code(1).stderr_has("RK4");
    t.jello(&["info", "ipc.w", "--integrator", "rk4"])
        .success()
        .stdout_has("RK4");
    // An unknown name on the command line is refused too, listing the known ones.
    let r = t.jello(&["run", "OUT.w", "--integrator", "IPC"]);
    assert_ne!(r.code, Some(0), "{}", r.context());
    r.no_panic().stderr_has("RK4");
}

#[test]
#[cfg_attr(
    not(shared_worlds),
    ignore = "needs ../shared/worlds, absent when this crate was built"
)]
fn nonstandard_worlds_from_the_wild_fail_cleanly() {
    let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../../shared/worlds/nonstandard");
    let t = TempDir::new("nonstandard");
    let mut files: Vec<PathBuf> = fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path())
        .filter(|p| p.is_file())
        .collect();
    files.sort();
    assert!(!files.is_empty(), "{} is empty", dir.display());
    for file in &files {
        let path = file.to_str().unwrap();
        let name = file.file_name().unwrap().to_str().unwrap();
        let r = t.jello(&["run", path, "--steps", "1", "--save", "X.w", "-q"]);
        r.code(1).stderr_has(name);
        r.stderr_line_of(name);
        assert!(!t.path("X.w").exists(), "{name}: left X.w behind");
    }
    t.assert_no_temp_files();
}

/// A reader that goes away (`jello info … | head`) stops `jello` quietly, as SIGPIPE stops a Unix
/// tool (status 141), not with a panic.
#[test]
fn a_closed_pipe_stops_quietly() {
    let examples = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples");
    let mut child = std::process::Command::new(env!("CARGO_BIN_EXE_jello"))
        .arg("info")
        .arg(examples.join("jello.w"))
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    drop(child.stdout.take()); // the reader is gone before anything is written
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(141), "{err}");
    assert!(!err.contains("panicked"), "{err}");
}

/// A build without the GPU backend says how to get one.
#[cfg(not(feature = "gpu"))]
#[test]
fn device_gpu_without_the_backend_says_how_to_build_it() {
    let dir = TempDir::new("no-gpu");
    let world = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/jello.w");
    for command in ["run", "bench"] {
        let mut args = vec![command, "--device", "gpu"];
        if command == "run" {
            args.insert(1, world.to_str().unwrap());
        }
        let out = dir.run(&args);
        assert_eq!(out.status.code(), Some(2), "{command}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("--features gpu"), "{command}: {err}");
    }
}

/// The value of `"key": number` in one line of JSON from `jello bench --json`; `None` for null.
fn json_number(json: &str, key: &str) -> Option<f64> {
    let at = json
        .find(&format!("\"{key}\": "))
        .unwrap_or_else(|| panic!("no {key}: {json}"));
    let rest = &json[at + key.len() + 4..];
    let value = &rest[..rest.find([',', '}']).unwrap()];
    (value != "null").then(|| value.parse().unwrap())
}

/// `jello bench --steps N` measures exactly N steps from the scene's start, whatever the
/// machine's speed: two runs do the same work (the implicit solver's iterations agree), and the
/// flag is refused with `--seconds` or as 0.
#[test]
fn bench_steps_measures_exactly_those_steps_from_the_start() {
    let t = TempDir::new("bench-steps");
    let explicit = t.succeeds(&["bench", "--size", "4", "--steps", "7", "--json"]);
    assert_eq!(json_number(&explicit, "steps"), Some(7.0), "{explicit}");
    let implicit = || {
        t.succeeds(&[
            "bench",
            "--size",
            "6",
            "--integrator",
            "BackwardEuler",
            "--dt",
            "0.0166667",
            "--steps",
            "5",
            "--json",
        ])
    };
    let (first, second) = (implicit(), implicit());
    assert_eq!(json_number(&first, "steps"), Some(5.0), "{first}");
    for key in ["newton_iterations_per_step", "linear_iterations_per_step"] {
        let value = json_number(&first, key);
        assert!(value.is_some_and(|v| v > 0.0), "{first}");
        assert_eq!(value, json_number(&second, key), "{key}: {first}\n{second}");
    }
    for args in [
        &["bench", "--steps", "3", "--seconds", "1"][..],
        &["bench", "--steps", "0"][..],
    ] {
        let out = t.run(args);
        assert_eq!(out.status.code(), Some(2), "{args:?}");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains("--steps"), "{args:?}: {err}");
    }
}

/// `jello bench --job rest|drop` steps the frame-rate job: the very scene `jello create` makes
/// with the flags BENCHMARKS.md gives, at 1/60 s for an implicit integrator, over the job's
/// simulated time unless told otherwise, with its real-time factor in `--json`.
#[test]
fn bench_job_steps_the_scene_jello_create_makes() {
    use jello_core::benchmark::Job;
    use jello_core::SceneFile;
    let t = TempDir::new("bench-job");
    for (job, centre) in [(Job::Rest, "0,0,0.5"), (Job::Drop, "0,0,1")] {
        let path = t.path(&format!("{}.toml", job.name()));
        let path = path.to_str().unwrap();
        t.succeeds(&[
            "create",
            path,
            "--cube",
            "5",
            "--total-mass",
            "1",
            "--modulus",
            "1400",
            "--viscosity",
            "1.75",
            "--field",
            "gravity",
            "--plane",
            "0,0,1,0",
            "--at",
            centre,
        ]);
        let created = SceneFile::parse(&fs::read(path).unwrap(), path).unwrap();
        let ours = SceneFile::parse(job.scene_text(5).as_bytes(), "job").unwrap();
        assert_eq!(created.to_toml(), ours.to_toml(), "{}", job.name());
        let out = t.succeeds(&[
            "bench",
            "--job",
            job.name(),
            "--size",
            "5",
            "--integrator",
            "BackwardEuler",
            "--json",
        ]);
        assert!(
            out.contains(&format!("\"job\": \"{}\"", job.name())),
            "{out}"
        );
        assert_eq!(json_number(&out, "dt"), Some(1.0 / 60.0), "{out}");
        // 3 s of simulated time at 1/60 s.
        assert_eq!(json_number(&out, "steps"), Some(180.0), "{out}");
        assert!(
            json_number(&out, "real_time").is_some_and(|r| r > 0.0),
            "{out}"
        );
        // After 3 s the 1 m cube rests on the floor, its centre half a metre up (less its
        // settling), a little into the floor.
        let centre = json_number(&out, "end_centre_z").unwrap();
        let depth = json_number(&out, "end_depth").unwrap();
        assert!((0.45..0.5).contains(&centre), "{out}");
        assert!(depth > 0.0 && depth < 0.05, "{out}");
    }
    let out = t.succeeds(&[
        "bench", "--job", "drop", "--size", "5", "--steps", "4", "--json",
    ]);
    assert_eq!(json_number(&out, "steps"), Some(4.0), "{out}");
    assert!(out.contains("\"job\": \"drop\""), "{out}");
    // Four steps into the drop, the cube is still falling from 0.5 m up.
    assert!(
        json_number(&out, "end_centre_z").is_some_and(|z| z > 0.9),
        "{out}"
    );
    // The benchmark scene has no floor to end on.
    let out = t.succeeds(&["bench", "--size", "4", "--steps", "2", "--json"]);
    assert!(out.contains("\"end_centre_z\": null"), "{out}");
}

/// `jello bench --per-step` reports each measured step: as many as it measured, its solver's
/// work summing to the run's (the dropped cube's free fall solved by its change of momentum
/// alone, its landing by Newton's method), in `--json` as an array and in text as a table; an
/// explicit integrator's steps with their times alone; refused on the GPU.
#[test]
fn bench_per_step_reports_each_measured_step() {
    let t = TempDir::new("bench-per-step");
    let out = t.succeeds(&[
        "bench",
        "--job",
        "drop",
        "--size",
        "5",
        "--integrator",
        "BackwardEuler",
        "--steps",
        "30",
        "--per-step",
        "--json",
    ]);
    let json: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    let steps = json["per_step"].as_array().unwrap();
    assert_eq!(steps.len(), 30, "{out}");
    let total = |key: &str| steps.iter().map(|s| s[key].as_u64().unwrap()).sum::<u64>() as f64;
    for (key, per_step) in [
        ("newton_iterations", "newton_iterations_per_step"),
        ("linear_iterations", "linear_iterations_per_step"),
        ("assemblies", "assemblies_per_step"),
    ] {
        let reported = json[per_step].as_f64().unwrap();
        assert!((total(key) / 30.0 - reported).abs() < 1e-3, "{key}: {out}");
    }
    assert!(
        steps.iter().all(|s| s["seconds"].as_f64().unwrap() > 0.0),
        "{out}"
    );
    // Falling from 0.5 m for 0.32 s (19 steps), then landing.
    assert_eq!(steps[0]["newton_iterations"], 0, "{out}");
    assert!(total("newton_iterations") > 0.0, "{out}");
    // Text: a header and a line per step before the summary.
    let text = t.succeeds(&["bench", "--size", "4", "--steps", "3", "--per-step"]);
    let lines: Vec<&str> = text.lines().collect();
    assert_eq!(lines.len(), 5, "{text}");
    assert_eq!(
        lines[0].split_whitespace().collect::<Vec<_>>(),
        ["step", "wall", "(ms)"]
    );
    assert!(lines[3].trim_start().starts_with("2 "), "{text}");
    let explicit = t.succeeds(&["bench", "--size", "4", "--steps", "2", "--json"]);
    assert!(explicit.contains("\"per_step\": null"), "{explicit}");
    let out = t.run(&["bench", "--device", "gpu", "--per-step", "--steps", "2"]);
    assert_eq!(out.status.code(), Some(2), "{out:?}");
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("--per-step"),
        "{out:?}"
    );
}

/// `jello bench` and `jello run` report the implicit solver's work per step: Newton
/// iterations (fewer than one a step once the benchmark's small cube comes to rest, where a
/// step starts within the tolerance), at least one conjugate-gradient iteration each, more
/// Newton iterations at a tighter tolerance; null under an explicit integrator.
#[test]
fn bench_and_run_report_the_implicit_solvers_work() {
    let t = TempDir::new("solver-stats");
    let bench = |integrator: &str, extra: &[&str]| {
        let args = [
            &["bench", "--size", "4", "--seconds", "0.05", "--json"][..],
            &["--integrator", integrator],
            extra,
        ]
        .concat();
        t.succeeds(&args)
    };
    let per_step = |json: &str| {
        let newton = json_number(json, "newton_iterations_per_step").unwrap();
        let linear = json_number(json, "linear_iterations_per_step").unwrap();
        let assemblies = json_number(json, "assemblies_per_step").unwrap();
        assert!(
            newton > 0.0 && linear >= newton && assemblies > 0.0,
            "{json}"
        );
        newton
    };
    let at_60 = ["--dt", "0.0166667"];
    let tight = bench(
        "BackwardEuler",
        &[&at_60[..], &["--tolerance", "1e-10"]].concat(),
    );
    let loose = bench(
        "BackwardEuler",
        &[&at_60[..], &["--tolerance", "1e-2"]].concat(),
    );
    assert!(per_step(&tight) > per_step(&loose), "{tight}\n{loose}");
    per_step(&bench("SDIRK2", &at_60));
    let explicit = bench("RK4", &[]);
    for key in [
        "newton_iterations_per_step",
        "linear_iterations_per_step",
        "assemblies_per_step",
    ] {
        assert_eq!(json_number(&explicit, key), None, "{explicit}");
    }

    let world = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../examples/jello.w");
    let world = world.to_str().unwrap();
    let text = t.succeeds(&[
        "run",
        world,
        "-q",
        "--steps",
        "3",
        "--integrator",
        "BackwardEuler",
    ]);
    assert!(
        text.contains("Newton and ") && text.contains(" assemblies"),
        "{text}"
    );
    let text = t.succeeds(&["run", world, "-q", "--steps", "3"]);
    assert!(!text.contains("Newton"), "{text}");
}

/// A negative number given to a numeric flag reaches our own check, which names the flag and
/// the value (clap alone took `-0.001` for a flag and suggested `-- -0`).
#[test]
fn negative_numbers_are_values_that_our_checks_answer() {
    let t = TempDir::new("negative");
    t.create("w.w", &[]);
    for (flag, value, says) in [
        (
            "--dt",
            "-0.001",
            "must be a finite number above 0 (got -0.001)",
        ),
        ("--time", "-2", "must be a finite number above 0 (got -2)"),
        ("--steps", "-1", "must be a whole number ≥ 0 (got -1)"),
    ] {
        t.jello(&["run", "w.w", flag, value, "-q"])
            .code(2)
            .stderr_has(&format!("'{value}' for '{flag}"))
            .stderr_has(says);
    }
    t.jello(&[
        "run", "w.w", "--steps", "1", "--frames", "f", "--every", "-3",
    ])
    .code(2)
    .stderr_has("must be a whole number ≥ 1 (got -3)");
}

/// A mesh given to `jello run` is named as a mesh, with how to make a scene of it, rather than
/// read as a world (whose first word would be taken for an integrator).
#[test]
fn a_mesh_given_to_run_says_how_to_make_a_scene_of_it() {
    let t = TempDir::new("mesh-run");
    t.jello(&["shape", "sphere", "ball.obj"]).success();
    for command in ["run", "info"] {
        t.jello(&[command, "ball.obj"])
            .code(1)
            .stderr_has("ball.obj: this is a Wavefront OBJ mesh, not a world (.w) or scene (.toml)")
            .stderr_has("jello create scene.toml --mesh ball.obj");
    }
}

/// `--frames` without `--every` writes at `--export`'s rate, 30 frames per simulated second
/// (`--fps` changes it); an OBJ frame groups each body's faces under its name, and its header
/// shows the time without the rounding of summing it step by step.
#[test]
fn frames_default_to_thirty_per_second_with_a_group_per_body() {
    let t = TempDir::new("frame-rate");
    t.create(
        "two.toml",
        &[
            "--dt", "0.0005", "--cube", "3", "--size", "0.4", "--centre", "0,0,0", "--name",
            "left", "--cube", "3", "--size", "0.4", "--centre", "1,0,0", "--name", "right",
        ],
    );
    // 0.1 s is 200 steps; 30 fps is a frame every round(66.7) = 67 steps: steps 0, 67 and 134.
    t.jello(&[
        "run", "two.toml", "--time", "0.1", "--frames", "f", "--format", "obj", "-q",
    ])
    .success()
    .stdout_has("3 frames");
    let text = String::from_utf8(t.read("f/frame_000001.obj")).unwrap();
    assert!(
        text.starts_with("# jello frame, step 67, t = 0.0335 s\n"),
        "{text:.60}"
    );
    let groups: Vec<&str> = text.lines().filter(|l| l.starts_with("o ")).collect();
    assert_eq!(groups, ["o left", "o right"]);
    // At 100 fps: a frame every 20 steps, 11 in all.
    t.jello(&[
        "run", "two.toml", "--time", "0.1", "--frames", "g", "--fps", "100", "-q",
    ])
    .success()
    .stdout_has("11 frames");
    // --fps means nothing without an output that has frames.
    t.jello(&["run", "two.toml", "--steps", "1", "--fps", "10"])
        .code(2);
}
