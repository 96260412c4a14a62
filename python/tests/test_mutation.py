"""A mutation campaign through Python: a particle run's files (a snapshot, the time series, the
config) damaged in seeded ways and read by `motile.open` (config, time series, status, every
snapshot's arrays) and, for snapshots, by `motile.run` with the file as the initial state.

Each outcome is classified as in the Rust campaign (experiments/src/campaign/mutation): a
clear error (a Python exception naming the file), accepted and consistent (checked on what
came back: finite arrays of the right shapes, unit orientations, increasing times), an error
not naming the file, accepted but inconsistent, or a panic (pyo3's PanicException, which is
not an Exception). Only the first two may occur.

`MOTILE_PY_MUTATIONS` inputs per family (default 150 here; docs/faults.md gives the table of
10 000 per family, seed 1: `MOTILE_PY_MUTATIONS=10000 python3 -m pytest -q -s
python/tests/test_mutation.py`).
"""

import os
import random
import shutil
from pathlib import Path

import h5py
import numpy as np
import pytest

import motile

PER_FAMILY = int(os.environ.get("MOTILE_PY_MUTATIONS", "150"))
SEED = int(os.environ.get("MOTILE_PY_MUTATION_SEED", "1"))

SEED_RUN = {
    "box_length": 4.0,
    "rods": 12,
    "hydrodynamics": "sbt-explicit",
    "dt": 0.02,
    "t_end": 0.1,
    "diagnostic_interval": 0.02,
    "snapshot_interval": 0.04,
    "checkpoint_interval": 0.04,
    "vtk": False,
    "seed": 5,
}

SPECIAL = [b"\xff" * 8, b"\x00" * 8, np.float64(np.nan).tobytes(), np.float64(np.inf).tobytes(),
           np.float64(-1e300).tobytes(), np.float64(1e300).tobytes()]


def mutate_bytes(data: bytes, rng: random.Random) -> tuple:
    """Truncation, bit flips, or an 8-byte window overwritten."""
    b = bytearray(data)
    kind = rng.randrange(3)
    if kind == 0:
        cut = rng.randrange(len(b))
        return bytes(b[:cut]), f"truncated at {cut}"
    if kind == 1:
        at = [rng.randrange(len(b)) for _ in range(rng.randint(1, 4))]
        for i in at:
            b[i] ^= 1 << rng.randrange(8)
        return bytes(b), f"bits flipped at {at}"
    at = rng.randrange(max(1, len(b) - 8))
    b[at:at + 8] = rng.choice(SPECIAL)
    return bytes(b), f"8 bytes at {at} overwritten"


def mutate_hdf5(src: Path, dst: Path, rng: random.Random) -> str:
    """A byte-level damage, or the file rebuilt by h5py with one dataset or attribute damaged."""
    data = src.read_bytes()
    if rng.random() < 0.5:
        damaged, what = mutate_bytes(data, rng)
        dst.write_bytes(damaged)
        return what
    shutil.copy(src, dst)
    with h5py.File(dst, "r+") as f:
        names = sorted(f.keys())
        attrs = sorted(f.attrs.keys())
        kind = rng.randrange(6)
        if kind == 0:
            n = rng.choice(names)
            del f[n]
            return f"dataset {n} dropped"
        if kind == 1:
            n = rng.choice(names)
            f.move(n, n + "_renamed")
            return f"dataset {n} renamed"
        if kind == 2:
            n = rng.choice(names)
            v = f[n][...]
            del f[n]
            f[n] = v[: max(0, len(v) - 1)] if rng.random() < 0.5 else np.concatenate([v, v[:1]])
            return f"dataset {n}: a row fewer or more"
        if kind == 3:
            n = rng.choice(names)
            v = f[n][...].astype(np.float64)
            if v.size:
                v.flat[rng.randrange(v.size)] = rng.choice([np.nan, np.inf, -np.inf, 1e300, -1e300, 0.0])
            del f[n]
            f[n] = v
            return f"dataset {n}: one value poisoned"
        if kind == 4:
            a = rng.choice(attrs)
            f.attrs[a] = rng.choice([np.nan, -1.0, 0.0, 1e300, "text", np.int64(-5)])
            return f"attribute {a} replaced"
        a = rng.choice(attrs)
        del f.attrs[a]
        return f"attribute {a} dropped"


def mutate_text(text: str, rng: random.Random) -> tuple:
    """A line deleted, duplicated or swapped, or a value replaced by a bad one."""
    lines = text.splitlines()
    kind = rng.randrange(4)
    i = rng.randrange(len(lines))
    if kind == 0:
        del lines[i]
        what = f"line {i} deleted"
    elif kind == 1:
        lines.insert(i, lines[i])
        what = f"line {i} duplicated"
    elif kind == 2:
        j = rng.randrange(len(lines))
        lines[i], lines[j] = lines[j], lines[i]
        what = f"lines {i}, {j} swapped"
    else:
        bad = rng.choice(["nan", "inf", "-1", "0", "1e400", "x", '"text"', "[1, 2]", ""])
        line = lines[i]
        sep = "=" if "=" in line else ","
        parts = line.split(sep)
        k = rng.randrange(len(parts))
        parts[k] = (" " if sep == "=" and k else "") + bad
        lines[i] = sep.join(parts)
        what = f"line {i}, field {k} set to {bad!r}"
    return "\n".join(lines) + "\n", what


@pytest.fixture(scope="module")
def seed_run(tmp_path_factory):
    base = tmp_path_factory.mktemp("mutation")
    run = base / "seed"
    motile.run("particle", SEED_RUN, run, progress=False)
    return base, run


def consistent_run(run) -> str:
    """What is inconsistent in an opened run's contents ('' if nothing)."""
    cfg = run.config
    ts = run.timeseries
    t = ts["t"]
    if not (np.all(np.isfinite(t)) and np.all(np.diff(t) > 0)):
        return f"times {t}"
    status = run.status
    if status["state"] not in ("finished", "resumable", "failed", "empty"):
        return f"status {status}"
    for k in range(len(run.snapshots)):
        s = run.snapshots[k]
        x, p = s.positions, s.orientations
        if x.shape != p.shape or x.ndim != 2 or x.shape[1] != 3:
            return f"snapshot {k}: shapes {x.shape}, {p.shape}"
        if not (np.all(np.isfinite(x)) and np.allclose(np.linalg.norm(p, axis=1), 1.0, atol=1e-8)):
            return f"snapshot {k}: positions not finite or orientations not unit"
        if s.box_length != cfg["box_length"]:
            return f"snapshot {k}: box {s.box_length}, config {cfg['box_length']}"
    return ""


def classify(call, file_name: str) -> tuple:
    """Run `call` (which returns '' when what it accepted is consistent)."""
    try:
        why = call()
    except Exception as e:  # noqa: BLE001 - any Python exception is a refusal
        message = str(e)
        stem = Path(file_name).stem
        return ("clear error" if stem in message else "error not naming the file"), message
    except BaseException as e:  # pyo3's PanicException
        if type(e).__name__ == "PanicException":
            return "panic", str(e)
        raise
    return ("accepted, consistent" if not why else "accepted, inconsistent"), why


def campaign(family: str, seed_run, make, read) -> dict:
    base, run = seed_run
    counts, defects = {}, []
    rng = random.Random(f"{SEED}-{family}")
    for i in range(PER_FAMILY):
        work = base / f"{family}-{i}"
        shutil.copytree(run, work)
        file_name, what = make(work, rng)
        outcome, message = classify(lambda: read(work, base / f"{family}-{i}-out"), file_name)
        counts[outcome] = counts.get(outcome, 0) + 1
        if outcome not in ("clear error", "accepted, consistent"):
            defects.append(f"{family} #{i} ({what}): {outcome}: {message}")
        shutil.rmtree(work, ignore_errors=True)
        shutil.rmtree(base / f"{family}-{i}-out", ignore_errors=True)
    print(f"\n{family}: {PER_FAMILY} inputs, seed {SEED}: {counts}")
    return {"counts": counts, "defects": defects}


def damage_snapshot(work: Path, rng: random.Random) -> tuple:
    snap = work / "snapshots" / "snap_000001.h5"
    spare = work / "spare.h5"
    shutil.move(snap, spare)
    what = mutate_hdf5(spare, snap, rng)
    spare.unlink()
    return snap.name, what


def damage_text(name: str):
    def damage(work: Path, rng: random.Random) -> tuple:
        path = work / name
        text, what = mutate_text(path.read_text(), rng)
        path.write_text(text)
        return name, what

    return damage


def opened(work: Path, _out: Path) -> str:
    return consistent_run(motile.open(work))


def as_initial(work: Path, out: Path) -> str:
    cfg = dict(SEED_RUN, initial=str(work / "snapshots" / "snap_000001.h5"), t_end=0.04)
    motile.run("particle", cfg, out, progress=False)
    s = motile.open(out).snapshots[-1]
    x, p = s.positions, s.orientations
    ok = np.all(np.isfinite(x)) and np.allclose(np.linalg.norm(p, axis=1), 1.0, atol=1e-8)
    return "" if ok else "the run from it has non-finite positions or non-unit orientations"


@pytest.mark.parametrize(
    "family, make, read",
    [
        ("open-snapshot", damage_snapshot, opened),
        ("initial-snapshot", damage_snapshot, as_initial),
        ("open-timeseries", damage_text("timeseries.csv"), opened),
        ("open-config", damage_text("config.toml"), opened),
    ],
)
def test_damaged_files_through_python_are_refused_by_name_or_read_consistently(seed_run, family, make, read):
    result = campaign(family, seed_run, make, read)
    assert not result["defects"], "\n".join(result["defects"][:20])
    assert sum(result["counts"].values()) == PER_FAMILY
