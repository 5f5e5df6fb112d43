"""texplorer: ``python -m texplorer`` runs the ``texplorer`` command (:func:`scanner.cli.main`).

The library itself is in the packages ``scanner`` (scan model, storage, acquisition), ``features`` (extraction,
feature space, selection), ``taxonomy`` (labels, evaluation, models) and ``gui`` (the web application).
"""

from __future__ import annotations

from scanner.version import __version__

__all__ = ["__version__"]
