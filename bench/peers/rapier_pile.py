#!/usr/bin/env python3
"""Rapier's soft bodies (PyPI `rapier3d`) doing the pile of scripts/pile_bench.py.

The pile is read from a Jello scene file (examples/pile.toml by default) each time, so a change
to the scene is followed without editing this file:

* each body's embedded mesh (its `vertices` and `triangles`) is placed as Jello places it: turned
  about the middle of its rest lattice box (degrees about x, then y, then z, `R = Rz·Ry·Rx`) and
  that middle moved to `centre` (the lattice box starts at the mesh's lower corner and has `cells`
  cubic cells of side h = longest side / cells along the longest side, as many as cover the others);
* Rapier fills the mesh with tetrahedra of the same size h (`SoftBody.volumetric`, its default
  lattice cover) and keeps the mesh as a skin embedded in them that collides (`skinned=True`,
  `skin_collision(True)`): the surface other bodies and the walls touch is the scene's mesh, as in
  Jello (`--surface cells` collides through the cells' boundary instead);
* each body weighs what Jello's does (`--masses`, from `jello info`; without it density × the
  mesh's enclosed volume);
* the box's six walls are half-spaces at the scene's `[box]`, friction the scene's
  `wall_friction` on the walls and `friction` on the bodies; gravity the scene's.

Rapier's defaults otherwise: dt 1/60 s, its default solver (`SoftBodySolver.CONSTRAINTS`) and
iterations, its default soft-body material; sleeping off, so every body is simulated every step
(as bench/peers/rapier_peer.py does); one thread unless --threads.

Prints one JSON object: steps, simulated and wall-clock time of the stepping (building the bodies
not counted), the real-time factor, whether every position is finite, and whether the bodies
stayed in the box (the largest distance of a colliding surface point beyond a wall). Stepping
stops at --time simulated seconds or after --max-wall seconds of wall clock, whichever comes first
(the factor is then measured over the steps done).
"""

import argparse
import json
import math
import os
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
SCENE = os.path.join(ROOT, "examples", "pile.toml")
# A colliding surface point further than this beyond a wall means the body left the box.
OUT_TOLERANCE = 0.01


def rotation_xyz(rx, ry, rz):
    """Rows of the rotation by rx degrees about x, then ry about y, then rz about z (Jello's
    `rotation_xyz`, crates/jello-core/src/model/body.rs)."""
    sx, cx = math.sin(math.radians(rx)), math.cos(math.radians(rx))
    sy, cy = math.sin(math.radians(ry)), math.cos(math.radians(ry))
    sz, cz = math.sin(math.radians(rz)), math.cos(math.radians(rz))
    return [[cz * cy, cz * sy * sx - sz * cx, cz * sy * cx + sz * sx],
            [sz * cy, sz * sy * sx + cz * cx, sz * sy * cx - cz * sx],
            [-sy, cy * sx, cy * cx]]


def load_scene(path):
    try:
        import tomllib
    except ImportError:  # Python < 3.11
        import tomli as tomllib
    with open(path, "rb") as f:
        return tomllib.load(f)


def placed_mesh(np, body):
    """The body's mesh where Jello puts it at rest, its triangles and its cell size h."""
    mesh = body["mesh"]
    v = np.asarray(mesh["vertices"], dtype=float)
    tris = np.asarray(mesh["triangles"], dtype=np.uint32)
    lo = v.min(axis=0)
    size = v.max(axis=0) - lo
    longest = float(size.max())
    cells = int(mesh.get("cells", 10))
    h = longest / cells
    # Cells per axis as Jello's voxeliser counts them (crates/jello-core/src/model/voxel.rs).
    counts = np.array([cells if s == longest else max(1, math.ceil(s / h * (1 - 1e-12)))
                       for s in size], dtype=float)
    middle = lo + counts * h / 2.0
    rot = np.asarray(rotation_xyz(*body.get("rotation", [0.0, 0.0, 0.0])))
    centre = np.asarray(body.get("centre", middle), dtype=float)
    return (v - middle) @ rot.T + centre, tris, h


def enclosed_volume(np, v, tris):
    a, b, c = v[tris[:, 0]], v[tris[:, 1]], v[tris[:, 2]]
    return float(np.einsum("ij,ij->i", a, np.cross(b, c)).sum() / 6.0)


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=SCENE, help="the Jello scene (examples/pile.toml)")
    ap.add_argument("--masses", default=None,
                    help="comma-separated mass (kg) of each body, in the scene's order")
    ap.add_argument("--surface", choices=["skin", "cells"], default="skin",
                    help="collide through the mesh as a skin (default) or the cells' boundary")
    ap.add_argument("--time", type=float, default=5.0, help="simulated seconds (5)")
    ap.add_argument("--max-wall", type=float, default=300.0, help="wall-clock cap (s)")
    ap.add_argument("--threads", type=int, default=1)
    args = ap.parse_args()

    try:
        import numpy as np
        import rapier3d as r
    except ImportError as e:
        print("rapier_pile: cannot run the rapier peer: %s" % e, file=sys.stderr)
        return 2

    scene = load_scene(args.scene)
    bodies = scene.get("body", [])
    if not bodies or any("mesh" not in b for b in bodies):
        print("rapier_pile: every body of %s must be a mesh" % args.scene, file=sys.stderr)
        return 2
    masses = [float(m) for m in args.masses.split(",")] if args.masses else None
    if masses is not None and len(masses) != len(bodies):
        print("rapier_pile: %d masses for %d bodies" % (len(masses), len(bodies)),
              file=sys.stderr)
        return 2
    collision = scene.get("collision", {})
    friction = float(collision.get("friction", 0.5))
    wall_friction = float(collision.get("wall_friction", friction))
    gravity = tuple(float(g) for g in scene.get("simulation", {}).get("gravity",
                                                                       [0.0, 0.0, -9.81]))
    box = scene.get("box", {"min": [-2.0] * 3, "max": [2.0] * 3})
    lo, hi = np.asarray(box["min"], dtype=float), np.asarray(box["max"], dtype=float)

    world = r.PhysicsWorld(gravity=gravity)
    world.set_num_threads(args.threads)
    dt = 1.0 / 60.0
    world.integration_parameters.dt = dt
    # The walls: half-spaces whose solid side is outside the box.
    walls = []
    for axis in range(3):
        for side, at in ((1.0, lo[axis]), (-1.0, hi[axis])):
            normal, where = [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]
            normal[axis], where[axis] = side, float(at)
            walls.append(r.Collider.halfspace(tuple(normal), translation=tuple(where),
                                              friction=wall_friction))
    world.add_body(r.RigidBody.fixed(), walls)

    start = time.perf_counter()
    handles, names, given, particles, cells = [], [], [], 0, 0
    for i, body in enumerate(bodies):
        v, tris, h = placed_mesh(np, body)
        if masses is not None:
            mass = masses[i]
        else:
            mass = float(body.get("density", 1000.0)) * enclosed_volume(np, v, tris)
        builder = r.SoftBody.volumetric(v, tris, h, skinned=args.surface == "skin")
        if args.surface == "skin":
            builder = builder.skin_collision(True)
        builder = (builder.mass(mass).can_sleep(False)
                   .surface_collider(r.Collider.ball(0.1, friction=friction)))
        handle = world.add_soft_body(builder)
        sb = world.soft_bodies[handle]
        particles += sb.num_particles
        cells += sb.num_cells
        handles.append(handle)
        names.append(body.get("name", "body%d" % (i + 1)))
        given.append(mass)
    build_s = time.perf_counter() - start

    def beyond_walls():
        """The largest distance of a colliding surface point beyond a wall (m, 0 inside)."""
        worst = 0.0
        for handle in handles:
            sb = world.soft_bodies[handle]
            mesh = sb.collision_mesh()
            pts = np.asarray(mesh.vertices if mesh is not None else sb.particle_positions,
                             dtype=float)
            worst = max(worst, float(np.max(lo - pts)), float(np.max(pts - hi)))
        return worst

    steps_wanted = max(1, round(args.time / dt))
    steps, worst, checking = 0, 0.0, 0.0
    start = time.perf_counter()
    while steps < steps_wanted:
        world.step()
        steps += 1
        if steps % 15 == 0:  # four times a simulated second; not counted in the wall time
            t = time.perf_counter()
            worst = max(worst, beyond_walls())
            checking += time.perf_counter() - t
        if time.perf_counter() - start > args.max_wall:
            break
    wall = time.perf_counter() - start - checking
    final_out = beyond_walls()
    worst = max(worst, final_out)

    pos = [np.asarray(world.soft_bodies[h].particle_positions, dtype=float) for h in handles]
    body_mass = [float(world.soft_bodies[h].mass) for h in handles]
    coms = [np.array([c.x, c.y, c.z]) for c in (world.soft_bodies[h].center_of_mass for h in handles)]
    com = sum(m * c for m, c in zip(body_mass, coms)) / sum(body_mass)
    print(json.dumps({
        "peer": "rapier",
        "version": getattr(r, "__version__", "?"),
        "scene": os.path.relpath(args.scene, ROOT),
        "surface": args.surface,
        "bodies": len(handles),
        "particles": particles,
        "cells": cells,
        "mass": sum(body_mass),
        "masses": "jello" if masses is not None else "density x mesh volume",
        "dt": dt,
        "solver_iterations": world.integration_parameters.num_solver_iterations,
        "threads": args.threads,
        "build_s": build_s,
        "steps": steps,
        "sim_time": steps * dt,
        "wall_s": wall,
        "realtime": steps * dt / wall,
        "capped": steps < steps_wanted,
        "finite": bool(all(np.isfinite(p).all() for p in pos)),
        "beyond_walls": worst,
        "beyond_walls_end": final_out,
        "in_box": worst <= OUT_TOLERANCE,
        "centre": [float(x) for x in com],
    }))
    return 0


if __name__ == "__main__":
    sys.exit(main())
