#!/usr/bin/env bash
# Issue 13's "the GPU path faster than the CPU one where a GPU exists":
# the conservative bake (`vis5d build --conservative`) of each scene with
# the oracle's Depth Maps on the CPU and on the GPU (`--gpu`: wgpu, the
# maps of the halves of a cell's cuts in one submission; with --try-cuts
# the halves of all three cuts, six cells a submission), side by side in
# one run. Prints per scene and setting the bake's seconds, the oracle's
# milliseconds a cell, the rasteriser and whether the two trees agree in
# size (the GPU fills a subset of the CPU's pixels, so its sets may be a
# little larger, never smaller). Fails when `--gpu` finds no adapter, so
# that a run on a machine without one is not mistaken for a measurement
# (Mesa's lavapipe counts as one: it is a CPU driver, slower than the
# CPU path).
#
#   scripts/oracle-gpu-speed.sh [MODEL...]
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet --bin vis5d
bin=${CARGO_TARGET_DIR:-target}/release/vis5d
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
models=("$@")
if [ ${#models[@]} -eq 0 ]; then
    models=(scenes/city.obj scenes/office.obj)
    sf=../shared/scenes/city_san_francisco/san_francisco.obj
    [ -f "$sf" ] && models+=("$sf")
fi
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
printf '| scene | cuts | rasteriser | bake s | oracle ms a cell | cells | mean leaf set |\n'
printf '|---|---|---|---:|---:|---:|---:|\n'
for model in "${models[@]}"; do
    for cuts in "" --try-cuts; do
        for gpu in "" --gpu; do
            # shellcheck disable=SC2086
            json=$("$bin" build "$model" --conservative $cuts $gpu --json -o "$tmp/out.v5d")
            line=$(python3 -c '
import json, sys
j = json.loads(sys.argv[1])
if sys.argv[2] and not j["rasteriser"].startswith("GPU"):
    sys.exit("--gpu found no adapter: " + j["rasteriser"])
print("| %s | %s | %s | %.1f | %.1f | %d | %.1f |" % (
    sys.argv[3], sys.argv[4] or "longest side", j["rasteriser"], j["seconds"]["bake"],
    j["oracle_ms_per_cell"], j["oracle_cells"], j["mean_leaf_objects"]))
' "$json" "$gpu" "$(basename "$model" .obj)" "$cuts")
            echo "$line"
        done
    done
done
