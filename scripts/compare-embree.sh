#!/usr/bin/env bash
# vis5d's tracer against Embree (issue 16), side by side in one run, on
# exactly the same rays and triangles: `vis5d trace --write-rays
# --write-triangles` writes them, scripts/embree_trace.py times Embree 4 on
# them through the embreex package (installed here into a virtual
# environment, pinned in scripts/requirements-embree.txt). Prints one line
# per scene, kind of rays and thread count: both tracers' rays per second,
# their ratio and both hit counts (the same rays: the counts should agree).
#
#   scripts/compare-embree.sh [RAYS [MODEL...]]
#
# Defaults: 1,000,000 rays; the committed city, apartment x18 (made here),
# and the largest real scenes when ../shared/scenes has them.
set -euo pipefail
cd "$(dirname "$0")/.."
rays=${1:-1000000}
shift || true
venv=${VIS5D_EMBREE_VENV:-target/embree-venv}
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet -r scripts/requirements-embree.txt
fi
cargo build --release --quiet --bin vis5d
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
models=("$@")
if [ ${#models[@]} -eq 0 ]; then
    target/release/vis5d scene apartment --replicate 18 -o "$tmp/apartment_x18.obj" > /dev/null
    models=(scenes/city.obj "$tmp/apartment_x18.obj")
    for m in ../shared/scenes/forest_morse_land1_trees/land1_trees.obj \
             ../shared/scenes/city_san_francisco/san_francisco.obj; do
        [ -f "$m" ] && models+=("$m")
    done
fi
cores=$(nproc)
row() {
    "$venv/bin/python" - "$@" <<'PY'
import json, sys
name, kind, threads, vf, ef = sys.argv[1:]
v, e = json.load(open(vf)), json.load(open(ef))
print(f"{name:<28} {kind:<8} {threads:>7} {v['rays_per_second'] / 1e6:12.3f} "
      f"{e['rays_per_second'] / 1e6:12.3f} {v['rays_per_second'] / e['rays_per_second']:7.2f} "
      f"{v['hits']:>10} {e['hits']:>10}")
PY
}
printf '%-28s %-8s %7s %12s %12s %7s %10s %10s\n' scene rays threads "vis5d Mr/s" "Embree Mr/s" ratio "vis5d hit" "Embree hit"
for m in "${models[@]}"; do
    for kind in builder random; do
        for threads in 1 "$cores"; do
            target/release/vis5d trace "$m" --rays "$rays" --kind "$kind" --threads "$threads" \
                --write-rays "$tmp/rays" --write-triangles "$tmp/tris" --json > "$tmp/v.json"
            "$venv/bin/python" scripts/embree_trace.py "$tmp/tris" "$tmp/rays" \
                --threads "$threads" --json > "$tmp/e.json"
            row "$(basename "$m")" "$kind" "$threads" "$tmp/v.json" "$tmp/e.json"
        done
    done
done
