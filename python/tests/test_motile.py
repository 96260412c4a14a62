"""Tests of the Python module `motile` (run by scripts/test.sh after `pip install ./python`).

References: the `motile` command's own runs (bit for bit), h5py and the CSV/TOML files read
independently, direct sums in numpy (NUFFT, correlations), exact identities of the Bingham
closure, and the time series the runs wrote with the same quantities.
"""

import _thread
import math
import os
import re
import shutil
import signal
import subprocess
import threading
import tomllib
from pathlib import Path

import h5py
import numpy as np
import pytest

import motile

ROOT = Path(__file__).resolve().parents[2]

PARTICLE = {
    "box_length": 10.0,
    "volume_fraction": 0.625,
    "hydrodynamics": "sbt-explicit",
    "dt": 0.05,
    "t_end": 2.0,
    "diagnostic_interval": 0.1,
    "snapshot_interval": 0.5,
    "checkpoint_interval": 0.5,
    "vtk": False,
    "seed": 7,
    "contact": {"margin": 0.15},
}

MEANFIELD = {
    "grid": 16,
    "zeta": 1.137,
    "diffusion": 1e-3,
    "t_end": 3.0,
    "diagnostic_interval": 0.5,
    "snapshot_interval": 1.0,
    "checkpoint_interval": 1.0,
    "seed": 3,
}


def motile_binary() -> str:
    """The CLI built by `cargo test --release --workspace` (or $MOTILE_BIN)."""
    exe = os.environ.get("MOTILE_BIN") or str(ROOT / "target" / "release" / "motile")
    if not os.access(exe, os.X_OK):
        pytest.fail(f"{exe}: no motile binary (cargo build --release first, or set MOTILE_BIN)")
    return exe


def toml_value(v) -> str:
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, str):
        return f'"{v}"'
    return repr(v)


def write_toml(path: Path, cfg: dict) -> None:
    """A config file by hand (top-level keys, then one level of tables): the CLI's input."""
    lines = [f"{k} = {toml_value(v)}" for k, v in cfg.items() if not isinstance(v, dict)]
    for k, t in cfg.items():
        if isinstance(t, dict):
            lines.append(f"[{k}]")
            lines += [f"{kk} = {toml_value(v)}" for kk, v in t.items()]
    path.write_text("\n".join(lines) + "\n")


def cli_run(model: str, cfg: dict, out: Path) -> None:
    config = out.parent / f"{out.name}.toml"
    write_toml(config, cfg)
    done = subprocess.run(
        [motile_binary(), model, "run", str(config), "--out", str(out)],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, f"motile {model} run failed: {done.stderr}"


@pytest.fixture(scope="module")
def runs(tmp_path_factory):
    """Each model run once by the CLI and once from Python, same config."""
    base = tmp_path_factory.mktemp("runs")
    calls = []
    for model, cfg in (("particle", PARTICLE), ("meanfield", MEANFIELD)):
        cli_run(model, cfg, base / f"cli_{model}")
        seen = []
        summary = motile.run(model, cfg, base / f"py_{model}", progress=lambda p, n, t: seen.append((p, n, t)))
        calls.append((model, seen, summary))
    return base, calls


def csv_without_timing(path: Path) -> list:
    """The time series' rows less `steps_per_second` (wall-clock timing)."""
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    drop = [i for i, h in enumerate(header) if h.startswith("steps_per_second")]
    return [[c for i, c in enumerate(l.split(",")) if i not in drop] for l in lines]


def h5_contents(path: Path) -> dict:
    out = {}
    with h5py.File(path, "r") as f:
        for k, v in f.attrs.items():
            out["@" + k] = v.decode() if isinstance(v, bytes) else v
        f.visititems(lambda name, obj: out.__setitem__(name, obj[...]) if isinstance(obj, h5py.Dataset) else None)
    return out


def assert_same_h5(a: Path, b: Path) -> None:
    x, y = h5_contents(a), h5_contents(b)
    assert sorted(x) == sorted(y), f"{a.name}: different entries {sorted(x)} vs {sorted(y)}"
    for k in x:
        if isinstance(x[k], np.ndarray):
            assert x[k].dtype == y[k].dtype and x[k].shape == y[k].shape, f"{a.name}/{k}"
            assert x[k].tobytes() == y[k].tobytes(), f"{a.name}/{k}: not bit-identical"
        else:
            assert np.array_equal(x[k], y[k]), f"{a.name}@{k}: {x[k]} vs {y[k]}"


# --- runs --------------------------------------------------------------------------------------


@pytest.mark.parametrize("model", ["particle", "meanfield"])
def test_python_run_matches_cli_bit_for_bit(runs, model):
    base, _ = runs
    cli, py = base / f"cli_{model}", base / f"py_{model}"
    assert csv_without_timing(cli / "timeseries.csv") == csv_without_timing(py / "timeseries.csv")
    assert (cli / "config.toml").read_text() == (py / "config.toml").read_text()
    snaps = sorted((cli / "snapshots").glob("*.h5"))
    assert len(snaps) >= 3, f"{len(snaps)} snapshots"
    assert [s.name for s in snaps] == [s.name for s in sorted((py / "snapshots").glob("*.h5"))]
    for s in snaps:
        assert_same_h5(s, py / "snapshots" / s.name)
    ckpts = sorted((cli / "checkpoints").glob("ckpt_*.h5"))
    assert ckpts, "no checkpoints"
    assert_same_h5(ckpts[-1], py / "checkpoints" / ckpts[-1].name)


SCENE = """[scene]
name = "tiny"
version = 1
description = "Two short runs for the tests: swimmers without hydrodynamics and a 16^3 continuum."
level = "No hydrodynamics (a test of the scene machinery, not of physics)."
cost = "seconds"

[[run]]
name = "rods"
model = "particle"
[run.config]
box_length = 6.0
volume_fraction = 0.625
hydrodynamics = "none"
dt = 0.04
t_end = 1.0
diagnostic_interval = 0.08
snapshot_interval = 0.4
checkpoint_interval = 0.4
vtk = false
seed = 5

[[run]]
name = "continuum"
model = "meanfield"
[run.config]
grid = 16
zeta = 1.137
diffusion = 1e-3
t_end = 1.0
diagnostic_interval = 0.25
snapshot_interval = 0.5
checkpoint_interval = 0.5
seed = 3
"""


def test_run_scene_matches_the_cli(tmp_path):
    """A scene file run from Python: its runs are the CLI's `motile run` of the same file, bit
    for bit, and its report is written and returned."""
    scene = tmp_path / "tiny.toml"
    scene.write_text(SCENE)
    done = subprocess.run(
        [motile_binary(), "run", str(scene), "--out", str(tmp_path / "cli")],
        capture_output=True,
        text=True,
    )
    assert done.returncode == 0, f"motile run failed: {done.stderr}"
    report = motile.run_scene(scene, tmp_path / "py", progress=False)
    assert "tiny" in report and (tmp_path / "py" / "scene.md").read_text() == report
    for run in ("rods", "continuum"):
        cli, py = tmp_path / "cli" / run, tmp_path / "py" / run
        assert csv_without_timing(cli / "timeseries.csv") == csv_without_timing(py / "timeseries.csv"), run
        snaps = sorted((cli / "snapshots").glob("*.h5"))
        assert len(snaps) >= 2, f"{run}: {len(snaps)} snapshots"
        for snap in snaps:
            assert_same_h5(snap, py / "snapshots" / snap.name)
    only = motile.run_scene(scene, tmp_path / "only", only="rods", progress=False)
    assert (tmp_path / "only" / "rods").is_dir() and not (tmp_path / "only" / "continuum").exists(), only


def test_progress_reaches_the_callback(runs):
    _, calls = runs
    for model, seen, summary in calls:
        assert seen, f"{model}: progress never called"
        positions = [p for p, _, _ in seen]
        assert positions == sorted(positions), f"{model}: progress went backwards"
        assert seen[-1][0] == seen[-1][1], f"{model}: last progress {seen[-1]} is not the end"
        assert summary["steps"] > 0 and summary["seconds"] > 0


def test_interrupted_run_resumes_to_the_same_result(runs, tmp_path):
    """Ctrl-C (a real SIGINT to the interpreter, from a timer thread) stops the run at a step
    boundary with a checkpoint and raises KeyboardInterrupt; motile.resume ends where the
    uninterrupted run ended, bit for bit."""
    base, _ = runs
    out = tmp_path / "interrupted"
    # Long enough that the interrupt lands while the run steps (the callback sees progress
    # every 20 ms; a run of a few hundred milliseconds can end first on an idle machine).
    cfg = dict(PARTICLE, t_end=20.0)
    timer = None

    def progress(p, n, t):
        nonlocal timer
        if timer is None and t >= 0.6:  # after the first checkpoint, well before the end
            timer = threading.Timer(0.0, _thread.interrupt_main)
            timer.start()

    # An interpreter started with SIGINT ignored (a background job of a non-interactive shell)
    # installs no handler for it, and then interrupt_main does nothing: Python's own handler for
    # the test's span.
    previous = signal.signal(signal.SIGINT, signal.default_int_handler)
    try:
        # The message says how to continue from Python, not from a shell.
        with pytest.raises(KeyboardInterrupt, match=r"checkpoint.*motile\.resume\("):
            motile.run("particle", cfg, out, progress=progress)
    finally:
        signal.signal(signal.SIGINT, previous)
    status = motile.open(out).status
    assert status["state"] == "resumable", status
    assert status["t"] < cfg["t_end"], status
    motile.resume(out, progress=False)
    assert motile.open(out).status["state"] == "finished"
    whole = tmp_path / "whole"
    motile.run("particle", cfg, whole, progress=False)
    assert csv_without_timing(out / "timeseries.csv") == csv_without_timing(whole / "timeseries.csv")
    last = sorted((whole / "snapshots").glob("*.h5"))[-1]
    assert_same_h5(last, out / "snapshots" / last.name)


def test_failing_progress_callback_stops_the_run_with_its_error(tmp_path):
    def progress(p, n, t):
        raise RuntimeError("callback broke")

    with pytest.raises(RuntimeError, match="callback broke"):
        motile.run("meanfield", MEANFIELD, tmp_path / "r", progress=progress)
    assert motile.open(tmp_path / "r").status["state"] in ("resumable", "empty")
    # The log says who stopped it (no signal was sent).
    log = (tmp_path / "r" / "run.log").read_text()
    assert "signal" not in log, log
    if "stopped" in log:
        assert "at the caller's request" in log, log


def test_a_callback_stop_between_diagnostics_keeps_the_time_reached(tmp_path):
    """A callback that raises after t = 1.2 (diagnostics every 0.5) stops the run with a
    checkpoint at the step it reached: status says what stopped it and that time (the
    checkpoint's, later than the time series' last row), and the run resumes from it."""

    def progress(p, n, t):
        if t > 1.2:
            raise RuntimeError("enough")

    out = tmp_path / "r"
    with pytest.raises(RuntimeError, match="enough"):
        motile.run("meanfield", MEANFIELD, out, progress=progress)
    status = motile.open(out).status
    stopped = re.search(r"stopped at step \d+ \(t = ([0-9.]+)\) at the caller's request", status["reason"] or "")
    assert status["state"] == "resumable" and stopped, status
    assert status["t"] == pytest.approx(float(stopped.group(1)), abs=1e-4), status
    assert status["t"] > motile.open(out).timeseries["t"][-1], status
    motile.resume(out, progress=False)
    assert motile.open(out).status == {"state": "finished", "t": 3.0, "t_end": 3.0, "reason": None}


# --- run directories --------------------------------------------------------------------------


@pytest.mark.parametrize("model", ["particle", "meanfield"])
def test_open_returns_what_the_files_hold(runs, model):
    base, _ = runs
    path = base / f"cli_{model}"
    run = motile.open(path)
    assert run.model == model
    with (path / "config.toml").open("rb") as f:
        cfg = tomllib.load(f)
    cfg.pop("motile")
    assert run.config == cfg
    assert run.status["state"] == "finished", run.status
    # The time series: every column, its unit, its values.
    header = (path / "timeseries.csv").read_text().splitlines()[0].split(",")
    data = np.loadtxt(path / "timeseries.csv", delimiter=",", skiprows=1, ndmin=2)
    ts = run.timeseries
    assert len(ts) == len(header)
    for i, h in enumerate(header):
        name, unit = re.fullmatch(r"(.*) \[(.*)\]", h).groups()
        assert ts.units[name] == unit
        np.testing.assert_array_equal(ts[name], data[:, i], err_msg=name)
    # Snapshots, lazily: each against h5py.
    files = sorted((path / "snapshots").glob("*.h5"))
    assert len(run.snapshots) == len(files)
    np.testing.assert_array_equal(run.snapshots.times(), [h5py.File(f, "r").attrs["time"] for f in files])
    for k in (0, -1):
        snap = run.snapshots[k]
        with h5py.File(files[k], "r") as f:
            assert snap.time == f.attrs["time"] and snap.step == f.attrs["step"]
            assert snap.box_length == f.attrs["box_length"]
            if model == "particle":
                assert {"positions", "orientations", "image_counts"} <= set(f)
                if k == -1:
                    assert {"force_points", "point_forces", "velocities"} <= set(f), set(f)
                for name in f:  # every dataset the file holds
                    np.testing.assert_array_equal(snap[name], f[name][...], err_msg=name)
                np.testing.assert_array_equal(
                    snap.unwrapped(), f["positions"][...] + f.attrs["box_length"] * f["image_counts"][...]
                )
            else:
                assert snap.grid == f.attrs["grid"]
                for name in ("Q", "u"):
                    # motile's order [c, x, y, z]; the file's [c, z, y, x]
                    np.testing.assert_array_equal(snap[name], f[name][...].transpose(0, 3, 2, 1), err_msg=name)
    with pytest.raises(IndexError, match="snapshot"):
        run.snapshots[len(files)]


def test_meanfield_analysis_reproduces_the_runs_diagnostics(runs):
    """The velocity norm and the entropy of the last snapshot, from Python, are the numbers the
    run wrote in its time series at that time (the same code; the entropy's grid average)."""
    base, _ = runs
    run = motile.open(base / "cli_meanfield")
    snap = run.snapshots[-1]
    ts = run.timeseries
    row = int(np.argmin(abs(ts["t"] - snap.time)))
    assert abs(ts["t"][row] - snap.time) < 1e-9
    u_l2 = motile.velocity_norm(snap.u)
    assert abs(u_l2 - ts["u_l2"][row]) <= 1e-6 * ts["u_l2"][row], (u_l2, ts["u_l2"][row])
    # numpy's own volume average
    assert math.isclose(u_l2, math.sqrt(np.mean(np.sum(snap.u**2, axis=0))), rel_tol=1e-12)
    h = motile.relative_entropy(snap.Q)
    assert abs(h - ts["entropy"][row]) <= 1e-6 * abs(ts["entropy"][row]) + 1e-12, (h, ts["entropy"][row])


def test_status_of_a_missing_directory_is_an_error(tmp_path):
    with pytest.raises(ValueError):
        motile.open(tmp_path / "nothing")


# --- analysis ---------------------------------------------------------------------------------


def direct_type1(x, s, box, modes):
    ms = [np.arange(-(m // 2), m - m // 2) for m in modes]
    k = [2 * np.pi * m / box for m in ms]
    ex = np.exp(-1j * np.outer(k[0], x[:, 0]))
    ey = np.exp(-1j * np.outer(k[1], x[:, 1]))
    ez = np.exp(-1j * np.outer(k[2], x[:, 2]))
    return np.einsum("aj,bj,cj,kj->kabc", ex, ey, ez, s)


@pytest.mark.parametrize("tol", [1e-2, 1e-5, 1e-9, 1e-12])
def test_nufft_against_direct_sums(tol):
    rng = np.random.default_rng(11)
    box = 7.0
    modes = (6, 9, 10)
    x = rng.uniform(-box, 2 * box, (400, 3))  # outside [0, L) too: wrapped
    s = rng.normal(size=(2, 400)) + 1j * rng.normal(size=(2, 400))
    exact = direct_type1(x, s, box, modes)
    c = motile.nufft1(x, s, box, modes, tol)
    assert c.shape == (2, *modes)
    for k in range(2):
        err = np.linalg.norm(c[k] - exact[k]) / np.linalg.norm(exact[k])
        assert err <= tol, f"type 1, tol {tol:g}: relative L2 error {err:.2e}"
    c1 = motile.nufft1(x, s[0].real, box, modes, tol)  # one real transform
    assert c1.shape == modes
    coef = rng.normal(size=(2, *modes)) + 1j * rng.normal(size=(2, *modes))
    ms = [np.arange(-(m // 2), m - m // 2) for m in modes]
    kx, ky, kz = np.meshgrid(*[2 * np.pi * m / box for m in ms], indexing="ij")
    phase = np.exp(1j * (np.multiply.outer(x[:, 0], kx) + np.multiply.outer(x[:, 1], ky) + np.multiply.outer(x[:, 2], kz)))
    exact2 = np.einsum("jabc,kabc->kj", phase, coef)
    v = motile.nufft2(x, coef, box, tol)
    assert v.shape == (2, 400)
    for k in range(2):
        err = np.linalg.norm(v[k] - exact2[k]) / np.linalg.norm(exact2[k])
        assert err <= tol, f"type 2, tol {tol:g}: relative L2 error {err:.2e}"


def test_velocity_autocorrelation_against_direct_sums():
    """Swimmer-like velocities (a speed along random orientations plus a smooth flow): the
    coefficients by direct sums, Corr(r) = sum_k |u~|^2 j0(|k| r) summed in numpy."""
    rng = np.random.default_rng(5)
    box, n, modes, tol = 9.0, 800, 6, 1e-9
    x = rng.uniform(0, box, (n, 3))
    p = rng.normal(size=(n, 3))
    p /= np.linalg.norm(p, axis=1)[:, None]
    u = p + 0.3 * np.stack([np.sin(2 * np.pi * x[:, 1] / box), np.cos(2 * np.pi * x[:, 2] / box), np.zeros(n)], 1)
    r, corr = motile.velocity_autocorrelation(x, u, box, modes=modes, tolerance=tol, shell_width=0.25)
    coef = direct_type1(x, (u / n).T.astype(complex), box, (modes,) * 3)
    power = np.sum(abs(coef) ** 2, axis=0)
    ms = np.arange(-(modes // 2), modes - modes // 2)
    kx, ky, kz = np.meshgrid(*(2 * np.pi * ms / box,) * 3, indexing="ij")
    kk = np.sqrt(kx**2 + ky**2 + kz**2)
    np.testing.assert_allclose(r, 0.25 * np.arange(len(r)))
    assert r[-1] <= box / 2 < r[-1] + 0.25
    exact = np.array([np.sum(power * np.sinc(kk * ri / np.pi)) for ri in r])
    err = np.max(abs(corr - exact)) / exact[0]
    assert err <= 10 * tol, f"max error {err:.2e} of Corr(0)"


def test_msd_and_velocity_norm_against_numpy():
    rng = np.random.default_rng(2)
    a, b = rng.normal(size=(1000, 3)), rng.normal(size=(1000, 3))
    assert math.isclose(motile.mean_squared_displacement(a, b), np.mean(np.sum((b - a) ** 2, 1)), rel_tol=1e-13)
    f = rng.normal(size=(3, 8, 8, 8))
    assert math.isclose(motile.velocity_norm(f), math.sqrt(np.mean(np.sum(f**2, 0))), rel_tol=1e-13)


def bingham_moments(b: np.ndarray) -> tuple:
    """Second and fourth moments of the Bingham distribution f(p) ~ exp(p.B.p) on the unit
    sphere by Gauss-Legendre (cos theta) x uniform (phi) quadrature: Q as (6,), S as (6, 6)
    over the components xx, xy, xz, yy, yz, zz."""
    z, wz = np.polynomial.legendre.leggauss(120)
    phi = np.linspace(0, 2 * np.pi, 240, endpoint=False)
    zz, pp = np.meshgrid(z, phi, indexing="ij")
    r = np.sqrt(1 - zz**2)
    p = np.stack([r * np.cos(pp), r * np.sin(pp), zz], -1).reshape(-1, 3)
    w = np.repeat(wz, len(phi)) * np.exp(np.einsum("ni,ij,nj->n", p, b, p))
    w /= w.sum()
    comps = [(0, 0), (0, 1), (0, 2), (1, 1), (1, 2), (2, 2)]
    pq = np.stack([p[:, i] * p[:, j] for i, j in comps], 1)
    return w @ pq, np.einsum("n,na,nb->ab", w, pq, pq)


@pytest.mark.parametrize("degree,tol", [(20, 1e-5), (40, 5e-8)])
def test_bingham_closure_against_quadrature(degree, tol):
    """The closure's fourth moment of Q against the Bingham distribution's moments by quadrature
    on the sphere (rotated B from isotropic to strongly aligned); tolerances: the tables'
    documented error budget at degree 20 (6.7e-6), converging with degree. Also the trace
    identity S_ijkk = Q_ij and the entropy of the isotropic state (0)."""
    rng = np.random.default_rng(4)
    qs, ss = [], []
    for eig in ([0, 0, 0], [1, 0, 0], [3, -1, 0.5], [8, 2, -4], [-6, 0, 0], [15, 5, 0]):
        rot, _ = np.linalg.qr(rng.normal(size=(3, 3)))
        q, s = bingham_moments(rot @ np.diag(eig) @ rot.T)
        qs.append(q)
        ss.append(s)
    got = motile.bingham_closure(np.array(qs), degree=degree)
    assert got.shape == (len(qs), 6, 6) and np.allclose(got, got.transpose(0, 2, 1))
    err = np.max(abs(got - np.array(ss)), axis=(1, 2))
    assert np.all(err <= tol), f"degree {degree}: errors {err} (tolerance {tol:g})"
    trace = got[:, :, 0] + got[:, :, 3] + got[:, :, 5]
    assert np.max(abs(trace - np.array(qs))) <= tol
    eye = np.array([1, 0, 0, 1, 0, 1.0]) / 3
    assert abs(motile.relative_entropy(np.tile(eye, (10, 1)), degree=degree)) <= tol


# --- bad input --------------------------------------------------------------------------------

X = np.random.default_rng(0).uniform(0, 5, (10, 3))
NAN = X.copy()
NAN[3, 1] = np.nan
BAD_INPUTS = [
    (lambda: motile.nufft1(X[:, :2], np.ones(10), 5, 4), r"points: expected shape \(N, 3\)"),
    (lambda: motile.nufft1(NAN, np.ones(10), 5, 4), r"points: entry \(3, 1\) is nan"),
    (lambda: motile.nufft1(X, np.ones(9), 5, 4), r"strengths: expected shape \(10,\)"),
    (lambda: motile.nufft1(X, np.ones(10), -5, 4), r"box_length: expected a positive"),
    (lambda: motile.nufft1(X, np.ones(10), 5, 0), r"modes: expected"),
    (lambda: motile.nufft1(X, np.ones(10), 5, (4, 4)), r"modes: expected"),
    (lambda: motile.nufft1(X, np.ones(10), 5, 4, tolerance=1.0), r"tolerance: expected a value in"),
    (lambda: motile.nufft1(X, ["a"] * 10, 5, 4), r"strengths: expected numbers"),
    (lambda: motile.nufft2(X, np.ones((4, 4)), 5), r"coefficients: expected shape"),
    (lambda: motile.nufft2(X, np.full((4, 4, 4), np.inf), 5), r"coefficients: entry \(0, 0, 0\) is \(inf"),
    (lambda: motile.velocity_autocorrelation(X, X[:5], 5), r"velocities: expected shape \(10, 3\)"),
    (lambda: motile.velocity_autocorrelation(X, X, 5, shell_width=0), r"shell_width: expected a positive"),
    (lambda: motile.velocity_autocorrelation(X, X, 5, modes=(4, 4, 4)), r"modes: expected one int"),
    (lambda: motile.velocity_norm(np.ones(5)), r"u: expected shape \(C, n, n, n\)"),
    (lambda: motile.relative_entropy(np.ones((4, 5))), r"q: expected shape \(P, 6\)"),
    (lambda: motile.relative_entropy(-np.ones((4, 6))), r"q: point 0 has trace"),
    (lambda: motile.bingham_closure(np.ones((4, 6)), degree=3), r"degree: expected an int in 10..=200"),
    (lambda: motile.mean_squared_displacement(X, X[:4]), r"xt: expected shape \(10, 3\)"),
    (lambda: motile.run("fluid", {}, "/nonexistent/x"), r'model: expected "particle" or "meanfield"'),
    (lambda: motile.run("particle", {"dt": -1.0}, "/nonexistent/x"), r"dt"),
    (lambda: motile.run("particle", {"box_lenght": 5.0}, "/nonexistent/x"), r"box_lenght"),
    (lambda: motile.run("meanfield", {"grid": "big"}, "/nonexistent/x"), r"grid"),
    (lambda: motile.run("meanfield", {"grid": {1, 2}}, "/nonexistent/x"), r"config.grid: a value of type set"),
    (lambda: motile.run("particle", [], "/nonexistent/x"), r"config: expected a dict"),
    (lambda: motile.run("particle", {}, "/nonexistent/x", progress=3), r"progress: expected True, False or a callable"),
    (lambda: motile.run_scene("no-such-scene", "/nonexistent/x"), r"no-such-scene"),
]


@pytest.mark.parametrize("call,message", BAD_INPUTS, ids=[m for _, m in BAD_INPUTS])
def test_bad_input_raises_value_error_naming_the_argument(call, message):
    with pytest.raises(ValueError, match=message):
        call()


def test_raw_module_rejects_bad_arrays_without_panicking():
    """The compiled half checks too (second line): NaN and shape errors are ValueError."""
    from motile import _motile

    with pytest.raises(ValueError, match="points: row 3"):
        _motile.nufft1(NAN, np.ones((1, 10), complex), 5.0, (4, 4, 4), 1e-6)
    with pytest.raises(ValueError, match="modes"):
        _motile.nufft1(X, np.ones((1, 10), complex), 5.0, (0, 4, 4), 1e-6)
    with pytest.raises(ValueError, match="box_length"):
        _motile.velocity_autocorrelation(X, X, float("nan"))
    with pytest.raises(ValueError, match="q: row 0"):
        _motile.relative_entropy(np.full((2, 6), np.nan))
