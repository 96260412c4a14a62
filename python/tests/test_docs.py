"""docs/python.md's examples (and docs/run-directory.md's), run as written, so that none can go
stale.

Every ```python block runs in order in one namespace, in a scratch directory, with two
shortenings that leave what the examples call unchanged:
- `motile.run` runs each config as given, every key checked by the real parser, but to
  t_end = 5 dt (the examples ask for 40/beta and a 32^3 grid to the default end: minutes);
- `motile.run_scene("demo", ...)` is checked by `motile run demo --dry-run` (the demo takes
  about four minutes on 2 cores; tests/tests/demo_physics.rs runs it whole).
The run directories the examples open ("runs/demo/particle", "runs/demo/meanfield") are made
first by short runs of the same kind, analysed as the demo's are. Where matplotlib is missing
the worked example's plotting calls go to a stand-in (the motile calls still run).

Every ```text block's `>>> call` is evaluated and must raise the error shown (up to a `...`).
"""

import os
import re
import subprocess
import sys
import types
from pathlib import Path
from unittest import mock

import numpy as np
import pytest

import motile

from test_motile import motile_binary

ROOT = Path(__file__).resolve().parents[2]
DOC = ROOT / "docs" / "python.md"


def blocks(lang: str, doc: Path = DOC) -> list:
    """The fenced blocks of `lang` in `doc`, in order."""
    return re.findall(rf"```{lang}\n(.*?)```", doc.read_text(), flags=re.S)


@pytest.fixture
def scratch(tmp_path, monkeypatch):
    """A scratch working directory holding the demo's two run directories (short runs)."""
    monkeypatch.chdir(tmp_path)
    real_run = motile.run
    real_run(
        "particle",
        {"box_length": 8.0, "hydrodynamics": "sbt-explicit", "dt": 0.05, "t_end": 0.5,
         "snapshot_interval": 0.25, "vtk": False},
        "runs/demo/particle",
        progress=False,
    )
    real_run("meanfield", {"grid": 8, "t_end": 1.0}, "runs/demo/meanfield", progress=False)
    done = subprocess.run([motile_binary(), "analyze", "runs/demo/particle"], capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    calls = []

    def short_run(model, config, out, progress=True):
        cfg = dict(config or {})
        dt = cfg.get("dt", 0.02 if model == "particle" else 0.05)
        cfg["t_end"] = 5 * dt
        calls.append((model, dict(config or {})))
        return real_run(model, cfg, out, progress=False)

    def checked_scene(name, out, only=None, progress=True):
        done = subprocess.run([motile_binary(), "run", os.fspath(name), "--out", os.fspath(out), "--dry-run"],
                              capture_output=True, text=True)
        assert done.returncode == 0, f"motile run {name} --dry-run: {done.stderr}"
        calls.append(("scene", name))
        return done.stdout

    monkeypatch.setattr(motile, "run", short_run)
    monkeypatch.setattr(motile, "run_scene", checked_scene)
    return calls


def plotting_stand_in(monkeypatch) -> None:
    """matplotlib where it is installed (drawing off screen), else a stand-in for pyplot."""
    try:
        import matplotlib

        matplotlib.use("Agg")
    except ImportError:
        pyplot = mock.MagicMock()
        pyplot.subplots.return_value = (mock.MagicMock(), mock.MagicMock())
        package = types.ModuleType("matplotlib")
        package.pyplot = pyplot
        monkeypatch.setitem(sys.modules, "matplotlib", package)
        monkeypatch.setitem(sys.modules, "matplotlib.pyplot", pyplot)


def test_the_python_examples_run_as_written(scratch, monkeypatch):
    code = blocks("python")
    assert len(code) >= 4, f"{len(code)} python blocks in {DOC}"
    plotting_stand_in(monkeypatch)
    namespace = {}
    for i, block in enumerate(code):
        try:
            exec(compile(block, f"{DOC.name} python block {i + 1}", "exec"), namespace)
        except Exception as e:  # the block's text with the error, for the reader
            raise AssertionError(f"python block {i + 1} of {DOC} failed: {e!r}\n{block}") from e
    models = [c[0] for c in scratch]
    assert models == ["particle", "meanfield", "scene"], scratch
    # What the examples computed is what they say.
    run = namespace["run"]
    assert run.model == "particle" and "hydro" in run.config
    assert run.status["state"] == "finished", run.status
    assert len(namespace["corr"]) > 0 and namespace["s"].positions.shape[1] == 3
    r, corr = namespace["r"], namespace["corr"]
    assert np.all(np.isfinite(corr)) and r.shape == corr.shape
    assert namespace["c"].shape == (32, 32, 32)


def test_the_python_examples_of_the_file_formats_run(scratch):
    doc = ROOT / "docs" / "run-directory.md"
    code = blocks("python", doc)
    assert code, f"no python block in {doc}"
    namespace = {}
    for block in code:
        exec(compile(block, doc.name, "exec"), namespace)
    assert namespace["x"].shape[1] == 3 and namespace["p"].shape == namespace["x"].shape


def test_the_error_examples_raise_what_they_show(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    rng = np.random.default_rng(1)
    x = rng.uniform(0, 10, (1000, 3))
    u = rng.normal(size=(1000, 3))
    u[3, 1] = np.nan
    namespace = {"motile": motile, "x": x, "s": rng.normal(size=1000), "u": u}
    shown = [
        (m.group(1), m.group(2), m.group(3))
        for block in blocks("text")
        for m in re.finditer(r">>> (.*?)(?:\s+#.*)?\n(\w+): (.*)", block)
    ]
    assert len(shown) >= 4, shown
    for call, kind, message in shown:
        expected = message.split("...")[0].strip()
        with pytest.raises(Exception) as raised:
            eval(call, namespace)
        assert type(raised.value).__name__ == kind, f"{call}: {raised.value!r}"
        assert str(raised.value).startswith(expected), f"{call}:\n  shown  {message}\n  raised {raised.value}"
