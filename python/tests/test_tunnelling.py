"""`jello.TunnellingWarning`: points passing through an obstacle are warned of, once per body and
obstacle, with the command line's facts and advice in Python's terms; a gentle drop is not."""

from __future__ import annotations

import os
import warnings
from collections.abc import Iterable

import numpy as np
import pytest

import jello

PLATE = jello.box((-1, -1, -0.05), (1, 1, 0))


def thrown(speed: float = 30.0, *, dt: float = 0.002) -> jello.Simulation:
    """The command line's test: a 0.2 m cube of 3³ points thrown down at a 5 cm plate, under
    BackwardEuler at dt = 0.002 s (a step moves it 6 cm: its bottom layer jumps the plate)."""
    cube = jello.cube(3, 0.2, centre=(0, 0, 0.5), velocity=(0, 0, -speed), name="cube")
    return jello.create(
        [cube],
        obstacles=[PLATE],
        collision_stiffness=1e6,
        collision_damping=20,
        integrator="BackwardEuler",
        dt=dt,
        name="thrown",
    )


def tunnelling(record: Iterable[warnings.WarningMessage]) -> list[jello.TunnellingWarning]:
    """The tunnelling warnings among those recorded."""
    return [w.message for w in record if isinstance(w.message, jello.TunnellingWarning)]


def test_a_cube_thrown_through_a_plate_warns_with_the_advice_in_python_terms() -> None:
    sim = thrown()
    with pytest.warns(jello.TunnellingWarning) as record:
        sim.run(250)
    [w] = tunnelling(record)
    text = str(w)
    assert text.startswith(
        "thrown: 9 points of body 'cube' passed through obstacle 1 (box, 5 cm thick there) "
        "between t = 0.014 s and 0.016 s"
    ), text
    assert "try sim.dt = " in text and "--dt" not in text, text
    assert (w.body, w.obstacle, w.points) == (0, 0, 9)
    assert w.time == pytest.approx((0.014, 0.016))
    assert w.suggested_dt is not None and w.suggested_dt == pytest.approx(0.00042, rel=0.05)
    assert "try sim.dt = 0.00042 or less" in text, text
    # Attributed to the line that called `run`, not to the package.
    assert record[0].filename == __file__

    # The advice followed (the model changed, so the watch starts again): it bounces off.
    again = thrown()
    again.dt = w.suggested_dt
    with warnings.catch_warnings():
        warnings.simplefilter("error", jello.TunnellingWarning)
        again.run(round(0.5 / again.dt))
    assert again.positions[:, 2].min() > 0.0


def test_steps_one_at_a_time_are_watched_across_calls_and_warned_once() -> None:
    sim = thrown()
    with warnings.catch_warnings(record=True) as record:
        warnings.simplefilter("always")
        for _ in range(250):
            sim.step()
    [w] = tunnelling(record)
    # Found over the steps as in one call, and warned of once.
    assert "between t = 0.014 s and 0.016 s" in str(w), str(w)


def test_a_warning_made_an_error_raises_and_the_state_is_kept() -> None:
    sim = thrown()
    with warnings.catch_warnings():
        warnings.simplefilter("error", jello.TunnellingWarning)
        with pytest.raises(jello.TunnellingWarning):
            sim.run(20)
    assert sim.steps == 20


def test_a_gentle_drop_on_the_plate_does_not_warn() -> None:
    cube = jello.cube(3, 0.2, centre=(0, 0, 0.3), name="cube")
    sim = jello.create([cube], obstacles=[PLATE], collision_stiffness=1e4, collision_damping=5)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sim.run(2000)
    assert sim.positions[:, 2].min() > -0.01


def test_positions_assigned_are_not_a_crossing() -> None:
    """A cube moved from above the plate to under it from Python is not counted as passing."""
    cube = jello.cube(3, 0.2, centre=(0, 0, 0.3), name="cube")
    sim = jello.create([cube], obstacles=[PLATE], collision_stiffness=1e4, collision_damping=5)
    sim.step()
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        sim.positions = sim.positions - np.array([0.0, 0.0, 0.6])
        sim.step(10)


def gpu_or_skip(sim: jello.Simulation) -> None:
    try:
        sim.device = "gpu"
    except jello.GpuError as e:
        if os.environ.get("JELLO_REQUIRE_GPU") == "1":
            pytest.fail(f"JELLO_REQUIRE_GPU=1 but there is no usable GPU: {e}")
        pytest.skip(f"no usable GPU (install Mesa's lavapipe: mesa-vulkan-drivers): {e}")


def test_on_the_gpu_the_states_read_back_are_compared() -> None:
    """SymplecticEuler at 60 m/s on the plate with a soft contact passes through it on the CPU
    and on the GPU; there the states read back are compared, several steps apart."""

    def soft(device: str) -> jello.Simulation:
        cube = jello.cube(3, 0.2, centre=(0, 0, 0.5), velocity=(0, 0, -60), name="cube")
        sim = jello.create(
            [cube], obstacles=[PLATE], collision_stiffness=1e3, integrator="SymplecticEuler", dt=5e-4
        )
        if device == "gpu":
            gpu_or_skip(sim)
        return sim

    with pytest.warns(jello.TunnellingWarning, match="a step carried them past its middle"):
        soft("cpu").run(400)
    on_gpu = soft("gpu")
    with pytest.warns(jello.TunnellingWarning, match="read back up to [0-9]+ steps apart they went past") as record:
        on_gpu.run(400)
    [w] = tunnelling(record)
    assert (w.body, w.obstacle) == (0, 0) and w.points == 27, str(w)
    assert w.suggested_collision_stiffness is not None, str(w)


def test_an_obstacle_through_a_coarse_body_is_warned_of_after_the_call() -> None:
    """A cube of 4³ points (13 cm apart) dropped on an upright 5 cm blade: the blade passes
    between its points without touching one; after the call, the cube has it through it."""
    blade = jello.box((-0.025, -1, -2), (0.025, 1, 0))
    cube = jello.cube(4, 0.4, centre=(0, 0, 0.5), name="cube")
    sim = jello.create([cube], obstacles=[blade], collision_stiffness=1e4, collision_damping=5)
    with pytest.warns(jello.TunnellingWarning, match="ends with obstacle 1 .* through it") as record:
        sim.run(3000)
    [w] = tunnelling(record)
    assert (w.body, w.obstacle, w.points) == (0, 0, None)
    assert w.time == (sim.time, sim.time)
    assert "thinner than the body's lattice spacing" in str(w)


def two_cubes(small_at: tuple[float, float, float], velocity: tuple[float, float, float]):
    """The command line's test: a 0.1 m cube of 3³ points and a 0.5 m cube of 5³, without
    gravity, at a contact too soft to stop the small one at 60 m/s."""
    block = jello.cube(5, 0.5, centre=(0, 0, 0), total_mass=10, name="block")
    bullet = jello.cube(3, 0.1, centre=small_at, velocity=velocity, total_mass=0.5, name="bullet")
    return jello.create(
        [block, bullet],
        gravity=(0, 0, 0),
        collision_stiffness=2000,
        dt=0.0001,
        name="thrown",
    )


def overlaps(record: Iterable[warnings.WarningMessage]) -> list[jello.OverlapWarning]:
    """The overlap warnings among those recorded."""
    return [w.message for w in record if isinstance(w.message, jello.OverlapWarning)]


def test_bodies_that_end_a_run_inside_each_other_are_warned_of_once_with_a_stiffness() -> None:
    sim = two_cubes((-0.8, 0, 0), (60, 0, 0))
    with pytest.warns(jello.OverlapWarning) as record:
        sim.run(200)
    [w] = overlaps(record)
    text = str(w)
    assert text.startswith(
        "thrown: bodies 'block' and 'bullet' end 7.23 cm inside each other"
    ), text
    assert "`sim.set_collision(stiffness=140000)`" in text and "--collision" not in text, text
    assert w.bodies == (0, 1)
    assert w.depth == pytest.approx(0.0723, abs=5e-5)
    assert w.suggested_collision_stiffness == 140000
    assert record[0].filename == __file__
    # Still inside after the next call: not warned again.
    with warnings.catch_warnings(record=True) as again:
        warnings.simplefilter("always")
        sim.run(1)
    assert not overlaps(again)
    # `step` does not look (a loop of single steps would pay a contact search each).
    sim = two_cubes((-0.8, 0, 0), (60, 0, 0))
    with warnings.catch_warnings():
        warnings.simplefilter("error", jello.OverlapWarning)
        sim.step(200)


def test_bodies_side_by_side_at_rest_are_not_warned_of() -> None:
    sim = two_cubes((0.301, 0, 0), (0, 0, 0))
    with warnings.catch_warnings():
        warnings.simplefilter("error", jello.OverlapWarning)
        sim.run(200)
