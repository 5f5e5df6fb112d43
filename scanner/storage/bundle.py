"""Export bundles for other labs, and their import into a database (docs/export.md).

A bundle is a folder, or a ``.zip`` file holding the same tree at its root::

    README.md                  how to load scans and features in MATLAB/Octave or Python, without texplorer
    load_texplorer.m           MATLAB/Octave loader (plain ``load``)
    load_texplorer.py          Python loader (numpy + scipy only)
    manifest.json              format and schema versions, software version, creation time, filters, counts,
                               calibrations used, the scans, and the SHA-256 and size of every other file
    manifest.json.sha256       SHA-256 of manifest.json (``sha256sum`` format), so the manifest is checked too
    features.csv, features.mat the feature space of the exported scans (docs/evaluation.md, ``features.space``)
    taxonomy.csv               the exporting database's taxonomy: shipped table plus its extensions
    scans/<label>/<sample>/<scan_id>.mat, <scan_id>_disp.png, ...   the files exactly as in the database

Export writes the whole bundle under a temporary name beside the target (``.<name>.tmp-<hex>``, a folder
or a zip file) and renames it when complete, so a bundle that exists is whole; scan files are copied with
their SHA-256 checked against the catalog on the way.

Import works in two phases. **Verify** touches nothing the database uses: every file of the bundle is
copied into a staging folder ``<db>/.import.tmp-<hex>/bundle`` (on the database's file system, so the files
can later be moved, not copied; the folder holds a SQLite lock while the import runs,
:func:`scanner.storage.files.owned_folder`) while its size and SHA-256 are checked against the manifest; the
manifest is checked against ``manifest.json.sha256`` and its schema; every scan is loaded and validated
(with the limits of :func:`scanner.load_scan`, photos included) and must match its manifest entry and
path; the taxonomy must parse. Any problem refuses the whole bundle with the list of problems. Member names
that are absolute, contain ``..``, backslashes or drive letters, that put a file under another file
(``features.csv/x``), and symbolic links, are refused before anything is extracted. **Merge** then skips
scans already stored with the same content, reports a scan id stored with other content, a sample stored
under another label and a taxonomy code named differently here as conflicts (nothing is overwritten),
appends the codes of new materials to the database's taxonomy extension ``<db>/taxonomy.csv`` and catalogs
all new scans in one transaction (:meth:`scanner.storage.database.Database.add_written`: rows first, then the files
are moved into place). If that fails, the moved files are moved back and the taxonomy codes taken back: the
database is as it was. A process killed during import leaves the catalog as it was; at worst the staging
folder, moved files of the uncommitted batch and the new taxonomy codes remain, and ``texplorer db check``
lists the first two as crash leftovers, which the next write or ``db check --repair`` removes.
"""

from __future__ import annotations

import contextlib
import csv
import hashlib
import io
import json
import math
import os
import re
import shutil
import stat
import tempfile
import time
import zipfile
import zlib
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field
from datetime import UTC, datetime
from pathlib import Path
from typing import IO, Any, Protocol

import scipy.io

from scanner.scan import CHANNELS, IMAGES, SCHEMA_VERSION, ScanMeta
from scanner.storage.database import STAGING_PREFIX, Database, FileEntry, ScanRecord, content_hash
from scanner.storage.files import atomic_write_bytes, fsync_dir, owned_folder, temp_path_for
from scanner.storage.matfile import ScanFormatError, load_scan, photo_file_name
from scanner.storage.metadata import (
    CROISSANT,
    DATAPACKAGE,
    RO_CRATE,
    SCANS_CSV,
    Provenance,
    as_bytes,
    checked_creator,
    croissant,
    croissant_file_sets,
    describe_tables,
    license_url,
    metadata_problems,
    ro_crate,
    scan_bundle_tables,
    scan_channels,
    sessions_of,
    taxonomy_table,
)
from scanner.version import __version__
from taxonomy.errors import TexplorerError
from taxonomy.labels import Label
from taxonomy.table import HEADER, Taxonomy, TaxonomyError, read_table, select_labels

BUNDLE_FORMAT = "texplorer-bundle"
BUNDLE_SCHEMA = 1
MANIFEST = "manifest.json"
MANIFEST_SUM = "manifest.json.sha256"
README = "README.md"
LOADERS = ("load_texplorer.m", "load_texplorer.py")
FEATURES_CSV = "features.csv"
FEATURES_MAT = "features.mat"
TAXONOMY_CSV = "taxonomy.csv"
REQUIRED_FILES = (README, *LOADERS, FEATURES_CSV, FEATURES_MAT, TAXONOMY_CSV)
"""Files every bundle lists in its manifest besides the scans."""

MAX_MANIFEST_BYTES = 64 << 20
"""A manifest larger than this is refused unread (about 300,000 scans' worth)."""

_DATA = Path(__file__).parents[1] / "data"
_STORED = (".mat", ".png", ".jpg", ".jpeg", ".zip")
"""Already compressed: kept as they are inside a zip bundle, everything else is deflated."""
_CHUNK = 1 << 20
_LINK = "a symbolic link (refused: it could point outside the bundle)"
_HEX64 = re.compile(r"[0-9a-f]{64}")
_DRIVE = re.compile(r"^[A-Za-z]:")
_SCAN_FIELDS: dict[str, type] = {"scan_id": str, "label": str, "sample_id": str, "session_id": str,
                                 "operator": str, "scan_index": int, "started": str, "rigid": bool,
                                 "content_hash": str, "files": dict}

Progress = Callable[[Iterable], Iterable]


class FeatureTable(Protocol):
    """The feature space of the exported scans, as the caller computed it (``features.FeatureSpace``)."""

    columns: Sequence[str]
    failed: Sequence[tuple[str, str]]

    def __len__(self) -> int: ...

    def to_csv(self, path: str | os.PathLike[str]) -> Path: ...

    def to_mat(self, path: str | os.PathLike[str]) -> Path: ...


Features = Callable[[Sequence[ScanRecord]], FeatureTable]
"""The caller's feature space of the scans to export (``scanner.workflows.exchange.export_database`` reads it from
the database's feature cache)."""


class BundleError(TexplorerError, ValueError):
    """A bundle cannot be written or is refused; ``problems`` lists every reason found, one line each."""

    def __init__(self, message: str, problems: Sequence[str] = ()) -> None:
        super().__init__(message)
        self.problems = list(problems)


@dataclass(frozen=True)
class ExportReport:
    """What :func:`export_bundle` wrote."""

    path: Path
    scans: int
    files: int
    bytes: int
    seconds: float
    feature_failures: tuple[tuple[str, str], ...] = ()
    metadata_seconds: float = 0.0
    """Of ``seconds``, the time spent on the standard metadata (:mod:`scanner.storage.metadata`)."""


@dataclass
class ImportReport:
    """What :func:`import_bundle` did; ``conflicts`` are ``"<scan_id>: <reason>"`` lines."""

    bundle: Path
    added: list[str] = field(default_factory=list)
    identical: list[str] = field(default_factory=list)
    conflicts: list[str] = field(default_factory=list)
    taxonomy_added: list[str] = field(default_factory=list)
    unknown_labels: list[str] = field(default_factory=list)
    """Labels of added scans that neither this database's nor the bundle's taxonomy names."""
    bytes: int = 0
    seconds: float = 0.0


# -- export ------------------------------------------------------------------------------------------

def export_bundle(db: Database, out: str | os.PathLike[str], features: Features, *, feature_code_version: str,
                  license: str | None, creator: str | None = None, feature_units: Mapping[str, str] | None = None,
                  label: str | None = None, session: str | None = None, progress: Progress = iter) -> ExportReport:
    """Write the scans of ``db`` (optionally only a label or class prefix, or one session) as a bundle.

    ``out`` ending in ``.zip`` gives a zip file, anything else a folder; it must not exist yet. The feature
    tables are ``features(records)``, the caller's feature space of the scans in export order, computed by
    ``feature_code_version`` (recorded in the manifest); ``feature_units`` gives the unit of each feature
    that has one (the Frictionless schema of ``features.csv``). ``license`` is an SPDX identifier or a URL,
    or ``"none"`` to export without one; ``creator`` a name or URL (:mod:`scanner.storage.metadata`).

    Raises
    ------
    BundleError
        ``out`` exists, no license was given, no scan matches the filters, or a database file no longer
        matches its catalog SHA-256 (run ``texplorer db check``). Nothing is left at ``out`` then.
    MetadataError
        A license or creator that cannot be written.
    """
    started = time.perf_counter()
    out, license, creator = export_target(out, license, creator)
    records = sorted(db.records(label=label, session=session), key=lambda r: (r.started, r.scan_id))
    if label:  # a prefix in its canonical spelling (" c7 " -> C7); part of a name as given
        label = select_labels(label, db.taxonomy)[0] or label.strip()
    if not records:
        raise BundleError(f"{db.root}: no scans{_filter_text(label, session)} to export")
    space = features(records)
    out.parent.mkdir(parents=True, exist_ok=True)
    created = datetime.now(UTC).replace(microsecond=0)
    writer = bundle_writer(out, created)
    try:
        files, scans = {}, []
        for record in progress(records):
            entries = db.files(record.scan_id)
            for entry in entries:
                files[entry.path] = _copy_checked(db, entry, writer)
            scans.append(_scan_entry(record, entries))
        generated = _generated_files(db, space)
        for name, data in generated.items():
            files[name] = writer.add(name, io.BytesIO(data))
        metadata_started = time.perf_counter()
        provenance = Provenance(license, creator, created, __version__, feature_code_version,
                                f"texplorer scans{_filter_text(label, session)}")
        scan_files = {scan["scan_id"]: scan["files"] for scan in scans}
        for name, data in _scan_metadata(records, scan_files, generated, files, feature_units or {},
                                         provenance).items():
            files[name] = writer.add(name, io.BytesIO(data))
        crate = ro_crate(files, provenance, sessions_of(records, scan_files), _DESCRIPTION, ABOUT)
        files[RO_CRATE] = writer.add(RO_CRATE, io.BytesIO(as_bytes(crate)))
        metadata_seconds = time.perf_counter() - metadata_started
        manifest = _manifest(db, records, scans, files, space, created, label, session, feature_code_version)
        manifest["license"], manifest["creator"] = license, creator
        size = finish_bundle(writer, files, manifest)
    except BaseException:
        writer.discard()
        raise
    return ExportReport(out, len(records), len(files) + 2, size, time.perf_counter() - started, space.failed,
                        metadata_seconds)


_DESCRIPTION = ("Multimodal material scans of a Texplorer2 scanner (acceleration, sound, IR reflectance, force, "
                "flex, temperature, magnetic field, metal contact, three photos, mass and volume) as MATLAB v5 "
                "files, with their features and material taxonomy; see README.md")
ABOUT = {
    README: "how to load the scans and features in MATLAB/Octave or Python", MANIFEST: "texplorer's own manifest: "
    "versions, counts, calibrations, scans and the SHA-256 of every file", "load_texplorer.m": "MATLAB/Octave loader",
    "load_texplorer.py": "Python loader (numpy and scipy)", FEATURES_CSV: "feature table, one row per scan",
    FEATURES_MAT: "the feature table as a MATLAB file", TAXONOMY_CSV: "the material taxonomy (C/S/M/P/X codes)",
    SCANS_CSV: "one row per scan: label codes, sample, session, operator, files",
    CROISSANT: "Croissant 1.1 description for machine-learning loaders",
    DATAPACKAGE: "Frictionless Data Package of the CSV tables",
}
"""What the bundle's own files are, for the RO-Crate description."""

NO_LICENSE_TEXT = ("no license for the bundle: give --license with an SPDX identifier (CC-BY-4.0, CC0-1.0) or a "
                   "license URL, set the database's with 'texplorer db settings --license', or give --license none")


def _scan_metadata(records: Sequence[ScanRecord], scan_files: Mapping[str, Mapping[str, str]],
                   generated: Mapping[str, bytes], written: Mapping[str, Mapping[str, Any]],
                   feature_units: Mapping[str, str], provenance: Provenance) -> dict[str, bytes]:
    """The standard metadata of a bundle of scans (:mod:`scanner.storage.metadata`), in writing order: the
    tables and schemas, then Croissant (which lists the tables' checksums), then RO-Crate (every file's)."""
    tables = [*scan_bundle_tables(records, scan_files, generated[FEATURES_CSV], feature_units),
              taxonomy_table(generated[TAXONOMY_CSV])]
    out = {SCANS_CSV: tables[0][1], **describe_tables(tables, scan_channels(), provenance)}
    checksums = {**written, **{name: checksum(data) for name, data in out.items()}}  # the written ones hashed once
    photo_kinds = sorted({IMAGES[v] for roles in scan_files.values() for v in roles if v in IMAGES})
    file_sets = croissant_file_sets(photo_kinds, "scans/**/*.mat", "one MATLAB v5 file per scan (docs/database.md): "
                                    "one variable per channel (channels record set) and a meta struct")
    out[CROISSANT] = as_bytes(croissant([table for table, _ in tables], checksums, provenance, file_sets,
                                        photo_kinds))
    return out


def checksum(data: bytes) -> dict[str, Any]:
    """A generated file's manifest entry: its SHA-256 and size."""
    return {"sha256": hashlib.sha256(data).hexdigest(), "size": len(data)}


def export_target(out: str | os.PathLike[str], license: str | None,
                  creator: str | None) -> tuple[Path, str | None, str | None]:
    """The new bundle's path and its license URL and creator, checked before anything is written.

    Raises
    ------
    BundleError
        ``out`` exists, or no license was given (``"none"`` is one).
    MetadataError
        A license or creator that cannot be written.
    """
    out = Path(out)
    if out.exists():
        raise BundleError(f"{out} already exists; export to a new name")
    if license is None:
        raise BundleError(NO_LICENSE_TEXT)
    return out, license_url(license), checked_creator(creator)


def finish_bundle(writer: _FolderWriter | _ZipWriter, files: Mapping[str, Mapping[str, Any]],
                  manifest: Mapping[str, Any]) -> int:
    """Write ``manifest.json`` and its checksum file, then commit the bundle; returns the bundle's bytes."""
    manifest_bytes = json.dumps(manifest, indent=1, allow_nan=False).encode("utf-8") + b"\n"
    writer.add(MANIFEST, io.BytesIO(manifest_bytes))
    writer.add(MANIFEST_SUM, io.BytesIO(manifest_sum(manifest_bytes)))
    writer.commit()
    return sum(f["size"] for f in files.values()) + len(manifest_bytes) + len(manifest_sum(manifest_bytes))


def _filter_text(label: str | None, session: str | None) -> str:
    parts = [text for text in (label and f"label {label}", session and f"session {session}") if text]
    return f" with {' and '.join(parts)}" if parts else ""


def _copy_checked(db: Database, entry: FileEntry, writer: _FolderWriter | _ZipWriter) -> dict[str, Any]:
    with open(db.root / entry.path, "rb") as source:
        written = writer.add(entry.path, source, entry.size)
    if written["sha256"] != entry.sha256:
        raise BundleError(f"{db.root / entry.path}: differs from the catalog's SHA-256 (changed since it was "
                          "stored); run 'texplorer db check'")
    return written


def _scan_entry(record: ScanRecord, entries: Sequence[FileEntry]) -> dict[str, Any]:
    return {"scan_id": record.scan_id, "label": record.label, "sample_id": record.sample_id,
            "session_id": record.session_id, "operator": record.operator, "scan_index": record.scan_index,
            "started": record.started, "rigid": record.rigid, "content_hash": record.content_hash,
            "files": {entry.role: entry.path for entry in entries}}


def _generated_files(db: Database, space: FeatureTable) -> dict[str, bytes]:
    """Feature tables, taxonomy, README and loaders as bytes (the writers do the atomic part)."""
    with tempfile.TemporaryDirectory(prefix="texplorer-export-") as scratch:
        folder = Path(scratch)
        space.to_csv(folder / FEATURES_CSV)
        space.to_mat(folder / FEATURES_MAT)
        db.taxonomy().to_csv(folder / TAXONOMY_CSV)
        generated = {name: (folder / name).read_bytes()
                     for name in (FEATURES_CSV, FEATURES_MAT, TAXONOMY_CSV)}
    generated[README] = (_DATA / "bundle_readme.md").read_bytes()
    generated.update({name: (_DATA / name).read_bytes() for name in LOADERS})
    return generated


def _calibrations(db: Database, records: Sequence[ScanRecord]) -> list[dict[str, Any]]:
    """Distinct ``meta.calibration`` structs of the scans, each with the scans that used it.

    Read from the ``meta`` variable alone (scipy skips the compressed traces), so export stays fast.
    """
    groups: dict[str, dict[str, Any]] = {}
    for record in records:
        meta = scipy.io.loadmat(db.root / record.path, variable_names=["meta"], simplify_cells=True)["meta"]
        calibration = meta.get("calibration")
        values = {k: _json_number(v) for k, v in calibration.items()} if isinstance(calibration, dict) else {}
        key = json.dumps(values, sort_keys=True)
        groups.setdefault(key, {"values": values, "scans": []})["scans"].append(record.scan_id)
    return list(groups.values())


def _json_number(value: Any) -> float | None:
    number = float(value)
    return None if math.isnan(number) else number


def _manifest(db: Database, records: Sequence[ScanRecord], scans: list[dict[str, Any]],
              files: Mapping[str, dict[str, Any]], space: FeatureTable, created: datetime, label: str | None,
              session: str | None, feature_code_version: str) -> dict[str, Any]:
    return {
        "format": BUNDLE_FORMAT,
        "bundle_schema": BUNDLE_SCHEMA,
        "scan_schema": SCHEMA_VERSION,
        "software_version": __version__,
        "feature_code_version": feature_code_version,
        "created": created.isoformat(),
        "filters": {"label": label, "session": session},
        "counts": {"scans": len(records), "materials": len({r.label for r in records}),
                   "samples": len({r.sample_id for r in records}),
                   "sessions": len({r.session_id for r in records}),
                   "operators": len({r.operator for r in records}), "files": len(files),
                   "bytes": sum(f["size"] for f in files.values()), "feature_rows": len(space),
                   "feature_columns": len(space.columns)},
        "calibrations": _calibrations(db, records),
        "feature_failures": [{"scan_id": scan_id, "reason": reason} for scan_id, reason in space.failed],
        "scans": scans,
        "files": dict(sorted(files.items())),
    }


def manifest_sum(manifest: bytes) -> bytes:
    return f"{hashlib.sha256(manifest).hexdigest()}  {MANIFEST}\n".encode("ascii")


def _copy(source: IO[bytes], target: IO[bytes]) -> dict[str, Any]:
    digest, size = hashlib.sha256(), 0
    while block := source.read(_CHUNK):
        digest.update(block)
        target.write(block)
        size += len(block)
    return {"sha256": digest.hexdigest(), "size": size}


class _FolderWriter:
    """Builds a folder bundle in ``.<name>.tmp-<hex>`` beside the target; :meth:`commit` renames it."""

    def __init__(self, target: Path) -> None:
        self.target = target
        self.temp = temp_path_for(target)
        self.temp.mkdir()

    def add(self, name: str, source: IO[bytes], size: int = 0) -> dict[str, Any]:
        path = self.temp.joinpath(*name.split("/"))
        path.parent.mkdir(parents=True, exist_ok=True)
        with open(path, "xb") as target:
            written = _copy(source, target)
            target.flush()
            os.fsync(target.fileno())
        return written

    def commit(self) -> None:
        for folder, _, _ in os.walk(self.temp):
            fsync_dir(Path(folder))
        os.rename(self.temp, self.target)
        fsync_dir(self.target.parent)

    def discard(self) -> None:
        shutil.rmtree(self.temp, ignore_errors=True)


class _ZipWriter:
    """Builds a zip bundle in ``.<name>.tmp-<hex>`` beside the target; :meth:`commit` renames it."""

    def __init__(self, target: Path, created: datetime) -> None:
        self.target = target
        self.temp = temp_path_for(target)
        self.date_time = created.timetuple()[:6]
        self.archive = zipfile.ZipFile(self.temp, "x", allowZip64=True)

    def add(self, name: str, source: IO[bytes], size: int = 0) -> dict[str, Any]:
        info = zipfile.ZipInfo(name, self.date_time)
        info.compress_type = zipfile.ZIP_STORED if name.lower().endswith(_STORED) else zipfile.ZIP_DEFLATED
        info.external_attr = 0o644 << 16
        info.file_size = size
        with self.archive.open(info, "w", force_zip64=size >= zipfile.ZIP64_LIMIT) as target:
            return _copy(source, target)

    def commit(self) -> None:
        self.archive.close()
        with open(self.temp, "rb+") as handle:
            os.fsync(handle.fileno())
        os.replace(self.temp, self.target)
        fsync_dir(self.target.parent)

    def discard(self) -> None:
        with contextlib.suppress(Exception):
            self.archive.close()
        self.temp.unlink(missing_ok=True)


def bundle_writer(out: Path, created: datetime) -> _FolderWriter | _ZipWriter:
    """The writer of a new bundle at ``out``: a zip file if it ends in ``.zip``, else a folder; both build it
    under a temporary name and rename it on ``commit()`` (``discard()`` removes it)."""
    return _ZipWriter(out, created) if out.suffix.lower() == ".zip" else _FolderWriter(out)


# -- reading bundles ---------------------------------------------------------------------------------

def unsafe_name(name: str) -> str | None:
    """Why ``name`` may not be a bundle member (it could escape the folder it is extracted to), or None.

    A member name is a relative POSIX path: no leading ``/``, drive letter, backslash, ``:``, NUL, empty,
    ``.`` or ``..`` component.
    """
    if not name:
        return "empty name"
    if name.startswith("/") or _DRIVE.match(name):
        return "absolute path"
    if "\\" in name or ":" in name or "\x00" in name:
        return "backslash, colon or NUL in the name"
    if any(part in ("", ".", "..") for part in name.split("/")):
        return "empty, '.' or '..' path component"
    return None


def nested_names(names: Iterable[str]) -> list[str]:
    """Member names that put a file under another member that is a file (``features.csv/x``): a zip file
    can hold both, a folder cannot."""
    files = set(names)
    return [f"{name}: inside {'/'.join(name.split('/')[:i])}, which is a file" for name in sorted(files)
            for i in range(1, name.count("/") + 1) if "/".join(name.split("/")[:i]) in files][:100]


class _FolderReader:
    def __init__(self, root: Path) -> None:
        self.root = root

    def members(self) -> tuple[list[str], list[str]]:
        names, problems = [], []
        for folder, dirs, files in os.walk(self.root):
            for entry in sorted(dirs + files):
                path = Path(folder) / entry
                relative = path.relative_to(self.root).as_posix()
                mode = path.lstat().st_mode
                if stat.S_ISLNK(mode):
                    problems.append(f"{relative}: {_LINK}")
                    dirs[:] = [d for d in dirs if d != entry]
                elif stat.S_ISREG(mode):
                    names.append(relative)
                elif not stat.S_ISDIR(mode):
                    problems.append(f"{relative}: not a regular file")
        return names, problems

    def open(self, name: str) -> IO[bytes]:
        return open(self.root.joinpath(*name.split("/")), "rb")

    def close(self) -> None:
        pass


class _ZipReader:
    def __init__(self, path: Path) -> None:
        self.archive = zipfile.ZipFile(path)

    def members(self) -> tuple[list[str], list[str]]:
        names, problems, seen = [], [], set()
        for info in self.archive.infolist():
            reason = unsafe_name(info.filename.rstrip("/") if info.is_dir() else info.filename)
            if reason:
                problems.append(f"{info.filename!r}: {reason} (refused: it could write outside the bundle)")
            elif stat.S_ISLNK(info.external_attr >> 16):
                problems.append(f"{info.filename}: {_LINK}")
            elif info.filename in seen:
                problems.append(f"{info.filename}: stored twice in the zip file")
            elif not info.is_dir():
                names.append(info.filename)
            seen.add(info.filename)
        return names, problems

    def open(self, name: str) -> IO[bytes]:
        return self.archive.open(name)

    def close(self) -> None:
        self.archive.close()


def open_bundle(path: Path) -> _FolderReader | _ZipReader:
    if path.is_dir():
        return _FolderReader(path)
    if not path.is_file():
        raise BundleError(f"{path}: no such bundle (a folder or .zip file)")
    try:
        return _ZipReader(path)
    except (zipfile.BadZipFile, OSError) as exc:
        raise BundleError(f"{path}: not a readable zip file ({exc})",
                          [f"{path.name}: not a readable zip file"]) from None


# -- verification ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class StagedScan:
    """A verified scan of a bundle: its meta, its files by role (bundle paths) and its content hash."""

    meta: ScanMeta
    files: dict[str, str]
    content_hash: str


@dataclass
class VerifiedBundle:
    """What :func:`verify_bundle` found sound: the manifest, the scans, the taxonomy rows by code, bytes."""

    manifest: dict[str, Any]
    scans: list[StagedScan]
    taxonomy: dict[str, Any]
    bytes: int


def refuse(bundle: Path, problems: Sequence[str]) -> BundleError:
    count = f"{len(problems)} problem{'s' if len(problems) != 1 else ''}"
    return BundleError(f"{bundle}: refused ({count}, first: {problems[0]}); the database was not changed",
                       problems)


def verify_bundle(bundle: str | os.PathLike[str], staging: str | os.PathLike[str],
                  progress: Progress = iter) -> VerifiedBundle:
    """Copy every file of ``bundle`` into ``staging`` (an empty folder) and check it completely.

    Raises :class:`BundleError` listing every problem found: unsafe member names or links (nothing is
    extracted then), a missing or damaged manifest or checksum file, an unknown format or schema, files
    missing, unlisted, of the wrong size or SHA-256, scans that do not load or do not match their entry, a
    broken taxonomy.
    """
    bundle, staging = Path(bundle), Path(staging)
    reader = open_bundle(bundle)
    try:
        names, problems = reader.members()
        problems += nested_names(names)
        if problems:
            raise refuse(bundle, problems)
        present = set(names)
        if MANIFEST not in present:
            raise refuse(bundle, [f"{MANIFEST}: missing (not a texplorer bundle, or an incomplete one)"])
        manifest_bytes, unreadable = read_small(reader, MANIFEST)
        if unreadable:
            raise refuse(bundle, [unreadable])
        problems += check_manifest_sum(reader, present, manifest_bytes)
        manifest, manifest_problems = parse_manifest(manifest_bytes)
        problems += manifest_problems
        if manifest is None:
            raise refuse(bundle, problems)
        listed: dict[str, dict[str, Any]] = manifest["files"]
        problems += [f"{name}: not listed in the manifest" for name in sorted(present - set(listed))
                     if name not in (MANIFEST, MANIFEST_SUM)]
        problems += [f"{name}: missing" for name in sorted(set(listed) - present)]
        owned = {path for scan in manifest["scans"] for path in scan["files"].values()}
        problems += [f"{name}: belongs to no scan of the manifest" for name in sorted(listed)
                     if name.startswith("scans/") and name not in owned]
        staged_ok = {name for name in sorted((set(listed) - owned) & present)
                     if not stage_noting(reader, name, listed[name], staging, problems)}
        scans = []
        for entry in progress(manifest["scans"]):
            paths = [path for path in entry["files"].values() if path in present]
            failed = [path for path in paths if stage_noting(reader, path, listed[path], staging, problems)]
            if failed or len(paths) < len(entry["files"]):
                continue  # its problems are listed already
            checked = _validated_scan(entry, listed, staging)
            if isinstance(checked, str):
                problems.append(checked)
            else:
                scans.append(checked)
    finally:
        reader.close()
    taxonomy, taxonomy_problems = _check_taxonomy(staging, staged_ok)
    problems += taxonomy_problems
    problems += metadata_problems(staged_ok, manifest, lambda name: (staging / name).read_bytes(),
                                  {name: spec.unit for name, spec in CHANNELS.items()})
    if problems:
        raise refuse(bundle, problems)
    return VerifiedBundle(manifest, scans, taxonomy, sum(f["size"] for f in listed.values()))


def read_small(reader: _FolderReader | _ZipReader, name: str) -> tuple[bytes, str | None]:
    """Up to one byte more than :data:`MAX_MANIFEST_BYTES` of a member, or the reason it cannot be read."""
    try:
        with reader.open(name) as handle:
            return handle.read(MAX_MANIFEST_BYTES + 1), None
    except (zipfile.BadZipFile, zlib.error, OSError, EOFError, RuntimeError, NotImplementedError) as exc:
        return b"", f"{name}: cannot be read ({exc})"  # RuntimeError: encrypted; NotImplementedError: a compression


def check_manifest_sum(reader: _FolderReader | _ZipReader, present: set[str], manifest: bytes) -> list[str]:
    if MANIFEST_SUM not in present:
        return [f"{MANIFEST_SUM}: missing, so the manifest cannot be checked"]
    data, unreadable = read_small(reader, MANIFEST_SUM)
    if unreadable:
        return [unreadable]
    if data != manifest_sum(manifest):
        return [f"{MANIFEST}: does not match {MANIFEST_SUM} (changed or damaged)"]
    return []


def parse_manifest(data: bytes) -> tuple[dict[str, Any] | None, list[str]]:
    """The manifest if its format and schema are known and its structure is sound, and every problem found.

    Returns None for the manifest when nothing further can be checked with it.
    """
    if len(data) > MAX_MANIFEST_BYTES:
        return None, [f"{MANIFEST}: larger than {MAX_MANIFEST_BYTES} bytes"]
    try:
        manifest = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        return None, [f"{MANIFEST}: not valid JSON ({exc})"]
    if not isinstance(manifest, dict):
        return None, [f"{MANIFEST}: not a JSON object"]
    if manifest.get("format") != BUNDLE_FORMAT:
        return None, [f"{MANIFEST}: format {manifest.get('format')!r} is not {BUNDLE_FORMAT!r}"]
    problems = []
    if manifest.get("bundle_schema") != BUNDLE_SCHEMA:
        problems.append(f"{MANIFEST}: unknown bundle schema {manifest.get('bundle_schema')!r} "
                        f"(this software reads {BUNDLE_SCHEMA})")
    if manifest.get("scan_schema") != SCHEMA_VERSION:
        problems.append(f"{MANIFEST}: unknown scan schema {manifest.get('scan_schema')!r} "
                        f"(this software reads {SCHEMA_VERSION})")
    files = manifest.get("files")
    if not isinstance(files, dict):
        problems.append(f"{MANIFEST}: 'files' must be an object of path -> sha256 and size")
    else:
        problems += [p for name, entry in files.items() for p in _file_entry_problems(name, entry)]
        problems += [f"{MANIFEST}: {p}" for p in nested_names([n for n in files if isinstance(n, str)])]
        problems += [f"{MANIFEST}: does not list {name}" for name in REQUIRED_FILES if name not in files]
    scans = manifest.get("scans")
    if not isinstance(scans, list):
        problems.append(f"{MANIFEST}: 'scans' must be a list")
    else:
        listed = files if isinstance(files, dict) else {}
        problems += [p for scan in scans for p in _scan_entry_problems(scan, listed)]
        ids = [str(scan.get("scan_id")) for scan in scans if isinstance(scan, dict)]
        twice = sorted({i for i in ids if ids.count(i) > 1})
        problems += [f"{MANIFEST}: scan {i} is listed twice" for i in twice]
    counts = manifest.get("counts")
    if not isinstance(counts, dict):
        problems.append(f"{MANIFEST}: 'counts' must be an object")
    elif isinstance(scans, list) and counts.get("scans") != len(scans):
        problems.append(f"{MANIFEST}: counts.scans is {counts.get('scans')!r}, but {len(scans)} are listed")
    return (None if problems else manifest), problems


def _file_entry_problems(name: Any, entry: Any) -> list[str]:
    reason = unsafe_name(name)
    if reason:
        return [f"{MANIFEST}: file {name!r}: {reason}"]
    if name in (MANIFEST, MANIFEST_SUM):
        return [f"{MANIFEST}: lists itself or its checksum file"]
    sound = (isinstance(entry, dict) and isinstance(entry.get("sha256"), str)
             and _HEX64.fullmatch(entry["sha256"]) and type(entry.get("size")) is int and entry["size"] >= 0)
    if not sound:
        return [f"{MANIFEST}: file {name}: needs a lower-case hex sha256 and a size in bytes"]
    return []


def _scan_entry_problems(scan: Any, files: Mapping[str, Any]) -> list[str]:
    if not isinstance(scan, dict):
        return [f"{MANIFEST}: every entry of 'scans' must be an object"]
    where = f"{MANIFEST}: scan {scan.get('scan_id')!r}"
    wrong = [name for name, kind in _SCAN_FIELDS.items() if type(scan.get(name)) is not kind]
    if wrong:
        return [f"{where}: missing or mistyped {', '.join(wrong)}"]
    problems = []
    if set(scan["files"]) - {"mat", *IMAGES} or "mat" not in scan["files"]:
        problems.append(f"{where}: files must be 'mat' and photo variables ({', '.join(IMAGES)})")
    problems += [f"{where}: file {path!r} is not listed in 'files'" for path in scan["files"].values()
                 if path not in files]
    return problems


def _stage(reader: _FolderReader | _ZipReader, name: str, expected: Mapping[str, Any],
           staging: Path) -> str | None:
    """Copy one member into ``staging`` checking size and SHA-256 on the way; the problem, or None."""
    target = staging.joinpath(*name.split("/"))
    digest, size, limit = hashlib.sha256(), 0, expected["size"]
    try:
        target.parent.mkdir(parents=True, exist_ok=True)
        with reader.open(name) as source, open(target, "xb") as out:
            while block := source.read(_CHUNK):
                size += len(block)
                if size > limit:
                    return f"{name}: larger than the {limit} bytes the manifest says"
                digest.update(block)
                out.write(block)
            out.flush()
            os.fsync(out.fileno())
    except (zipfile.BadZipFile, zlib.error, EOFError, OSError, RuntimeError, NotImplementedError) as exc:
        return f"{name}: cannot be read ({exc})"  # RuntimeError: an encrypted member; NotImplementedError: a method
    if size != limit:
        return f"{name}: {size} bytes, the manifest says {limit}"
    if digest.hexdigest() != expected["sha256"]:
        return f"{name}: SHA-256 differs from the manifest (changed or damaged)"
    return None


def stage_noting(reader: _FolderReader | _ZipReader, name: str, expected: Mapping[str, Any], staging: Path,
                  problems: list[str]) -> bool:
    """Stage one member; True (and the problem appended to ``problems``) if it failed its checks."""
    problem = _stage(reader, name, expected, staging)
    if problem:
        problems.append(problem)
    return problem is not None


def _validated_scan(entry: dict[str, Any], files: Mapping[str, Any], staging: Path) -> StagedScan | str:
    """The validated scan of a manifest entry, or the problem with it."""
    mat_name = entry["files"]["mat"]
    mat = staging.joinpath(*mat_name.split("/"))
    try:
        scan = load_scan(mat)
    except ScanFormatError as exc:
        return f"{mat_name}: {str(exc).removeprefix(f'{mat}: ')}"
    meta = scan.meta
    folder = f"scans/{meta.label}/{meta.sample_id}"
    expected_files = {"mat": f"{folder}/{meta.scan_id}.mat",
                      **{var: f"{folder}/{photo_file_name(Path(mat_name), var)}" for var in scan.images}}
    if entry["files"] != expected_files:
        return f"{mat_name}: its files should be {', '.join(sorted(expected_files.values()))}"
    names = scipy.io.loadmat(mat, variable_names=list(IMAGES), simplify_cells=True)
    if any(names.get(var) != photo_file_name(mat, var) for var in scan.images):
        return f"{mat_name}: photo variables must name <scan id>_<disp|macro|illu>.png"
    stored = {"scan_id": meta.scan_id, "label": meta.label, "sample_id": meta.sample_id,
              "session_id": meta.session_id, "operator": meta.operator, "scan_index": meta.scan_index,
              "started": meta.started, "rigid": meta.rigid}
    differing = [key for key, value in stored.items() if entry[key] != value]
    if differing:
        return f"{mat_name}: manifest entry differs from the scan in {', '.join(differing)}"
    digest = _content_hash(entry["files"], files)
    if digest != entry["content_hash"]:
        return f"{mat_name}: content_hash in the manifest does not match its files"
    return StagedScan(meta, dict(entry["files"]), digest)


def _content_hash(roles: Mapping[str, str], files: Mapping[str, Any]) -> str:
    return content_hash(FileEntry(path, role, files[path]["sha256"], files[path]["size"])
                        for role, path in roles.items())


def _check_taxonomy(staging: Path, staged_ok: set[str]) -> tuple[dict[str, Any], list[str]]:
    if TAXONOMY_CSV not in staged_ok:
        return {}, []
    try:
        entries = read_table(staging / TAXONOMY_CSV)
        Taxonomy(entries)
    except TaxonomyError as exc:
        return {}, [f"{TAXONOMY_CSV}: {str(exc).replace(str(staging / TAXONOMY_CSV), TAXONOMY_CSV)}"]
    return {entry.code: entry for entry in entries}, []


# -- import ------------------------------------------------------------------------------------------

def import_bundle(db: Database, bundle: str | os.PathLike[str], progress: Progress = iter) -> ImportReport:
    """Verify ``bundle`` completely, then merge its scans into ``db`` (module docstring).

    Raises
    ------
    BundleError
        The bundle is damaged, incomplete, unsafe or of an unknown format or schema; ``problems`` lists
        every reason and the database is unchanged.
    """
    started = time.perf_counter()
    bundle = Path(bundle)
    with owned_folder(temp_path_for(db.root / STAGING_PREFIX.lstrip("."))) as owned:
        staging = owned / "bundle"
        verified = verify_bundle(bundle, staging, progress)
        report = ImportReport(bundle, bytes=verified.bytes)
        new, codes = _taxonomy_codes(db, verified, _plan(db, verified, report), report)
        previous = db.taxonomy_path.read_bytes() if db.taxonomy_path.is_file() else None
        if codes:
            _extend_taxonomy(db, codes)
            report.taxonomy_added = [entry.code for entry in codes]
        try:
            db.add_written([(scan.meta, _staged_paths(staging, scan)) for scan in new])
        except BaseException:
            if codes:  # the scans were refused: so are the codes they brought
                _restore(db.taxonomy_path, previous)
            raise
        report.added = [scan.meta.scan_id for scan in new]
    report.seconds = time.perf_counter() - started
    return report


def _restore(path: Path, data: bytes | None) -> None:
    if data is None:
        path.unlink(missing_ok=True)
    else:
        atomic_write_bytes(path, data)


def _staged_paths(staging: Path, scan: StagedScan) -> dict[str, Path]:
    return {role: staging.joinpath(*name.split("/")) for role, name in scan.files.items()}


def _plan(db: Database, verified: VerifiedBundle, report: ImportReport) -> list[StagedScan]:
    """New scans to add; identical ones and conflicts go to ``report``."""
    local = {record.scan_id: record for record in db.records()}
    samples = {record.sample_id: record.label for record in local.values()}
    new = []
    for scan in verified.scans:
        meta = scan.meta
        if meta.scan_id in local:
            if local[meta.scan_id].content_hash == scan.content_hash:
                report.identical.append(meta.scan_id)
            else:
                report.conflicts.append(f"{meta.scan_id}: stored here with other content; not overwritten")
        elif samples.get(meta.sample_id, meta.label) != meta.label:
            report.conflicts.append(f"{meta.scan_id}: sample {meta.sample_id} is {samples[meta.sample_id]} "
                                    f"here, {meta.label} in the bundle; not imported")
        else:
            samples[meta.sample_id] = meta.label
            new.append(scan)
    return new


def _same_name(a: str, b: str) -> bool:
    return " ".join(a.split()).casefold() == " ".join(b.split()).casefold()


def _taxonomy_codes(db: Database, verified: VerifiedBundle, new: list[StagedScan],
                    report: ImportReport) -> tuple[list[StagedScan], list]:
    """The scans to add and the taxonomy rows their labels need that this database lacks.

    A scan whose label uses a code this database names differently from the bundle is a conflict (the
    same code would mean two materials) and is left out. Labels neither taxonomy knows are imported and
    listed in ``report.unknown_labels``.
    """
    local = {entry.code: entry for entry in db.taxonomy().entries()}
    kept, needed = [], {}
    for scan in new:
        label = scan.meta.label
        codes = Label.parse(label).codes()
        renamed = [code for code in codes if code in local and code in verified.taxonomy
                   and not _same_name(local[code].name, verified.taxonomy[code].name)]
        if renamed:
            code = renamed[0]
            report.conflicts.append(f"{scan.meta.scan_id}: label {label}: {code} is {local[code].name!r} "
                                    f"here but {verified.taxonomy[code].name!r} in the bundle; not imported")
            continue
        kept.append(scan)
        missing = [code for code in codes if code not in local]
        if any(code not in verified.taxonomy for code in missing):
            if label not in report.unknown_labels:
                report.unknown_labels.append(label)
        else:
            needed.update({code: verified.taxonomy[code] for code in missing})
    return kept, list(needed.values())


def _extend_taxonomy(db: Database, entries: list) -> None:
    """Append rows to ``<db>/taxonomy.csv`` (atomically), after checking the merged table is consistent."""
    path = db.taxonomy_path
    existing = list(read_table(path)) if path.is_file() else []
    Taxonomy([*db.taxonomy().entries(), *entries])  # raises TaxonomyError before anything is written
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(HEADER)
    writer.writerows((e.kind, e.code, e.name, e.description) for e in [*existing, *entries])
    atomic_write_bytes(path, buffer.getvalue().encode("utf-8"))
