#!/usr/bin/env bash
# Builds the browser viewer: the jello-wasm core for wasm32, its JavaScript bindings
# (wasm-bindgen), then the TypeScript + three.js bundle in web/dist (Vite).
#   scripts/web.sh          build
# Installs what is missing: the wasm32 target, wasm-bindgen-cli of exactly the pinned version
# (cargo install, about 9 minutes on 2 cores, so only when missing or different), npm packages
# (npm ci, when node_modules is missing or older than package-lock.json).
set -euo pipefail
cd "$(dirname "$0")/.."
export PATH="$HOME/.cargo/bin:$PATH"

# The wasm-bindgen version the crate pins ("=X" in crates/jello-wasm/Cargo.toml).
version=$(sed -n 's/^wasm-bindgen = "=\([0-9.]*\)"/\1/p' crates/jello-wasm/Cargo.toml)
[ -n "$version" ] || { echo "web.sh: no pinned wasm-bindgen version in crates/jello-wasm/Cargo.toml" >&2; exit 1; }

if command -v rustup >/dev/null 2>&1 && ! rustup target list --installed | grep -qx wasm32-unknown-unknown; then
  rustup target add wasm32-unknown-unknown
fi
if [ "$(wasm-bindgen --version 2>/dev/null | awk '{print $2}')" != "$version" ]; then
  echo "web.sh: installing wasm-bindgen-cli $version (takes a while, once)"
  cargo install wasm-bindgen-cli --version "$version" --force
fi
if ! command -v node >/dev/null 2>&1; then
  echo "web.sh: node (>= 20.19) and npm are needed to build the viewer" >&2
  exit 1
fi

cargo build --profile wasm --target wasm32-unknown-unknown -p jello-wasm
rm -rf web/src/wasm
wasm-bindgen --target web --out-dir web/src/wasm \
  target/wasm32-unknown-unknown/wasm/jello_wasm.wasm

cd web
if [ ! -d node_modules ] || [ package-lock.json -nt node_modules ]; then
  npm ci --no-audit --no-fund
  touch node_modules
fi
npm run --silent build
echo "web.sh: built web/dist"
