#!/usr/bin/env bash
# The aarch64 build (NEON is that target's baseline tier), checked on an x86-64 machine:
#  1. the core and the command line type-check for aarch64-unknown-linux-gnu;
#  2. the release `jello` cross-built for aarch64 runs under qemu-user and saves the same bytes
#     as the native build, world by world (every tier computes the same bits; so does NEON).
# Installs what is missing: the target's rust-std (rustup), and Debian's qemu-user,
# gcc-aarch64-linux-gnu and libc6-dev-arm64-cross (about 20 s). Step 2 is skipped, with a
# message, where they cannot be installed (not root, no apt).
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$HOME/.cargo/bin:$PATH"
target=aarch64-unknown-linux-gnu
if command -v rustup >/dev/null 2>&1 && ! rustup target list --installed | grep -qx "$target"; then
  if ! rustup target add "$target"; then
    echo "aarch64-check.sh: cannot add the $target target here (offline?): skipping the aarch64 check"
    exit 0
  fi
fi
cargo check --quiet --target "$target" -p jello-core -p jello-cli --all-targets
echo "aarch64-check.sh: jello-core and jello-cli type-check for $target"

if ! command -v qemu-aarch64 >/dev/null 2>&1 || ! command -v aarch64-linux-gnu-gcc >/dev/null 2>&1; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "aarch64-check.sh: installing qemu-user and the aarch64 cross linker"
    if ! { apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq \
        qemu-user gcc-aarch64-linux-gnu libc6-dev-arm64-cross >/dev/null; }; then
      echo "aarch64-check.sh: cannot install them here (offline?): skipping the run under qemu"
      exit 0
    fi
  else
    echo "aarch64-check.sh: qemu-aarch64 or aarch64-linux-gnu-gcc missing and cannot be installed here: skipping the run under qemu"
    exit 0
  fi
fi

export CARGO_TARGET_AARCH64_UNKNOWN_LINUX_GNU_LINKER=aarch64-linux-gnu-gcc
cargo build --quiet --release --target "$target" -p jello-cli
cargo build --quiet --release -p jello-cli
arm=target/$target/release/jello
native=target/release/jello
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
# Each integrator, the plane and a field; 150 steps each (qemu runs about 50 times slower).
for case in "rotate.w rk4" "skewedCorner.w euler" "jello.w rk2" "tornado.w symplecticeuler" \
  "spin.w backwardeuler"; do
  set -- $case
  "$native" run "examples/$1" --integrator "$2" --steps 150 -q --save "$tmp/native.w" >/dev/null
  qemu-aarch64 -L /usr/aarch64-linux-gnu "$arm" run "examples/$1" --integrator "$2" --steps 150 -q \
    --save "$tmp/arm.w" >/dev/null
  if ! cmp -s "$tmp/native.w" "$tmp/arm.w"; then
    echo "aarch64-check.sh: examples/$1 with $2: the aarch64 build saved a different state" >&2
    exit 1
  fi
done
echo "aarch64-check.sh: the aarch64 build (under qemu) saves the same bytes as the native one on 5 worlds"
