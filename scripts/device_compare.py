#!/usr/bin/env python3
"""Whole runs compared, for the device check (device_run.sh runs): `device_compare.py A B`.

Prints, for the time series (every column but the wall-clock rate) and for the newest
checkpoint's datasets, the largest difference of run B from run A: relative (absolute below
1e-9) for the time series, absolute for the checkpoint's arrays, and whether B repeats A bit
for bit. Needs numpy and h5py (both on the device image).
"""
import csv
import glob
import os
import sys

import h5py
import numpy as np

# Columns that depend on the order of the contact solver's constraints (the CPU orders them
# by cell, the device by pair): compared, but reported apart from the state's columns.
SOLVER = ("solver_iterations", "solver_residual", "active_contacts", "max_overlap",
          "contact_corrections", "projections")


def series(run):
    with open(os.path.join(run, "timeseries.csv")) as f:
        rows = list(csv.reader(f))
    head = [h.split(" [")[0] for h in rows[0]]
    return head, np.array([[float(x) for x in r] for r in rows[1:]])


def newest_checkpoint(run):
    return sorted(glob.glob(os.path.join(run, "checkpoints", "ckpt_*.h5")))[-1]


def arrays(path):
    out = {}
    with h5py.File(path) as f:
        f.visititems(lambda name, d: out.__setitem__(name, np.asarray(d[()]))
                     if isinstance(d, h5py.Dataset) else None)
    return out


def main(a, b):
    ha, ra = series(a)
    hb, rb = series(b)
    if ha != hb or ra.shape != rb.shape:
        print(f"time series differ in shape: {ra.shape} vs {rb.shape}")
        return 1
    state, solver, identical = 0.0, 0.0, True
    for k, name in enumerate(ha):
        if name == "steps_per_second":
            continue
        d = np.abs(ra[:, k] - rb[:, k]) / np.maximum(np.abs(ra[:, k]), 1e-9)
        identical &= bool(np.all(ra[:, k] == rb[:, k]))
        if name in SOLVER:
            solver = max(solver, float(d.max()))
        else:
            state = max(state, float(d.max()))
    ca, cb = arrays(newest_checkpoint(a)), arrays(newest_checkpoint(b))
    rods = {}
    for name in ("positions", "quaternions"):
        x, y = ca.get(name), cb.get(name)
        if x is None or y is None or x.shape != y.shape:
            print(f"checkpoint {name}: missing or of other shape")
            return 1
        rods[name] = float(np.abs(x - y).max())
        identical &= bool(np.array_equal(x, y))
    print(f"{len(ra)} rows to t = {ra[-1, 0]:g}: state columns {state:.2e} relative, "
          f"solver columns {solver:.2e}; final positions {rods['positions']:.2e} l, "
          f"quaternions {rods['quaternions']:.2e}; "
          f"{'bit for bit' if identical else 'not bit for bit'}")
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1], sys.argv[2]))
