#!/usr/bin/env bash
# Screenshots of the example scenes in the viewer, for docs/viewer.md: builds the viewer and the
# release binary, then web/screenshots.mjs opens each scene in headless Chromium (Debian's, driven
# by playwright-core, as the browser tests), steps it a given simulated time and saves
# docs/images/viewer-<scene>.png (800×500).
#   scripts/screenshots.sh                          the contact examples and the torus (3 s; stack.toml 0.4 s)
#   scripts/screenshots.sh --seconds 2 ring.toml    one scene, another time
#   scripts/screenshots.sh --camera home            the home camera rather than a close one
#   scripts/screenshots.sh --out /tmp/shots         elsewhere
# About 3 minutes on 2 cores, most of it pile.toml's 20 bodies.
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$HOME/.cargo/bin:$PATH"

if [ ! -x "${CHROMIUM:-/usr/bin/chromium}" ]; then
  echo "screenshots.sh: no Chromium at ${CHROMIUM:-/usr/bin/chromium} (scripts/web-test.sh installs it)" >&2
  exit 1
fi
scripts/web.sh
cargo build --release -p jello-cli
node web/screenshots.mjs "$@"
