"""numpy in, numpy out: shapes, dtypes, copies, and what the physics makes of them."""

from __future__ import annotations

import re
import subprocess
from pathlib import Path

import numpy as np
import pytest

import jello
from conftest import EXAMPLES


def test_state_arrays_are_float64_n_by_3_copies() -> None:
    sim = jello.load(EXAMPLES / "jello.w")
    for array in (sim.positions, sim.velocities):
        assert array.shape == (512, 3)
        assert array.dtype == np.float64
        assert array.flags.c_contiguous and array.flags.writeable
    assert len(sim) == sim.point_count == 512
    # A snapshot: changing it, or stepping, does not change the other.
    before = sim.positions
    kept = before.copy()
    before[:] = 0.0
    assert np.array_equal(sim.positions, kept)
    sim.step(10)
    assert np.array_equal(before, np.zeros((512, 3)))
    assert sim.control_forces is None


def test_positions_and_velocities_are_set_from_arrays() -> None:
    sim = jello.load(EXAMPLES / "jello.w")
    p = sim.positions + np.array([0.1, 0.0, -0.2])
    sim.positions = p
    assert np.array_equal(sim.positions, p)
    # Lists, other dtypes and strided views are taken as numpy.asarray takes them.
    v = np.zeros((512, 6), dtype=np.float32)[:, ::2]
    v[:, 2] = 1.5
    sim.velocities = v
    assert np.array_equal(sim.velocities, np.tile([0.0, 0.0, 1.5], (512, 1)))
    sim.velocities = [[0.0, 0.0, 0.0]] * 512
    assert not sim.velocities.any()


@pytest.mark.parametrize(
    ("value", "message"),
    [
        (np.zeros((511, 3)), r"expected an array of shape \(512, 3\), found shape \[511, 3\]"),
        (np.zeros(1536), r"expected a 2-D array of shape \(n, 3\)"),
        (np.full((512, 3), np.nan), r"row 0 is not finite"),
        ("nonsense", r"positions: expected"),
    ],
)
def test_bad_arrays_are_refused_and_change_nothing(value: object, message: str) -> None:
    sim = jello.load(EXAMPLES / "jello.w")
    before = sim.positions
    with pytest.raises(ValueError, match=message):
        sim.positions = value
    assert np.array_equal(sim.positions, before)


def test_a_constant_control_force_accelerates_the_centre_of_mass_as_f_over_m() -> None:
    # A free cube (no field, far from the walls) under a force F on every point: internal forces
    # cancel, so the centre of mass moves as x0 + v0 t + F/(2m) t², which RK4 integrates exactly.
    body = jello.cube(4, 0.3, at=(0.0, 0.0, 0.0), mass=0.01)
    sim = jello.create([body], gravity=(0.0, 0.0, 0.0), bounds=((-5, -5, -5), (5, 5, 5)))
    f = np.array([0.002, -0.001, 0.0005])
    sim.control_forces = np.broadcast_to(f, (len(sim), 3))
    forces = sim.control_forces
    assert forces is not None and np.array_equal(forces[7], f)
    x0 = sim.positions.mean(axis=0)
    sim.step(400)
    t = sim.time
    expected = x0 + 0.5 * (f / 0.01) * t * t
    assert np.allclose(sim.positions.mean(axis=0), expected, rtol=0, atol=1e-12)
    # Internal forces conserve momentum: every point has the same mean velocity change.
    assert np.allclose(sim.velocities.mean(axis=0), f / 0.01 * t, rtol=0, atol=1e-12)
    sim.control_forces = None
    assert sim.control_forces is None


def test_energy_is_its_parts_and_rest_has_none() -> None:
    body = jello.cube(5, 1.0, at=(0.0, 0.0, 0.0))
    sim = jello.create([body], gravity=(0.0, 0.0, 0.0))
    e = sim.energy()
    assert (e.kinetic, e.spring, e.collision, e.total) == (0.0, 0.0, 0.0, 0.0)
    sim.velocities = np.tile([1.0, 0.0, 0.0], (len(sim), 1))
    mass = 1.0 / 512.0
    assert sim.energy().kinetic == pytest.approx(0.5 * mass * len(sim), rel=1e-14)
    sim.step(100)
    e = sim.energy()
    assert e.total == e.kinetic + e.spring + e.collision


def test_copies_are_independent() -> None:
    import copy

    sim = jello.load(EXAMPLES / "rotate.w")
    twin = sim.copy()
    other = copy.deepcopy(sim)
    sim.step(50)
    assert twin.steps == 0 and other.steps == 0
    twin.step(50)
    assert np.array_equal(twin.positions, sim.positions)


def test_material_and_collision_changes_are_saved_and_read_back(tmp_path: object) -> None:
    from pathlib import Path

    out = Path(str(tmp_path)) / "stack.toml"
    sim = jello.load(EXAMPLES / "stack.toml")
    sim.set_material(stiffness=(300.0, 250.0, 200.0), damping=0.5, body=0)
    sim.set_collision(stiffness=900.0)
    sim.step(20)
    sim.save(out)
    again = jello.load(out)
    sim.step(20)
    again.step(20)
    assert np.array_equal(sim.positions, again.positions)
    with pytest.raises(ValueError, match="body: 7 does not exist"):
        sim.set_material(mass=1.0, body=7)


def test_advance_is_step_under_the_rust_name() -> None:
    a, b = jello.load(EXAMPLES / "jello.w"), jello.load(EXAMPLES / "jello.w")
    a.step(300)
    b.advance(300)
    assert a.steps == b.steps == 300
    assert np.array_equal(a.positions, b.positions) and np.array_equal(a.velocities, b.velocities)


def info_point_counts(cli: Path, scene: Path) -> list[int]:
    """Each body's points as `jello info` counts them (`body N  name: P points (lattice …)`)."""
    out = subprocess.run([cli, "info", scene], check=True, capture_output=True, text=True).stdout
    return [int(m) for m in re.findall(r"^body \d+ .*?: (\d+) points", out, re.MULTILINE)]


@pytest.mark.parametrize("scene", ["torus.toml", "mould.toml", "ring.toml"])
def test_arrays_hold_the_active_points_jello_info_counts(cli: Path, scene: str) -> None:
    """A body voxelised from a mesh keeps a whole lattice whose points outside its cells never
    move: `len`, `positions`, `velocities`, `control_forces` and `bodies` show the active points
    only, as many as `jello info` counts; `lattice_positions[active]` is `positions`."""
    counts = info_point_counts(cli, EXAMPLES / scene)
    sim = jello.load(EXAMPLES / scene)
    assert len(sim) == sim.point_count == sum(counts)
    assert [s.stop - s.start for _, s in sim.bodies] == counts
    assert sim.bodies[-1][1].stop == len(sim)
    assert sim.positions.shape == sim.velocities.shape == (len(sim), 3)
    lattice = sim.lattice_positions
    assert sim.active.dtype == np.bool_ and sim.active.shape == (len(lattice),)
    assert int(sim.active.sum()) == len(sim) < len(lattice)
    assert np.array_equal(lattice[sim.active], sim.positions)
    # Every point shown takes part: all of them fall, none stands still.
    start = sim.positions
    sim.step(20)
    assert np.all(sim.positions[:, 2] < start[:, 2])
    assert np.array_equal(sim.lattice_positions[~sim.active], lattice[~sim.active])
    # Setting the arrays sets the active points and leaves the placeholders.
    sim.velocities = np.zeros((len(sim), 3))
    sim.positions = start
    assert np.array_equal(sim.positions, start)
    assert np.array_equal(sim.lattice_positions, lattice)
    sim.control_forces = np.ones((len(sim), 3))
    assert np.array_equal(sim.control_forces, np.ones((len(sim), 3)))
    with pytest.raises(ValueError, match=rf"positions: expected an array of shape \({len(sim)}, 3\)"):
        sim.positions = lattice


def test_a_world_shows_all_its_points() -> None:
    """The classic world's lattice is all active: the two views are the same 512 points."""
    sim = jello.load(EXAMPLES / "jello.w")
    assert len(sim) == 512 and bool(sim.active.all())
    assert np.array_equal(sim.lattice_positions, sim.positions)


def test_a_blow_up_names_the_row_of_positions() -> None:
    """`BlowUp.point` indexes `positions`; the message keeps the lattice's index, as the CLI's."""
    sim = jello.load(EXAMPLES / "torus.toml", integrator="Euler", dt=0.01)
    with pytest.raises(jello.BlowUp) as caught:
        sim.step(1000)
    lattice_index = int(re.search(r"point (\d+) \(", str(caught.value)).group(1))  # type: ignore[union-attr]
    row = caught.value.point
    assert 0 <= row < len(sim)
    assert int(np.flatnonzero(sim.active)[row]) == lattice_index
