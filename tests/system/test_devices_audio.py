"""The microphone through the real sounddevice/PortAudio, capturing from an ALSA ``file`` PCM fed with a known
signal (the test writes its own ALSA configuration), and the playback microphone: the system tests (PortAudio
in a subprocess)."""

from __future__ import annotations

import ctypes.util
import json
import os
import subprocess
import sys
import textwrap
from pathlib import Path

import numpy as np
import pytest

SYSTEM_ALSA = Path("/usr/share/alsa/alsa.conf")


def ramp(n: int) -> np.ndarray:
    """A signal no two stretches of which look alike: sample i is (i mod 30000) - 15000, 16 bits."""
    return ((np.arange(n) % 30000) - 15000).astype("<i2")


@pytest.fixture
def alsa_file_device(tmp_path):
    """ALSA config: ``texplorer_mic`` reads S16_LE mono 44.1 kHz from a raw file (the ``file`` plugin's
    ``infile``), behind a ``plug`` so PortAudio may ask for any format."""
    if sys.platform != "linux":
        pytest.skip("ALSA is Linux only")
    if ctypes.util.find_library("portaudio") is None:
        pytest.skip("PortAudio library missing: install libportaudio2 (.ci/run does)")
    if not SYSTEM_ALSA.exists():
        pytest.skip(f"no ALSA configuration at {SYSTEM_ALSA}: install libasound2")
    signal = tmp_path / "signal.raw"
    ramp(3 * 44100).tofile(signal)
    config = tmp_path / "asound.conf"
    config.write_text(textwrap.dedent(f"""\
        <{SYSTEM_ALSA}>
        pcm.texplorer_file {{
            type file
            slave.pcm {{ type null }}
            file "/dev/null"
            infile "{signal}"
            format "raw"
        }}
        pcm.texplorer_mic {{
            type plug
            slave {{ pcm "texplorer_file" format S16_LE rate 44100 channels 1 }}
        }}
        """))
    return config


CAPTURE = textwrap.dedent("""\
    import json, sys, time
    import numpy as np
    from scanner.acquisition.config import MicrophoneConfig
    from scanner.acquisition.devices.audio import SoundDeviceMicrophone
    from scanner.acquisition.devices.protocols import DeviceUnavailable

    microphone = SoundDeviceMicrophone(MicrophoneConfig(device="texplorer_mic"))
    before = time.perf_counter()
    first = microphone.start("finger_slide")
    returned = time.perf_counter()
    time.sleep(0.05)
    live = microphone.read()
    capture = microphone.stop()
    np.save(sys.argv[1], capture.samples[:100000])
    try:
        SoundDeviceMicrophone(MicrophoneConfig(device="no such microphone"))
        missing = ""
    except DeviceUnavailable as error:
        missing = str(error)
    print(json.dumps({"name": microphone.describe()["microphone"], "live": int(live.size),
                      "total": int(capture.samples.size), "overflows": capture.overflows,
                      "first_before_return": first <= returned, "first_after_open": first > before - 1.0,
                      "missing": missing}))
    """)


def test_sounddevice_captures_the_known_signal(alsa_file_device, tmp_path):
    environment = {**os.environ, "ALSA_CONFIG_PATH": str(alsa_file_device),
                   "PYTHONPATH": str(Path(__file__).resolve().parents[2])}
    out = tmp_path / "captured.npy"
    # PortAudio reads the ALSA configuration once, when sounddevice is imported: a fresh process.
    run = subprocess.run([sys.executable, "-c", CAPTURE, str(out)], env=environment, capture_output=True,
                         text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    report = json.loads(run.stdout.strip().splitlines()[-1])
    captured = np.load(out)
    n = min(captured.size, 3 * 44100)
    assert n >= 44100
    # 16-bit samples scaled by 1/32768: exactly the file's integers
    assert np.array_equal(captured[:n] * 32768, ramp(n).astype(np.float64))
    assert report["name"] == "texplorer_mic (44100 Hz)"
    assert report["overflows"] == 0 and report["live"] > 0 and report["total"] >= report["live"]
    assert report["first_before_return"] and report["first_after_open"]
    assert report["missing"].startswith("microphone no such microphone:") and "\n" not in report["missing"]
