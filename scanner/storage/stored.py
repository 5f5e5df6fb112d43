"""Stored scans loaded where they are processed: here, on a cluster worker that shares the storage, or on
one that gets the files' bytes from this machine.

A :class:`StoredScan` is what ``features.extract_many`` calls to load a scan. In a process of this machine
it reads the ``.mat`` file and its photos as :func:`scanner.storage.matfile.load_scan` always does. A Dask worker
(``scanner.runtime.cluster``) first tries :meth:`StoredScan.load_seen`: the files at the same path as this machine
names them (an absolute path on storage mounted alike everywhere, or a path relative to the directory the
worker was started in), accepted only with the size and SHA-256 the catalog recorded, so a worker that has
another database at that path never computes features for this one. A worker that cannot see the files
(or sees other bytes) raises :class:`NotOnThisMachine`; the client then reads them itself and sends them
as a :class:`ShippedScan`, which loads from those bytes and reports every problem exactly as a local load
would, naming the file as this machine names it. Reading stays bounded: a file larger than a scan file or
a photo may be is not read, its size alone travels and is refused on the worker as it would be here.

Before cached features are served, :meth:`StoredScan.verify` checks that the files are still the catalogued
bytes. Hashing every file on every read made serving a dozen cached scans sixty times slower, so a file whose
stat record (size, modification and inode change times, inode, device) is the one recorded when its SHA-256
last matched is taken as unchanged; any other file is hashed, and recorded again when it matches
(:class:`StatLedger`). The inode change time cannot be set back by copying with ``cp -p`` or by ``touch -r``,
which restore only the modification time; a file changed within :data:`RACY_SECONDS` of its check is not
recorded, so that a change within one tick of a coarse file-system clock is still hashed next time.
"""

from __future__ import annotations

import contextlib
import errno
import hashlib
import os
import sqlite3
import time
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path

from scanner.photo import max_file_bytes
from scanner.scan import Scan
from scanner.storage.files import sha256_file
from scanner.storage.matfile import MAX_SCAN_BYTES, load_scan, photo_names
from taxonomy.errors import NotOnThisMachine, TexplorerError

Catalogued = Mapping[str, tuple[int, str]]
"""File name (the ``.mat`` and each photo) -> (size in bytes, SHA-256) as the catalog recorded them."""

RACY_SECONDS = 2.0
"""A file whose inode changed less than this long before its hash was checked gets no stat record: file
systems whose clocks tick in seconds (FAT: two) could give a change within the same tick the same record."""

def stat_record(info: os.stat_result) -> str:
    """``"size:mtime_ns:ctime_ns:inode:device"`` of a file's ``stat``."""
    return f"{info.st_size}:{info.st_mtime_ns}:{info.st_ctime_ns}:{info.st_ino}:{info.st_dev}"


@dataclass(frozen=True)
class StatLedger:
    """Writes the stat records of files whose SHA-256 was found to match into the catalog at ``catalog``
    (its table ``file_stats``: ``path`` as ``files.path`` -> ``stat``, :func:`stat_record` and the SHA-256 it
    was checked against; paths relative to ``root``). A record only saves a later hash: a catalog that is
    busy, read-only or damaged, or a file no longer catalogued, leaves it unwritten without a word."""

    root: Path
    catalog: Path

    def record(self, folder: Path, stats: Mapping[str, str]) -> None:
        """Record ``stats`` (file name in ``folder`` -> stat record with its SHA-256)."""
        rows = [((folder / name).relative_to(self.root).as_posix(), stat) for name, stat in stats.items()]
        with contextlib.suppress(sqlite3.Error, ValueError), contextlib.closing(
                sqlite3.connect(self.catalog, timeout=5.0, isolation_level=None)) as conn:
            conn.execute("PRAGMA foreign_keys=ON")
            with conn:
                conn.execute("BEGIN IMMEDIATE")
                conn.executemany("INSERT OR REPLACE INTO file_stats (path, stat) SELECT ?, ? "
                                 "WHERE EXISTS (SELECT 1 FROM files WHERE files.path = ?)",
                                 [(path, stat, path) for path, stat in rows])


class ChangedSinceStored(TexplorerError):
    """A stored scan's file is not the bytes the catalog recorded: changed in place since it was stored.

    Its features are neither computed nor served from the feature cache (the cache is keyed by the
    catalogued bytes, which are not there); ``texplorer db check`` lists the file."""

    def __init__(self, path: Path, what: str) -> None:
        super().__init__(path, what)  # both in args: the error travels back from a worker process
        self.path, self.what = path, what

    def __str__(self) -> str:
        if not hasattr(self, "path"):  # made without __init__ (copied or unpickled by other means)
            return super().__str__()
        return (f"{self.path}: changed since it was stored ({self.what} differs from the catalog); "
                "run 'texplorer db check'")


@dataclass(frozen=True)
class SentFile:
    """A file as the client saw it: whether it is one, its size and its bytes, or the ``OSError`` that
    asking raised. Bytes beyond what a load accepts stay unread (``None``): the size refuses them."""

    is_file: bool
    size: int | OSError
    data: bytes | OSError | None


def _sent(path: Path, limit: int) -> SentFile:
    is_file = path.is_file()
    try:
        size = path.stat().st_size
    except OSError as exc:
        return SentFile(is_file, exc, exc)
    if size > limit:
        return SentFile(is_file, size, None)
    try:
        return SentFile(is_file, size, path.read_bytes())
    except OSError as exc:
        return SentFile(is_file, size, exc)


@dataclass(frozen=True)
class ShippedScan:
    """A stored scan's files as read on the client (file name -> :class:`SentFile`), loaded when called;
    a :class:`scanner.storage.matfile.FileView` that answers as this machine's file system did."""

    path: Path
    files: Mapping[str, SentFile]
    changed: ChangedSinceStored | None = None

    def __call__(self) -> Scan:
        if self.changed is not None:  # the client read other bytes than catalogued
            raise self.changed
        return load_scan(self.path, files=self)

    @property
    def nbytes(self) -> int:
        """Bytes carried."""
        return sum(len(f.data) for f in self.files.values() if isinstance(f.data, bytes))

    def is_file(self, path: Path) -> bool:
        sent = self.files.get(path.name)
        return sent is not None and sent.is_file

    def size(self, path: Path) -> int:
        return _value(self._sent(path).size)

    def read(self, path: Path) -> bytes:
        data = self._sent(path).data
        if data is None:  # only after its size passed here: the limit differs on this worker
            raise OSError(errno.EFBIG, "not sent, larger than the client accepts", str(path))
        return _value(data)

    def _sent(self, path: Path) -> SentFile:
        sent = self.files.get(path.name)
        if sent is None:  # a name the client did not read: the .mat did not name it
            raise FileNotFoundError(errno.ENOENT, os.strerror(errno.ENOENT), str(path))
        return sent


def _value(value: int | bytes | OSError) -> int | bytes:
    if isinstance(value, OSError):
        raise value
    return value


@dataclass(frozen=True)
class StoredScan:
    """The scan stored at ``path`` (a ``.mat`` file with its photos beside it), loaded when called.

    ``catalogued`` holds the size and SHA-256 of its files from the catalog; without it (files named on
    the command line) a worker accepts whatever file it finds at ``path``.
    """

    path: Path
    catalogued: Catalogued = field(default_factory=dict)
    stats: Mapping[str, str] = field(default_factory=dict)
    """File name -> its stat record and SHA-256 when the hash last matched (:class:`StatLedger`)."""
    ledger: StatLedger | None = None

    def __call__(self) -> Scan:
        """The scan, parsed from bytes checked against the catalog where it has them
        (:class:`ChangedSinceStored` otherwise): its features are stored under the catalogued hash."""
        return load_scan(self.path, files=CheckedFiles(self.catalogued) if self.catalogued else None)

    def verify(self) -> None:
        """Raise :class:`ChangedSinceStored` unless every catalogued file (the ``.mat`` and its photos) is
        there with its catalogued size and SHA-256: before serving cached features, which were computed
        from those bytes. A file whose stat record is the one :attr:`stats` holds for this SHA-256 is not
        hashed again; the others are, and their records go to the :attr:`ledger` when they match. A
        missing or unreadable file raises its ``OSError``."""
        fresh = {}
        for name, (size, digest) in sorted(self.catalogued.items()):
            path = self.path.with_name(name)
            info = path.stat()
            if info.st_size != size:
                raise ChangedSinceStored(path, "size")
            record = f"{stat_record(info)}:{digest}"
            if self.stats.get(name) == record:
                continue
            if sha256_file(path) != digest:
                raise ChangedSinceStored(path, "SHA-256")
            if time.time() - info.st_ctime > RACY_SECONDS:
                fresh[name] = record
        if fresh and self.ledger is not None:
            self.ledger.record(self.path.parent, fresh)

    def load_seen(self) -> Scan:
        """Load from this machine's view of ``path``; :class:`NotOnThisMachine` if a file is missing,
        unreadable or not the catalogued one (checked on the bytes that are then parsed)."""
        return load_scan(self.path, files=SeenFiles(self.catalogued))

    def visible(self) -> bool:
        """Whether this machine sees the ``.mat`` file as catalogued (a worker answers for a whole run)."""
        seen = SeenFiles(self.catalogued)
        try:
            if seen.is_file(self.path) and seen.size(self.path) <= MAX_SCAN_BYTES:
                seen.read(self.path)
        except NotOnThisMachine:
            return False
        return True

    def shipped(self) -> ShippedScan:
        """The ``.mat`` and the photos it names, read here for a worker that cannot see them; where a file's
        bytes are not the catalogued ones, the worker's load raises :class:`ChangedSinceStored`."""
        mat = _sent(self.path, MAX_SCAN_BYTES)
        files = {self.path.name: mat}
        if isinstance(mat.data, bytes):
            files.update((name, _sent(self.path.with_name(name), max_file_bytes())) for name in photo_names(mat.data))
        return ShippedScan(self.path, files, self._changed(files))

    def _changed(self, files: Mapping[str, SentFile]) -> ChangedSinceStored | None:
        """The error a local load of these files would raise for the first that is not catalogued bytes
        (its size, then its SHA-256, in the order the load reads them), or None."""
        for name, sent in files.items():
            path = self.path.with_name(name)
            if name in self.catalogued and isinstance(sent.size, int) and sent.size != self.catalogued[name][0]:
                return ChangedSinceStored(path, "size")
            try:
                if isinstance(sent.data, bytes):
                    CheckedFiles(self.catalogued).check(path, sent.data)
            except ChangedSinceStored as exc:
                return exc
        return None


@dataclass(frozen=True)
class CheckedFiles:
    """This machine's files as a :class:`scanner.storage.matfile.FileView` that parses only catalogued bytes:
    the hash is computed on the bytes that are then parsed (a file changed between a check and the read
    cannot slip in). Missing or unreadable files raise as a plain load does."""

    catalogued: Catalogued

    def is_file(self, path: Path) -> bool:
        return path.is_file()

    def size(self, path: Path) -> int:
        size = path.stat().st_size
        if path.name in self.catalogued and size != self.catalogued[path.name][0]:
            raise ChangedSinceStored(path, "size")
        return size

    def read(self, path: Path) -> bytes:
        data = path.read_bytes()
        self.check(path, data)
        return data

    def check(self, path: Path, data: bytes) -> None:
        """Raise :class:`ChangedSinceStored` if ``data`` read from ``path`` is not the catalogued file."""
        if path.name in self.catalogued and hashlib.sha256(data).hexdigest() != self.catalogued[path.name][1]:
            raise ChangedSinceStored(path, "SHA-256")


@dataclass(frozen=True)
class SeenFiles:
    """This machine's files as a :class:`scanner.storage.matfile.FileView` that accepts only catalogued ones."""

    catalogued: Catalogued

    def is_file(self, path: Path) -> bool:
        if not path.is_file():
            raise NotOnThisMachine(f"{path}: no such file here")
        return True

    def size(self, path: Path) -> int:
        try:
            size = path.stat().st_size
        except OSError as exc:
            raise NotOnThisMachine(f"{path}: {exc.strerror or exc}") from None
        if path.name in self.catalogued and size != self.catalogued[path.name][0]:
            raise NotOnThisMachine(f"{path}: other content than catalogued (size differs)")
        return size

    def read(self, path: Path) -> bytes:
        try:
            data = path.read_bytes()
        except OSError as exc:
            raise NotOnThisMachine(f"{path}: {exc.strerror or exc}") from None
        if path.name in self.catalogued and hashlib.sha256(data).hexdigest() != self.catalogued[path.name][1]:
            raise NotOnThisMachine(f"{path}: other content than catalogued (SHA-256 differs)")
        return data
