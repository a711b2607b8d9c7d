#!/usr/bin/env python3
"""C peers: the benchmark scene of `jello bench` in C (c_peer.c), float64, driven through ctypes.

--variant simd (default): structure of arrays, `#pragma omp simd` rows per stencil offset, OpenMP
threads over planes, built with `gcc -O3 -march=native -fopenmp -fno-math-errno`: the hand-vectorised C baseline.
--variant naive: one flat spring list, arrays of 3-vectors, one thread, same flags.
The library is compiled once per source version into bench/.build/ (CC overrides gcc).
"""

import ctypes
import hashlib
import os
import subprocess
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402

HERE = os.path.dirname(os.path.abspath(__file__))
SOURCE = os.path.join(HERE, "c_peer.c")
BUILD = os.path.join(HERE, "..", ".build")
# -fno-math-errno: without it GCC keeps sqrt a possible libm call (to set errno) and does not
# vectorise the spring loop at all, `#pragma omp simd` or not (checked with -fopt-info-vec).
# GNU C mode (the default) keeps GCC's usual floating-point contraction (FMA).
FLAGS = ["-O3", "-march=native", "-fopenmp", "-fno-math-errno", "-shared", "-fPIC"]


def compiler():
    cc = os.environ.get("CC", "gcc")
    out = subprocess.run([cc, "--version"], capture_output=True, text=True, check=True)
    return cc, out.stdout.splitlines()[0]


def library():
    cc, version = compiler()
    with open(SOURCE, "rb") as f:
        key = hashlib.sha256(f.read() + " ".join([version] + FLAGS).encode()).hexdigest()[:16]
    path = os.path.join(BUILD, "c_peer-%s.so" % key)
    if not os.path.exists(path):
        os.makedirs(BUILD, exist_ok=True)
        tmp = path + ".tmp%d" % os.getpid()
        subprocess.run([cc, *FLAGS, "-o", tmp, SOURCE, "-lm"], check=True)
        os.replace(tmp, path)
    lib = ctypes.CDLL(path)
    dp = ctypes.POINTER(ctypes.c_double)
    lib.sim_new.restype = ctypes.c_void_p
    lib.sim_new.argtypes = [ctypes.c_int, ctypes.c_int, ctypes.c_int, ctypes.c_int,
                            ctypes.c_double, dp, dp]
    lib.sim_step.argtypes = [ctypes.c_void_p, ctypes.c_long]
    lib.sim_state.argtypes = [ctypes.c_void_p, dp, dp]
    lib.sim_free.argtypes = [ctypes.c_void_p]
    return lib, "%s %s" % (version, " ".join(FLAGS[:4]))


class Stepper:
    def __init__(self, lib, scene, integrator, threads, naive):
        import numpy as np

        self.lib, self.points = lib, scene.points
        pos = np.ascontiguousarray(scene.pos, dtype=np.float64)
        vel = np.ascontiguousarray(scene.vel, dtype=np.float64)
        dp = ctypes.POINTER(ctypes.c_double)
        self.sim = lib.sim_new(scene.n, int(integrator == "RK4"), int(naive), threads,
                               common.DT, pos.ctypes.data_as(dp), vel.ctypes.data_as(dp))
        if not self.sim:
            raise MemoryError("c_peer: sim_new failed")

    def step(self, k):
        self.lib.sim_step(self.sim, k)

    def sync(self):
        pass

    def state(self):
        import numpy as np

        p = np.empty((self.points, 3))
        v = np.empty((self.points, 3))
        dp = ctypes.POINTER(ctypes.c_double)
        self.lib.sim_state(self.sim, p.ctypes.data_as(dp), v.ctypes.data_as(dp))
        return p, v


def main():
    variant = "simd"
    argv = list(sys.argv[1:])
    if "--variant" in argv:
        i = argv.index("--variant")
        variant = argv[i + 1]
        del argv[i:i + 2]
        if variant not in ("simd", "naive"):
            sys.exit("c_peer: --variant is simd or naive")
    args = common.parse_args(__doc__.splitlines()[0], argv)
    common.set_thread_env(args.threads)
    lib, version = library()
    naive = variant == "naive"
    common.run("c-" + variant, version,
               lambda scene, integ, threads: Stepper(lib, scene, integ, threads, naive),
               args, threads_used=1 if naive else None,
               note="naive spring list, one thread" if naive else None)


if __name__ == "__main__":
    main()
