# Sourced by scripts/frame-rate.sh and scripts/pile-bench.sh (not run alone): makes (or reuses)
# bench/.venv with the pinned rapier3d and numpy of bench/peers/requirements-rapier.txt, and sets
# VENV to it. Expects to be sourced from the repository root.
PYTHON=${PYTHON:-python3}
VENV=bench/.venv
REQ=bench/peers/requirements-rapier.txt

if [ ! -x "$VENV/bin/python" ]; then
    echo "$(basename "$0"): creating $VENV" >&2
    "$PYTHON" -m venv "$VENV"
fi
STAMP="$VENV/.requirements-rapier.installed"
if ! cmp -s "$REQ" "$STAMP"; then
    "$VENV/bin/python" -m pip install -q -r "$REQ" >&2
    cp "$REQ" "$STAMP"
fi
