"""Crash-safe file writing and checksums: what every stored byte of a database goes through.

A write goes to a temporary file in the target folder, is flushed and fsync'ed, then renamed over the
target (atomic on POSIX and on Windows via ``os.replace``), and the folder entry is fsync'ed where the OS
allows it. A reader therefore sees either the old file or the complete new one, never a partial file.
"""

from __future__ import annotations

import contextlib
import hashlib
import json
import os
import re
import secrets
import shutil
import sqlite3
import time
from collections.abc import Iterator
from pathlib import Path
from typing import Any, BinaryIO

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


STALE_TEMP_S = 600.0
"""A temporary file of :func:`atomic_writer` untouched for this long is a leftover of a killed writer: a
write holds its temporary file for the time of writing and one fsync (a model file: well under a second)."""


def stale_temp_files(folder: str | os.PathLike[str], name: str | None = None,
                     older_than_s: float = STALE_TEMP_S) -> list[Path]:
    """Temporary files of killed atomic writes in ``folder`` (of the target ``name`` only, if given): named
    by :func:`temp_path_for` and not modified for ``older_than_s`` seconds, so a write in progress is left
    alone."""
    folder = Path(folder)
    if not folder.is_dir():
        return []
    now = time.time()
    found = []
    for path in sorted(folder.iterdir()):
        if not (path.is_file() and is_temp_file(path)):
            continue
        if name is not None and not path.name.startswith(f".{name}{TEMP_MARK}"):
            continue
        with contextlib.suppress(OSError):
            if now - path.stat().st_mtime >= older_than_s:
                found.append(path)
    return found


def remove_stale_temp_files(folder: str | os.PathLike[str], name: str | None = None) -> list[Path]:
    """Remove :func:`stale_temp_files`; returns the ones removed (another process may have removed some)."""
    removed = []
    for path in stale_temp_files(folder, name):
        with contextlib.suppress(FileNotFoundError):
            path.unlink()
            removed.append(path)
    return removed


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


def read_json(path: str | os.PathLike[str], limit: int, error: type[Exception], missing: Any = None,
               hint: str = "") -> Any:
    """The JSON value of a small file, ``missing`` if there is none; ``error`` (one line naming the file) if
    it cannot be read, is larger than ``limit`` bytes (never read further) or is not JSON (``hint`` appended)."""
    path = Path(path)
    try:
        with open(path, "rb") as handle:
            data = handle.read(limit + 1)
    except FileNotFoundError:
        return missing
    except OSError as exc:
        raise error(f"{path}: cannot be read ({exc.strerror})") from None
    if len(data) > limit:
        raise error(f"{path}: larger than {limit} bytes")
    try:
        return json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        raise error(f"{path}: not valid JSON ({str(exc)[:200]}){hint}") from None


def sha256_file(path: str | os.PathLike[str], chunk: int = 1 << 20) -> str:
    """Hex SHA-256 of a file's bytes."""
    digest = hashlib.sha256()
    with open(path, "rb") as handle:
        while block := handle.read(chunk):
            digest.update(block)
    return digest.hexdigest()


# -- folders replaced whole ----------------------------------------------------------------------------
#
# A folder (a recording set) is written into an owned staging folder, then swapped in by renames under one
# lock per parent folder:  staged -> .NAME.new-T (complete),  NAME -> .NAME.old-T,  .NAME.new-T -> NAME,
# and .NAME.old-T removed. A process killed between any two steps leaves names that say how far it got:
# :func:`recover_swaps` rolls a complete new folder forward and removes what is left of the old one.

SWAP_LOCK = ".swap.lock"
"""The lock file of a parent folder whose sub-folders are swapped (:func:`swap_in`, :func:`recover_swaps`)."""
_SWAP_NAME = re.compile(r"\.(?P<name>.+)\.(?P<step>tmp|new|old)-(?P<token>[0-9a-f]{8})")


def staging_folder(target: Path) -> contextlib.AbstractContextManager[Path]:
    """An :func:`owned_folder` beside ``target`` (``.NAME.tmp-T``) to write the new content into, in its
    sub-folder ``content``; removed when the block ends, whatever happened."""
    return owned_folder(target.with_name(f".{target.name}.tmp-{secrets.token_hex(4)}"))


@contextlib.contextmanager
def _swap_lock(parent: Path) -> Iterator[None]:
    lock = sqlite3.connect(parent / SWAP_LOCK, isolation_level=None, timeout=60)
    try:
        lock.execute("BEGIN EXCLUSIVE")
        yield
    finally:
        lock.close()


def swap_in(content: Path, target: Path) -> None:
    """Make the complete folder ``content`` the folder ``target`` (replacing what was there), crash-safe:
    after a kill at any point, :func:`recover_swaps` finds ``target`` as it was or as ``content``."""
    token = secrets.token_hex(4)
    new = target.with_name(f".{target.name}.new-{token}")
    old = target.with_name(f".{target.name}.old-{token}")
    with _swap_lock(target.parent):
        _recover(target.parent)  # every set's: a killed ingest of another set leaves nothing behind either
        os.replace(content, new)
        fsync_dir(target.parent)
        if target.exists():
            os.replace(target, old)
        os.replace(new, target)
        fsync_dir(target.parent)
        shutil.rmtree(old, ignore_errors=True)


def swap_leftovers(parent: Path) -> list[Path]:
    """What killed swaps left in ``parent``: abandoned staging folders, complete new folders not swapped in,
    old folders not removed (a staging folder whose writer still runs is not listed)."""
    if not parent.is_dir():
        return []
    found = []
    for path in sorted(parent.iterdir()):
        match = _SWAP_NAME.fullmatch(path.name)
        if match and path.is_dir() and (match["step"] != "tmp" or is_abandoned(path)):
            found.append(path)
    return found


def recover_swaps(parent: Path) -> list[str]:
    """Finish or undo every swap a killed process left in ``parent``; returns what was done, one line each."""
    if not parent.is_dir():
        return []
    with _swap_lock(parent):
        return _recover(parent)


def _recover(parent: Path, name: str | None = None) -> list[str]:
    """:func:`recover_swaps` for the folder ``name`` (all: None), the swap lock held."""
    done = []
    leftovers = [(path, _SWAP_NAME.fullmatch(path.name)) for path in swap_leftovers(parent)]
    leftovers = [(path, match) for path, match in leftovers if name is None or match["name"] == name]
    for path, match in sorted(leftovers, key=lambda item: "tno".index(item[1]["step"][0])):
        target = parent / match["name"]
        if not path.exists():
            continue
        if match["step"] == "new":  # complete: roll forward
            old = target.with_name(f".{target.name}.old-{match['token']}")
            if target.exists():
                os.replace(target, old)
            os.replace(path, target)
            fsync_dir(parent)
            shutil.rmtree(old, ignore_errors=True)
            done.append(f"{path.name}/ -> {target.name}/ (an interrupted replacement finished)")
        elif match["step"] == "old" and not target.exists():  # its replacement never came: roll back
            os.replace(path, target)
            fsync_dir(parent)
            done.append(f"{path.name}/ -> {target.name}/ (an interrupted replacement undone)")
        else:
            shutil.rmtree(path, ignore_errors=True)
            done.append(f"{path.name}/ removed")
    return done
