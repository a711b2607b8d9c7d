#!/usr/bin/env bash
# Benchmarks Jello (each SIMD tier) against NumPy, Numba, Taichi, Warp and C peers; writes BENCHMARKS.md.
#   scripts/benchmarks.sh [--seconds S] [--quick] [--only numpy,numba] [--rounds R] [--no-check]
# Makes (or reuses) the virtual environment bench/.venv, installs the pinned
# bench/peers/requirements.txt, builds target/release/jello, then runs scripts/benchmarks.py.
set -euo pipefail
cd "$(dirname "$0")/.."

PYTHON=${PYTHON:-python3}
VENV=bench/.venv
REQ=bench/peers/requirements.txt

if [ ! -x "$VENV/bin/python" ]; then
    echo "benchmarks: creating $VENV" >&2
    "$PYTHON" -m venv "$VENV"
fi
# Reinstall only when the requirements changed since the last successful install.
STAMP="$VENV/.requirements.installed"
if ! cmp -s "$REQ" "$STAMP"; then
    rm -f "$VENV/pip-failures.log"
    "$VENV/bin/python" -m pip install -q --upgrade pip >&2 || true
    if "$VENV/bin/python" -m pip install -r "$REQ" >&2; then
        cp "$REQ" "$STAMP"
    else
        # Install what can be installed; a peer whose library is missing is reported as failed
        # in BENCHMARKS.md together with this log.
        echo "benchmarks: installing $REQ as a whole failed; trying one package at a time" >&2
        while read -r pkg; do
            case "$pkg" in ''|\#*) continue ;; esac
            if ! out=$("$VENV/bin/python" -m pip install "$pkg" 2>&1); then
                { echo "pip install $pkg failed:"; echo "$out" | tail -n 5; } >>"$VENV/pip-failures.log"
            fi
        done <"$REQ"
    fi
fi

if command -v cargo >/dev/null; then
    cargo build --release -p jello-cli >&2 \
        || echo "benchmarks: cargo build failed; using target/release/jello if it exists" >&2
else
    echo "benchmarks: cargo not found; using target/release/jello if it exists" >&2
fi

exec "$VENV/bin/python" scripts/benchmarks.py "$@"
