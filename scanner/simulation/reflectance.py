"""The simulated IR reflectance sensor of TU1: albedo texture and macro depth seen through the sensor's spot."""

from __future__ import annotations

import numpy as np
from scipy import fft, ndimage

from scanner.simulation.materials import Material
from scanner.simulation.signals import DAQ_LSB_V, Rng, bank_normals, quantise
from scanner.simulation.surface import MACRO_DX_MM, lookup

IR_SPOT_MM = 0.8
"""Standard deviation of the IR sensor's spot on the surface."""
IR_DEPTH_MM = 1.5
"""Depth below the top surface at which the reflected IR has halved."""
def _smooth_noise(rng: Rng, n: int, sigma: float) -> np.ndarray:
    """Gaussian noise smoothed by a Gaussian of ``sigma`` samples, periodic over its ``n`` samples: white
    noise's spectrum times the Gaussian's transform ``exp(-2 (pi sigma k)^2)`` (an FFT instead of a kernel of
    ``8 sigma`` taps per sample)."""
    k = fft.rfftfreq(n)
    spectrum = fft.rfft(bank_normals(rng, n).astype(np.float64)) * np.exp(-2 * (np.pi * sigma * k) ** 2)
    return fft.irfft(spectrum, n)


def reflectance(material: Material, rng: Rng, x: np.ndarray, macro: np.ndarray) -> np.ndarray:
    """IR reflectance volts along the path: albedo texture and the depth of the macro profile.

    ``V = V_amb + 4.6 g level (1 + variation n(x)) / (1 + depth / 1.5 mm)``, both seen through the sensor's
    spot, with the ambient light ``V_amb`` (0.05-0.2 V) and the emitter's gain ``g`` (+-4 %, temperature)
    varying from scan to scan; the unit rests first, so the first ~0.5 s read the static reflectance.
    """
    reflect = material.reflectance
    spot = IR_SPOT_MM / MACRO_DX_MM
    scale = max(0.5 / material.appearance.frequency_per_mm, IR_SPOT_MM) / MACRO_DX_MM
    albedo = _smooth_noise(rng, macro.size, scale)
    albedo = ndimage.gaussian_filter1d(albedo / max(float(albedo.std()), 1e-12), spot, mode="nearest")
    depth = ndimage.gaussian_filter1d(np.maximum(-macro, 0.0), spot, mode="nearest")
    level = reflect.level * np.clip(1 + reflect.variation * albedo, 0.05, None) / (1 + depth / IR_DEPTH_MM)
    ambient, gain = rng.uniform(0.05, 0.2), rng.normal(1.0, 0.04)
    volts = ambient + 4.6 * gain * lookup(level, x / MACRO_DX_MM) + rng.normal(0.0, 0.002, x.size)
    return quantise(np.clip(volts, 0.0, 5.0), DAQ_LSB_V)
