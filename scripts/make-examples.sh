#!/usr/bin/env bash
# Makes the example worlds in examples/ with `jello create`.
#   scripts/make-examples.sh           rewrite examples/
#   scripts/make-examples.sh --check   fail if examples/ differs from what this script makes
# The first five are the official worlds of the original assignment, made anew: they equal the
# official files up to the original writer's six decimals (1/512 is 0.001953 there).
set -euo pipefail
cd "$(dirname "$0")/.."
jello=${JELLO:-target/release/jello}
[ -x "$jello" ] || cargo build --release --quiet -p jello-cli

check=false
out=examples
if [ "${1:-}" = "--check" ]; then
  check=true
  out=$(mktemp -d)
  trap 'rm -rf "$out"' EXIT
fi
mkdir -p "$out"

corner=7,7,7:0.14285714285714285,0.14285714285714285,0.14285714285714285
stiff=(--k-elastic 500 --d-elastic 0.25 --k-collision 1000 --d-collision 0.25)
create() { "$jello" create --force "$@" >/dev/null; }

# The official five.
create "$out/jello.w" --dt 0.0005 --plane=-1,1,1,2 --field uniform:0,0,0 \
  --drag "$corner" --velocity=10,-10,20
create "$out/gravity.w" --dt 0.0001 "${stiff[@]}" --plane=-1,1,2,6 \
  --field uniform:0,0,-0.06 --velocity=10,-10,0
create "$out/moveLeft.w" --dt 0.0005 "${stiff[@]}" --field uniform:0,0,0 --velocity=-50,0,0
create "$out/rotate.w" --dt 0.001 "${stiff[@]}" --plane=1,-1,-1,4 --field vortex:0.009765625:z
create "$out/skewedCorner.w" --dt 0.00001 "${stiff[@]}" --field uniform:0,0,0 --drag "$corner"

# More to play with.
create "$out/drop.w" --field gravity --res 2 --plane=0.2,0.1,1,1.5 --offset=-0.5,-0.5,0.5 --rotate 20,35,10
create "$out/spin.w" --field gravity --res 2 --offset=-0.5,-0.5,-1.9 --spin 0,0,12 --velocity 3,0,6
create "$out/tornado.w" --field tornado:0.02 --res 16 --offset=-1.5,-1.5,-1.9 --velocity 0,2,0 --scale 0.8
create "$out/squash.w" --integrator SymplecticEuler --dt 0.0002 --field radial:0.05 --res 2 --scale 1.4 --offset=-0.7,-0.7,-0.7

if $check; then
  if ! diff -r -q "$out" examples; then
    echo "examples/ is out of date: run scripts/make-examples.sh" >&2
    exit 1
  fi
  echo "examples/ is up to date"
fi
