#!/usr/bin/env python3
"""The share of a step that contacts between bodies take, on fifty shapes dropped into a box
(issue 45's scene: meshes of 8 to 12 cells), written into BENCHMARKS.md (its "Contact between
bodies: fifty shapes" section). Normally started by scripts/contact-share.sh, which builds
target/release/jello.

The scene is made here with `jello shape` and `jello create` (a sphere, a torus, an L-shape and a
capsule, 0.4 m across, nine to a layer 0.45 m apart, each turned its own way), then stepped from
its start with `jello run SCENE --time T --timings` on 1 and 2 threads (RAYON_NUM_THREADS), the
wall-clock time of the contacts (timed in the core) against the rest of the run. Each thread
count runs `--repeat` times, the counts taking turns (a shared machine's speed drifts by more
than the differences measured): the table has the run of the median share, and the range. Under
it, the contact passes' work as `--timings` counts it, which must be the same in every run (it
does not depend on the machine or the thread count): a change to the pass shows there first.

    scripts/contact_share.py [--time 2.5] [--threads 1,2] [--repeat 3] [--out BENCHMARKS.md]
"""

import argparse
import os
import re
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_sections import failure, write_section  # noqa: E402
from benchmarks import JELLO, ROOT, machine, wait_quiet  # noqa: E402

OUT = os.path.join(ROOT, "BENCHMARKS.md")
BEGIN = "<!-- contact-share: begin (scripts/contact-share.sh) -->"
END = "<!-- contact-share: end -->"

SHAPES = ["sphere", "torus", "ell", "capsule"]
BODIES = 50
# The scene's material and contact: a firm jelly, stiff enough contact that skins at rest are
# under 2 % of a cell into each other, and RK4 at a step it is stable at.
JELLY = ["--density", "1000", "--modulus", "2e5", "--viscosity", "40"]
CREATE = ["--bounds=-0.75,-0.75,-1,0.75,0.75,2.5", "--dt", "0.00025",
          "--collision-stiffness", "2e5", "--collision-damping", "50"]
TIMINGS = re.compile(r"timings: wall ([0-9.]+) s, of it contacts between bodies ([0-9.]+) s")
WORK = re.compile(r"^contact work: (.*)$", re.M)


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def run(args, **kw):
    p = subprocess.run(args, capture_output=True, text=True, **kw)
    if p.returncode != 0:
        raise SystemExit("%s failed: %s" % (" ".join(args[:3]), failure(p)))
    return p


def make_scene(folder):
    """The fifty shapes' scene in `folder`; returns its path and its points."""
    for shape in SHAPES:
        run([JELLO, "shape", shape, os.path.join(folder, shape + ".obj"),
             "--detail", "6", "--size", "0.4"])
    bodies = []
    for n in range(BODIES):
        layer, k = divmod(n, 9)
        shape = SHAPES[(layer + k) % 4]
        x, y, z = (k % 3) * 45 - 45, (k // 3) * 45 - 45, 50 * layer - 70
        bodies += ["--mesh", os.path.join(folder, shape + ".obj"), "--cells", str(8 + n % 5),
                   "--centre", "%de-2,%de-2,%de-2" % (x, y, z),
                   "--rotation", "%d,%d,%d" % (17 * n % 90, 31 * n % 90, 47 * n % 90),
                   "--name", "%s%d" % (shape, n + 1)] + JELLY
    scene = os.path.join(folder, "fifty.toml")
    run([JELLO, "create", scene] + CREATE + bodies)
    info = run([JELLO, "info", scene]).stdout
    points = sum(int(n) for n in re.findall(r"^body .*?: ([0-9]+) points", info, re.M))
    return scene, "{:,}".format(points).replace(",", " ")


def measure(scene, seconds, threads):
    wait_quiet()
    env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
    p = run([JELLO, "run", scene, "--time", str(seconds), "--timings"], env=env)
    m = TIMINGS.search(p.stdout + p.stderr)
    if not m:
        raise SystemExit("no timings in: %s" % (p.stdout + p.stderr)[-300:])
    wall, contact = float(m.group(1)), float(m.group(2))
    work = WORK.search(p.stdout)
    if not work:
        raise SystemExit("no contact work in: %s" % p.stdout[-300:])
    log("%d thread(s): wall %.1f s, contact %.1f s (%.1f %%)"
        % (threads, wall, contact, 100 * contact / wall))
    return wall, contact, work.group(1)


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--time", type=float, default=2.5, help="simulated seconds from the drop")
    ap.add_argument("--threads", default="1,2", help="thread counts, comma-separated")
    ap.add_argument("--repeat", type=int, default=3, help="runs of each thread count")
    ap.add_argument("--out", default=OUT)
    args = ap.parse_args()
    if not os.path.exists(JELLO):
        raise SystemExit("no %s: run scripts/contact-share.sh (it builds it)" % JELLO)
    threads = [int(t) for t in args.threads.split(",")]
    with tempfile.TemporaryDirectory() as folder:
        scene, points = make_scene(folder)
        runs = {t: [] for t in threads}
        for _ in range(max(args.repeat, 1)):
            for t in threads:
                runs[t].append(measure(scene, args.time, t))
    # The work is counted, not timed: every run's the same, whatever the thread count.
    works = {r[2] for t in threads for r in runs[t]}
    if len(works) != 1:
        raise SystemExit("the contact work differs between runs: %s" % sorted(works))
    rows = []
    for t in threads:
        by_share = sorted(runs[t], key=lambda r: r[1] / r[0])
        shares = [100 * contact / wall for wall, contact, _ in by_share]
        rows.append((t,) + by_share[len(by_share) // 2][:2] + (shares[0], shares[-1]))
    info = machine()
    lines = [
        BEGIN,
        "## Contact between bodies: fifty shapes",
        "",
        "Generated by `scripts/contact-share.sh --time %g --repeat %d` on %s. Do not edit by "
        "hand: run the command again." % (args.time, max(args.repeat, 1),
                                          time.strftime("%Y-%m-%d %H:%M UTC", time.gmtime())),
        "",
        "**Scene.** %d shapes (a sphere, a torus, an L-shape and a capsule, 0.4 m across, meshes "
        "voxelised into 8 to 12 cells, %s points in all) dropped into a 1.5 m box, nine to a "
        "layer 0.45 m apart, each turned its own way; a jelly of 1000 kg/m³ and 2e5 Pa, "
        "collision stiffness 2e5 N/m, friction 0.5, RK4 at dt 0.25 ms. Stepped from the drop for "
        "%g s with `jello run SCENE --time %g --timings`: the wall-clock time of the contacts "
        "between bodies (the broad phase and the placing of surface points in other bodies' "
        "cells, timed in the core) against the whole run; each thread count %d times, taking "
        "turns, the run of the median share shown with the range of all." % (
            BODIES, points, args.time, args.time, max(args.repeat, 1)),
        "",
        "Machine: %s." % "; ".join("%s: %s" % (k, v) for k, v in info.items()),
        "",
        "| threads | wall (s) | contacts (s) | contacts' share of the run | range of the runs |",
        "| ---: | ---: | ---: | ---: | ---: |",
    ]
    for t, wall, contact, low, high in rows:
        lines.append("| %d | %.1f | %.1f | %.1f %% | %.1f–%.1f %% |"
                     % (t, wall, contact, 100 * contact / wall, low, high))
    lines += [
        "",
        "The contact passes' work, counted (`--timings`; the same in every run, on any thread "
        "count): %s." % works.pop(),
    ]
    lines.append(END)
    write_section(args.out, "\n".join(lines) + "\n", BEGIN, END)
    log("wrote %s" % args.out)


if __name__ == "__main__":
    main()
