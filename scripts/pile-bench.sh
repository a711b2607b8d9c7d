#!/usr/bin/env bash
# The pile scene (examples/pile.toml) with Jello against Rapier's soft bodies (PyPI rapier3d)
# doing the same pile, alternated on the same machine (issue 45); writes the "Pile of bodies"
# section of BENCHMARKS.md.
#   scripts/pile-bench.sh [--time 5] [--reps 3] [--max-wall 300] [--scene examples/pile.toml]
# Makes (or reuses) bench/.venv with the pinned rapier3d and numpy (scripts/rapier-venv.sh),
# builds target/release/jello, then runs scripts/pile_bench.py.
set -euo pipefail
cd "$(dirname "$0")/.."

source scripts/rapier-venv.sh
cargo build --release -p jello-cli >&2
exec "$VENV/bin/python" scripts/pile_bench.py "$@"
