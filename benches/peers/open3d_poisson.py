#!/usr/bin/env python3
"""Screened Poisson reconstruction with Open3D, as a peer for `recon-bench`.

    open3d_poisson.py IN.ply OUT.ply [--depth 10] [--scale 1.1] [--linear-fit]
                      [--trim-quantile Q] [--estimate-normals K]

Reads an oriented point set (PLY with nx ny nz), runs
`TriangleMesh.create_from_point_cloud_poisson` (Kazhdan & Hoppe's screened Poisson, as
packaged by Open3D) and writes the mesh untrimmed, as PoissonRecon does by default.
`--trim-quantile Q` removes the vertices whose density is below the Q-quantile (the usual
Open3D recipe). Needs `pip install open3d` (0.18 or later); the CI never runs it.
"""
import argparse
import sys
import time


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("input")
    ap.add_argument("output")
    ap.add_argument("--depth", type=int, default=10)
    ap.add_argument("--scale", type=float, default=1.1)
    ap.add_argument("--linear-fit", action="store_true")
    ap.add_argument("--trim-quantile", type=float, default=None)
    ap.add_argument("--estimate-normals", type=int, default=0, metavar="K",
                    help="estimate and orient normals from K neighbours (for unoriented input)")
    a = ap.parse_args(argv)

    import numpy as np
    import open3d as o3d

    t0 = time.perf_counter()
    pcd = o3d.io.read_point_cloud(a.input)
    if len(pcd.points) == 0:
        print(f"error: no points read from {a.input}", file=sys.stderr)
        return 2
    if a.estimate_normals > 0:
        pcd.estimate_normals(o3d.geometry.KDTreeSearchParamKNN(a.estimate_normals))
        pcd.orient_normals_consistent_tangent_plane(a.estimate_normals)
    elif not pcd.has_normals():
        print("error: the input has no normals (pass --estimate-normals K)", file=sys.stderr)
        return 2
    t1 = time.perf_counter()
    mesh, densities = o3d.geometry.TriangleMesh.create_from_point_cloud_poisson(
        pcd, depth=a.depth, scale=a.scale, linear_fit=a.linear_fit)
    t2 = time.perf_counter()
    if a.trim_quantile is not None:
        d = np.asarray(densities)
        mesh.remove_vertices_by_mask(d < np.quantile(d, a.trim_quantile))
    if not o3d.io.write_triangle_mesh(a.output, mesh):
        print(f"error: cannot write {a.output}", file=sys.stderr)
        return 1
    t3 = time.perf_counter()
    print(f"open3d poisson depth {a.depth}: {len(pcd.points)} points -> {len(mesh.triangles)} triangles; "
          f"read {t1 - t0:.2f} s, poisson {t2 - t1:.2f} s, write {t3 - t2:.2f} s", file=sys.stderr)
    return 0


if __name__ == "__main__":
    sys.exit(main())
