"""Scenes built in Python are the scenes `jello create` writes, and behave as physics says."""

from __future__ import annotations

import subprocess
from pathlib import Path

import numpy as np
import pytest

import jello
from conftest import EXAMPLES

JELLY = {"density": 1000.0, "modulus": 2e5, "viscosity": 40.0}
SCENE = {"dt": 0.001, "collision_stiffness": 2e5, "collision_damping": 50.0}


def test_the_stack_example_built_in_python_is_the_shipped_scene() -> None:
    bodies = [
        jello.cube(5, 0.5, at=(0.1, 0.0, -0.75), name="bottom", **JELLY),
        jello.cube(5, 0.5, at=(0.15, 0.05, 0.0), rotation=(0, 0, 20), name="middle", **JELLY),
        jello.cube(5, 0.5, at=(0.1, 0.1, 0.75), rotation=(0, 0, 40), name="top", **JELLY),
    ]
    sim = jello.create(bodies, obstacles=[jello.sphere((0, 0, -1.5), 0.45)], **SCENE)
    shipped = jello.load(EXAMPLES / "stack.toml")
    assert sim.dumps() == shipped.dumps()
    assert [name for name, _ in sim.bodies] == ["bottom", "middle", "top"]


def test_a_placed_cube_is_where_its_quarter_turns_take_it() -> None:
    # By hand: a 2 x 1 x 1 m box of 3 x 2 x 2 points, its middle (1, 0.5, 0.5) put at (1, 0, 0),
    # turned 90 degrees about x (y -> z, z -> -y) and then about z (x -> y, y -> -x): a corner at
    # d from the middle goes to (1, 0, 0) + (dz, dx, dy).
    body = jello.cube((3, 2, 2), (2.0, 1.0, 1.0), centre=(1.0, 0.0, 0.0), rotation=(90, 0, 90))
    sim = jello.create([body], gravity=(0, 0, 0))
    p = sim.positions.reshape(3, 2, 2, 3)
    assert np.allclose(p[0, 0, 0], (0.5, -1.0, -0.5), rtol=0, atol=1e-12)
    assert np.allclose(p[2, 0, 0], (0.5, 1.0, -0.5), rtol=0, atol=1e-12)
    assert np.allclose(p[0, 0, 1], (1.5, -1.0, -0.5), rtol=0, atol=1e-12)
    assert np.allclose(p[1, 1, 1], (1.5, 0.0, 0.5), rtol=0, atol=1e-12)
    # `at` is the same placement under the command line's old name; both at once is an error.
    again = jello.create([jello.cube((3, 2, 2), (2.0, 1.0, 1.0), at=(1.0, 0.0, 0.0), rotation=(90, 0, 90))],
                         gravity=(0, 0, 0))
    assert np.array_equal(again.positions, sim.positions)
    with pytest.raises(ValueError, match="centre or at"):
        jello.cube(3, centre=(0, 0, 0), at=(0, 0, 0))


def test_a_spun_cube_moves_as_a_rigid_rotation() -> None:
    # v = v0 + w x r about the centre of mass: w = 2 rad/s about z, v0 = 0.1 m/s along x.
    sim = jello.create([jello.cube(2, 1.0, centre=(0.5, -0.5, 0.0), velocity=(0.1, 0, 0),
                                   spin=(0, 0, 2))], gravity=(0, 0, 0))
    v = sim.velocities.reshape(2, 2, 2, 3)
    assert np.allclose(v[0, 0, 0], (1.1, -1.0, 0.0), rtol=0, atol=1e-12)  # r = (-0.5, -0.5, -0.5)
    assert np.allclose(v[1, 1, 0], (-0.9, 1.0, 0.0), rtol=0, atol=1e-12)  # r = (0.5, 0.5, -0.5)


def test_a_mesh_on_a_plane_is_the_shipped_blob(cli: Path, tmp_path: Path) -> None:
    obj = tmp_path / "blob.obj"
    subprocess.run([cli, "shape", "blob", obj, "--detail", "8"], check=True, capture_output=True)
    body = jello.mesh(obj, cells=10, at=(-0.8, 0.3, 0), rotation=(20, 0, 30), spin=(0, 0, 2), **JELLY)
    sim = jello.create([body], plane=(0.35, 0, 1, 1.5), **SCENE)
    assert sim.dumps() == jello.load(EXAMPLES / "blob.toml").dumps()
    # The same mesh given as arrays makes the same body.
    vertices, triangles = jello.read_mesh(obj)
    assert vertices.dtype == np.float64 and triangles.dtype == np.uint32
    assert vertices.shape[1] == 3 and triangles.shape[1] == 3
    again = jello.mesh(vertices=vertices, triangles=triangles, cells=10, at=(-0.8, 0.3, 0),
                       rotation=(20, 0, 30), spin=(0, 0, 2), name="blob", **JELLY)
    sim2 = jello.create([again], plane=(0.35, 0, 1, 1.5), **SCENE)
    assert np.array_equal(sim2.positions, sim.positions)


def test_a_field_preset_is_the_cli_field(cli: Path, tmp_path: Path) -> None:
    out = tmp_path / "swirl.toml"
    subprocess.run(
        [cli, "create", out, "--cube", "4", "--size", "0.6", "--field", "vortex:0.5:x", "--res", "8",
         "--pin", "0,0,0,0.25"],
        check=True,
        capture_output=True,
    )
    sim = jello.create(
        [jello.cube(4, 0.6, pins=[jello.pin((0, 0, 0), 0.25)])], field="vortex:0.5:x", res=8
    )
    assert sim.dumps() == jello.load(out).dumps()


def test_a_field_array_is_sampled_as_given() -> None:
    # A uniform field of force F as an array: the centre of mass accelerates at F/m.
    forces = np.zeros((3, 3, 3, 3))
    forces[..., 0] = 0.001
    sim = jello.create([jello.cube(3, 0.4, mass=0.01)], field=forces)
    x0 = sim.positions.mean(axis=0)
    sim.step(200)
    expected = x0 + np.array([0.5 * 0.1 * sim.time**2, 0.0, 0.0])
    assert np.allclose(sim.positions.mean(axis=0), expected, rtol=0, atol=1e-12)
    with pytest.raises(ValueError, match=r"\(r, r, r, 3\)"):
        jello.create([jello.cube(3)], field=np.zeros((3, 3, 3)))


def test_a_dropped_cube_falls_as_g_t_squared_over_two_until_it_lands() -> None:
    sim = jello.create([jello.cube(4, 0.5, at=(0, 0, 0))], gravity=(0, 0, -9.81))
    z0 = sim.positions[:, 2].mean()
    sim.step(400)  # 0.2 s: it falls 0.196 m, far from the floor at -2 m
    assert sim.positions[:, 2].mean() == pytest.approx(z0 - 0.5 * 9.81 * sim.time**2, abs=1e-12)
    assert np.allclose(sim.velocities[:, 2], -9.81 * sim.time, rtol=0, atol=1e-10)


def test_pins_hold_their_points() -> None:
    sim = jello.create([jello.cube(4, 0.6, at=(0, 0, 0), pins=[jello.pin((-0.3, -0.3, 0.3))])])
    corner = int(np.argmin(np.linalg.norm(sim.positions - [-0.3, -0.3, 0.3], axis=1)))
    start = sim.positions[corner].copy()
    sim.step(500)
    assert np.array_equal(sim.positions[corner], start)
    assert sim.positions[:, 2].mean() < 0.0  # the rest of it sags


@pytest.mark.parametrize(
    ("make", "error", "message"),
    [
        (lambda: jello.create([]), ValueError, "at least one body"),
        (lambda: jello.cube(4, mass=1.0, total_mass=2.0), ValueError, "at most one of mass"),
        (lambda: jello.cube(4, stiffness=10.0, modulus=2e5), ValueError, "either stiffness or modulus"),
        (lambda: jello.cube("many"), ValueError, "n: expected points per side"),
        (lambda: jello.cube(4, at=(0, 0)), ValueError, "at: expected 3 numbers, found 2"),
        (lambda: jello.cube(4, velocity=(0, float("inf"), 0)), ValueError, "finite"),
        (lambda: jello.create([jello.cube(4)], field="whirl:3"), ValueError, "field: expected none"),
        (lambda: jello.create([jello.cube(4)], field="gravity", gravity=(0, 0, -1)), ValueError,
         "not both"),
        (lambda: jello.create([jello.cube(4)], plane=(0, 0, 0, 1)), jello.WorldError, "plane"),
        (lambda: jello.create([jello.cube(4), jello.cube(4)]), jello.WorldError, "start inside each other"),
        (lambda: jello.create([jello.cube(1)]), jello.WorldError, "lattice 1×1×1 needs"),
        (lambda: jello.create([jello.cube(100_000)]), jello.WorldError, "too large"),
        (lambda: jello.create([jello.cube(4)], integrator="Verlet"), ValueError, "integrator: "),
        (lambda: jello.create([jello.mesh(vertices=np.zeros((3, 3)), triangles=[[0, 1, 2]])]),
         jello.WorldError, "mesh"),
        (lambda: jello.mesh(vertices=np.zeros((3, 3)), triangles=[[0, 1, -2]]), ValueError,
         "index -2"),
        (lambda: jello.mesh(), ValueError, "give a mesh file's path"),
        (lambda: jello.pin((0, 0, 0), -1.0), ValueError, "radius"),
        (lambda: jello.region((0, 0, 0), (1, 1, 1), stiffness=-2.0), ValueError, "region"),
    ],
)
def test_bad_descriptions_say_what_was_expected(make: object, error: type, message: str) -> None:
    with pytest.raises(error, match=message):
        make()  # type: ignore[operator]


def test_a_built_scene_saves_and_reads_back(tmp_path: Path) -> None:
    sim = jello.create(
        [jello.cube(5, 0.5, at=(0, 0, -1.5), regions=[jello.region((-1, -1, -2), (1, 1, -1.5), stiffness=3)])],
        obstacles=[jello.box((-1, -1, -2), (1, 1, -1.9))],
        dt=0.001,
    )
    sim.step(50)
    out = tmp_path / "built.toml"
    sim.save(out)
    again = jello.load(out)
    assert again.time == sim.time
    assert np.array_equal(again.positions, sim.positions)
    sim.step(50)
    again.step(50)
    assert np.array_equal(again.positions, sim.positions)


def test_the_walls_friction_stops_a_cube_thrown_along_the_floor() -> None:
    # A stiff cube thrown at 1.5 m/s along the box's floor stops after v^2 / (2 mu g) with the
    # walls' friction mu = 0.4, and slides on at its speed without it.
    def thrown(wall_friction: float) -> float:
        body = jello.cube(4, 0.3, centre=(-1.0, 0.0, -1.849), mass=0.01, stiffness=2000.0,
                          damping=2.0, velocity=(1.5, 0.0, 0.0))
        sim = jello.create([body], wall_friction=wall_friction, collision_stiffness=4000.0,
                           collision_damping=2.0, gravity=(0, 0, -9.81))
        x0 = sim.positions[:, 0].mean()
        sim.step(2000)  # 1 s
        return float(sim.positions[:, 0].mean() - x0)
    stopped = thrown(0.4)
    assert stopped == pytest.approx(1.5**2 / (2 * 0.4 * 9.81), rel=0.1)
    assert thrown(0.0) > 1.4
    assert "wall_friction = 0.4" in jello.create([jello.cube(3)], wall_friction=0.4).dumps()
