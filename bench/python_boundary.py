"""The cost of the Python boundary: motile.velocity_autocorrelation on 1e6 points from Python
against the same call in Rust (analysis/examples/correlation_timing.rs), same data, same
session, medians of REPS calls. Needs `pip install ./python` and
`cargo build --release -p motile-analysis --example correlation_timing`.

    python3 bench/python_boundary.py [N] [REPS]
"""

import json
import os
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

import motile

root = Path(__file__).resolve().parents[1]
n = int(sys.argv[1]) if len(sys.argv) > 1 else 1_000_000
reps = int(sys.argv[2]) if len(sys.argv) > 2 else 5
box, modes, tol = 50.0, 25, 1e-6
rng = np.random.default_rng(1)
x = rng.uniform(0, box, (n, 3))
p = rng.normal(size=(n, 3))
u = p / np.linalg.norm(p, axis=1)[:, None] + 0.1 * np.sin(2 * np.pi * x[:, [1, 2, 0]] / box)
times = []
for _ in range(reps):
    t = time.perf_counter()
    r, c = motile.velocity_autocorrelation(x, u, box, modes=modes, tolerance=tol)
    times.append(time.perf_counter() - t)
py = sorted(times)[len(times) // 2]
with tempfile.NamedTemporaryFile(suffix=".f64", delete=False) as f:
    f.write(np.ascontiguousarray(np.hstack([x, u]), dtype="<f8").tobytes())
exe = root / "target" / "release" / "examples" / "correlation_timing"
out = subprocess.run([exe, f.name, str(box), str(modes), str(tol), str(reps)], check=True, capture_output=True, text=True)
os.unlink(f.name)
rs = json.loads(out.stdout)
assert rs["corr0"] == c[0], (rs["corr0"], c[0])
print(f"{n} points, {modes}^3 modes, tol {tol:g}, {os.cpu_count()} cores, median of {reps}:")
print(f"  Python motile.velocity_autocorrelation  {py:.4f} s")
print(f"  Rust   sampled_vector_coefficients      {rs['median_s']:.4f} s")
print(f"  ratio Python/Rust {py / rs['median_s']:.3f}; Corr(0) identical: {c[0]:.6e}")
