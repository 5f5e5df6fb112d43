"""TU4: the scale, the displacement volume and the operator's judged adhesive tack and yielding."""

from __future__ import annotations

import numpy as np

from scanner.simulation.materials import Material
from scanner.simulation.signals import Rng, quantise
from scanner.simulation.variability import OperatorDraw


def tu4(material: Material, rng: Rng, operator: OperatorDraw) -> dict[str, float]:
    """TU4: mass (scale: 0.1 g steps) and volume (displacement: read within +-3 %, 0.5 cm^3 steps), and
    the operator's judged adhesive tack and yielding (the material's typical value, off by the operator's
    occasional +-0.25, kept on the five-step scale)."""
    volume = material.sample_volume_cm3
    mass = material.density_g_cm3 * volume
    return {
        "mass_g": max(0.1, quantise(mass + rng.normal(0.0, 0.05), 0.1)),
        "volume_cm3": max(0.5, quantise(volume * rng.uniform(0.97, 1.03), 0.5)),
        "atk": float(np.clip(material.adhesive_tack + operator.atk_offset, 0.0, 1.0)),
        "cyd": float(np.clip(material.yielding + operator.cyd_offset, 0.0, 1.0)),
    }
