"""Sensor calibrations (Strese et al. 2020, eq. 1; the ADXL335, flex and metal sensors): expected values
derived by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from scanner.calibration import FSR_REFERENCE_N, accel_g, flex_degrees, fsr_newtons, fsr_volts, metal_sign


def test_fsr_newtons_follows_eq_1():
    volts = np.array([0.0, math.log(2.0) / 1.33, math.log(10.0) / 1.33])
    np.testing.assert_allclose(fsr_newtons(volts), [0.0981, 0.1962, 0.981], rtol=1e-12)


def test_flex_degrees_is_the_two_point_line():
    np.testing.assert_allclose(flex_degrees(np.array([1.0, 2.0, 3.0, 4.0]), 1.0, 0.0, 3.0, 90.0),
                               [0.0, 45.0, 90.0, 135.0])
    with pytest.raises(ValueError, match="two different voltages"):
        flex_degrees(np.zeros(3), 1.0, 0.0, 1.0, 90.0)


def test_metal_sign_threshold():
    np.testing.assert_array_equal(metal_sign(np.array([0.0, 2.49, 2.5, 4.9])), [1.0, 1.0, -1.0, -1.0])


def test_accel_g_zero_and_sensitivity():
    np.testing.assert_allclose(accel_g(np.array([1.65, 1.98, 1.32])), [0.0, 1.0, -1.0], atol=1e-12)
    with pytest.raises(ValueError, match="sensitivity"):
        accel_g(np.zeros(2), sensitivity=0.0)


def test_fsr_volts_inverts_eq_1_above_its_floor():
    volts = np.array([0.0, 0.5, 1.0, 3.7])
    np.testing.assert_allclose(fsr_volts(fsr_newtons(volts)), volts, rtol=1e-12, atol=1e-15)
    assert fsr_volts(np.array([0.0, FSR_REFERENCE_N / 2])).tolist() == [0.0, 0.0]  # below 0 V's 0.0981 N
