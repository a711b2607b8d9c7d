"""`device="gpu"`: the f32 shaders of jello-gpu through wgpu, against the f64 core.

On a machine without a GPU these run on Mesa's lavapipe (`scripts/setup.sh` installs Debian's
mesa-vulkan-drivers). Where no adapter at all is found they skip, saying so, unless
JELLO_REQUIRE_GPU=1 (as `scripts/python-test.sh` sets it), where they fail.
"""

from __future__ import annotations

import os
import sys

import numpy as np
import pytest

import jello
from conftest import EXAMPLES


def spinning_cube(device: str = "cpu", integrator: str = "RK4") -> jello.Simulation:
    """A 6×5×4 lattice spinning and drifting in the middle of the box, under gravity: no
    contact within 200 steps."""
    body = jello.cube((6, 5, 4), 0.5, at=(0.0, 0.0, 0.5), velocity=(0.3, -0.2, 0.5), spin=(1.0, 2.0, -3.0))
    sim = jello.create([body], gravity=(0.0, 0.0, -9.81), integrator=integrator, dt=0.0005)
    sim.device = device
    return sim


@pytest.fixture(scope="module")
def gpu() -> str:
    """The adapter's name, or a skip when there is no usable GPU."""
    try:
        sim = spinning_cube("gpu")
    except jello.GpuError as e:
        if os.environ.get("JELLO_REQUIRE_GPU") == "1":
            pytest.fail(f"JELLO_REQUIRE_GPU=1 but there is no usable GPU: {e}")
        pytest.skip(f"no usable GPU (install Mesa's lavapipe: mesa-vulkan-drivers): {e}")
    adapter = sim.adapter
    assert adapter
    return adapter


@pytest.mark.parametrize("integrator", ["Euler", "SymplecticEuler", "RK2", "RK4"])
def test_the_gpu_agrees_with_the_core_within_f32(gpu: str, integrator: str) -> None:
    cpu, on_gpu = spinning_cube("cpu", integrator), spinning_cube("gpu", integrator)
    assert on_gpu.device == "gpu" and cpu.adapter is None
    cpu.step(200)
    on_gpu.step(200)
    assert on_gpu.steps == 200 and on_gpu.time == pytest.approx(cpu.time)
    # Far apart in f64 terms (the cube moved centimetres), close in f32 ones.
    assert np.abs(cpu.positions - spinning_cube().positions).max() > 1e-2
    assert np.abs(on_gpu.positions - cpu.positions).max() < 1e-4
    assert np.abs(on_gpu.velocities - cpu.velocities).max() < 1e-2
    assert on_gpu.energy().total == pytest.approx(cpu.energy().total, rel=1e-4)


def test_changes_from_python_reach_the_gpu(gpu: str) -> None:
    cpu, on_gpu = spinning_cube(), spinning_cube("gpu")
    centre = cpu.positions.mean(axis=0)
    stretched = centre + 1.1 * (cpu.positions - centre)
    pushed = np.zeros((len(cpu), 3))
    pushed[:10] = [0.0, 0.05, 0.0]
    # Each change, made on both between calls, then 20 steps: the GPU's copy is made again from
    # the core's each time (a stale copy would be millimetres away).
    changes = {
        "positions": lambda sim: setattr(sim, "positions", stretched),
        "velocities": lambda sim: setattr(sim, "velocities", np.zeros((len(sim), 3))),
        "control_forces": lambda sim: setattr(sim, "control_forces", pushed),
        "dt": lambda sim: setattr(sim, "dt", 0.00025),
        "material": lambda sim: sim.set_material(stiffness=2000.0),
        "no control_forces": lambda sim: setattr(sim, "control_forces", None),
    }
    for what, change in changes.items():
        for sim in (cpu, on_gpu):
            change(sim)
            sim.step(20)
        assert on_gpu.time == pytest.approx(cpu.time), what
        assert np.abs(on_gpu.positions - cpu.positions).max() < 1e-4, what


def test_moving_between_devices_carries_the_state_on(gpu: str) -> None:
    sim = spinning_cube("gpu")
    sim.step(50)
    sim.device = "cpu"
    assert sim.device == "cpu" and sim.adapter is None
    sim.step(50)
    reference = spinning_cube()
    reference.step(100)
    assert sim.steps == 100
    assert np.abs(sim.positions - reference.positions).max() < 1e-4
    assert "device='gpu'" not in repr(sim)
    sim.device = "GPU"
    assert "device='gpu' (f32)" in repr(sim)
    # A copy makes its own GPU copy, and steps on as its original does.
    twin = sim.copy()
    for s in (sim, twin):
        s.step(10)
    assert twin.device == "gpu" and np.array_equal(twin.positions, sim.positions)


def test_run_reports_the_deepest_penetration_on_the_gpu(gpu: str) -> None:
    cpu = jello.load(EXAMPLES / "jello.w")
    on_gpu = jello.load(EXAMPLES / "jello.w", device="gpu")
    assert on_gpu.device == "gpu"
    deepest = [sim.run(2000) for sim in (cpu, on_gpu)]
    assert deepest[0] > 0.0
    assert deepest[1] == pytest.approx(deepest[0], rel=5e-2)
    assert abs(on_gpu.energy().total - cpu.energy().total) <= 1e-2 * cpu.energy().total


def test_a_blow_up_on_the_gpu_leaves_the_last_good_step(gpu: str) -> None:
    cpu = jello.load(EXAMPLES / "jello.w", integrator="Euler", dt=0.01)
    sim = jello.load(EXAMPLES / "jello.w", device="gpu", integrator="Euler", dt=0.01)
    with pytest.raises(jello.BlowUp) as on_cpu:
        cpu.run(10_000)
    with pytest.raises(jello.BlowUp) as raised:
        sim.run(10_000)
    e = raised.value
    assert sim.steps == e.step - 1 and sim.time == pytest.approx(e.time)
    assert np.isfinite(sim.positions).all()
    assert "jello.w" in str(e) and e.integrator == "Euler"
    # The same blow-up as the core's, to f32 rounding: the same step, give or take one, and the
    # deepest penetration before it within a few per cent.
    assert abs(e.step - on_cpu.value.step) <= 1
    assert e.max_penetration == pytest.approx(on_cpu.value.max_penetration, rel=0.05)
    # Kept at the last good step: stepping on fails at the same step again.
    with pytest.raises(jello.BlowUp) as again:
        sim.step(10)
    assert again.value.step == e.step


def test_what_the_gpu_does_not_cover_is_refused_and_nothing_changes(gpu: str) -> None:
    sim = spinning_cube("gpu")
    with pytest.raises(ValueError, match="implicit integrator BackwardEuler"):
        sim.integrator = "BackwardEuler"
    assert sim.integrator == "RK4" and sim.device == "gpu"
    cpu = spinning_cube(integrator="BackwardEuler")
    with pytest.raises(ValueError, match="implicit integrator"):
        cpu.device = "gpu"
    assert cpu.device == "cpu"
    implicit = jello.loads(
        '[simulation]\nintegrator = "BackwardEuler"\n\n'
        "[[body]]\ncube = { points = [4, 4, 4], size = [1.0, 1.0, 1.0] }\n",
        format="toml",
    )
    with pytest.raises(
        ValueError, match=r"does not support the implicit integrator BackwardEuler .*yet; run it on the CPU"
    ):
        implicit.device = "gpu"
    assert implicit.device == "cpu"
    with pytest.raises(ValueError, match='expected "cpu" or "gpu", found "tpu"'):
        sim.device = "tpu"
    with pytest.raises(ValueError, match="device"):
        jello.load(EXAMPLES / "jello.w", device="cuda")


def test_several_bodies_an_obstacle_and_friction_on_the_gpu(gpu: str) -> None:
    # The stack: three cubes on a ball, with friction between them and on the ball.
    cpu = jello.load(EXAMPLES / "stack.toml")
    on_gpu = jello.load(EXAMPLES / "stack.toml", device="gpu")
    cpu.step(300)
    on_gpu.step(300)
    assert np.abs(on_gpu.positions - cpu.positions).max() < 1e-3
    assert on_gpu.energy().total == pytest.approx(cpu.energy().total, rel=0.01)


def test_no_usable_gpu_is_a_clear_error(monkeypatch: pytest.MonkeyPatch) -> None:
    # A backend this platform has no driver for: wgpu finds no adapter.
    monkeypatch.setenv("WGPU_BACKEND", "metal" if sys.platform == "win32" else "dx12")
    sim = spinning_cube()
    with pytest.raises(jello.GpuError, match="no usable GPU"):
        sim.device = "gpu"
    assert sim.device == "cpu"
    sim.step(10)
    assert sim.steps == 10


def test_ctrl_c_stops_a_long_gpu_call_with_the_state_read_back(gpu: str) -> None:
    # In a child process, SIGINT a second into a call of ten million GPU steps: KeyboardInterrupt
    # comes between chunks, with the state read back at the last one and the time at its step.
    import subprocess
    import sys

    script = """
import os, signal, threading
import numpy as np
import jello
signal.signal(signal.SIGINT, signal.default_int_handler)
sim = jello.load(%r, device="gpu")
threading.Timer(1.0, lambda: os.kill(os.getpid(), signal.SIGINT)).start()
try:
    sim.step(10_000_000)
except KeyboardInterrupt:
    print(sim.steps, bool(np.isfinite(sim.positions).all()), abs(sim.time - sim.steps * sim.dt) <= 1e-9 * max(sim.time, 1.0))
    sim.step(10)
    print(sim.steps)
""" % str(EXAMPLES / "jello.w")
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=120)
    assert run.returncode == 0, run.stderr
    (steps, finite, on_time), (after,) = (line.split() for line in run.stdout.splitlines())
    assert 0 < int(steps) < 10_000_000 and finite == "True" and on_time == "True"
    # It steps on from there.
    assert int(after) == int(steps) + 10


def test_device_is_a_sweep_parameter(gpu: str) -> None:
    table = jello.sweep(
        EXAMPLES / "jello.w",
        {"stiffness": [300.0], "device": ["cpu", "gpu"]},
        steps=1000,
        metrics=("final_energy", "max_penetration", "steps"),
        scheduler="serial",
        progress=False,
    )
    assert list(table["device"]) == ["cpu", "gpu"] and list(table["steps"]) == [1000, 1000]
    cpu, on_gpu = table.iloc[0], table.iloc[1]
    assert on_gpu["final_energy"] == pytest.approx(cpu["final_energy"], rel=1e-2)
    # The GPU row is the case run alone there (the shader gives the same bits every run).
    sim = jello.load(EXAMPLES / "jello.w")
    sim.set_material(stiffness=300.0)
    sim.device = "gpu"
    deepest = sim.run(1000)
    assert on_gpu["final_energy"] == sim.energy().total and on_gpu["max_penetration"] == deepest
    # A case the GPU cannot step is refused, naming why.
    with pytest.raises(ValueError, match="implicit integrator BackwardEuler"):
        jello.sweep(EXAMPLES / "jello.w", {"integrator": ["BackwardEuler"], "device": ["gpu"]},
                    steps=10, scheduler="serial", progress=False)


def test_points_outside_a_mesh_body_are_in_no_contact_on_the_gpu(gpu: str) -> None:
    # An octahedron voxelised into a lattice whose corners lie outside it, turned 45° about z so
    # that those corners reach past a wall the body itself stays clear of: the deepest
    # penetration is the body's, as the core measures it, not the corners'.
    vertices = [(0.5, 0, 0), (-0.5, 0, 0), (0, 0.5, 0), (0, -0.5, 0), (0, 0, 0.5), (0, 0, -0.5)]
    triangles = [(0, 2, 4), (2, 1, 4), (1, 3, 4), (3, 0, 4), (2, 0, 5), (1, 2, 5), (3, 1, 5), (0, 3, 5)]
    wall = 0.6
    deepest = []
    for device in ("cpu", "gpu"):
        body = jello.mesh(vertices=vertices, triangles=triangles, cells=6, rotation=(0, 0, 45))
        sim = jello.create([body], bounds=((-2, -2, -2), (wall, 2, 2)), dt=0.0005)
        sim.device = device
        lattice_depth = sim.lattice_positions[:, 0].max() - wall
        deepest.append(sim.run(1))
    assert lattice_depth > deepest[0] + 0.05
    assert deepest[1] == pytest.approx(deepest[0], abs=1e-4)
