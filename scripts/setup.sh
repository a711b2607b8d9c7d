#!/usr/bin/env bash
# Makes sure what `make test` needs is here: cargo with rustfmt and clippy and the wasm32 target
# (added when missing), and a Vulkan loader with a driver for the GPU backend's tests (Mesa's
# lavapipe, which runs the shaders on the CPU, installed from Debian when there is no Vulkan
# driver at all).
set -euo pipefail
export PATH="$HOME/.cargo/bin:$PATH"
if ! command -v cargo >/dev/null 2>&1; then
  echo "setup: cargo not found; install Rust with rustup first" >&2
  exit 1
fi
if command -v rustup >/dev/null 2>&1; then
  for component in rustfmt clippy; do
    rustup component list --installed 2>/dev/null | grep -q "^$component" || rustup component add "$component"
  done
  # `make test` lints the browser core for wasm32 before scripts/web.sh builds it.
  rustup target list --installed | grep -qx wasm32-unknown-unknown \
    || rustup target add wasm32-unknown-unknown
fi

# A Vulkan driver: any (a GPU's), else lavapipe.
icds=$(ls /usr/share/vulkan/icd.d/*.json /etc/vulkan/icd.d/*.json 2>/dev/null || true)
if [ -z "$icds" ] || ! ldconfig -p 2>/dev/null | grep 'libvulkan\.so\.1' >/dev/null; then
  if [ "$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then
    echo "setup: installing Mesa's lavapipe (mesa-vulkan-drivers) for the GPU backend's tests"
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq mesa-vulkan-drivers libvulkan1 >/dev/null
  else
    echo "setup: no Vulkan driver, and not root with apt-get to install Mesa's lavapipe" \
      "(Debian: mesa-vulkan-drivers): the GPU backend's tests will fail" >&2
  fi
fi
