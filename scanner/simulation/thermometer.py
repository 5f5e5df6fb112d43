"""The simulated MLX90614 thermometer of TU2: the heated spot cooling after the Peltier element (``t_cool``)."""

from __future__ import annotations

import numpy as np

from scanner.simulation.materials import Material
from scanner.simulation.signals import FS_THERMAL, Arrays, Rng, quantise, smoothstep, times
from scanner.simulation.variability import OperatorDraw

COOL_S = 10.0
def _mlx90614(temperature: np.ndarray, rng: Rng) -> np.ndarray:
    """Object temperature with 0.02 degC noise, quantised to the MLX90614's 0.02 degC steps."""
    return quantise(temperature + rng.normal(0.0, 0.02, temperature.shape), 0.02)
def thermal(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU2 thermal: ``t_cool``, 10 s at 20 Hz after heating the Peltier element for 3 s (docs/operator.md#procedure
    step 5).

    The heated spot cools as ``t_amb + dT exp(-r t)`` (paper eq. 26); ``dT`` is the library's heat rise,
    corrected for how long the operator takes to move the MLX90614 over the spot (``heat_delay_s`` against
    the nominal 1 s) and for the contact while heating. The sensor reaches the spot within the first
    0.15-0.5 s, so the maximum is not the first sample. Metals barely heat and cool fast; foams heat most.
    """
    heat = material.thermal
    t = times(COOL_S, FS_THERMAL)
    rise = heat.heat_rise_k * np.exp(-heat.cooling_rate_per_s * (operator.heat_delay_s - 1.0))
    rise *= rng.uniform(0.85, 1.15)
    arrive = smoothstep(t / rng.uniform(0.15, 0.5))
    surface = operator.t_amb + rng.normal(0.0, 0.05)
    return {"t_cool": _mlx90614(surface + arrive * rise * np.exp(-heat.cooling_rate_per_s * t), rng)}
