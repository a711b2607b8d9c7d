"""Python computes what the `jello` command line computes, bit for bit."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

import jello
from conftest import EXAMPLES, OFFICIAL


@pytest.mark.parametrize("world", OFFICIAL)
def test_official_worlds_after_1000_steps_equal_the_cli(world: str, cli: Path, tmp_path: Path) -> None:
    path = EXAMPLES / world
    cli_out = tmp_path / "cli.w"
    subprocess.run(
        [cli, "run", path, "--steps", "1000", "--save", cli_out, "--quiet"],
        check=True,
        capture_output=True,
    )
    sim = jello.load(path)
    sim.step(1000)
    py_out = tmp_path / "py.w"
    sim.save(py_out)
    assert py_out.read_bytes() == cli_out.read_bytes()
    # The arrays themselves, not only their printed digits.
    again = jello.load(cli_out)
    assert np.array_equal(sim.positions, again.positions)
    assert np.array_equal(sim.velocities, again.velocities)
    assert sim.steps == 1000
    assert sim.time == pytest.approx(1000 * sim.dt, rel=1e-12)


def test_steps_in_pieces_equal_steps_at_once() -> None:
    whole = jello.load(EXAMPLES / "rotate.w")
    whole.step(300)
    pieces = jello.load(EXAMPLES / "rotate.w")
    for _ in range(3):
        pieces.step(100)
    assert np.array_equal(whole.positions, pieces.positions)
    assert np.array_equal(whole.velocities, pieces.velocities)


@pytest.mark.parametrize("integrator", ["Euler", "RK2", "SymplecticEuler", "BackwardEuler", "SDIRK2"])
def test_integrator_and_dt_equal_the_cli_options(integrator: str, cli: Path, tmp_path: Path) -> None:
    path = EXAMPLES / "gravity.w"
    cli_out = tmp_path / "cli.w"
    dt = "0.01" if integrator in ("BackwardEuler", "SDIRK2") else "0.0002"
    subprocess.run(
        [cli, "run", path, "--steps", "50", "--integrator", integrator, "--dt", dt,
         "--save", cli_out, "--quiet"],
        check=True,
        capture_output=True,
    )
    # Set after loading, as a script would.
    sim = jello.load(path)
    sim.integrator = integrator.lower()
    sim.dt = float(dt)
    assert sim.integrator == integrator
    sim.step(50)
    py_out = tmp_path / "py.w"
    sim.save(py_out)
    assert py_out.read_bytes() == cli_out.read_bytes()
    # And given to load.
    loaded = jello.load(path, integrator=integrator, dt=float(dt))
    loaded.step(50)
    assert np.array_equal(loaded.positions, sim.positions)


def test_scene_saved_equals_the_cli(cli: Path, tmp_path: Path) -> None:
    path = EXAMPLES / "stack.toml"
    cli_out = tmp_path / "cli.toml"
    subprocess.run(
        [cli, "run", path, "--steps", "200", "--save", cli_out, "--quiet"],
        check=True,
        capture_output=True,
    )
    sim = jello.load(path)
    sim.step(200)
    py_out = tmp_path / "py.toml"
    sim.save(py_out)
    assert py_out.read_text() == cli_out.read_text()
    assert sim.dumps() == cli_out.read_text()


def test_loads_equals_load() -> None:
    path = EXAMPLES / "moveLeft.w"
    a = jello.load(path)
    b = jello.loads(path.read_text(), name=str(path))
    c = jello.loads(path.read_bytes(), format="w")
    for s in (a, b, c):
        s.step(100)
    assert np.array_equal(a.positions, b.positions)
    assert np.array_equal(a.positions, c.positions)
    assert b.name == str(path) and c.name == "<string>"
