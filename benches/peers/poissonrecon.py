#!/usr/bin/env python3
"""Screened Poisson reconstruction with Kazhdan's own PoissonRecon, as a peer for `recon-bench`.

    poissonrecon.py IN.ply OUT.ply [--bin DIR] [--depth 10] [--trim T] [-- EXTRA...]

Runs `PoissonRecon --in IN --out OUT --depth D` on an oriented point set (PLY with nx ny nz)
and writes the mesh untrimmed, as PoissonRecon does by default. With `--trim T` it also asks
PoissonRecon for the sampling density (`--density`) and runs its `SurfaceTrimmer --trim T`,
which removes the surface where the density is below T (7 at depth 10 in PoissonRecon's
documentation) and the small islands this leaves. Arguments after `--` go to PoissonRecon.

PoissonRecon is not on a package index: build it from https://github.com/mkazhdan/PoissonRecon
(`make poissonrecon surfacetrimmer`) and pass `--bin` the directory holding `PoissonRecon` and
`SurfaceTrimmer` (default: `$POISSONRECON_BIN`, else the `PATH`). The CI never runs it.
"""
import argparse
import os
import shutil
import subprocess
import sys
import tempfile
import time


def find(name, bin_dir):
    if bin_dir:
        path = os.path.join(bin_dir, name)
        return path if os.access(path, os.X_OK) else None
    return shutil.which(name)


def main(argv=None):
    argv = sys.argv[1:] if argv is None else argv
    extra = []
    if "--" in argv:
        k = argv.index("--")
        argv, extra = argv[:k], argv[k + 1:]
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("input")
    ap.add_argument("output")
    ap.add_argument("--bin", default=os.environ.get("POISSONRECON_BIN"),
                    help="directory of the PoissonRecon and SurfaceTrimmer executables")
    ap.add_argument("--depth", type=int, default=10)
    ap.add_argument("--trim", type=float, default=None,
                    help="run SurfaceTrimmer with this density threshold")
    a = ap.parse_args(argv)

    recon = find("PoissonRecon", a.bin)
    trimmer = find("SurfaceTrimmer", a.bin) if a.trim is not None else None
    if recon is None or (a.trim is not None and trimmer is None):
        where = f"in {a.bin}" if a.bin else "on the PATH (or pass --bin DIR)"
        print(f"error: PoissonRecon{' and SurfaceTrimmer' if a.trim is not None else ''} not found {where}",
              file=sys.stderr)
        return 2

    t0 = time.perf_counter()
    with tempfile.TemporaryDirectory(prefix="poissonrecon-") as tmp:
        untrimmed = os.path.join(tmp, "untrimmed.ply") if trimmer else a.output
        cmd = [recon, "--in", a.input, "--out", untrimmed, "--depth", str(a.depth)]
        if trimmer:
            cmd.append("--density")
        subprocess.run(cmd + extra, check=True, stdout=subprocess.DEVNULL)
        t1 = time.perf_counter()
        if trimmer:
            subprocess.run([trimmer, "--in", untrimmed, "--out", a.output, "--trim", str(a.trim)],
                           check=True, stdout=subprocess.DEVNULL)
    t2 = time.perf_counter()
    trimmed = f", SurfaceTrimmer --trim {a.trim:g} {t2 - t1:.2f} s" if trimmer else ""
    print(f"PoissonRecon depth {a.depth}: {t1 - t0:.2f} s{trimmed}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    try:
        sys.exit(main())
    except subprocess.CalledProcessError as e:
        print(f"error: {e}", file=sys.stderr)
        sys.exit(1)
