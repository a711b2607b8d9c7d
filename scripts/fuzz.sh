#!/usr/bin/env bash
# Fuzzes the parsers with cargo-fuzz (libFuzzer).
#
#   scripts/fuzz.sh [TARGET...] [SECONDS]
#
# Runs each TARGET (default: every target `cargo fuzz list` gives, in turn: parse_obj, parse_scene, parse_stl,
# parse_world) for SECONDS (default 60). A target's corpus is fuzz/corpus/TARGET, seeded from
# fuzz/seeds/TARGET when that exists; crashes land in fuzz/artifacts/TARGET.
# Installs the nightly toolchain and cargo-fuzz when they are missing.
set -euo pipefail
cd "$(dirname "$0")/.."

seconds=60
targets=()
for arg in "$@"; do
    if [[ $arg =~ ^[0-9]+$ ]]; then
        seconds=$arg
    else
        targets+=("$arg")
    fi
done

rustup toolchain list | grep -q '^nightly' || rustup toolchain install nightly --profile minimal
command -v cargo-fuzz >/dev/null 2>&1 || cargo install cargo-fuzz

known=$(cargo +nightly fuzz list)
if [ ${#targets[@]} -eq 0 ]; then
    mapfile -t targets <<<"$known"
fi
for target in "${targets[@]}"; do
    if ! grep -qx "$target" <<<"$known"; then
        echo "fuzz.sh: unknown target '$target'; the targets are:" $known >&2
        exit 2
    fi
done

for target in "${targets[@]}"; do
    corpus=("fuzz/corpus/$target")
    mkdir -p "${corpus[0]}"
    if [ -d "fuzz/seeds/$target" ]; then
        corpus+=("fuzz/seeds/$target")
    fi
    echo "== fuzz.sh: $target for $seconds s"
    cargo +nightly fuzz run "$target" "${corpus[@]}" -- -max_total_time="$seconds"
done
