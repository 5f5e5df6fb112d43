"""The .mat scan format (docs/database.md): lossless round trip, readable without project code, clear errors: the
system tests (peak memory in a fresh process)."""

from __future__ import annotations

import subprocess
import sys

import numpy as np
import pytest
import scipy.io

_PEAK_WHILE_READING = """
import sys
from scanner.storage import mat5

def peak_bytes():  # this process image's high-water mark (ru_maxrss would carry the parent's over the exec)
    with open("/proc/self/status") as status:
        return int(next(line for line in status if line.startswith("VmHWM:")).split()[1]) * 1024

start = peak_bytes()
stream = mat5.uncompressed_copy(sys.argv[1], 1 << 30)
print(len(stream.getbuffer()), peak_bytes() - start)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the peak from /proc")
def test_reading_a_large_mat_file_holds_about_the_stream_and_one_variable(tmp_path):
    # The uncompressed copy (up to 1 GB for an ingested file) grows variable by variable, each variable let
    # go once written: the stream with its 1/8 overallocation, plus one 20 MB variable while inflated and
    # copied, is below 1.5 times the stream. Keeping every variable to join them once needed twice it.
    # Read in a fresh process, whose peak is that of the reading alone.
    scipy.io.savemat(tmp_path / "big.mat", {f"v{i}": np.zeros(2_500_000) for i in range(8)}, do_compression=True)
    run = subprocess.run([sys.executable, "-c", _PEAK_WHILE_READING, str(tmp_path / "big.mat")],
                         capture_output=True, text=True, check=True, timeout=120)
    size, peak = map(int, run.stdout.split())
    assert size > 160e6 and peak < 1.5 * size
