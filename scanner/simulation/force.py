"""The simulated FSR400 force sensors of TU2, read in newtons through paper eq. (1): the friction slide and the
press."""

from __future__ import annotations

import numpy as np

from scanner.calibration import fsr_newtons, fsr_volts
from scanner.simulation.materials import Friction, Material
from scanner.simulation.signals import (
    DAQ_LSB_V,
    FS_DAQ,
    STEP_S,
    Arrays,
    Rng,
    band_noise,
    envelope,
    quantise,
    smoothstep,
    times,
)
from scanner.simulation.surface import MACRO_DX_MM, Tip, lookup, macro_profile, tip_path
from scanner.simulation.variability import OperatorDraw

INDENTATION_MM = 4.0
"""The TU2 casing stops the hemisphere at this indentation (paper Fig. 12)."""
FSR_MAX_V = 4.9
def fsr(force_n: np.ndarray, rng: Rng) -> np.ndarray:
    """An FSR400 reading in N: the force through its volts and back with paper eq. (1).

    Eq. (1) maps 0 V to 0.098 N, so forces below that read as 0.098 N: the FSR's turn-on floor.
    """
    volts = fsr_volts(force_n)
    volts = np.clip(volts + rng.normal(0.0, 0.002, volts.shape), 0.0, FSR_MAX_V)
    return fsr_newtons(quantise(volts, DAQ_LSB_V))

FINGER_CONTACT = Tip("finger-fsr", radius_mm=6.0, min_contact_mm=1.0, frequency_hz=180.0, damping=0.25,
                     gain=0.0, tap_g=0.0, mass_g=3.0, modulus_mpa=3500.0)
"""The TU2 friction contact (finger on the FSR with a PLA hemisphere): only its geometry matters."""

def friction_slide(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU2 friction slide: normal ``f_frn`` and tangential ``f_frt`` in N (docs/operator.md#procedure step 6, paper
    Fig. 11).

    The unit rests, the operator presses (normal force rising to ``friction_normal_n``), then pushes: the
    tangential force follows the push until it reaches ``mu_s f_n`` (stiction), drops to ``mu_k f_n`` within
    ~20 ms and slides with fluctuations from the macro profile (the slope under the finger) and micro
    stick-slip, until both forces are released well before the end. The operator's finger adds a constant
    offset on the tangential FSR (removed by docs/features.md#preprocessing's friction offset).
    """
    fric, t = _finger_friction(material.friction, operator), times(STEP_S, FS_DAQ)
    on, off, press_time = operator.friction_start_s, rng.uniform(3.6, 4.3), rng.uniform(0.25, 0.5)
    normal = operator.friction_normal_n * envelope(t, on, press_time, off, rng.uniform(0.15, 0.3))
    normal *= 1 + 0.03 * band_noise(rng, t.size, FS_DAQ, 0.5, 6.0)
    push_at = on + press_time * rng.uniform(0.6, 1.0)
    push_time = rng.uniform(0.15, 0.35)
    push = fric.static * operator.friction_normal_n * 1.3 * smoothstep((t - push_at) / push_time)
    slipping = np.cumsum((push >= fric.static * normal) & (t > push_at)) > 0
    if not slipping.any():
        slipping[int(off * FS_DAQ)] = True
        slipping = np.cumsum(slipping) > 0
    slip_at = int(np.argmax(slipping))
    kinetic = fric.kinetic * normal * (1 + _sliding_fluctuation(material, rng, operator, t, slip_at))
    since = np.maximum(t - t[slip_at], 0.0)
    drop = np.exp(-since / 0.02)
    tangential = np.where(slipping, kinetic + (fric.static - fric.kinetic) * normal * drop, push)
    offset = rng.uniform(0.05, 0.3)
    return {"f_frn": fsr(normal, rng), "f_frt": fsr(np.maximum(tangential, 0.0) + offset, rng)}


def _finger_friction(friction: Friction, operator: OperatorDraw) -> Friction:
    return Friction(friction.static * operator.friction_factor, friction.kinetic * operator.friction_factor)


def _sliding_fluctuation(material: Material, rng: Rng, operator: OperatorDraw,
                         t: np.ndarray, slip_at: int) -> np.ndarray:
    """Relative tangential-force fluctuation while sliding: macro slope under the finger plus stick-slip."""
    speed = operator.friction_speed_mm_s * (t >= t[slip_at])
    x = np.concatenate(([0.0], np.cumsum(speed[1:]) / FS_DAQ))
    macro = macro_profile(material.roughness, rng, int(x[-1] / MACRO_DX_MM) + 8, MACRO_DX_MM)
    ridge = np.gradient(tip_path(macro, MACRO_DX_MM, FINGER_CONTACT.radius_mm), MACRO_DX_MM)
    stick_slip = min(0.15, 0.03 * np.sqrt(1 + material.roughness.micro_um / 10)) * band_noise(
        rng, t.size, FS_DAQ, 5.0, 150.0)
    relative = np.clip(0.8 * lookup(ridge, x / MACRO_DX_MM) + stick_slip, -0.9, 2.0)
    return np.where(t >= t[slip_at], relative, 0.0)


def press(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU2 press: ``f_press`` in N with the indentation fixed at 4.0 mm by the casing (docs/operator.md#procedure step
    7).

    A deformable sample reaches the stop and reads ``k * 4.0 mm``, then relaxes by ``relaxation`` with time
    constant ``relaxation_time_s`` while held to the end. A sample stiffer than the operator's force can
    indent 4 mm reads the operator's force (slow tremor, no relaxation).
    """
    comp, t = material.compliance, times(STEP_S, FS_DAQ)
    reach = comp.stiffness_n_per_mm * INDENTATION_MM
    rise = rng.uniform(0.3, 0.6)
    peak_at = operator.press_start_s + rise
    if reach < operator.press_force_n:
        held = np.maximum(t - peak_at, 0.0)
        relax = 1.0 - comp.relaxation * (1.0 - np.exp(-held / comp.relaxation_time_s))
        force = reach * smoothstep((t - operator.press_start_s) / rise) * relax
    else:
        tremor = 1 + 0.03 * band_noise(rng, t.size, FS_DAQ, 0.5, 6.0)
        force = operator.press_force_n * smoothstep((t - operator.press_start_s) / rise) * tremor
    return {"f_press": fsr(force, rng)}
