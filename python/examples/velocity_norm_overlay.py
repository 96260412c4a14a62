"""The demo's velocity norm in both models on one chart, from Python (docs/python.md).

    motile demo --out runs/demo                     # the README's first command
    python3 python/examples/velocity_norm_overlay.py runs/demo docs/gallery/python_velocity_norm.png

Particle quantities are converted to the mean-field units (docs/MODEL.md §5):
t_mf = t_p nu / (8 eta), u_mf = (u_p / (beta L)) 8 eta / nu, eta = ln(2 l / b) / (4 pi);
the time series holds u_p / (beta L) already.
"""

import math
import sys

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt

import motile

demo = sys.argv[1] if len(sys.argv) > 1 else "runs/demo"
out = sys.argv[2] if len(sys.argv) > 2 else "velocity_norm.png"

particle = motile.open(f"{demo}/particle")
meanfield = motile.open(f"{demo}/meanfield")

cfg = particle.config
nu, box = cfg["volume_fraction"], cfg["box_length"]
eta = math.log(2.0 / cfg["diameter"]) / (4 * math.pi)
ts = particle.timeseries
t_p = ts["t"] * nu / (8 * eta)
u_p = ts["velocity_norm_box"] * 8 * eta / nu  # the column is in units of beta L

mf = meanfield.timeseries
fig, ax = plt.subplots(figsize=(6.4, 4.2), constrained_layout=True)
ax.semilogy(mf["t"], mf["u_l2"], label=f"mean field, {meanfield.config['grid']}$^3$")
ax.semilogy(t_p, u_p, "o", ms=3, label=f"particles, {len(particle.snapshots[0].positions)} rods (box modes)")
ax.set_xlabel(r"$t$  [$\mu/|\sigma_a|$]")
ax.set_ylabel(r"$\|u\|_2$  [$L\,|\sigma_a|/\mu$]")
ax.set_title(rf"demo: $\nu$ = {nu:g}, $L/\ell$ = {box:g}, $\zeta$ = {meanfield.config['zeta']:.3f}")
ax.legend()
fig.savefig(out, dpi=150)
print(f"wrote {out}")
