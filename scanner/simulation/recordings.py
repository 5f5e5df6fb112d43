"""Simulated recordings of the related methods' sensors (docs/ingest.md; docs/features.md#related).

So the related methods run, and can be compared, without anybody's data, each seed paper's sensor has a
simulated twin producing :class:`scanner.Recording` objects with channel roles, a label, group ids and
coarser class levels. Recordings are deterministic per seed: every recording draws from its own generator
seeded by (seed, kind, object, trial, motion), so one recording does not depend on how many others are made.

=============  ===============================================================================================
kind           sensor and protocol
=============  ===============================================================================================
``biotac``     BioTac-like finger (Hoelscher et al. 2015; Huang and Wu 2021): PAC vibration at 2200 Hz
               delivered as 22 samples per 100 Hz row, PDC pressure, TDC temperature, TAC heat flow, 19
               electrodes at 100 Hz; objects of eight material classes, five motions per trial (15 s static
               contact, four 4 s slides at 2.5 cm/s). Label: the object; level ``material``: its class.
``array``      44 x 44 pressure array (Tekscan 5101, Xie et al. 2019) dragged 1 s at 2.5 mm/s under 200 g, 100 Hz,
               intensities 0..255; Xie's 12 materials. Label: the material; level ``property``:
               soft/rigid x rough/smooth.
``soft3axis``  soft 3-axis magnetic tactile sensor at 1 kHz with a 3-axis force sensor (Chathuranga et al.
               2015); three 1 s palpations per trial at 10-20 mm/s and 0.1-0.2 N. Label: the material.
=============  ===============================================================================================

The models are simple physics with the structure the methods rely on (texture vibration at speed / spatial
period, contact area growing with compliance, heat flow growing with thermal effusivity, friction tilting
the force), objects of one class differing by a few tens of percent, and trial-to-trial variation of force,
position and speed, so the methods classify well above chance but not perfectly.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np
from scipy import ndimage

from scanner.scan import Recording, Trace
from scanner.simulation.materials import SimulationError

KINDS = ("biotac", "array", "soft3axis")
"""Simulated sensors, as named in ``sim:<kind>`` datasets."""

_KIND_ID = {kind: index + 1 for index, kind in enumerate(KINDS)}


def _rng(seed: int, kind: str, *keys: int) -> np.random.Generator:
    return np.random.default_rng([int(seed), _KIND_ID[kind], *(int(k) for k in keys)])


def shaped_noise(rng: np.random.Generator, n: int, fs: float, centre: float, width: float) -> np.ndarray:
    """Unit-RMS Gaussian noise whose spectrum is a Gaussian bump at ``centre`` Hz of std ``width`` Hz."""
    spectrum = np.fft.rfft(rng.standard_normal(n))
    frequency = np.fft.rfftfreq(n, 1.0 / fs)
    spectrum *= np.exp(-0.5 * ((frequency - centre) / width) ** 2)
    noise = np.fft.irfft(spectrum, n)
    rms = float(np.sqrt(np.mean(noise**2)))
    return noise / rms if rms > 0 else noise


def _jitter(rng: np.random.Generator, value: float, relative: float) -> float:
    """``value`` times a log-normal factor of ``relative`` spread (positive values stay positive)."""
    return float(value * np.exp(relative * rng.standard_normal()))


# -- biotac --------------------------------------------------------------------------------------------

PAC_FS = 2200.0
ROW_FS = 100.0
PAC_PER_ROW = 22
"""The BioTac delivers 22 PAC samples with every 100 Hz row of the other channels (2200 Hz)."""

ELECTRODES = 19
SLIDE_SPEED_MM_S = 25.0
BIOTAC_MOTIONS = MappingProxyType({"static": 15.0, "slide_backward": 4.0, "slide_left": 4.0,
                                   "slide_forward": 4.0, "slide_right": 4.0})
"""The five motions of Hoelscher et al. 2015 and their durations in s: 15 s static contact, 10 cm slides at 2.5 cm/s."""


@dataclass(frozen=True)
class BiotacMaterial:
    """Class-level properties: stiffness 0..1, PAC roughness (bits RMS), texture period (mm), friction,
    thermal effusivity relative to metal, and anisotropy of the texture between slide directions."""

    stiffness: float
    roughness: float
    period_mm: float
    friction: float
    effusivity: float
    anisotropy: float = 0.0


BIOTAC_CLASSES: Mapping[str, BiotacMaterial] = MappingProxyType({
    "wood": BiotacMaterial(0.80, 14.0, 0.60, 0.45, 0.30, 0.35),
    "ceramic": BiotacMaterial(0.95, 5.0, 0.30, 0.35, 0.50),
    "stone": BiotacMaterial(1.00, 22.0, 0.22, 0.50, 0.60),
    "plastic": BiotacMaterial(0.70, 4.0, 1.00, 0.40, 0.22),
    "sponge": BiotacMaterial(0.10, 18.0, 1.50, 0.70, 0.05),
    "paper": BiotacMaterial(0.50, 10.0, 0.40, 0.45, 0.14),
    "metal": BiotacMaterial(0.98, 4.0, 0.50, 0.30, 1.00),
    "fabric": BiotacMaterial(0.30, 20.0, 0.80, 0.60, 0.11, 0.30),
})
"""The eight material classes of Hoelscher et al. 2015 (Fig. 3)."""


@dataclass(frozen=True)
class _Finger:
    """Per-sensor constants shared by every recording of one simulated finger."""

    baseline: np.ndarray
    press_pattern: np.ndarray
    shear: Mapping[str, np.ndarray]


def _finger(seed: int) -> _Finger:
    rng = _rng(seed, "biotac", 0)
    baseline = 2800.0 + 200.0 * rng.random(ELECTRODES)
    press = 0.2 + 0.8 * rng.random(ELECTRODES)
    shear = {motion: rng.standard_normal(ELECTRODES) for motion in BIOTAC_MOTIONS if motion != "static"}
    return _Finger(baseline, press, shear)


def _object(material: BiotacMaterial, rng: np.random.Generator) -> tuple[BiotacMaterial, np.ndarray]:
    """One object of a class: every property varied by ~15-20 % (objects of a class are alike, not equal),
    and its local shape: a log factor per electrode on how strongly the contact presses it."""
    properties = BiotacMaterial(float(np.clip(material.stiffness + 0.06 * rng.standard_normal(), 0.02, 1.0)),
                                _jitter(rng, material.roughness, 0.2), _jitter(rng, material.period_mm, 0.2),
                                _jitter(rng, material.friction, 0.15),
                                _jitter(rng, material.effusivity, 0.12),
                                material.anisotropy)
    return properties, 0.15 * rng.standard_normal(ELECTRODES)


def _contact(t: np.ndarray, ramp: float) -> np.ndarray:
    """0 -> 1 over ``ramp`` seconds (the finger settling on the surface), then 1."""
    return np.clip(t / ramp, 0.0, 1.0) if ramp > 0 else np.ones_like(t)


def _thermal(obj: BiotacMaterial, t: np.ndarray, static: bool,
             rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray]:
    """TDC and TAC in bits: the warm core cools into the object, faster and deeper for high effusivity.

    Sliding keeps meeting fresh surface, so the drop is smaller and reaches its level sooner.
    """
    # Contact quality and the object's own temperature vary from trial to trial.
    drop = _jitter(rng, 6.0 * obj.effusivity / (obj.effusivity + 0.3) * (1.0 if static else 0.5), 0.1)
    tau = _jitter(rng, 3.0 / (0.5 + obj.effusivity) * (1.0 if static else 0.4), 0.1)
    decay = np.exp(-t / tau)
    start = 2600.0 + 10.0 * rng.standard_normal()
    tdc = start - 40.0 * drop * (1.0 - decay) + 0.5 * rng.standard_normal(t.size)
    # The AC-coupled heat flow: the initial rate of cooling, plus the steady flow a conductor keeps drawing.
    steady = 25.0 * obj.effusivity + 4.0 * rng.standard_normal()
    tac = 2000.0 + 150.0 * drop / tau * decay + steady + 1.5 * rng.standard_normal(t.size)
    return tdc, tac


def _pac(obj: BiotacMaterial, motion: str, seconds: float, force: float,
         rng: np.random.Generator) -> np.ndarray:
    """PAC at 2200 Hz: texture vibration at speed / period while sliding, contact transient when static."""
    n = int(round(seconds * PAC_FS))
    noise = 2.0 * rng.standard_normal(n)
    if motion == "static":
        t = np.arange(n) / PAC_FS
        ring = 30.0 * obj.stiffness * np.exp(-t / 0.05) * np.sin(2 * np.pi * (60 + 200 * obj.stiffness) * t)
        return 2048.0 + ring + noise
    period = obj.period_mm * (1.0 + obj.anisotropy * (motion in ("slide_left", "slide_right")))
    centre = SLIDE_SPEED_MM_S / period
    texture = (shaped_noise(rng, n, PAC_FS, centre, 0.2 * centre)
               + 0.35 * shaped_noise(rng, n, PAC_FS, 2 * centre, 0.4 * centre))
    amplitude = _jitter(rng, obj.roughness * (0.8 + 0.2 * force), 0.15)
    slips = (rng.random(n) < 0.004 * max(obj.friction - 0.4, 0.0)) * 40.0 * rng.standard_normal(n)
    return 2048.0 + amplitude * texture + np.convolve(slips, np.exp(-np.arange(40) / 8.0))[:n] + noise


def _electrodes(obj: BiotacMaterial, shape: np.ndarray, finger: _Finger, motion: str, force: np.ndarray,
                rng: np.random.Generator) -> np.ndarray:
    """Electrode impedances fall where the skin is compressed; a rigid object concentrates the pattern,
    a soft one spreads it, the object's shape and the trial's contact spot reshape it; sliding adds a
    shear pattern proportional to friction."""
    spot = 0.15 * rng.standard_normal(shape.size)
    pattern = finger.press_pattern ** (1.0 + 2.0 * obj.stiffness) * np.exp(shape + spot)
    deformation = np.outer(force, 300.0 * pattern)
    if motion != "static":
        ripple = 1.0 + 0.05 * obj.roughness / 20.0 * rng.standard_normal(force.size)
        deformation += np.outer(force * ripple, 60.0 * obj.friction * finger.shear[motion])
    return finger.baseline - deformation + 4.0 * rng.standard_normal(deformation.shape)


def biotac_recording(obj: BiotacMaterial, shape: np.ndarray, finger: _Finger, motion: str,
                     rng: np.random.Generator, name: str, label: str, group: Mapping[str, str],
                     material: str) -> Recording:
    """One motion of one trial: all BioTac channels with their roles."""
    seconds = BIOTAC_MOTIONS[motion]
    t = np.arange(int(round(seconds * ROW_FS))) / ROW_FS
    static = motion == "static"
    force = _jitter(rng, 0.6 + 0.8 * obj.stiffness, 0.04) * _contact(t, 0.3 if static else 0.0)
    pdc = 1800.0 + 400.0 * force + 2.0 * rng.standard_normal(t.size)
    if not static:
        pdc += 0.3 * obj.roughness * ndimage.gaussian_filter1d(rng.standard_normal(t.size), 3.0)
    tdc, tac = _thermal(obj, t, static, rng)
    channels = {
        "pac": Trace(_pac(obj, motion, seconds, float(force[-1]), rng), PAC_FS, "bit"),
        "pdc": Trace(pdc, ROW_FS, "bit"),
        "tdc": Trace(tdc, ROW_FS, "bit"),
        "tac": Trace(tac, ROW_FS, "bit"),
        "electrodes": Trace(_electrodes(obj, shape, finger, motion, force, rng), ROW_FS, "bit"),
    }
    roles = {"vibration": "pac", "pressure_dc": "pdc", "temperature": "tdc", "heat_flow": "tac",
             "electrodes": "electrodes"}
    meta = {"levels": {"material": material}, "label_level": "object", "sensor": "biotac"}
    return Recording(name, channels, roles, label, group, meta)


def biotac_recordings(seed: int = 0, classes: Sequence[str] | None = None, objects: int = 3,
                      trials: int = 6, motions: Sequence[str] | None = None) -> list[Recording]:
    """Simulated BioTac recordings: ``objects`` objects per material class, ``trials`` x every motion.

    Names ``<class>-<object>-t<trial>-<motion>``; label the object (``wood-2``); groups ``object``,
    ``trial``, ``motion``; ``meta["levels"]["material"]`` the class.
    """
    classes = list(BIOTAC_CLASSES) if classes is None else list(classes)
    motions = list(BIOTAC_MOTIONS) if motions is None else list(motions)
    _check_names(classes, BIOTAC_CLASSES, "material class")
    _check_names(motions, BIOTAC_MOTIONS, "motion")
    _check_counts(objects=objects, trials=trials)
    finger = _finger(seed)
    out = []
    for material in classes:
        c = list(BIOTAC_CLASSES).index(material)
        for o in range(objects):
            out += _biotac_object(seed, finger, material, c, o, trials, motions)
    return out


def _biotac_object(seed: int, finger: _Finger, material: str, c: int, o: int, trials: int,
                   motions: Sequence[str]) -> list[Recording]:
    """Every trial and motion of object ``o`` of class ``material`` (class index ``c``)."""
    obj, shape = _object(BIOTAC_CLASSES[material], _rng(seed, "biotac", 1, c, o))
    label = f"{material}-{o + 1}"
    out = []
    for trial in range(trials):
        for motion in motions:
            rng = _rng(seed, "biotac", 2, c, o, trial, list(BIOTAC_MOTIONS).index(motion))
            group = {"object": label, "trial": f"{trial + 1:02d}", "motion": motion}
            out.append(biotac_recording(obj, shape, finger, motion, rng, f"{label}-t{trial + 1:02d}-{motion}",
                                        label, group, material))
    return out


def biotac_rows(recording: Recording) -> tuple[list[str], np.ndarray]:
    """A BioTac recording as the sensor delivers it: one 100 Hz row with 22 PAC samples (``pac_01`` ..).

    Columns ``time`` (s), ``pdc``, ``pac_01`` .. ``pac_22``, ``tdc``, ``tac``, ``e01`` .. ``e19``; useful to
    write CSV files in that layout (e.g. to try ``texplorer ingest``).
    """
    c = recording.channels
    rows = c["pdc"].n
    pac = c["pac"].data[:rows * PAC_PER_ROW].reshape(rows, PAC_PER_ROW)
    columns = ["time", "pdc", *(f"pac_{i + 1:02d}" for i in range(PAC_PER_ROW)), "tdc", "tac",
               *(f"e{i + 1:02d}" for i in range(c["electrodes"].data.shape[1]))]
    table = np.column_stack([np.arange(rows) / ROW_FS, c["pdc"].data, pac, c["tdc"].data, c["tac"].data,
                             c["electrodes"].data])
    return columns, table


# -- array (Xie) ---------------------------------------------------------------------------------------

ARRAY_SIDE = 44
ARRAY_FS = 100.0
ARRAY_SECONDS = 1.0
ARRAY_SPEED_TAXELS_S = 1.0
"""2.5 mm/s over taxels 2.5 mm apart."""


@dataclass(frozen=True)
class ArrayMaterial:
    """Compliance 0..1, asperity roughness, asperity correlation length (taxels), stick-slip (or adhesion)
    frequency in Hz and relative amplitude, and the property category of Xie et al.'s Table 1."""

    compliance: float
    roughness: float
    correlation: float
    slip_hz: float
    slip: float
    category: str


XIE_MATERIALS: Mapping[str, ArrayMaterial] = MappingProxyType({
    "FSR": ArrayMaterial(0.80, 0.45, 3.0, 6.0, 0.04, "soft-rough"),
    "sponge": ArrayMaterial(0.95, 0.55, 4.0, 4.0, 0.05, "soft-rough"),
    "cotton": ArrayMaterial(0.88, 0.65, 1.8, 9.0, 0.06, "soft-rough"),
    "PVC": ArrayMaterial(0.55, 0.10, 2.0, 2.5, 0.16, "soft-smooth"),
    "SR": ArrayMaterial(0.68, 0.08, 2.5, 3.5, 0.20, "soft-smooth"),
    "rubber": ArrayMaterial(0.50, 0.12, 2.0, 2.0, 0.13, "soft-smooth"),
    "sandpaper": ArrayMaterial(0.08, 0.85, 1.0, 18.0, 0.07, "rigid-rough"),
    "wood": ArrayMaterial(0.15, 0.50, 2.5, 11.0, 0.05, "rigid-rough"),
    "iron": ArrayMaterial(0.05, 0.60, 1.5, 14.0, 0.06, "rigid-rough"),
    "ceramics": ArrayMaterial(0.02, 0.05, 3.0, 20.0, 0.015, "rigid-smooth"),
    "copper": ArrayMaterial(0.03, 0.08, 3.0, 16.0, 0.02, "rigid-smooth"),
    "acrylic": ArrayMaterial(0.08, 0.06, 3.0, 12.0, 0.025, "rigid-smooth"),
})
"""Xie et al.'s 12 test materials (Fig. 2c, Table 1)."""


def _asperities(rng: np.random.Generator, material: ArrayMaterial, width: int) -> np.ndarray:
    """Texture factor >= 0 over (44, width) taxels: 1 + roughness x correlated unit noise."""
    field = ndimage.gaussian_filter(rng.standard_normal((ARRAY_SIDE, width)), material.correlation)
    field /= max(float(field.std()), 1e-12)
    return np.clip(1.0 + material.roughness * field, 0.0, None)


def pressure_frames(material: ArrayMaterial, rng: np.random.Generator) -> np.ndarray:
    """(100, 44, 44) intensities 0..255 of a 1 s drag under a 200 g load.

    The contact patch grows with compliance (a soft sample conforms); a rigid rough sample carries the load
    on its asperities; the patch's texture shifts by one taxel over the second; stick-slip (or adhesion of
    soft smooth samples, slow and large) modulates the pressure; the sensor reads 0 below 3 counts.
    """
    n = int(round(ARRAY_SECONDS * ARRAY_FS))
    t = np.arange(n) / ARRAY_FS
    radius = _jitter(rng, 7.0 + 9.0 * material.compliance, 0.05)
    centre = 21.5 + rng.normal(0.0, 1.5, 2)
    rows, cols = np.mgrid[0:ARRAY_SIDE, 0:ARRAY_SIDE]
    r2 = ((rows - centre[0]) ** 2 + (cols - centre[1]) ** 2) / radius**2
    patch = np.clip(1.0 - r2, 0.0, None) ** (0.5 + material.compliance)
    texture = _asperities(rng, material, ARRAY_SIDE + 2) ** (1.0 + 2.0 * (1.0 - material.compliance))
    shift = ARRAY_SPEED_TAXELS_S * t
    base = np.floor(shift).astype(int)
    frac = (shift - base)[:, None, None]
    columns = base[:, None] + np.arange(ARRAY_SIDE)
    moving = ((1 - frac) * texture[:, columns].transpose(1, 0, 2)
              + frac * texture[:, columns + 1].transpose(1, 0, 2))
    pressure = patch[None] * moving
    pressure *= _jitter(rng, 1.0, 0.05) * 8000.0 / max(float(pressure[0].sum()), 1e-9)
    slip_hz = _jitter(rng, material.slip_hz, 0.1)
    slip = 1.0 + material.slip * np.sin(2 * np.pi * slip_hz * t + rng.uniform(0, 6.3))
    slip += 0.01 * rng.standard_normal(n)
    counts = 255.0 * (pressure * slip[:, None, None] / 255.0) ** 0.85 + rng.normal(0.0, 0.8, pressure.shape)
    counts = np.clip(np.rint(counts), 0.0, 255.0)
    return np.where(counts < 3.0, 0.0, counts)


def array_recordings(seed: int = 0, materials: Sequence[str] | None = None,
                     trials: int = 10) -> list[Recording]:
    """Simulated 44 x 44 pressure-array slides: ``trials`` per material (each at a new surface spot).

    Label the material; ``meta["levels"]["property"]`` its category; groups ``object`` (the material's
    sample) and ``trial``.
    """
    materials = list(XIE_MATERIALS) if materials is None else list(materials)
    _check_names(materials, XIE_MATERIALS, "material")
    _check_counts(trials=trials)
    out = []
    for m, name in enumerate(materials):
        material = XIE_MATERIALS[name]
        for trial in range(trials):
            frames = pressure_frames(material, _rng(seed, "array", m, trial))
            group = {"object": name, "trial": f"{trial + 1:03d}"}
            out.append(Recording(f"{name}-t{trial + 1:03d}", {"taxels": Trace(frames, ARRAY_FS, "count")},
                                 {"taxels": "taxels"}, name, group,
                                 {"levels": {"property": material.category}, "label_level": "material",
                                  "sensor": "tekscan-5101"}))
    return out


# -- soft 3-axis sensor (Chathuranga) ------------------------------------------------------------------

SOFT_FS = 1000.0
PALPATION_SECONDS = 1.0


@dataclass(frozen=True)
class SoftMaterial:
    """Friction coefficient, texture spatial period in mm (0: no visible texture) and its force amplitude
    (N), micro-roughness (N RMS) and compliance 0..1 (soft surfaces make the normal force fluctuate)."""

    friction: float
    period_mm: float
    texture_n: float
    micro_n: float
    compliance: float


SOFT_MATERIALS: Mapping[str, SoftMaterial] = MappingProxyType({
    "aluminium": SoftMaterial(0.25, 0.0, 0.0, 0.004, 0.05),
    "hardboard": SoftMaterial(0.40, 0.0, 0.0, 0.008, 0.10),
    "rubber": SoftMaterial(0.85, 0.0, 0.0, 0.006, 0.60),
    "plastic": SoftMaterial(0.32, 0.0, 0.0, 0.003, 0.15),
    "denim": SoftMaterial(0.55, 0.9, 0.012, 0.006, 0.40),
    "duct_tape": SoftMaterial(0.60, 1.6, 0.008, 0.005, 0.30),
    "nylon": SoftMaterial(0.45, 0.5, 0.010, 0.005, 0.35),
    "leather": SoftMaterial(0.65, 2.5, 0.007, 0.007, 0.50),
})
"""Eight samples with and without visible texture, after Chathuranga et al.'s Fig. 3."""

_CROSSTALK = np.array([[1.00, 0.06, 0.03], [0.05, 1.00, 0.04], [0.02, 0.05, 1.00]])
"""Sensor voltage per unit displacement along x, y, z (the three linear Hall sensors are not perfectly
perpendicular)."""


def palpation(material: SoftMaterial, rng: np.random.Generator) -> tuple[np.ndarray, np.ndarray, float]:
    """One 1 s forward stroke: sensor volts (n, 3), force (n, 3) in N, and the palpation velocity (mm/s)."""
    n = int(round(PALPATION_SECONDS * SOFT_FS))
    velocity = rng.uniform(10.0, 20.0)
    load = rng.uniform(0.1, 0.2)
    sway = ndimage.gaussian_filter1d(rng.standard_normal(n), 20.0)
    normal = load * (1.0 + material.compliance * 0.08 * sway)
    tangential = _jitter(rng, material.friction, 0.12) * normal
    if material.period_mm > 0:
        # Irregular textures (leather) wander in spatial frequency.
        drift = ndimage.gaussian_filter1d(rng.standard_normal(n), 80.0)
        wander = 1.0 + 0.15 * material.period_mm / 2.5 * drift
        phase = 2 * np.pi * np.cumsum(velocity / material.period_mm * wander) / SOFT_FS + rng.uniform(0, 6.3)
        tangential = tangential + _jitter(rng, material.texture_n, 0.2) * np.sin(phase)
    tangential = tangential + material.micro_n * shaped_noise(rng, n, SOFT_FS, 120.0, 60.0)
    lateral = 0.1 * (tangential - tangential.mean()) + 0.002 * rng.standard_normal(n)
    force = np.column_stack([tangential, lateral, normal])
    displacement = force / np.array([0.05, 0.05, 0.08])  # mm: the silicone's stiffness per axis, N/mm
    volts = 2.5 + 0.4 * np.tanh(displacement @ _CROSSTALK.T / 4.0) + 0.002 * rng.standard_normal((n, 3))
    return volts, force + 0.001 * rng.standard_normal((n, 3)), float(velocity)


def soft3axis_recordings(seed: int = 0, materials: Sequence[str] | None = None, trials: int = 30,
                         palpations: int = 3) -> list[Recording]:
    """Simulated soft-sensor palpations: ``trials`` per material, each ``palpations`` strokes.

    Channels ``sensor`` (n, 3) V (role ``force_xyz``, the signal the method reads) and ``force`` (n, 3) N
    from the reference force sensor; ``meta["velocity_mm_s"]``; groups ``object``, ``trial``, ``motion``
    (``palpation_1`` ..).
    """
    materials = list(SOFT_MATERIALS) if materials is None else list(materials)
    _check_names(materials, SOFT_MATERIALS, "material")
    _check_counts(trials=trials, palpations=palpations)
    out = []
    for m, name in enumerate(materials):
        for trial in range(trials):
            for k in range(palpations):
                volts, force, velocity = palpation(SOFT_MATERIALS[name], _rng(seed, "soft3axis", m, trial, k))
                group = {"object": name, "trial": f"{trial + 1:03d}", "motion": f"palpation_{k + 1}"}
                channels = {"sensor": Trace(volts, SOFT_FS, "V"), "force": Trace(force, SOFT_FS, "N")}
                out.append(Recording(f"{name}-t{trial + 1:03d}-p{k + 1}", channels,
                                     {"force_xyz": "sensor"}, name, group,
                                     {"velocity_mm_s": velocity, "label_level": "material",
                                      "sensor": "soft-3-axis"}))
    return out


# -- dispatch ------------------------------------------------------------------------------------------

def _check_names(names: Sequence[str], known: Mapping[str, object], what: str) -> None:
    unknown = [name for name in names if name not in known]
    if unknown or not names:
        raise SimulationError(f"unknown {what}(s) {', '.join(unknown) or '(none given)'} "
                              f"(known: {', '.join(known)})")


def _check_counts(**counts: int) -> None:
    for name, count in counts.items():
        if isinstance(count, bool) or not isinstance(count, int) or count < 1:
            raise SimulationError(f"{name} must be a positive integer, got {count!r}")


def simulate_recordings(kind: str, seed: int = 0, **options: object) -> list[Recording]:
    """The simulated recordings of one sensor ``kind`` (see :data:`KINDS`); options as the kind's function.

    Examples
    --------
    >>> recordings = simulate_recordings("soft3axis", materials=["denim", "rubber"], trials=2)
    >>> len(recordings), recordings[0].label, dict(recordings[0].roles)
    (12, 'denim', {'force_xyz': 'sensor'})
    """
    makers = {"biotac": biotac_recordings, "array": array_recordings, "soft3axis": soft3axis_recordings}
    if kind not in makers:
        raise SimulationError(f"unknown simulated sensor {kind!r} (known: {', '.join(KINDS)})")
    return makers[kind](seed, **options)
