"""The simulated flex sensor of TU2 and the fold step (``f_fold`` on the FSR, ``alpha_f`` on the flex sensor)."""

from __future__ import annotations

import numpy as np

from scanner.simulation.force import fsr
from scanner.simulation.materials import Material
from scanner.simulation.signals import DAQ_LSB_V, FS_DAQ, STEP_S, Arrays, Rng, envelope, quantise, smoothstep, times
from scanner.simulation.variability import OperatorDraw

FLEX_V_PER_DEG = 0.01
def fold(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU2 fold: ``f_fold`` in N and ``alpha_f`` in deg (docs/operator.md#procedure step 8, paper Fig. 13).

    Foldable: one or two folds of ``fold_angle_deg * fold_extent``, each smooth over 0.4-1.0 s, held, then
    released (a sample that stays deformed, yielding > 0, springs back only partly); the force is the grip
    plus ``k_b alpha + c dalpha/dt``. Rigid: the operator grips and tries, the flex sensor reads only noise
    (std well below 1 deg) — or the step is skipped (returns no arrays) when ``skips_rigid_fold``.
    """
    comp, t = material.compliance, times(STEP_S, FS_DAQ)
    if not comp.foldable and operator.skips_rigid_fold:
        return {}
    start = rng.uniform(0.3, 0.8)
    grip = operator.fold_force_n * envelope(t, start, 0.3, 4.4, 0.3)
    if comp.foldable:
        angle = _fold_angle(material, rng, operator, t, start + 0.2)
        force = grip + comp.fold_stiffness_n_per_deg * angle + comp.fold_damping_n_s_per_deg * np.gradient(
            angle, 1 / FS_DAQ)
    else:
        angle = rng.uniform(0.0, 0.4) * envelope(t, start + 0.2, 0.5, 4.0, 0.5)
        force = grip * rng.uniform(2.0, 3.0)
    flex = angle + 0.15 * rng.standard_normal(t.size)
    return {"f_fold": fsr(np.maximum(force, 0.0), rng),
            "alpha_f": quantise(flex * FLEX_V_PER_DEG, DAQ_LSB_V) / FLEX_V_PER_DEG}


def _fold_angle(material: Material, rng: Rng, operator: OperatorDraw, t: np.ndarray,
                first: float) -> np.ndarray:
    """Flex angle (deg) of one or two folds; a yielding sample keeps part of the fold."""
    amplitude = material.compliance.fold_angle_deg * operator.fold_extent
    kept = 0.5 * material.yielding
    count = int(rng.integers(1, 3))
    span = (4.2 - first) / count
    angle = np.zeros(t.size)
    for k in range(count):
        on = first + k * span
        bend = rng.uniform(0.4, 1.0)
        hold = rng.uniform(0.2, max(0.25, span - 2 * bend - 0.3))
        rise = smoothstep((t - on) / bend)
        back = smoothstep((t - on - bend - hold) / bend)
        angle = np.maximum(angle, amplitude * (rise - (1 - kept) * back))
    return angle
