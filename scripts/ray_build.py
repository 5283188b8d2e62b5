#!/usr/bin/env python3
"""Build a .v5d on a Ray cluster (issue 17, notes/scale.md).

The build is cut into shards (`vis5d build --top-levels K --shard I/N`):
each shard is a Ray task. The driver puts the vis5d binary and the scene
in Ray's object store once; each task writes them to a scratch folder on
its worker, runs its shard there and returns the part's bytes. Ray runs
a task again when its worker dies or the shard fails (`--retries`). The
driver gathers the parts and joins them with `vis5d merge`, which checks
them and writes the very bytes a single `vis5d build --top-levels K`
writes.

    scripts/ray_build.py MODEL -o OUT.v5d [--shards N] [--top-levels K]
        [--address ADDR] [--vis5d BIN] [-- BUILD_FLAGS...]

Without --address it joins the cluster that `ray start` made on this
machine (RAY_ADDRESS, else "auto"), or starts a local one. The model must
be one file (.obj or .glb; a .gltf with separate buffers: pack it as .glb
first). Install the pinned Ray with
`pip install -r scripts/requirements.txt` (a virtual environment).
"""

import argparse
import os
import subprocess
import sys
import tempfile
import time

import ray
from tqdm import tqdm


@ray.remote
def build_shard(binary, scene, scene_name, shard, shards, flags):
    """Runs shard `shard` of `shards` of the build of `scene` (bytes, file
    name `scene_name`) with the vis5d `binary` (bytes) and build `flags`;
    returns the part's bytes. Raises when the build fails, so that Ray
    runs the task again."""
    with tempfile.TemporaryDirectory(prefix="vis5d-shard-") as d:
        exe = os.path.join(d, "vis5d")
        with open(exe, "wb") as f:
            f.write(binary)
        os.chmod(exe, 0o755)
        model = os.path.join(d, scene_name)
        with open(model, "wb") as f:
            f.write(scene)
        part = os.path.join(d, f"part{shard}.v5dpart")
        cmd = [exe, "build", model, "--shard", f"{shard}/{shards}", "-o", part, *flags]
        run = subprocess.run(cmd, capture_output=True, text=True)
        if run.returncode != 0:
            raise RuntimeError(
                f"shard {shard}/{shards} failed ({run.returncode}): {run.stderr.strip()}"
            )
        with open(part, "rb") as f:
            return f.read()


def main():
    p = argparse.ArgumentParser(
        description="Build a .v5d on a Ray cluster: one task per shard, "
        "retried when a worker fails, merged into the bytes of a single build.",
        epilog="Flags after -- go to every `vis5d build` (e.g. -- --seed 3 --max-depth 10).",
    )
    p.add_argument("model", help="the scene (.obj or .glb)")
    p.add_argument("-o", "--output", required=True, help="where to write the .v5d")
    p.add_argument("--shards", type=int, default=0,
                   help="tasks to cut the build into [default: the cluster's CPUs, at most 2^K]")
    p.add_argument("--top-levels", type=int, default=4,
                   help="fixed levels K: 2^K subtrees to deal to the shards [0 to 10; default 4]")
    p.add_argument("--address", default=None,
                   help="the Ray cluster [default: RAY_ADDRESS, a cluster on this machine, "
                   "else a new local one]")
    p.add_argument("--vis5d", default=None,
                   help="the vis5d binary to ship [default: target/release/vis5d, "
                   "under CARGO_TARGET_DIR when set]")
    p.add_argument("--retries", type=int, default=3,
                   help="times a shard is run again after a failure [default 3]")
    p.add_argument("--cpus-per-shard", type=float, default=1.0,
                   help="CPUs Ray reserves for each shard [default 1]")
    argv = sys.argv[1:]
    cut = argv.index("--") if "--" in argv else len(argv)
    a = p.parse_args(argv[:cut])
    flags = argv[cut + 1:]
    for bad in ("--shard", "-o", "--output", "--top-levels", "--checkpoint"):
        if bad in flags:
            p.error(f"{bad} is set by the driver; remove it from the build flags")
    if not 0 <= a.top_levels <= 10:
        p.error("--top-levels must be 0 to 10")
    root = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
    target = os.environ.get("CARGO_TARGET_DIR") or os.path.join(root, "target")
    exe = a.vis5d or os.path.join(target, "release", "vis5d")
    if not os.access(exe, os.X_OK):
        p.error(f"{exe}: no vis5d binary there (cargo build --release, or --vis5d BIN)")
    if not os.path.isfile(a.model):
        p.error(f"{a.model}: no such scene file")
    if a.model.lower().endswith(".gltf"):
        p.error(f"{a.model}: a .gltf may need files beside it; pack it as .glb first")

    address = a.address or os.environ.get("RAY_ADDRESS")
    try:
        ray.init(address=address or "auto", logging_level="ERROR", log_to_driver=False)
    except ConnectionError:
        if address:
            raise
        ray.init(logging_level="ERROR", log_to_driver=False)
    cpus = int(ray.cluster_resources().get("CPU", 1))
    shards = a.shards or max(1, min(cpus, 1 << a.top_levels))
    start = time.time()
    with open(exe, "rb") as f:
        binary = ray.put(f.read())
    with open(a.model, "rb") as f:
        scene = ray.put(f.read())
    build_flags = ["--top-levels", str(a.top_levels), *flags]
    task = build_shard.options(
        max_retries=a.retries, retry_exceptions=True, num_cpus=a.cpus_per_shard
    )
    pending = {
        task.remote(binary, scene, os.path.basename(a.model), i, shards, build_flags): i
        for i in range(shards)
    }
    parts = {}
    with tempfile.TemporaryDirectory(prefix="vis5d-merge-") as d, tqdm(
        total=shards, desc=f"{shards} shards on {cpus} CPUs", unit="shard",
        disable=None, file=sys.stderr,
    ) as bar:
        while pending:
            done, _ = ray.wait(list(pending), num_returns=1)
            i = pending.pop(done[0])
            path = os.path.join(d, f"part{i}.v5dpart")
            with open(path, "wb") as f:
                f.write(ray.get(done[0]))
            parts[i] = path
            bar.update(1)
        merge = subprocess.run(
            [exe, "merge", *[parts[i] for i in range(shards)], "-o", a.output],
            capture_output=True, text=True,
        )
    if merge.returncode != 0:
        sys.exit(f"ray_build: merging the parts failed: {merge.stderr.strip()}")
    print(f"built {a.output} from {shards} shards of 2^{a.top_levels} subtrees "
          f"in {time.time() - start:.1f} s", file=sys.stderr)


if __name__ == "__main__":
    main()
