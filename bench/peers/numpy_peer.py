#!/usr/bin/env python3
"""NumPy peer: the benchmark scene of `jello bench`, vectorised NumPy, float64.

Two variants (--variant):
  stencil  (default) the springs of one stencil offset are a strided slice pair of the 3-D grid,
           so each of the 16 offsets is evaluated with whole-array operations and scattered
           with slice adds (no gather, no index arrays);
  scatter  one flat array of springs: gather both ends with fancy indexing and scatter the
           forces with np.bincount (per component), the textbook "vectorise over springs".
Both evaluate every spring once per force evaluation. NumPy's element-wise operations are
single-threaded; --threads only sets the BLAS/OpenMP variables, which this code never uses.
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402


class NumpyStepper:
    def __init__(self, scene, integrator, variant="stencil"):
        import numpy as np

        self.np = np
        self.n = scene.n
        self.P = scene.points
        self.integrator = integrator
        self.p = np.ascontiguousarray(scene.pos.T)  # (3, P) structure of arrays
        self.v = np.ascontiguousarray(scene.vel.T)
        self.F = np.zeros((3, self.P))
        if variant == "stencil":
            self.force = self._force_stencil
            self.pairs = []
            for off in common.OFFSETS:
                sa, sb = common.offset_slices(self.n, off)
                rest = scene.spacing * float(np.sqrt(sum(o * o for o in off)))
                self.pairs.append(((slice(None),) + sa, (slice(None),) + sb, rest))
        elif variant == "scatter":
            self.force = self._force_scatter
            self.sa, self.sb, self.rest = scene.sa, scene.sb, scene.rest
        else:
            raise ValueError("unknown variant %r" % variant)

    def _walls_gravity(self, p, v, F):
        np = self.np
        kc, dc, box = common.K_COLLISION, common.D_COLLISION, common.BOX
        hi = p > box
        lo = p < -box
        if hi.any():
            F += np.where(hi, -kc * (p - box) - dc * v, 0.0)
        if lo.any():
            F += np.where(lo, kc * (-box - p) - dc * v, 0.0)
        F[2] += common.GRAVITY

    def _force_stencil(self, p, v):
        np = self.np
        n = self.n
        F = self.F
        F.fill(0.0)
        P3 = p.reshape(3, n, n, n)
        V3 = v.reshape(3, n, n, n)
        F3 = F.reshape(3, n, n, n)
        k, d = common.K_ELASTIC, common.D_ELASTIC
        for sa, sb, rest in self.pairs:
            L = P3[sa] - P3[sb]                       # (3, ...)
            ln = np.sqrt(L[0] * L[0] + L[1] * L[1] + L[2] * L[2])
            L /= ln                                   # unit vector
            dv = V3[sa] - V3[sb]
            dv *= L
            fm = dv[0] + dv[1] + dv[2]
            fm *= -d
            fm -= k * (ln - rest)
            L *= fm                                   # force on A
            F3[sa] += L
            F3[sb] -= L
        self._walls_gravity(p, v, F)
        return F * (1.0 / common.MASS)

    def _force_scatter(self, p, v):
        np = self.np
        P = self.P
        k, d = common.K_ELASTIC, common.D_ELASTIC
        L = p[:, self.sa] - p[:, self.sb]
        ln = np.sqrt(L[0] * L[0] + L[1] * L[1] + L[2] * L[2])
        L /= ln
        dv = v[:, self.sa] - v[:, self.sb]
        fm = -k * (ln - self.rest) - d * (dv[0] * L[0] + dv[1] * L[1] + dv[2] * L[2])
        L *= fm
        F = np.empty((3, P))
        for c in range(3):
            F[c] = np.bincount(self.sa, L[c], minlength=P) - np.bincount(self.sb, L[c], minlength=P)
        self._walls_gravity(p, v, F)
        return F * (1.0 / common.MASS)

    def step(self, k):
        h = common.DT
        f = self.force
        for _ in range(k):
            p, v = self.p, self.v
            if self.integrator == "Euler":
                a = f(p, v)
                self.p = p + h * v
                self.v = v + h * a
            else:
                a1 = f(p, v)
                v2 = v + (0.5 * h) * a1
                a2 = f(p + (0.5 * h) * v, v2)
                v3 = v + (0.5 * h) * a2
                a3 = f(p + (0.5 * h) * v2, v3)
                v4 = v + h * a3
                a4 = f(p + h * v3, v4)
                self.p = p + (h / 6.0) * (v + 2.0 * v2 + 2.0 * v3 + v4)
                self.v = v + (h / 6.0) * (a1 + 2.0 * a2 + 2.0 * a3 + a4)

    def sync(self):
        pass

    def state(self):
        return self.p.T.copy(), self.v.T.copy()


def main():
    variant = "stencil"
    argv = sys.argv[1:]
    if "--variant" in argv:
        i = argv.index("--variant")
        variant = argv[i + 1]
        del argv[i:i + 2]
    args = common.parse_args(__doc__.splitlines()[1], argv)
    common.set_thread_env(args.threads)
    import numpy as np

    common.run("numpy", np.__version__,
               lambda s, integ, t: NumpyStepper(s, integ, variant), args,
               threads_used=1,
               note="NumPy element-wise operations run on one thread; --threads is not used",
               extra={"variant": variant})


if __name__ == "__main__":
    main()
