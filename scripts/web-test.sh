#!/usr/bin/env bash
# Runs the viewer's browser tests: Playwright (playwright-core) drives Debian's Chromium against
# `jello view` (the tests start it on a free port of 127.0.0.1 and stop it).
# Installs Chromium with apt when missing (never `playwright install`), builds the release
# binary and the viewer first.
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$HOME/.cargo/bin:$PATH"

if [ ! -x "${CHROMIUM:-/usr/bin/chromium}" ]; then
  echo "web-test.sh: installing chromium"
  if [ "$(id -u)" = 0 ]; then apt=(apt-get); else apt=(sudo apt-get); fi
  "${apt[@]}" update
  DEBIAN_FRONTEND=noninteractive "${apt[@]}" install -y chromium
fi
scripts/web.sh
cargo build --release -p jello-cli
cd web
node --test --test-concurrency=1 tests/
