"""Jello from Python: mass-spring soft bodies (the classic jello cube and shapes of your own).

The physics is Jello's Rust core (the native module ``jello._jello``); this package gives it
numpy arrays in and out, Python exceptions, and parameter sweeps on Dask (:func:`sweep`).

>>> import jello
>>> sim = jello.load("examples/jello.w")          # doctest: +SKIP
>>> sim.step(1000)                                 # the GIL is released while stepping
>>> sim.positions.shape                            # (512, 3) float64
"""

from jello._jello import (
    BlowUp,
    Body,
    ContactWork,
    Energy,
    GpuError,
    Obstacle,
    OverlapWarning,
    Pin,
    Region,
    Simulation,
    SolverStats,
    TunnellingWarning,
    WorldError,
    create,
    cube,
    integrators,
    load,
    loads,
    mesh,
    pin,
    read_mesh,
    region,
    simd_tier,
    sphere,
)
from jello._jello import box as box  # noqa: A001 (the obstacle, as `jello create --box`)
from jello.sweep import sweep

__all__ = [
    "BlowUp",
    "Body",
    "ContactWork",
    "Energy",
    "GpuError",
    "Obstacle",
    "OverlapWarning",
    "Pin",
    "Region",
    "Simulation",
    "SolverStats",
    "TunnellingWarning",
    "WorldError",
    "box",
    "create",
    "cube",
    "integrators",
    "load",
    "loads",
    "mesh",
    "pin",
    "read_mesh",
    "region",
    "simd_tier",
    "sphere",
    "sweep",
]
