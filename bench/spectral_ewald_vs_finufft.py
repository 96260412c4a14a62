#!/usr/bin/env python3
"""The same spectral Ewald RPY product as motile (particle/src/spectral_ewald.rs), written on
FINUFFT and numpy, side by side with motile in one run.

For each (points, tolerance) this script runs motile's `ewald_export` example (which writes its
random points, forces, result, parameters and timings; its timed calls alternate between two
point sets, so each prepares its points like the peer's calls do), then computes the same sum
in Python with the same splitting parameter and cutoff:
  * Fourier part: FINUFFT type 1 (isign -1) and type 2 (isign +1), upsampfac 2, on the modes
    with |k| <= k_max (motile instead spreads with Gaussians onto a grid of about that many
    points, no upsampling), two real force components packed per complex transform,
    Hermitian unpacking, the Hasimoto/RPY multiplier;
  * real space: a numpy cell list (cells of side >= r_c/2, 5^3 stencil, padded cells), the
    real-space kernel from a table of the smooth Fourier part (as motile does), self term.
It prints the relative L2 difference between the two results (an independent check of motile's
code) and the time ratios motile / peer per stage.

    cargo build --release -p motile-particle --example ewald_export
    python3 bench/spectral_ewald_vs_finufft.py --points 1e4 1e5 --tols 1e-3 1e-6
"""
import argparse
import json
import math
import subprocess
import tempfile
import time
from pathlib import Path

import finufft
import numpy as np

PI32 = math.pi ** 1.5


def rpy_real(r, xi, a):
    a2, r2, x2 = a * a, r * r, xi * xi
    ec = math.erfc(xi * r)
    e = math.exp(-x2 * r2)
    x4 = x2 * x2
    a4 = a2 * a2
    pa = (-4 * a4 * r2 * r2 * x4 * x4 + 22 * a4 * r2 * x4 * x2 - 14 * a4 * x4
          - 12 * a2 * r2 * x4 + 24 * a2 * x2 - 9)
    pb = 4 * a4 * r2 * r2 * x4 * x4 - 18 * a4 * r2 * x4 * x2 + 12 * a2 * r2 * x4 - 12 * a2 * x2 + 9
    g = xi * e / PI32
    c = ec / (math.pi * r * r2)
    return (c * (r2 / 8 + a2 / 12) + g * (a2 / (6 * r2) + pa / 36),
            c * (r2 / 8 - a2 / 4) + g * (-a2 / (2 * r2) + pb / 36))


def rpy_far(r, a):
    return ((1 / r + 2 * a * a / (3 * r ** 3)) / (8 * math.pi),
            (1 / r - 2 * a * a / r ** 3) / (8 * math.pi))


def fourier_free_series(r, xi, a):
    a2, x2, r2 = a * a, xi * xi, r * r
    a4 = a2 * a2
    c = xi / PI32
    aa = [0.5 + 7 * a4 * x2 * x2 / 18 - 5 * a2 * x2 / 9,
          -a4 * x2 ** 3 + 14 * a2 * x2 * x2 / 15 - x2 / 3,
          11 * a4 * x2 ** 4 / 12 - 9 * a2 * x2 ** 3 / 14 + 3 * x2 * x2 / 20,
          -13 * a4 * x2 ** 5 / 27 + 22 * a2 * x2 ** 4 / 81 - x2 ** 3 / 21]
    bb = [a4 * x2 ** 3 / 2 - 7 * a2 * x2 * x2 / 15 + x2 / 6,
          -11 * a4 * x2 ** 4 / 18 + 3 * a2 * x2 ** 3 / 7 - x2 * x2 / 10,
          13 * a4 * x2 ** 5 / 36 - 11 * a2 * x2 ** 4 / 54 + x2 ** 3 / 28,
          -5 * a4 * x2 ** 6 / 36 + 13 * a2 * x2 ** 5 / 198 - x2 ** 4 / 108]
    h = lambda k: k[0] + r2 * (k[1] + r2 * (k[2] + r2 * k[3]))
    return c * h(aa), c * h(bb)


def table(rc, xi, a, n=4096):
    h = rc / n
    g = np.empty((n + 1, 2))
    for k in range(n + 1):
        r = k * h
        if xi * r < 0.05:
            g[k] = fourier_free_series(r, xi, a)
        else:
            af, bf = rpy_far(r, a)
            ar, br = rpy_real(r, xi, a)
            g[k] = (af - ar, (bf - br) / (r * r))
    return g, 1.0 / h


def real_space(y, f, L, rc, xi, a):
    """Sum over neighbours within rc (minimum image), self excluded, with padded cells."""
    g, inv_h = table(rc, xi, a)
    ntab = g.shape[0] - 1
    n = max(int(math.floor(2 * L / rc)), 1)
    if n < 5:
        n = 1  # one cell, every pair by minimum image (the stencil would repeat cells)
    reach = range(-2, 3) if n >= 5 else range(0, 1)
    idx = np.minimum((y / L * n).astype(np.int64), n - 1)
    cell = (idx[:, 2] * n + idx[:, 1]) * n + idx[:, 0]
    order = np.argsort(cell, kind="stable")
    counts = np.bincount(cell, minlength=n ** 3)
    cap = counts.max()
    start = np.concatenate([[0], np.cumsum(counts)])
    slot = np.arange(len(y)) - start[cell[order]]
    P = np.full((n ** 3, cap, 3), 1e9)
    F = np.zeros((n ** 3, cap, 3))
    P[cell[order], slot] = y[order]
    F[cell[order], slot] = f[order]
    P3 = P.reshape(n, n, n, cap, 3)
    F3 = F.reshape(n, n, n, cap, 3)
    U = np.zeros((n ** 3, cap, 3))
    rc2 = rc * rc
    c8 = 1 / (8 * math.pi)
    a2 = a * a
    for dz in reach:
        for dy in reach:
            for dx in reach:
                Pn = np.roll(P3, shift=(-dz, -dy, -dx), axis=(0, 1, 2)).reshape(n ** 3, cap, 3)
                Fn = np.roll(F3, shift=(-dz, -dy, -dx), axis=(0, 1, 2)).reshape(n ** 3, cap, 3)
                for c0 in range(0, n ** 3, 512):
                    c1 = min(c0 + 512, n ** 3)
                    r = P[c0:c1, :, None, :] - Pn[c0:c1, None, :, :]
                    r -= L * np.round(r / L)
                    r2 = np.einsum("abcd,abcd->abc", r, r)
                    m = (r2 < rc2) & (r2 > 0)
                    if not m.any():
                        continue
                    rn = np.sqrt(np.where(m, r2, 1.0))
                    x = rn * inv_h
                    i = np.clip(x.astype(np.int64) - 1, 0, ntab - 3)
                    t = x - i
                    w = [-(t - 1) * (t - 2) * (t - 3) / 6, t * (t - 2) * (t - 3) / 2,
                         -t * (t - 1) * (t - 3) / 2, t * (t - 1) * (t - 2) / 6]
                    af = sum(w[q] * g[i + q, 0] for q in range(4))
                    bf = sum(w[q] * g[i + q, 1] for q in range(4))
                    inv = 1 / rn
                    A = c8 * (inv + 2 * a2 / 3 * inv ** 3) - af
                    B = c8 * (inv - 2 * a2 * inv ** 3) - bf * r2
                    # Overlapping spheres (r < 2a): M_overlap - M_far.
                    ov = m & (rn < 2 * a)
                    if ov.any():
                        c6 = 1 / (6 * math.pi * a)
                        A = np.where(ov, c6 * (1 - 9 * rn / (32 * a)) - c8 * (inv + 2 * a2 / 3 * inv ** 3) + A, A)
                        B = np.where(ov, c6 * 3 * rn / (32 * a) - c8 * (inv - 2 * a2 * inv ** 3) + B, B)
                    A = np.where(m, A, 0.0)
                    B = np.where(m, B, 0.0)
                    fj = np.broadcast_to(Fn[c0:c1, None, :, :], r.shape)
                    rdotf = np.einsum("abcd,abcd->abc", r, fj) / (rn * rn)
                    U[c0:c1] += np.einsum("abc,abcd->abd", A, fj) + np.einsum("abc,abcd->abd", B * rdotf, r)
    u = np.empty_like(y)
    u[order] = U[cell[order], slot]
    return u


def fourier(y, f, L, xi, a, K, eps, threads):
    x = [2 * np.pi * (y[:, d] % L) / L for d in range(3)]
    packed = np.stack([f[:, 0] + 1j * f[:, 1], f[:, 2] + 0j])
    p1 = finufft.Plan(1, (K, K, K), n_trans=2, eps=eps, isign=-1, upsampfac=2.0, nthreads=threads)
    p1.setpts(*x)
    C = p1.execute(packed)
    m = np.arange(K) - K // 2
    k = 2 * np.pi * m / L
    kx, ky, kz = np.meshgrid(k, k, k, indexing="ij")
    k2 = kx ** 2 + ky ** 2 + kz ** 2
    mirror = lambda A: np.conj(A[..., ::-1, ::-1, ::-1])  # valid away from the -K/2 planes
    Cm = np.roll(mirror(C), shift=(1, 1, 1), axis=(1, 2, 3))
    Fx = 0.5 * (C[0] + Cm[0])
    Fy = -0.5j * (C[0] - Cm[0])
    Fz = 0.5 * (C[1] + Cm[1])
    with np.errstate(divide="ignore", invalid="ignore"):
        xx = k2 / (4 * xi * xi)
        s = (1 + xx) * np.exp(-xx) * (1 - a * a * k2 / 6) ** 2 / k2 / L ** 3
        kf = (kx * Fx + ky * Fy + kz * Fz) / k2
        ux, uy, uz = [(F - kd * kf) * s for F, kd in ((Fx, kx), (Fy, ky), (Fz, kz))]
    for arr in (ux, uy, uz):
        arr[0, :, :] = arr[:, 0, :] = arr[:, :, 0] = 0
        arr[K // 2, K // 2, K // 2] = 0
    p2 = finufft.Plan(2, (K, K, K), n_trans=2, eps=eps, isign=1, upsampfac=2.0, nthreads=threads)
    p2.setpts(*x)
    out = p2.execute(np.stack([ux + 1j * uy, uz + 0j]))
    return np.stack([out[0].real, out[0].imag, out[1].real], axis=1)


def peer(d, threads):
    prm = json.loads((d / "params.json").read_text())
    n = prm["n"]
    y = np.fromfile(d / "points.f64").reshape(n, 3)
    f = np.fromfile(d / "forces.f64").reshape(n, 3)
    u_m = np.fromfile(d / "u.f64").reshape(n, 3)
    L, a, xi, rc, K, eps = (prm[k] for k in ("box_length", "radius", "xi", "cutoff", "modes", "nufft_tol"))
    t0 = time.perf_counter()
    ur = real_space(y, f, L, rc, xi, a)
    t1 = time.perf_counter()
    uf = fourier(y, f, L, xi, a, K, eps, threads)
    # Self term: the Fourier part's own contribution, A_F(0) f.
    a0 = xi * (7 * a ** 4 * xi ** 4 - 10 * a * a * xi * xi + 9) / (18 * PI32)
    u = ur + uf - a0 * f
    t2 = time.perf_counter()
    err = np.linalg.norm(u - u_m) / np.linalg.norm(u_m)
    return prm, (t1 - t0, t2 - t1, t2 - t0), err


def main():
    p = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    p.add_argument("--bin", default="target/release/examples/ewald_export")
    p.add_argument("--points", nargs="+", type=lambda s: int(float(s)), default=[1000, 10_000, 100_000])
    p.add_argument("--tols", nargs="+", type=float, default=[1e-3, 1e-6])
    p.add_argument("--density", type=float, default=2.5, help="points per unit volume (4 per rod at nu = 0.625)")
    p.add_argument("--threads", type=int, default=2)
    args = p.parse_args()
    print("| points | tol | motile s (real / Fourier) | peer s (real numpy / Fourier FINUFFT) | "
          "ratio total | ratio Fourier | |u_motile - u_peer| / |u| |")
    print("|---|---|---|---|---|---|---|")
    for n in args.points:
        for tol in args.tols:
            with tempfile.TemporaryDirectory() as tmp:
                subprocess.run([args.bin, str(n), str(tol), str(args.density), tmp, "3"],
                               check=True, capture_output=True)
                prm, (tr, tf, tt), err = peer(Path(tmp), args.threads)
            print(f"| {n} | {tol:.0e} | {prm['median_s']:.4f} ({prm['real_s']:.4f} / {prm['fourier_s']:.4f}) | "
                  f"{tt:.4f} ({tr:.4f} / {tf:.4f}) | {prm['median_s'] / tt:.2f} | "
                  f"{prm['fourier_s'] / tf:.2f} | {err:.2e} |", flush=True)


if __name__ == "__main__":
    main()
