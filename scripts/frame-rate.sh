#!/usr/bin/env bash
# Jello's integrators at frame-rate steps against Rapier's soft bodies (PyPI rapier3d) on the job
# of issue 9; writes the "Frame-rate soft bodies" section of BENCHMARKS.md.
#   scripts/frame-rate.sh [--sizes 8,16,32] [--max-wall 60]
# Makes (or reuses) bench/.venv with the pinned rapier3d and numpy (scripts/rapier-venv.sh),
# builds target/release/jello, then runs scripts/frame_rate.py.
set -euo pipefail
cd "$(dirname "$0")/.."

source scripts/rapier-venv.sh
cargo build --release -p jello-cli >&2
exec "$VENV/bin/python" scripts/frame_rate.py "$@"
