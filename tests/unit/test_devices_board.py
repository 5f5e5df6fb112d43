"""The serial sensor board: protocol parsing by hand, exact byte exchanges through pyserial on a
pseudo-terminal (PyMeasure style), and the driver against the emulator with every injected fault."""

from __future__ import annotations

import doctest
import sys

import numpy as np
import pytest

pytestmark = pytest.mark.skipif(sys.platform == "win32", reason="pseudo-terminals are POSIX only")


from scanner.acquisition.config import BoardConfig  # noqa: E402
from scanner.acquisition.devices import board as board_module  # noqa: E402
from scanner.acquisition.devices.board import (  # noqa: E402
    BoardModel,
    LineError,
    SerialBoard,
    StreamCollector,
    checksum,
    field_change,
    format_data_line,
    parse_data_line,
    resync,
)
from scanner.acquisition.devices.protocols import (  # noqa: E402
    BoardSample,
    DeviceUnavailable,
)
from scanner.acquisition.devices.sources import SimulatedSample  # noqa: E402


def test_docstring_examples():
    assert doctest.testmod(board_module).failed == 0


# -- the protocol by hand ----------------------------------------------------------------------------

def test_checksum_is_the_xor_of_the_characters():
    assert checksum("M") == "4D"                  # 0x4D
    assert checksum("AB") == "03"                 # 0x41 ^ 0x42
    assert checksum("T,1") == "49"                # 0x54 ^ 0x2C ^ 0x31
    assert checksum("") == "00"
    assert format_data_line("T", 1000, (25.0, 21.5)) == "T,1000,25.00,21.50*78"


def test_parse_data_lines():
    assert parse_data_line("T,1000,25.00,21.50*78") == BoardSample("T", 1000, (25.0, 21.5))
    assert parse_data_line("T,1000,25.00,21.50*78".lower().upper()) == BoardSample("T", 1000, (25.0, 21.5))
    assert parse_data_line("M,2000,0.10,-0.05,1.00*79") == BoardSample("M", 2000, (0.1, -0.05, 1.0))
    with pytest.raises(LineError, match="bad checksum 79") as bad:
        parse_data_line("T,1000,25.00,21.50*79")
    assert not bad.value.garbage
    for garbage in ("T,1000,25.00*78", "X,1,2*00", "T,1000,25.00,21.50", "hello"):
        with pytest.raises(LineError) as error:
            parse_data_line(garbage)
        assert error.value.garbage


def test_resync_keeps_the_frame_after_noise():
    assert resync(b"\x00\xff#~T,1000,25.00,21.50*78") == ("T,1000,25.00,21.50*78", 4)
    assert resync(b"OK HEAT") == ("OK HEAT", 0)
    assert resync(b"xxERR relay") == ("ERR relay", 2)
    assert resync(b"\x00\x01\x02") == (None, 3)
    # a damaged frame after noise is still a frame (dropped later for its checksum, not as garbage)
    assert resync(b"zzT,1000,25.00,21.50*00") == ("T,1000,25.00,21.50*00", 2)


def test_field_change_is_the_signed_magnitude():
    b = np.array([[3.0, 4.0, 0.0], [0.0, 0.0, -2.0], [1.0, -2.0, 2.0], [0.0, 0.0, 0.0]])
    assert list(field_change(b)) == [5.0, -2.0, 3.0, 0.0]


def test_stream_collector_places_samples_by_the_counter():
    collector = StreamCollector(hz=20, count=5, fields=2)
    for ms, value in ((1000, 20.0), (1050, 21.0), (1150, 23.0), (1150, 99.0), (1200, 24.0)):
        collector.add(BoardSample("T", ms, (value, 21.5)))
    record = collector.record()
    # 1100 ms never arrived: interpolated between 21 and 23; the repeated 1150 ms line is a duplicate
    assert record.missing == 1 and record.duplicates == 1
    assert list(record.values[:, 0]) == [20.0, 21.0, 22.0, 23.0, 24.0]
    assert collector.done


def test_board_model_plays_cooling_after_heat_and_field_after_calibration():
    sample = SimulatedSample("granite-polished", seed=3)
    model = BoardModel(sample, device="test")
    model.begin("T", 20)
    assert model.values("T", 0)[0] == pytest.approx(sample.t_amb + 0.1, abs=0.1)
    model.heat()
    model.begin("T", 20)
    cooling = SimulatedSample("granite-polished", seed=3).cooling("test")
    assert [model.values("T", i)[0] for i in range(5)] == list(cooling[:5])
    model.begin("M", 80)
    assert np.linalg.norm(model.values("M", 0)) == pytest.approx(np.linalg.norm([18.0, -4.0, 41.0]))
    model.calibrate()
    model.begin("M", 80)
    field = SimulatedSample("granite-polished", seed=3).field_change("test")
    measured = field_change(np.array([model.values("M", i) for i in range(len(field))]))
    assert measured == pytest.approx(field, abs=1e-12)


# -- exact byte exchanges through pyserial on a pty (PyMeasure-style expected protocol) ----------------


def test_a_missing_port_is_one_line():
    with pytest.raises(DeviceUnavailable, match="serial board: cannot open /nonexistent/ttyACM9") as error:
        SerialBoard(BoardConfig(port="/nonexistent/ttyACM9"))
    assert "\n" not in str(error.value)


# -- the emulator: exact answers, then the driver against every fault ---------------------------------

@pytest.fixture
def sample():
    return SimulatedSample("granite-polished", seed=5)


