"""Contacts between bodies from Python and as a user measures them: self-contact in a scene made
in Python, and `scripts/contact_report.py` on the OBJ frames of two cubes resting on each other."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import jello

from conftest import REPO


def test_self_contact_is_asked_for_by_name() -> None:
    on = jello.create([jello.cube(4, size=0.5)], self_contact=True)
    off = jello.create([jello.cube(4, size=0.5)])
    assert "self_contact = true" in on.dumps()
    assert "self_contact" not in off.dumps()


def test_the_report_finds_cubes_resting_skin_to_skin(cli: Path, tmp_path: Path) -> None:
    """Two 0.5 m cubes of 5³ points dropped on each other: at rest their skins are neither apart
    nor inside each other by more than 2 % of a cell (0.125 m), and they stay one above the
    other."""
    scene = tmp_path / "pair.toml"
    subprocess.run(
        [cli, "create", scene, "--cube", "5", "--size", "0.5", "--centre", "0,0,-1.75",
         "--total-mass", "1", "--cube", "5", "--size", "0.5", "--centre", "0,0,-1.2",
         "--total-mass", "1", "--collision-stiffness", "2000"],
        check=True, capture_output=True,
    )
    frames = tmp_path / "frames"
    subprocess.run(
        [cli, "run", scene, "--time", "3", "--frames", frames, "--format", "obj", "--every", "1000", "-q"],
        check=True, capture_output=True,
    )
    out = subprocess.run(
        [sys.executable, REPO / "scripts" / "contact_report.py", frames, "--json", "--drift"],
        check=True, capture_output=True, text=True,
    )
    report = json.loads(out.stdout)
    assert [p["bodies"] for p in report["pairs"]] == [["cube1", "cube2"]]
    cell = 0.125
    assert report["deepest_overlap"] < 0.02 * cell, report
    assert report["largest_gap"] < 0.02 * cell, report
    assert all(d < 0.01 for d in report["drift"].values()), report
