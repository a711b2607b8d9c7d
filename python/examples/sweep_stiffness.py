"""A parameter sweep on Dask: how stiffness and the integrator change the energy a world keeps.

    python python/examples/sweep_stiffness.py examples/jello.w --workers 2

Runs on a LocalCluster (one process per worker) unless --scheduler gives a scheduler's address
(tcp://host:8786) to spread the cases over many machines.
"""

from __future__ import annotations

import argparse
import sys

import jello


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("worlds", nargs="*", default=["examples/jello.w"], help=".w worlds or .toml scenes")
    parser.add_argument("--time", type=float, default=1.0, help="simulated seconds per case (default 1)")
    parser.add_argument("--workers", type=int, default=None, help="LocalCluster workers (default: one per core)")
    parser.add_argument("--scheduler", default="local", help='"local", "serial" or a scheduler address')
    parser.add_argument("--csv", help="also write the table here")
    args = parser.parse_args(argv)

    table = jello.sweep(
        args.worlds,
        {
            "stiffness": [100.0, 200.0, 400.0, 800.0],
            "integrator": ["RK4", "BackwardEuler"],
            "dt": [0.0005, 1 / 60],
        },
        time=args.time,
        metrics=("final_energy", "max_penetration", "blew_up", "steps"),
        scheduler=args.scheduler,
        workers=args.workers,
    )
    print(table.to_string(index=False))
    if args.csv:
        table.to_csv(args.csv, index=False)
    return 0


if __name__ == "__main__":
    sys.exit(main())
