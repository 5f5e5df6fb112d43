"""TU1 slides: the accelerometer, the microphone and the IR sensor along one path, from one excitation.

The path, the macro-profile and the micro-profile's spectrum are drawn once per slide
(:mod:`~scanner.simulation.contact`); the tip's acceleration through the contact resonance is what the
accelerometer sees (:func:`~scanner.simulation.accelerometer.unit_vibration`) and, times the tip's mass,
the force whose sound the microphone hears (:func:`~scanner.simulation.microphone.sound`). Linear filtering
happens in the frequency domain on one grid (:func:`grid_length`) padded by at least ``PAD_S``, so that
ringing never wraps around into the rest before the slide.
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy import fft

from scanner.simulation.accelerometer import (
    adxl335,
    hand_motion,
    onset_jolt,
    rolling_psd,
    tip_response,
    unit_vibration,
)
from scanner.simulation.contact import SMOOTH_STEP, excitation
from scanner.simulation.materials import Material
from scanner.simulation.microphone import sound
from scanner.simulation.reflectance import reflectance
from scanner.simulation.signals import FS_AUDIO, FS_DAQ, STEP_S, Arrays, Rng, gravity, tilt, times
from scanner.simulation.surface import (
    FINGER,
    MACRO_DX_MM,
    TOOL,
    ResampledPath,
    Tip,
    draw_motion,
    macro_profile,
    slide_path,
    surface,
)
from scanner.simulation.variability import OperatorDraw

PAD_S = 0.5
"""Zero padding of the frequency-domain grid: longer than any ringing the slide excites."""


@lru_cache(maxsize=8)
def grid_length(samples: int) -> int:
    """Samples of the audio-rate grid for ``samples`` samples of slide: at least ``PAD_S`` longer, a
    multiple of 147 so that the DAQ's 3000 Hz share the grid's frequencies (``n FS_DAQ / FS_AUDIO`` =
    ``10 n / 147`` samples), and 147 times a product of 2, 3 and 5 with :data:`SMOOTH_STEP` twice among
    its factors (the FFT's fast lengths; the last bin on the coarse grid of the smooth factors)."""
    unit = round(FS_AUDIO / FS_DAQ * 10)  # 147
    k = -(-(samples + int(PAD_S * FS_AUDIO)) // unit)
    while True:
        rest = k
        for p in (2, 3, 5):
            while rest % p == 0:
                rest //= p
        if rest == 1 and k % (2 * SMOOTH_STEP) == 0:
            return unit * k
        k += 1


def timed_spectra(timed: np.ndarray, n_fft: int) -> list[np.ndarray | None]:
    """The spectrum of each row of ``timed`` on the ``n_fft`` grid, None for a row that is all zeros (a flat
    surface, or a contact without stick-slip: nothing happens at a particular moment)."""
    return [fft.rfft(row, n_fft) if row.any() else None for row in timed]


def _slide(material: Material, rng: Rng, operator: OperatorDraw, tip: Tip, speed: float, start_s: float,
           normal_n: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Acceleration (n, 3) g at 3000 Hz, audio at 44100 Hz and IR volts at 3000 Hz of one TU1 slide."""
    motion = draw_motion(rng)
    slow = slide_path(STEP_S, FS_DAQ, start_s, speed, motion)
    fast = ResampledPath(slow, FS_DAQ, FS_AUDIO, round(STEP_S * FS_AUDIO))
    n_fft = grid_length(fast.size)
    length = fast.end_mm + 1.0
    macro = macro_profile(material.roughness, rng, int(length / MACRO_DX_MM) + 8, MACRO_DX_MM)
    exc = excitation(material, rng, tip, fast, FS_AUDIO, normal_n, surface(material, tip, macro), n_fft,
                     rolling_psd)
    response = tip_response(material, tip, n_fft)
    timed = timed_spectra(exc.timed, n_fft)
    envelope = (slow.v / exc.mean_speed) ** 2
    unit = (unit_vibration(exc, response, timed, tip, envelope, n_fft, slow.x.size) + hand_motion(rng, slow)
            + onset_jolt(rng, times(STEP_S, FS_DAQ), start_s))
    accel = unit @ tilt(*operator.tilt_deg).T + gravity(unit.shape[0], operator.tilt_deg)
    audio = sound(material, rng, tip, exc, response, timed, fast.size)
    return adxl335(accel, rng), audio, reflectance(material, rng, slow.x, macro)


def finger_slide(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU1 finger slide: ``v_fs``, ``a_fs``, ``r_fs`` (docs/operator.md#procedure step 2)."""
    v, a, r = _slide(material, rng, operator, FINGER, operator.finger_speed_mm_s, operator.finger_slide_start_s,
                     operator.finger_force_n)
    return {"v_fs": v, "a_fs": a, "r_fs": r}


def tool_slide(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU1 tool slide: ``v_ts``, ``a_ts``, ``r_ts`` (docs/operator.md#procedure step 4)."""
    v, a, r = _slide(material, rng, operator, TOOL, operator.tool_speed_mm_s, operator.tool_slide_start_s,
                     operator.tool_force_n)
    return {"v_ts": v, "a_ts": a, "r_ts": r}
