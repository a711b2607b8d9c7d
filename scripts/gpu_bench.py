#!/usr/bin/env python3
"""Jello's GPU backend against the hand-written CUDA anchor, on the same card in the same run.

    scripts/gpu_bench.py [--jello target/release/jello] [--anchor ../shared/gpu-anchor]
                         [--sizes 8,32,64,128] [--seconds 2]

Runs `jello bench --device gpu --size N --json` for each size (a jello built with
`--features gpu`), then, when the anchor's folder is given and CuPy is importable,
`bench_gpu.py` there on the same sizes (its gather, edges and torch variants, f64 and f32),
and prints a Markdown table of spring evaluations/s (RK4; at 8³ steps/s) with Jello over the
anchor's f32 gather kernel. Run it on the machine with the GPU.
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--jello", default=os.path.join(ROOT, "target", "release", "jello"))
    ap.add_argument("--anchor", help="the folder of bench_gpu.py (../shared/gpu-anchor)")
    ap.add_argument("--sizes", default="8,32,64,128")
    ap.add_argument("--seconds", type=float, default=2.0)
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]

    jello = {}
    for n in sizes:
        out = subprocess.run(
            [args.jello, "bench", "--device", "gpu", "--size", str(n), "--seconds",
             str(args.seconds), "--json"], capture_output=True, text=True)
        if out.returncode != 0:
            sys.exit("gpu_bench.py: jello bench --device gpu failed: " + out.stderr.strip())
        jello[n] = json.loads(out.stdout)
        print(out.stdout.strip(), file=sys.stderr)

    anchor = {}
    if args.anchor:
        with tempfile.NamedTemporaryFile(suffix=".jsonl") as f:
            out = subprocess.run(
                [sys.executable, os.path.join(args.anchor, "bench_gpu.py"), f.name]
                + [str(n) for n in sizes], capture_output=True, text=True, cwd=args.anchor)
            if out.returncode != 0:
                sys.exit("gpu_bench.py: the anchor failed: " + out.stderr.strip()[-2000:])
            for line in open(f.name):
                r = json.loads(line)
                if r.get("kind") == "rate":
                    anchor[(r["variant"], r["prec"], r["N"])] = r

    adapter = jello[sizes[0]]["adapter"]
    print("Adapter: %s. RK4, dt 0.0005, the benchmark scene; spring evaluations/s (G), at 8³ "
          "steps/s.\n" % adapter)
    cols = ["Jello (WGSL, f32)", "CUDA gather f32", "CUDA gather f64", "CUDA edges f32",
            "Jello / CUDA gather f32"]
    print("| N³ | " + " | ".join(cols) + " |")
    print("| --- |" + " ---: |" * len(cols))
    for n in sizes:
        def rate(r):
            if r is None:
                return None
            return r["steps_per_s"] if n == 8 else r["spring_evals_per_s"] / 1e9
        fmt = (lambda v: "—" if v is None else ("%.0f" % v if n == 8 else "%.1f" % v))
        mine = rate(jello[n])
        g32 = rate(anchor.get(("gather", "f32", n)))
        g64 = rate(anchor.get(("gather", "f64", n)))
        e32 = rate(anchor.get(("edges", "f32", n)))
        ratio = "—" if not g32 else "%.2f" % (mine / g32)
        print("| %d³ | %s | %s | %s | %s | %s |" % (n, fmt(mine), fmt(g32), fmt(g64), fmt(e32),
                                                   ratio))


if __name__ == "__main__":
    main()
