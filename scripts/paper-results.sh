#!/usr/bin/env bash
# Reruns the figures of notes/paper-results.md: our numbers beside the
# papers' (papers/003 sec. 8, papers/001 sec. 6, papers/002 Fig. 8,
# papers/004 Fig. 1), on the committed scenes and, where ../shared/scenes
# is present, San Francisco. Prints the Markdown to stdout.
# Usage: scripts/paper-results.sh > notes/paper-results.md
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --quiet --bin vis5d --example street_cells
tgt=${CARGO_TARGET_DIR:-target}
bin=$tgt/release/vis5d
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
"$bin" scene apartment --replicate 18 -o "$tmp/block.obj" >/dev/null
json() { python3 -c "import json,sys; d=json.load(open('$1')); print($2)"; }

# The apartment: spatial cells, then 8 angular intervals (papers/003 sec. 8).
"$bin" build scenes/apartment.obj --spatial-only --max-depth 8 --json --dry-run > "$tmp/spatial.json"
"$bin" build scenes/apartment.obj --spatial-only --max-depth 8 --angular-leaves 8 --json --dry-run > "$tmp/angular.json"
# Codings on one apartment and on the block of 18 (same tree depth).
"$bin" build scenes/apartment.obj --max-depth 8 --json --dry-run > "$tmp/one.json"
"$bin" build "$tmp/block.obj" --max-depth 8 --json --dry-run > "$tmp/block.json"
# The copy machine, the city (objects drawn per view, lazy vs busy) and
# the pixel error at 1000 x 1000.
"$bin" report scenes/machine.obj -o "$tmp/machine" --random 100 --no-oracle >/dev/null
"$bin" report scenes/city.obj -o "$tmp/city" --random 100 --no-oracle >/dev/null
"$bin" report scenes/city.obj -o "$tmp/city1000" --random 20 --resolution 1000 --no-oracle >/dev/null
# Street-level culling of the oracle.
"$tgt"/release/examples/street_cells scenes/city.obj 20 4 > "$tmp/street_city.txt"
"$tgt"/release/examples/street_cells scenes/forest.obj 20 4 > "$tmp/street_forest.txt"
# The dense forest whose crowns are closed (the grove), from 0.25 m cells,
# with the sweep of many thin steps reaching back (notes/oracle.md).
"$bin" scene grove -o "$tmp/grove.obj" > /dev/null
"$tgt"/release/examples/street_cells "$tmp/grove.obj" 6 0.25 --height 0.25 --rays 1000000 \
    --sweep-planes 16 --sweep-reach 5 > "$tmp/street_grove.txt"
# Slices (papers/004): triangles drawn with the slice-wise structure
# against whole objects, from street cells of 1 m, and along a street-level
# camera path (20 street points 1.7 m up, looking along +-x and +-y).
"$tgt"/release/examples/street_cells scenes/city.obj 10 1 --height 1 --rays 100000 --slices 16 > "$tmp/slices_city.txt"
street_path() {
    grep '^cell' "$1" | python3 -c '
import re, sys, json
views = []
for line in sys.stdin:
    x0, y0, z0, x1, y1, z1 = map(float, re.match(r"cell \(([-\d.]+), ([-\d.]+), ([-\d.]+)\)-\(([-\d.]+), ([-\d.]+), ([-\d.]+)\)", line).groups())
    for d in ([1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0]):
        views.append({"pos": [(x0 + x1) / 2, (y0 + y1) / 2, z0 + 0.7], "dir": d, "fov": 90})
json.dump(views, sys.stdout)'
}
"$tgt"/release/examples/street_cells scenes/city.obj 20 1 --height 1 --rays 1000 > "$tmp/path_city.txt"
street_path "$tmp/path_city.txt" > "$tmp/path_city.json"
"$bin" report scenes/city.obj -o "$tmp/city_path" --views "$tmp/path_city.json" --resolution 256 --slices 16 --oracle-cell 0.004 --no-shrink >/dev/null
sf=../shared/scenes/city_san_francisco/san_francisco.obj
if [ -f "$sf" ]; then
    "$tgt"/release/examples/street_cells "$sf" 4 1 --height 1 --rays 100000 --slices 16 > "$tmp/slices_sf1.txt"
    "$tgt"/release/examples/street_cells "$sf" 4 6 --height 1 --rays 100000 --slices 16 > "$tmp/slices_sf6.txt"
    "$tgt"/release/examples/street_cells "$sf" 20 1 --height 1 --rays 1000 > "$tmp/path_sf.txt"
    street_path "$tmp/path_sf.txt" > "$tmp/path_sf.json"
    # A shallow sampled tree for the report's tree row: the path's figures
    # are the oracle's.
    "$bin" build "$sf" --max-depth 2 -o "$tmp/sf.v5d" >/dev/null
    "$bin" report "$sf" --pvs "$tmp/sf.v5d" -o "$tmp/sf_path" --views "$tmp/path_sf.json" --resolution 256 --slices 16 --oracle-cell 0.00125 --no-shrink >/dev/null
fi

python3 - "$tmp" <<'PY'
import json, sys, re
t = sys.argv[1]
L = lambda n: json.load(open(f"{t}/{n}"))
sp, an, one, block = L("spatial.json"), L("angular.json"), L("one.json"), L("block.json")
mach, city, c1000 = L("machine/report.json"), L("city/report.json"), L("city1000/report.json")
def coding(d, name):
    return next(c["bytes"] for c in d["coding_sizes"] if c["coding"] == name)
def method(r, name):
    return next(m for m in r["methods"] if m["name"] == name)
def street(n):
    line = open(f"{t}/street_{n}.txt").read().strip().splitlines()[-1]
    m = re.search(r"([\d.]+)% of objects and ([\d.]+)% of triangles", line)
    return float(m.group(1)), float(m.group(2))
lazy = sum(c["lazy_pixel_queries"] for c in city["grid_costs"])
busy = sum(c["busy_pixel_queries"] for c in city["grid_costs"])
mf, mv = method(mach, "frustum")["summary"], method(mach, "vis5d")["summary"]
cs, cf, cg = street("city"), street("forest"), street("grove")
gline = open(f"{t}/street_grove.txt").read().strip().splitlines()[-1]
gseen = float(re.search(r">= ([\d.]+) seen", gline).group(1))
import os
def slices(n):
    p = f"{t}/slices_{n}.txt"
    if not os.path.exists(p):
        return None
    line = open(p).read().strip().splitlines()[-1]
    m = re.search(r"([\d.]+)% of triangles culled \(objects: ([\d.]+)%\): ([\d.]+)% fewer", line)
    return float(m.group(2)), float(m.group(1)), float(m.group(3))
def path(n):
    p = f"{t}/{n}_path/report.json"
    if not os.path.exists(p):
        return None
    o = method(json.load(open(p)), "oracle")["summary"]
    return o["mean_triangles"], o["mean_slice_triangles"]
def slice_row(what, s, how):
    if s is None:
        return (what, "51% fewer triangles", "not measured (../shared/scenes absent)", how)
    return (what, "51% fewer triangles", f"{s[2]:.1f}% fewer ({s[0]:.1f}% -> {s[1]:.1f}% of triangles culled)", how)
def path_row(what, p, how):
    if p is None:
        return (what, "51% fewer triangles", "not measured (../shared/scenes absent)", how)
    return (what, "51% fewer triangles", f"{p[0]:,.0f} -> {p[1]:,.0f} triangles a view ({100 * (1 - p[1] / max(p[0], 1e-9)):.1f}% fewer)", how)
print("""# Our figures beside the papers'

Generated by `scripts/paper-results.sh > notes/paper-results.md`
(development machine, release build, committed scenes; every random
stream seeded). Our scenes are procedural stand-ins for the papers'
models (notes/scenes.md), so agreement is in kind, not in digits.

| what | paper | ours | notes |
|---|---|---|---|""")
rows = [
    ("apartment: objects, polygons (papers/003 sec. 8)", "159 objects, 3,061 polygons",
     f"{one['objects']} objects, {one['triangles']:,} triangles", "ours is a procedural two-room apartment"),
    ("apartment, spatial splits only: cells, objects per cell", "188 cells, 47 objects",
     f"{sp['leaves']:,} cells, {sp['mean_leaf_objects']:.1f} objects", "`build --spatial-only --max-depth 8`"),
    ("apartment, spatial then 8 angular intervals", "1,504 cells, 26 objects",
     f"{an['leaves']:,} cells, {an['mean_leaf_objects']:.1f} objects", "`--angular-leaves 8`"),
    ("codings, one apartment: leaves vs parent-relative", "3,263 vs 2,981 bytes",
     f"{coding(one,'leaf'):,} vs {coding(one,'parent'):,} bytes ({coding(one,'sibling'):,} sibling)", f"{one['leaves']} leaves, `--max-depth 8`"),
    ("codings, block of 18", "73,053 vs 24,618 bytes",
     f"{coding(block,'leaf'):,} vs {coding(block,'parent'):,} bytes ({coding(block,'sibling'):,} sibling)", f"{block['leaves']} leaves, `scene apartment --replicate 18`, `--max-depth 8`"),
    ("copy machine: objects drawn, frustum vs tree", "1,726 objects, about 10x fewer drawn",
     f"{mach['objects']} objects; {mf['mean_objects']:.1f} vs {mv['mean_objects']:.1f} per view ({mf['mean_objects']/max(mv['mean_objects'],1e-9):.1f}x)", "`report scenes/machine.obj --random 100`"),
    ("city street cells culled by the oracle (papers/001)", "96% of polygons",
     f"{cs[0]:.1f}% of objects, {cs[1]:.1f}% of triangles", "`examples/street_cells.rs`, 20 cells of 4 x 4 x 1 m; see notes/oracle.md"),
    ("forest culled by the oracle (papers/001, occlusion sweep)", "95.5%",
     f"{cf[0]:.1f}% of objects, {cf[1]:.1f}% of triangles", "the committed forest is sparse: rays see every object from a 2 m cell (notes/oracle.md)"),
    ("dense forest culled by the oracle (papers/001, occlusion sweep)", "95.5%",
     f"{cg[0]:.1f}% of objects, {cg[1]:.1f}% of triangles (rays see {gseen:.1f} objects)", "`scene grove` (closed crowns of separate leaves), `street_cells` 6 cells of 0.25 m, `--sweep-planes 16 --sweep-reach 5`; from 1 m cells about nothing (notes/oracle.md)"),
    ("lazy vs busy grid, pixel-level queries (papers/002 Fig. 8)", "lazy far fewer",
     f"{lazy:,} vs {busy:,} ({100*lazy/max(busy,1):.1f}%)", "`report scenes/city.obj --random 100`, 512 x 512, 32 x 32 cells"),
    ("pixel error of the tree on a city at 1000 x 1000", "about 1e-4 of the pixels",
     f"{method(c1000,'vis5d')['summary']['mean_pixel_error']:.1e} (worst view {method(c1000,'vis5d')['summary']['worst_pixel_error']:.1e})", "`report scenes/city.obj --random 20 --resolution 1000`"),
    slice_row("slices vs whole objects, city street cells (papers/004 Fig. 1)", slices("city"), "`street_cells scenes/city.obj 10 1 --height 1 --slices 16`: the oracle's, 1 m cells; buildings of 12 triangles"),
    slice_row("slices vs whole objects, San Francisco street cells, 1 m", slices("sf1"), "`street_cells SF 4 1 --height 1 --slices 16`; the terrain cut into pieces"),
    slice_row("slices vs whole objects, San Francisco street cells, 6 m", slices("sf6"), "`street_cells SF 4 6 --height 1 --slices 16`"),
    path_row("slices vs whole objects, city street-level camera path", path("city"), "80 views, `report --views --slices 16 --oracle-cell 0.004` (1.9 m cube): the oracle's row"),
    path_row("slices vs whole objects, San Francisco street-level camera path", path("sf"), "80 views, `report --views --slices 16 --oracle-cell 0.00125` (1.9 m cube): the oracle's row"),
]
for r in rows:
    print("| " + " | ".join(r) + " |")
print("""
Where we differ and why: the apartment's cell counts depend on the split
rule and depth (ours splits by the effectiveness E(A, B) of papers/003 up
to the given depth, see notes/build.md); our sets are larger because our
apartment has more, smaller objects and a leaf keeps every object any ray
proved visible (notes/query.md); the relative codings win on the block,
as in the paper, and lose or tie on one apartment. Our copy machine has
146 objects, 12 times fewer than the paper's, and its views are random in
the whole view box, where much of the machine is in sight; the paper
walked around a machine of 1,726 parts. The oracle's culling
falls short of Durand's (notes/oracle.md, "Street-level culling"); the
committed forest is too sparse for the occlusion sweep to prove anything
(notes/oracle.md, "The thicket's truth"); the grove, a dense forest whose
crowns are closed, is culled from cells of 0.25 m but hardly from cells of
1 m, whose spread opens the seams between its leaves (notes/oracle.md, "The
grove, and the sweep reaching back"). The paper's
51% is for buildings of 5,000-8,000 polygons, where a slice holds part of
a facade; the committed city's buildings are boxes of 12 triangles, and
San Francisco's gain comes from its terrain cut into pieces (papers/004
sec. 6; notes/shrink.md, "Pieces").""")
PY
