"""Types of the native module ``jello._jello`` (re-exported by ``jello``)."""

import os
from collections.abc import Sequence
from typing import Any, Literal, final

import numpy as np
import numpy.typing as npt

_Path = str | os.PathLike[str]
_Vec3 = Sequence[float] | npt.NDArray[np.floating[Any]]
_PerKind = float | Sequence[float]
_Points = npt.ArrayLike

class BlowUp(RuntimeError):
    """A step blew up; the simulation stays at the last good step."""

    step: int
    time: float
    point: int
    body: int
    integrator: str
    dt: float
    suggested_dt: float | None
    residual: float | None
    max_penetration: float

class WorldError(ValueError):
    """A file or description that makes no valid simulation; names the file and line."""

    filename: str | None

class GpuError(RuntimeError):
    """No usable GPU for ``device="gpu"``, or the GPU failed while stepping."""

class TunnellingWarning(UserWarning):
    """Points of a body passed through a box or ball obstacle; warned once per pair."""

    body: int
    obstacle: int
    points: int | None
    time: tuple[float, float]
    suggested_dt: float | None
    suggested_collision_stiffness: float | None

class OverlapWarning(UserWarning):
    """Two bodies end ``run`` deep inside each other; warned once per pair."""

    bodies: tuple[int, int]
    depth: float
    at: tuple[float, float, float]
    suggested_collision_stiffness: float

@final
class Energy:
    """Kinetic, spring and collision energy (J)."""

    @property
    def kinetic(self) -> float: ...
    @property
    def spring(self) -> float: ...
    @property
    def collision(self) -> float: ...
    @property
    def total(self) -> float: ...

@final
class ContactWork:
    """The contact passes' work between bodies, counted: passes, sorts of the grid, samples
    listed (over the sorts), placed and the cells sought in, touches (over the passes)."""

    @property
    def passes(self) -> int: ...
    @property
    def sorts(self) -> int: ...
    @property
    def listed(self) -> int: ...
    @property
    def placed(self) -> int: ...
    @property
    def placings(self) -> int: ...
    @property
    def touches(self) -> int: ...

@final
class SolverStats:
    """The implicit solver's work: solves, Newton and conjugate-gradient iterations, assemblies."""

    @property
    def solves(self) -> int: ...
    @property
    def newton_iterations(self) -> int: ...
    @property
    def linear_iterations(self) -> int: ...
    @property
    def assemblies(self) -> int: ...

@final
class Simulation:
    """A world or scene being stepped: numpy arrays in and out."""

    def step(self, n: int = 1) -> None: ...
    def advance(self, n: int) -> None: ...
    def run(self, n: int) -> float: ...
    @property
    def positions(self) -> npt.NDArray[np.float64]: ...
    @positions.setter
    def positions(self, value: _Points) -> None: ...
    @property
    def velocities(self) -> npt.NDArray[np.float64]: ...
    @velocities.setter
    def velocities(self, value: _Points) -> None: ...
    @property
    def lattice_positions(self) -> npt.NDArray[np.float64]: ...
    @property
    def active(self) -> npt.NDArray[np.bool_]: ...
    @property
    def control_forces(self) -> npt.NDArray[np.float64] | None: ...
    @control_forces.setter
    def control_forces(self, value: _Points | None) -> None: ...
    @property
    def time(self) -> float: ...
    @property
    def steps(self) -> int: ...
    @property
    def point_count(self) -> int: ...
    def __len__(self) -> int: ...
    @property
    def dt(self) -> float: ...
    @dt.setter
    def dt(self, value: float) -> None: ...
    @property
    def integrator(self) -> str: ...
    @integrator.setter
    def integrator(self, value: str) -> None: ...
    @property
    def device(self) -> Literal["cpu", "gpu"]: ...
    @device.setter
    def device(self, value: Literal["cpu", "gpu"] | str) -> None: ...
    @property
    def adapter(self) -> str | None: ...
    @property
    def cutbacks(self) -> int: ...
    @cutbacks.setter
    def cutbacks(self, value: int) -> None: ...
    @property
    def tolerance(self) -> float: ...
    @tolerance.setter
    def tolerance(self, value: float) -> None: ...
    @property
    def split_steps(self) -> int: ...
    @property
    def contact_seconds(self) -> float: ...
    @property
    def contact_work(self) -> ContactWork: ...
    @property
    def solver_stats(self) -> SolverStats: ...
    @property
    def steps_per_frame(self) -> int: ...
    @property
    def name(self) -> str: ...
    @property
    def bodies(self) -> list[tuple[str, slice]]: ...
    def set_material(
        self,
        *,
        stiffness: _PerKind | None = None,
        damping: _PerKind | None = None,
        mass: float | None = None,
        body: int | None = None,
    ) -> None: ...
    def set_collision(
        self, *, stiffness: float | None = None, damping: float | None = None
    ) -> None: ...
    def energy(self) -> Energy: ...
    def max_penetration(self) -> float: ...
    def save(self, path: _Path) -> None: ...
    def dumps(self) -> str: ...
    def copy(self) -> Simulation: ...
    def __copy__(self) -> Simulation: ...
    def __deepcopy__(self, memo: Any) -> Simulation: ...

@final
class Body:
    """A body of a scene to create: ``cube(...)`` or ``mesh(...)``."""

@final
class Obstacle:
    """A static obstacle: ``sphere(...)`` or ``box(...)``."""

@final
class Pin:
    """Pinned points of a body: ``pin(...)``."""

@final
class Region:
    """Springs of a body with their own factors: ``region(...)``."""

def load(
    path: _Path,
    *,
    integrator: str | None = None,
    dt: float | None = None,
    device: Literal["cpu", "gpu"] | str = "cpu",
) -> Simulation: ...
def loads(
    text: str | bytes,
    *,
    format: Literal["w", "toml"] | str = "w",
    name: str = "<string>",
    integrator: str | None = None,
    dt: float | None = None,
    device: Literal["cpu", "gpu"] | str = "cpu",
) -> Simulation: ...
def cube(
    n: int | Sequence[int] | None = None,
    size: float | Sequence[float] | None = None,
    *,
    centre: _Vec3 | None = None,
    at: _Vec3 | None = None,
    rotation: _Vec3 | None = None,
    velocity: _Vec3 | None = None,
    spin: _Vec3 | None = None,
    mass: float | None = None,
    total_mass: float | None = None,
    density: float | None = None,
    stiffness: _PerKind | None = None,
    damping: _PerKind | None = None,
    modulus: float | None = None,
    viscosity: float | None = None,
    pins: Sequence[Pin] = ...,
    regions: Sequence[Region] = ...,
    name: str | None = None,
) -> Body: ...
def mesh(
    path: _Path | None = None,
    *,
    vertices: _Points | None = None,
    triangles: _Points | None = None,
    cells: int = 10,
    centre: _Vec3 | None = None,
    at: _Vec3 | None = None,
    rotation: _Vec3 | None = None,
    velocity: _Vec3 | None = None,
    spin: _Vec3 | None = None,
    mass: float | None = None,
    total_mass: float | None = None,
    density: float | None = None,
    stiffness: _PerKind | None = None,
    damping: _PerKind | None = None,
    modulus: float | None = None,
    viscosity: float | None = None,
    pins: Sequence[Pin] = ...,
    regions: Sequence[Region] = ...,
    name: str | None = None,
) -> Body: ...
def read_mesh(path: _Path) -> tuple[npt.NDArray[np.float64], npt.NDArray[np.uint32]]: ...
def sphere(centre: _Vec3, radius: float) -> Obstacle: ...
def box(min: _Vec3, max: _Vec3) -> Obstacle: ...
def pin(
    at: _Vec3, radius: float = 0.0, *, shake: tuple[_Vec3, float] | None = None
) -> Pin: ...
def region(
    min: _Vec3,
    max: _Vec3,
    *,
    stiffness: float = 1.0,
    damping: float = 1.0,
    rest: float = 1.0,
) -> Region: ...
def create(
    bodies: Sequence[Body],
    *,
    obstacles: Sequence[Obstacle] = ...,
    plane: Sequence[float] | None = None,
    gravity: _Vec3 | None = None,
    field: str | npt.ArrayLike | None = None,
    resolution: int | None = None,
    res: int | None = None,
    bounds: tuple[_Vec3, _Vec3] | None = None,
    collision_stiffness: float | None = None,
    collision_damping: float | None = None,
    friction: float | None = None,
    wall_friction: float | None = None,
    self_contact: bool = False,
    integrator: str = "RK4",
    dt: float | None = None,
    steps_per_frame: int | None = None,
    name: str = "<scene>",
) -> Simulation: ...
def simd_tier() -> str: ...
def integrators() -> list[str]: ...

