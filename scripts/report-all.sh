#!/usr/bin/env bash
# Runs `vis5d report` on every committed scene and every real scene of
# ../shared/scenes and prints one table row per scene and method (the
# figures of notes/report.md).
# Usage: scripts/report-all.sh [VIEWS] [EXTRA REPORT FLAGS...]
set -euo pipefail
cd "$(dirname "$0")/.."
views=${1:-50}
shift || true
cargo build --release --quiet --bin vis5d
bin=target/release/vis5d
out=$(mktemp -d)
trap 'rm -rf "$out"' EXIT
source scripts/scenes.sh
echo "| scene | method | objects / view | geometry ratio | pixel error | worst view | missed objects | Q_u / Q_o | ms / view |"
echo "|---|---|---:|---:|---:|---:|---:|---|---:|"
for s in "${scenes[@]}"; do
    name=$(scene_name "$s")
    "$bin" report "$s" -o "$out/$name" --random "$views" "$@" >/dev/null
    python3 - "$out/$name/report.json" "$name" <<'PY'
import json, sys
d = json.load(open(sys.argv[1]))
seen = sum(v["seen_objects"] for v in d["views"]) / len(d["views"])
lazy = sum(c["lazy_pixel_queries"] for c in d["grid_costs"])
busy = sum(c["busy_pixel_queries"] for c in d["grid_costs"])
for m in d["methods"]:
    s = m["summary"]
    g = "n/a" if s["geometry_ratio"] is None else f"{s['geometry_ratio']:.2f}"
    print(f"| {sys.argv[2]} | {m['name']} | {s['mean_objects']:.1f} | {g} | {100*s['mean_pixel_error']:.4f}% | "
          f"{100*s['worst_pixel_error']:.3f}% | {s['missed_objects']} | {s['mean_q_u']:.4f} / {s['mean_q_o']:.2f} | {s['mean_ms_per_view']:.2f} |")
print(f"| {sys.argv[2]} | *seen* | {seen:.1f} | | | | | | {d['truth_ms_per_view']:.0f} (truth) |")
print(f"| {sys.argv[2]} | *grid lazy / busy pixel queries* | {lazy} / {busy} | | | | | | |")
PY
done
