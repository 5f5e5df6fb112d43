"""What changes between scans, operators and pieces, each from a named physical source.

- **Operators** (:func:`habit_of`, seeded by the operator's name): a habitual slide speed around the
  130 mm/s average of hand-held tool exploration within its 20-240 mm/s range (Culbertson et al., as cited
  in the paper, section III-D), a habitual slide force of about 1 N, a posture (the unit's tilt); the
  finger's friction that day (skin moisture) and how they judge tack and yielding.
- **Scans** (:func:`draw_operator`): each stroke's speed and force about 20 % around the habit, the hand's
  modulation, timing, tilt, tap, press and fold forces, the camera's placement, light and exposure.
- **Pieces** (:func:`sample_of`, seeded by the sample id): the piece's size (cut from one stock: its face,
  hence its plate modes, :mod:`~scanner.simulation.microphone`), density, surface statistics (micro- and
  macro-roughness), friction, heat rise and colour, a few percent off the material's typical values.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass, replace

import numpy as np

from scanner.simulation.materials import Material, SimulationError
from scanner.simulation.signals import Rng, quantise


@dataclass(frozen=True)
class OperatorDraw:
    """What one operator does differently in one scan (docs/devices.md): speeds, forces, timing, judgement, camera.

    Speeds are in mm/s within the 20-240 mm/s range of hand-held exploration (Culbertson et al., paper
    section III-D); ``*_start_s`` is when the unit starts moving after resting still; ``finger_force_n`` and
    ``tool_force_n`` press the finger and the tool tip on the surface during the TU1 slides.
    """

    t_amb: float
    finger_speed_mm_s: float
    tool_speed_mm_s: float
    friction_speed_mm_s: float
    finger_slide_start_s: float
    tool_slide_start_s: float
    friction_start_s: float
    finger_force_n: float
    tool_force_n: float
    friction_normal_n: float
    friction_factor: float
    press_force_n: float
    press_start_s: float
    fold_force_n: float
    fold_extent: float
    tap_strength: float
    tilt_deg: tuple[float, float]
    heat_delay_s: float
    skips_rigid_fold: bool
    atk_offset: float
    cyd_offset: float
    light_gain: float
    white_balance: tuple[float, float, float]
    camera_zoom: float
    photo_rotation_deg: float


SPEED_RANGE_MM_S = (20.0, 240.0)
SPEED_MEAN_MM_S, SPEED_SPREAD_MM_S = 130.0, 40.0
"""Operators' habitual speeds scatter around the 130 mm/s average Culbertson et al. observed for hand-held
tools (paper section III-D); every speed stays within its 20-240 mm/s range."""
SLIDE_FORCE_N, SLIDE_FORCE_SPREAD = 1.0, 0.3
"""Median and log-spread between operators of the force pressing the finger or the tool tip during a TU1
slide (interpretation: a light exploratory touch of about 1 N)."""
STROKE_SPREAD = 0.2
"""Log-spread of one operator's speed and force from stroke to stroke around their habit (interpretation:
repeated strokes of one hand differ by about a fifth)."""


@dataclass(frozen=True)
class Habit:
    """How one operator tends to scan: habitual slide speed, slide force and posture (tilt of the unit)."""

    speed_mm_s: float
    force_n: float
    tilt_deg: tuple[float, float]


def habit_of(operator: str) -> Habit:
    """The habit of the operator named ``operator``, the same in every scan they make (seeded by the name)."""
    rng = np.random.default_rng(zlib.crc32(f"operator/{operator}".encode()))
    speed = float(np.clip(rng.normal(SPEED_MEAN_MM_S, SPEED_SPREAD_MM_S), *SPEED_RANGE_MM_S))
    force = float(rng.lognormal(np.log(SLIDE_FORCE_N), SLIDE_FORCE_SPREAD))
    tilt = rng.normal(0.0, 5.0, 2)
    return Habit(speed, force, (float(tilt[0]), float(tilt[1])))
SLIDE_START_RANGE_S = (0.42, 0.75)


def draw_operator(rng: Rng, *, t_amb: float | None = None, fold_skip_probability: float = 0.5,
                  operator: str = "sim") -> OperatorDraw:
    """Draw one scan's operator variability.

    Slide speeds, slide forces and the unit's tilt scatter around the habit of ``operator``
    (:func:`habit_of`) by :data:`STROKE_SPREAD` (speeds and forces) and 3 degrees (tilt), so two operators
    differ more than two scans of one.

    The judged tack and yielding are off by +-0.25 in about one scan in six; a rigid sample's fold step is
    skipped with ``fold_skip_probability``. ``friction_factor`` scales both friction coefficients for the
    operator's finger that day (skin moisture, contact angle: about +-12 %); the camera draws exposure,
    white balance, distance (zoom +-8 %) and rotation. ``t_amb`` (degC) is the session's MLX90614 ambient
    reading, drawn around 21.5 degC when not given and quantised to the sensor's 0.02 degC steps.
    """
    if not 0.0 <= fold_skip_probability <= 1.0:
        raise SimulationError(f"fold_skip_probability must be in [0, 1], got {fold_skip_probability!r}")
    ambient = rng.normal(21.5, 1.2) if t_amb is None else float(t_amb)
    habit = habit_of(operator)
    speeds = np.clip(habit.speed_mm_s * rng.lognormal(0.0, STROKE_SPREAD, size=3), *SPEED_RANGE_MM_S)
    forces = habit.force_n * rng.lognormal(0.0, STROKE_SPREAD, size=2)
    starts = rng.uniform(*SLIDE_START_RANGE_S, size=3)
    disagree = rng.random(2) < 1 / 6
    return OperatorDraw(
        t_amb=quantise(ambient, 0.02),
        finger_speed_mm_s=float(speeds[0]), tool_speed_mm_s=float(speeds[1]),
        friction_speed_mm_s=float(speeds[2]),
        finger_slide_start_s=float(starts[0]), tool_slide_start_s=float(starts[1]),
        friction_start_s=float(starts[2]),
        finger_force_n=float(forces[0]), tool_force_n=float(forces[1]),
        friction_normal_n=float(rng.uniform(3.0, 7.0)),
        friction_factor=float(rng.lognormal(0.0, 0.12)),
        press_force_n=float(rng.uniform(6.0, 15.0)),
        press_start_s=float(rng.uniform(0.3, 0.8)),
        fold_force_n=float(rng.uniform(1.0, 3.0)),
        fold_extent=float(rng.uniform(0.7, 1.1)),
        tap_strength=float(rng.uniform(0.6, 1.4)),
        tilt_deg=(habit.tilt_deg[0] + float(rng.normal(0.0, 3.0)), habit.tilt_deg[1] + float(rng.normal(0.0, 3.0))),
        heat_delay_s=float(rng.uniform(0.6, 1.4)),
        skips_rigid_fold=bool(rng.random() < fold_skip_probability),
        atk_offset=float(disagree[0] * rng.choice([-0.25, 0.25])),
        cyd_offset=float(disagree[1] * rng.choice([-0.25, 0.25])),
        light_gain=float(np.clip(rng.normal(1.0, 0.1), 0.7, 1.3)),
        white_balance=tuple(float(g) for g in np.clip(rng.normal(1.0, 0.04, 3), 0.9, 1.1)),
        camera_zoom=float(rng.uniform(0.92, 1.08)),
        photo_rotation_deg=float(rng.normal(0.0, 10.0)),
    )


FACE_CM2 = 100.0
"""The face of the library's typical sample (10 cm x 10 cm): its thickness is its volume over this face."""


def plate_thickness_mm(material: Material) -> float:
    """Thickness of ``material``'s plate: the stock's for a piece, else the typical volume over a 100 cm^2 face."""
    if material.stock_thickness_mm is not None:
        return material.stock_thickness_mm
    return material.sample_volume_cm3 / FACE_CM2 * 10.0


def sample_of(material: Material, sample_id: str) -> Material:
    """The material as one physical sample: a few percent off the library's typical values.

    Deterministic in (slug, sample_id), so every scan of a sample sees the same piece: its volume (80-125 %
    of the typical sample; pieces are cut from one stock, so the face varies and the thickness does not),
    density (+-1 %, at most 2 %), roughness and friction (+-5 %), heat rise (+-5 %) and colour.
    """
    rng = np.random.default_rng(zlib.crc32(f"{material.slug}/{sample_id}".encode()))
    scale = rng.normal(1.0, 0.05, size=5)
    rough, fric, thermal, look = material.roughness, material.friction, material.thermal, material.appearance
    tint = np.clip(rng.normal(1.0, 0.03, size=3), 0.85, 1.15)
    colors = tuple(tuple(float(min(255.0, c * t)) for c, t in zip(color, tint, strict=True))
                   for color in look.colors)
    return replace(
        material,
        density_g_cm3=material.density_g_cm3 * float(np.clip(rng.normal(1.0, 0.01), 0.98, 1.02)),
        sample_volume_cm3=material.sample_volume_cm3 * float(rng.uniform(0.8, 1.25)),
        stock_thickness_mm=plate_thickness_mm(material),
        roughness=replace(rough, micro_um=rough.micro_um * scale[0],
                          macro_height_um=rough.macro_height_um * min(scale[1], 1.1)),
        friction=replace(fric, static=fric.static * scale[2], kinetic=fric.kinetic * min(scale[2], scale[3])),
        thermal=replace(thermal, heat_rise_k=thermal.heat_rise_k * scale[4]),
        appearance=replace(look, colors=colors),
    )
