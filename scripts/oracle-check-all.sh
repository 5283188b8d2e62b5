#!/usr/bin/env bash
# Builds every committed scene and every real scene of ../shared/scenes,
# then runs `vis5d check` on a sample of each tree's leaves and prints one
# table row per scene (the figures of notes/oracle.md).
# Usage: scripts/oracle-check-all.sh [SAMPLE] [EXTRA CHECK FLAGS...]
set -euo pipefail
cd "$(dirname "$0")/.."
sample=${1:-300}
shift || true
cargo build --release --quiet
bin=target/release/vis5d
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
source scripts/scenes.sh
echo "| scene | objects | leaves | checked | oracle cells | ms/cell | oracle (all dirs) | oracle | sampled | truth | sampled only | violations | suspects | confirmed misses | max missed fraction |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"
for s in "${scenes[@]}"; do
    name=$(scene_name "$s")
    "$bin" build "$s" -o "$out/$name.v5d" >/dev/null
    "$bin" check "$s" "$out/$name.v5d" --sample "$sample" --json "$@" > "$out/$name.json"
    python3 - "$out/$name.json" "$name" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
print(f"| {sys.argv[2]} | {d['objects']} | {d['tree_leaves']} | {d['leaves_checked']} | {d['oracle_cells']} | {d['oracle_ms_per_cell']:.1f} | "
      f"{d['mean_oracle_all_directions']:.1f} | {d['mean_oracle']:.1f} | {d['mean_sampled']:.1f} | {d['mean_truth']:.1f} | {d['mean_sampled_only']:.2f} | "
      f"{d['violations']} | {d['suspects']} | {d['confirmed_misses']} | {d['max_missed_fraction']:.3f} |")
PY
done
