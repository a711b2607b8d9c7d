#!/usr/bin/env bash
# Checks that two `jello` binaries compute the same bits: for a change that moves or reorganises
# code without meaning to change any result (docs/architecture.md, "Moving code").
#   scripts/same-bits.sh OLD_JELLO [NEW_JELLO]      (NEW_JELLO defaults to target/release/jello)
# Runs each example world under every integrator (the implicit ones at 1/60 s), each example scene
# under its own integrator, backward Euler and SDIRK2, a 24³ cube on a team of threads, two cubes
# stacked, frames in every format, two glTF exports, `jello info` on every example, and, when
# ../shared/worlds is there, every corpus world (its own integrator, then backward Euler) and
# every bad file of its nonstandard/ folder; then compares everything each binary wrote or
# printed (wall-clock times left out). Exits 1 at the first difference, naming it.
set -uo pipefail
cd "$(dirname "$0")/.."
old=$(realpath "${1:?usage: scripts/same-bits.sh OLD_JELLO [NEW_JELLO]}")
new=$(realpath "${2:-target/release/jello}")
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT

# Scenes made once, by the old binary, so that both read the same files.
"$old" create "$tmp/big.toml" --box=-2,-2,-2,2,2,-1.9 --cube 24 --size 1 --at 0,0,-1.2 \
  --total-mass 1 >/dev/null
"$old" create "$tmp/two.toml" --box=-2,-2,-2,2,2,-1.9 --cube 5 --size 0.5 --at 0,0,-1.6 \
  --total-mass 1 --cube 5 --size 0.5 --at 0,0,-0.9 --total-mass 1 >/dev/null

outputs() {
  local jello=$1 out=$2
  mkdir -p "$out"
  run() { # name, then the arguments of `jello run`
    local name=$1
    shift
    "$jello" run "$@" -q >"$out/$name.out" 2>"$out/$name.err"
    echo $? >"$out/$name.rc"
    sed -i -E 's/wall [0-9.]+ s, [0-9.]+ steps\/s, //' "$out/$name.out"
  }
  for f in examples/*.w; do
    b=$(basename "$f" .w)
    run "$b" "$f" --steps 1500 --save "$out/$b.w"
    for i in Euler RK2 SymplecticEuler; do
      run "$b-$i" "$f" --steps 400 --integrator "$i" --save "$out/$b-$i.w"
    done
    for i in BackwardEuler SDIRK2; do
      run "$b-$i" "$f" --steps 40 --integrator "$i" --dt 0.0166667 --save "$out/$b-$i.w"
    done
    "$jello" info "$f" >"$out/$b.info" 2>&1
  done
  for f in examples/*.toml "$tmp/big.toml" "$tmp/two.toml"; do
    b=$(basename "$f" .toml)
    run "$b" "$f" --time 0.3 --save "$out/$b.toml"
    run "$b-BackwardEuler" "$f" --time 1 --integrator BackwardEuler --dt 0.0166667 \
      --save "$out/$b-BackwardEuler.toml"
    run "$b-SDIRK2" "$f" --time 0.5 --integrator SDIRK2 --dt 0.0166667 --save "$out/$b-SDIRK2.toml"
    "$jello" info "$f" >"$out/$b.info" 2>&1
  done
  run frames-obj examples/torus.toml --time 0.2 --frames "$out/obj" --every 50 --format obj
  run frames-ply examples/stack.toml --time 0.2 --frames "$out/ply" --every 50 --format ply
  run frames-csv examples/blob.toml --time 0.1 --frames "$out/csv" --every 50 --format csv
  run export-world examples/rotate.w --time 0.5 --export "$out/rotate.glb"
  run export-scene examples/mould.toml --time 0.3 --export "$out/mould.glb"
  if [ -d ../shared/worlds ]; then
    for f in ../shared/worlds/*.w; do
      b=corpus-$(basename "$f" .w)
      run "$b" "$f" --steps 300 --save "$out/$b.w"
      run "$b-BackwardEuler" "$f" --steps 20 --integrator BackwardEuler --dt 0.0166667 \
        --save "$out/$b-BackwardEuler.w"
    done
    for f in ../shared/worlds/nonstandard/*; do
      "$jello" run "$f" -q >"$out/bad-$(basename "$f").out" 2>&1
    done
  fi
}

echo "same-bits.sh: running $old"
outputs "$old" "$tmp/old"
echo "same-bits.sh: running $new"
outputs "$new" "$tmp/new"
[ -d ../shared/worlds ] || echo "same-bits.sh: ../shared/worlds is absent: the corpus was not compared"
if diff -r "$tmp/old" "$tmp/new" >"$tmp/diff"; then
  echo "same-bits.sh: the same bits: $(find "$tmp/new" -type f | wc -l) outputs compared"
else
  head -20 "$tmp/diff" >&2
  echo "same-bits.sh: the binaries differ (above)" >&2
  exit 1
fi
