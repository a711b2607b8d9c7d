# The few verbs a newcomer needs.
#   make run    build everything (binary, wasm, web bundle), then serve the viewer on the default
#               world: `jello view examples/jello.w` prints the URL to open
#   make test   everything CI runs: format, lints, docs, the aarch64 build (type-checked, and run
#               under qemu against the native one), all tests (the GPU backend's on any Vulkan
#               adapter: Mesa's lavapipe where there is no GPU), examples up to date, and the
#               Python package's tests (its own venv, pytest), and the viewer's browser tests
#               (Playwright + Chromium)
#   make fuzz   fuzz the world-file, OBJ, STL and scene parsers in turn, FUZZ_SECONDS each (one with
#               FUZZ_TARGET=parse_obj; installs cargo-fuzz and nightly when missing)
#   make bench  Jello (each SIMD tier) against NumPy, Numba, Taichi, Warp and C; rewrites
#               BENCHMARKS.md

JELLO := target/release/jello
WORLD ?= examples/jello.w
PORT ?= 7878
FUZZ_SECONDS ?= 60
FUZZ_TARGET ?=

.PHONY: setup build web run test examples fuzz bench

# What the tests need and a fresh machine may lack (rustfmt, clippy, the wasm32 target, a
# Vulkan driver): scripts/setup.sh adds what is missing and does nothing otherwise.
setup:
	scripts/setup.sh

# The `jello` binary (the GPU backend is a feature of its own: `--features gpu`).
build:
	cargo build --release -p jello-cli

web:
	scripts/web.sh

run: build web
	$(JELLO) view $(WORLD) --port $(PORT)

# The GPU build of the command line is linted and tested as `--workspace --features
# jello-cli/gpu`: the same features for every other crate as the plain `--workspace` run, so only
# jello-cli is built again (`-p jello-cli --features gpu` unifies features differently and rebuilt
# jello-core and the whole wgpu stack: 210 s of a CI run against 17 s). The release build is the
# `jello` binary alone, all the examples, the Python tests and the browser tests use of it.
test: setup
	cargo fmt --all --check
	cargo clippy --workspace --all-targets -- -D warnings
	cargo clippy --workspace --all-targets --features jello-cli/gpu -- -D warnings
	RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --quiet
	scripts/aarch64-check.sh
	cargo clippy -p jello-wasm --target wasm32-unknown-unknown -- -D warnings
	cargo build --release -p jello-cli
	scripts/make-examples.sh --check
	cargo test --workspace
	cargo test --workspace --features jello-cli/gpu --test gpu
	scripts/python-test.sh
	scripts/web-test.sh

examples: build
	scripts/make-examples.sh

fuzz:
	scripts/fuzz.sh $(FUZZ_TARGET) $(FUZZ_SECONDS)

bench:
	scripts/benchmarks.sh
