//! `jello run` warns when points pass through an obstacle, with a time step that avoids it, and
//! stays quiet about a body resting on one.

use std::process::Output;

mod common;

use common::TempDir;

/// A small cube thrown at 30 m/s at a 5 cm plate under BackwardEuler at dt = 0.002 s: a step
/// moves it 6 cm, so its bottom layer jumps through the plate and it ends impaled on it.
const THROWN: &[&str] = &[
    "create",
    "thrown.toml",
    "--cube",
    "3",
    "--size",
    "0.2",
    "--centre",
    "0,0,0.5",
    "--velocity",
    "0,0,-30",
    "--name",
    "cube",
    "--collision-stiffness",
    "1e6",
    "--collision-damping",
    "20",
    "--box=-1,-1,-0.05,1,1,0",
    "--integrator",
    "BackwardEuler",
    "--dt",
    "0.002",
];

fn stderr(out: &Output) -> String {
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The z of the centre of mass `jello info` gives for a saved state.
fn centre_z(dir: &TempDir, file: &str) -> f64 {
    let info = dir.succeeds(&["info", file]);
    let line = info
        .lines()
        .find(|l| l.starts_with("centre of mass"))
        .unwrap_or_else(|| panic!("{info}"));
    let inner = &line[line.find('(').unwrap() + 1..line.find(')').unwrap()];
    inner.split(", ").nth(2).unwrap().parse().unwrap()
}

#[test]
fn a_cube_thrown_through_a_plate_is_reported_and_the_advised_dt_stops_it() {
    let dir = TempDir::new("tunnel");
    dir.succeeds(THROWN);
    let run = |extra: &[&str]| {
        let mut args = vec!["run", "thrown.toml", "--time", "0.5", "-q"];
        args.extend_from_slice(extra);
        let out = dir.run(&args);
        assert!(out.status.success(), "{}", stderr(&out));
        stderr(&out)
    };
    let warned = run(&["--save", "impaled.toml"]);
    assert!(
        warned.contains(
            "warning: thrown.toml: 9 points of body 'cube' passed through obstacle 1 (box, 5 cm \
             thick there) between t = 0.014 s and 0.016 s"
        ),
        "{warned}"
    );
    // Impaled: the cube (0.2 m) straddles the plate, its centre under its half size.
    assert!(centre_z(&dir, "impaled.toml") < 0.05);

    let dt = warned
        .split("try --dt ")
        .nth(1)
        .and_then(|rest| rest.split(' ').next())
        .unwrap_or_else(|| panic!("no --dt advised: {warned}"));
    assert!(dt.parse::<f64>().unwrap() < 0.002, "{dt}");
    let quiet = run(&["--dt", dt, "--save", "bounced.toml"]);
    assert!(!quiet.contains("warning"), "{quiet}");
    assert!(centre_z(&dir, "bounced.toml") > 0.1);
}

#[test]
fn a_cube_resting_on_a_plate_is_not_reported() {
    let dir = TempDir::new("rest");
    dir.succeeds(common::CUBE_RESTING_ON_A_PLATE);
    let out = dir.run(&[
        "run",
        "rest.toml",
        "--time",
        "2",
        "-q",
        "--save",
        "after.toml",
    ]);
    assert!(
        out.status.success() && stderr(&out).is_empty(),
        "{}",
        stderr(&out)
    );
    // It rests on the plate (its centre at its half size, 0.1 m, less the contact's give).
    assert!((centre_z(&dir, "after.toml") - 0.1).abs() < 1e-3);
}

/// A cube of 4³ points (13 cm apart) dropped on the edge of an upright 5 cm blade: the blade
/// passes between its points, none touching it, and it ends on the floor with the blade through
/// it. No point passed through, so the end state says so; a cube of 11³ (4 cm apart) rests on
/// the edge.
#[test]
fn a_blade_between_a_coarse_lattices_points_is_reported_at_the_end() {
    let dir = TempDir::new("blade");
    let create = |file: &str, n: &str| {
        dir.succeeds(&[
            "create",
            file,
            "--cube",
            n,
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
        ])
    };
    create("coarse.toml", "4");
    create("fine.toml", "11");
    let run = |file: &str, saved: &str| {
        let out = dir.run(&["run", file, "--time", "1.5", "-q", "--save", saved]);
        assert!(out.status.success(), "{}", stderr(&out));
        stderr(&out)
    };
    let cut = run("coarse.toml", "cut.toml");
    assert_eq!(
        cut.lines().count(),
        1,
        "one warning, for the end state: {cut}"
    );
    assert!(
        cut.starts_with(
            "warning: coarse.toml: body 'cube' ends with obstacle 1 (box, 5 cm thick there) \
             through it: 16 edges of its lattice cross the obstacle's middle"
        ),
        "{cut}"
    );
    assert!(
        cut.contains("thinner than the body's lattice spacing (13.3 cm)"),
        "{cut}"
    );
    assert!(centre_z(&dir, "cut.toml") < -1.5);

    let rests = run("fine.toml", "rests.toml");
    assert!(rests.is_empty(), "{rests}");
    assert!(centre_z(&dir, "rests.toml") > 0.1);
}

/// A small cube thrown at 60 m/s into a big one in empty space, at a contact too soft to stop
/// it: after 20 ms it is 7 cm inside, and the run says so with a stiffness to try; the same
/// bodies side by side at rest, a millimetre apart, are not reported.
#[test]
fn bodies_that_end_inside_each_other_are_reported() {
    let dir = TempDir::new("sunk");
    let two = |file: &str, small_at: &str, velocity: &str| {
        dir.succeeds(&[
            "create",
            file,
            "--field",
            "uniform:0,0,0",
            "--collision-stiffness",
            "2000",
            "--dt",
            "0.0001",
            "--cube",
            "5",
            "--size",
            "0.5",
            "--at",
            "0,0,0",
            "--total-mass",
            "10",
            "--name",
            "block",
            "--cube",
            "3",
            "--size",
            "0.1",
            "--at",
            small_at,
            "--velocity",
            velocity,
            "--total-mass",
            "0.5",
            "--name",
            "bullet",
        ])
    };
    two("thrown.toml", "-0.8,0,0", "60,0,0");
    let out = dir.run(&["run", "thrown.toml", "--time", "0.02", "-q"]);
    assert!(out.status.success(), "{}", stderr(&out));
    let said = stderr(&out);
    assert!(
        said.starts_with(
            "warning: thrown.toml: bodies 'block' and 'bullet' end 7.23 cm inside each other"
        ),
        "{said}"
    );
    assert!(
        said.contains("more than half the finer of their cells (5 cm)")
            && said.contains("try a collision stiffness of about 140000 N/m"),
        "{said}"
    );
    // The same, at rest side by side with a millimetre between them: nothing to say.
    two("apart.toml", "0.301,0,0", "0,0,0");
    let out = dir.run(&["run", "apart.toml", "--time", "0.02", "-q"]);
    assert!(
        out.status.success() && stderr(&out).is_empty(),
        "{}",
        stderr(&out)
    );
}
