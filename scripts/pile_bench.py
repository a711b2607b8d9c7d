#!/usr/bin/env python3
"""The pile scene's real-time factor: Jello against Rapier's soft bodies on the same pile, on the
same machine in the same run, written into BENCHMARKS.md (its "Pile of bodies" section). Normally
started by scripts/pile-bench.sh, which sets up the venv (bench/.venv, with `rapier3d`) and builds
target/release/jello.

Jello runs the scene as it is (`jello run SCENE --time T`: its own integrator and dt), with 1 and
2 threads; Rapier runs the same bodies (bench/peers/rapier_pile.py reads the same scene file) at
its defaults (dt 1/60 s), with 1 and 2 threads. The runs alternate, Jello and Rapier, for a few
repetitions. Everything about the scene is read from the scene file when the script runs, so it
follows changes to examples/pile.toml without edits.

    scripts/pile_bench.py [--scene examples/pile.toml] [--time 5] [--reps 3] [--max-wall 300]
                          [--out BENCHMARKS.md]
"""

import argparse
import json
import math
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_sections import failure, fmt_rt, rapier_version, write_section  # noqa: E402
from benchmarks import JELLO, QUIET, ROOT, machine, wait_quiet  # noqa: E402

PEER = os.path.join(ROOT, "bench", "peers", "rapier_pile.py")
SCENE = os.path.join(ROOT, "examples", "pile.toml")
OUT = os.path.join(ROOT, "BENCHMARKS.md")
BEGIN = "<!-- pile: begin (scripts/pile-bench.sh) -->"
END = "<!-- pile: end -->"

# (label, engine, threads), in the order one repetition runs them: Jello and Rapier alternate.
COLUMNS = [
    ("Jello, 1 thread", "jello", 1),
    ("Rapier, 1 thread", "rapier", 1),
    ("Jello, 2 threads", "jello", 2),
    ("Rapier, 2 threads", "rapier", 2),
]
# A run whose colliding points went no further than this beyond a wall stayed in the box (m).
IN_BOX = 0.01
# Simulated seconds the probe of a Jello run takes, to cut a slow run to about --max-wall.
PROBE_TIME = 0.1


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def load_scene(path):
    try:
        import tomllib
    except ImportError:  # Python < 3.11
        import tomli as tomllib
    with open(path, "rb") as f:
        return tomllib.load(f)


def jello_bodies(jello, path):
    """Per body of the scene, what `jello info` says: name, points, cells, cell size, mass."""
    out = subprocess.run([jello, "info", path], check=True, capture_output=True, text=True).stdout
    bodies = []
    for m in re.finditer(r"^body\s+\d+\s+(.+?): (\d+) points.*?(\d+) cells of ([0-9.eE+-]+) m"
                         r".*?mass ([0-9.eE+-]+) kg", out, re.M):
        bodies.append({"name": m.group(1), "points": int(m.group(2)), "cells": int(m.group(3)),
                       "h": float(m.group(4)), "mass": float(m.group(5))})
    return bodies


def jello_outcome(jello, saved):
    """Where a saved state of the pile ended, from `jello info`: the centre of mass, the deepest
    point into a wall, whether the energy is finite, and the deepest overlap between bodies."""
    out = subprocess.run([jello, "info", saved], check=True, capture_output=True, text=True).stdout
    centre = re.search(r"centre of mass\s+\(([^,]+), ([^,]+), ([^)]+)\)", out)
    depth = re.search(r"penetration\s+([0-9.eE+-]+) m", out)
    energy = re.search(r"^energy\s+(\S+) J", out, re.M)
    overlap = re.search(r"deepest overlap ([0-9.eE+-]+) m", out)
    return {
        "centre": [float(centre.group(i)) for i in (1, 2, 3)] if centre else None,
        "beyond_walls_end": float(depth.group(1)) if depth else None,
        "finite": bool(energy and math.isfinite(float(energy.group(1)))),
        "deepest_overlap_end": float(overlap.group(1)) if overlap else 0.0,
    }


def jello_steps(jello, scene, threads, sim_time, dt, max_wall):
    """Steps of a run of `sim_time` simulated seconds, cut to about `max_wall` seconds of wall
    clock from the speed of a short probe (at least the probe's own steps)."""
    steps = max(1, math.ceil(sim_time / dt - 1e-9))
    probe = min(steps, max(1, round(PROBE_TIME / dt)))
    env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
    t0 = time.perf_counter()
    p = subprocess.run([jello, "run", scene, "--steps", str(probe), "-q"], env=env,
                       capture_output=True, text=True)
    rate = probe / max(time.perf_counter() - t0, 1e-6)
    if p.returncode != 0:
        return None, failure(p)
    return (min(steps, max(probe, round(rate * max_wall))), steps), None


def run_jello(jello, scene, tmp, threads, steps, steps_wanted, dt):
    env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
    saved = os.path.join(tmp, "out.toml")
    if os.path.exists(saved):
        os.remove(saved)
    wait_quiet()
    t0 = time.perf_counter()
    p = subprocess.run([jello, "run", scene, "--steps", str(steps), "--save", saved, "-q"],
                       env=env, capture_output=True, text=True)
    wall = time.perf_counter() - t0
    if p.returncode != 0:
        return {"error": failure(p)}
    summary = p.stdout + p.stderr
    own = re.search(r"wall ([0-9.eE+-]+) s", summary)
    worst = re.search(r"max penetration ([0-9.eE+-]+) m", summary)
    r = {"peer": "jello", "threads": threads, "dt": dt, "steps": steps, "sim_time": steps * dt,
         "wall_s": wall, "realtime": steps * dt / wall, "capped": steps < steps_wanted,
         "stepping_wall_s": float(own.group(1)) if own else None,
         "beyond_walls": float(worst.group(1)) if worst else None}
    r.update(jello_outcome(jello, saved))
    return r


def run_rapier(scene, masses, threads, sim_time, max_wall):
    wait_quiet()
    p = subprocess.run([sys.executable, PEER, "--scene", scene, "--masses",
                        ",".join(repr(m) for m in masses), "--threads", str(threads),
                        "--time", repr(sim_time), "--max-wall", repr(max_wall)],
                       capture_output=True, text=True)
    if p.returncode != 0:
        return {"error": failure(p)}
    return json.loads(p.stdout.strip().splitlines()[-1])


def median_rt(runs):
    ok = [r["realtime"] for r in runs if "error" not in r]
    return statistics.median(ok) if ok else None


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scene", default=SCENE)
    ap.add_argument("--time", type=float, default=5.0, help="simulated seconds per run (5)")
    ap.add_argument("--reps", type=int, default=3, help="repetitions of each run (3)")
    ap.add_argument("--max-wall", type=float, default=300.0,
                    help="cap on one run's wall-clock seconds (300)")
    ap.add_argument("--out", default=OUT)
    args = ap.parse_args()
    if not os.path.exists(JELLO):
        sys.exit("pile_bench: build target/release/jello first (cargo build --release -p jello-cli)")
    scene_path = os.path.abspath(args.scene)
    scene = load_scene(scene_path)
    dt = float(scene.get("simulation", {}).get("dt", 0.001))

    info = machine()
    results = {label: [] for label, _, _ in COLUMNS}
    with tempfile.TemporaryDirectory() as tmp:
        # One binary for the whole run, whatever rebuilds target/release/jello meanwhile.
        jello = os.path.join(tmp, "jello")
        shutil.copy2(JELLO, jello)
        version = subprocess.run([jello, "--version"], capture_output=True,
                                 text=True).stdout.strip()
        bodies = jello_bodies(jello, scene_path)
        if len(bodies) != len(scene.get("body", [])):
            sys.exit("pile_bench: `jello info` lists %d bodies, the scene %d"
                     % (len(bodies), len(scene.get("body", []))))
        masses = [b["mass"] for b in bodies]
        plan = {}
        for label, engine, threads in COLUMNS:
            if engine == "jello":
                plan[label], err = jello_steps(jello, scene_path, threads, args.time, dt,
                                               args.max_wall)
                if err:
                    sys.exit("pile_bench: `jello run %s` failed: %s" % (args.scene, err))
        for rep in range(args.reps):
            # Alternate Jello and Rapier; every other repetition in the reverse order, so that a
            # drift in the machine's speed falls on both alike.
            order = COLUMNS if rep % 2 == 0 else COLUMNS[::-1]
            for label, engine, threads in order:
                log("repetition %d/%d: %s" % (rep + 1, args.reps, label))
                load = os.getloadavg()[0]
                if engine == "jello":
                    steps, wanted = plan[label]
                    r = run_jello(jello, scene_path, tmp, threads, steps, wanted, dt)
                else:
                    r = run_rapier(scene_path, masses, threads, args.time, args.max_wall)
                r["load_before"] = load
                log("  " + json.dumps(r))
                results[label].append(r)

    info["load average at end"] = " ".join("%.2f" % x for x in os.getloadavg())
    info["outside load"] = (
        "before each run the script waited (at most 20 s per run, 180 s in all) for the CPUs to "
        "be idle (< 25 %% busy over 0.5 s); %d of %d runs had to start on a busy machine; %.0f s "
        "spent waiting; each run's 1-minute load average before it is in the raw results"
        % (QUIET["busy_starts"], QUIET["runs"], QUIET["waited_s"]))
    section = render(args, scene, bodies, results, info, version)
    write_section(args.out, section, BEGIN, END)
    log("wrote the pile section of " + args.out)


def shapes_of(scene):
    """The scene's bodies as "4 sphere, 4 torus, …" (names without their trailing numbers)."""
    kinds = {}
    for b in scene.get("body", []):
        kind = re.sub(r"\d+$", "", b.get("name", "body")) or "body"
        kinds[kind] = kinds.get(kind, 0) + 1
    return ", ".join("%d %s" % (n, k) for k, n in kinds.items())


def render(args, scene, bodies, results, info, version):
    L = [BEGIN, "", "## Pile of bodies: Jello against Rapier", ""]
    w = L.append
    sim = scene.get("simulation", {})
    col = scene.get("collision", {})
    box = scene.get("box", {})
    rel = os.path.relpath(os.path.abspath(args.scene), ROOT)
    rapier_runs = [r for label, _, _ in COLUMNS for r in results[label]
                   if r.get("peer") == "rapier"]
    first_rapier = rapier_runs[0] if rapier_runs else {}
    hs = sorted({b["h"] for b in bodies})
    w("Generated by `scripts/pile-bench.sh%s` on %s. Do not edit by hand: run the command again."
      % ((" " + " ".join(sys.argv[1:])) if sys.argv[1:] else "", info["date"]))
    w("")
    w("**Job.** The pile scene, `%s` (made by `scripts/make-examples.sh`): %d soft bodies (%s), "
      "meshes about 0.4 m across, dropped in layers into the box (%s) to (%s) m under gravity "
      "(%s) m/s², and left to settle for %g s of simulated time; %.4g kg in all. The number is the "
      "**real-time factor**: simulated seconds per wall-clock second (higher is faster; 1× is "
      "real time), the median of %d runs, Jello's and Rapier's runs alternated (every other "
      "repetition in reverse order) on the same machine in the same run."
      % (rel, len(bodies), shapes_of(scene),
         ", ".join("%g" % x for x in box.get("min", [])),
         ", ".join("%g" % x for x in box.get("max", [])),
         ", ".join("%g" % x for x in sim.get("gravity", [0, 0, -9.81])),
         args.time, sum(b["mass"] for b in bodies), args.reps))
    w("")
    w("- **Jello** (%s): `jello run %s --time %g`, the scene as it is: %s at dt = %g s, each "
      "mesh voxelised into a lattice of cubic cells (%s m) carrying the mesh as its skin "
      "(%d points, %d cells in all), the scene's material (density, modulus, viscosity), "
      "penalty contacts between the bodies' skins and at the walls (stiffness %g N/m, damping "
      "%g N·s/m, friction %g, at the walls %g). Timed as the whole process (loading the scene "
      "included), threads set by `RAYON_NUM_THREADS`."
      % (version or "jello", rel, args.time, sim.get("integrator", "?"), sim.get("dt", 0),
         ", ".join("%.4g" % h for h in hs), sum(b["points"] for b in bodies),
         sum(b["cells"] for b in bodies), col.get("stiffness", 0), col.get("damping", 0),
         col.get("friction", 0.5), col.get("wall_friction", col.get("friction", 0.5))))
    w("- **Rapier** (PyPI `rapier3d`, %s; `bench/peers/rapier_pile.py`, reading the same scene "
      "file): each body from the same mesh, placed and turned as Jello places it, filled with "
      "tetrahedra of the same cell size by `SoftBody.volumetric` (%s particles, %s tetrahedra in "
      "all), the mesh kept as a skin embedded in them that is what collides "
      "(`skinned=True`, `skin_collision(True)`), each body the mass Jello gives it; the box's "
      "walls as six half-spaces, the same friction and gravity. Rapier's defaults otherwise: dt "
      "1/60 s, its default solver (`CONSTRAINTS`, %s solver iterations) and soft-body material "
      "(edges and volume held by constraints of 30 Hz natural frequency, critically damped, "
      "not the scene's modulus and viscosity), its contacts (constraints, not springs); sleeping "
      "off so every body is simulated every step, as in the frame-rate section. Timed over the "
      "stepping (building the bodies not counted), threads set by `set_num_threads`."
      % (rapier_version(rapier_runs), first_rapier.get("particles", "?"),
         first_rapier.get("cells", "?"), first_rapier.get("solver_iterations", "?")))
    w("- ¹ marks a run cut to about %g s of wall clock (the factor is then measured over the "
      "steps done, the start of the drop)." % args.max_wall)
    w("- Machine: %s." % "; ".join("%s: %s" % (k, v) for k, v in info.items()
                                    if k in ("CPU", "AVX-512", "cores (logical CPUs available)",
                                             "OS", "load average at start",
                                             "load average at end", "outside load",
                                             "git commit")))
    w("")
    if QUIET["runs"] and QUIET["busy_starts"] > 0.25 * QUIET["runs"]:
        w("> **Outside load:** %d of %d runs started while other processes kept the CPUs busy "
          "(see *outside load* under Machine): the factors, the 2-thread ones most, are "
          "disturbed; rerun on an idle machine before quoting them."
          % (QUIET["busy_starts"], QUIET["runs"]))
        w("")
    w("| | " + " | ".join(label for label, _, _ in COLUMNS) + " |")
    w("| --- |" + " ---: |" * len(COLUMNS))
    w("| real-time factor (median) | " + " | ".join(
        fmt_rt({"realtime": median_rt(results[label]),
                "capped": any(r.get("capped") for r in results[label])})
        if median_rt(results[label]) is not None else "failed"
        for label, _, _ in COLUMNS) + " |")
    w("| runs | " + " | ".join(", ".join(fmt_rt(r) for r in results[label])
                                 for label, _, _ in COLUMNS) + " |")
    w("| simulated time per run | " + " | ".join(
        ", ".join(sorted({"%.3g s" % r["sim_time"] for r in results[label] if "error" not in r}))
        or "–" for label, _, _ in COLUMNS) + " |")
    w("")
    w("Jello / Rapier, thread for thread (medians): %s." % "; ".join(
        "%d thread%s %s" % (t, "" if t == 1 else "s", ratio(results, t)) for t in (1, 2)))
    w("")
    w("Where the runs ended (the last run of each): whether every position is finite; the "
      "largest distance of a colliding point beyond a wall over the run, and at its end (Jello: "
      "its lattice points, which the walls push; Rapier: its skins' vertices, which collide, "
      "checked every 15 steps); the centre of mass of the pile (m):")
    w("")
    w("| | " + " | ".join(label for label, _, _ in COLUMNS) + " |")
    w("| --- |" + " --- |" * len(COLUMNS))
    last = [results[label][-1] if results[label] else {"error": "not run"}
            for label, _, _ in COLUMNS]
    w("| finite | " + " | ".join(cell(r, lambda r: "yes" if r.get("finite") else "**no**")
                                 for r in last) + " |")
    w("| beyond a wall: most, at the end (m) | " + " | ".join(
        cell(r, lambda r: "%s, %s" % (num(r.get("beyond_walls")), num(r.get("beyond_walls_end"))))
        for r in last) + " |")
    w("| stayed in the box (within %g m) | " % IN_BOX + " | ".join(
        cell(r, lambda r: "yes" if (r.get("beyond_walls") or 0.0) <= IN_BOX else "**no**")
        for r in last) + " |")
    w("| centre of mass (m) | " + " | ".join(
        cell(r, lambda r: "(%s)" % ", ".join("%.3f" % x for x in r["centre"])
             if r.get("centre") else "?") for r in last) + " |")
    w("")
    w("Raw results (one line per run, in each column the order they ran):")
    w("")
    w("```json")
    w("{")
    for i, (label, _, _) in enumerate(COLUMNS):
        w(" %s: [" % json.dumps(label))
        w(",\n".join("  " + json.dumps(r) for r in results[label]))
        w(" ]" + ("," if i + 1 < len(COLUMNS) else ""))
    w("}")
    w("```")
    w("")
    w(END)
    return "\n".join(L) + "\n"


def ratio(results, threads):
    j = median_rt(results["Jello, %d thread%s" % (threads, "" if threads == 1 else "s")])
    r = median_rt(results["Rapier, %d thread%s" % (threads, "" if threads == 1 else "s")])
    if j is None or r is None:
        return "not measured"
    return "%.3g×" % (j / r)


def cell(r, f):
    return r["error"].replace("|", "/") if "error" in r else f(r)


def num(x):
    return "?" if x is None else "%.1e" % x


if __name__ == "__main__":
    main()
