"""Export bundles of a recording set (``texplorer export OUT --set NAME``) and their import (docs/export.md).

Another lab's recordings go out as they came in: the set's recording files byte for byte, the mapping it was
ingested with, its feature table when it was computed from these recordings by this feature code, and the
same standard metadata as a bundle of scans (:mod:`scanner.storage.metadata`), with the roles, units and
rates of every channel::

    README.md                       what the bundle holds and how to load it without texplorer
    manifest.json, manifest.json.sha256
    recordings/<set>/<recording>.mat
    mapping.toml                    the mapping the set was ingested with (when the set kept it)
    features.csv, features.json     the set's feature table and the options it was written with (when current)
    recordings.csv                  one row per recording: name, label, groups, file
    channels/<role>_channels.tsv    + .json: every channel by role, its units and rate
    ro-crate-metadata.json, croissant.json, datapackage.json, schemas/*.schema.json

Import verifies every checksum, the manifest and every recording (each must read as a recording) before the
set is stored (:class:`scanner.storage.ingest.SetWriter`: complete or absent, an existing set refused).
"""

from __future__ import annotations

import io
import json
import os
import shutil
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path
from typing import Any

from scanner.scan import Recording
from scanner.storage.bundle import (
    BUNDLE_FORMAT,
    BUNDLE_SCHEMA,
    MANIFEST,
    MANIFEST_SUM,
    MAX_MANIFEST_BYTES,
    README,
    BundleError,
    Progress,
    bundle_writer,
    check_manifest_sum,
    checksum,
    export_target,
    finish_bundle,
    nested_names,
    open_bundle,
    read_small,
    refuse,
    stage_noting,
)
from scanner.storage.database import STAGING_PREFIX
from scanner.storage.files import owned_folder, temp_path_for
from scanner.storage.ingest import MAPPING, RECORDINGS, IngestError, SetWriter, read_recording, set_folder
from scanner.storage.metadata import (
    CROISSANT,
    DATAPACKAGE,
    RECORDINGS_CSV,
    RO_CRATE,
    Provenance,
    Table,
    as_bytes,
    croissant,
    croissant_file_sets,
    csv_header,
    describe_tables,
    features_schema,
    metadata_problems,
    recording_channels,
    recordings_schema,
    recordings_table,
    ro_crate,
)
from scanner.version import __version__

KIND = "recordings"
"""``manifest.json``'s ``kind`` of a recording-set bundle (a bundle of scans has none)."""

FEATURES_CSV, FEATURES_JSON = "features.csv", "features.json"
_FOLDER = "recordings"


@dataclass(frozen=True)
class SetExportReport:
    """What :func:`export_set` wrote."""

    path: Path
    recordings: int
    files: int
    bytes: int
    seconds: float
    features: bool
    mapping: bool


def export_set(db_root: str | os.PathLike[str], name: str, out: str | os.PathLike[str], *, license: str | None,
               creator: str | None = None, features: Path | None = None, feature_units: Mapping[str, str] | None = None,
               progress: Progress = iter) -> SetExportReport:
    """Write the recording set ``name`` of the database at ``db_root`` as a bundle at ``out`` (a folder, or a
    ``.zip`` file), built under a temporary name and renamed when complete.

    ``features`` is the set's feature table to include (the caller checks that it was computed from these
    recordings by the current feature code; its ``features.json`` goes along), or None.

    Raises
    ------
    BundleError
        ``out`` exists, no license was given, or the set does not exist or holds no recordings.
    MetadataError
        A license or creator that cannot be written.
    """
    started = time.perf_counter()
    out, license, creator = export_target(out, license, creator)
    try:
        folder = set_folder(db_root, name)
    except IngestError as exc:
        raise BundleError(str(exc)) from None
    paths = sorted(folder.glob("*.mat")) if folder.is_dir() else []
    if not paths:
        raise BundleError(f"{db_root}: no recording set {name!r} to export (see 'texplorer ingest')")
    created = datetime.now(UTC).replace(microsecond=0)
    provenance = Provenance(license, creator, created, __version__, "", f"texplorer recording set {name}")
    writer = bundle_writer(out, created)
    try:
        files: dict[str, dict[str, Any]] = {}
        entries, channels_of = [], []
        for path in progress(paths):
            recording = read_recording(path)
            member = f"{_FOLDER}/{name}/{path.name}"
            with open(path, "rb") as source:
                files[member] = writer.add(member, source, path.stat().st_size)
            entries.append(_entry(recording, member))
            channels_of.append(_shape_only(recording))
        extra = {MAPPING: folder / MAPPING} if (folder / MAPPING).is_file() else {}
        if features is not None:
            extra |= {FEATURES_CSV: features, FEATURES_JSON: features.with_name(FEATURES_JSON)}
        for member, path in extra.items():
            if path.is_file():
                files[member] = writer.add(member, io.BytesIO(path.read_bytes()))
        generated = _set_files(name, channels_of, entries, files, feature_units or {}, provenance, extra)
        for member, data in generated.items():
            files[member] = writer.add(member, io.BytesIO(data))
        crate = ro_crate(files, provenance, [], f"Recordings of the set {name}, ingested from another lab's files "
                         "with mapping.toml, as MATLAB v5 files with their channel roles; see README.md",
                         {README: "what the bundle holds and how to load it", MAPPING: "the ingest mapping: which "
                          "files form a recording, which channel plays which role", RECORDINGS_CSV: "one row per "
                          "recording", CROISSANT: "Croissant 1.1 description", DATAPACKAGE: "Frictionless Data "
                          "Package of the CSV tables"})
        files[RO_CRATE] = writer.add(RO_CRATE, io.BytesIO(as_bytes(crate)))
        manifest = {"format": BUNDLE_FORMAT, "bundle_schema": BUNDLE_SCHEMA, "kind": KIND, "set": name,
                    "software_version": __version__, "created": created.isoformat(), "license": license,
                    "creator": creator, "counts": {"recordings": len(entries), "files": len(files),
                                                   "bytes": sum(f["size"] for f in files.values())},
                    "recordings": entries, "files": dict(sorted(files.items()))}
        size = finish_bundle(writer, files, manifest)
    except BaseException:
        writer.discard()
        raise
    return SetExportReport(out, len(entries), len(files) + 2, size, time.perf_counter() - started,
                           FEATURES_CSV in files, MAPPING in files)


def _entry(recording: Recording, member: str) -> dict[str, Any]:
    return {"name": recording.name, "label": recording.label or "", "group": dict(recording.group),
            "roles": dict(recording.roles), "file": member}


def _shape_only(recording: Recording) -> Recording:
    """The recording without its samples' memory (one row per channel is enough to describe it)."""
    channels = {name: type(trace)(trace.data[:1], trace.fs, trace.unit) for name, trace in recording.channels.items()}
    return Recording(recording.name, channels, {r: c for r, c in recording.roles.items() if c in channels},
                     recording.label, recording.group)


def _set_files(name: str, recordings: Sequence[Recording], entries: Sequence[Mapping[str, Any]],
               files: Mapping[str, Mapping[str, Any]], feature_units: Mapping[str, str], provenance: Provenance,
               extra: Mapping[str, Path]) -> dict[str, bytes]:
    """README, recordings.csv, channel tables, schemas, Data Package and Croissant of a set bundle."""
    listing, groups = recordings_table(recordings, {e["name"]: e["file"] for e in entries})
    tables = [(Table("recordings", RECORDINGS_CSV, recordings_schema(groups),
                     "one row per recording: its name, label, groups and MATLAB file"), listing)]
    if FEATURES_CSV in files:
        data = extra[FEATURES_CSV].read_bytes()
        header = csv_header(data)
        tables.append((Table("features", FEATURES_CSV, features_schema(header, feature_units, None),
                             "the set's feature table (texplorer features set:NAME; options in features.json)"),
                       data))
    out = {README: _readme(name, len(recordings), FEATURES_CSV in files, MAPPING in files).encode("utf-8"),
           RECORDINGS_CSV: listing, **describe_tables(tables, recording_channels(recordings), provenance)}
    checksums = {**files, **{member: checksum(data) for member, data in out.items()}}
    file_sets = croissant_file_sets([], f"{_FOLDER}/{name}/*.mat", "one MATLAB v5 file per recording: one "
                                    "variable per channel (channels record set) and a meta struct")
    out[CROISSANT] = as_bytes(croissant([table for table, _ in tables], checksums, provenance, file_sets))
    return out


def _readme(name: str, count: int, features: bool, mapping: bool) -> str:
    lines = [
        f"# texplorer recording set {name}", "",
        f"{count} recordings another lab's sensors made, as texplorer ingested them: one MATLAB v5 file each in "
        f"`recordings/{name}/`, one variable per channel and a `meta` struct (`fs` and `units` per channel, "
        "`roles`, `label`, `group`).", "",
        "| file | content |", "| --- | --- |",
        f"| `recordings/{name}/<recording>.mat` | one recording |",
        "| `recordings.csv` | one row per recording: name, label, groups, file |",
        "| `channels/<role>_channels.tsv` (+ `.json`) | every channel by role: units, sampling frequency, variable |",
    ]
    if mapping:
        lines.append("| `mapping.toml` | the mapping the files were ingested with |")
    if features:
        lines.append("| `features.csv`, `features.json` | the feature table and the options it was written with |")
    lines += [
        "| `ro-crate-metadata.json`, `croissant.json`, `datapackage.json`, `schemas/` | RO-Crate 1.2, Croissant "
        "1.1 and Frictionless descriptions |",
        "| `manifest.json`, `manifest.json.sha256` | SHA-256 and size of every file |", "",
        "MATLAB or Octave: `r = load('recordings/NAME/REC.mat'); r.meta.fs`; Python: "
        "`scipy.io.loadmat(path, simplify_cells=True)`. `texplorer import` stores the set in a database.", ""]
    return "\n".join(lines)


# -- import ------------------------------------------------------------------------------------------

def bundle_kind(bundle: str | os.PathLike[str]) -> str:
    """``"recordings"`` for a recording-set bundle, ``"scans"`` for anything else (which the scan import
    then checks in full)."""
    try:
        reader = open_bundle(Path(bundle))
    except BundleError:
        return "scans"
    try:
        names, _ = reader.members()
        if MANIFEST not in names:
            return "scans"
        data, problem = read_small(reader, MANIFEST)
    finally:
        reader.close()
    try:
        manifest = json.loads(data.decode("utf-8")) if not problem else {}
    except (UnicodeDecodeError, ValueError):
        return "scans"
    return KIND if isinstance(manifest, dict) and manifest.get("kind") == KIND else "scans"


@dataclass(frozen=True)
class SetImportReport:
    """What :func:`import_set_bundle` stored."""

    bundle: Path
    name: str
    folder: Path
    recordings: int
    bytes: int
    seconds: float


def import_set_bundle(db_root: str | os.PathLike[str], bundle: str | os.PathLike[str], *, name: str | None = None,
                      replace: bool = False, progress: Progress = iter) -> SetImportReport:
    """Verify a recording-set bundle completely, then store it as the set ``name`` (default: the bundle's).

    Raises
    ------
    BundleError
        Every problem found (unsafe names, the manifest or a file damaged, a recording that does not read,
        metadata that disagree with the files); or the set exists and ``replace`` is not given. Nothing is
        stored then.
    """
    started = time.perf_counter()
    bundle, root = Path(bundle), Path(db_root)
    made = [path for path in (root, root / RECORDINGS) if not path.exists()]  # removed again if refused
    try:
        if name is not None:
            _check_target(bundle, root, name, replace)  # before a large bundle is read
        root.mkdir(parents=True, exist_ok=True)
        # On the database's file system, so the verified files are moved into the set, not copied; a killed
        # import leaves a folder 'texplorer db check' lists and --repair removes (as a scan import's).
        with owned_folder(temp_path_for(root / STAGING_PREFIX.lstrip("."))) as owned:
            manifest, staged = _verify(bundle, owned / "bundle", progress)
            target = name or manifest["set"]
            _check_target(bundle, root, target, replace)
            try:
                with SetWriter(root, target, replace=replace) as writer:
                    for kept in (MAPPING, FEATURES_CSV, FEATURES_JSON):  # the feature table: current if the
                        if (owned / "bundle" / kept).is_file():        # bytes are (features.json has their hash)
                            writer.keep(kept, (owned / "bundle" / kept).read_bytes())
                    for path in staged:
                        writer.adopt(path)
                    folder = writer.commit()
            except IngestError as exc:
                raise BundleError(f"{bundle}: {exc}; the database was not changed") from None
    except BaseException:
        for path in reversed(made):
            shutil.rmtree(path, ignore_errors=True)
        raise
    return SetImportReport(bundle, target, folder, len(staged),
                           sum(f["size"] for f in manifest["files"].values()), time.perf_counter() - started)


def _check_target(bundle: Path, root: Path, name: str, replace: bool) -> None:
    """Refuse a set name that cannot be stored, or an existing set without ``replace``."""
    try:
        folder = set_folder(root, name)
    except IngestError as exc:
        raise BundleError(f"{bundle}: {exc}; the database was not changed") from None
    if folder.exists() and not replace:
        raise BundleError(f"{bundle}: the set {name!r} exists in {root}; give --name for another name or "
                          "--replace to replace it; the database was not changed")


def _verify(bundle: Path, staging: Path, progress: Progress) -> tuple[dict[str, Any], list[Path]]:
    """The manifest and the staged recording files of a set bundle, or BundleError with every problem."""
    staging.mkdir()
    reader = open_bundle(bundle)
    try:
        names, problems = reader.members()
        problems += nested_names(names)
        if problems:
            raise refuse(bundle, problems)
        present = set(names)
        data, problem = read_small(reader, MANIFEST)
        if problem or len(data) > MAX_MANIFEST_BYTES:
            raise refuse(bundle, [problem or f"{MANIFEST}: larger than {MAX_MANIFEST_BYTES} bytes"])
        problems += check_manifest_sum(reader, present, data)
        manifest, manifest_problems = _parse(data)
        problems += manifest_problems
        if manifest is None:
            raise refuse(bundle, problems)
        listed = manifest["files"]
        unlisted = present - set(listed) - {MANIFEST, MANIFEST_SUM}
        problems += [f"{n}: not listed in the manifest" for n in sorted(unlisted)]
        problems += [f"{n}: missing" for n in sorted(set(listed) - present)]
        ok = {n for n in sorted(set(listed) & present) if not stage_noting(reader, n, listed[n], staging, problems)}
    finally:
        reader.close()
    staged: list[Path] = []
    units: dict[str, set[str]] = {}
    prefix = f"{_FOLDER}/{manifest['set']}/"
    owned: set[str] = set()
    for entry in progress(manifest["recordings"]):
        member = entry.get("file") if isinstance(entry, dict) else None
        if not isinstance(member, str) or not member.startswith(prefix) or member.count("/") != 2:
            problems.append(f"{MANIFEST}: recording entry {str(entry)[:200]} does not name a file of "
                            f"recordings/{manifest['set']}/")
            continue
        if member in owned:
            problems.append(f"{MANIFEST}: {member} is named by two recording entries")
            continue
        owned.add(member)
        if member not in listed:
            problems.append(f"{MANIFEST}: recording file {member} is not in its 'files'")
            continue
        if member not in ok:
            continue  # its problem is listed already
        try:
            recording = read_recording(staging / member)
        except IngestError as exc:
            problems.append(f"{member}: {str(exc).replace(str(staging / member), member)}")
            continue
        for channel, trace in recording.channels.items():
            units.setdefault(channel, set()).add(trace.unit)
        staged.append(staging / member)
    problems += [f"{name}: belongs to no recording of the manifest" for name in sorted(listed)
                 if name.startswith(f"{_FOLDER}/") and name not in owned]
    problems += _options_problems(staging, ok)
    problems += metadata_problems(ok - owned, manifest, lambda n: (staging / n).read_bytes(),
                                  {channel: "/".join(sorted(found)) for channel, found in units.items()},
                                  holder="recordings")
    if problems:
        raise refuse(bundle, problems)
    return manifest, staged


def _options_problems(staging: Path, ok: set[str]) -> list[str]:
    """``features.json`` must be the JSON object ``texplorer features set:NAME`` writes."""
    if FEATURES_JSON not in ok:
        return []
    try:
        options = json.loads((staging / FEATURES_JSON).read_bytes().decode("utf-8"))
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        return [f"{FEATURES_JSON}: not valid JSON ({str(exc)[:200]})"]
    return [] if isinstance(options, dict) else [f"{FEATURES_JSON}: not the options of a feature table"]


def _parse(data: bytes) -> tuple[dict[str, Any] | None, list[str]]:
    try:
        manifest = json.loads(data.decode("utf-8"))
    except (UnicodeDecodeError, ValueError) as exc:
        return None, [f"{MANIFEST}: not valid JSON ({exc})"]
    if not isinstance(manifest, dict) or manifest.get("format") != BUNDLE_FORMAT or manifest.get("kind") != KIND:
        return None, [f"{MANIFEST}: not a texplorer recording-set bundle"]
    if manifest.get("bundle_schema") != BUNDLE_SCHEMA:
        return None, [f"{MANIFEST}: unknown bundle schema {manifest.get('bundle_schema')!r} "
                      f"(this software reads {BUNDLE_SCHEMA})"]
    files, recordings, name = manifest.get("files"), manifest.get("recordings"), manifest.get("set")
    problems = []
    if not isinstance(name, str):
        problems.append(f"{MANIFEST}: 'set' must be the set's name")
    if not isinstance(files, dict) or not all(isinstance(e, dict) and isinstance(e.get("sha256"), str)
                                              and isinstance(e.get("size"), int) and e["size"] >= 0
                                              for e in files.values()):
        problems.append(f"{MANIFEST}: 'files' must be an object of path -> sha256 and size")
    counts = manifest.get("counts")
    if not isinstance(recordings, list) or not recordings:
        problems.append(f"{MANIFEST}: 'recordings' must be a non-empty list")
    elif not isinstance(counts, dict):
        problems.append(f"{MANIFEST}: 'counts' must be an object")
    elif counts.get("recordings") != len(recordings):
        problems.append(f"{MANIFEST}: counts.recordings is {str(counts.get('recordings'))[:40]}, but "
                        f"{len(recordings)} are listed")
    return (None if problems else manifest), problems
