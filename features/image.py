"""Image features, 31 per photo (SPEC section 7.2), computed on the cropped photo (SPEC 6)."""

from __future__ import annotations

import numpy as np


def tamura_contrast(gray: np.ndarray) -> float:
    """Tamura contrast ``sigma / kurt^(1/4)`` with ``kurt = mu4 / sigma^4`` (Tamura et al. 1978, eq. 5).

    Population moments over all pixels; 0 for a constant image (SPEC 7.2).
    """
    values = np.asarray(gray, dtype=np.float64).ravel()
    centred = values - values.mean()
    variance = float(np.mean(centred**2))
    if variance == 0.0:
        return 0.0
    kurtosis = float(np.mean(centred**4)) / variance**2
    return float(np.sqrt(variance) / kurtosis**0.25)
