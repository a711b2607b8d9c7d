#!/usr/bin/env bash
# Makes the example worlds and scenes in examples/ with `jello create`, the scenes from meshes
# that `jello shape` makes (no third-party model).
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
meshes=$(mktemp -d)
cleanup=("$meshes")
trap 'rm -rf "${cleanup[@]}"' EXIT
if [ "${1:-}" = "--check" ]; then
  check=true
  out=$(mktemp -d)
  cleanup+=("$out")
fi
mkdir -p "$out"

corner=7,7,7:0.14285714285714285,0.14285714285714285,0.14285714285714285
stiff=(--stiffness 500 --damping 0.25 --collision-stiffness 1000 --collision-damping 0.25)
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
create "$out/drop.w" --field gravity --resolution 2 --plane=0.2,0.1,1,1.5 --offset=-0.5,-0.5,0.5 --rotation 20,35,10
create "$out/spin.w" --field gravity --resolution 2 --offset=-0.5,-0.5,-1.9 --spin 0,0,12 --velocity 3,0,6
create "$out/tornado.w" --field tornado:0.02 --resolution 16 --offset=-1.5,-1.5,-1.9 --velocity 0,2,0 --scale 0.8
create "$out/squash.w" --integrator SymplecticEuler --dt 0.0002 --field radial:0.05 --resolution 2 --scale 1.4 --offset=-0.7,-0.7,-0.7

# Scenes of shapes. One material for all: resolution-independent (density in kg/m³, modulus in
# Pa, viscosity in Pa·s; see docs/scenes.md#materials), with walls and obstacles stiff enough for its weight.
for shape in torus blob mould; do
  "$jello" shape "$shape" "$meshes/$shape.obj" --detail 8 >/dev/null
done
jelly=(--density 1000 --modulus 2e5 --viscosity 40)
scene=(--dt 0.001 --collision-stiffness 2e5 --collision-damping 50)
# A ring dropped tilted on the floor.
create "$out/torus.toml" "${scene[@]}" --mesh "$meshes/torus.obj" --cells 12 --centre 0,0,-1 \
  --rotation 35,10,0 "${jelly[@]}"
# A lumpy blob thrown spinning down a ramp.
create "$out/blob.toml" "${scene[@]}" --plane=0.35,0,1,1.5 --mesh "$meshes/blob.obj" --cells 10 \
  --centre=-0.8,0.3,0 --rotation 20,0,30 --spin 0,0,2 "${jelly[@]}"
# A fluted jelly mould turned out onto a plate and pushed: it wobbles to a stop (friction).
create "$out/mould.toml" "${scene[@]}" --box=-0.8,-0.8,-2,0.8,0.8,-1.9 --mesh "$meshes/mould.obj" \
  --cells 12 --centre 0,0,-1.4 --velocity 1,0,0 "${jelly[@]}"
# Three cubes stacked a little askew, dropped on a ball.
create "$out/stack.toml" "${scene[@]}" --sphere 0,0,-1.5,0.45 \
  --cube 5 --size 0.5 --centre 0.1,0,-0.75 --name bottom "${jelly[@]}" \
  --cube 5 --size 0.5 --centre 0.15,0.05,0 --rotation 0,0,20 --name middle "${jelly[@]}" \
  --cube 5 --size 0.5 --centre 0.1,0.1,0.75 --rotation 0,0,40 --name top "${jelly[@]}"

# Five firm cubes stacked on the floor: a tower that stands (a softer jelly, modulus 2e5 Pa,
# buckles under its own weight at this height, as a column would).
tower=()
for i in 1 2 3 4 5; do
  tower+=(--cube 5 --size 0.3 --centre "0,0,$(( 30 * i - 215 ))e-2" --name "cube$i" --density 1000 --modulus 2e6 --viscosity 40)
done
create "$out/tower.toml" --dt 0.0005 --collision-stiffness 2e6 --collision-damping 200 "${tower[@]}"
# Twenty shapes dropped into a box, four to a layer (collision stiffness 5e5 N/m: at rest their
# skins are under 2 % of a cell into each other).
for shape in sphere torus ell capsule; do
  "$jello" shape "$shape" "$meshes/small-$shape.obj" --detail 6 --size 0.4 >/dev/null
done
shapes=(sphere torus ell capsule)
pile=()
for n in $(seq 0 19); do
  layer=$(( n / 4 )); k=$(( n % 4 ))
  shape=${shapes[$(( (layer + k) % 4 ))]}
  x=$(( k % 2 * 90 - 45 )); y=$(( k / 2 * 90 - 45 )); z=$(( 55 * layer - 70 ))
  pile+=(--mesh "$meshes/small-$shape.obj" --cells 6 --centre "${x}e-2,${y}e-2,${z}e-2"
    --rotation "$(( 17 * n % 90 )),$(( 31 * n % 90 )),$(( 47 * n % 90 ))" --name "$shape$(( n + 1 ))" "${jelly[@]}")
done
create "$out/pile.toml" --bounds=-1,-1,-1,1,1,2.5 --dt 0.0005 --collision-stiffness 5e5 --collision-damping 150 "${pile[@]}"
# A soft ring standing on its edge between two panes (the walls, 0.3 m apart), squashed by a
# heavy block, with self-contact on: as the block lands the inner faces of the ring's hole meet
# for a moment, and its crushed cells are kept right side out. Without self-contact the ring
# folds down through itself (scripts/contact_report.py counts the faces that cross,
# docs/scenes.md#the-example-scenes). Self-contact is stiff for an explicit step: dt 0.5 ms.
# Standing free, the ring falls over; flat, its hole never closes.
"$jello" shape torus "$meshes/ring.obj" --detail 8 --size 0.8 >/dev/null
create "$out/ring.toml" --dt 0.0005 --collision-stiffness 2e5 --collision-damping 50 --self-contact \
  --bounds=-0.6,-0.15,0,0.6,0.15,1.2 \
  --mesh "$meshes/ring.obj" --cells 12 --centre 0,0,0.4 --rotation 90,0,0 --name ring \
  --density 1000 --modulus 1.5e4 --viscosity 40 \
  --cube 5 --size 0.28 --centre 0,0,0.95 --name weight --total-mass 150 --modulus 2e6 --viscosity 40

if $check; then
  if ! diff -r -q "$out" examples; then
    echo "examples/ is out of date: run scripts/make-examples.sh" >&2
    exit 1
  fi
  echo "examples/ is up to date"
fi
