#!/usr/bin/env bash
# Type-checks the core and the command line for aarch64 (NEON is that target's baseline tier),
# so code that only compiles on x86-64 is caught on an x86-64 machine. Adds the rust-std of
# aarch64-unknown-linux-gnu with rustup when missing.
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$HOME/.cargo/bin:$PATH"
target=aarch64-unknown-linux-gnu
if command -v rustup >/dev/null 2>&1 && ! rustup target list --installed | grep -qx "$target"; then
  rustup target add "$target"
fi
cargo check --quiet --target "$target" -p jello-core -p jello-cli --all-targets
echo "aarch64-check.sh: jello-core and jello-cli type-check for $target"
