# The few verbs a newcomer needs.
#   make run    build, then run the default world and print its summary
#   make test   everything CI runs: format, lints, docs, all tests, examples up to date
#   make fuzz   fuzz the world-file parser (installs cargo-fuzz and nightly when missing)

JELLO := target/release/jello
WORLD ?= examples/jello.w
FUZZ_SECONDS ?= 60

.PHONY: build run test examples fuzz

build:
	cargo build --release

run: build
	$(JELLO) run $(WORLD)

test:
	cargo fmt --all --check
	cargo clippy --workspace --all-targets -- -D warnings
	RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --quiet
	cargo build --release
	scripts/make-examples.sh --check
	cargo test --workspace

examples: build
	scripts/make-examples.sh

fuzz:
	scripts/fuzz.sh $(FUZZ_SECONDS)
