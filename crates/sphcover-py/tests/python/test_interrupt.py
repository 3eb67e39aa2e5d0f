"""Ctrl-C ends a long call within a second."""

import signal
import subprocess
import sys
import textwrap
import time

LONG_RECONSTRUCTION = textwrap.dedent(
    """
    import numpy as np
    import sphcover

    n = 400_000
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    s = np.sqrt(1.0 - z * z)
    golden = np.pi * (3.0 - np.sqrt(5.0))
    normals = np.stack([s * np.cos(golden * i), s * np.sin(golden * i), z], axis=1)

    def progress(name, index, count):
        if index == 0:
            print("started", flush=True)

    sphcover.reconstruct(0.4 * normals, normals, progress=progress)
    print("finished", flush=True)
    """
)


def test_ctrl_c_ends_a_long_reconstruction_within_a_second():
    child = subprocess.Popen(
        [sys.executable, "-c", LONG_RECONSTRUCTION],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        assert child.stdout.readline().strip() == "started"
        time.sleep(0.5)  # well inside the first stages of a run of several seconds
        sent = time.monotonic()
        child.send_signal(signal.SIGINT)
        child.wait(timeout=10)
        elapsed = time.monotonic() - sent
    finally:
        child.kill()
    out, err = child.communicate()
    assert "finished" not in out, "the reconstruction ended before the interrupt: not a long call"
    assert "KeyboardInterrupt" in err
    assert elapsed < 1.0, f"the call took {elapsed:.2f} s to end after Ctrl-C"
