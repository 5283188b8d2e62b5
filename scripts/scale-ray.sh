#!/usr/bin/env bash
# Sharded builds through the Ray driver against a local build (issue 17,
# notes/scale.md): for the apartment replicated 1, 4, 16 and 64 times and
# San Francisco tiled 1 and 4 times (when ../shared/scenes has it), a
# local `vis5d build --top-levels K` (build seconds, peak memory), then
# scripts/ray_build.py on a Ray cluster on this machine with 1, 2 and 4
# worker CPUs (wall seconds from the driver's start to the merged file,
# checked byte for byte against the local build), and each shard's
# measured cost: the 2^K subtrees built one shard each (`--shard I/2^K`,
# build seconds without loading), dealt to 64 machines by their
# measured costs (largest first to the least loaded), which bounds what
# a 64-machine cluster would take.
#
#   scripts/scale-ray.sh [K]   (K: fixed levels, default 6: 64 subtrees;
#   VIS5D_SCALE_QUICK=1: the apartment alone)
set -euo pipefail
cd "$(dirname "$0")/.."
k=${1:-6}
. scripts/ray-env.sh
tmp=$(mktemp -d)
port=${VIS5D_RAY_PORT:-6392}
trap '"$venv/bin/ray" stop --force > /dev/null 2>&1 || true; rm -rf "$tmp"' EXIT
rows=()
# VIS5D_SCALE_QUICK=1: the apartment alone (a check of the script).
copies=(1 4 16 64)
[ "${VIS5D_SCALE_QUICK:-0}" = 1 ] && copies=(1)
for n in "${copies[@]}"; do
    "$bin" scene apartment --replicate "$n" -o "$tmp/apartment_x$n.obj" 2> /dev/null
    rows+=("$tmp/apartment_x$n.obj")
done
sf=../shared/scenes/city_san_francisco/san_francisco.obj
if [ -f "$sf" ] && [ "${VIS5D_SCALE_QUICK:-0}" != 1 ]; then
    for n in 1 4; do
        "$bin" scene --tile "$sf" --replicate "$n" -o "$tmp/san_francisco_x$n.obj" 2> /dev/null
        rows+=("$tmp/san_francisco_x$n.obj")
    done
fi
printf '%-20s %8s %9s %9s %9s %9s %9s %12s %12s\n' scene objects "local s" "peak MiB" \
    "ray 1 s" "ray 2 s" "ray 4 s" "subtrees s" "64 machines"
for m in "${rows[@]}"; do
    name=$(basename "$m" .obj)
    /usr/bin/time -f '%M' -o "$tmp/rss" "$bin" build "$m" --top-levels "$k" -o "$tmp/local.v5d" \
        --json > "$tmp/local.json" 2> /dev/null
    ray_s=()
    for w in 1 2 4; do
        "$venv/bin/ray" start --head --node-ip-address 127.0.0.1 --port "$port" --num-cpus "$w" \
            --include-dashboard=false --disable-usage-stats > /dev/null 2>&1
        start=$(date +%s.%N)
        RAY_ADDRESS="127.0.0.1:$port" "$venv/bin/python" scripts/ray_build.py "$m" \
            -o "$tmp/ray.v5d" --top-levels "$k" --shards "$w" --vis5d "$bin" 2> /dev/null
        end=$(date +%s.%N)
        "$venv/bin/ray" stop --force > /dev/null 2>&1
        cmp -s "$tmp/local.v5d" "$tmp/ray.v5d" || { echo "scale-ray: $name with $w workers differs" >&2; exit 1; }
        ray_s+=("$(python3 -c "print(f'{$end - $start:.1f}')")")
    done
    # Each subtree alone: its shard's build seconds.
    : > "$tmp/costs"
    subtrees=$((1 << k))
    for i in $(seq 0 $((subtrees - 1))); do
        "$bin" build "$m" --top-levels "$k" --shard "$i/$subtrees" --dry-run --json 2> /dev/null \
            | python3 -c "import json,sys; print(json.load(sys.stdin)['seconds'])" >> "$tmp/costs"
    done
    python3 - "$name" "$tmp/local.json" "$(cat "$tmp/rss")" "$tmp/costs" "${ray_s[@]}" <<'PY'
import json, sys
name, local, rss, costs = sys.argv[1:5]
ray = sys.argv[5:]
j = json.load(open(local))
c = sorted((float(x) for x in open(costs) if x.strip()), reverse=True)
load = [0.0] * 64
for x in c:
    load[load.index(min(load))] += x
print(f"{name:<20} {j['objects']:>8} {j['seconds']['build']:>9.2f} {int(rss) / 1024:>9.0f} "
      f"{ray[0]:>9} {ray[1]:>9} {ray[2]:>9} {sum(c):>12.2f} {max(load):>12.2f}")
PY
done
