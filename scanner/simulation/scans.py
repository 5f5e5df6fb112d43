"""Whole simulated scans: every step of the procedure from one seed, and numbered samples and scans of many
materials (bit-identical for the same arguments)."""

from __future__ import annotations

import zlib
from collections.abc import Iterable, Iterator
from dataclasses import dataclass
from datetime import datetime, timedelta
from typing import Any

import numpy as np

from scanner.scan import CHANNELS, Scan, ScanMeta, Trace
from scanner.simulation.camera import photos
from scanner.simulation.derived import material_named
from scanner.simulation.materials import Material, SimulationError, default_library
from scanner.simulation.steps import STEP_FUNCTIONS, STEPS
from scanner.simulation.variability import OperatorDraw, draw_operator, sample_of
from scanner.version import __version__

SIMULATOR = "texplorer-sim"
_EPOCH = datetime.fromisoformat("2024-03-04T09:00:00+00:00")


def _check_image_size(image_size: tuple[int, int]) -> tuple[int, int]:
    try:
        h, w = (int(v) for v in image_size)
    except (TypeError, ValueError):
        raise SimulationError(f"image_size must be (height, width), got {image_size!r}") from None
    if h < 16 or w < 16 or (h, w) != tuple(image_size):
        raise SimulationError(f"image_size must be two integers >= 16, got {image_size!r}")
    return h, w


def synthetic_scan(material: Material | str, *, seed: int, scan_index: int = 1, sample_id: str | None = None,
                   session_id: str = "sim", operator: str = "sim", image_size: tuple[int, int] = (512, 512),
                   started: str | None = None, t_amb: float | None = None,
                   fold_skip_probability: float = 0.5) -> Scan:
    """One simulated scan of ``material``: every channel of docs/database.md at its true rate and shape, the
    three photos and the meta data.

    Bit-identical for the same arguments: the seed feeds an ``np.random.SeedSequence`` whose children drive
    the operator draw and each procedure step.

    Parameters
    ----------
    material : Material or str
        A material, a slug of the default library (``scanner/data/materials.toml``) or any full label of
        the taxonomy (:func:`~scanner.simulation.derived.material_named`).
    seed : int
        Seed of this scan.
    scan_index : int
        The scan's number within its sample.
    sample_id : str, optional
        Default ``<slug>-01``.
    session_id, operator : str
        Written into ``meta``.
    image_size : (int, int)
        Photo height and width in pixels (at least 202 for the image features after the 100 px crop).
    started : str, optional
        ISO 8601 start time (default: fixed, so the scan is reproducible).
    t_amb : float, optional
        Ambient temperature in degC (default: drawn).
    fold_skip_probability : float
        How often the fold step of a rigid sample is skipped (``meta.rigid``, no fold channels).

    Returns
    -------
    Scan

    Examples
    --------
    >>> from scanner.simulation import synthetic_scan
    >>> scan = synthetic_scan("granite-polished", seed=0, image_size=(256, 256))
    >>> str(scan.meta.label), scan["v_ts"].fs, scan["v_ts"].data.shape[1]
    ('C6S1M1P2X1', 3000.0, 3)
    """
    material = material_named(material)
    size = _check_image_size(image_size)
    sample_id = sample_id or f"{material.slug}-01"
    sample = sample_of(material, sample_id)
    children = np.random.SeedSequence(seed).spawn(1 + len(STEPS))
    draw = draw_operator(np.random.default_rng(children[0]), t_amb=t_amb,
                         fold_skip_probability=fold_skip_probability, operator=operator)
    results: dict[str, dict[str, Any]] = {}
    for step, child in zip(STEPS, children[1:], strict=True):
        rng = np.random.default_rng(child)
        results[step] = (photos(sample, rng, draw, size) if step == "photos"
                         else STEP_FUNCTIONS[step](sample, rng, draw))
    traces = {name: Trace(data, CHANNELS[name].fs, CHANNELS[name].unit)
              for step in STEPS if step not in ("photos", "tu4") for name, data in results[step].items()}
    meta = ScanMeta(
        label=material.label, operator=operator, sample_id=sample_id, scan_index=scan_index,
        session_id=session_id, started=started or _default_start(scan_index),
        t_amb=draw.t_amb, rigid=not material.compliance.foldable and draw.skips_rigid_fold,
        device={"simulator": SIMULATOR, "material": material.slug, "seed": str(seed),
                "daq": "NI USB-6002 (simulated)", "sensor_board": "TEXPLORER-SB (simulated)",
                "camera": "procedural"},
        software_version=__version__, notes=_notes(draw), **results["tu4"])
    return Scan(meta, traces, results["photos"])


def _default_start(scan_index: int) -> str:
    """A fixed, plausible start time (scans 15 min apart), so equal arguments give equal scans."""
    return (_EPOCH + timedelta(minutes=15 * (scan_index - 1))).isoformat()


def _notes(draw: OperatorDraw) -> str:
    return (f"simulated operator: finger slide {draw.finger_speed_mm_s:.0f} mm/s, tool slide "
            f"{draw.tool_speed_mm_s:.0f} mm/s, friction slide {draw.friction_speed_mm_s:.0f} mm/s")


def scan_seed(seed: int, slug: str, scan_index: int, sample: int = 1) -> int:
    """The seed of scan ``scan_index`` of sample number ``sample`` of ``slug`` in a simulated database built
    with ``seed``.

    Derived with ``np.random.SeedSequence`` from (seed, slug, scan index[, sample number]), so a single scan
    can be regenerated without the others and does not depend on which other materials were simulated. The
    first sample's key has no sample number: databases simulated before samples were numbered stay valid.
    """
    key = (zlib.crc32(slug.encode()), scan_index) + ((sample,) if sample != 1 else ())
    sequence = np.random.SeedSequence(seed, spawn_key=key)
    return int(sequence.generate_state(1, np.uint64)[0])


def sample_id_of(slug: str, sample: int) -> str:
    """Sample id of sample number ``sample`` of a simulated material: ``<slug>-01``, ``<slug>-02``, ..."""
    return f"{slug}-{sample:02d}"


@dataclass(frozen=True)
class _Job:
    """One simulated scan of a database: material, sample number, scan index and the settings."""

    slug: str
    sample: int
    index: int
    seed: int
    image_size: tuple[int, int]
    fold_skip_probability: float

    @property
    def scan_id(self) -> str:
        return f"{sample_id_of(self.slug, self.sample)}-{self.index:03d}"


def scan_jobs(materials: Iterable[str] | None, samples_per_material: int, scans_per_sample: int, seed: int,
          image_size: tuple[int, int], fold_skip_probability: float) -> list[_Job]:
    slugs = list(default_library()) if materials is None else [material_named(m).slug for m in materials]
    for name, value in (("samples_per_material", samples_per_material), ("scans_per_material", scans_per_sample)):
        if not (isinstance(value, int) and value >= 1):
            raise SimulationError(f"{name} must be an integer >= 1, got {value!r}")
    _check_image_size(image_size)
    return [_Job(slug, sample, index, seed, image_size, fold_skip_probability) for slug in slugs
            for sample in range(1, samples_per_material + 1) for index in range(1, scans_per_sample + 1)]


def simulate_one(job: _Job) -> Scan:
    return synthetic_scan(material_named(job.slug), seed=scan_seed(job.seed, job.slug, job.index, job.sample),
                          scan_index=job.index, sample_id=sample_id_of(job.slug, job.sample),
                          image_size=job.image_size, fold_skip_probability=job.fold_skip_probability)


def synthetic_scans(materials: Iterable[str] | None = None, scans_per_material: int = 5, seed: int = 0,
                    image_size: tuple[int, int] = (512, 512), fold_skip_probability: float = 0.5,
                    samples_per_material: int = 1) -> Iterator[Scan]:
    """Scans 1..n of each of ``samples_per_material`` samples (pieces) per material (sample ids
    ``<slug>-01``, ``<slug>-02``, ...), material by material; ``scans_per_material`` is n, the scans of
    each sample.

    ``materials``: slugs of the default library or full taxonomy labels, or None for the whole library.
    Scan k of sample j of material m is
    ``synthetic_scan(m, seed=scan_seed(seed, m, k, j), scan_index=k, sample_id=sample_id_of(m, j), ...)``.
    """
    return map(simulate_one, scan_jobs(materials, samples_per_material, scans_per_material, seed, image_size,
                                    fold_skip_probability))
