#!/usr/bin/env python3
"""How `jello bench` scales with threads on this machine, against what the machine itself allows.

For each lattice size and thread count T, alternated in rounds (medians reported):
  - threaded:    one `jello bench --threads T` process;
  - independent: T single-thread `jello bench` processes at once, their rates summed. They share
                 nothing, so their sum is what T threads of this machine can do on this work at
                 all (cores, shared caches, memory bandwidth, and whether the CPUs the system
                 shows are whole cores or hyperthreads of fewer). The threaded figure over it is
                 the efficiency of Jello's own threading.
With --baseline BIN, a second jello binary is measured threaded too, alternated with this one
(before/after comparisons on the same machine in the same run).

    scripts/scaling.py [--sizes 32,64,128] [--threads 1,2,4,8,16] [--rounds 2] [--seconds 1.5]
                       [--jello target/release/jello] [--baseline OTHER_JELLO]

Prints a Markdown table (spring evaluations/s, RK4) and the CPU it ran on.
"""

import argparse
import json
import os
import platform
import statistics
import subprocess
import sys

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def bench(jello, size, threads, seconds):
    """Spring evaluations/s of one `jello bench` process."""
    out = subprocess.run(
        [jello, "bench", "--size", str(size), "--threads", str(threads),
         "--seconds", str(seconds), "--json"],
        capture_output=True, text=True, check=True, timeout=600).stdout
    return json.loads(out)["spring_evals_per_s"]


def independent(jello, size, count, seconds):
    """Sum of the rates of `count` single-thread processes running at once."""
    procs = [subprocess.Popen(
        [jello, "bench", "--size", str(size), "--threads", "1", "--seconds", str(seconds),
         "--json"], stdout=subprocess.PIPE, text=True) for _ in range(count)]
    total = 0.0
    for p in procs:
        out, _ = p.communicate(timeout=600)
        if p.returncode != 0:
            raise RuntimeError("jello bench failed (exit %d)" % p.returncode)
        total += json.loads(out)["spring_evals_per_s"]
    return total


def cpu_model():
    try:
        with open("/proc/cpuinfo") as f:
            for line in f:
                if line.startswith("model name"):
                    return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--sizes", default="32,64,128")
    ap.add_argument("--threads", default="1,2,4,8,16")
    ap.add_argument("--rounds", type=int, default=2)
    ap.add_argument("--seconds", type=float, default=1.5)
    ap.add_argument("--jello", default=os.path.join(ROOT, "target", "release", "jello"))
    ap.add_argument("--baseline", help="another jello binary, measured threaded alongside")
    args = ap.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    threads = [int(t) for t in args.threads.split(",")]
    if 1 not in threads:
        threads = [1] + threads
    for binary in filter(None, [args.jello, args.baseline]):
        if not os.access(binary, os.X_OK):
            sys.exit("scaling.py: %s is not an executable jello (build it: cargo build --release)"
                     % binary)

    runs = {}  # (kind, size, threads) -> [evals/s]
    for r in range(args.rounds):
        for n in sizes:
            for t in threads:
                print("round %d: %d³, %d thread(s)" % (r + 1, n, t), file=sys.stderr, flush=True)
                runs.setdefault(("threaded", n, t), []).append(
                    bench(args.jello, n, t, args.seconds))
                if args.baseline:
                    runs.setdefault(("baseline", n, t), []).append(
                        bench(args.baseline, n, t, args.seconds))
                runs.setdefault(("independent", n, t), []).append(
                    independent(args.jello, n, t, args.seconds))

    med = {k: statistics.median(v) for k, v in runs.items()}
    print("CPU: %s, %d logical CPUs; medians of %d alternated rounds of %.1f s each; RK4, "
          "spring evaluations/s (M)\n" % (cpu_model(), os.cpu_count() or 0, args.rounds,
                                          args.seconds))
    head = "| size | threads | Jello threaded | × 1 thread | independent processes | × 1 process " \
           "| threaded / independent |"
    if args.baseline:
        head += " baseline threaded | × 1 thread | Jello / baseline |"
    print(head)
    print("| " + " | ".join(["---"] * (head.count("|") - 1)) + " |")
    for n in sizes:
        one_t, one_i = med[("threaded", n, 1)], med[("independent", n, 1)]
        for t in threads:
            th, ind = med[("threaded", n, t)], med[("independent", n, t)]
            row = "| %d³ | %d | %.0f | %.1f× | %.0f | %.1f× | %.2f |" % (
                n, t, th / 1e6, th / one_t, ind / 1e6, ind / one_i, th / ind)
            if args.baseline:
                b, one_b = med[("baseline", n, t)], med[("baseline", n, 1)]
                row += " %.0f | %.1f× | %.2f |" % (b / 1e6, b / one_b, th / b)
            print(row)


if __name__ == "__main__":
    main()
