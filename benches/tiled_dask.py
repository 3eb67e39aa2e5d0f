#!/usr/bin/env python3
"""The tiled reconstruction on a local Dask cluster, timed: `sphcover.reconstruct(...,
tiles=N, client=...)` of one scan, with the wall time, the calling process's peak memory and
each worker's, and the mesh written to PLY (compare it with `sphcover recon --tiles N`
using `cmp`).

    python3 benches/tiled_dask.py SCAN.ply OUT.ply --tiles 4 --halo 0.05 --workers 2 \\
        --threads 1 --scratch /tmp/tiles

With `--kill-a-worker` the first attempt at the first tile ends its worker's process at
once, as a machine that goes down would; Dask runs the task again on a new worker, and the
mesh must come out the same (`cmp` it with a run without the flag).

With `--stream` it runs `sphcover.reconstruct_file(SCAN, tiles=N, client=...)` instead
(`sphcover recon --tiles N --stream`): the scan is read from its file into tile files in the
scratch directory (needed then), never whole, and each tile's function is a task that reads
its tile's file.

Needs the `sphcover` package (docs/python.md) and `distributed` in the interpreter's
environment. A real cluster takes `--scheduler ADDRESS` instead of a local one; its
workers must then reach the scratch directory.
"""

import argparse
import os
import resource
import sys
import time

from distributed import Client, LocalCluster

import sphcover


def killing_first_attempt(function, marker):
    """`function`, except that its first call anywhere ends the calling process at once."""

    def run(tile, options):
        if not os.path.exists(marker):
            with open(marker, "w"):
                pass
            os._exit(1)
        return function(tile, options)

    return run


def peak_mib() -> float:
    """This process's peak resident set, in MiB (Linux reports KiB)."""
    return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scan")
    parser.add_argument("out")
    parser.add_argument("--tiles", type=int, default=2)
    parser.add_argument("--halo", type=float, help="default: a fifth of a tile, at most 0.1")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--threads", type=int, default=1, help="threads per worker")
    parser.add_argument("--scratch", help="directory for the tiles' inputs")
    parser.add_argument("--scheduler", help="address of a running Dask scheduler")
    parser.add_argument(
        "--stream", action="store_true", help="stream the file into tile files (needs --scratch)"
    )
    parser.add_argument(
        "--kill-a-worker",
        action="store_true",
        help="end the first task's worker process (needs --scratch, where a marker file goes)",
    )
    args = parser.parse_args()
    if (args.stream or args.kill_a_worker) and not args.scratch:
        parser.error("--stream and --kill-a-worker need --scratch")

    start = time.perf_counter()
    if args.scheduler:
        cluster = None
        client = Client(args.scheduler)
    else:
        cluster = LocalCluster(
            n_workers=args.workers,
            threads_per_worker=args.threads,
            processes=True,
            dashboard_address=None,
            memory_limit=0,
        )
        client = Client(cluster)
    with client:
        if args.scratch:
            os.makedirs(args.scratch, exist_ok=True)
        function = sphcover.streamed_tile_function if args.stream else sphcover.tile_function
        marker = None
        if args.kill_a_worker:
            marker = os.path.join(args.scratch, "killed-a-worker")
            if os.path.exists(marker):
                os.remove(marker)
            function = killing_first_attempt(function, marker)
        map_tiles = sphcover.dask_map_tiles(client, function=function)
        if args.stream:
            read = time.perf_counter()
            mesh = sphcover.reconstruct_file(
                args.scan, tiles=args.tiles, halo=args.halo, scratch=args.scratch,
                map_tiles=map_tiles,
            )
        else:
            cloud = sphcover.read(args.scan)
            read = time.perf_counter()
            mesh = sphcover.reconstruct(
                cloud, tiles=args.tiles, halo=args.halo, scratch=args.scratch, map_tiles=map_tiles
            )
        done = time.perf_counter()
        if marker is not None:
            print(f"a worker was killed: {os.path.exists(marker)}")
            os.remove(marker)
        sphcover.write(args.out, mesh)
        workers = client.run(peak_mib)
    if cluster is not None:
        cluster.close()
    stats = mesh.stats
    print(
        f"{stats['points']} points in {args.tiles}^3 tiles (halo {args.halo or 'default'}) on "
        f"{args.workers} workers x {args.threads} threads: read {read - start:.1f} s, "
        f"reconstruct {done - read:.1f} s; {stats['triangles']} triangles, "
        f"{stats['components']} components, watertight {stats['watertight']}"
    )
    print(f"peak MiB: caller {peak_mib():.0f}; workers " + ", ".join(
        f"{v:.0f}" for v in sorted(workers.values())
    ))
    return 0


if __name__ == "__main__":
    sys.exit(main())
