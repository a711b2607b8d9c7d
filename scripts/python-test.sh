#!/usr/bin/env bash
# The Python package's checks: rustfmt and clippy on its native module, then `pip install
# "./python[test]"` (the README's install command, with the test tools) into its own venv,
# python/.venv (made when missing, with $PYTHON or python3, which must be 3.10 or newer), then
# pytest, whose tests compare with the release `jello` binary (built first).
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$HOME/.cargo/bin:$PATH"

python=${PYTHON:-python3}
if ! "$python" -c 'import sys; sys.exit(sys.version_info < (3, 10))' 2>/dev/null; then
  echo "python-test.sh: $python is missing or older than 3.10 (set PYTHON to a newer one)" >&2
  exit 1
fi
venv=python/.venv
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c 'import sys; sys.exit(sys.version_info < (3, 10))'; then
  rm -rf "$venv"
  "$python" -m venv "$venv"
fi
"$venv/bin/python" -m pip install --quiet --upgrade pip

cargo fmt --manifest-path python/Cargo.toml --check
PYO3_PYTHON="$PWD/$venv/bin/python" cargo clippy --manifest-path python/Cargo.toml --all-targets --quiet -- -D warnings

cargo build --release -p jello-cli
"$venv/bin/python" -m pip install --quiet "./python[test]"
# The GPU tests fail, rather than skip, without an adapter: scripts/setup.sh installs Mesa's
# lavapipe. JELLO_REQUIRE_GPU=0 lets them skip on a machine without one.
export JELLO_REQUIRE_GPU="${JELLO_REQUIRE_GPU:-1}"
# From the repository's root, so that `import jello` is the installed package, not python/jello.
"$venv/bin/pytest" -q python/tests
