#!/usr/bin/env bash
# Issue 13's "never wrong" target: 10^6 independent random rays from each
# of many random cells of every committed and real scene, with the CPU
# rasteriser and the GPU one (wgpu: a real GPU where there is one, else
# Mesa's lavapipe), default oracle settings. examples/street_cells stops
# with an error on the first object a ray hits that the oracle hid, so a
# run that prints its mean line found no violation. Cells: street cells
# (6 x 6 x 2 m, cities), room cells (3 x 3 x 2 m, buildings) and cells
# anywhere in the scene's box (geometry in them or not, 4 sizes); the
# grove (made here) gets trail cells of 1 and 0.25 m.
# METHOD shrink checks occluder shrinking (papers/004, issue 14) instead,
# its cube maps on the CPU and on the GPU; both checks what neither proves.
# SLICES N > 0 also culls the hidden slices of kept objects (papers/004
# sec. 3, N slices an axis) and checks that no ray hits a culled triangle.
#
#   scripts/oracle-never-wrong.sh [CELLS] [RAYS] [extended|shrink|both] [SLICES]
set -euo pipefail
cd "$(dirname "$0")/.."
cells=${1:-5}
rays=${2:-1000000}
method=${3:-extended}
slices=${4:-0}
cargo build --release --quiet --example street_cells
bin=${CARGO_TARGET_DIR:-target}/release/examples/street_cells
export XDG_RUNTIME_DIR="${XDG_RUNTIME_DIR:-$(mktemp -d)}"
shared=../shared/scenes
# The grove (made): its crowns are the convex shells (stop 45).
made=$(mktemp -d)
trap 'rm -rf "$made"' EXIT
cargo build --release --quiet --bin vis5d
"${CARGO_TARGET_DIR:-target}/release/vis5d" scene grove -o "$made/grove.obj" > /dev/null
models=(scenes/*.obj
    "$made/grove.obj"
    "$shared/apartment_ifc_duplex/duplex_apartment.obj"
    "$shared/apartment_morse/apartment.obj"
    "$shared/city_san_francisco/san_francisco.obj"
    "$shared/forest_morse_land1_trees/land1_trees.obj"
    "$shared/hall_morse_grande_salle/grande_salle.obj"
    "$shared/house_ifc_fzk_haus/AC14-FZK-Haus.obj")
status=0
for model in "${models[@]}"; do
    [ -f "$model" ] || { echo "$model missing, skipped"; continue; }
    name=$(basename "$(dirname "$model")")/$(basename "$model" .obj)
    kinds=("--anywhere|1 --height 1" "--anywhere|4 --height 2" "--anywhere|0.05 --height 0.05" "--anywhere|30 --height 10")
    case "$name" in
        */city|*/san_francisco|*/land1_trees|*/forest) kinds+=("|6 --height 2") ;;
        */grove) kinds+=("|1 --height 1" "|0.25 --height 0.25") ;;
        */machine) ;;
        *) kinds+=("--rooms|3 --height 2") ;;
    esac
    rasters=(cpu gpu)
    for raster in "${rasters[@]}"; do
        gpu=""
        [ "$raster" = gpu ] && gpu=--gpu
        for kind in "${kinds[@]}"; do
            IFS='|' read -r flag size <<< "$kind"
            # shellcheck disable=SC2086
            if line=$($bin "$model" "$cells" $size $flag $gpu --rays "$rays" --method "$method" --slices "$slices" 2>&1 | grep '^mean over\|error' | tail -1); then
                echo "$name | $method $raster | ${flag:-street} $size | ${line#mean over }"
            elif [[ "$line" == *"found no place"* ]]; then
                echo "$name | $raster | ${flag:-street} $size | no such cell in this scene"
            else
                echo "$name | $raster | ${flag:-street} $size | FAILED: $line"
                status=1
            fi
        done
    done
done
exit $status
