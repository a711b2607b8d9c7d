#!/usr/bin/env python3
"""Run `jello bench` and the peer implementations (bench/peers: Python, C, and Jello with each
SIMD tier forced) on the same scene, alternating Jello and each peer, and write BENCHMARKS.md. Normally started by scripts/benchmarks.sh, which
sets up the venv; run with that venv's python so the peers find their libraries.

    scripts/benchmarks.py [--seconds S] [--quick] [--only numpy,numba] [--rounds R] [--no-check]
"""

import argparse
import datetime
import json
import os
import platform
import statistics
import subprocess
import sys
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
from bench_sections import kept_sections  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
PEERS_DIR = os.path.join(ROOT, "bench", "peers")
JELLO = os.path.join(ROOT, "target", "release", "jello")
OUT = os.path.join(ROOT, "BENCHMARKS.md")
# Python peers, the C peers (bench/peers/c_peer.c through c_peer.py), and Jello itself with
# its SIMD tier forced by JELLO_SIMD (a tier the CPU lacks is reported, not run).
PEERS = ["numpy", "numba", "taichi", "warp", "c", "c-naive",
         "jello-baseline", "jello-avx2", "jello-avx512"]
LIBS = {"numpy": "numpy", "numba": "numba", "taichi": "taichi", "warp": "warp-lang"}
TIERS = [p for p in PEERS if p.startswith("jello-")]

# (size, integrator, threads)
CONFIGS = [(8, "RK4", 1), (8, "RK4", 2), (32, "RK4", 1), (32, "RK4", 2),
           (64, "RK4", 1), (64, "RK4", 2), (32, "Euler", 1), (32, "Euler", 2)]
QUICK_CONFIGS = [(8, "RK4", 1), (8, "RK4", 2), (32, "RK4", 1), (32, "RK4", 2),
                 (32, "Euler", 2)]


def log(msg):
    print(msg, file=sys.stderr, flush=True)


def sh(cmd):
    try:
        return subprocess.run(cmd, capture_output=True, text=True, timeout=60,
                              shell=isinstance(cmd, str)).stdout.strip()
    except Exception as e:  # noqa: BLE001
        return "unavailable (%s)" % e


def last_json(text):
    for line in reversed(text.splitlines()):
        line = line.strip()
        if line.startswith("{"):
            return json.loads(line)
    raise ValueError("no JSON object in the output")


def run_json(cmd, timeout, quiet=True, env=None):
    """Run a benchmark command; return (result dict, None) or (None, error text)."""
    if quiet:
        wait_quiet()
    try:
        r = subprocess.run(cmd, capture_output=True, text=True, timeout=timeout,
                           env=None if env is None else {**os.environ, **env})
    except subprocess.TimeoutExpired:
        return None, "timed out after %d s" % timeout
    except OSError as e:
        return None, str(e)
    if r.returncode != 0:
        lines = [ln for ln in (r.stderr + "\n" + r.stdout).splitlines() if ln.strip()]
        return None, "exit %d: %s" % (r.returncode, " | ".join(lines[-3:]) or "no output")
    try:
        return last_json(r.stdout), None
    except ValueError as e:
        return None, "%s: %s" % (e, r.stdout[-300:])


def cpu_busy(interval=0.5):
    """Fraction of all CPUs busy over `interval` seconds (from /proc/stat)."""
    def snap():
        with open("/proc/stat") as f:
            v = [int(x) for x in f.readline().split()[1:]]
        return sum(v), v[3] + v[4]  # total, idle + iowait
    t0, i0 = snap()
    time.sleep(interval)
    t1, i1 = snap()
    return 1.0 - (i1 - i0) / max(1, t1 - t0)


QUIET = {"busy_starts": 0, "runs": 0, "waited_s": 0.0}


def wait_quiet(max_wait=20.0, threshold=0.25, budget=180.0):
    """Before a run: wait (up to max_wait s) until other processes leave the CPUs idle, so that
    outside load (a build, a browser) disturbs as few runs as possible; count the runs that had
    to start on a busy machine anyway."""
    QUIET["runs"] += 1
    if not os.path.exists("/proc/stat"):
        return
    start = time.time()
    while cpu_busy() > threshold:
        if time.time() - start > max_wait or QUIET["waited_s"] + time.time() - start > budget:
            QUIET["busy_starts"] += 1
            break
    QUIET["waited_s"] += time.time() - start


def jello_cmd(size, integ, threads, seconds):
    return [JELLO, "bench", "--size", str(size), "--integrator", integ, "--threads",
            str(threads), "--seconds", str(seconds), "--json"]


def peer_cmd(peer, size, integ, threads, seconds):
    """The command of a peer and the environment it adds."""
    if peer in TIERS:
        return jello_cmd(size, integ, threads, seconds), {"JELLO_SIMD": peer[len("jello-"):]}
    variant = []
    if peer in ("c", "c-naive"):
        peer, variant = "c", ["--variant", "naive" if peer == "c-naive" else "simd"]
    return [sys.executable, os.path.join(PEERS_DIR, peer + "_peer.py"), "--size", str(size),
            "--integrator", integ, "--threads", str(threads), "--seconds", str(seconds),
            "--json"] + variant, None


def jello_available():
    if not os.path.exists(JELLO):
        return "target/release/jello does not exist (build: cargo build --release -p jello-cli)"
    try:
        r = subprocess.run([JELLO, "bench", "--help"], capture_output=True, text=True,
                           timeout=30)
    except Exception as e:  # noqa: BLE001
        return "jello bench --help failed: %s" % e
    if r.returncode != 0:
        return "`jello bench` is not available in this build: %s" % (
            (r.stderr or r.stdout).strip().splitlines() or ["?"])[-1]
    return None


def machine():
    info = {}
    cpu = open("/proc/cpuinfo").read() if os.path.exists("/proc/cpuinfo") else ""
    model = next((ln.split(":", 1)[1].strip() for ln in cpu.splitlines()
                  if ln.startswith("model name")), platform.processor() or "unknown")
    flags = next((ln.split(":", 1)[1].split() for ln in cpu.splitlines()
                  if ln.startswith("flags")), [])
    info["CPU"] = model
    avx512 = sorted(f for f in flags if f.startswith("avx512"))
    info["AVX-512"] = ("yes (%s)" % ", ".join(avx512)) if avx512 else "no"
    info["AVX2 / FMA"] = "%s / %s" % ("yes" if "avx2" in flags else "no",
                                      "yes" if "fma" in flags else "no")
    info["cores (logical CPUs available)"] = str(len(os.sched_getaffinity(0)))
    mem = sh("grep MemTotal /proc/meminfo")
    if mem.split()[1:2]:
        info["memory"] = "%.1f GiB" % (int(mem.split()[1]) / 1048576)
    osname = "unknown"
    if os.path.exists("/etc/os-release"):
        for ln in open("/etc/os-release"):
            if ln.startswith("PRETTY_NAME="):
                osname = ln.split("=", 1)[1].strip().strip('"')
    info["OS"] = "%s, Linux %s" % (osname, platform.release())
    info["rustc"] = sh(["rustc", "--version"])
    info["Python"] = platform.python_version()
    info["load average at start"] = " ".join(open("/proc/loadavg").read().split()[:3])
    info["date"] = datetime.datetime.now().astimezone().strftime("%Y-%m-%d %H:%M %Z")
    info["git commit"] = sh(["git", "-C", ROOT, "rev-parse", "--short", "HEAD"]) + (
        " (with uncommitted changes)" if sh(["git", "-C", ROOT, "status", "--porcelain",
                                             "--untracked-files=no"]) else "")
    return info


def lib_versions(peers):
    try:
        from importlib import metadata
    except ImportError:
        return {}
    out = {}
    for p in peers:
        if p not in LIBS:
            continue
        try:
            out[LIBS[p]] = metadata.version(LIBS[p])
        except Exception:  # noqa: BLE001
            out[LIBS[p]] = "not installed"
    for extra in ("llvmlite",):
        try:
            out[extra] = metadata.version(extra)
        except Exception:  # noqa: BLE001
            pass
    return out


def springs_of(n):
    return 3 * n * n * (n - 1) + 6 * n * (n - 1) ** 2 + 4 * (n - 1) ** 3 + 3 * n * n * (n - 2)


def fmt(x, digits=3):
    if x is None:
        return "–"
    if x >= 1e6:
        return "%.*g M" % (digits, x / 1e6)
    if x >= 100:
        return "%.0f" % x
    return "%.*g" % (digits, x)


def median(xs):
    return statistics.median(xs) if xs else None


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seconds", type=float, default=None, help="timed seconds per run (3)")
    ap.add_argument("--quick", action="store_true", help="1 s per run and fewer configurations")
    ap.add_argument("--only", default=None, help="comma-separated peers, e.g. numpy,numba")
    ap.add_argument("--rounds", type=int, default=2, help="Jello/peer pairs per peer (2)")
    ap.add_argument("--no-check", action="store_true", help="skip the correctness check")
    ap.add_argument("--out", default=OUT)
    args = ap.parse_args()
    seconds = args.seconds if args.seconds is not None else (1.0 if args.quick else 3.0)
    configs = QUICK_CONFIGS if args.quick else CONFIGS
    peers = PEERS if not args.only else [p.strip() for p in args.only.split(",") if p.strip()]
    for p in peers:
        if p not in PEERS:
            ap.error("unknown peer %r; known: %s" % (p, ", ".join(PEERS)))
    timeout = int(120 + 10 * seconds)

    info = machine()
    versions = lib_versions(peers)
    jello_missing = jello_available()
    if jello_missing:
        log("WARNING: %s; showing the peers' numbers alone" % jello_missing)
    else:
        info["jello"] = sh([JELLO, "--version"]) or "?"

    failure_log = os.path.join(ROOT, "bench", ".venv", "pip-failures.log")
    install_failures = open(failure_log).read().strip() if os.path.exists(failure_log) else ""

    # Correctness first: cheap, and a wrong peer's speed means nothing.
    check = None
    if not args.no_check:
        log("correctness check (bench/peers/check.py)...")
        cmd = [sys.executable, os.path.join(PEERS_DIR, "check.py"), "--only", ",".join(peers),
               "--sizes", "8" if args.quick else "8,5"]
        if not jello_missing:
            cmd += ["--jello", JELLO]
        check, err = run_json(cmd, timeout=1800, quiet=False)
        if err:
            check = {"error": err}

    results = []  # one dict per configuration
    broken = {}   # peer -> first error, so a peer that cannot start is not retried forever
    for size, integ, threads in configs:
        cfg = {"size": size, "integrator": integ, "threads": threads,
               "jello": [], "jello_err": None, "peers": {}}
        for peer in peers:
            pr = cfg["peers"][peer] = {"runs": [], "err": None, "meta": None}
            for rnd in range(args.rounds):
                if not jello_missing:
                    log("N=%d %s T=%d  round %d  jello" % (size, integ, threads, rnd + 1))
                    j, err = run_json(jello_cmd(size, integ, threads, seconds), timeout)
                    if j:
                        cfg["jello"].append(j)
                    else:
                        cfg["jello_err"] = err
                        log("  jello failed: " + err)
                if peer in broken:
                    pr["err"] = broken[peer]
                    break
                log("N=%d %s T=%d  round %d  %s" % (size, integ, threads, rnd + 1, peer))
                cmd, env = peer_cmd(peer, size, integ, threads, seconds)
                r, err = run_json(cmd, timeout, env=env)
                if r:
                    pr["runs"].append(r)
                    pr["meta"] = r
                else:
                    pr["err"] = err
                    log("  %s failed: %s" % (peer, err))
                    if ("No module named" in err or "ImportError" in err
                            or "cannot run the" in err):
                        broken[peer] = err
                    break
        results.append(cfg)

    info["load average at end"] = " ".join(open("/proc/loadavg").read().split()[:3])
    info["outside load"] = (
        "before each run the script waited (at most 20 s per run, 180 s in all) for the CPUs to be idle (< 25 %% busy "
        "over 0.5 s); %d of %d runs had to start on a busy machine; %.0f s spent waiting"
        % (QUIET["busy_starts"], QUIET["runs"], QUIET["waited_s"]))
    write_md(args, seconds, configs, peers, info, versions, jello_missing, install_failures,
             check, results)
    log("wrote " + args.out)


def write_md(args, seconds, configs, peers, info, versions, jello_missing, install_failures,
             check, results):
    L = []
    w = L.append
    w("# Benchmarks: Jello and its peers")
    w("")
    w("Generated by `scripts/benchmarks.sh%s` on %s. Do not edit by hand: run the command again (the last section, [kept by hand](#measurements-kept-by-hand), is the exception)." % (
        (" " + " ".join(sys.argv[1:])) if sys.argv[1:] else "", info["date"]))
    w("")
    w("Regenerate with `scripts/benchmarks.sh` (the full run: about 15 minutes on an idle 2-core machine, 20 under load); "
      "`scripts/benchmarks.sh --quick` (1 s runs, fewer configurations) or "
      "`scripts/benchmarks.sh --only numpy,numba` for a subset. The script makes (or reuses) a "
      "virtual environment in `bench/.venv` with the pinned `bench/peers/requirements.txt`, "
      "builds `target/release/jello` and runs `scripts/benchmarks.py`.")
    w("")
    if jello_missing:
        w("> **Jello was not measured:** %s. The tables show the peers alone." % jello_missing)
        w("")
    if QUIET["runs"] and QUIET["busy_starts"] > 0.25 * QUIET["runs"]:
        w("> **Outside load:** %d of %d runs started while other processes kept the CPUs busy "
          "(see *outside load* under Machine). Absolute numbers and especially the 2-thread "
          "runs (Numba's OpenMP threads suffer most) are disturbed; rerun on an idle machine "
          "before quoting them." % (QUIET["busy_starts"], QUIET["runs"]))
        w("")
    w("## Method")
    w("")
    w("* **Scene** (the same in every implementation: `jello bench`, "
      "`crates/jello-core/src/scenes.rs`, `bench/peers/common.py`): an N×N×N lattice of side 1 "
      "(spacing 1/(N−1)) centred at the origin; the springs of [docs/spec.md](docs/spec.md) (structural, 12 face + 8 "
      "body shear, bend; each pair once; rest lengths from the rest grid) with kElastic 200, "
      "dElastic 0.25; the box [−2, 2]³ with penalty springs kCollision 400, dCollision 0.25; mass "
      "1/512 per point at every N; every point starting at velocity (10, −10, 20); gravity "
      "(0, 0, −9.81·mass) on every point; no plane; dt 0.0005 s; float64 everywhere. Springs: "
      "3N²(N−1) structural + 6N(N−1)² face shear + 4(N−1)³ body shear + 3N²(N−2) bend = %s."
      % ", ".join("{:,} at N = {}".format(springs_of(n), n)
                  for n in sorted({c[0] for c in configs})))
    w("* **Work measured**: *steps/s* of the whole integrator step, and *spring evaluations/s* = "
      "springs × force evaluations per step (4 for RK4, 1 for Euler) × steps/s, which makes "
      "sizes comparable.")
    w("* **Each run** is a fresh process: build the scene, compile (JIT peers), warm up "
      "(compile + about 0.5 s of steps), then step for about %g s in batches of about 50 ms and "
      "report steps / elapsed time. Compile time is not counted." % seconds)
    w("* **Alternation**: for each configuration and each peer, %d rounds of the pair "
      "(Jello, peer), so that drift of the machine (turbo, other load) affects both. The value "
      "shown is the median over rounds (Jello: over all its runs in that configuration). "
      "Ratio = Jello / peer: above 1 means Jello is faster." % args.rounds)
    w("* **Threads**: `--threads T` is passed to every implementation. Jello uses T worker "
      "threads; Numba `numba.set_num_threads(T)` (and NUMBA_NUM_THREADS); Taichi "
      "`ti.init(cpu_max_num_threads=T)`; NumPy's element-wise operations are single-threaded "
      "whatever T is (OMP/MKL/OpenBLAS variables are set but unused); Warp runs CPU kernels on "
      "one thread. The tables mark a peer that ignores T.")
    w("* **Peers** (bench/peers/*_peer.py), each reasonably fast in its own idiom, each spring "
      "evaluated once per force evaluation:")
    w("  * *NumPy*: the 16 stencil offsets are strided slice pairs of the 3-D grid, so each "
      "offset's springs are whole-array operations and forces are scattered with slice adds "
      "(2–3× faster here than the flat spring list with `np.bincount` scatter, which is kept "
      "as `--variant scatter` and used as the correctness reference).")
    w("  * *Numba*: `@njit(parallel=True)`; the spring list is split into one chunk per thread, "
      "each with a private force buffer (no atomics, which Numba lacks), then a parallel loop "
      "over points sums the buffers and forms the next RK stage; the step loop is compiled too.")
    w("  * *Taichi*: CPU backend, a kernel over springs with atomic adds into a force field, a "
      "kernel over points for walls, gravity and the stage update.")
    w("  * *Warp*: device \"cpu\", the same two kernels with `wp.atomic_add`/`wp.atomic_sub`.")
    w("  * *c* (`bench/peers/c_peer.c`, built by `c_peer.py` with `gcc -O3 -march=native "
      "-fopenmp -fno-math-errno`, driven through ctypes; without the last flag GCC leaves the "
      "spring loop scalar): the hand-vectorised C baseline. Structure of arrays; "
      "per point plane and stencil offset, each row of springs is one `#pragma omp simd` loop "
      "into a row buffer, then added to the first ends and subtracted from the second; OpenMP "
      "threads take planes in three phases (i mod 3) so no two write the same plane.")
    w("  * *c-naive*: the textbook C loop over one flat spring list, arrays of 3-vectors, one "
      "thread, same flags.")
    w("  * *jello-baseline*, *jello-avx2*, *jello-avx512*: Jello itself with its SIMD tier "
      "forced by `JELLO_SIMD` (the plain *Jello* column runs the best tier the CPU has, which "
      "`jello bench --json` reports). A tier the CPU lacks is listed as failed. Every tier "
      "computes the same bits (tests compare saved states byte for byte).")
    w("")
    w("## Machine")
    w("")
    w("| | |")
    w("| --- | --- |")
    for k, v in info.items():
        w("| %s | %s |" % (k, v))
    for k, v in versions.items():
        w("| %s | %s |" % (k, v))
    w("")
    if install_failures:
        w("**Install failures** (from `bench/.venv/pip-failures.log`):")
        w("")
        w("```")
        w(install_failures[-3000:])
        w("```")
        w("")

    w("## Correctness")
    w("")
    if check is None:
        w("Skipped (`--no-check`).")
    elif "error" in check:
        w("The check failed to run: `%s`" % check["error"])
    else:
        w("`bench/peers/check.py`: every implementation steps the scene %d steps (including the "
          "first wall contacts) and its final state is compared with the plain NumPy reference "
          "(flat spring list, bincount scatter). Jello is compared through a world file: "
          "`jello create` writes the 8³ scene (gravity as a res-2 field, offset −0.5, velocity "
          "(10, −10, 20)), `jello run --steps %d --save` steps it. Tolerance on positions: %g m."
          % (check["steps"], check["steps"], check["tol"]))
        w("")
        w("| implementation | N | integrator | max \\|Δposition\\| (m) | max \\|Δvelocity\\| (m/s) | |")
        w("| --- | --- | --- | --- | --- | --- |")
        for r in check["rows"]:
            if "error" in r:
                w("| %s | %d | %s | – | – | **error**: %s |" % (
                    r["impl"], r["size"], r["integrator"], r["error"].replace("|", "\\|")))
            else:
                w("| %s | %d | %s | %.1e | %.1e | %s |" % (
                    r["impl"], r["size"], r["integrator"], r["max_dpos"], r["max_dvel"],
                    "ok" if r["ok"] else "**MISMATCH**"))
    w("")

    w("## Results")
    w("")
    w("Spring evaluations per second (median of rounds); ratio = Jello / peer.")
    w("")
    head = "| N | integrator | threads | springs | Jello |"
    sep = "| --- | --- | --- | --- | --- |"
    for p in peers:
        head += " %s | Jello / %s |" % (p, p)
        sep += " --- | --- |"
    for metric, title in (("spring_evals_per_s", "Spring evaluations / s"),
                          ("steps_per_s", "Steps / s")):
        w("### " + title)
        w("")
        w(head)
        w(sep)
        for cfg in results:
            jv = median([j[metric] for j in cfg["jello"]])
            springs = cfg["jello"][0]["springs"] if cfg["jello"] else next(
                (pr["meta"]["springs"] for pr in cfg["peers"].values() if pr["meta"]), None)
            jcell = fmt(jv) if jv is not None else (
                "not run" if jello_missing else "failed")
            row = "| %d | %s | %d | %s | %s |" % (cfg["size"], cfg["integrator"], cfg["threads"],
                                                  "{:,}".format(springs) if springs else "?",
                                                  jcell)
            for p in peers:
                pr = cfg["peers"][p]
                pv = median([r[metric] for r in pr["runs"]])
                if pv is None:
                    row += " failed | – |"
                    continue
                mark = ""
                meta = pr["meta"]
                if meta.get("threads_used", cfg["threads"]) != cfg["threads"]:
                    mark = " (%d thr.)" % meta["threads_used"]
                if springs and meta["springs"] != springs:
                    mark += " **spring count %d differs**" % meta["springs"]
                if not all(r.get("final_finite", True) for r in pr["runs"]):
                    mark += " **non-finite state**"
                ratio = ("%.2f" % (jv / pv)) if jv else "–"
                row += " %s%s | %s |" % (fmt(pv), mark, ratio)
            w(row)
        w("")
    w("\"(1 thr.)\" marks a peer that ran on one thread although more were asked for. "
      "M = millions.")
    w("")
    tiers = [t for t in TIERS if t in peers]
    if tiers and any(c in peers for c in ("c", "c-naive")):
        w("### Jello's SIMD tiers against the C baselines")
        w("")
        w("Spring evaluations / s of each tier over those of the C peers in the same "
          "configuration (each measured alternated with Jello's best tier, medians of rounds).")
        w("")
        cs = [c for c in ("c", "c-naive") if c in peers]
        w("| N | integrator | threads | " + " | ".join(
            "%s / %s" % (t, c) for t in tiers for c in cs) + " |")
        w("| --- | --- | --- | " + " | ".join("---" for _ in tiers for _ in cs) + " |")
        for cfg in results:
            def val(p):
                return median([r["spring_evals_per_s"] for r in cfg["peers"][p]["runs"]])
            cells = []
            for t in tiers:
                for c in cs:
                    tv, cv = val(t), val(c)
                    cells.append("%.2f" % (tv / cv) if tv and cv else "–")
            w("| %d | %s | %d | %s |" % (cfg["size"], cfg["integrator"], cfg["threads"],
                                         " | ".join(cells)))
        w("")

    errors = []
    # A peer that failed the same way everywhere (a tier this CPU lacks) is listed once.
    same_everywhere = {p for p in peers
                       if len({cfg["peers"][p]["err"] for cfg in results}) == 1
                       and results[0]["peers"][p]["err"]}
    for p in sorted(same_everywhere):
        errors.append("* %s, every configuration: `%s`" % (p, results[0]["peers"][p]["err"]))
    for cfg in results:
        tag = "N=%d %s threads=%d" % (cfg["size"], cfg["integrator"], cfg["threads"])
        if cfg["jello_err"]:
            errors.append("* Jello, %s: `%s`" % (tag, cfg["jello_err"]))
        for p in peers:
            if cfg["peers"][p]["err"] and p not in same_everywhere:
                errors.append("* %s, %s: `%s`" % (p, tag, cfg["peers"][p]["err"]))
    if errors:
        w("## Failures")
        w("")
        L.extend(errors)
        w("")

    w("## Raw runs")
    w("")
    w("Steps/s of every run, in the order they ran (Jello's runs are interleaved with each "
      "peer's), and the peers' compile times.")
    w("")
    w("| N | integrator | threads | Jello runs | peer: runs (compile s) |")
    w("| --- | --- | --- | --- | --- |")
    for cfg in results:
        js = ", ".join("%.4g" % j["steps_per_s"] for j in cfg["jello"]) or "–"
        ps = "; ".join("%s: %s (%s)" % (
            p, ", ".join("%.4g" % r["steps_per_s"] for r in cfg["peers"][p]["runs"]) or "–",
            ", ".join("%.1f" % r.get("compile_s", 0) for r in cfg["peers"][p]["runs"]) or "–")
            for p in peers)
        w("| %d | %s | %d | %s | %s |" % (cfg["size"], cfg["integrator"], cfg["threads"], js, ps))
    w("")
    # The sections scripts/frame-rate.sh and scripts/pile-bench.sh write (Jello against Rapier)
    # are separate runs, and the measurements kept by hand each have their date and machine:
    # keep them.
    old = open(args.out).read() if os.path.exists(args.out) else ""
    for kept in kept_sections(old):
        L.append(kept)
        w("")
    tmp = args.out + ".tmp"
    with open(tmp, "w") as f:
        f.write("\n".join(L))
    os.replace(tmp, args.out)


if __name__ == "__main__":
    main()
