#!/usr/bin/env python3
"""Times Embree (through the embreex package) on a ray file written by
`vis5d trace --write-rays`, over the triangles of `--write-triangles`:
closest hits within each ray's tmax, on 1 or more processes (embreex
traces on the calling thread; each process builds its own BVH and traces
its share of the rays, all starting together). Formats: notes/trace.md.

    embree_trace.py TRIANGLES RAYS [--threads T] [--min-seconds S] [--json]
"""

import argparse
import json
import multiprocessing as mp
import sys
import time

import numpy as np
from embreex import rtcore_scene as rtcs
from embreex.mesh_construction import TriangleMesh


def load(tris_path, rays_path):
    tris = np.fromfile(tris_path, dtype="<f4")
    rays = np.fromfile(rays_path, dtype="<f4")
    if tris.size % 9 or rays.size % 7:
        sys.exit(f"{tris_path} or {rays_path} is not a whole number of records")
    return tris.reshape(-1, 3, 3), rays.reshape(-1, 7)


def worker(tris_path, rays_path, share, shares, passes, barrier, out):
    tris, rays = load(tris_path, rays_path)
    part = rays[share::shares]
    origins = np.ascontiguousarray(part[:, 0:3])
    dirs = np.ascontiguousarray(part[:, 3:6])
    tmax = np.ascontiguousarray(part[:, 6])
    start = time.perf_counter()
    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, tris)
    # A first trace commits the scene (Embree builds lazily) and warms it.
    hits = int((scene.run(origins, dirs, dists=tmax.copy()) >= 0).sum())
    bvh = time.perf_counter() - start
    times = []
    for _ in range(passes):
        # embreex writes the hit distances into `dists`: a fresh copy each
        # pass, made before the clock starts.
        dists = tmax.copy()
        barrier.wait()
        t = time.perf_counter()
        scene.run(origins, dirs, dists=dists)
        times.append(time.perf_counter() - t)
    out.put((share, hits, bvh, times))


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("triangles")
    ap.add_argument("rays")
    ap.add_argument("--threads", type=int, default=1)
    ap.add_argument("--min-seconds", type=float, default=1.0)
    ap.add_argument("--json", action="store_true")
    a = ap.parse_args()
    tris, rays = load(a.triangles, a.rays)
    # Passes enough for the time asked, from one timed pass on one process.
    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, tris)
    o, d, m = (np.ascontiguousarray(rays[:, s]) for s in (slice(0, 3), slice(3, 6), 6))
    scene.run(o[:1000], d[:1000], dists=m[:1000].copy())
    t = time.perf_counter()
    scene.run(o, d, dists=m.copy())
    one = time.perf_counter() - t
    passes = max(3, int(a.min_seconds * a.threads / max(one, 1e-6)) + 1)
    del scene
    # Spawned, not forked: this process has started Embree's task threads,
    # which a fork does not carry over safely.
    ctx = mp.get_context("spawn")
    barrier = ctx.Barrier(a.threads)
    out = ctx.Queue()
    procs = [
        ctx.Process(target=worker, args=(a.triangles, a.rays, k, a.threads, passes, barrier, out))
        for k in range(a.threads)
    ]
    for p in procs:
        p.start()
    # A worker that dies (out of memory, say) ends the run, not a wait.
    results = [out.get(timeout=3600) for _ in procs]
    for p in procs:
        p.join()
    # A pass takes as long as its slowest process.
    per_pass = [max(r[3][k] for r in results) for k in range(passes)]
    per_pass.sort()
    report = {
        "tracer": "embree (embreex)",
        "triangles": int(tris.shape[0]),
        "rays": int(rays.shape[0]),
        "hits": sum(r[1] for r in results),
        "threads": a.threads,
        "bvh_seconds": max(r[2] for r in results),
        "passes": passes,
        "best_pass_seconds": per_pass[0],
        "median_pass_seconds": per_pass[len(per_pass) // 2],
        "rays_per_second": rays.shape[0] / per_pass[0],
        "median_rays_per_second": rays.shape[0] / per_pass[len(per_pass) // 2],
    }
    if a.json:
        print(json.dumps(report, indent=2))
    else:
        print(
            f"embree   {report['rays_per_second'] / 1e6:.3f} Mrays/s on {a.threads} "
            f"process{'es' if a.threads > 1 else ''} ({report['hits']} of {report['rays']} hit)"
        )


if __name__ == "__main__":
    main()
