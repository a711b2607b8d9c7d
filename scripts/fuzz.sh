#!/usr/bin/env bash
# Fuzzes the world-file parser for N seconds (default 60) with cargo-fuzz (libFuzzer).
# Installs the nightly toolchain and cargo-fuzz when they are missing.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=${1:-60}
rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal
command -v cargo-fuzz >/dev/null 2>&1 || cargo install cargo-fuzz
cargo +nightly fuzz run parse_world -- -max_total_time="$seconds"
