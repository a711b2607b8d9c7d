"""The examples run as scripts and as a notebook, and type-check against the stubs."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import pytest

from conftest import REPO

EXAMPLES_DIR = REPO / "python" / "examples"


def run_example(name: str, *args: str) -> subprocess.CompletedProcess[str]:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    return subprocess.run(
        [sys.executable, str(EXAMPLES_DIR / name), *args],
        cwd=REPO, env=env, capture_output=True, text=True, timeout=300,
    )


def test_energy_plot_writes_a_png(tmp_path: Path) -> None:
    out = tmp_path / "energy.png"
    run = run_example("energy_plot.py", "examples/rotate.w", "--time", "0.2", "--out", str(out))
    assert run.returncode == 0, run.stderr
    assert out.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


def test_energy_plot_reports_a_blow_up() -> None:
    run = run_example("energy_plot.py", "examples/jello.w", "--dt", "0.01", "--out", "/dev/null")
    assert run.returncode == 3
    assert "blew up" in run.stderr


def test_animate_writes_a_gif_of_every_frame(tmp_path: Path) -> None:
    iio = pytest.importorskip("imageio.v3")
    out = tmp_path / "stack.gif"
    run = run_example("animate.py", "examples/stack.toml", "--time", "0.2", "--fps", "25", "--out", str(out))
    assert run.returncode == 0, run.stderr
    frames = iio.imread(out, index=None)
    assert frames.shape[0] == 6 and frames.shape[-1] == 3
    bad = run_example("animate.py", "--out", str(tmp_path / "x.avi"))
    assert bad.returncode == 2 and "expected a .gif or .mp4" in bad.stderr
    assert not (tmp_path / "x.avi").exists()


def test_the_sweep_example_prints_its_table() -> None:
    run = run_example("sweep_stiffness.py", "--scheduler", "serial", "--time", "0.02")
    assert run.returncode == 0, run.stderr
    lines = run.stdout.strip().splitlines()
    assert lines[0].split()[:4] == ["world", "stiffness", "integrator", "dt"]
    assert len(lines) == 1 + 16


def test_the_notebook_runs(monkeypatch: pytest.MonkeyPatch) -> None:
    pytest.importorskip("IPython")
    import matplotlib

    matplotlib.use("Agg")
    notebook = json.loads((EXAMPLES_DIR / "jello.ipynb").read_text())
    monkeypatch.chdir(REPO / "python" / "examples")
    namespace: dict[str, object] = {}
    for cell in notebook["cells"]:
        if cell["cell_type"] == "code":
            exec(compile("".join(cell["source"]), "jello.ipynb", "exec"), namespace)
    table = namespace["table"]
    assert len(table) == 4  # type: ignore[arg-type]


def test_the_examples_type_check_strictly_against_the_stubs() -> None:
    api = pytest.importorskip("mypy.api")
    files = [str(p) for p in sorted(EXAMPLES_DIR.glob("*.py"))]
    config = str(REPO / "python" / "pyproject.toml")
    stdout, stderr, status = api.run(
        ["--strict", "--no-incremental", "--config-file", config, *files, str(REPO / "python" / "jello")]
    )
    assert status == 0, stdout + stderr
