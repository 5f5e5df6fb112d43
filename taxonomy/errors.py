"""The base of every texplorer error.

Each layer's errors derive from :class:`TexplorerError` (and, where callers may expect it, from the built-in
class they replaced, e.g. ``class ScanError(TexplorerError, ValueError)``), so a caller such as the CLI
catches one class and shows its one-line message. It lives in the ground layer, beside the labels, because
every layer above (scan model, storage, features, learning, devices, web) derives from it; see
``docs/extending.md`` for the layer order. (In the ``scanner`` package it would make the packages import
each other: ``scanner``'s ``__init__`` imports the scan model, which needs the labels, which need this.)
Bad arguments raise :class:`ParameterError`.
"""

from __future__ import annotations


class TexplorerError(Exception):
    """Bad input or an operation that cannot be carried out; the message is one line saying what is wrong."""


class ParameterError(TexplorerError, ValueError):
    """A bad argument: a value out of range, of the wrong shape or not one of the choices.

    Raised wherever a function refuses an argument (where a bare ``ValueError`` would otherwise be raised),
    so the CLI and the web application show its one-line message like any other texplorer error, and a
    caller that catches ``ValueError`` still catches it.
    """


class NotOnThisMachine(TexplorerError):
    """A worker does not see a task's stored data as the client does (a stored scan's file: missing,
    unreadable or other bytes): the client sends the data with the task instead. Raised by the loaders of
    ``scanner.storage.stored``, caught by ``scanner.runtime.cluster``; here, below both, so that storage does
    not import the runtime (nor the runtime storage), and opening a database loads no worker machinery."""
