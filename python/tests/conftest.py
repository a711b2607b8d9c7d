"""Shared fixtures: the repository, the `jello` binary, the corpus in ../shared (when present)."""

from __future__ import annotations

import os
import subprocess
from pathlib import Path

import pytest

REPO = Path(__file__).resolve().parents[2]
EXAMPLES = REPO / "examples"
SHARED_WORLDS = REPO.parent / "shared" / "worlds"
OFFICIAL = ["jello.w", "gravity.w", "moveLeft.w", "rotate.w", "skewedCorner.w"]


@pytest.fixture(scope="session")
def cli() -> Path:
    """The release `jello` binary (`make test` builds it first; built here when missing)."""
    exe = Path(os.environ.get("JELLO_CLI", REPO / "target" / "release" / "jello"))
    if not exe.exists():
        subprocess.run(["cargo", "build", "--release", "-p", "jello-cli"], cwd=REPO, check=True)
    return exe


@pytest.fixture(scope="session")
def shared_worlds() -> Path:
    """../shared/worlds, or a skip saying it is absent."""
    if not SHARED_WORLDS.is_dir():
        pytest.skip(f"{SHARED_WORLDS} is absent: the corpus tests need ../shared beside the repository")
    return SHARED_WORLDS
