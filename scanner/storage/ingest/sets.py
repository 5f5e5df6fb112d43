"""Imported recordings stored in a database as ``recordings/<set>/<recording>.mat`` (MATLAB v5, one
variable per channel plus a ``meta`` struct), written to a temporary folder first and renamed into
place, so a set is either complete or absent.
"""

from __future__ import annotations

import contextlib
import json
import os
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path
from typing import Any

import numpy as np
from isal import isal_zlib

from scanner.lazy import library
from scanner.scan import Recording, Trace
from scanner.storage.files import atomic_write_bytes, atomic_writer, recover_swaps, staging_folder, swap_in
from scanner.storage.ingest.mapping import _NAME, _SET, IngestError
from scanner.storage.mat5 import write_variables
from scanner.storage.matfile import COMPRESSION_LEVEL

scipy_io = library("scipy.io")  # read a stored recording when one is loaded, not at every command's start

RECORDINGS = "recordings"
"""Folder of imported recording sets inside a database."""

MAPPING = "mapping.toml"
"""The mapping file a set was ingested with, kept in the set's folder (docs/ingest.md)."""


def _struct(mapping: Mapping[str, Any]) -> dict[str, Any]:
    return {k: v for k, v in mapping.items() if _NAME.match(k)}


def recording_variables(recording: Recording) -> dict[str, Any]:
    """The MATLAB variables of a recording: one per channel and ``meta`` (name, label, label level, fs,
    units, roles, group, levels, ndim per channel, and all of ``Recording.meta`` as JSON text, which is what
    :func:`read_recording` restores it from)."""
    bad = [name for name in [*recording.channels, *recording.images] if not _NAME.match(name) or name == "meta"]
    if bad:
        raise IngestError(f"recording {recording.name}: channel name(s) {', '.join(bad)} "
                          "are not MATLAB names")
    meta = {
        "name": recording.name, "label": recording.label or "",
        "label_level": str(recording.meta.get("label_level", "label")),
        "fs": {n: t.fs for n, t in recording.channels.items()},
        "units": {n: t.unit for n, t in recording.channels.items()},
        "ndim": {n: float(t.data.ndim) for n, t in recording.channels.items()},
        "images": {n: np.array(image.shape, dtype=np.float64) for n, image in recording.images.items()},
        "roles": dict(recording.roles), "group": _struct(recording.group),
        "levels": _struct(recording.meta.get("levels", {})), "split": str(recording.meta.get("split", "")),
        "meta_json": json.dumps(dict(recording.meta), default=str),
    }
    return {**{n: t.data for n, t in recording.channels.items()}, **recording.images, "meta": meta}


def write_recording(recording: Recording, path: str | os.PathLike[str]) -> None:
    """The recording as a MATLAB v5 file at ``path`` (atomic), holding no copy of its traces while writing
    (:func:`scanner.storage.mat5.write_variables`, at the scans' compression level)."""
    with atomic_writer(path) as handle:
        write_variables(handle, recording_variables(recording), isal_zlib, COMPRESSION_LEVEL)


def _plain(value: Any) -> Any:
    if isinstance(value, scipy_io.matlab.mat_struct):
        return {name: _plain(getattr(value, name)) for name in value._fieldnames}
    if isinstance(value, np.ndarray) and value.dtype.kind == "U":
        return "".join(value.ravel().tolist())
    if isinstance(value, np.ndarray) and value.size == 1 and value.dtype.kind in "fiu":
        return float(value.ravel()[0])
    return value


def read_recording(path: str | os.PathLike[str]) -> Recording:
    """A recording written by :func:`store_recordings`."""
    path = Path(path)
    try:
        data = scipy_io.loadmat(path, squeeze_me=True, struct_as_record=False)
        meta = {k: _plain(v) for k, v in _plain(data["meta"]).items()}
        channels = {}
        for name, fs in dict(meta.get("fs") or {}).items():
            array = np.asarray(data[name], dtype=np.float64)
            ndim = int(meta["ndim"][name])
            shape = array.shape if array.ndim == ndim else ((array.size,) if ndim == 1 else (array.size, 1))
            channels[name] = Trace(array.reshape(shape), float(fs), str(meta["units"][name]))
        images = {name: np.asarray(data[name], dtype=np.uint8).reshape(np.asarray(shape, dtype=int).tolist())
                  for name, shape in dict(meta.get("images") or {}).items()}
        group = meta.get("group") or {}
        roles = meta.get("roles") or {}
        extra = json.loads(meta.get("meta_json") or "{}")
        return Recording(str(meta["name"]), channels, dict(roles), str(meta["label"]) or None,
                         {k: str(v) for k, v in dict(group).items()}, extra, images)
    except IngestError:
        raise
    except Exception as exc:  # scipy and the data model raise many types for foreign files
        raise IngestError(f"{path}: not a readable recording file ({type(exc).__name__}: {exc})") from None


def set_folder(db_root: str | os.PathLike[str], name: str) -> Path:
    if not _SET.match(name):
        raise IngestError(f"set name {name!r} must be 1-64 letters, digits, '.', '_' or '-'")
    return Path(db_root) / RECORDINGS / name


class SetWriter:
    """A recording set written one recording at a time, as they are read: memory does not grow with the
    number of recordings. Used as ``with SetWriter(db, name) as writer: writer.add(r); ...; writer.commit()``.

    The recordings go to a staging folder, which :meth:`commit` swaps into place
    (:func:`scanner.storage.files.swap_in`), so a crash leaves the previous set (or none), never part of
    one; a replacement killed between its renames is finished by the next writer or ``texplorer db check
    --repair`` (:func:`recover_sets`). Leaving the block without :meth:`commit` (an error, Ctrl-C) removes
    the staging folder and changes nothing. An existing set is refused unless ``replace``, on entering.
    """

    def __init__(self, db_root: str | os.PathLike[str], name: str, replace: bool = False) -> None:
        self.target = set_folder(db_root, name)
        self.name, self.replace, self.db_root = name, replace, db_root
        self.count = 0
        self._stack = contextlib.ExitStack()
        self._content: Path | None = None

    def __enter__(self) -> SetWriter:
        recover_sets(self.db_root)  # a replacement killed before: finished first, so "exists" is the truth
        self._refuse_existing()
        self.target.parent.mkdir(parents=True, exist_ok=True)
        staging = self._stack.enter_context(staging_folder(self.target))
        self._content = staging / "content"
        self._content.mkdir()
        return self

    def __exit__(self, *exc_info: object) -> None:
        self._stack.close()

    def add(self, recording: Recording) -> None:
        """Write one recording into the staging folder."""
        assert self._content is not None, "add() inside the with block"
        write_recording(recording, self._content / f"{recording.name}.mat")
        self.count += 1

    def keep(self, name: str, data: bytes) -> None:
        """Keep a file of the set beside its recordings (the mapping it was ingested with, :data:`MAPPING`)."""
        assert self._content is not None, "keep() inside the with block"
        if not _NAME.match(name.replace(".", "_")) or name.endswith(".mat"):
            raise IngestError(f"set {self.name!r}: {name!r} cannot be kept beside the recordings")
        atomic_write_bytes(self._content / name, data)

    def adopt(self, path: Path) -> None:
        """Move a recording file written and checked elsewhere (an import's staging folder, on the same file
        system) into the set, unchanged."""
        assert self._content is not None, "adopt() inside the with block"
        os.replace(path, self._content / path.name)
        self.count += 1

    def rewrite(self, change: Callable[[Recording], Recording]) -> None:
        """Replace every written recording by ``change(recording)``, one at a time."""
        assert self._content is not None, "rewrite() inside the with block"
        for path in sorted(self._content.glob("*.mat")):
            write_recording(change(read_recording(path)), path)

    def commit(self) -> Path:
        """Swap the written set into place; returns its folder."""
        assert self._content is not None, "commit() inside the with block"
        if not self.count:
            raise IngestError(f"set {self.name!r}: no recordings to store")
        self._refuse_existing()  # another ingest stored it meanwhile
        swap_in(self._content, self.target)
        return self.target

    def _refuse_existing(self) -> None:
        if self.target.exists() and not self.replace:
            raise IngestError(f"{self.target}: the set {self.name!r} exists; choose another name or replace it")


def store_recordings(db_root: str | os.PathLike[str], name: str, recordings: Iterable[Recording],
                     replace: bool = False) -> Path:
    """Write a set of recordings to ``<db_root>/recordings/<name>/<recording>.mat``; returns the folder.

    Crash-safe as :class:`SetWriter` (which writes them, one at a time). An existing set is refused unless
    ``replace``.
    """
    with SetWriter(db_root, name, replace) as writer:
        for recording in recordings:
            writer.add(recording)
        return writer.commit()


def recover_sets(db_root: str | os.PathLike[str]) -> list[str]:
    """Finish or undo the set replacements a killed ingest left, and remove its staging folders
    (:func:`scanner.storage.files.recover_swaps`); returns what was done."""
    return recover_swaps(Path(db_root) / RECORDINGS)


def load_recordings(folder: str | os.PathLike[str]) -> list[Recording]:
    """Every recording of a stored set (a folder of recording ``.mat`` files), in name order."""
    folder = Path(folder)
    files = sorted(folder.glob("*.mat")) if folder.is_dir() else []
    if not files:
        raise IngestError(f"{folder}: no recording files here")
    return [read_recording(path) for path in files]


def recording_sets(db_root: str | os.PathLike[str]) -> list[str]:
    """Names of the recording sets stored in a database."""
    folder = Path(db_root) / RECORDINGS
    return sorted(p.name for p in folder.iterdir() if p.is_dir() and not p.name.startswith(".")) \
        if folder.is_dir() else []
