"""How compressible are the degree-80 Bingham closure tables? (BENCHMARKS.md, mean-field step)

Reads the cached tables that `motile meanfield run` writes ($MOTILE_CACHE_DIR or
~/.cache/motile/bingham_degree80.bin) and prints, per table: the number of Chebyshev
coefficients above a threshold (and the largest i, j, i+j they reach), the numerical rank, and
the error of re-interpolating the global table on uniform K x K patches of degree m.
    python3 bench/closure_table_analysis.py
"""
import os
import numpy as np
from numpy.polynomial import chebyshev as C

cache = os.environ.get("MOTILE_CACHE_DIR", os.path.expanduser("~/.cache/motile"))
raw = open(os.path.join(cache, "bingham_degree80.bin"), "rb").read()
n = 81
c = np.frombuffer(raw[8:], dtype="<f8").reshape(4, n, n)  # c[f][i][j], T_i(2x-1) T_j(2y-1)
names = ["S1111", "S2222", "S1122", "entropy (regular part)"]

for f in range(4):
    a = np.abs(c[f])
    m = a.max()
    for thr in [1e-13, 1e-14]:
        s = a > thr * m
        ii, jj = np.where(s)
        print(f"{names[f]}: {s.sum()} of {n*n} coefficients above {thr:g} of the largest "
              f"(max i {ii.max()}, max j {jj.max()}, max i+j {(ii+jj).max()})")
    sv = np.linalg.svd(c[f], compute_uv=False)
    print(f"  numerical rank above 1e-14: {(sv > 1e-14).sum()}")

rng = np.random.default_rng(1)
xs = np.concatenate([rng.random(20000), rng.random(2000) * 1e-3, 1 - rng.random(2000) * 1e-3, rng.random(2000)])
ys = np.concatenate([rng.random(20000), rng.random(2000), rng.random(2000), rng.random(2000) * 1e-3])
for K, m in [(8, 16), (8, 24)]:
    nodes = np.cos(np.pi * (np.arange(m + 1) + 0.5) / (m + 1))
    Ti = np.linalg.inv(C.chebvander(nodes, m))
    err = 0.0
    for f in range(3):
        ref = C.chebval2d(2 * xs - 1, 2 * ys - 1, c[f])
        px = np.minimum((xs * K).astype(int), K - 1)
        py = np.minimum((ys * K).astype(int), K - 1)
        approx = np.empty_like(ref)
        for a_ in range(K):
            for b_ in range(K):
                X = (a_ + 0.5 * (nodes + 1)) / K
                Y = (b_ + 0.5 * (nodes + 1)) / K
                cc = Ti @ C.chebgrid2d(2 * X - 1, 2 * Y - 1, c[f]) @ Ti.T
                sel = (px == a_) & (py == b_)
                approx[sel] = C.chebval2d(2 * (xs[sel] * K - a_) - 1, 2 * (ys[sel] * K - b_) - 1, cc)
        err = max(err, np.abs(approx - ref).max())
    print(f"uniform {K}x{K} patches of degree {m}: max difference from the global table {err:.2e}")
