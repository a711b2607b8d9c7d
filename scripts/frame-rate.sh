#!/usr/bin/env bash
# Jello's integrators at frame-rate steps against Rapier's soft bodies (PyPI rapier3d) on the job
# of issue 9; writes the "Frame-rate soft bodies" section of BENCHMARKS.md.
#   scripts/frame-rate.sh [--sizes 8,16,32] [--max-wall 60]
# Makes (or reuses) bench/.venv with the pinned rapier3d and numpy, builds target/release/jello,
# then runs scripts/frame_rate.py.
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON=${PYTHON:-python3}
VENV=bench/.venv
REQ=bench/peers/requirements-rapier.txt

if [ ! -x "$VENV/bin/python" ]; then
    echo "frame-rate: creating $VENV" >&2
    "$PYTHON" -m venv "$VENV"
fi
STAMP="$VENV/.requirements-rapier.installed"
if ! cmp -s "$REQ" "$STAMP"; then
    "$VENV/bin/python" -m pip install -q -r "$REQ" >&2
    cp "$REQ" "$STAMP"
fi
cargo build --release -p jello-cli >&2
exec "$VENV/bin/python" scripts/frame_rate.py "$@"
