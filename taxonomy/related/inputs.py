"""What the related work's feature sets read: a recording's channels by role, checked, and a scan as a recording.

Every set reads its inputs by channel **role** (docs/database.md: ``vibration``, ``pressure_dc``, ``temperature``,
``heat_flow``, ``electrodes`` (n, k), ``taxels`` (n, h, w), ``force_xyz`` (n, 3), ``audio``), so the same
code runs on a BioTac recording, a pressure-array slide, a soft 3-axis sensor or a scan converted by
:func:`scan_recording`. A recording without a role a set needs raises :class:`RelatedFeatureError`, whose
one-line message names the set, the roles it needs and the ones missing (docs/features.md#related).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from scanner.preprocess import QualityError, band_limit, dft321, slide_signal
from scanner.scan import Recording, Scan, Trace
from taxonomy.errors import TexplorerError


class RelatedFeatureError(TexplorerError, ValueError):
    """Input a related-work feature set cannot use; the message names the set and what is wrong."""


# -- inputs ------------------------------------------------------------------------------------------

def _check_roles(recording: Recording, set_name: str, roles: Sequence[str]) -> None:
    missing = [role for role in roles if role not in recording.roles]
    if missing:
        raise RelatedFeatureError(f"{set_name} needs the role(s) {', '.join(roles)}; "
                                  f"recording {recording.name!r} lacks {', '.join(missing)}")


def _trace(recording: Recording, role: str) -> Trace:
    trace = recording.role(role)
    assert trace is not None  # _check_roles ran first
    return trace


def _signal(x: np.ndarray, name: str, min_samples: int = 1) -> np.ndarray:
    values = np.asarray(x, dtype=np.float64)
    if values.ndim != 1 or values.size < min_samples:
        raise RelatedFeatureError(f"{name} must be a 1-D signal of at least {min_samples} samples, "
                                  f"got shape {values.shape}")
    return values


def one_axis(x: np.ndarray) -> np.ndarray:
    """A vibration as one signal: 1-D as it is, several axes combined by DFT321 (docs/features.md#preprocessing).

    Parameters
    ----------
    x : array of shape (n,) or (n, axes)
        A vibration of one or several axes.

    Returns
    -------
    ndarray of shape (n,)
        ``x`` for one axis; else :func:`scanner.preprocess.dft321` of the axes, which keeps their energy
        ``sum(x^2)`` over all axes.

    Examples
    --------
    >>> import numpy as np
    >>> from taxonomy.related.inputs import one_axis
    >>> one_axis(np.array([1.0, -2.0, 3.0])).tolist()
    [1.0, -2.0, 3.0]

    Three axes of energy 9, 16 and 0 become one signal of energy 25:

    >>> combined = one_axis(np.array([[3.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 0.0], [0.0, 0.0, 0.0]]))
    >>> combined.shape, round(float(np.sum(combined**2)), 6)
    ((4,), 25.0)
    """
    values = np.asarray(x, dtype=np.float64)
    return values if values.ndim == 1 else dft321(values)


def _ratio(numerator: float, denominator: float) -> float:
    return math.nan if denominator == 0 else float(numerator / denominator)


def _log(value: float) -> float:
    """Natural logarithm, NaN (not -inf or an error) for a value that is not positive."""
    return math.log(value) if value > 0 else math.nan


SCAN_ROLES = {"vibration": "v", "audio": "a_ts", "temperature": "t_cool"}
"""Roles of a scan as a generic recording: the tool-slide signal ``v``, the tool-slide audio and the
object temperature."""


def slide_vibration(v_ts: Trace) -> Trace:
    """The tool-slide signal ``v`` (docs/features.md#preprocessing: ``v_ts`` band-limited 10-1000 Hz, 1 s window,
    DFT321).

    When the slide check fails, the band-limited DFT321 of the whole recording, so the scan still has a
    vibration (the other roles' methods would otherwise lose the whole database over one bad slide).

    Parameters
    ----------
    v_ts : Trace
        The tool-slide acceleration (n, 3) at 3000 Hz, in g.

    Returns
    -------
    Trace
        The 1-D signal at the rate and in the unit of ``v_ts``.

    Examples
    --------
    A slide starting at 0.5 s gives its 1 s window; a recording without a slide keeps all its 3 s:

    >>> import numpy as np
    >>> from scanner import Trace
    >>> from taxonomy.related.inputs import slide_vibration
    >>> v_ts = np.zeros((9000, 3))
    >>> v_ts[1500:, 0] = 0.4 * np.sin(2 * np.pi * 250.0 * np.arange(7500) / 3000.0)
    >>> slide_vibration(Trace(v_ts, 3000.0, "g")).n, slide_vibration(Trace(np.zeros((9000, 3)), 3000.0, "g")).n
    (3000, 9000)
    """
    try:
        return Trace(slide_signal(v_ts), v_ts.fs, v_ts.unit)
    except QualityError:
        return Trace(dft321(band_limit(v_ts.data, v_ts.fs)), v_ts.fs, v_ts.unit)


def scan_recording(scan: Scan) -> Recording:
    """A scan as a generic :class:`Recording`: every channel under its name plus ``v``
    (:func:`slide_vibration`), roles per :data:`SCAN_ROLES`.

    The label is the scan's taxonomy label; the groups are the sample (``object``) and the scan index
    (``trial``), so the scans of one sample count as repeated trials on one object.

    Parameters
    ----------
    scan : Scan
        Any scan.

    Returns
    -------
    Recording
        Named by the scan id, with the scan's channels, the roles found among them, label and groups.

    Examples
    --------
    >>> import numpy as np
    >>> from scanner import Scan, ScanMeta, Trace
    >>> meta = ScanMeta("C6S1M1P2X1", "ab", "granite-01", 1, "s-1", "2026-11-21T08:00:00+00:00")
    >>> v_ts = np.zeros((9000, 3))
    >>> v_ts[1500:, 0] = 0.4 * np.sin(2 * np.pi * 250.0 * np.arange(7500) / 3000.0)
    >>> from taxonomy.related.inputs import scan_recording
    >>> recording = scan_recording(Scan(meta, {"v_ts": Trace(v_ts, 3000.0, "g")}))
    >>> recording.name, sorted(recording.channels), dict(recording.roles), recording.role("vibration").n
    ('granite-01-001', ['v', 'v_ts'], {'vibration': 'v'}, 3000)
    >>> recording.label, dict(recording.group)
    ('C6S1M1P2X1', {'object': 'granite-01', 'trial': '001'})
    """
    channels = dict(scan.traces)
    if "v_ts" in channels:
        channels["v"] = slide_vibration(channels["v_ts"])
    roles = {role: channel for role, channel in SCAN_ROLES.items() if channel in channels}
    group = {"object": scan.meta.sample_id, "trial": f"{scan.meta.scan_index:03d}"}
    return Recording(scan.scan_id, channels, roles, scan.meta.label, group)
