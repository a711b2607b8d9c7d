#!/usr/bin/env bash
# How much of a step the contacts between bodies take on fifty shapes dropped into a box
# (issue 45); writes the "Contact between bodies: fifty shapes" section of BENCHMARKS.md.
#   scripts/contact-share.sh [--time 2.5] [--threads 1,2] [--repeat 3]
# Builds target/release/jello, then runs scripts/contact_share.py (standard library only).
set -euo pipefail
cd "$(dirname "$0")/.."

cargo build --release -p jello-cli >&2
exec python3 scripts/contact_share.py "$@"
