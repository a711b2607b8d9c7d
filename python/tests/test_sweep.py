"""Sweeps: a grid of cases on Dask equals the same cases run one by one, alone."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import jello
from conftest import EXAMPLES

WORLDS = [EXAMPLES / "jello.w", EXAMPLES / "rotate.w"]
GRID = {"stiffness": [150.0, 300.0], "dt": [0.0005, 0.004], "integrator": ["RK4", "BackwardEuler"]}
METRICS = ("final_energy", "kinetic_energy", "max_penetration", "blew_up", "blow_up", "steps", "time")


def test_a_sweep_on_a_local_cluster_of_two_workers_equals_the_serial_sweep(tmp_path: Path) -> None:
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(
        n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None
    ) as cluster, distributed.Client(cluster) as client:
        on_cluster = jello.sweep(WORLDS, GRID, steps=200, metrics=METRICS, scheduler=client,
                                 save=tmp_path / "cluster", progress=False)
    serial = jello.sweep(WORLDS, GRID, steps=200, metrics=METRICS, scheduler="serial",
                         save=tmp_path / "serial", progress=False)
    assert len(on_cluster) == 2 * 8
    pd.testing.assert_frame_equal(
        on_cluster.drop(columns="saved"), serial.drop(columns="saved"), check_exact=True
    )
    for a, b in zip(on_cluster["saved"], serial["saved"]):
        assert Path(a).read_text() == Path(b).read_text()
    # Some cases blow up (RK4 at dt 0.004 with these springs), some do not: both are reported.
    assert on_cluster["blew_up"].any() and not on_cluster["blew_up"].all()
    blown = on_cluster[on_cluster["blew_up"]].iloc[0]
    assert "blew up" in blown["blow_up"] and blown["steps"] < 200


def test_each_row_is_the_case_run_alone() -> None:
    table = jello.sweep(WORLDS[:1], {"stiffness": [120.0], "velocity": [(0.5, 0.0, -1.0)]},
                        time=0.1, metrics=("final_energy", "max_penetration", "steps"),
                        scheduler="serial", progress=False)
    sim = jello.load(WORLDS[0])
    sim.set_material(stiffness=120.0)
    sim.velocities = np.tile([0.5, 0.0, -1.0], (len(sim), 1))
    deepest = sim.run(200)
    row = table.iloc[0]
    assert row["steps"] == 200
    assert row["final_energy"] == sim.energy().total
    assert row["max_penetration"] == deepest
    assert list(table.columns) == ["world", "stiffness", "velocity", "final_energy", "max_penetration", "steps"]


def test_metric_functions_and_explicit_cases() -> None:
    def lowest_z(sim: jello.Simulation) -> float:
        return float(sim.positions[:, 2].min())

    table = jello.sweep(EXAMPLES / "gravity.w", cases=[{"dt": 0.0001}, {"dt": 0.0002, "mass": 0.004}],
                        steps=50, metrics=(lowest_z, "time"), scheduler="serial", progress=False)
    alone = jello.load(EXAMPLES / "gravity.w", dt=0.0002)
    alone.set_material(mass=0.004)
    alone.step(50)
    assert table["lowest_z"][1] == lowest_z(alone)
    assert table["lowest_z"][0] != table["lowest_z"][1]
    assert table["time"].tolist() == pytest.approx([0.005, 0.01])
    assert np.isnan(table["mass"][0]) and table["mass"][1] == 0.004


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"parameters": {"stiffnes": [1.0]}}, "unknown parameter 'stiffnes'"),
        ({"parameters": {"dt": 0.1}}, "needs a list of values"),
        ({"metrics": ("energy",)}, "unknown metric 'energy'"),
        ({"steps": 10, "time": 1.0}, "either steps or time"),
        ({"parameters": {"dt": [1.0]}, "cases": [{}]}, "either parameters"),
    ],
)
def test_bad_sweeps_are_refused_before_anything_runs(kwargs: dict[str, object], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        jello.sweep(EXAMPLES / "jello.w", scheduler="serial", progress=False, **kwargs)  # type: ignore[arg-type]


def test_a_bad_world_fails_before_the_cluster_starts(tmp_path: Path) -> None:
    bad = tmp_path / "bad.w"
    bad.write_text("RK4\n")
    with pytest.raises(jello.WorldError, match="bad.w"):
        jello.sweep(bad, scheduler="tcp://127.0.0.1:1", progress=False)


def test_cutbacks_are_a_parameter_and_split_steps_a_metric(shared_worlds: Path) -> None:
    """leapfrog.w under SDIRK2 at 0.05 s: its first step converges only in halves."""
    table = jello.sweep(shared_worlds / "leapfrog.w", {"integrator": ["SDIRK2"], "dt": [0.05], "cutbacks": [0, 6]},
                        steps=2, metrics=("blew_up", "steps", "split_steps"), scheduler="serial", progress=False)
    strict, lenient = table.iloc[0], table.iloc[1]
    assert (strict["cutbacks"], lenient["cutbacks"]) == (0, 6)
    assert strict["blew_up"] and strict["steps"] == 0 and strict["split_steps"] == 0
    assert not lenient["blew_up"] and lenient["steps"] == 2 and lenient["split_steps"] >= 1


def test_tolerance_is_a_parameter(shared_worlds: Path) -> None:
    """jello.w under backward Euler at 1/60 s: a looser tolerance is another case of the table,
    whose final energy after 30 steps is within 0.1 % of the default solve's."""
    table = jello.sweep(shared_worlds / "jello.w",
                        {"integrator": ["BackwardEuler"], "dt": [1 / 60], "tolerance": [1e-9, 1e-5]},
                        steps=30, metrics=("blew_up", "steps", "final_energy"), scheduler="serial",
                        progress=False)
    strict, loose = table.iloc[0], table.iloc[1]
    assert (strict["tolerance"], loose["tolerance"]) == (1e-9, 1e-5)
    assert not strict["blew_up"] and not loose["blew_up"] and strict["steps"] == loose["steps"] == 30
    assert loose["final_energy"] == pytest.approx(strict["final_energy"], rel=1e-3)


def test_the_implicit_solvers_work_is_a_property_and_a_metric() -> None:
    """`solver_stats` counts the implicit solver's work: a solve a backward-Euler step, at least
    a conjugate-gradient iteration a Newton iteration; it starts again when the model changes
    and stays zero under RK4. The sweep's `newton_iterations` and `linear_iterations` are those
    counts, higher at a tighter tolerance."""
    sim = jello.load(EXAMPLES / "jello.w", integrator="BackwardEuler", dt=1 / 60)
    assert sim.solver_stats.solves == 0
    sim.step(5)
    stats = sim.solver_stats
    assert isinstance(stats, jello.SolverStats) and "newton_iterations=" in repr(stats)
    assert stats.solves == 5 and stats.newton_iterations >= 5
    assert stats.linear_iterations >= stats.newton_iterations and stats.assemblies >= 1
    sim.tolerance = 1e-6
    assert sim.solver_stats.newton_iterations == 0
    explicit = jello.load(EXAMPLES / "jello.w")
    explicit.step(5)
    assert explicit.solver_stats.solves == explicit.solver_stats.linear_iterations == 0

    table = jello.sweep(EXAMPLES / "jello.w", {"integrator": ["BackwardEuler"], "dt": [1 / 60],
                                              "tolerance": [1e-10, 1e-3]},
                        steps=5, metrics=("newton_iterations", "linear_iterations"),
                        scheduler="serial", progress=False)
    tight, loose = table.iloc[0], table.iloc[1]
    assert tight["tolerance"] == 1e-10 and loose["tolerance"] == 1e-3
    assert tight["newton_iterations"] > loose["newton_iterations"] > 0
    assert tight["linear_iterations"] > loose["linear_iterations"]
    again = jello.load(EXAMPLES / "jello.w", integrator="BackwardEuler", dt=1 / 60)
    again.tolerance = 1e-10
    again.step(5)
    assert tight["newton_iterations"] == again.solver_stats.newton_iterations
