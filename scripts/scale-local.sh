#!/usr/bin/env bash
# How a default build scales with the size of the world (issue 17,
# notes/scale.md): the procedural apartment replicated 1, 4, 16 and 64
# times, and San Francisco (when ../shared/scenes has it) tiled 1, 4 (2x2)
# and, with VIS5D_SCALE_BIG=1, 16 (4x4) times by `vis5d scene --tile`.
# For each: objects, triangles, the fixed top's levels (chosen from the
# scene: --subtree-objects), build seconds, leaves, rays, peak memory
# (GNU time's maximum resident set), and the seconds per object and per
# leaf. One default build each (--dry-run: nothing written), all cores.
#
#   scripts/scale-local.sh [--threads T]
set -euo pipefail
cd "$(dirname "$0")/.."
threads=()
if [ "${1:-}" = "--threads" ]; then
    threads=(--threads "$2")
fi
if [ ! -x /usr/bin/time ]; then
    echo "scale-local.sh: needs GNU time (/usr/bin/time; Debian package 'time')" >&2
    exit 1
fi
cargo build --release --quiet --bin vis5d
bin="${CARGO_TARGET_DIR:-target}/release/vis5d"
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
rows=()
for n in 1 4 16 64; do
    "$bin" scene apartment --replicate "$n" -o "$tmp/apartment_x$n.obj" > /dev/null
    rows+=("$tmp/apartment_x$n.obj")
done
sf=../shared/scenes/city_san_francisco/san_francisco.obj
if [ -f "$sf" ]; then
    tiles=(1 4)
    [ "${VIS5D_SCALE_BIG:-0}" = 1 ] && tiles+=(16)
    for n in "${tiles[@]}"; do
        "$bin" scene --tile "$sf" --replicate "$n" -o "$tmp/san_francisco_x$n.obj" > /dev/null
        rows+=("$tmp/san_francisco_x$n.obj")
    done
fi
printf '%-22s %8s %10s %4s %9s %7s %12s %9s %11s %10s\n' scene objects triangles top "build s" leaves rays "peak MiB" "ms/object" "ms/leaf"
for m in "${rows[@]}"; do
    /usr/bin/time -f '%M' -o "$tmp/rss" "$bin" build "$m" --dry-run --json "${threads[@]}" \
        > "$tmp/b.json" 2> /dev/null
    python3 - "$(basename "$m" .obj)" "$tmp/b.json" "$(cat "$tmp/rss")" <<'PY'
import json, sys
name, path, rss_kib = sys.argv[1], sys.argv[2], int(sys.argv[3])
j = json.load(open(path))
s = j["seconds"]["build"]
print(f"{name:<22} {j['objects']:>8} {j['triangles']:>10} {j['top_levels']:>4} {s:>9.2f} {j['leaves']:>7} "
      f"{j['rays_cast']:>12} {rss_kib / 1024:>9.0f} {1e3 * s / j['objects']:>11.3f} "
      f"{1e3 * s / j['leaves']:>10.2f}")
PY
done
