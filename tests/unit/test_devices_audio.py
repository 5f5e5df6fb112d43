"""The microphone through the real sounddevice/PortAudio, capturing from an ALSA ``file`` PCM fed with a
known signal (the test writes its own ALSA configuration), and the playback microphone."""

from __future__ import annotations

import numpy as np

from scanner.acquisition.devices.audio import PlaybackMicrophone
from scanner.acquisition.devices.sources import SimulatedSample
from scanner.pacing import Pacer


def test_playback_microphone_records_as_long_as_the_shared_clock_ran():
    sample = SimulatedSample("cork-board", seed=4)
    pacer = Pacer(0.0)
    microphone = PlaybackMicrophone(sample, pacer=pacer)
    microphone.start("tool_slide")
    pacer.start()                                  # the DAQ starts after the microphone, on the same clock
    pacer.wait(0.5)                                # the DAQ has read 0.5 s
    live = microphone.read()
    pacer.wait(6.0)                                # longer than the 5 s take
    capture = microphone.stop()
    take = SimulatedSample("cork-board", seed=4).audio("tool_slide", "other")
    assert live.size == 22050 and np.array_equal(live, take[:22050])
    assert capture.samples.size == 6 * 44100
    assert np.array_equal(capture.samples[:take.size], take)
    assert not capture.samples[take.size:].any()   # silence after the take
    assert capture.first_sample_time == pacer.started and capture.overflows == 0


def test_playback_microphone_outside_slides_hears_silence():
    microphone = PlaybackMicrophone(SimulatedSample("cork-board", seed=4), pacer=Pacer(0.0))
    microphone.start("press")
    microphone.pacer.wait(1.0)
    assert not microphone.stop().samples.any()
