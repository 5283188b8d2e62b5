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
#
# VIS5D_COMPARE_RUNS=N times each pair N times, alternating the two
# tracers on the same rays, and adds a line with the ratio's mean, standard
# deviation and range: for ratios near 1, where one run is within the
# machine's noise. VIS5D_COMPARE_SECONDS=S makes each timing the best pass
# of at least S seconds (default 1) for both tracers.
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
runs=${VIS5D_COMPARE_RUNS:-1}
seconds=${VIS5D_COMPARE_SECONDS:-1}
if ! [[ $runs =~ ^[1-9][0-9]*$ ]]; then
    echo "compare-embree.sh: VIS5D_COMPARE_RUNS must be a whole number of runs, not '$runs'" >&2
    exit 2
fi
# One line of the table; the ratio is appended to the file $6.
row() {
    "$venv/bin/python" - "$@" <<'PY'
import json, sys
name, kind, threads, vf, ef, ratios = sys.argv[1:]
v, e = json.load(open(vf)), json.load(open(ef))
ratio = v['rays_per_second'] / e['rays_per_second']
print(f"{name:<28} {kind:<8} {threads:>7} {v['rays_per_second'] / 1e6:12.3f} "
      f"{e['rays_per_second'] / 1e6:12.3f} {ratio:7.2f} "
      f"{v['hits']:>10} {e['hits']:>10}")
with open(ratios, "a") as f:
    print(ratio, file=f)
PY
}
# The ratios of file $1 summed up (for more than one run).
summary() {
    "$venv/bin/python" - "$1" <<'PY'
import statistics, sys
r = [float(x) for x in open(sys.argv[1])]
print(f"{'':<28} {'':<8} {'':>7} {'ratio over ' + str(len(r)) + ' runs:':>25} "
      f"mean {statistics.mean(r):.3f}, sd {statistics.stdev(r):.3f}, "
      f"{min(r):.3f} to {max(r):.3f}")
PY
}
printf '%-28s %-8s %7s %12s %12s %7s %10s %10s\n' scene rays threads "vis5d Mr/s" "Embree Mr/s" ratio "vis5d hit" "Embree hit"
for m in "${models[@]}"; do
    for kind in builder random; do
        for threads in 1 "$cores"; do
            : > "$tmp/ratios"
            for run in $(seq "$runs"); do
                write=()
                if [ "$run" -eq 1 ]; then
                    write=(--write-rays "$tmp/rays" --write-triangles "$tmp/tris")
                fi
                target/release/vis5d trace "$m" --rays "$rays" --kind "$kind" --threads "$threads" \
                    --min-seconds "$seconds" "${write[@]}" --json > "$tmp/v.json"
                "$venv/bin/python" scripts/embree_trace.py "$tmp/tris" "$tmp/rays" \
                    --threads "$threads" --min-seconds "$seconds" --json > "$tmp/e.json"
                row "$(basename "$m")" "$kind" "$threads" "$tmp/v.json" "$tmp/e.json" "$tmp/ratios"
            done
            if [ "$runs" -gt 1 ]; then
                summary "$tmp/ratios"
            fi
        done
    done
done
