#!/usr/bin/env bash
# The Ray driver end to end (issue 17, run by .ci/run): installs the
# pinned Ray in a virtual environment, starts a Ray cluster on 127.0.0.1
# with two worker CPUs, builds a committed scene through
# scripts/ray_build.py in four shards, kills (SIGKILL) the Ray worker
# running one shard mid-way, and checks that Ray ran that shard again
# and that the merged file is byte for byte a local build's.
#
#   scripts/test-ray-build.sh
set -euo pipefail
cd "$(dirname "$0")/.."
. scripts/ray-env.sh
tmp=$(mktemp -d)
port=${VIS5D_RAY_PORT:-6391}
export RAY_ADDRESS="127.0.0.1:$port"
cleanup() {
    "$venv/bin/ray" stop --force > /dev/null 2>&1 || true
    rm -rf "$tmp"
}
trap cleanup EXIT
"$venv/bin/ray" start --head --node-ip-address 127.0.0.1 --port "$port" --num-cpus 2 \
    --include-dashboard=false --disable-usage-stats > "$tmp/ray-start.log" 2>&1 \
    || { cat "$tmp/ray-start.log" >&2; exit 1; }

model=scenes/apartment.obj
"$bin" build "$model" --top-levels 3 -o "$tmp/local.v5d" > /dev/null
"$venv/bin/python" scripts/ray_build.py "$model" -o "$tmp/ray.v5d" --shards 4 \
    --top-levels 3 --vis5d "$bin" > "$tmp/driver.log" 2>&1 &
driver=$!

# The first shard seen running: kill the Ray worker that runs it (and the
# shard's process).
killed=""
for _ in $(seq 1 3000); do
    shard=$(pgrep -f 'vis5d-shard-.*/vis5d build' | head -1 || true)
    if [ -n "$shard" ]; then
        worker=$(ps -o ppid= -p "$shard" | tr -d ' ')
        kill -9 "$worker" "$shard" 2> /dev/null || true
        killed="worker $worker (shard process $shard)"
        break
    fi
    kill -0 "$driver" 2> /dev/null || break
    sleep 0.02
done
rc=0
wait "$driver" || rc=$?
if [ "$rc" -ne 0 ]; then
    cat "$tmp/driver.log" >&2
    echo "test-ray-build: the driver failed ($rc)" >&2
    exit 1
fi
if [ -z "$killed" ]; then
    echo "test-ray-build: no shard was seen running, so none was killed" >&2
    exit 1
fi
if ! cmp -s "$tmp/local.v5d" "$tmp/ray.v5d"; then
    echo "test-ray-build: the Ray build differs from the local one" >&2
    exit 1
fi
echo "test-ray-build: killed Ray $killed mid-way; Ray ran the shard again;" \
    "the merged file ($(stat -c %s "$tmp/ray.v5d") bytes) equals the local build's"
