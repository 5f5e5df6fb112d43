"""TU1 slides: the accelerometer, the microphone and the IR sensor along one path."""

from __future__ import annotations

import numpy as np

from scanner.simulation.accelerometer import adxl335, contact_vibration, hand_motion, onset_jolt
from scanner.simulation.materials import Material
from scanner.simulation.microphone import microphone
from scanner.simulation.reflectance import reflectance
from scanner.simulation.signals import FS_AUDIO, FS_DAQ, STEP_S, Arrays, Rng, gravity, tilt, times
from scanner.simulation.surface import FINGER, MACRO_DX_MM, TOOL, Tip, draw_motion, macro_profile, slide_path, surface
from scanner.simulation.variability import OperatorDraw


def _slide(material: Material, rng: Rng, operator: OperatorDraw, tip: Tip,
           speed: float, start_s: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Acceleration (n, 3) g at 3000 Hz, audio at 44100 Hz and IR volts at 3000 Hz of one TU1 slide."""
    motion = draw_motion(rng)
    fast = slide_path(STEP_S, FS_AUDIO, start_s, speed, motion)
    slow = slide_path(STEP_S, FS_DAQ, start_s, speed, motion)
    length = float(fast.x[-1]) + 1.0
    macro = macro_profile(material.roughness, rng, int(length / MACRO_DX_MM) + 8, MACRO_DX_MM)
    normal = surface(material, rng, tip, length, fast.x.size, macro).acceleration(fast)
    lateral = surface(material, rng, tip, length, fast.x.size, macro).acceleration(fast)
    unit = (contact_vibration(material, rng, tip, fast, normal, lateral) + hand_motion(rng, slow)
            + onset_jolt(rng, times(STEP_S, FS_DAQ), start_s))
    accel = unit @ tilt(*operator.tilt_deg).T + gravity(unit.shape[0], operator.tilt_deg)
    return adxl335(accel, rng), microphone(rng, normal, fast, tip), reflectance(material, rng, slow.x, macro)

def finger_slide(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU1 finger slide: ``v_fs``, ``a_fs``, ``r_fs`` (docs/operator.md#procedure step 2)."""
    speed, start = operator.finger_speed_mm_s, operator.finger_slide_start_s
    v, a, r = _slide(material, rng, operator, FINGER, speed, start)
    return {"v_fs": v, "a_fs": a, "r_fs": r}


def tool_slide(material: Material, rng: Rng, operator: OperatorDraw) -> Arrays:
    """TU1 tool slide: ``v_ts``, ``a_ts``, ``r_ts`` (docs/operator.md#procedure step 4)."""
    v, a, r = _slide(material, rng, operator, TOOL, operator.tool_speed_mm_s, operator.tool_slide_start_s)
    return {"v_ts": v, "a_ts": a, "r_ts": r}
