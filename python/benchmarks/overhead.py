"""What stepping from Python costs against the `jello` command line, on the same worlds.

    python python/benchmarks/overhead.py [--rounds 7] [--jello target/release/jello]

For each world, alternating rounds of: `jello run W --steps 1000` (its loop measures the penetration
after every step; the printed "wall" covers the loop only), then in this process
`Simulation.run(1000)`, the same loop (steps plus the penetration), and `Simulation.step(1000)`,
steps alone. The medians over the rounds are printed as a Markdown table with the ratios
Python / CLI (above 1: Python slower).
"""

from __future__ import annotations

import argparse
import platform
import re
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import jello

REPO = Path(__file__).resolve().parents[2]


def cli_wall(exe: Path, world: Path, steps: int) -> float:
    out = subprocess.run(
        [str(exe), "run", str(world), "--steps", str(steps), "--quiet"],
        check=True, capture_output=True, text=True,
    ).stdout
    match = re.search(r"wall ([0-9.]+) s", out)
    if match is None:
        raise RuntimeError(f"no wall time in: {out}")
    return float(match.group(1))


def python_wall(world: Path, steps: int, penetration: bool) -> float:
    sim = jello.load(world)
    start = time.perf_counter()
    if penetration:
        sim.run(steps)
    else:
        sim.step(steps)
    return time.perf_counter() - start


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--rounds", type=int, default=7)
    parser.add_argument("--steps", type=int, default=1000)
    parser.add_argument("--jello", type=Path, default=REPO / "target" / "release" / "jello")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory() as tmp:
        big = Path(tmp) / "cube24.toml"
        subprocess.run([str(args.jello), "create", str(big), "--cube", "24", "--at", "0,0,0"],
                       check=True, capture_output=True)
        worlds = [
            ("jello.w (8³, RK4)", REPO / "examples" / "jello.w"),
            ("stack.toml (3 × 5³, RK4)", REPO / "examples" / "stack.toml"),
            ("24³ cube scene (RK4)", big),
        ]
        print(f"{platform.processor() or platform.machine()}, Python {platform.python_version()}, "
              f"SIMD tier {jello.simd_tier()}, {args.rounds} rounds of {args.steps} steps, medians\n")
        print("| world | CLI `jello run` (s) | Python `run` (s) | Python `step` (s) | run / CLI | step / CLI |")
        print("| --- | ---: | ---: | ---: | ---: | ---: |")
        for label, world in worlds:
            cli, py_run, py_step = [], [], []
            python_wall(world, args.steps, False)  # warm up the page cache and the thread pool
            for _ in range(args.rounds):
                cli.append(cli_wall(args.jello, world, args.steps))
                py_run.append(python_wall(world, args.steps, True))
                py_step.append(python_wall(world, args.steps, False))
            c, r, s = (statistics.median(v) for v in (cli, py_run, py_step))
            print(f"| {label} | {c:.4f} | {r:.4f} | {s:.4f} | {r / c:.3f} | {s / c:.3f} |")
            sys.stdout.flush()
    return 0


if __name__ == "__main__":
    sys.exit(main())
