"""What the simulated and replay devices observe: a simulated material sample, or a stored scan played back.

Both sources answer the same questions (:class:`SignalSource`): the DAQ volts while the operator performs a
step, the microphone's samples, the MLX90614 cooling curve after heating, the MAG3110 field change as the
unit is placed, the photos and the room's ambient temperature. The playback devices
(:mod:`scanner.acquisition.devices.daq`, ``board``, ``audio``, ``camera``) and the emulators
(:mod:`scanner.acquisition.emulators`) turn these into what each device reports, so "simulated" and "replay" differ
only in their source.

:class:`SimulatedSample` gets its physics from :mod:`scanner.simulation` (one function per procedure step).
Every time a device starts recording a step, the operator performs that step once more (a *take*): take
``k`` of a step is seeded by (seed, step, k), so a redo gives a new, still deterministic, performance, and
the DAQ and the microphone starting the same slide for the k-th time see the same take.
:class:`ReplayedScan` plays the same recording every time. Both produce volts where a real device gives volts,
through the inverse of the configured calibration (or the scan's stored raw volts).
"""

from __future__ import annotations

import math
import threading
from collections.abc import Mapping
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from scanner.acquisition.config import CHANNEL_ROLES, DAQ_ROLES, Calibration, Config, ConfigError
from scanner.scan import CHANNELS, Scan
from scanner.simulation import (
    STEP_FUNCTIONS,
    STEPS,
    Material,
    SimulationError,
    draw_operator,
    load_materials,
    material_for_label,
    photos,
    sample_of,
    scan_seed,
)
from scanner.storage.matfile import load_scan
from taxonomy.errors import ParameterError

STEP_SECONDS = 5.0
"""Length of a simulated tap, slide, friction, press or fold (docs/operator.md#procedure)."""
REST_G = (0.0, 0.0, 1.0)
"""A unit resting level reads 1 g on z."""
REST_IR_V = 0.1
"""IR reflectance volts with nothing under the sensor (ambient light)."""
ROOM_T_AMB = 21.5
"""Ambient temperature assumed when a stored scan did not record one, degC."""


class SignalSource(Protocol):
    """The physical signals the playback devices and the emulators report."""

    t_amb: float
    kind: str
    """"simulated" or "replay"."""

    def describe(self) -> str: ...

    def daq_volts(self, step: str, calibration: Calibration, device: str = "daq") -> np.ndarray: ...

    def audio(self, step: str, device: str = "microphone") -> np.ndarray: ...

    def cooling(self, device: str = "board") -> np.ndarray: ...

    def field_change(self, device: str = "board") -> np.ndarray: ...

    def photos(self, device: str = "camera") -> Mapping[str, np.ndarray]: ...


def _rest(role: str) -> float:
    if role.startswith("accel_"):
        return REST_G["xyz".index(role[-1])]
    return {"ir": REST_IR_V, "fsr_normal": 0.0, "fsr_tangential": 0.0, "flex": 0.0, "metal": -1.0}[role]


def rest_volts(n: int, calibration: Calibration) -> np.ndarray:
    """(n, 8) volts of a unit at rest: 1 g on z, ambient IR, unloaded FSRs and flex, open electrodes."""
    row = [float(calibration.to_volts(role, np.array(_rest(role)))) for role in DAQ_ROLES]
    return np.tile(row, (n, 1))


def volts_of(signals: Mapping[str, np.ndarray], calibration: Calibration,
             raw: Mapping[str, np.ndarray] | None = None, n: int | None = None) -> np.ndarray:
    """(n, 8) DAQ volts carrying the scan channels in ``signals`` (physical units) on their roles.

    A channel in ``raw`` (volts as recorded) is used as is; the others go through the inverse calibration.
    Roles no channel drives read their resting level; ``n`` defaults to the longest channel.
    """
    n = n or max((len(v) for v in signals.values()), default=int(STEP_SECONDS * CHANNELS["v_ts"].fs))
    volts = rest_volts(n, calibration)
    for name, values in signals.items():
        if name not in CHANNEL_ROLES:
            continue
        recorded = (raw or {}).get(name)
        columns = np.asarray(values, dtype=np.float64).reshape(len(values), -1)
        for k, role in enumerate(CHANNEL_ROLES[name]):
            column = DAQ_ROLES.index(role)
            if recorded is not None:
                volts[:len(values), column] = np.asarray(recorded).reshape(len(values), -1)[:, k]
            else:
                volts[:len(values), column] = calibration.to_volts(role, columns[:, k])
    return volts


class SimulatedSample:
    """A material sample under the simulated scanner, with the operator's per-scan draw.

    Parameters
    ----------
    material : Material or str
        A library material or its slug.
    sample_id : str, optional
        Which physical piece (:func:`scanner.simulation.sample_of`: a few percent off the library values);
        default ``<slug>-01``.
    seed : int
        Seeds the operator draw and every take.
    image_size : (int, int)
        Photo size (h, w).
    t_amb : float, optional
        Ambient temperature (degC); drawn around 21.5 degC when not given.
    """

    def __init__(self, material: Material | str, *, sample_id: str | None = None, seed: int = 0,
                 image_size: tuple[int, int] = (512, 512), t_amb: float | None = None) -> None:
        resolved = material if isinstance(material, Material) else material_for("", material)
        self.material = sample_of(resolved, sample_id or f"{resolved.slug}-01")
        self.seed = int(seed)
        self.image_size = (int(image_size[0]), int(image_size[1]))
        # The operator always performs the fold when asked; skipping it is the session's decision.
        self.operator = draw_operator(np.random.default_rng(np.random.SeedSequence(self.seed)), t_amb=t_amb,
                                      fold_skip_probability=0.0)
        self.t_amb = self.operator.t_amb
        self.kind = "simulated"
        self._lock = threading.Lock()
        self._counts: dict[tuple[str, str], int] = {}
        self._cache: dict[tuple[str, int], dict[str, Any]] = {}

    def describe(self) -> str:
        return f"simulated {self.material.slug} (seed {self.seed})"

    def take(self, step: str, device: str) -> dict[str, Any]:
        """The next performance of ``step`` as seen by ``device``: the step function's arrays.

        Each device counts its own takes, so the microphone and the DAQ that both record the k-th finger
        slide get the same one.
        """
        if step not in STEP_FUNCTIONS:
            raise ParameterError(f"unknown procedure step {step!r} (known: {', '.join(STEPS)})")
        with self._lock:
            index = self._counts.get((step, device), 0)
            self._counts[step, device] = index + 1
            cached = self._cache.get((step, index))
            if cached is None:
                cached = self._perform(step, index)
                self._cache[step, index] = cached
                self._cache.pop((step, index - 2), None)
            return cached

    def _perform(self, step: str, index: int) -> dict[str, Any]:
        sequence = np.random.SeedSequence(self.seed, spawn_key=(STEPS.index(step) + 1, index))
        rng = np.random.default_rng(sequence)
        if step == "photos":
            return photos(self.material, rng, self.operator, self.image_size)
        return STEP_FUNCTIONS[step](self.material, rng, self.operator)

    def daq_volts(self, step: str, calibration: Calibration, device: str = "daq") -> np.ndarray:
        """(n, 8) volts on :data:`~scanner.acquisition.config.DAQ_ROLES` while the operator performs one take of
        ``step`` (5 s, 1 s for the static touch; steps without DAQ channels give 5 s at rest)."""
        arrays = self.take(step, device) if step in STEP_FUNCTIONS else {}
        return volts_of({k: v for k, v in arrays.items() if k in CHANNEL_ROLES}, calibration)

    def audio(self, step: str, device: str = "microphone") -> np.ndarray:
        """Microphone samples (full scale) of one take of a slide; 5 s of silence for other steps."""
        arrays = self.take(step, device) if step in ("finger_slide", "tool_slide") else {}
        for name in ("a_fs", "a_ts"):
            if name in arrays:
                return np.asarray(arrays[name], dtype=np.float64)
        return np.zeros(int(STEP_SECONDS * CHANNELS["a_ts"].fs))

    def cooling(self, device: str = "board") -> np.ndarray:
        """Object temperature (degC, 20 Hz) after one heating: a take of the thermal step's ``t_cool``."""
        return np.asarray(self.take("thermal", device)["t_cool"], dtype=np.float64)

    def field_change(self, device: str = "board") -> np.ndarray:
        """Signed field-magnitude change (uT, 80 Hz) as the unit is placed: a take of the static ``dB``."""
        return np.asarray(self.take("static", device)["dB"], dtype=np.float64)

    def photos(self, device: str = "camera") -> Mapping[str, np.ndarray]:
        """The three photos of one take: ``I_disp``, ``I_macro``, ``I_illu``."""
        return self.take("photos", device)


class ReplayedScan:
    """A stored scan played back: every step gives the same recording, in volts where the DAQ gives volts
    (the scan's raw volts where kept, else through the inverse calibration)."""

    def __init__(self, scan: Scan, name: str = "") -> None:
        self.scan = scan
        self.name = name or scan.scan_id
        self.t_amb = scan.meta.t_amb if math.isfinite(scan.meta.t_amb) else ROOM_T_AMB
        self.kind = "replay"

    @classmethod
    def load(cls, path: str | Path) -> ReplayedScan:
        return cls(load_scan(path), Path(path).name)

    def describe(self) -> str:
        return f"replay of {self.name}"

    def _channels(self, step: str) -> dict[str, np.ndarray]:
        return {name: trace.data for name, trace in self.scan.traces.items()
                if CHANNELS[name].step == step and name in CHANNEL_ROLES}

    def daq_volts(self, step: str, calibration: Calibration, device: str = "daq") -> np.ndarray:
        """(n, 8) volts of the stored step; roles the scan lacks (a skipped fold) read at rest."""
        raw = {name: trace.data for name, trace in self.scan.raw.items()}
        return volts_of(self._channels(step), calibration, raw)

    def audio(self, step: str, device: str = "microphone") -> np.ndarray:
        name = {"finger_slide": "a_fs", "tool_slide": "a_ts"}.get(step)
        trace = self.scan.get(name) if name else None
        return trace.data.copy() if trace is not None else np.zeros(int(STEP_SECONDS * CHANNELS["a_ts"].fs))

    def cooling(self, device: str = "board") -> np.ndarray:
        trace = self.scan.get("t_cool")
        return trace.data.copy() if trace is not None else np.full(200, self.t_amb)

    def field_change(self, device: str = "board") -> np.ndarray:
        trace = self.scan.get("dB")
        return trace.data.copy() if trace is not None else np.zeros(80)

    def photos(self, device: str = "camera") -> Mapping[str, np.ndarray]:
        return dict(self.scan.images)


@dataclass(frozen=True)
class Specimen:
    """The sample the scanner is put on: its label, its id and the index of the scan about to be taken."""

    label: str
    sample_id: str
    scan_index: int = 1


def simulated_sample(config: Config, specimen: Specimen) -> SimulatedSample:
    """What simulated devices observe of ``specimen``, as ``config.simulated`` says: the library material
    with its label (or ``simulated.material``) as the piece ``sample_id``, seeded by ``simulated.seed``, the
    material and the scan index, so repeated scans of a sample differ like real ones."""
    material = material_for(specimen.label, config.simulated.material)
    return SimulatedSample(material, sample_id=specimen.sample_id, image_size=config.simulated.image_size,
                           seed=scan_seed(config.simulated.seed, material.slug, specimen.scan_index))


def material_for(label: str, slug: str = "") -> Material:
    """The library material named ``slug``, else the material of ``label``: hand-set in the library, or
    derived from the label's taxonomy codes (:func:`scanner.simulation.material_for_label`)."""
    library = load_materials()
    if slug:
        if slug not in library:
            raise ConfigError(f"the simulated scanner has no material {slug!r}: remove simulated.material from "
                              f"the configuration to simulate the scan's own label, or set it to one of: "
                              f"{', '.join(library)}")
        return library[slug]
    try:
        return material_for_label(label)
    except SimulationError as exc:
        raise ConfigError(str(exc)) from None
