#!/usr/bin/env python3
"""Warp peer: the benchmark scene of `jello bench`, NVIDIA Warp on the "cpu" device, float64.

wp.init(); arrays of wp.vec3d on device "cpu". Each force evaluation is a kernel over springs
(each spring evaluated once, its force added to both ends with wp.atomic_add/atomic_sub) and a
kernel over points (walls, gravity, acceleration, next integrator stage, force buffer cleared).
Warp runs CPU kernels on one thread: --threads is recorded but has no effect.
"""

import os
import sys

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import common  # noqa: E402


def build():
    import warp as wp

    K = wp.constant(wp.float64(common.K_ELASTIC))
    D = wp.constant(wp.float64(common.D_ELASTIC))
    KC = wp.constant(wp.float64(common.K_COLLISION))
    DC = wp.constant(wp.float64(common.D_COLLISION))
    BOX = wp.constant(wp.float64(common.BOX))
    G = wp.constant(wp.float64(common.GRAVITY))
    INV_M = wp.constant(wp.float64(1.0 / common.MASS))

    @wp.kernel
    def springs(p: wp.array(dtype=wp.vec3d), v: wp.array(dtype=wp.vec3d),
                sa: wp.array(dtype=wp.int32), sb: wp.array(dtype=wp.int32),
                rest: wp.array(dtype=wp.float64), F: wp.array(dtype=wp.vec3d)):
        s = wp.tid()
        i = sa[s]
        j = sb[s]
        L = p[i] - p[j]
        ln = wp.length(L)
        u = L / ln
        fm = -K * (ln - rest[s]) - D * wp.dot(v[i] - v[j], u)
        f = fm * u
        wp.atomic_add(F, i, f)
        wp.atomic_sub(F, j, f)

    @wp.func
    def wall(x: wp.float64, vc: wp.float64):
        r = wp.float64(0.0)
        if x > BOX:
            r = -KC * (x - BOX) - DC * vc
        elif x < -BOX:
            r = KC * (-BOX - x) - DC * vc
        return r

    @wp.func
    def accel(i: int, p: wp.array(dtype=wp.vec3d), v: wp.array(dtype=wp.vec3d),
              F: wp.array(dtype=wp.vec3d)):
        f = F[i]
        F[i] = wp.vec3d(wp.float64(0.0), wp.float64(0.0), wp.float64(0.0))
        x = p[i]
        vi = v[i]
        f = f + wp.vec3d(wall(x[0], vi[0]), wall(x[1], vi[1]), wall(x[2], vi[2]) + G)
        return f * INV_M

    @wp.kernel
    def stage(p0: wp.array(dtype=wp.vec3d), v0: wp.array(dtype=wp.vec3d),
              p: wp.array(dtype=wp.vec3d), v: wp.array(dtype=wp.vec3d),
              F: wp.array(dtype=wp.vec3d), hp: wp.float64, hv: wp.float64,
              pout: wp.array(dtype=wp.vec3d), vout: wp.array(dtype=wp.vec3d),
              acc: wp.array(dtype=wp.vec3d)):
        i = wp.tid()
        a = accel(i, p, v, F)
        acc[i] = a
        pout[i] = p0[i] + hp * v[i]
        vout[i] = v0[i] + hv * a

    @wp.kernel
    def combine(p: wp.array(dtype=wp.vec3d), v: wp.array(dtype=wp.vec3d),
                v2: wp.array(dtype=wp.vec3d), v3: wp.array(dtype=wp.vec3d),
                p4: wp.array(dtype=wp.vec3d), v4: wp.array(dtype=wp.vec3d),
                a1: wp.array(dtype=wp.vec3d), a2: wp.array(dtype=wp.vec3d),
                a3: wp.array(dtype=wp.vec3d), F: wp.array(dtype=wp.vec3d), h: wp.float64):
        i = wp.tid()
        a4 = accel(i, p4, v4, F)
        two = wp.float64(2.0)
        c = h / wp.float64(6.0)
        p[i] = p[i] + c * (v[i] + two * v2[i] + two * v3[i] + v4[i])
        v[i] = v[i] + c * (a1[i] + two * a2[i] + two * a3[i] + a4)

    @wp.kernel
    def euler(p: wp.array(dtype=wp.vec3d), v: wp.array(dtype=wp.vec3d),
              F: wp.array(dtype=wp.vec3d), h: wp.float64):
        i = wp.tid()
        a = accel(i, p, v, F)
        p[i] = p[i] + h * v[i]
        v[i] = v[i] + h * a

    return springs, stage, combine, euler


class WarpStepper:
    def __init__(self, scene, integrator, threads):
        import numpy as np
        import warp as wp

        wp.config.quiet = True
        wp.init()
        self.wp = wp
        dev = "cpu"
        P, S = scene.points, scene.springs
        springs, stage, combine, euler = build()
        vec = lambda a: wp.array(a, dtype=wp.vec3d, device=dev)  # noqa: E731
        self.p = vec(scene.pos)
        self.v = vec(scene.vel)
        zero = np.zeros((P, 3))
        p2, v2, p3, v3, p4, v4, a1, a2, a3, F = (vec(zero) for _ in range(10))
        sa = wp.array(scene.sa.astype(np.int32), dtype=wp.int32, device=dev)
        sb = wp.array(scene.sb.astype(np.int32), dtype=wp.int32, device=dev)
        rest = wp.array(scene.rest, dtype=wp.float64, device=dev)
        p, v = self.p, self.v
        launch = wp.launch
        h = wp.float64(common.DT)
        half = wp.float64(0.5 * common.DT)

        def rk4_step():
            launch(springs, S, inputs=[p, v, sa, sb, rest, F], device=dev)
            launch(stage, P, inputs=[p, v, p, v, F, half, half, p2, v2, a1], device=dev)
            launch(springs, S, inputs=[p2, v2, sa, sb, rest, F], device=dev)
            launch(stage, P, inputs=[p, v, p2, v2, F, half, half, p3, v3, a2], device=dev)
            launch(springs, S, inputs=[p3, v3, sa, sb, rest, F], device=dev)
            launch(stage, P, inputs=[p, v, p3, v3, F, h, h, p4, v4, a3], device=dev)
            launch(springs, S, inputs=[p4, v4, sa, sb, rest, F], device=dev)
            launch(combine, P, inputs=[p, v, v2, v3, p4, v4, a1, a2, a3, F, h], device=dev)

        def euler_step():
            launch(springs, S, inputs=[p, v, sa, sb, rest, F], device=dev)
            launch(euler, P, inputs=[p, v, F, h], device=dev)

        self._step = rk4_step if integrator == "RK4" else euler_step

    def step(self, k):
        f = self._step
        for _ in range(k):
            f()

    def sync(self):
        self.wp.synchronize()

    def state(self):
        return self.p.numpy().astype("float64"), self.v.numpy().astype("float64")


def main():
    args = common.parse_args(__doc__.splitlines()[1])
    common.set_thread_env(args.threads)
    import warp as wp

    common.run("warp", wp.config.version, WarpStepper, args, threads_used=1,
               note="Warp runs CPU kernels on a single thread; --threads has no effect")


if __name__ == "__main__":
    main()
