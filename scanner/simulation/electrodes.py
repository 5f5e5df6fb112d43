"""The simulated metal electrodes of TU2 (``m``: +1 conductive, -1 not)."""

from __future__ import annotations

import numpy as np

from scanner.simulation.materials import Material
from scanner.simulation.signals import FS_DAQ, STATIC_S, Rng, times


def electrodes(material: Material, rng: Rng) -> np.ndarray:
    """Metal electrodes ``m`` during the 1 s static touch: +1 where a conductive sample pulls the electrode
    below 2.5 V, else -1; the electrodes bounce for a few ms as they settle."""
    t = times(STATIC_S, FS_DAQ)
    m = -np.ones(t.size)
    if material.conductive:
        contact = rng.uniform(0.0, 0.05)
        settled = contact + rng.uniform(0.005, 0.03)
        bouncing = (t >= contact) & (t < settled)
        m[t >= contact] = 1.0
        m[bouncing] = np.where(rng.random(int(bouncing.sum())) < 0.4, -1.0, 1.0)
    return m
