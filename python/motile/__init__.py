"""motile from Python: runs, run directories and the analysis on numpy arrays.

The same code as the ``motile`` command: runs go through its run loop (the same results bit
for bit), run directories are read by its readers, and the analysis is the Rust crate
``motile-analysis`` (NUFFT, correlations, norms) and the mean-field model's Bingham closure.
Units are motile's (docs/MODEL.md): particle runs in rod lengths l and 1/beta, mean-field runs
in box lengths and mu/|sigma_a|.

Conventions for arrays:

- points, velocities, orientations: shape ``(N, 3)``, rows (x, y, z);
- grid fields: shape ``(C, n, n, n)`` indexed ``[component, x, y, z]`` (run-directory
  snapshots come in this order; the HDF5 files store ``[component, z, y, x]``);
- Q tensors: the six components xx, xy, xz, yy, yz, zz, along the first axis of a grid field
  or as rows ``(P, 6)``;
- Fourier modes: ``m`` in ``-floor(M/2) .. ceil(M/2) - 1`` per axis (the most negative first,
  as FINUFFT's default ``modeord=0``), ``k = 2 pi m / L``, arrays indexed ``[mx, my, mz]``.

Every argument is checked at the boundary: a wrong shape, a NaN or an out-of-range value raises
``ValueError`` naming the argument and what was expected.

See docs/python.md for a worked example.
"""

from __future__ import annotations

import math
import os
import sys
import time
from typing import Any, Callable, Mapping, Optional, Sequence, Union

import numpy as np

from . import _motile

__version__ = _motile.__version__

__all__ = [
    "RunDirectory",
    "Snapshot",
    "TimeSeries",
    "open",
    "run",
    "resume",
    "run_scene",
    "nufft1",
    "nufft2",
    "velocity_autocorrelation",
    "velocity_norm",
    "relative_entropy",
    "bingham_closure",
    "mean_squared_displacement",
]

PathLike = Union[str, "os.PathLike[str]"]
Progress = Union[bool, Callable[[int, int, float], Any], None]


# --- argument checks -------------------------------------------------------------------------


def _array(value: Any, name: str, dtype: Any = np.float64) -> np.ndarray:
    try:
        a = np.asarray(value)
    except Exception as e:  # ragged lists and the like
        raise ValueError(f"{name}: not an array ({e})") from None
    if a.dtype == object:
        raise ValueError(f"{name}: not a numeric array")
    if dtype is np.float64 and np.iscomplexobj(a):
        raise ValueError(f"{name}: expected real values, got dtype {a.dtype}")
    if not (np.issubdtype(a.dtype, np.number) or a.dtype == np.bool_):
        raise ValueError(f"{name}: expected numbers, got dtype {a.dtype}")
    a = np.ascontiguousarray(a, dtype=dtype)
    if not np.all(np.isfinite(a)):
        bad = np.argwhere(~np.isfinite(a))[0]
        raise ValueError(
            f"{name}: entry {tuple(int(i) for i in bad)} is {a[tuple(bad)]} (values must be finite)"
        )
    return a


def _rows(value: Any, name: str, width: int, n: Optional[int] = None) -> np.ndarray:
    a = _array(value, name)
    want = f"({'N' if n is None else n}, {width})"
    if a.ndim != 2 or a.shape[1] != width or (n is not None and a.shape[0] != n):
        raise ValueError(f"{name}: expected shape {want}, got {a.shape}")
    return a


def _positive(value: Any, name: str) -> float:
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: expected a positive number, got {value!r}") from None
    if not (v > 0 and math.isfinite(v)):
        raise ValueError(f"{name}: expected a positive finite number, got {v}")
    return v


def _tolerance(value: Any) -> float:
    v = _positive(value, "tolerance")
    if not (1e-15 <= v <= 1e-1):
        raise ValueError(f"tolerance: expected a value in [1e-15, 1e-1], got {v:g}")
    return v


def _modes(value: Any) -> tuple:
    m = (value,) * 3 if np.isscalar(value) else tuple(value)
    if len(m) != 3 or not all(isinstance(x, (int, np.integer)) and 1 <= x <= 4096 for x in m):
        raise ValueError(f"modes: expected an int or three ints in 1..=4096, got {value!r}")
    return tuple(int(x) for x in m)


def _q_rows(q: Any) -> np.ndarray:
    """Q as rows (P, 6) from (P, 6) rows or a (6, n, n, n) / (6, ...) grid field."""
    a = _array(q, "q")
    if a.ndim == 2 and a.shape[1] == 6:
        rows = a
    elif a.ndim >= 2 and a.shape[0] == 6:
        rows = np.ascontiguousarray(a.reshape(6, -1).T)
    else:
        raise ValueError(
            f"q: expected shape (P, 6) or (6, n, n, n) (xx, xy, xz, yy, yz, zz), got {a.shape}"
        )
    tr = rows[:, 0] + rows[:, 3] + rows[:, 5]
    if np.any(tr <= 0):
        p = int(np.argmax(tr <= 0))
        raise ValueError(f"q: point {p} has trace {tr[p]}: a second moment needs a positive trace")
    return rows


# --- runs -------------------------------------------------------------------------------------


class _Printer:
    """Terminal progress for runs started from Python: one line, rewritten at most twice a
    second (stderr, as the CLI's bar)."""

    def __init__(self, label: str) -> None:
        self.label = label
        self.last = 0.0
        self.start = time.monotonic()

    def __call__(self, position: int, length: int, t: float) -> None:
        now = time.monotonic()
        if now - self.last < 0.5 and position < length:
            return
        self.last = now
        frac = position / length if length else 1.0
        sys.stderr.write(
            f"\r{self.label}: {100 * frac:5.1f}%  t = {t:.4g}  ({now - self.start:.0f} s)"
        )
        if position >= length:
            sys.stderr.write("\n")
        sys.stderr.flush()


def _progress(progress: Progress, label: str) -> Optional[Callable[[int, int, float], Any]]:
    if progress is True:
        return _Printer(label)
    if progress is None or progress is False:
        return None
    if not callable(progress):
        raise ValueError(
            f"progress: expected True, False or a callable (position, length, t), got {progress!r}"
        )
    return progress


def run(
    model: str,
    config: Optional[Mapping[str, Any]],
    out: PathLike,
    progress: Progress = True,
) -> dict:
    """Run ``model`` ("particle" or "meanfield") with the keys of ``config`` (a dict laid out as
    a config file, every key optional, docs/config.md; ``None`` for the defaults) into the new
    run directory ``out``, through the ``motile`` command's run loop: the same files, the same
    numbers bit for bit.

    The interpreter is released while the run steps. ``progress``: ``True`` prints a progress
    line on stderr, a callable is called as ``progress(position, length, t)`` after the steps
    (at most every 20 ms), ``False`` shows nothing. Ctrl-C (``KeyboardInterrupt``) stops the run
    at the next step boundary with a checkpoint, as the CLI does on SIGINT, and is then raised;
    :func:`resume` continues it. Bad config keys or values raise ``ValueError`` naming the key.

    Returns ``{"steps", "seconds", "path"}``.
    """
    if model not in ("particle", "meanfield"):
        raise ValueError(f'model: expected "particle" or "meanfield", got {model!r}')
    if config is None:
        config = {}
    if not isinstance(config, Mapping):
        raise ValueError(f"config: expected a dict of config keys, got {type(config).__name__}")
    return _motile.run_model(model, dict(config), os.fspath(out), _progress(progress, model))


def resume(path: PathLike, progress: Progress = True) -> dict:
    """Continue the run in ``path`` from its newest valid checkpoint to its ``t_end`` (the
    result is the same bit for bit as an uninterrupted run). ``progress`` as for :func:`run`."""
    return _motile.resume(os.fspath(path), _progress(progress, os.fspath(path)))


def run_scene(
    name: PathLike,
    out: PathLike,
    only: Optional[Sequence[str]] = None,
    progress: Progress = True,
) -> str:
    """Run the scene ``name`` (built in, as ``motile scenes`` lists them, or a scene file) into
    ``out``, only the runs named in ``only`` if given, resuming runs already there, and compare
    them as ``motile run`` does. Returns the scene's Markdown report (also in ``out/scene.md``)."""
    if isinstance(only, str):
        only = [only]
    name = os.fspath(name)
    return _motile.run_scene(
        name, os.fspath(out), None if only is None else list(only), _progress(progress, name)
    )


# --- run directories --------------------------------------------------------------------------


class TimeSeries(Mapping):
    """A run's ``timeseries.csv`` (or another of its CSV files): a mapping from column name to
    numpy array, with :attr:`units` (column name to unit, e.g. ``"1/beta"``) and
    :attr:`columns` in file order."""

    def __init__(self, names: Sequence[str], units: Sequence[str], columns: Sequence[np.ndarray],
                 source: str = ""):
        self.columns = list(names)
        self.units = dict(zip(names, units))
        self._data = dict(zip(names, columns))
        self._source = source

    def __getitem__(self, name: str) -> np.ndarray:
        try:
            return self._data[name]
        except KeyError:
            where = f"{self._source} has no column {name!r}" if self._source else f"no column {name!r}"
            raise KeyError(f"{where}; its columns are {', '.join(self.columns)}") from None

    def __iter__(self):
        return iter(self.columns)

    def __len__(self) -> int:
        return len(self.columns)

    def __repr__(self) -> str:
        rows = len(next(iter(self._data.values()))) if self._data else 0
        return f"TimeSeries({rows} rows: {', '.join(self.columns)})"


class Snapshot(dict):
    """One snapshot: a dict with ``kind``, ``time``, ``step``, ``box_length`` and the arrays.

    Particle: ``positions``, ``orientations``, ``image_counts`` ``(N, 3)``; with hydrodynamics
    ``force_points``, ``point_forces`` ``(P, 3)``; with kinematics ``velocities``,
    ``angular_velocities``, ``contact_forces`` ``(N, 3)``. Unwrapped positions:
    ``positions + box_length * image_counts`` (:meth:`unwrapped`).

    Mean field: ``grid`` (n), ``Q`` ``(6, n, n, n)`` and ``u`` ``(3, n, n, n)`` indexed
    ``[component, x, y, z]`` (views of the file's ``[component, z, y, x]`` arrays).
    """

    def __getattr__(self, name: str) -> Any:
        try:
            return self[name]
        except KeyError:
            raise AttributeError(name) from None

    def unwrapped(self) -> np.ndarray:
        """Particle positions with the periodic images crossed added back."""
        return self["positions"] + self["box_length"] * self["image_counts"]


class _Snapshots(Sequence):
    """The snapshots of a run, each read from its file when indexed."""

    def __init__(self, inner: Any) -> None:
        self._inner = inner

    def __len__(self) -> int:
        return self._inner.snapshot_count

    def __getitem__(self, k: Any) -> Any:
        if isinstance(k, slice):
            return [self[i] for i in range(*k.indices(len(self)))]
        if not isinstance(k, (int, np.integer)):
            raise TypeError(f"snapshot index: expected an int or a slice, got {k!r}")
        n = len(self)
        if not -n <= k < n:
            raise IndexError(f"snapshot {k}: the run has {n} snapshot(s)")
        d = Snapshot(self._inner.snapshot(int(k)))
        if d["kind"] == "meanfield":
            d["Q"] = d["Q"].transpose(0, 3, 2, 1)
            d["u"] = d["u"].transpose(0, 3, 2, 1)
        return d

    def times(self) -> np.ndarray:
        """Every snapshot's time (reads each file's attributes)."""
        return np.asarray(self._inner.snapshot_times())


class RunDirectory:
    """A run directory (docs/run-directory.md), opened by :func:`open`. Files are read when a
    property is asked for: the config and the list of snapshots on opening, the time series on
    each access to :attr:`timeseries`, a snapshot when indexed."""

    def __init__(self, path: PathLike) -> None:
        self._inner = _motile.open(os.fspath(path))

    @property
    def path(self) -> str:
        return self._inner.path

    @property
    def model(self) -> str:
        """``"particle"`` or ``"meanfield"``."""
        return self._inner.model

    @property
    def config(self) -> dict:
        """The resolved config: every key, defaults filled in (``config.toml`` less its
        ``[motile]`` header)."""
        return self._inner.config

    @property
    def timeseries(self) -> TimeSeries:
        """``timeseries.csv``: columns by name, with units."""
        return self.read_csv("timeseries.csv")

    def read_csv(self, file: str) -> TimeSeries:
        """Another CSV file of the run, such as ``analysis/correlations.csv``."""
        return TimeSeries(*self._inner.read_csv(file), source=os.path.join(self.path, file))

    @property
    def snapshots(self) -> _Snapshots:
        """The snapshots, a sequence read lazily: ``run.snapshots[-1]``."""
        return _Snapshots(self._inner)

    @property
    def status(self) -> dict:
        """``{"state", "t", "t_end", "reason"}``: ``state`` is ``"finished"``, ``"resumable"``
        (stopped with a checkpoint), ``"failed"`` (with ``reason`` from the log and the state
        before the failed step in ``checkpoints/last_good.h5``) or ``"empty"``; ``t`` the last
        time in the time series."""
        return self._inner.status()

    def __repr__(self) -> str:
        return repr(self._inner)


def open(path: PathLike) -> RunDirectory:  # noqa: A001 (the module's verb, as h5py.File)
    """Open the run directory ``path`` (``ValueError`` if it is not one)."""
    return RunDirectory(path)


# --- analysis ---------------------------------------------------------------------------------


def nufft1(
    points: Any,
    strengths: Any,
    box_length: float,
    modes: Union[int, Sequence[int]],
    tolerance: float = 1e-6,
) -> np.ndarray:
    """Type-1 NUFFT: ``c[m] = sum_j s_j exp(-i k_m . x_j)``, ``k_m = 2 pi m / L``.

    ``points`` ``(N, 3)`` in the periodic box ``[0, L)^3`` (others are wrapped); ``strengths``
    ``(N,)`` or ``(K, N)`` (K transforms sharing the points), real or complex; ``modes`` per
    axis (an int or three). Returns complex ``(Mx, My, Mz)`` or ``(K, Mx, My, Mz)``, centred
    modes (see the module's conventions). ``tolerance`` bounds the relative L2 error over all
    modes, as FINUFFT's (1e-15 to 1e-1).
    """
    x = _rows(points, "points", 3)
    m = _modes(modes)
    box = _positive(box_length, "box_length")
    tol = _tolerance(tolerance)
    s = _array(strengths, "strengths", np.complex128)
    single = s.ndim == 1
    s2 = s.reshape(1, -1) if single else s
    if s2.ndim != 2 or s2.shape[1] != x.shape[0]:
        raise ValueError(f"strengths: expected shape ({x.shape[0]},) or (K, {x.shape[0]}), got {s.shape}")
    c = _motile.nufft1(x, s2, box, m, tol).transpose(0, 3, 2, 1)
    return c[0] if single else c


def nufft2(
    points: Any,
    coefficients: Any,
    box_length: float,
    tolerance: float = 1e-6,
) -> np.ndarray:
    """Type-2 NUFFT: ``s_j = sum_m c[m] exp(+i k_m . x_j)``, the adjoint of :func:`nufft1`.

    ``coefficients`` ``(Mx, My, Mz)`` or ``(K, Mx, My, Mz)`` with centred modes. Returns complex
    ``(N,)`` or ``(K, N)``. ``tolerance`` bounds the relative L2 error over all points.
    """
    x = _rows(points, "points", 3)
    box = _positive(box_length, "box_length")
    tol = _tolerance(tolerance)
    c = _array(coefficients, "coefficients", np.complex128)
    single = c.ndim == 3
    c4 = c[None] if single else c
    if c4.ndim != 4:
        raise ValueError(f"coefficients: expected shape (Mx, My, Mz) or (K, Mx, My, Mz), got {c.shape}")
    _modes(c4.shape[1:])
    s = _motile.nufft2(x, np.ascontiguousarray(c4.transpose(0, 3, 2, 1)), box, tol)
    return s[0] if single else s


def velocity_autocorrelation(
    points: Any,
    velocities: Any,
    box_length: float,
    modes: Optional[int] = None,
    tolerance: float = 1e-6,
    shell_width: Optional[float] = None,
) -> tuple:
    """The radial velocity autocorrelation of velocities sampled at points in a periodic box
    (docs/MODEL.md §6, A2): ``u~(k) = (1/N) sum_n u_n exp(-i k . x_n)`` on ``modes`` per axis
    (default ``max(4, floor(L/2))``, as ``motile analyze``) by a type-1 NUFFT at ``tolerance``,
    then ``Corr(r) = sum_k |u~(k)|^2 j0(|k| r)`` at ``r = 0, w, 2w, ... <= L/2``
    (``w = shell_width``, default ``L/128``). ``Corr(0)`` is the mean square of the field the
    retained modes resolve. Returns ``(r, corr)`` in the units of the inputs.
    """
    x = _rows(points, "points", 3)
    u = _rows(velocities, "velocities", 3, x.shape[0])
    box = _positive(box_length, "box_length")
    tol = _tolerance(tolerance)
    if modes is not None:
        if not np.isscalar(modes):
            raise ValueError(f"modes: expected one int (the same count on every axis), got {modes!r}")
        modes = _modes(modes)[0]
    if shell_width is not None:
        shell_width = _positive(shell_width, "shell_width")
    return _motile.velocity_autocorrelation(x, u, box, modes, tol, shell_width)


def velocity_norm(u: Any) -> float:
    """The volume-averaged L2 norm ``sqrt(< |u|^2 >)`` of a field on a uniform grid: ``u`` of
    shape ``(C, n1, n2, ...)`` (C components; any grid shape), as the mean-field time series'
    ``u_l2``."""
    a = _array(u, "u")
    if a.ndim < 2:
        raise ValueError(f"u: expected shape (C, n, n, n) (components first), got {a.shape}")
    return _motile.l2_norm(np.ascontiguousarray(a.reshape(a.shape[0], -1)))


def relative_entropy(q: Any, degree: int = 20) -> float:
    """The relative entropy ``H = < c ln c + c h(Q/c) >`` of a field of second moments Q
    (docs/MODEL.md §4), the volume average over equal grid cells: ``q`` as ``(6, n, n, n)`` (a
    mean-field snapshot's ``Q``) or rows ``(P, 6)``. ``degree``: the closure tables' (default 20,
    the runs' default; built once, cached on disk)."""
    return _motile.relative_entropy(_q_rows(q), _degree(degree))


def bingham_closure(q: Any, degree: int = 20) -> np.ndarray:
    """The Bingham closure's fourth moment ``c S_(ij)(kl)`` of each second moment Q: ``q`` as
    rows ``(P, 6)`` or a ``(6, ...)`` field; returns ``(P, 6, 6)`` symmetric matrices over the
    components xx, xy, xz, yy, yz, zz (a field's points in C order of its grid axes)."""
    return _motile.bingham_closure(_q_rows(q), _degree(degree))


def _degree(degree: Any) -> int:
    if not isinstance(degree, (int, np.integer)) or not 10 <= degree <= 200:
        raise ValueError(f"degree: expected an int in 10..=200 (a run's closure_degree), got {degree!r}")
    return int(degree)


def mean_squared_displacement(x0: Any, xt: Any) -> float:
    """``< |x_t - x_0|^2 >`` over rods, from unwrapped positions ``(N, 3)`` at two times (a
    snapshot's :meth:`Snapshot.unwrapped`)."""
    a = _rows(x0, "x0", 3)
    b = _rows(xt, "xt", 3, a.shape[0])
    return _motile.msd(a, b)
