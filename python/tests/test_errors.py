"""Bad input: clear exceptions naming the file and line; blow-ups leave the last good step."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

import jello
from conftest import EXAMPLES


def test_a_missing_file_is_file_not_found(tmp_path: Path) -> None:
    missing = tmp_path / "nowhere.w"
    with pytest.raises(FileNotFoundError) as e:
        jello.load(missing)
    assert e.value.filename == str(missing)
    with pytest.raises(IsADirectoryError):
        jello.load(tmp_path)


def test_a_bad_world_names_the_file_and_line(tmp_path: Path, cli: Path) -> None:
    bad = tmp_path / "bad.w"
    lines = (EXAMPLES / "jello.w").read_text().splitlines()
    lines[2] = "200 oops 400 0.25"
    bad.write_text("\n".join(lines) + "\n")
    with pytest.raises(jello.WorldError) as e:
        jello.load(bad)
    assert isinstance(e.value, ValueError)
    assert e.value.filename == str(bad)
    assert str(e.value).startswith(f"{bad}:3: ")
    # The CLI's message, word for word.
    run = subprocess.run([cli, "run", bad, "--steps", "1"], capture_output=True, text=True)
    assert run.returncode == 1
    assert run.stderr.strip() == f"jello: error: {e.value}"


def test_a_bad_scene_names_the_line_and_column(tmp_path: Path) -> None:
    bad = tmp_path / "bad.toml"
    bad.write_text("[simulation]\ndt = -1\n\n[[body]]\ncube = { points = [4, 4, 4], size = [1, 1, 1] }\n")
    with pytest.raises(jello.WorldError, match=r"bad\.toml"):
        jello.load(bad)
    bad.write_text("[simulation]\ndt = 'soon'\n")
    with pytest.raises(jello.WorldError, match=r"bad\.toml:2:"):
        jello.load(bad)


def test_every_nonstandard_world_is_refused_or_loads(shared_worlds: Path) -> None:
    # Every file of the corpus' nonstandard folder either loads or raises WorldError: never
    # another exception, never a crash of the interpreter.
    files = sorted((shared_worlds / "nonstandard").glob("*.w"))
    assert files
    for f in files:
        try:
            jello.load(f)
        except jello.WorldError as e:
            assert str(f) in str(e)


def test_loads_refuses_what_is_not_a_world() -> None:
    with pytest.raises(jello.WorldError, match=r"<string>:1:"):
        jello.loads("not a world")
    with pytest.raises(ValueError, match=r'format: expected "w"'):
        jello.loads("", format="obj")
    with pytest.raises(jello.WorldError, match="expected UTF-8"):
        jello.loads(b"\xff\xfe", format="toml")


def test_unknown_integrators_and_bad_time_steps_are_refused() -> None:
    sim = jello.load(EXAMPLES / "jello.w")
    with pytest.raises(ValueError, match="integrator: "):
        sim.integrator = "leapfrog"
    with pytest.raises(ValueError, match="dt: expected a positive"):
        sim.dt = -0.1
    with pytest.raises(ValueError, match="dt: expected a positive"):
        jello.load(EXAMPLES / "jello.w", dt=float("nan"))
    assert (sim.integrator, sim.dt) == ("RK4", 0.0005)


def test_a_blow_up_carries_the_cli_message_and_keeps_the_last_good_step(cli: Path) -> None:
    path = EXAMPLES / "jello.w"
    sim = jello.load(path, dt=0.004)
    with pytest.raises(jello.BlowUp) as e:
        sim.step(10_000)
    err = e.value
    assert isinstance(err, RuntimeError)
    assert sim.steps == err.step - 1
    assert np.isfinite(sim.positions).all() and np.isfinite(sim.velocities).all()
    assert err.integrator == "RK4" and err.dt == 0.004
    assert err.suggested_dt is not None and err.suggested_dt < 0.004
    run = subprocess.run(
        [cli, "run", path, "--dt", "0.004", "--steps", "10000", "--quiet"],
        capture_output=True,
        text=True,
    )
    assert run.returncode == 3
    # The CLI's message, its advice given the Python way.
    assert f"; try sim.dt = {err.suggested_dt}" in str(err) and "--dt" not in str(err)
    assert run.stderr.strip() == f"jello: error: {err}".replace("try sim.dt = ", "try --dt ")
    # Stepping on from the last good step blows up at the same step again.
    with pytest.raises(jello.BlowUp) as again:
        sim.step(10)
    assert again.value.step == err.step


def test_run_reports_the_deepest_penetration_as_the_cli_does(cli: Path) -> None:
    path = EXAMPLES / "moveLeft.w"
    run = subprocess.run([cli, "run", path, "--steps", "500", "--quiet"], capture_output=True, text=True, check=True)
    reported = float(run.stdout.split("max penetration ")[1].split(" m")[0])
    sim = jello.load(path)
    deepest = sim.run(500)
    assert f"{deepest:.3e}" == f"{reported:.3e}"


def test_saving_refuses_the_wrong_format_and_leaves_nothing(tmp_path: Path) -> None:
    sim = jello.load(EXAMPLES / "jello.w")
    with pytest.raises(ValueError, match=r"a world saves as \.w"):
        sim.save(tmp_path / "out.toml")
    with pytest.raises(OSError, match="does not exist"):
        sim.save(tmp_path / "no" / "such" / "out.w")
    assert list(tmp_path.iterdir()) == []


def test_an_implicit_step_that_fails_is_cut_back_or_raises(shared_worlds: Path, cli: Path) -> None:
    """leapfrog.w under SDIRK2 at 0.05 s: its first step does not converge whole."""
    path = shared_worlds / "leapfrog.w"
    sim = jello.load(path, integrator="SDIRK2", dt=0.05)
    assert sim.cutbacks == 6 and sim.split_steps == 0
    sim.cutbacks = 0
    start = sim.positions.copy()
    with pytest.raises(jello.BlowUp) as e:
        sim.step()
    assert "did not converge at step 1" in str(e.value)
    assert sim.steps == 0 and np.array_equal(sim.positions, start)
    with pytest.raises(ValueError, match="halved at most 20 times, not 21"):
        sim.cutbacks = 21
    sim.cutbacks = 6
    assert sim.tolerance == 1e-9
    for bad in (0.0, -1e-6, 0.2, float("nan")):
        with pytest.raises(ValueError, match="Newton tolerance"):
            sim.tolerance = bad
    assert sim.tolerance == 1e-9
    sim.step(2)
    assert sim.steps == 2 and sim.split_steps >= 1
    run = subprocess.run(
        [cli, "run", path, "--integrator", "SDIRK2", "--dt", "0.05", "--steps", "2", "--quiet"],
        capture_output=True,
        text=True,
    )
    assert f"{sim.split_steps} steps taken in parts" in run.stdout, run.stdout + run.stderr


@pytest.mark.parametrize("method", ["step", "advance", "run"])
def test_a_negative_number_of_steps_is_a_value_error_naming_it(method: str) -> None:
    sim = jello.load(EXAMPLES / "jello.w")
    with pytest.raises(ValueError, match=r"^n: the number of steps must be 0 or more, not -1$"):
        getattr(sim, method)(-1)
    assert sim.steps == 0
