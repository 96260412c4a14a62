"""Step-time and communication model of the particle step shared among MPI ranks,
fitted to measurements on 1-2 ranks, projected to the paper's largest run.

Usage: python3 bench/mpi_model.py [RUN_1RANK RUN_2RANKS VALUES_SENT EXCHANGES]
  RUN_*: run directories of `motile particle run` on one rank and under `mpirun -n 2` of the
  same config (their timeseries.csv gives steps/s); VALUES_SENT, EXCHANGES: the
  "rank 0 of 2: E exchanges, V values" line the 2-rank run prints. Without arguments the figures
  measured for BENCHMARKS.md are used.

The model (hydrodynamics "none", z slabs):
  T(P) = t_rod (N/P + H) / e_node + E (alpha P) + c_V H 8 bytes / beta
  H    = 2 r N / L            copies per rank (two slab faces of width r = l + b + margin)
  t_rod                        seconds per rod and step on one core (fitted at P = 1)
  e_node                       speed-up of one rank's threads on a node (16 cores: 5.9, the
                               contact step's measured 16-thread figure, BENCHMARKS.md)
  E                            exchanges per step (measured), each an all-to-all: alpha P latency
  c_V                          values sent per copy per step (measured)
  alpha, beta                  interconnect latency and bandwidth (stated, not fitted):
                               HDR InfiniBand, 1.5 us, 25 GB/s.
The dipole level (function `dipole`) takes its per-point and per-grid-point costs from the
phases of the shared stresslet sum measured on 2 ranks, and the transposes' volume
9 fields x 16 bytes x M^3 / P per rank (six stresslet components there, three velocity
components back).
A cubic decomposition, not implemented, is shown for comparison: copies
  H_cube = (N/P) ((1 + 2 r / a)^3 - 1),  a = L / P^(1/3),
  with messages to 26 neighbours instead of P ranks.
"""

import sys

import numpy as np

R = 1.3  # contact reach l + b + margin
ALPHA = 1.5e-6
BETA = 25e9
E_NODE = 5.9


def steps_per_second(run):
    t = np.loadtxt(f"{run}/timeseries.csv", delimiter=",", skiprows=1)
    return float(np.mean(t[5:, 1]))


def main():
    n_meas, l_meas, steps = 20480, 16.0, 50
    if len(sys.argv) == 5:
        s1, s2 = steps_per_second(sys.argv[1]), steps_per_second(sys.argv[2])
        values, exchanges = float(sys.argv[3]), float(sys.argv[4])
    else:
        s1, s2, values, exchanges = 8.82, 12.01, 40361266.0, 3895.0
    h_meas = 2 * R * n_meas / l_meas
    t_rod = 1.0 / s1 / n_meas
    pred2 = t_rod * (n_meas / 2 + h_meas)
    c_v = values / steps / h_meas
    e = exchanges / steps
    print(f"fit: t_rod = {t_rod * 1e6:.2f} us per rod-step (1 rank, 1 thread)")
    print(
        f"check at 2 ranks: model {pred2 * 1e3:.1f} ms (copies cost as own rods, "
        f"communication on one node neglected), measured {1e3 / s2:.1f} ms"
    )
    print(f"measured: {e:.0f} exchanges per step, {c_v:.0f} values per copy per step")
    n = 20e6
    nu = 5.0
    big_l = (n / nu) ** (1 / 3)
    print(f"\nprojection: N = {n:.0e} rods, nu = {nu}, L/l = {big_l:.1f}, one rank per node")
    print("| nodes | own rods | copies (slabs) | compute | latency | volume | step (slabs) | copies (cubes) | step (cubes) |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for p in [8, 64, 512]:
        own = n / p
        h = 2 * R * n / big_l
        comp = t_rod * (own + h) / E_NODE
        lat = e * ALPHA * p
        vol = c_v * h * 8 / BETA
        a = big_l / p ** (1 / 3)
        h_cube = own * ((1 + 2 * R / a) ** 3 - 1)
        comp_c = t_rod * (own + h_cube) / E_NODE
        step_c = comp_c + e * ALPHA * 26 + c_v * h_cube * 8 / BETA
        print(
            f"| {p} | {own:.3g} | {h:.3g} | {comp:.3f} s | {lat * 1e3:.1f} ms | "
            f"{vol * 1e3:.1f} ms | {comp + lat + vol:.3f} s | {h_cube:.3g} | {step_c:.3f} s |"
        )


def dipole():
    """The dipole level: the shared stresslet sum's phases measured on 2 ranks (L/l = 25,
    nu = 0.625, 9 766 rods, 4 900 own points and 7 450 local ones per rank, grid 72^3, cutoff
    3.28 l, one thread per rank), per point and per grid point, projected the same way."""
    real, spread, gather, fft = 7.4e-6, 4.1e-6, 22e-6, 0.91e-6  # s per local pt, own pt, own pt, grid pt
    m_per_l, rc = 72 / 25, 3.28
    nu = 0.625
    print("\ndipole level, nu = 0.625, one rank per node (node speed-up 6.0: the 16-thread mobility product)")
    print("| L/l | rods | grid | nodes | own | copies | compute | transposes | step |")
    print("|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
    for big_l in [100, 175]:
        n = nu * big_l**3
        m = int(round(m_per_l * big_l))
        for p in [8, 64, 512]:
            own = n / p
            h = 2 * rc * n / big_l
            comp = (real * (own + h) + (spread + gather) * own + fft * m**3 / p) / 6.0
            trans = 9 * 16 * m**3 / p * (p - 1) / p / BETA + 2 * p * ALPHA
            note = "" if p <= m else " (more ranks than planes)"
            print(
                f"| {big_l} | {n:.3g} | {m}^3 | {p}{note} | {own:.3g} | {h:.3g} | "
                f"{comp:.3f} s | {trans * 1e3:.1f} ms | {comp + trans:.3f} s |"
            )


if __name__ == "__main__":
    main()
    dipole()
