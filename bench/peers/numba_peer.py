#!/usr/bin/env python3
"""Numba peer: the benchmark scene of `jello bench`, @njit(parallel=True), float64.

Each force evaluation is two parallel loops: one over springs, split into one contiguous chunk
per thread, each spring evaluated once and its force added to both ends in that chunk's private
force buffer (race-free without atomics, which Numba lacks on the CPU); then one over points that
sums the buffers, adds walls and gravity and writes the next integrator stage. The whole step loop
runs inside one compiled function.
Threads: NUMBA_NUM_THREADS and numba.set_num_threads(--threads).
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402


def build(integrator):
    import numpy as np
    from numba import njit, prange

    K, D = common.K_ELASTIC, common.D_ELASTIC
    KC, DC, BOX = common.K_COLLISION, common.D_COLLISION, common.BOX
    G, INV_M = common.GRAVITY, 1.0 / common.MASS

    @njit(parallel=True)
    def spring_forces(p, v, sa, sb, rest, fb):
        # fb[c] is chunk c's private force buffer: no races, no atomics, one pass per spring.
        nch = fb.shape[0]
        ns = sa.shape[0]
        for c in prange(nch):
            lo = ns * c // nch
            hi = ns * (c + 1) // nch
            f = fb[c]
            for s in range(lo, hi):
                i = sa[s]
                j = sb[s]
                lx = p[i, 0] - p[j, 0]
                ly = p[i, 1] - p[j, 1]
                lz = p[i, 2] - p[j, 2]
                ln = np.sqrt(lx * lx + ly * ly + lz * lz)
                ux = lx / ln
                uy = ly / ln
                uz = lz / ln
                dot = ((v[i, 0] - v[j, 0]) * ux + (v[i, 1] - v[j, 1]) * uy
                       + (v[i, 2] - v[j, 2]) * uz)
                fm = -K * (ln - rest[s]) - D * dot
                fx = fm * ux
                fy = fm * uy
                fz = fm * uz
                f[i, 0] += fx
                f[i, 1] += fy
                f[i, 2] += fz
                f[j, 0] -= fx
                f[j, 1] -= fy
                f[j, 2] -= fz

    @njit(inline="always")
    def accel(i, c, p, v, fb):
        # total force on point i, component c, divided by the mass; clears the buffers
        f = 0.0
        for b in range(fb.shape[0]):
            f += fb[b, i, c]
            fb[b, i, c] = 0.0
        x = p[i, c]
        if x > BOX:
            f += -KC * (x - BOX) - DC * v[i, c]
        elif x < -BOX:
            f += KC * (-BOX - x) - DC * v[i, c]
        if c == 2:
            f += G
        return f * INV_M

    @njit(parallel=True)
    def stage(p0, v0, p, v, fb, hp, hv, pout, vout, acc):
        # acc <- a(p, v);  pout <- p0 + hp * v;  vout <- v0 + hv * acc
        for i in prange(p0.shape[0]):
            for c in range(3):
                a = accel(i, c, p, v, fb)
                acc[i, c] = a
                pout[i, c] = p0[i, c] + hp * v[i, c]
                vout[i, c] = v0[i, c] + hv * a

    @njit(parallel=True)
    def combine(p, v, v2, v3, v4, a1, a2, a3, p4, fb, h):
        for i in prange(p.shape[0]):
            for c in range(3):
                a4 = accel(i, c, p4, v4, fb)
                dp = v[i, c] + 2.0 * v2[i, c] + 2.0 * v3[i, c] + v4[i, c]
                dv = a1[i, c] + 2.0 * a2[i, c] + 2.0 * a3[i, c] + a4
                p[i, c] += (h / 6.0) * dp
                v[i, c] += (h / 6.0) * dv

    @njit
    def run_rk4(nsteps, p, v, sa, sb, rest, fb, p2, v2, p3, v3, p4, v4, a1, a2, a3, h):
        for _ in range(nsteps):
            spring_forces(p, v, sa, sb, rest, fb)
            stage(p, v, p, v, fb, 0.5 * h, 0.5 * h, p2, v2, a1)
            spring_forces(p2, v2, sa, sb, rest, fb)
            stage(p, v, p2, v2, fb, 0.5 * h, 0.5 * h, p3, v3, a2)
            spring_forces(p3, v3, sa, sb, rest, fb)
            stage(p, v, p3, v3, fb, h, h, p4, v4, a3)
            spring_forces(p4, v4, sa, sb, rest, fb)
            combine(p, v, v2, v3, v4, a1, a2, a3, p4, fb, h)

    @njit(parallel=True)
    def euler_update(p, v, fb, h):
        for i in prange(p.shape[0]):
            for c in range(3):
                a = accel(i, c, p, v, fb)
                p[i, c] += h * v[i, c]
                v[i, c] += h * a

    @njit
    def run_euler(nsteps, p, v, sa, sb, rest, fb, h):
        for _ in range(nsteps):
            spring_forces(p, v, sa, sb, rest, fb)
            euler_update(p, v, fb, h)

    return run_rk4 if integrator == "RK4" else run_euler


class NumbaStepper:
    def __init__(self, scene, integrator, threads=1):
        import numpy as np

        self.integrator = integrator
        self.p = scene.pos.copy()
        self.v = scene.vel.copy()
        # one private force buffer per thread
        self.topo = (scene.sa, scene.sb, scene.rest, np.zeros((threads, scene.points, 3)))
        self.bufs = tuple(np.zeros_like(self.p) for _ in range(9))
        self.fn = build(integrator)

    def step(self, k):
        if self.integrator == "RK4":
            self.fn(k, self.p, self.v, *self.topo, *self.bufs, common.DT)
        else:
            self.fn(k, self.p, self.v, *self.topo, common.DT)

    def sync(self):
        pass

    def state(self):
        return self.p.copy(), self.v.copy()


def main():
    args = common.parse_args(__doc__.splitlines()[1])
    common.set_thread_env(args.threads)
    import numba

    numba.set_num_threads(args.threads)
    common.run("numba", numba.__version__, NumbaStepper, args,
               threads_used=numba.get_num_threads())


if __name__ == "__main__":
    main()
