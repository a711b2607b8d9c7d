#!/usr/bin/env python3
"""Correctness check of the peers: every peer steps the benchmark scene K steps from its initial
state (--dump-steps) and its final positions and velocities are compared with the plain NumPy
reference (numpy_peer.py --variant scatter: one flat spring list, bincount scatter), for RK4
and Euler. With --jello BIN the 8^3 scene is also written as a world file by `jello create`
(gravity as a res-2 field, offset -0.5, velocity (10, -10, 20)), run K steps by `jello run
--save`, and compared the same way. K = 300 includes the cube's first wall contacts (the top
face reaches z = 2 after about 150 steps).

Prints one JSON object: {"steps": K, "rows": [{"impl", "size", "integrator", "max_dpos",
"max_dvel", "ok"} or {"impl", ..., "error"}]}.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import common  # noqa: E402

PEERS = ["numpy", "numba", "taichi", "warp", "c", "c-naive"]


def last_json(text):
    for line in reversed(text.splitlines()):
        line = line.strip()
        if line.startswith("{"):
            return json.loads(line)
    raise ValueError("no JSON object in output")


def dump(impl, size, integ, steps, threads, variant=None, timeout=600):
    if impl in ("c", "c-naive"):
        impl, variant = "c", "naive" if impl == "c-naive" else "simd"
    cmd = [sys.executable, os.path.join(HERE, impl + "_peer.py"), "--size", str(size),
           "--integrator", integ, "--threads", str(threads), "--dump-steps", str(steps)]
    if variant:
        cmd += ["--variant", variant]
    r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout)
    if r.returncode != 0:
        raise RuntimeError((r.stderr or r.stdout).strip().splitlines()[-1])
    d = last_json(r.stdout)
    return d["pos"], d["vel"]


def jello_dump(jello, integ, steps):
    """The 8^3 benchmark scene through world files and `jello run`."""
    with tempfile.TemporaryDirectory() as tmp:
        w0 = os.path.join(tmp, "bench8.w")
        w1 = os.path.join(tmp, "after.w")
        subprocess.run([jello, "create", w0, "--integrator", integ, "--dt", str(common.DT),
                        "--field", "gravity", "--res", "2", "--offset=-0.5,-0.5,-0.5",
                        "--velocity", "10,-10,20", "--force"],
                       check=True, capture_output=True, text=True)
        r = subprocess.run([jello, "run", w0, "--steps", str(steps), "--save", w1, "-q"],
                           capture_output=True, text=True)
        if r.returncode != 0:
            raise RuntimeError(r.stderr.strip())
        tok = open(w1).read().split()
    i = 1 + 2 + 4 + 1
    plane = int(tok[i])
    i += 1 + (4 if plane == 1 else 0)
    res = int(tok[i])
    i += 1 + 3 * res ** 3
    nums = [float(t) for t in tok[i:i + 2 * 3 * 512]]
    return nums[:1536], nums[1536:]


def maxdiff(a, b):
    return max(abs(x - y) for x, y in zip(a, b)) if len(a) == len(b) else float("inf")


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--sizes", default="8,5")
    ap.add_argument("--only", default=",".join(PEERS))
    ap.add_argument("--threads", type=int, default=2)
    ap.add_argument("--tol", type=float, default=1e-12)
    ap.add_argument("--jello", default=None, help="path of the jello binary")
    args = ap.parse_args()
    rows = []
    for integ in ("RK4", "Euler"):
        for size in [int(s) for s in args.sizes.split(",")]:
            ref = dump("numpy", size, integ, args.steps, 1, variant="scatter")
            # numpy here is the benchmarked variant (stencil slices), checked against scatter
            # Jello's SIMD tiers (jello-avx2, ...) compute the same bits as Jello (the test
            # suite compares them byte for byte), so only Jello itself is checked below.
            cands = [(p, "stencil" if p == "numpy" else None)
                     for p in args.only.split(",") if p and not p.startswith("jello-")]
            for impl, variant in cands:
                row = {"impl": impl, "size": size, "integrator": integ}
                try:
                    p, v = dump(impl, size, integ, args.steps, args.threads, variant)
                    row.update(max_dpos=maxdiff(p, ref[0]), max_dvel=maxdiff(v, ref[1]))
                    row["ok"] = row["max_dpos"] <= args.tol
                except Exception as e:  # reported, not hidden
                    row["error"] = str(e)
                rows.append(row)
            if args.jello and size == 8:
                row = {"impl": "jello (world file, jello run)", "size": 8, "integrator": integ}
                try:
                    p, v = jello_dump(args.jello, integ, args.steps)
                    row.update(max_dpos=maxdiff(p, ref[0]), max_dvel=maxdiff(v, ref[1]))
                    row["ok"] = row["max_dpos"] <= args.tol
                except Exception as e:
                    row["error"] = str(e)
                rows.append(row)
    print(json.dumps({"steps": args.steps, "tol": args.tol, "rows": rows}))


if __name__ == "__main__":
    main()
