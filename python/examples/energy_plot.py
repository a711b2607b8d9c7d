"""Plots a world's energy over time: kinetic, spring, collision and their total.

    python python/examples/energy_plot.py examples/jello.w --time 2 --out energy.png

Without --out the plot opens in a window. Needs matplotlib (`pip install "./python[examples]"`).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np
import numpy.typing as npt

import jello


def energy_over_time(
    sim: jello.Simulation, seconds: float, samples: int = 400
) -> dict[str, npt.NDArray[np.float64]]:
    """Steps ``sim`` for ``seconds``, reading the energy ``samples`` times along the way."""
    total_steps = max(1, round(seconds / sim.dt))
    every = max(1, total_steps // samples)
    rows = []
    for _ in range(0, total_steps, every):
        e = sim.energy()
        rows.append((sim.time, e.kinetic, e.spring, e.collision, e.total))
        sim.step(every)
    e = sim.energy()
    rows.append((sim.time, e.kinetic, e.spring, e.collision, e.total))
    table = np.array(rows)
    names = ("time", "kinetic", "spring", "collision", "total")
    return {name: table[:, i] for i, name in enumerate(names)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("world", nargs="?", default="examples/jello.w", help="a .w world or .toml scene")
    parser.add_argument("--time", type=float, default=2.0, help="simulated seconds (default 2)")
    parser.add_argument("--integrator", help="integrator instead of the file's")
    parser.add_argument("--dt", type=float, help="time step instead of the file's (s)")
    parser.add_argument("--out", type=Path, help="write the plot here (.png, .svg, .pdf)")
    args = parser.parse_args(argv)
    try:
        import matplotlib.pyplot as plt
    except ImportError:
        print('energy_plot: needs matplotlib: pip install "./python[examples]"', file=sys.stderr)
        return 1

    sim = jello.load(args.world, integrator=args.integrator, dt=args.dt)
    try:
        curves = energy_over_time(sim, args.time)
    except jello.BlowUp as e:
        print(f"energy_plot: {e}", file=sys.stderr)
        return 3
    fig, ax = plt.subplots(figsize=(8, 4.5))
    for name in ("kinetic", "spring", "collision", "total"):
        ax.plot(curves["time"], curves[name], label=name, linewidth=2 if name == "total" else 1)
    ax.set_xlabel("time (s)")
    ax.set_ylabel("energy (J)")
    ax.set_title(f"{args.world}: {sim.integrator}, dt = {sim.dt:g} s")
    ax.legend()
    ax.grid(alpha=0.3)
    fig.tight_layout()
    if args.out:
        fig.savefig(args.out, dpi=120)
        print(f"wrote {args.out}")
    else:
        plt.show()
    return 0


if __name__ == "__main__":
    sys.exit(main())
