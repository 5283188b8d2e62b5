#!/usr/bin/env bash
# The oracle's tightness against rays (issue 13's "tight" target): street
# cells of the cities, room cells of the buildings, cells among the trees of
# two dense forests (the thicket's crowns of random leaves, the grove's
# closed crowns of overlapping leaves), each with the sweep off and on.
# Prints one line per run: the scene, the sweep setting and
# examples/street_cells' means (objects kept, seen by 10^5 rays, their
# ratio, the share of the objects no ray hit that the oracle proved hidden,
# ms per cell on the CPU).
#
#   scripts/oracle-tightness.sh [CELLS [SWEEP...]]
#
# SWEEP is "PLANES PATCHES" (default: "0 0" "4 4" "8 8").
set -euo pipefail
cd "$(dirname "$0")/.."
cells=${1:-10}
shift || true
sweeps=("$@")
[ ${#sweeps[@]} -gt 0 ] || sweeps=("0 0" "4 4" "8 8")
cargo build --release --quiet --bin vis5d --example street_cells
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
mkdir -p "$tmp/city21" "$tmp/offices11" "$tmp/thicket" "$tmp/grove"
target/release/vis5d scene city --seed 21 -o "$tmp/city21/city.obj" > /dev/null
target/release/vis5d scene office --seed 11 --replicate 2 -o "$tmp/offices11/office.obj" > /dev/null
target/release/vis5d scene thicket -o "$tmp/thicket/thicket.obj" > /dev/null
target/release/vis5d scene grove -o "$tmp/grove/grove.obj" > /dev/null
sf=../shared/scenes/city_san_francisco/san_francisco.obj
duplex=../shared/scenes/apartment_ifc_duplex/duplex_apartment.obj
runs=(
    "city|scenes/city.obj|$cells 6 --height 2"
    "city seed 21 (made)|$tmp/city21/city.obj|$cells 6 --height 2"
    "San Francisco|$sf|$(( (cells + 2) / 3 )) 6 --height 2"
    "office|scenes/office.obj|$cells 3 --height 2 --rooms"
    "offices seed 11 x2 (made)|$tmp/offices11/office.obj|$cells 3 --height 2 --rooms"
    "duplex|$duplex|$cells 3 --height 2 --rooms"
    "thicket (made)|$tmp/thicket/thicket.obj|$(( (cells + 1) / 2 )) 1 --height 1"
    "grove (made)|$tmp/grove/grove.obj|$(( (cells + 1) / 2 )) 1 --height 1"
)
for run in "${runs[@]}"; do
    IFS='|' read -r name model rest <<< "$run"
    [ -f "$model" ] || { echo "$name: $model missing, skipped"; continue; }
    for sweep in "${sweeps[@]}"; do
        set -- $sweep
        # shellcheck disable=SC2086
        line=$(target/release/examples/street_cells "$model" $rest --rays 100000 \
            --sweep-planes "$1" --sweep-patches "$2" | tail -1)
        echo "$name | sweep $1+$2 | ${line#mean over }"
    done
done
