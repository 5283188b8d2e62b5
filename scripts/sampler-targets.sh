#!/usr/bin/env bash
# The sampled tree against issue 12's targets, on every committed scene and
# every real scene of ../shared/scenes: builds each with the default
# parameters (plus any flags given), then `vis5d report` over 300 random
# views of 256x256 pixels (one ray per pixel, the independent ray-cast
# truth) and prints one table row per scene: build time and rays, the mean
# and worst pixel error, and the objects the query answers per view against
# those really seen (notes/build.md).
# Usage: scripts/sampler-targets.sh [EXTRA BUILD FLAGS...]
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet --bin vis5d
bin=target/release/vis5d
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
source scripts/scenes.sh
echo "| scene | build (s) | rays (M) | leaves | mean pixel error | worst view | drawn / view | seen / view | drawn / seen | views with misses | retest finds | edge finds |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
for s in "${scenes[@]}"; do
    name=$(scene_name "$s")
    start=$(date +%s.%N)
    "$bin" build "$s" "$@" -o "$out/$name.v5d" --json >"$out/$name.json"
    end=$(date +%s.%N)
    "$bin" report "$s" --pvs "$out/$name.v5d" --random 300 --resolution 256 --no-oracle \
        -o "$out/$name" >/dev/null
    python3 - "$out/$name.json" "$out/$name/report.json" "$name" "$start" "$end" <<'PY'
import json, sys
b = json.load(open(sys.argv[1]))
r = json.load(open(sys.argv[2]))
t = [m for m in r["methods"] if m["name"] == "vis5d"][0]["summary"]
seen = sum(v["seen_objects"] for v in r["views"]) / len(r["views"])
d = b["decisions"]
print(f"| {sys.argv[3]} | {float(sys.argv[5]) - float(sys.argv[4]):.2f} | {b['rays_cast'] / 1e6:.2f} | "
      f"{b['leaves']} | {t['mean_pixel_error']:.2e} | {100 * t['worst_pixel_error']:.3f}% | "
      f"{t['mean_objects']:.1f} | {seen:.1f} | {t['mean_objects'] / seen:.2f} | "
      f"{t['views_with_misses']} | {d.get('retest_found', 0)} | {d.get('edge_found', 0)} |")
PY
done
