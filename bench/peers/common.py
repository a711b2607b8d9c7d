"""Shared scene, command line and timing harness for the peer implementations.

The scene is the one of `jello bench` (crates/jello-core/src/scenes.rs, docs/spec.md):

* an N x N x N lattice of side 1 (spacing 1/(N-1)), point (i, j, k) at
  (i/(N-1) - 0.5, j/(N-1) - 0.5, k/(N-1) - 0.5), flat index (i*N + j)*N + k;
* springs of docs/spec.md, each unordered pair once, rest length = spacing * |offset|:
  structural (axis neighbours at index distance 1), shear (12 face diagonals and
  8 body diagonals), bend (axis neighbours at index distance 2);
* kElastic 200, dElastic 0.25 on every spring; box [-2, 2]^3 with zero-rest-length
  penalty springs (kCollision 400, dCollision 0.25) per wall a point is strictly outside of;
* mass 1/512 per point at every N, gravity a constant force (0, 0, -9.81 * mass) per point,
  no plane, every point starting at velocity (10, -10, 20), dt 0.0005.

Only the standard library is imported at module level so that a peer can set thread
environment variables before NumPy / Numba / Taichi / Warp are imported.
"""

import argparse
import json
import os
import sys
import time

K_ELASTIC = 200.0
D_ELASTIC = 0.25
K_COLLISION = 400.0
D_COLLISION = 0.25
MASS = 1.0 / 512.0
GRAVITY = -9.81 * MASS  # z component of the constant force on every point
DT = 0.0005
BOX = 2.0
V0 = (10.0, -10.0, 20.0)

# One offset per unordered pair: the "positive half" of the stencil.
STRUCTURAL = [(1, 0, 0), (0, 1, 0), (0, 0, 1)]
FACE_SHEAR = [(1, 1, 0), (1, -1, 0), (1, 0, 1), (1, 0, -1), (0, 1, 1), (0, 1, -1)]
BODY_SHEAR = [(1, 1, 1), (1, 1, -1), (1, -1, 1), (1, -1, -1)]
BEND = [(2, 0, 0), (0, 2, 0), (0, 0, 2)]
OFFSETS = STRUCTURAL + FACE_SHEAR + BODY_SHEAR + BEND

EVALS_PER_STEP = {"RK4": 4, "Euler": 1}
INTEGRATORS = {"rk4": "RK4", "euler": "Euler"}


def expected_springs(n):
    return 3 * n * n * (n - 1) + 6 * n * (n - 1) ** 2 + 4 * (n - 1) ** 3 + 3 * n * n * (n - 2)


def offset_slices(n, off):
    """Index slices (sa, sb) of the 3-D grid such that point A = grid[sa] and B = grid[sb]
    are joined by a spring of offset `off` (B = A + off), every pair exactly once."""
    sa, sb = [], []
    for o in off:
        if o >= 0:
            sa.append(slice(0, n - o))
            sb.append(slice(o, n))
        else:
            sa.append(slice(-o, n))
            sb.append(slice(0, n + o))
    return tuple(sa), tuple(sb)


class Scene:
    """Arrays of the benchmark scene (float64, int64 indices)."""

    def __init__(self, n):
        import numpy as np

        if n < 3:
            raise ValueError("size must be at least 3 (bend springs need 3 points per axis)")
        self.n = n
        self.points = n ** 3
        h = 1.0 / (n - 1)
        self.spacing = h
        idx = np.arange(n, dtype=np.float64) / (n - 1) - 0.5
        I, J, K = np.meshgrid(idx, idx, idx, indexing="ij")
        self.pos = np.stack([I.ravel(), J.ravel(), K.ravel()], axis=1).copy()
        self.vel = np.tile(np.array(V0, dtype=np.float64), (self.points, 1))
        flat = np.arange(self.points, dtype=np.int64).reshape(n, n, n)
        a, b, r = [], [], []
        for off in OFFSETS:
            sa, sb = offset_slices(n, off)
            ia = flat[sa].ravel()
            ib = flat[sb].ravel()
            a.append(ia)
            b.append(ib)
            rest = h * float(np.sqrt(off[0] ** 2 + off[1] ** 2 + off[2] ** 2))
            r.append(np.full(ia.shape, rest))
        self.sa = np.concatenate(a)
        self.sb = np.concatenate(b)
        self.rest = np.concatenate(r)
        self.springs = int(self.sa.size)
        assert self.springs == expected_springs(n), (self.springs, expected_springs(n))

    def csr(self):
        """Per point, the springs it belongs to and the sign of the spring force on it
        (+1 for end A, -1 for end B): indptr, spring index, sign."""
        import numpy as np

        pts = np.concatenate([self.sa, self.sb])
        spr = np.concatenate([np.arange(self.springs), np.arange(self.springs)])
        sign = np.concatenate([np.ones(self.springs), -np.ones(self.springs)])
        order = np.argsort(pts, kind="stable")
        counts = np.bincount(pts, minlength=self.points)
        indptr = np.zeros(self.points + 1, dtype=np.int64)
        np.cumsum(counts, out=indptr[1:])
        return indptr, spr[order].astype(np.int64), sign[order]


def parse_args(description, argv=None):
    p = argparse.ArgumentParser(description=description)
    p.add_argument("--size", type=int, default=8, help="lattice side N (N^3 points)")
    p.add_argument("--integrator", default="rk4", help="rk4 or euler (any case)")
    p.add_argument("--seconds", type=float, default=3.0, help="timed run length (s)")
    p.add_argument("--warmup", type=float, default=0.5, help="warm-up length after compiling (s)")
    p.add_argument("--threads", type=int, default=1)
    p.add_argument("--json", action="store_true", help="print one JSON object (default: also)")
    p.add_argument("--dump-steps", type=int, default=0,
                   help="instead of timing: run this many steps from the initial state and "
                        "print the final positions and velocities as JSON (for check.py)")
    args = p.parse_args(argv)
    key = args.integrator.lower()
    if key not in INTEGRATORS:
        p.error("unknown integrator %r; known: RK4, Euler" % args.integrator)
    args.integrator = INTEGRATORS[key]
    if args.threads < 1:
        p.error("--threads must be at least 1")
    return args


def set_thread_env(threads):
    """Thread-count variables read by BLAS / OpenMP / Numba at import time."""
    t = str(threads)
    for var in ("OMP_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS",
                "NUMEXPR_NUM_THREADS", "NUMBA_NUM_THREADS", "VECLIB_MAXIMUM_THREADS"):
        os.environ[var] = t


def run(impl, version, make_stepper, args, threads_used=None, note=None, extra=None):
    """Build the scene, compile, warm up, time, print one JSON object.

    make_stepper(scene, integrator, threads) returns an object with
      step(k)   advance k steps (finished when it returns, or after sync())
      sync()    wait for outstanding work
      state()   (positions, velocities) as (P, 3) float64 NumPy arrays
    """
    import numpy as np

    scene = Scene(args.size)
    t0 = time.perf_counter()
    stepper = make_stepper(scene, args.integrator, args.threads)
    if args.dump_steps:
        stepper.step(args.dump_steps)
        stepper.sync()
        p, v = stepper.state()
        json.dump({"impl": impl, "size": args.size, "integrator": args.integrator,
                   "steps": args.dump_steps, "pos": np.asarray(p).ravel().tolist(),
                   "vel": np.asarray(v).ravel().tolist()}, sys.stdout)
        sys.stdout.write("\n")
        return
    stepper.step(1)  # compiles
    stepper.sync()
    compile_s = time.perf_counter() - t0

    # Warm-up: doubling batches until `warmup` seconds are spent.
    k, spent, done = 1, 0.0, 1
    while spent < args.warmup:
        t = time.perf_counter()
        stepper.step(k)
        stepper.sync()
        dt = time.perf_counter() - t
        spent += dt
        done += k
        rate = k / dt if dt > 0 else 1e6
        k *= 2
    batch = max(1, int(rate * 0.05))  # about 50 ms per batch

    steps = 0
    start = time.perf_counter()
    elapsed = 0.0
    while elapsed < args.seconds:
        stepper.step(batch)
        stepper.sync()
        steps += batch
        elapsed = time.perf_counter() - start
    p, v = stepper.state()
    sps = steps / elapsed
    out = {
        "impl": impl,
        "size": args.size,
        "points": scene.points,
        "springs": scene.springs,
        "integrator": args.integrator,
        "threads": args.threads,
        "threads_used": args.threads if threads_used is None else threads_used,
        "steps": steps,
        "seconds": elapsed,
        "steps_per_s": sps,
        "spring_evals_per_s": scene.springs * EVALS_PER_STEP[args.integrator] * sps,
        "compile_s": compile_s,
        "warmup_steps": done,
        "final_finite": bool(np.isfinite(p).all() and np.isfinite(v).all()),
        "version": version,
    }
    if note:
        out["note"] = note
    if extra:
        out.update(extra)
    print(json.dumps(out))
