#!/usr/bin/env python3
"""Rapier's soft bodies (PyPI `rapier3d`) on the frame-rate job of scripts/frame_rate.py.

An N x N x N cube of particles, 1 m on a side and 1 kg in all, under gravity (0, -9.81, 0) on a
floor (the half-space y < 0), either resting on it (centre at y = 0.5) or dropped from 0.5 m
(centre at y = 1.0). Rapier's defaults otherwise: dt 1/60, its default solver iterations
(substeps), sleeping off so the body is simulated every step, one thread.

Prints one JSON object: the simulated and wall-clock time, the real-time factor and where the
body ended. Stepping stops at --time simulated seconds or after --max-wall seconds of wall
clock, whichever comes first (the factor is measured over the steps done).
"""

import argparse
import json
import sys
import time


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--size", type=int, required=True, help="particles per side")
    ap.add_argument("--job", choices=["rest", "drop"], required=True)
    ap.add_argument("--solver", choices=["constraints", "fem"], default="constraints")
    ap.add_argument("--time", type=float, default=2.0, help="simulated seconds")
    ap.add_argument("--max-wall", type=float, default=30.0, help="wall-clock cap (s)")
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()

    try:
        import numpy as np
        import rapier3d as r
    except ImportError as e:
        print("rapier_peer: cannot run the rapier peer: %s" % e, file=sys.stderr)
        return 2

    world = r.PhysicsWorld(gravity=(0.0, -9.81, 0.0))
    world.set_num_threads(args.threads)
    dt = 1.0 / 60.0
    world.integration_parameters.dt = dt
    world.add_body(r.RigidBody.fixed(), [r.Collider.halfspace((0.0, 1.0, 0.0))])
    centre_y = 0.5 if args.job == "rest" else 1.0
    solver = r.SoftBodySolver.CONSTRAINTS if args.solver == "constraints" else r.SoftBodySolver.FEM
    n = args.size
    builder = (r.SoftBody.cuboid((0.0, centre_y, 0.0), (0.5, 0.5, 0.5), n, n, n)
               .mass(1.0).solver(solver).can_sleep(False))
    handle = world.add_soft_body(builder)

    steps_wanted = max(1, round(args.time / dt))
    steps = 0
    start = time.perf_counter()
    while steps < steps_wanted:
        world.step()
        steps += 1
        if time.perf_counter() - start > args.max_wall:
            break
    wall = time.perf_counter() - start

    pos = np.asarray(world.soft_bodies[handle].particle_positions, dtype=float)
    print(json.dumps({
        "peer": "rapier",
        "version": getattr(r, "__version__", "?"),
        "solver": args.solver,
        "size": n,
        "job": args.job,
        "dt": dt,
        "solver_iterations": world.integration_parameters.num_solver_iterations,
        "threads": args.threads,
        "steps": steps,
        "sim_time": steps * dt,
        "wall_s": wall,
        "realtime": steps * dt / wall,
        "capped": steps < steps_wanted,
        "lowest": float(pos[:, 1].min()),
        "centre": float(pos[:, 1].mean()),
        "finite": bool(np.isfinite(pos).all()),
    }))
    return 0


if __name__ == "__main__":
    sys.exit(main())
