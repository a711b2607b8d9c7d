#!/usr/bin/env python3
"""Taichi peer: the benchmark scene of `jello bench`, Taichi on the CPU backend, float64.

ti.init(arch=ti.cpu, default_fp=ti.f64, cpu_max_num_threads=--threads). Each force evaluation
is a kernel over springs (each spring evaluated once, its force added to both ends with atomic
adds) and a kernel over points (walls, gravity, acceleration, next integrator stage, and the
force buffer cleared for the next evaluation).
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402


class TaichiStepper:
    def __init__(self, scene, integrator, threads):
        import taichi as ti

        ti.init(arch=ti.cpu, default_fp=ti.f64, cpu_max_num_threads=threads,
                log_level=ti.WARN, offline_cache=True)
        self.ti = ti
        self.integrator = integrator
        P, S = scene.points, scene.springs
        vec = ti.types.vector(3, ti.f64)
        self.p = ti.Vector.field(3, ti.f64, P)
        self.v = ti.Vector.field(3, ti.f64, P)
        p2, v2, p3, v3, p4, v4, a1, a2, a3 = (ti.Vector.field(3, ti.f64, P) for _ in range(9))
        F = ti.Vector.field(3, ti.f64, P)
        sa = ti.field(ti.i32, S)
        sb = ti.field(ti.i32, S)
        rest = ti.field(ti.f64, S)
        self.p.from_numpy(scene.pos)
        self.v.from_numpy(scene.vel)
        sa.from_numpy(scene.sa.astype("int32"))
        sb.from_numpy(scene.sb.astype("int32"))
        rest.from_numpy(scene.rest)
        F.fill(0.0)

        K, D = common.K_ELASTIC, common.D_ELASTIC
        KC, DC, BOX = common.K_COLLISION, common.D_COLLISION, common.BOX
        G, INV_M = common.GRAVITY, 1.0 / common.MASS

        @ti.kernel
        def springs(p: ti.template(), v: ti.template()):
            for s in range(S):
                i = sa[s]
                j = sb[s]
                L = p[i] - p[j]
                ln = L.norm()
                u = L / ln
                fm = -K * (ln - rest[s]) - D * (v[i] - v[j]).dot(u)
                f = fm * u
                ti.atomic_add(F[i], f)
                ti.atomic_sub(F[j], f)

        @ti.func
        def accel(i, p, v):
            f = F[i]
            F[i] = vec(0.0, 0.0, 0.0)
            x = p[i]
            for c in ti.static(range(3)):
                if x[c] > BOX:
                    f[c] += -KC * (x[c] - BOX) - DC * v[i][c]
                elif x[c] < -BOX:
                    f[c] += KC * (-BOX - x[c]) - DC * v[i][c]
            f[2] += G
            return f * INV_M

        @ti.kernel
        def stage(p: ti.template(), v: ti.template(), hp: ti.f64, hv: ti.f64,
                  pout: ti.template(), vout: ti.template(), acc: ti.template()):
            for i in range(P):
                a = accel(i, p, v)
                acc[i] = a
                pout[i] = self.p[i] + hp * v[i]
                vout[i] = self.v[i] + hv * a

        @ti.kernel
        def combine(h: ti.f64):
            for i in range(P):
                a4 = accel(i, p4, v4)
                self.p[i] += (h / 6.0) * (self.v[i] + 2.0 * v2[i] + 2.0 * v3[i] + v4[i])
                self.v[i] += (h / 6.0) * (a1[i] + 2.0 * a2[i] + 2.0 * a3[i] + a4)

        @ti.kernel
        def euler(h: ti.f64):
            for i in range(P):
                a = accel(i, self.p, self.v)
                self.p[i] += h * self.v[i]
                self.v[i] += h * a

        p, v = self.p, self.v

        def rk4_step(h):
            springs(p, v)
            stage(p, v, 0.5 * h, 0.5 * h, p2, v2, a1)
            springs(p2, v2)
            stage(p2, v2, 0.5 * h, 0.5 * h, p3, v3, a2)
            springs(p3, v3)
            stage(p3, v3, h, h, p4, v4, a3)
            springs(p4, v4)
            combine(h)

        def euler_step(h):
            springs(p, v)
            euler(h)

        self._step = rk4_step if integrator == "RK4" else euler_step

    def step(self, k):
        h = common.DT
        f = self._step
        for _ in range(k):
            f(h)

    def sync(self):
        self.ti.sync()

    def state(self):
        return self.p.to_numpy(), self.v.to_numpy()


def main():
    args = common.parse_args(__doc__.splitlines()[1])
    common.set_thread_env(args.threads)
    import taichi as ti

    common.run("taichi", ".".join(map(str, ti.__version__)), TaichiStepper, args)


if __name__ == "__main__":
    main()
