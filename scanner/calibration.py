"""Sensor calibrations: the scanner's raw voltages in physical units and back (Strese et al. 2020, section III-B).

Pure functions of arrays: the FSR force of the paper's eq. 1 and its inverse, the flex sensor's two-point
line, the metal electrode's sign and the ADXL335 accelerometer. The device configuration
(:mod:`scanner.acquisition.config`) applies them per channel; the simulator inverts them to make volts.
"""

from __future__ import annotations

import numpy as np

from taxonomy.errors import ParameterError

FSR_REFERENCE_N = 9.81 * 0.01
"""Paper eq. 1: the force at 0 V, the weight of the 10 g reference mass (N)."""
FSR_PER_V = 1.33
"""Paper eq. 1: the exponent per volt (1/V)."""
ACCEL_ZERO_V = 1.65
ACCEL_V_PER_G = 0.330
"""ADXL335 zero-g output and sensitivity at 3.3 V supply (Strese et al. 2020, section III-B), the defaults
of a calibration."""


def fsr_newtons(volts: np.ndarray) -> np.ndarray:
    """FSR force from its voltage, paper eq. 1: ``f = 9.81 m/s^2 * 0.01 kg * exp(1.33 V^-1 * f')``.

    Interpretation (docs/devices.md) of the garbled equation: an exponential fit of the FSR divider output, so
    0 V reads 0.0981 N (the 10 g reference mass).
    """
    return FSR_REFERENCE_N * np.exp(FSR_PER_V * np.asarray(volts, dtype=np.float64))


def fsr_volts(force_n: np.ndarray) -> np.ndarray:
    """The inverse of :func:`fsr_newtons`; forces below eq. 1's 0 V floor (0.0981 N) read 0 V."""
    force = np.asarray(force_n, dtype=np.float64)
    return np.log(np.maximum(force, FSR_REFERENCE_N) / FSR_REFERENCE_N) / FSR_PER_V


def flex_degrees(volts: np.ndarray, v0: float, deg0: float, v1: float, deg1: float) -> np.ndarray:
    """Flex sensor angle by a two-point calibration: the line through (v0, deg0) and (v1, deg1) (Strese et al.
    2020, section III-B)."""
    if v0 == v1:
        raise ParameterError(f"flex calibration needs two different voltages, got {v0} V twice")
    slope = (deg1 - deg0) / (v1 - v0)
    return deg0 + slope * (np.asarray(volts, dtype=np.float64) - v0)


def metal_sign(volts: np.ndarray, threshold: float = 2.5) -> np.ndarray:
    """Metal electrode: +1 (conductive, the electrodes are shorted) below ``threshold`` V, else -1 (Strese et
    al. 2020, section III-B)."""
    return np.where(np.asarray(volts, dtype=np.float64) < threshold, 1.0, -1.0)


def accel_g(volts: np.ndarray, zero: float = ACCEL_ZERO_V, sensitivity: float = ACCEL_V_PER_G) -> np.ndarray:
    """ADXL335 acceleration in g: ``(volts - zero) / sensitivity`` (zero-g 1.65 V, 0.330 V/g)."""
    if not sensitivity > 0:
        raise ParameterError(f"accelerometer sensitivity must be positive V/g, got {sensitivity}")
    return (np.asarray(volts, dtype=np.float64) - zero) / sensitivity
