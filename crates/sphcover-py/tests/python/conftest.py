"""Shared fixtures of the sphcover Python tests: the repository's bundled files and the
`sphcover` command the package is compared with."""

import os
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

REPO = Path(__file__).resolve().parents[4]
FIXTURES = REPO / "fixtures"


@pytest.fixture
def fixtures() -> Path:
    return FIXTURES


@pytest.fixture
def cli() -> str:
    """The `sphcover` command: $SPHCOVER_CLI (what tests/pytest.rs builds), else the one on
    PATH. The comparisons with the command line cannot run without it, so its absence fails
    them rather than skipping."""
    path = os.environ.get("SPHCOVER_CLI") or shutil.which("sphcover")
    if not path:
        pytest.fail("no sphcover command: set SPHCOVER_CLI to the built binary")
    return path


@pytest.fixture
def run_cli(cli):
    def run(*args, expect_ok=True):
        result = subprocess.run(
            [cli, "--quiet", *map(str, args)], capture_output=True, text=True
        )
        if expect_ok and result.returncode != 0:
            pytest.fail(f"sphcover {' '.join(map(str, args))} failed: {result.stderr}")
        return result

    return run


def fibonacci_sphere(n: int, radius: float = 0.4):
    """`n` points evenly on a sphere, and their outward normals."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    s = np.sqrt(1.0 - z * z)
    golden = np.pi * (3.0 - np.sqrt(5.0))
    normals = np.stack([s * np.cos(golden * i), s * np.sin(golden * i), z], axis=1)
    return radius * normals, normals
