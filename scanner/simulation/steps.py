"""The scanning procedure (Strese et al. 2020, section III) as step functions.

``step(material, rng, operator)`` returns that step's arrays, so a simulated device can produce one step at a
time."""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

from scanner.simulation.accelerometer import finger_tap, tool_tap
from scanner.simulation.camera import photos
from scanner.simulation.electrodes import electrodes
from scanner.simulation.flex import fold
from scanner.simulation.force import friction_slide, press
from scanner.simulation.magnetometer import magnetometer
from scanner.simulation.materials import Material
from scanner.simulation.signals import Arrays, Rng
from scanner.simulation.slides import finger_slide, tool_slide
from scanner.simulation.thermometer import thermal
from scanner.simulation.tu4 import tu4
from scanner.simulation.variability import OperatorDraw

STEPS = ("finger_tap", "finger_slide", "tool_tap", "tool_slide", "static", "thermal", "friction", "press",
         "fold", "photos", "tu4")
"""Procedure steps in the order of docs/operator.md#procedure; each has a step function in :data:`STEP_FUNCTIONS`."""
def static_touch(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU2 static touch, 1 s: metal electrodes ``m`` and magnetometer ``dB`` (docs/operator.md#procedure step 5)."""
    return {"m": electrodes(material, rng), "dB": magnetometer(material, rng)}
STEP_FUNCTIONS: Mapping[str, Callable[[Material, np.random.Generator, OperatorDraw], dict[str, Any]]] = {
    "finger_tap": finger_tap, "finger_slide": finger_slide, "tool_tap": tool_tap, "tool_slide": tool_slide,
    "static": static_touch, "thermal": thermal, "friction": friction_slide, "press": press, "fold": fold,
    "photos": photos, "tu4": tu4,
}
