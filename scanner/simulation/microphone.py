"""The simulated lavalier microphone of TU1: the sound of one slide, from the same excitation the
accelerometer sees (:mod:`~scanner.simulation.contact`).

The contact force ``F = m_tip a_tip`` (the tip's acceleration through the contact resonance, times its
effective mass) drives two radiators, and the room adds its own:

- **The sample**, a square plate of the stock's thickness ``h`` (the typical volume over a 100 cm^2 face)
  and the piece's volume (so its face varies between pieces,
  :func:`~scanner.simulation.variability.sample_of`), of bending stiffness
  ``D = E h^3 / 12 (1 - nu^2)``. Its point mobility is the infinite-plate value ``1 / (8 sqrt(D rho h))``
  plus its bending modes ``f_mn = (pi / 2) sqrt(D / rho h) (m^2 + n^2) / L^2`` (simply supported square
  plate), each damped by the material's loss factor plus the table it rests on (Cremer, Heckl and
  Petersson 2005, *Structure-Borne Sound*, ch. 5; modal sum, ch. 7). It radiates
  ``p = rho0 c sigma(f) v`` with the radiation efficiency 1 above the coincidence frequency
  ``f_c = c0^2 / (2 pi) sqrt(rho h / D)`` and ``(P c0 / pi^2 S f_c) sqrt(f / f_c)`` below it, the edge
  modes of a finite plate (Fahy and Gardonio 2007, *Sound and Structural Vibration*, section 2.8). Below
  coincidence the plate also radiates from around the driving point: the bending near field there moves a
  net volume of air, ``Q = F / (i omega m'')``, whatever the plate's size and stiffness, so the power is
  ``W = rho0 |F|^2 / (12 pi c0 m''^2)`` with ``m'' = rho h`` the plate's mass per area (Heckl's result for
  a point-driven plate: Cremer, Heckl and Petersson 2005, ch. 7; Fahy and Gardonio 2007, section 2.10).
  The microphone, ``MIC_DISTANCE_M`` from the tip, hears it spread over a hemisphere:
  ``|p| = rho0 |F| / (2 pi sqrt(6) r m'')``, in phase with the force and flat in frequency, weighted by
  ``1 - sigma`` where the plate's own radiation takes over. This term is what makes a light sheet loud
  and a heavy block quiet for the same scratch, and it is the same for every piece cut from one stock:
  the piece's size moves its modes, not its mass per area. Metals and glass ring at their modes over it,
  wood and stone plates sound dull, foams and fabrics are pushed too softly to sound.
- **The unit** (TU1's housing, which carries the clip-on microphone): its acceleration, the accelerometer's
  signal at full band, radiated as a piston of 30 mm radius, ``sigma = (ka)^2 / (1 + (ka)^2)``.
- **The room**: pink background noise of 30-34 dB SPL and a reverberation tail of ``T60`` 0.3-0.45 s,
  drawn per scan.

The lavalier's band is 10-7500 Hz (paper section III-B1b), full scale 20 Pa (120 dB SPL), 16-bit samples.
Everything linear is computed in the frequency domain on one padded grid (no wrap-around of the ringing).
"""

from __future__ import annotations

from functools import lru_cache

import numpy as np
from scipy import fft

from scanner.simulation.contact import SMOOTH_STEP, Excitation, coarse_frequencies, on_bins
from scanner.simulation.materials import Material
from scanner.simulation.signals import FS_AUDIO, Rng, complex_normals, quantise
from scanner.simulation.surface import G_MM_S2, Tip
from scanner.simulation.variability import plate_thickness_mm

RHO_C = 415.0
"""Characteristic impedance of air at 20 degC (Pa s/m)."""
RHO_AIR = 1.21
"""Density of air at 20 degC (kg/m^3)."""
MIC_DISTANCE_M = 0.05
"""Distance from the tool or finger tip to the lavalier clipped on TU1 (interpretation: a few cm)."""
C0 = 343.0
"""Speed of sound in air (m/s)."""
SUPPORT_LOSS = 0.01
"""Loss factor the table adds to every plate mode (interpretation: a sample lying loosely on a table)."""
HOUSING_RADIUS_M = 0.03
FULL_SCALE_PA = 20.0
MIC_BAND_HZ = (10.0, 7500.0)
MODE_ORDERS = 5
ROOM_DB_SPL = (30.0, 34.0)
ROOM_T60_S = (0.3, 0.45)
"""Background noise and reverberation time of one quiet laboratory room, drawn per scan within what a
room's ventilation and furnishing change in a day (interpretation)."""


def plate_mobility(material: Material, f: np.ndarray, position: float) -> np.ndarray:
    """Point mobility (m/(N s)) of the sample plate at the frequencies ``f``, driven at the relative
    cross position ``position`` (0..1) of the slide; the slide runs along the other axis, so each mode's
    shape averages to 1/2 along it."""
    comp = material.compliance
    h = plate_thickness_mm(material) * 1e-3  # m
    side = np.sqrt(material.sample_volume_cm3 * 1e-6 / h)
    e_pa, rho = comp.elastic_modulus_mpa * 1e6, material.density_g_cm3 * 1e3
    stiffness = e_pa * h**3 / (12 * (1 - 0.3**2))
    mass = rho * h
    w = 2 * np.pi * f
    mobility = np.full(f.size, 1 / (8 * np.sqrt(stiffness * mass)), dtype=complex)
    eta = comp.loss_factor + SUPPORT_LOSS
    base = np.pi / 2 * np.sqrt(stiffness / mass) / side**2
    orders = np.arange(1, MODE_ORDERS + 1)
    for m in orders:
        for n in orders:
            f_mn = base * (m * m + n * n)
            if f_mn > MIC_BAND_HZ[1]:
                continue
            w_mn = 2 * np.pi * f_mn
            shape = 4 * 0.5 * np.sin(n * np.pi * position) ** 2
            mobility += shape / (mass * side**2) * 1j * w / (w_mn**2 - w**2 + 1j * eta * w_mn * w)
    return mobility


def radiation_efficiency(material: Material, f: np.ndarray) -> np.ndarray:
    """Radiation efficiency of the sample plate: 1 above coincidence, edge modes below it."""
    comp = material.compliance
    h = plate_thickness_mm(material) * 1e-3
    side = np.sqrt(material.sample_volume_cm3 * 1e-6 / h)
    stiffness = comp.elastic_modulus_mpa * 1e6 * h**3 / (12 * (1 - 0.3**2))
    coincidence = C0**2 / (2 * np.pi) * np.sqrt(material.density_g_cm3 * 1e3 * h / stiffness)
    edge = 4 * side * C0 / (np.pi**2 * side**2 * coincidence) * np.sqrt(np.maximum(f, 1.0) / coincidence)
    return np.where(f >= coincidence, 1.0, np.minimum(edge, 1.0))


def near_field(material: Material) -> float:
    """Pressure (Pa) per newton at the microphone from the plate's bending near field around the driving
    point: ``rho0 / (2 pi sqrt(6) r m'')``, from the radiated power ``rho0 |F|^2 / (12 pi c0 m''^2)`` of a
    point-driven plate below coincidence spread over a hemisphere of radius ``MIC_DISTANCE_M``."""
    mass_per_area = material.density_g_cm3 * 1e3 * plate_thickness_mm(material) * 1e-3  # kg/m^2
    return RHO_AIR / (2 * np.pi * np.sqrt(6) * MIC_DISTANCE_M * mass_per_area)


def mic_response(f: np.ndarray) -> np.ndarray:
    """Magnitude of the lavalier's 10-7500 Hz band (second-order Butterworth edges), zero phase."""
    lo, hi = MIC_BAND_HZ
    safe = np.maximum(f, 1e-3)
    return 1 / np.sqrt((1 + (lo / safe) ** 4) * (1 + (f / hi) ** 4))


def room_spectra(rng: Rng, n: int) -> tuple[np.ndarray, np.ndarray]:
    """The room's pink background noise (its spectrum in full scale, seen through the lavalier) on the
    ``n``-sample grid, and its reverberation response ``1 + tail`` on the grid's coarse frequencies
    (:func:`~scanner.simulation.contact.coarse_frequencies`)."""
    level_pa = 2e-5 * 10 ** (rng.uniform(*ROOM_DB_SPL) / 20)
    noise = np.float32(level_pa) * _pink_amplitude(n) * complex_normals(rng, n // 2 + 1)
    t60 = rng.uniform(*ROOM_T60_S)
    length = int(min(t60, 0.45) * FS_AUDIO)
    t = np.arange(length) / FS_AUDIO
    tail = rng.standard_normal(length) * np.exp(-6.9 * t / t60) * (t > 0.003)
    tail *= 10 ** (rng.uniform(-18.0, -10.0) / 20) / np.sqrt(np.sum(tail**2))  # direct-to-reverberant
    # The coarse frequencies are every SMOOTH_STEP-th bin: the tail's transform over n / SMOOTH_STEP samples
    # (longer than the tail) is its exact spectrum there (interpolated on a grid SMOOTH_STEP does not divide).
    short = fft.rfft(tail, n // SMOOTH_STEP)
    coarse = coarse_frequencies(n, FS_AUDIO)
    if n % (2 * SMOOTH_STEP):
        short = np.interp(coarse, fft.rfftfreq(n // SMOOTH_STEP, 1.0 / FS_AUDIO), short)
    return noise, 1 + short


@lru_cache(maxsize=4)
def _pink_amplitude(n: int) -> np.ndarray:
    """Spectral amplitude (full scale per Pa rms) of pink noise of 1 Pa rms over 20-20000 Hz on the
    ``n``-sample grid, through the lavalier (:func:`~scanner.simulation.signals.noise_spectrum`'s scaling)."""
    f = _frequencies(n)
    pink = 1 / np.maximum(f, 20.0)
    pink /= np.sum(pink[(f >= 20) & (f <= 20000)] * (f[1] - f[0]))
    amplitude = (np.sqrt(pink * (n * FS_AUDIO / 4)) * mic_response(f) / FULL_SCALE_PA).astype(np.float32)
    amplitude.flags.writeable = False
    return amplitude


def sound(material: Material, rng: Rng, tip: Tip, exc: Excitation, response: np.ndarray,
          timed: list[np.ndarray | None], n_out: int) -> np.ndarray:
    """Microphone samples (full scale) of one slide.

    The excitation's stationary spectra (vertical, lateral tip acceleration in g) and the ``timed`` ones (a
    row of None: silent) are on the padded grid of ``n`` samples, ``response`` the contact resonance on its
    coarse frequencies. Every factor between the tip and the microphone (resonance, plate and housing,
    room reverberation, lavalier) is smooth in frequency: they are multiplied on the coarse frequencies and
    interpolated once per track onto the grid (the plate's narrowest modes are several coarse steps wide).
    """
    n = 2 * (exc.draws.shape[1] - 1)
    coarse = coarse_frequencies(n, FS_AUDIO)
    sigma = radiation_efficiency(material, coarse)
    mobility = plate_mobility(material, coarse, rng.uniform(0.2, 0.8))
    radiated = RHO_C * sigma * mobility + (1 - sigma) * near_field(material)  # Pa per N of contact force
    plate = tip.mass_g * 1e-3 * radiated  # Pa per m/s^2 of the tip's acceleration
    housing = _housing(n, tip.gain)
    noise, reverb = room_spectra(rng, n)
    to_fs = (G_MM_S2 * 1e-3 * rng.lognormal(0.0, 0.1) / FULL_SCALE_PA) * mic_response(coarse) * reverb * response
    vertical = (plate + housing) * to_fs  # full scale per g of the tip's vertical and lateral acceleration
    lateral = (0.3 * plate + housing) * to_fs
    pressure = np.empty((2, exc.draws.shape[1]), np.complex64)
    pressure[0] = on_bins(vertical * exc.amplitude[0], n, FS_AUDIO) * exc.draws[0]
    pressure[0] += on_bins(lateral * exc.amplitude[1], n, FS_AUDIO) * exc.draws[1]
    pressure[1] = noise
    for path, spectrum in zip((vertical, lateral), timed, strict=True):
        if spectrum is not None:
            pressure[1] += on_bins(path, n, FS_AUDIO) * spectrum
    heard = fft.irfft(pressure, n)[:, :n_out]
    audio = heard[0] * exc.envelope
    audio += heard[1]
    np.clip(audio, -1.0, 1.0 - 2.0**-15, out=audio)
    return quantise(audio, 2.0**-15)


@lru_cache(maxsize=4)
def _frequencies(n: int) -> np.ndarray:
    f = fft.rfftfreq(n, 1.0 / FS_AUDIO)
    f.flags.writeable = False
    return f


@lru_cache(maxsize=8)
def _housing(n: int, gain: float) -> np.ndarray:
    """Pressure (Pa) per m/s^2 of the tip's acceleration radiated by TU1's housing (a piston of 30 mm), at
    the coarse frequencies of the ``n``-sample grid."""
    w = np.maximum(2 * np.pi * coarse_frequencies(n, FS_AUDIO), 1e-3)
    ka = w * (HOUSING_RADIUS_M / C0)
    response = (RHO_C * gain) * ka**2 / (1 + ka**2) / (1j * w)
    response.flags.writeable = False
    return response
