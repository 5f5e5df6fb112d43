"""``fishel3`` (Strese et al. 2020, Fig. 18, after Fishel and Loeb): traction, roughness and fineness of a
scan, the features of :mod:`taxonomy.related.fishel` (docs/features.md#related)."""

from __future__ import annotations

import math

import numpy as np

from features.tactum import frs, mico
from scanner.preprocess import QualityError, remove_friction_offset, slide_signal
from scanner.scan import Scan
from taxonomy.related.inputs import RelatedFeatureError

FISHEL_CHANNELS = ("v_ts", "f_frn", "f_frt")


def fishel3(scan: Scan) -> dict[str, float]:
    """Traction, roughness and fineness of a scan, as the paper adapts Fishel and Loeb's features (Fig. 18).

    ``traction = tactum.frs`` (sliding resistance, eq. 17), ``roughness = log10(mean(v^2))`` of the slide
    signal ``v`` (``v_ts`` band-passed 10-1000 Hz, 1 s window, DFT321; docs/features.md#preprocessing) and ``fineness =
    tactum.mico`` (its spectral centroid, eq. 15). A stored slide whose check fails gives NaN roughness
    and fineness, as for the TacTUM features.

    Parameters
    ----------
    scan : Scan
        A scan with the tool slide ``v_ts`` and the friction slide ``f_frn``, ``f_frt``.

    Returns
    -------
    dict of str to float
        ``fishel3.traction``, ``fishel3.roughness`` (log10 of g^2) and ``fishel3.fineness`` (Hz).

    Raises
    ------
    RelatedFeatureError
        If the scan lacks ``v_ts``, ``f_frn`` or ``f_frt``.

    Examples
    --------
    A tool slide of 0.4 g at 250 Hz after 0.5 s of rest, and a friction force of 1 N under a normal force
    of 2 N: the traction is 1 / 2 and the roughness ``log10(0.4^2 / 2) = log10(0.08) = -1.097``. The
    fineness lies above the tone: the band-pass spreads a little of the slide onset over all the bins.

    >>> import numpy as np
    >>> from scanner import Scan, ScanMeta, Trace
    >>> meta = ScanMeta("C6S1M1P2X1", "ab", "granite-01", 1, "s-1", "2026-11-21T08:00:00+00:00")
    >>> v_ts = np.zeros((9000, 3))
    >>> v_ts[1500:, 0] = 0.4 * np.sin(2 * np.pi * 250.0 * np.arange(7500) / 3000.0)
    >>> f_frt = np.where(np.arange(9000) >= 600, 1.0, 0.0)
    >>> scan = Scan(meta, {"v_ts": Trace(v_ts, 3000.0, "g"), "f_frn": Trace(np.full(9000, 2.0), 3000.0, "N"),
    ...                    "f_frt": Trace(f_frt, 3000.0, "N")})
    >>> from taxonomy.related.fishel_features import fishel3
    >>> values = fishel3(scan)
    >>> values["fishel3.traction"], round(values["fishel3.roughness"], 3), 250 < values["fishel3.fineness"] < 300
    (0.5, -1.097, True)
    """
    missing = [name for name in FISHEL_CHANNELS if scan.get(name) is None]
    if missing:
        raise RelatedFeatureError(f"fishel3 needs the scan channels {', '.join(FISHEL_CHANNELS)}; scan "
                                  f"{scan.scan_id} lacks {', '.join(missing)}")
    f_frn, f_frt = scan["f_frn"], scan["f_frt"]
    traction = frs(f_frn.data, remove_friction_offset(f_frt.data, f_frt.fs))
    try:
        v = slide_signal(scan["v_ts"])
    except QualityError:
        return {"fishel3.traction": traction, "fishel3.roughness": math.nan, "fishel3.fineness": math.nan}
    energy = float(np.mean(v**2))
    return {"fishel3.traction": traction,
            "fishel3.roughness": math.log10(energy) if energy > 0 else math.nan,
            "fishel3.fineness": mico(v, scan["v_ts"].fs)}
