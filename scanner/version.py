"""The software version, written into every scan, trained model and export bundle.

A module of its own, importing nothing, so that any layer can record the version without importing the
``scanner`` package's surface (the scan model and storage).
"""

__version__ = "0.1.0"
