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


# -- recordings written without copies of their traces ---------------------------------------------------------


def _recording_variables():
    from scanner.storage import mat5

    rng = np.random.default_rng(4)
    n = mat5.STREAMED_BYTES // 8 * 2 + 13  # two blocks and a part: streamed, the blocks' ends checked
    return {
        "acc": rng.standard_normal(n),  # 1-D: a column, as savemat's oned_as="column"
        "gyro": rng.standard_normal((n, 3)),  # 2-D, written column after column
        "small": np.arange(7.0),
        "image": rng.integers(0, 255, (4, 5, 3), dtype=np.uint8),
        "meta": {"name": "r1", "fs": {"acc": 100.0}, "meta_json": "{}"},
    }


def test_streamed_variables_read_back_exactly_as_savemat_writes_them(tmp_path):
    import zlib

    from scanner.storage import mat5

    variables = _recording_variables()
    with open(tmp_path / "streamed.mat", "wb") as handle:
        mat5.write_variables(handle, variables, zlib, 6)
    scipy.io.savemat(tmp_path / "savemat.mat", variables, long_field_names=True, do_compression=True,
                     oned_as="column")
    ours = scipy.io.loadmat(tmp_path / "streamed.mat")
    theirs = scipy.io.loadmat(tmp_path / "savemat.mat")
    for name in ("acc", "gyro", "small", "image"):
        assert ours[name].dtype == theirs[name].dtype and np.array_equal(ours[name], theirs[name]), name
    assert ours["acc"].shape == (len(variables["acc"]), 1)
    assert ours["meta"]["fs"][0, 0]["acc"][0, 0][0, 0] == 100.0
    # the project's bounded reader walks every element of it too
    bounded = mat5.read_mat_bytes((tmp_path / "streamed.mat").read_bytes(), 1 << 30)
    assert np.array_equal(bounded["gyro"], variables["gyro"])


@pytest.mark.skipif(__import__("shutil").which("octave") is None,
                    reason="GNU Octave is not installed (apt-get install octave)")
def test_octave_reads_a_streamed_recording(tmp_path):
    from isal import isal_zlib

    from scanner.storage import mat5

    variables = _recording_variables()
    with open(tmp_path / "r.mat", "wb") as handle:
        mat5.write_variables(handle, variables, isal_zlib, 1)
    code = (f"s = load('{tmp_path / 'r.mat'}'); printf('%d %d\\n', size(s.gyro)); "
            "printf('%.17g\\n', sum(s.gyro(:, 3))); printf('%.17g\\n', s.acc(end)); printf('%s\\n', s.meta.name);")
    result = subprocess.run(["octave", "--no-gui", "--no-window-system", "--quiet", "--eval", code],
                            capture_output=True, text=True, timeout=300)
    assert result.returncode == 0, result.stderr
    lines = result.stdout.split()
    assert lines[:2] == [str(len(variables["gyro"])), "3"]
    # Octave's sum adds in order as numpy's pairwise sum need not: equal within n ulps of the magnitude sum
    column = variables["gyro"][:, 2]
    assert abs(float(lines[2]) - column.sum()) <= len(column) * np.spacing(np.abs(column).sum())
    assert float(lines[3]) == variables["acc"][-1]
    assert lines[4] == "r1"


_PEAK_OF_INGEST = """
import sys
from scanner.cli import main

def peak_bytes():
    with open("/proc/self/status") as status:
        return int(next(line for line in status if line.startswith("VmHWM:")).split()[1]) * 1024

import scipy.io
from scanner.cli import build_parser
build_parser(["ingest"])  # the command's group and the libraries it loads (scipy.io when it writes), before the start
start = peak_bytes()
code = main(["ingest", "--mapping", sys.argv[1], sys.argv[2], "--db", sys.argv[3], "--name", "big"])
print(code, peak_bytes() - start)
"""


@pytest.mark.skipif(not sys.platform.startswith("linux"), reason="reads the peak from /proc")
def test_an_int8_npy_is_ingested_within_twice_its_size_as_held(tmp_path):
    # 20 M int8 samples are held as float64: 160 MB. The file read (20 MB), its float64 copy scaled in place,
    # the finite mask (20 MB) and the trace taken without a copy stay below 1.5 x 160 MB; the .mat is written
    # a block at a time. Before: the scaled copy, the trace's copy and savemat's element and compressed copies
    # peaked near 3.4 times the held size.
    (tmp_path / "src" / "a").mkdir(parents=True)
    np.save(tmp_path / "src" / "a" / "r.npy", np.random.default_rng(0).integers(-128, 127, 20_000_000, np.int8))
    (tmp_path / "map.toml").write_text('name = "big"\n[labels]\nfrom = "folder"\n[[files]]\nglob = "**/*.npy"\n'
                                       'rate = 1000\n  [[files.channels]]\n  name = "acc"\n  role = "vibration"\n'
                                       '  scale = 0.5\n')
    run = subprocess.run([sys.executable, "-c", _PEAK_OF_INGEST, str(tmp_path / "map.toml"), str(tmp_path / "src"),
                          str(tmp_path / "db")], capture_output=True, text=True, timeout=300)
    assert run.returncode == 0, run.stderr
    code, peak = map(int, run.stdout.splitlines()[-1].split())
    held = 20_000_000 * 8
    assert code == 0 and peak < 2 * held, peak / held
    from scanner.storage.ingest import load_recordings

    (recording,) = load_recordings(tmp_path / "db" / "recordings" / "big")
    expected = np.load(tmp_path / "src" / "a" / "r.npy").astype(np.float64) * 0.5
    assert np.array_equal(recording.channels["acc"].data, expected)
