"""Crash-safe file writing and checksums: what every stored byte of a database goes through.

A write goes to a temporary file in the target folder, is flushed and fsync'ed, then renamed over the
target (atomic on POSIX and on Windows via ``os.replace``), and the folder entry is fsync'ed where the OS
allows it. A reader therefore sees either the old file or the complete new one, never a partial file.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import re
import secrets
import shutil
import sqlite3
from collections.abc import Iterator
from pathlib import Path
from typing import BinaryIO

TEMP_MARK = ".tmp-"
"""Temporary files are named ``.<name>.tmp-<12 hex digits>``; a crash may leave them behind, never a target."""
_TEMP_NAME = re.compile(r"\..+\.tmp-[0-9a-f]{12}")
OWNER_LOCK = "owner.lock"


def temp_path_for(path: Path) -> Path:
    return path.with_name(f".{path.name}{TEMP_MARK}{secrets.token_hex(6)}")


def is_temp_file(path: Path) -> bool:
    """True for a name :func:`temp_path_for` makes: the temporary file (or folder) of a write in progress or
    interrupted by a crash."""
    return bool(_TEMP_NAME.fullmatch(path.name))


@contextlib.contextmanager
def owned_folder(path: str | os.PathLike[str]) -> Iterator[Path]:
    """A new folder that counts as in use while this ``with`` block runs in a live process; removed after.

    The mark is an exclusive lock on a SQLite file inside it (:data:`OWNER_LOCK`): SQLite's file locks work
    on every operating system and die with the process, so :func:`is_abandoned` can tell the folder of a
    running job from one a killed process left behind.
    """
    folder = Path(path)
    folder.mkdir()
    lock = sqlite3.connect(folder / OWNER_LOCK, isolation_level=None, timeout=0)
    try:
        lock.execute("BEGIN EXCLUSIVE")
        yield folder
    finally:
        lock.close()
        shutil.rmtree(folder, ignore_errors=True)


def is_abandoned(folder: str | os.PathLike[str]) -> bool:
    """True if no live process holds the lock of an :func:`owned_folder` (its owner finished or was killed)."""
    lock = Path(folder) / OWNER_LOCK
    if not lock.is_file():
        return False  # being created this instant, or not an owned folder at all: leave it alone
    try:
        probe = sqlite3.connect(lock, isolation_level=None, timeout=0)
    except sqlite3.Error:
        return False
    try:
        probe.execute("BEGIN EXCLUSIVE")
        probe.execute("ROLLBACK")
    except sqlite3.OperationalError:
        return False  # locked: its owner is alive
    finally:
        probe.close()
    return True


def fsync_dir(folder: Path) -> None:
    """Persist a rename in ``folder`` (a no-op where directories cannot be opened, e.g. Windows)."""
    try:
        fd = os.open(folder, os.O_RDONLY)
    except OSError:
        return
    try:
        os.fsync(fd)
    except OSError:
        pass
    finally:
        os.close(fd)


@contextlib.contextmanager
def atomic_writer(path: str | os.PathLike[str]) -> Iterator[BinaryIO]:
    """Open a binary file that appears at ``path`` only if the ``with`` block completes."""
    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    temp = temp_path_for(target)
    try:
        with open(temp, "xb") as handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.replace(temp, target)
    except BaseException:
        with contextlib.suppress(OSError):
            temp.unlink()
        raise
    fsync_dir(target.parent)


def atomic_write_bytes(path: str | os.PathLike[str], data: bytes) -> None:
    """Write ``data`` to ``path`` atomically."""
    with atomic_writer(path) as handle:
        handle.write(data)


def sha256_file(path: str | os.PathLike[str], chunk: int = 1 << 20) -> str:
    """Hex SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        while block := handle.read(chunk):
            digest.update(block)
    return digest.hexdigest()
