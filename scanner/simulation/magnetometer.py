"""The simulated MAG3110 magnetometer of TU2 (``dB``, 0.1 uT steps)."""

from __future__ import annotations

import numpy as np

from scanner.simulation.materials import Material
from scanner.simulation.signals import FS_MAGNET, STATIC_S, Rng, quantise, smoothstep, times


def magnetometer(material: Material, rng: Rng) -> np.ndarray:
    """MAG3110 field change ``dB`` (uT) during the 1 s static touch.

    The field change settles as the unit is placed; the sign follows ``magnet_response_ut``
    (interpretation: ferro- and paramagnetic samples raise the field magnitude at the MAG3110, diamagnetic
    ones lower it slightly; the paper's Fig. 7 caption uses the opposite sign for diamagnets, with no
    diamagnet in its database). Noise 0.1 uT, quantised to 0.1 uT.
    """
    tb = times(STATIC_S, FS_MAGNET)
    spread = 0.15 if material.magnetic == "ferro" else 0.1
    level = material.magnet_response_ut * rng.uniform(1 - spread, 1 + spread)
    placed = smoothstep((tb - rng.uniform(0.0, 0.05)) / rng.uniform(0.05, 0.2))
    db = level * placed + rng.normal(0.0, 0.1, tb.size)
    return quantise(db, 0.1)
