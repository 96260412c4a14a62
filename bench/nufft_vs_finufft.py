#!/usr/bin/env python3
"""Side-by-side timing of motile's 3D NUFFT against FINUFFT.

For every (type, points, modes, tol, threads) combination this script
  * times FINUFFT in-process: a plan is built once, points are set, and
    `execute` is timed `reps` times after one warm-up ("plan reused"); one
    full one-shot call (nufft3d1 / nufft3d2) is timed as well;
  * runs motile's `nufft_timing` example as a subprocess, which prints one
    JSON line with its own median execute time and point-sorting time;
and prints one row per combination with the ratios motile / FINUFFT.

Build the motile side first:
    cargo build --release -p motile-analysis --example nufft_timing
Use `--motile-bin none` to time FINUFFT alone.
"""
import argparse
import json
import os
import platform
import statistics
import subprocess
import sys
import time

import finufft
import numpy as np

BUILD_HINT = "cargo build --release -p motile-analysis --example nufft_timing"
COLUMNS = ["type", "N", "M", "tol", "threads", "finufft_exec_s", "finufft_full_s",
           "motile_median_s", "motile_setpts_s", "exec_ratio", "full_ratio", "motile_rel_err"]


def parse_args():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--motile-bin", default="target/release/examples/nufft_timing",
                   help="path to motile's nufft_timing binary, or 'none' to skip motile")
    p.add_argument("--points", nargs="+", type=lambda s: int(float(s)), default=[100_000, 1_000_000])
    p.add_argument("--modes", nargs="+", type=int, default=[32, 64, 128])
    p.add_argument("--tols", nargs="+", type=float, default=[1e-3, 1e-6, 1e-9])
    p.add_argument("--threads", nargs="+", type=int, default=[1, 2])
    p.add_argument("--types", nargs="+", type=int, choices=[1, 2], default=[1, 2])
    p.add_argument("--reps", type=int, default=5)
    p.add_argument("--quick", action="store_true",
                   help="small run: points 1e5, modes 32, tol 1e-6, threads 1 2, types 1 2, reps 3")
    p.add_argument("--markdown", metavar="PATH", help="also write the table as Markdown to PATH")
    a = p.parse_args()
    if a.quick:
        a.points, a.modes, a.tols, a.threads, a.types, a.reps = [100_000], [32], [1e-6], [1, 2], [1, 2], 3
    return a


def make_data(nufft_type, n, m):
    """Uniform points in [0, 2pi)^3 and complex input (strengths or modes), seed 42."""
    rng = np.random.default_rng(42)
    x, y, z = (rng.uniform(0.0, 2.0 * np.pi, n) for _ in range(3))
    shape = (n,) if nufft_type == 1 else (m, m, m)
    data = rng.standard_normal(shape) + 1j * rng.standard_normal(shape)
    return x, y, z, data.astype(np.complex128)


def time_finufft(nufft_type, n, m, tol, threads, reps):
    """Return (median execute seconds with plan reused, seconds of one full one-shot call)."""
    x, y, z, data = make_data(nufft_type, n, m)
    isign = -1 if nufft_type == 1 else +1
    plan = finufft.Plan(nufft_type, (m, m, m), n_trans=1, eps=tol, isign=isign,
                        nthreads=threads, upsampfac=2.0)
    plan.setpts(x, y, z)
    plan.execute(data)  # warm-up
    times = []
    for _ in range(reps):
        t0 = time.perf_counter()
        plan.execute(data)
        times.append(time.perf_counter() - t0)
    del plan

    # One-shot call: plan creation + point sorting + execute + teardown.
    t0 = time.perf_counter()
    if nufft_type == 1:
        finufft.nufft3d1(x, y, z, data, (m, m, m), eps=tol, isign=isign, nthreads=threads, upsampfac=2.0)
    else:
        finufft.nufft3d2(x, y, z, data, eps=tol, isign=isign, nthreads=threads, upsampfac=2.0)
    full = time.perf_counter() - t0
    return statistics.median(times), full


def run_motile(binary, nufft_type, n, m, tol, threads, reps):
    """Run motile's timing example and return its parsed JSON record."""
    cmd = [binary, "--type", str(nufft_type), "--points", str(n), "--modes", str(m),
           "--tol", str(tol), "--threads", str(threads), "--reps", str(reps)]
    proc = subprocess.run(cmd, capture_output=True, text=True)
    if proc.returncode != 0:
        sys.exit(f"motile failed ({proc.returncode}): {' '.join(cmd)}\n{proc.stderr}")
    lines = [l for l in proc.stdout.splitlines() if l.lstrip().startswith("{")]
    if not lines:
        sys.exit(f"motile printed no JSON line: {' '.join(cmd)}\n{proc.stdout}\n{proc.stderr}")
    return json.loads(lines[-1])


def fmt(v, spec):
    return "-" if v is None else format(v, spec)


def main():
    a = parse_args()
    use_motile = a.motile_bin.lower() != "none"
    if use_motile and not os.path.isfile(a.motile_bin):
        print(f"motile binary not found: {a.motile_bin}\nBuild it with:\n    {BUILD_HINT}", file=sys.stderr)
        sys.exit(2)

    print(f"platform: {platform.platform()}  python {platform.python_version()}")
    print(f"cpus: {os.cpu_count()}  finufft {finufft.__version__}  numpy {np.__version__}")
    print(f"motile: {a.motile_bin if use_motile else '(skipped)'}  reps: {a.reps}  upsampfac: 2.0\n")

    widths = [4, 8, 4, 6, 7, 14, 14, 15, 15, 10, 10, 14]
    print(" ".join(c.rjust(w) for c, w in zip(COLUMNS, widths)), flush=True)

    rows = []
    for t in a.types:
        for n in a.points:
            for m in a.modes:
                for tol in a.tols:
                    for th in a.threads:
                        f_exec, f_full = time_finufft(t, n, m, tol, th, a.reps)
                        mo_med = mo_set = mo_err = exec_ratio = full_ratio = None
                        if use_motile:
                            rec = run_motile(a.motile_bin, t, n, m, tol, th, a.reps)
                            mo_med, mo_set, mo_err = rec["median_s"], rec.get("setpts_s"), rec.get("rel_err")
                            exec_ratio = mo_med / f_exec
                            full_ratio = (mo_med + (mo_set or 0.0)) / f_full
                        row = [str(t), str(n), str(m), f"{tol:.0e}", str(th),
                               fmt(f_exec, ".4f"), fmt(f_full, ".4f"), fmt(mo_med, ".4f"),
                               fmt(mo_set, ".4f"), fmt(exec_ratio, ".2f"), fmt(full_ratio, ".2f"),
                               fmt(mo_err, ".2e")]
                        rows.append(row)
                        print(" ".join(c.rjust(w) for c, w in zip(row, widths)), flush=True)

    print("\nexec_ratio = motile_median / finufft_exec (both with points already set);"
          "\nfull_ratio = (motile_median + motile_setpts) / finufft_full (one-shot call)")

    if a.markdown:
        with open(a.markdown, "w") as f:
            f.write(f"Machine: {platform.platform()}, {os.cpu_count()} CPUs, "
                    f"finufft {finufft.__version__}, numpy {np.__version__}\n\n")
            f.write("| " + " | ".join(COLUMNS) + " |\n")
            f.write("|" + "---:|" * len(COLUMNS) + "\n")
            for row in rows:
                f.write("| " + " | ".join(row) + " |\n")
        print(f"Markdown table written to {a.markdown}")


if __name__ == "__main__":
    main()
