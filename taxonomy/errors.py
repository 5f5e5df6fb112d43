"""The base of every texplorer error.

Each layer's errors derive from :class:`TexplorerError` (and, where callers may expect it, from the built-in
class they replaced, e.g. ``class ScanError(TexplorerError, ValueError)``), so a caller such as the CLI
catches one class and shows its one-line message. It lives in the ground layer, beside the labels, because
every layer above (scan model, storage, features, learning, devices, web) derives from it; see
``docs/extending.md`` for the layer order.
"""

from __future__ import annotations


class TexplorerError(Exception):
    """Bad input or an operation that cannot be carried out; the message is one line saying what is wrong."""
