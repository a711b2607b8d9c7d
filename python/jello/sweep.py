"""Parameter sweeps: worlds × parameters run on Dask, results as a pandas table.

Each case is one world (or scene) with some parameters changed, run for a number of steps; the
table has one row per case with its parameters and the metrics asked for. The world files are
read here and sent to the workers as text, so workers on other machines need no shared disk,
only the ``jello`` package. Every case runs alone on one worker, and the core is deterministic
and bit-identical on any thread count, so a row is exactly what running that case by itself
gives.
"""

from __future__ import annotations

import itertools
import os
import time as _time
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any, Union

import numpy as np

from jello._jello import BlowUp, Simulation, loads

if TYPE_CHECKING:
    import pandas
    from distributed import Client

#: What a sweep can measure, by name: see :func:`sweep`.
METRICS: tuple[str, ...] = (
    "final_energy",
    "kinetic_energy",
    "spring_energy",
    "collision_energy",
    "max_penetration",
    "blew_up",
    "blow_up",
    "steps",
    "time",
    "split_steps",
    "newton_iterations",
    "linear_iterations",
    "wall_s",
)

#: The parameters a case may change, by name: see :func:`sweep`.
PARAMETERS: tuple[str, ...] = (
    "integrator",
    "dt",
    "cutbacks",
    "tolerance",
    "stiffness",
    "damping",
    "mass",
    "collision_stiffness",
    "collision_damping",
    "velocity",
    "device",
)

#: A metric computed by the caller's function from the final simulation.
MetricFunction = Callable[[Simulation], Any]
Metric = Union[str, MetricFunction]
PathLike = Union[str, "os.PathLike[str]"]


def sweep(
    worlds: PathLike | Iterable[PathLike],
    parameters: Mapping[str, Sequence[Any]] | None = None,
    *,
    cases: Sequence[Mapping[str, Any]] | None = None,
    steps: int | None = None,
    time: float | None = None,
    metrics: Sequence[Metric] = ("final_energy", "max_penetration", "blew_up"),
    save: PathLike | None = None,
    scheduler: str | Client = "local",
    workers: int | None = None,
    progress: bool = True,
) -> pandas.DataFrame:
    """Runs every world with every combination of ``parameters`` and returns a table.

    ``worlds``: a ``.w`` world or ``.toml`` scene file, or several.

    ``parameters``: a name → values mapping whose product is swept, e.g.
    ``{"stiffness": [100, 200, 400], "dt": [0.0005, 0.001]}`` is six cases per world. Or give
    ``cases``, a list of name → value mappings, each one case per world. The names:

    - ``integrator`` (``"RK4"``, ``"BackwardEuler"``…) and ``dt`` (s); ``cutbacks``, how many
      times an implicit step that fails may be halved (see ``Simulation.cutbacks``), and
      ``tolerance``, the residual an implicit step is solved to (m/s, see
      ``Simulation.tolerance``);
    - ``stiffness`` (N/m) and ``damping`` (N·s/m) of every spring, a number or one per kind,
      and ``mass`` (kg per point), of every body;
    - ``collision_stiffness`` (N/m) and ``collision_damping`` (N·s/m);
    - ``velocity``: every point's initial velocity (m/s), three numbers;
    - ``device``: ``"cpu"`` (the default) or ``"gpu"``, where the case steps (see
      ``Simulation.device``: f32, the explicit integrators; set after the other parameters, so a
      case the GPU cannot step raises ``ValueError``, and a worker without a GPU
      ``jello.GpuError``).

    ``steps`` or ``time`` (s, rounded up to whole steps): how long each case runs (default 1 s).

    ``metrics``: names from :data:`METRICS` (``final_energy`` (J), ``kinetic_energy``,
    ``spring_energy``, ``collision_energy``, ``max_penetration`` (the deepest over the run, m),
    ``blew_up`` (bool), ``blow_up`` (the message, or None), ``steps`` and ``time`` reached,
    ``split_steps`` (steps an implicit integrator took in parts), ``newton_iterations`` and
    ``linear_iterations`` (the implicit solver's Newton and conjugate-gradient iterations over
    the run, failed tries included), ``wall_s``) or functions of
    the final :class:`~jello.Simulation` (their ``__name__`` heads the column). A case that blows up reports the metrics of its last good step.

    ``save``: a folder (created when missing) where each case's final state is written as
    ``case-0000.w`` (or ``.toml`` for a scene); the table's ``saved`` column names the file.

    ``scheduler``: ``"local"`` (default) starts a ``distributed.LocalCluster`` of ``workers``
    processes (default: one per core) for this sweep and closes it after; an address such as
    ``"tcp://10.0.0.5:8786"`` uses a running scheduler (dask-jobqueue, Kubernetes, ``dask
    scheduler``); a ``distributed.Client`` uses that client; ``"serial"`` runs the cases here,
    one after the other, without Dask.

    ``progress``: a progress bar (tqdm) on stderr as cases finish.
    """
    import pandas

    world_paths = [worlds] if isinstance(worlds, (str, os.PathLike)) else list(worlds)
    if not world_paths:
        raise ValueError("worlds: expected at least one world or scene file")
    if parameters is not None and cases is not None:
        raise ValueError("give either parameters (a grid) or cases (a list), not both")
    if cases is None:
        grid = dict(parameters or {})
        for name, values in grid.items():
            if isinstance(values, (str, bytes)) or not isinstance(values, Iterable):
                raise ValueError(
                    f"parameters: {name!r} needs a list of values, found {values!r}"
                )
        names = list(grid)
        case_params = [
            dict(zip(names, combo)) for combo in itertools.product(*(list(grid[n]) for n in names))
        ]
    else:
        case_params = [dict(c) for c in cases]
    for params in case_params:
        for name in params:
            if name not in PARAMETERS:
                raise ValueError(
                    f"unknown parameter {name!r}: expected one of {', '.join(PARAMETERS)}"
                )
    if steps is not None and time is not None:
        raise ValueError("give either steps or time, not both")
    if steps is not None and steps < 0:
        raise ValueError(f"steps: expected 0 or more, found {steps}")
    if time is not None and not time > 0:
        raise ValueError(f"time: expected a positive time (s), found {time}")
    for m in metrics:
        if isinstance(m, str) and m not in METRICS:
            raise ValueError(f"unknown metric {m!r}: expected one of {', '.join(METRICS)}")
        if not isinstance(m, str) and not callable(m):
            raise ValueError(f"metrics: expected names or functions, found {m!r}")

    # The files are read here, once: the workers get their text.
    texts: list[tuple[str, str, str]] = []
    for w in world_paths:
        path = Path(w)
        fmt = "toml" if path.suffix.lower() == ".toml" else "w"
        texts.append((str(w), path.read_text(encoding="utf-8"), fmt))
        # A bad file fails here, before any cluster starts.
        loads(texts[-1][1], format=fmt, name=str(w))

    jobs = [
        _Job(
            index=i,
            world=world,
            text=text,
            format=fmt,
            params=params,
            steps=steps,
            time=time,
            metrics=tuple(metrics),
            keep_state=save is not None,
        )
        for i, ((world, text, fmt), params) in enumerate(
            itertools.product(texts, case_params)
        )
    ]
    results = _execute(jobs, scheduler, workers, progress)

    rows = []
    save_dir = Path(save) if save is not None else None
    if save_dir is not None:
        save_dir.mkdir(parents=True, exist_ok=True)
    for job, result in zip(jobs, results):
        row: dict[str, Any] = {"world": job.world, **job.params}
        row.update(result["metrics"])
        if save_dir is not None:
            out = save_dir / f"case-{job.index:04d}.{job.format}"
            _write_whole(out, result["state"])
            row["saved"] = str(out)
        rows.append(row)
    return pandas.DataFrame(rows)


@dataclass(frozen=True)
class _Job:
    """One case, as sent to a worker (plain data: it pickles)."""

    index: int
    world: str
    text: str
    format: str
    params: dict[str, Any]
    steps: int | None
    time: float | None
    metrics: tuple[Metric, ...]
    keep_state: bool


def run_case(job: _Job) -> dict[str, Any]:
    """Runs one case where it is called (on a worker) and returns its metrics (and state)."""
    sim = loads(job.text, format=job.format, name=job.world)
    apply_parameters(sim, job.params)
    n = job.steps if job.steps is not None else steps_for(job.time or 1.0, sim.dt)
    start = _time.perf_counter()
    blow_up: str | None = None
    try:
        deepest = sim.run(n)
    except BlowUp as e:
        blow_up = str(e)
        deepest = float(getattr(e, "max_penetration", float("nan")))
    wall = _time.perf_counter() - start
    energy = sim.energy()
    solver = sim.solver_stats
    values: dict[str, Any] = {
        "final_energy": energy.total,
        "kinetic_energy": energy.kinetic,
        "spring_energy": energy.spring,
        "collision_energy": energy.collision,
        "max_penetration": deepest,
        "blew_up": blow_up is not None,
        "blow_up": blow_up,
        "steps": sim.steps,
        "time": sim.time,
        "split_steps": sim.split_steps,
        "newton_iterations": solver.newton_iterations,
        "linear_iterations": solver.linear_iterations,
        "wall_s": wall,
    }
    out: dict[str, Any] = {}
    for m in job.metrics:
        if isinstance(m, str):
            out[m] = values[m]
        else:
            out[getattr(m, "__name__", repr(m))] = m(sim)
    return {"metrics": out, "state": sim.dumps() if job.keep_state else None}


def apply_parameters(sim: Simulation, params: Mapping[str, Any]) -> None:
    """Changes ``sim`` as a sweep's case says (the names of :data:`PARAMETERS`)."""
    if "integrator" in params:
        sim.integrator = params["integrator"]
    if "dt" in params:
        sim.dt = float(params["dt"])
    if "cutbacks" in params:
        sim.cutbacks = int(params["cutbacks"])
    if "tolerance" in params:
        sim.tolerance = float(params["tolerance"])
    material = {k: params[k] for k in ("stiffness", "damping", "mass") if k in params}
    if material:
        sim.set_material(**material)
    collision = {
        k.removeprefix("collision_"): params[k]
        for k in ("collision_stiffness", "collision_damping")
        if k in params
    }
    if collision:
        sim.set_collision(**collision)
    if "velocity" in params:
        v = np.asarray(params["velocity"], dtype=np.float64)
        if v.shape != (3,):
            raise ValueError(f"velocity: expected three numbers (m/s), found {params['velocity']!r}")
        sim.velocities = np.broadcast_to(v, (len(sim), 3))
    if "device" in params:
        sim.device = str(params["device"])


def steps_for(time: float, dt: float) -> int:
    """Whole steps covering ``time`` at ``dt``, as ``jello run --time`` counts them."""
    q = time / dt
    nearest = round(q)
    if abs(q - nearest) <= 1e-9 * max(nearest, 1):
        return int(nearest)
    return int(np.ceil(q))


def _execute(
    jobs: list[_Job], scheduler: str | Client, workers: int | None, progress: bool
) -> list[dict[str, Any]]:
    """Every job's result, in the jobs' order."""
    from tqdm.auto import tqdm

    bar = tqdm(total=len(jobs), desc="jello sweep", unit="case", disable=not progress)
    try:
        if isinstance(scheduler, str) and scheduler == "serial":
            results = []
            for job in jobs:
                results.append(run_case(job))
                bar.update(1)
            return results

        from distributed import Client, LocalCluster, as_completed

        own_cluster = None
        if isinstance(scheduler, str):
            if scheduler == "local":
                own_cluster = LocalCluster(
                    n_workers=workers or os.cpu_count() or 1,
                    threads_per_worker=1,
                    processes=True,
                    dashboard_address=None,
                )
                client = Client(own_cluster)
            else:
                client = Client(scheduler)
        else:
            client = scheduler
        try:
            futures = client.map(run_case, jobs, pure=False)
            for _ in as_completed(futures):
                bar.update(1)
            return list(client.gather(futures))
        finally:
            if own_cluster is not None:
                client.close()
                own_cluster.close()
            elif isinstance(scheduler, str):
                client.close()
    finally:
        bar.close()


def _write_whole(path: Path, text: str) -> None:
    """Writes ``text`` to ``path`` whole or not at all (a temporary file renamed over it)."""
    tmp = path.with_name(f".{path.name}.tmp-{os.getpid()}")
    try:
        tmp.write_text(text, encoding="utf-8")
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
