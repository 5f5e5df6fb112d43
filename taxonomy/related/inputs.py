"""What the related work's feature sets read: a recording's channels by role, checked (a scan is read as a
recording by :func:`features.recordings.scan_recording`).

Every set reads its inputs by channel **role** (docs/database.md: ``vibration``, ``pressure_dc``, ``temperature``,
``heat_flow``, ``electrodes`` (n, k), ``taxels`` (n, h, w), ``force_xyz`` (n, 3), ``audio``), so the same
code runs on a BioTac recording, a pressure-array slide, a soft 3-axis sensor or a scan converted by
:func:`features.recordings.scan_recording`. A recording without a role a set needs raises
:class:`RelatedFeatureError`, whose one-line message names the set, the roles it needs and the ones missing
(docs/features.md#related).
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np

from scanner.preprocess import dft321
from scanner.scan import Recording, Trace
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
