"""Standard metadata of an export bundle, which other labs' tools read without texplorer (docs/export.md).

Beside the project's own ``manifest.json`` a bundle describes itself four ways:

=============================  ===================================================================
``ro-crate-metadata.json``     RO-Crate 1.2: the bundle as a dataset; every file with its encoding format, size and
                               SHA-256; the scanner and its units as instruments; one ``CreateAction`` per
                               session (operator ids as given, the units used, the files made); license and creator
``croissant.json``             Croissant 1.1 (MLCommons): record sets of the scans, features, taxonomy,
                               channels and photos, with typed fields, for machine-learning loaders
``datapackage.json``,          Frictionless Data Package and Table Schemas of ``scans.csv``, ``features.csv``
``schemas/*.schema.json``      and ``taxonomy.csv``: types, units, the scan id as primary key, the label codes as
                               foreign keys into the taxonomy
``channels/*_channels.tsv``    one BIDS-style channel table per modality (name, type, units, sampling frequency,
                               device), with a JSON sidecar describing the columns and units
=============================  ===================================================================

Everything here is a pure function of what the bundle holds (records, file sizes and checksums, the feature
table's header): the writers in :mod:`scanner.storage.bundle` put the bytes in place, and
:func:`metadata_problems` checks on import that the descriptions agree with the files.
"""

from __future__ import annotations

import csv
import io
import json
import math
import re
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Any

import numpy as np

from scanner.scan import CHANNELS, IMAGES, Recording
from scanner.storage.database import ScanRecord
from taxonomy.errors import TexplorerError
from taxonomy.labels import Label
from taxonomy.table import HEADER

RO_CRATE = "ro-crate-metadata.json"
CROISSANT = "croissant.json"
DATAPACKAGE = "datapackage.json"
SCANS_CSV = "scans.csv"
RECORDINGS_CSV = "recordings.csv"
SCHEMAS = "schemas"
CHANNELS_FOLDER = "channels"
RO_CRATE_VERSION = "https://w3id.org/ro/crate/1.2"
RO_CRATE_CONTEXT = "https://w3id.org/ro/crate/1.2/context"
CROISSANT_VERSION = "http://mlcommons.org/croissant/1.1"
NO_LICENSE = "none"
"""``--license none``: export without a license, said so in the metadata."""

ENCODINGS = {".mat": "application/x-matlab-data", ".png": "image/png", ".jpg": "image/jpeg",
             ".jpeg": "image/jpeg", ".csv": "text/csv", ".tsv": "text/tab-separated-values",
             ".json": "application/json", ".md": "text/markdown", ".m": "text/x-matlab",
             ".py": "text/x-python", ".sha256": "text/plain", ".toml": "application/toml"}
"""Encoding format (IANA media type) of a bundle file by its suffix; anything else is a byte stream."""

_SPDX = re.compile(r"[A-Za-z0-9][A-Za-z0-9.+-]{0,63}")
_URL = re.compile(r"https?://[^\s\"<>]{1,500}")


class MetadataError(TexplorerError, ValueError):
    """A license or creator that cannot be written into a bundle's metadata."""


# -- provenance --------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Provenance:
    """Who made the bundle, under which license, with which software: the parts of the metadata that do
    not come from the files.

    ``license`` is an SPDX identifier (``CC-BY-4.0``), a license URL, or None for ``--license none``;
    ``creator`` a person's or lab's name, or an ORCID or other URL, or None.
    """

    license: str | None
    creator: str | None
    created: datetime
    software_version: str
    feature_code_version: str
    title: str = "texplorer scans"


def license_url(text: str | None) -> str | None:
    """The URL of a license given as an SPDX identifier or a URL; None for ``none``.

    Raises
    ------
    MetadataError
        Neither an SPDX identifier (letters, digits, ``.``, ``+``, ``-``) nor an http(s) URL.
    """
    text = (text or "").strip()
    if text.lower() == NO_LICENSE:
        return None
    if _URL.fullmatch(text):
        return text
    if _SPDX.fullmatch(text):
        return f"https://spdx.org/licenses/{text}"
    raise MetadataError(f"license {text!r} is neither an SPDX identifier (e.g. CC-BY-4.0) nor an http(s) URL; "
                        "give --license none to export without one")


def checked_creator(text: str | None) -> str | None:
    """``text`` stripped, or None if empty; a creator is one line of at most 200 printable characters."""
    text = (text or "").strip()
    if not text:
        return None
    if len(text) > 200 or any(ord(c) < 32 or ord(c) == 127 for c in text):
        raise MetadataError("creator must be one line of at most 200 printable characters")
    return text


# -- tables ------------------------------------------------------------------------------------------

SCAN_COLUMNS = ("scan_id", "sample_id", "label", "class_code", "subclass_code", "material_code", "process_code",
                "extra_code", "session_id", "operator", "scan_index", "started", "rigid", "content_hash",
                "mat_file", *(f"photo_{short}" for short in IMAGES.values()))
"""Columns of ``scans.csv``: one row per scan, its label's five taxonomy codes and its files."""


def _csv(rows: Iterable[Sequence[Any]], delimiter: str = ",") -> bytes:
    buffer = io.StringIO()
    writer = csv.writer(buffer, delimiter=delimiter, lineterminator="\n")
    writer.writerows(rows)
    return buffer.getvalue().encode("utf-8")


def scans_table(records: Sequence[ScanRecord], files: Mapping[str, Mapping[str, str]]) -> bytes:
    """``scans.csv``: :data:`SCAN_COLUMNS` for each record; ``files[scan_id]`` maps roles to bundle paths."""
    rows: list[Sequence[Any]] = [SCAN_COLUMNS]
    for record in records:
        roles = files[record.scan_id]
        rows.append([record.scan_id, record.sample_id, record.label, *Label.parse(record.label).codes(),
                     record.session_id, record.operator, record.scan_index, record.started,
                     "true" if record.rigid else "false", record.content_hash, roles.get("mat", ""),
                     *(roles.get(variable, "") for variable in IMAGES)])
    return _csv(rows)


RECORDING_COLUMNS = ("recording", "label", "mat_file")


def recordings_table(recordings: Sequence[Recording], files: Mapping[str, str]) -> tuple[bytes, list[str]]:
    """``recordings.csv`` of a recording set: name, label, ``group:<key>`` columns and the file; returns the
    bytes and the group keys."""
    groups = sorted({key for recording in recordings for key in recording.group})
    rows: list[Sequence[Any]] = [[*RECORDING_COLUMNS[:2], *(f"group:{g}" for g in groups), "mat_file"]]
    for recording in recordings:
        rows.append([recording.name, recording.label or "", *(recording.group.get(g, "") for g in groups),
                     files[recording.name]])
    return _csv(rows), groups


# -- channel tables ------------------------------------------------------------------------------------

@dataclass(frozen=True)
class ChannelRow:
    """One row of a BIDS-style ``channels.tsv``: a channel (or one axis of it) of a ``.mat`` variable."""

    modality: str
    name: str
    variable: str
    column: int
    """1-based column of the variable holding this channel; 0 for a one-column variable."""
    type: str
    """BIDS channel type: ``ACCEL``, ``AUDIO``, ``MAGN``, ``TEMP``, ``MISC``."""
    units: str
    sampling_frequency: float
    device: str
    description: str


SCAN_SOURCES: Mapping[str, tuple[str, str, str]] = {
    "v_ft": ("vibration", "ACCEL", "TU1 ADXL335 accelerometer on NI USB-6002 ai0-ai2"),
    "v_fs": ("vibration", "ACCEL", "TU1 ADXL335 accelerometer on NI USB-6002 ai0-ai2"),
    "v_tt": ("vibration", "ACCEL", "TU1 ADXL335 accelerometer on NI USB-6002 ai0-ai2"),
    "v_ts": ("vibration", "ACCEL", "TU1 ADXL335 accelerometer on NI USB-6002 ai0-ai2"),
    "a_fs": ("audio", "AUDIO", "TU1 microphone"),
    "a_ts": ("audio", "AUDIO", "TU1 microphone"),
    "r_fs": ("reflectance", "MISC", "TU1 IR reflectance sensor on NI USB-6002 ai3"),
    "r_ts": ("reflectance", "MISC", "TU1 IR reflectance sensor on NI USB-6002 ai3"),
    "f_frn": ("force", "MISC", "TU2 force sensor (normal) on NI USB-6002 ai4"),
    "f_frt": ("force", "MISC", "TU2 force sensor (tangential) on NI USB-6002 ai5"),
    "f_press": ("force", "MISC", "TU2 force sensor (normal) on NI USB-6002 ai4"),
    "f_fold": ("force", "MISC", "TU2 force sensor (normal) on NI USB-6002 ai4"),
    "alpha_f": ("flex", "MISC", "TU2 flex sensor on NI USB-6002 ai6"),
    "t_cool": ("thermal", "TEMP", "TU2 MLX90614 infrared thermometer on the sensor board"),
    "m": ("metal", "MISC", "TU2 metal electrode on NI USB-6002 ai7"),
    "dB": ("magnetic", "MAGN", "TU2 MAG3110 magnetometer on the sensor board"),
}
"""Scan channel -> (modality, BIDS channel type, device that records it) (docs/devices.md)."""

UNITS: Mapping[str, str] = {
    "g": "standard gravity, 9.80665 m/s^2", "FS": "full scale of the sound card, -1 to 1", "V": "volt",
    "N": "newton", "deg": "degree of angle", "degC": "degree Celsius", "uT": "microtesla",
    "-": "dimensionless: +1 conductive, -1 not", "1": "dimensionless",
}
"""The units a bundle's channel tables and feature schema use (as the ``.mat`` files store them)."""

_AXES = "xyz"


def scan_channels() -> list[ChannelRow]:
    """The channel table rows of the scanner's channels (every scan holds these, docs/database.md)."""
    rows = []
    for name, spec in CHANNELS.items():
        modality, kind, device = SCAN_SOURCES[name]
        columns = [(f"{name}_{_AXES[i]}", i + 1) for i in range(spec.axes)] if spec.axes else [(name, 0)]
        rows += [ChannelRow(modality, channel, name, column, kind, spec.unit, spec.fs, device,
                            f"{spec.description} (step {spec.step})") for channel, column in columns]
    return rows


_ROLE_TYPES = {"vibration": "ACCEL", "audio": "AUDIO", "temperature": "TEMP"}


def recording_channels(recordings: Sequence[Recording]) -> list[ChannelRow]:
    """The channel table rows of a recording set: one per channel column and role, its unit, and its rate
    when every recording has the same (``n/a`` in the table otherwise, the range in the description)."""
    seen: dict[tuple[str, str], dict[str, Any]] = {}
    for recording in recordings:
        roles = {channel: role for role, channel in recording.roles.items()}
        for name, trace in recording.channels.items():
            key = roles.get(name, "unmapped")
            role = "signal" if key.startswith("signal_") else key
            entry = seen.setdefault((role, name), {"units": set(), "fs": set(), "key": key,
                                                   "columns": trace.data.shape[1] if trace.data.ndim == 2 else 0})
            entry["units"].add(trace.unit)
            entry["fs"].add(float(f"{trace.fs:.9g}"))  # rates computed from timestamps differ in the last bits
    rows = []
    for (role, name), entry in sorted(seen.items()):
        fs, spread = _common_rate(sorted(entry["fs"]))
        units = "/".join(sorted(entry["units"]))
        kind = _ROLE_TYPES.get(role, "MISC")
        description = f"role {entry['key']}{spread}"
        count = entry["columns"]
        columns = [(f"{name}_{i + 1}", i + 1) for i in range(count)] if count else [(name, 0)]
        rows += [ChannelRow(role, channel, name, column, kind, units, fs, "", description)
                 for channel, column in columns]
    return rows


RATE_SPREAD = 0.01
"""Rates of one channel across a set's recordings within this fraction of their median are one rate (clocks
fitted per recording differ in the last digits); wider, the table says ``n/a`` and gives the range."""


def _common_rate(rates: Sequence[float]) -> tuple[float, str]:
    """The one rate of a channel across recordings (the median, when they agree within :data:`RATE_SPREAD`)
    or NaN, and a note of their range when they are not all equal."""
    if len(rates) == 1:
        return rates[0], ""
    median = float(np.median(rates))
    note = f"; {len(rates)} rates across recordings, {rates[0]:.6g} to {rates[-1]:.6g} Hz"
    return (median if rates[-1] - rates[0] <= RATE_SPREAD * median else math.nan), note


CHANNEL_COLUMNS = ("name", "type", "units", "sampling_frequency", "device", "variable", "column", "description")


def channel_tables(rows: Sequence[ChannelRow]) -> dict[str, bytes]:
    """``channels/<modality>_channels.tsv`` and its ``.json`` sidecar, for each modality of ``rows``."""
    tables: dict[str, bytes] = {}
    for modality in sorted({row.modality for row in rows}):
        mine = [row for row in rows if row.modality == modality]
        lines: list[Sequence[Any]] = [CHANNEL_COLUMNS]
        lines += [[row.name, row.type, row.units, _rate(row.sampling_frequency), row.device or "n/a",
                   row.variable, row.column or "n/a", row.description] for row in mine]
        stem = f"{CHANNELS_FOLDER}/{modality}_channels"
        tables[f"{stem}.tsv"] = _csv(lines, "\t")
        tables[f"{stem}.json"] = as_bytes(_channel_sidecar(mine))
    return tables


def _rate(fs: float) -> str:
    return "n/a" if math.isnan(fs) else f"{fs:g}"


def _channel_sidecar(rows: Sequence[ChannelRow]) -> dict[str, Any]:
    units = sorted({unit for row in rows for unit in row.units.split("/")})
    return {
        "device": {"Description": "the sensor and the input that records the channel"},
        "variable": {"Description": "the .mat variable that holds the channel"},
        "column": {"Description": "1-based column of that variable (one column per axis); n/a for a 1-D variable"},
        "units": {"Description": "unit of the stored samples",
                  "Levels": {unit: UNITS.get(unit, "as the source recorded it") for unit in units}},
    }


# -- Frictionless table schemas ---------------------------------------------------------------------

def _field(name: str, kind: str, description: str = "", **extra: Any) -> dict[str, Any]:
    field: dict[str, Any] = {"name": name, "type": kind}
    if description:
        field["description"] = description
    field.update(extra)
    return field


def scans_schema() -> dict[str, Any]:
    """Table Schema of ``scans.csv``: scan id primary key, the five label codes foreign keys into the taxonomy."""
    codes = ("class_code", "subclass_code", "material_code", "process_code", "extra_code")
    kinds = {"scan_index": "integer", "started": "datetime", "rigid": "boolean"}
    fields = [_field(name, kinds.get(name, "string"), constraints={"required": True} if name == "scan_id" else {})
              for name in SCAN_COLUMNS]
    for field in fields:
        if not field.get("constraints"):
            field.pop("constraints", None)
    return {"fields": fields, "primaryKey": ["scan_id"], "missingValues": [""],
            "foreignKeys": [{"fields": [code], "reference": {"resource": "taxonomy", "fields": ["code"]}}
                            for code in codes]}


def features_schema(header: Sequence[str], units: Mapping[str, str],
                    scans_resource: str | None = "scans") -> dict[str, Any]:
    """Table Schema of ``features.csv`` from its header: identifiers and label as strings, the label's parts
    as integers (-1 outside the taxonomy's format), every feature a number (``NaN`` where undefined) with its
    unit where it has one; the scan id the primary key and, with ``scans_resource``, the scan id and label a
    foreign key into that table (a recording set's rows are windows of recordings: none)."""
    integers = {"C", "S", "M", "P", "X"}
    fields = []
    for name in header:
        if name in integers:
            fields.append(_field(name, "integer", f"the label's {name} number"))
        elif name in ("scan_id", "sample_id", "split") or name.startswith(("label", "level:")):
            fields.append(_field(name, "string"))
        else:
            unit = units.get(name)
            fields.append(_field(name, "number", _unit_text(unit)) | ({"unit": unit} if unit else {}))
    key = header[0]
    schema: dict[str, Any] = {"fields": fields, "primaryKey": [key], "missingValues": [""]}
    if scans_resource:
        schema["foreignKeys"] = [{"fields": [key, header[2]],
                                  "reference": {"resource": scans_resource, "fields": [key, "label"]}}]
    return schema


def _unit_text(unit: str | None) -> str:
    return f"unit {unit} ({UNITS.get(unit, unit)})" if unit else ""


def taxonomy_schema() -> dict[str, Any]:
    """Table Schema of ``taxonomy.csv``: the code is the primary key."""
    return {"fields": [_field(name, "string") for name in HEADER], "primaryKey": ["code"], "missingValues": [""]}


def recordings_schema(groups: Sequence[str]) -> dict[str, Any]:
    """Table Schema of a recording set's ``recordings.csv``."""
    names = [*RECORDING_COLUMNS[:2], *(f"group:{g}" for g in groups), "mat_file"]
    return {"fields": [_field(name, "string") for name in names], "primaryKey": ["recording"],
            "missingValues": [""]}


def data_package(resources: Sequence[tuple[str, str, str, int]], provenance: Provenance) -> dict[str, Any]:
    """``datapackage.json``: ``(name, path, schema path, rows)`` for each table."""
    package: dict[str, Any] = {
        "name": "texplorer-bundle", "title": provenance.title, "created": provenance.created.isoformat(),
        "resources": [{"name": name, "path": path, "profile": "tabular-data-resource", "format": "csv",
                       "mediatype": "text/csv", "encoding": "utf-8", "schema": schema, "stats": {"rows": rows}}
                      for name, path, schema, rows in resources],
    }
    if provenance.license:
        package["licenses"] = [{"path": provenance.license, **({"name": _spdx(provenance.license)}
                                                                if _spdx(provenance.license) else {})}]
    if provenance.creator:
        package["contributors"] = [{"title": provenance.creator, "role": "author"}]
    return package


def _spdx(url: str) -> str | None:
    prefix = "https://spdx.org/licenses/"
    return url[len(prefix):] if url.startswith(prefix) else None


# -- Croissant ---------------------------------------------------------------------------------------

CROISSANT_CONTEXT: Mapping[str, Any] = {
    "@language": "en", "@vocab": "https://schema.org/", "arrayShape": "cr:arrayShape", "citeAs": "cr:citeAs",
    "column": "cr:column", "conformsTo": "dct:conformsTo", "containedIn": "cr:containedIn",
    "cr": "http://mlcommons.org/croissant/", "rai": "http://mlcommons.org/croissant/RAI/",
    "data": {"@id": "cr:data", "@type": "@json"}, "dataType": {"@id": "cr:dataType", "@type": "@vocab"},
    "dct": "http://purl.org/dc/terms/", "description": {"@container": "@language"},
    "equivalentProperty": "cr:equivalentProperty", "examples": {"@id": "cr:examples", "@type": "@json"},
    "extract": "cr:extract", "field": "cr:field", "fileProperty": "cr:fileProperty", "fileObject": "cr:fileObject",
    "fileSet": "cr:fileSet", "format": "cr:format", "includes": "cr:includes", "isArray": "cr:isArray",
    "isLiveDataset": "cr:isLiveDataset", "jsonPath": "cr:jsonPath", "key": "cr:key", "md5": "cr:md5",
    "name": {"@container": "@language"}, "parentField": "cr:parentField", "path": "cr:path",
    "recordSet": "cr:recordSet", "references": "cr:references", "regex": "cr:regex", "repeated": "cr:repeated",
    "replace": "cr:replace", "samplingRate": "cr:samplingRate", "sc": "https://schema.org/",
    "separator": "cr:separator", "source": "cr:source", "subField": "cr:subField", "transform": "cr:transform",
}
"""The JSON-LD context of Croissant 1.1 (as the MLCommons reference implementation writes it)."""

_CR_TYPES = {"string": "sc:Text", "integer": "sc:Integer", "number": "sc:Float", "boolean": "sc:Boolean",
             "datetime": "sc:DateTime"}


@dataclass(frozen=True)
class Table:
    """A CSV file of the bundle as Croissant and Frictionless see it."""

    name: str
    path: str
    schema: Mapping[str, Any]
    description: str


def _cr_fields(table: Table) -> list[dict[str, Any]]:
    fields = []
    for field in table.schema["fields"]:
        entry = {"@type": "cr:Field", "@id": f"{table.name}/{field['name']}", "name": field["name"],
                 "dataType": _CR_TYPES[field["type"]],
                 "source": {"fileObject": {"@id": table.path}, "extract": {"column": field["name"]}}}
        if field.get("description"):
            entry["description"] = field["description"]
        fields.append(entry)
    return fields


def croissant(tables: Sequence[Table], checksums: Mapping[str, Mapping[str, Any]], provenance: Provenance,
              file_sets: Sequence[tuple[str, str, str, str]], photo_kinds: Sequence[str] = ()) -> dict[str, Any]:
    """The Croissant 1.1 description: a ``FileObject`` per table (with its SHA-256), a ``FileSet`` per
    ``(id, glob, encoding, description)``, a record set per table with its typed fields, and, when the bundle
    holds photos of ``photo_kinds``, a ``photos`` record set (scan id and kind from the file name, the image)."""
    distribution = [{"@type": "cr:FileObject", "@id": table.path, "name": table.path, "contentUrl": table.path,
                     "encodingFormat": encoding(table.path), "sha256": checksums[table.path]["sha256"],
                     "contentSize": f"{checksums[table.path]['size']} B", "description": table.description}
                    for table in tables]
    distribution += [{"@type": "cr:FileSet", "@id": ident, "name": ident, "includes": glob,
                      "encodingFormat": media, "description": text} for ident, glob, media, text in file_sets]
    record_sets = []
    for table in tables:
        record_set = {"@type": "cr:RecordSet", "@id": table.name, "name": table.name,
                      "description": table.description, "field": _cr_fields(table)}
        keys = table.schema.get("primaryKey") or []
        if keys:
            record_set["key"] = [{"@id": f"{table.name}/{key}"} for key in keys]
        record_sets.append(record_set)
    record_sets.append(channel_record_set())
    if photo_kinds:
        record_sets.append(_photo_records(photo_kinds))
    body: dict[str, Any] = {
        "@context": dict(CROISSANT_CONTEXT), "@type": "sc:Dataset", "name": "texplorer-bundle",
        "description": f"{provenance.title}: multimodal material scans (vibration, sound, force, thermal, "
                       "magnetic, photos) with their features and material taxonomy",
        "conformsTo": CROISSANT_VERSION, "datePublished": provenance.created.isoformat(),
        "version": provenance.software_version, "citeAs": _cite(provenance),
        "url": "./", "distribution": distribution, "recordSet": record_sets,
        "license": provenance.license or "no license given",
    }
    if provenance.creator:
        body["creator"] = _creator_entity(provenance.creator)
    return body


def _photo_records(kinds: Sequence[str]) -> dict[str, Any]:
    alternatives = "|".join(re.escape(kind) for kind in kinds)
    source = {"fileSet": {"@id": "photo-files"}, "extract": {"fileProperty": "fullpath"}}
    return {"@type": "cr:RecordSet", "@id": "photos", "name": "photos",
            "description": "the scans' photos; scan_id joins scans.scan_id",
            "field": [
                {"@type": "cr:Field", "@id": "photos/scan_id", "name": "scan_id", "dataType": "sc:Text",
                 "source": source | {"transform": {"regex": f"^(?:.*/)?([^/]+)_(?:{alternatives})\\.png$"}}},
                {"@type": "cr:Field", "@id": "photos/kind", "name": "kind", "dataType": "sc:Text",
                 "source": source | {"transform": {"regex": f"^(?:.*/)?[^/]+_({alternatives})\\.png$"}}},
                {"@type": "cr:Field", "@id": "photos/image", "name": "image", "dataType": "sc:ImageObject",
                 "source": {"fileSet": {"@id": "photo-files"}, "extract": {"fileProperty": "content"}}},
            ]}


def _cite(provenance: Provenance) -> str:
    author = provenance.creator or "unknown"
    return (f"@misc{{texplorer{provenance.created:%Y%m%d%H%M%S}, title={{{provenance.title}}}, "
            f"author={{{author}}}, year={{{provenance.created.year}}}, note={{texplorer export bundle}}}}")


def _creator_entity(creator: str) -> dict[str, Any]:
    if _URL.fullmatch(creator):
        return {"@type": "sc:Person", "@id": creator, "url": creator, "name": creator}
    return {"@type": "sc:Person", "name": creator}


# -- RO-Crate ---------------------------------------------------------------------------------------

INSTRUMENTS: Mapping[str, tuple[str, str]] = {
    "#texplorer2": ("Texplorer2 handheld multimodal material scanner",
                    "four hand-held units on an NI USB-6002 DAQ, a serial sensor board, a microphone and a camera"),
    "#TU1": ("Texplorer2 unit TU1: taps and slides", "ADXL335 accelerometer, microphone, IR reflectance sensor"),
    "#TU2": ("Texplorer2 unit TU2: static touch, friction, press, fold",
             "metal electrode, MAG3110 magnetometer, MLX90614 thermometer, Peltier element, force sensors, flex "
             "sensor"),
    "#TU3": ("Texplorer2 unit TU3: photos", "camera with a 4x macro lens and a flash"),
    "#TU4": ("Texplorer2 unit TU4: mass and volume", "scale and water or micro-pearl displacement"),
}
"""The scanner and its units, the instruments of every scan session."""


def encoding(path: str) -> str:
    """The encoding format of a bundle file (:data:`ENCODINGS`)."""
    suffix = path[path.rfind("."):].lower() if "." in path.rsplit("/", 1)[-1] else ""
    return ENCODINGS.get(suffix, "application/octet-stream")


@dataclass(frozen=True)
class SessionRecord:
    """One scan session as RO-Crate provenance: who, when, and the files it made."""

    session_id: str
    operators: tuple[str, ...]
    started: str
    ended: str
    files: tuple[str, ...]


def sessions_of(records: Sequence[ScanRecord], files: Mapping[str, Mapping[str, str]]) -> list[SessionRecord]:
    """The sessions of ``records`` in order of their first scan; ``files`` as for :func:`scans_table`."""
    grouped: dict[str, list[ScanRecord]] = {}
    for record in records:
        grouped.setdefault(record.session_id, []).append(record)
    sessions = []
    for session_id, members in grouped.items():
        times = sorted(r.started for r in members)
        paths = tuple(path for r in members for path in files[r.scan_id].values())
        sessions.append(SessionRecord(session_id, tuple(sorted({r.operator for r in members})), times[0], times[-1],
                                paths))
    return sessions


def ro_crate(checksums: Mapping[str, Mapping[str, Any]], provenance: Provenance, sessions: Sequence[SessionRecord],
             description: str, about: Mapping[str, str]) -> dict[str, Any]:
    """The RO-Crate 1.2 metadata of a bundle whose files have ``checksums`` (``{"sha256", "size"}`` by path).

    ``about`` names what the bundle's own description files are (``{path: text}``): they are described
    as such; the manifest, which lists this file's checksum, is listed without one.
    """
    root: dict[str, Any] = {
        "@id": "./", "@type": "Dataset", "name": provenance.title, "description": description,
        "datePublished": provenance.created.isoformat(), "hasPart": [{"@id": path} for path in sorted(checksums)],
        "mentions": [{"@id": _session_id(s.session_id)} for s in sessions] + [{"@id": "#export"}],
    }
    graph: list[dict[str, Any]] = [
        {"@id": RO_CRATE, "@type": "CreativeWork", "conformsTo": {"@id": RO_CRATE_VERSION}, "about": {"@id": "./"}},
        root,
    ]
    if provenance.license:
        root["license"] = {"@id": provenance.license}
        graph.append({"@id": provenance.license, "@type": "CreativeWork",
                      "name": _spdx(provenance.license) or provenance.license,
                      "description": "the license the exporting lab gave the bundle"})
    else:
        root["license"] = "no license given by the exporting lab"
    if provenance.creator:
        creator = _crate_creator(provenance.creator)
        root["creator"] = root["publisher"] = {"@id": creator["@id"]}
        graph.append(creator)
    for path in sorted(checksums):
        entry = {"@id": path, "@type": "File", "name": path.rsplit("/", 1)[-1], "encodingFormat": encoding(path),
                 "contentSize": str(checksums[path]["size"]), "sha256": checksums[path]["sha256"]}
        entry["description"] = about.get(path) or _file_description(path)
        graph.append(entry)
    graph += [{"@id": ident, "@type": "IndividualProduct", "name": name, "description": text}
              | ({"hasPart": [{"@id": unit} for unit in INSTRUMENTS if unit != "#texplorer2"]}
                 if ident == "#texplorer2" else {})
              for ident, (name, text) in INSTRUMENTS.items()]
    operators = sorted({operator for session in sessions for operator in session.operators})
    graph += [{"@id": _operator_id(op), "@type": "Person", "name": op, "identifier": op,
               "description": "operator id as recorded by the scanner"} for op in operators]
    graph += [{"@id": _session_id(s.session_id), "@type": "CreateAction", "name": f"scan session {s.session_id}",
               "startTime": s.started, "endTime": s.ended,
               "agent": _one_or_list([{"@id": _operator_id(op)} for op in s.operators]),
               "instrument": [{"@id": ident} for ident in INSTRUMENTS],
               "result": _one_or_list([{"@id": path} for path in s.files])} for s in sessions]
    graph.append({"@id": "#texplorer", "@type": "SoftwareApplication", "name": "texplorer",
                  "version": provenance.software_version, "url": "README.md",
                  "description": f"feature code version {provenance.feature_code_version}"})
    graph.append({"@id": "#export", "@type": "CreateAction", "name": "texplorer export",
                  "endTime": provenance.created.isoformat(), "instrument": {"@id": "#texplorer"},
                  "result": {"@id": "./"}})
    return {"@context": RO_CRATE_CONTEXT, "@graph": graph}


def _one_or_list(items: list[dict[str, str]]) -> dict[str, str] | list[dict[str, str]]:
    return items[0] if len(items) == 1 else items


def _file_description(path: str) -> str:
    name = path.rsplit("/", 1)[-1]
    stem, _, suffix = name.rpartition(".")
    if path.startswith(f"{CHANNELS_FOLDER}/"):
        modality = stem.removesuffix("_channels")
        return f"channel table of the {modality} channels" + (" (column descriptions)" if suffix == "json" else "")
    if path.startswith(f"{SCHEMAS}/"):
        return f"Frictionless Table Schema of {stem.removesuffix('.schema')}.csv"
    if suffix == "mat":
        return f"{stem}: its channels and metadata as MATLAB v5 variables"
    if suffix in ("png", "jpg", "jpeg"):
        scan, _, kind = stem.rpartition("_")
        return f"photo {kind} of scan {scan}"
    return name


def _session_id(session_id: str) -> str:
    return f"#session-{session_id}"


def _operator_id(operator: str) -> str:
    return "#operator-" + re.sub(r"[^A-Za-z0-9._-]", lambda m: f"%{ord(m.group()):02X}", operator)


def _crate_creator(creator: str) -> dict[str, Any]:
    if _URL.fullmatch(creator):
        return {"@id": creator, "@type": "Person", "name": creator}
    return {"@id": "#creator", "@type": "Person", "name": creator}


def as_bytes(value: Any) -> bytes:
    """A metadata document as the bundle stores it (UTF-8 JSON, indented, no NaN)."""
    return json.dumps(value, indent=1, ensure_ascii=False, allow_nan=False).encode("utf-8") + b"\n"


# -- a bundle's metadata, assembled ---------------------------------------------------------------------

FEATURES_CSV = "features.csv"
TAXONOMY_CSV = "taxonomy.csv"


def _schema_path(name: str) -> str:
    return f"{SCHEMAS}/{name}.schema.json"


def csv_header(table: bytes) -> list[str]:
    """The column names of a CSV table (its first line)."""
    return next(csv.reader(io.StringIO(table.split(b"\n", 1)[0].decode("utf-8"))))


def _rows(text: str) -> int:
    """Data rows of a CSV table (its records after the header); csv.Error for one the csv module refuses."""
    return max(sum(1 for _ in csv.reader(io.StringIO(text))) - 1, 0)


def describe_tables(tables: Sequence[tuple[Table, bytes]], channels: Sequence[ChannelRow],
                    provenance: Provenance) -> dict[str, bytes]:
    """The schema files, ``datapackage.json`` and channel tables of a bundle whose CSV tables are ``tables``
    (each with its bytes, to count its rows)."""
    files = {_schema_path(table.name): as_bytes(table.schema) for table, _ in tables}
    resources = [(table.name, table.path, _schema_path(table.name), _rows(data.decode("utf-8")))
                 for table, data in tables]
    files[DATAPACKAGE] = as_bytes(data_package(resources, provenance))
    files.update(channel_tables(channels))
    return files


def scan_bundle_tables(records: Sequence[ScanRecord], scan_files: Mapping[str, Mapping[str, str]],
                       features_csv: bytes, feature_units: Mapping[str, str]) -> list[tuple[Table, bytes]]:
    """The CSV tables of a bundle of scans: ``scans.csv`` (made here), ``features.csv``, ``taxonomy.csv``
    (``taxonomy.csv``'s bytes are read by the caller and not needed here)."""
    scans = scans_table(records, scan_files)
    return [
        (Table("scans", SCANS_CSV, scans_schema(), "one row per scan: its label, the label's five taxonomy "
               "codes, sample, session, operator, time and files (mat_file: the scan's MATLAB file)"), scans),
        (Table("features", FEATURES_CSV, features_schema(csv_header(features_csv), feature_units),
               "the features of each scan (docs/features.md); NaN where a feature is undefined"), features_csv),
    ]


def taxonomy_table(data: bytes) -> tuple[Table, bytes]:
    """``taxonomy.csv`` as a table of the bundle."""
    return (Table("taxonomy", TAXONOMY_CSV, taxonomy_schema(),
                  "the material taxonomy: kind (C, S, M, P, X), code, name, description"), data)


def croissant_file_sets(photo_kinds: Sequence[str], data_glob: str, data_text: str) -> list[tuple[str, str, str, str]]:
    """The Croissant ``FileSet`` entries: the ``.mat`` files, the channel tables, and photos if any."""
    sets = [("mat-files", data_glob, ENCODINGS[".mat"], data_text),
            ("channel-tables", f"{CHANNELS_FOLDER}/*_channels.tsv", ENCODINGS[".tsv"],
             "BIDS-style channel tables: name, type, units, sampling frequency, device of every channel")]
    if photo_kinds:
        sets.append(("photo-files", "scans/**/*.png", ENCODINGS[".png"], "the scans' photos"))
    return sets


def channel_record_set() -> dict[str, Any]:
    """The Croissant record set of the channel tables (every column as text: BIDS writes ``n/a``)."""
    return {"@type": "cr:RecordSet", "@id": "channels", "name": "channels",
            "description": "every channel of the .mat files: its variable, column, type, units, rate and device",
            "field": [{"@type": "cr:Field", "@id": f"channels/{name}", "name": name, "dataType": "sc:Text",
                       "source": {"fileSet": {"@id": "channel-tables"}, "extract": {"column": name}}}
                      for name in CHANNEL_COLUMNS]}


# -- checking a bundle's metadata against its files (import) -------------------------------------------

MAX_METADATA_BYTES = 256 << 20
"""A metadata file the manifest lists as larger than this is refused unread (RO-Crate of about 150,000 scans)."""

TABLES = (SCANS_CSV, FEATURES_CSV, TAXONOMY_CSV, RECORDINGS_CSV)
"""The CSV tables a Data Package of a bundle may describe."""


def metadata_problems(staged: Iterable[str], manifest: Mapping[str, Any], read: Any,
                      units: Mapping[str, str] | None = None, holder: str = "scans") -> list[str]:
    """Where the standard metadata of a bundle disagree with its files, one line each; empty for a bundle
    written before they existed (none of them present).

    ``staged`` are the bundle's verified files outside its scans or recordings (names), ``manifest`` its
    parsed manifest (whose ``files`` sizes and SHA-256 were checked against the files), ``read(name)`` gives
    a file's bytes, ``units`` the unit each ``.mat`` variable must have (None skips that check) and ``holder``
    what holds the variables (``scans`` or ``recordings``, for the messages). Checked: every RO-Crate
    ``File`` and Croissant ``FileObject`` against the manifest's size and SHA-256, every file the manifest
    lists against the RO-Crate's parts, each Data Package table's row count, the scans of ``scans.csv``
    against the manifest's, and the channel tables' units against ``units``. Metadata of the wrong shape are
    problems too, never exceptions.
    """
    staged = set(staged)
    listed: Mapping[str, Mapping[str, Any]] = manifest["files"]
    problems: list[str] = []
    if RO_CRATE in staged:
        problems += _crate_problems(_load(read, RO_CRATE, listed, problems), listed)
    if CROISSANT in staged:
        problems += _croissant_problems(_load(read, CROISSANT, listed, problems), listed)
    if DATAPACKAGE in staged:
        problems += _package_problems(_load(read, DATAPACKAGE, listed, problems), staged, listed, read)
    if SCANS_CSV in staged and isinstance(manifest.get("scans"), list):
        problems += _scans_problems(_text(read, SCANS_CSV, listed, problems), manifest)
    if units is not None:
        for name in sorted(n for n in staged if n.startswith(f"{CHANNELS_FOLDER}/") and n.endswith(".tsv")):
            problems += _unit_problems(name, _text(read, name, listed, problems), units, holder)
    return problems


def _too_large(name: str, listed: Mapping[str, Mapping[str, Any]], problems: list[str]) -> bool:
    if listed.get(name, {}).get("size", 0) > MAX_METADATA_BYTES:
        problems.append(f"{name}: larger than {MAX_METADATA_BYTES} bytes (not read)")
        return True
    return False


def _refuse_constant(token: str) -> float:
    raise MetadataError(f"{token} is not a JSON number")


def _load(read: Any, name: str, listed: Mapping[str, Mapping[str, Any]], problems: list[str]) -> Any:
    if _too_large(name, listed, problems):
        return None
    try:
        return json.loads(read(name).decode("utf-8"), parse_constant=_refuse_constant)
    except (UnicodeDecodeError, ValueError, RecursionError) as exc:
        problems.append(f"{name}: not valid JSON ({str(exc)[:200]})")
        return None


def _text(read: Any, name: str, listed: Mapping[str, Mapping[str, Any]], problems: list[str]) -> str:
    return "" if _too_large(name, listed, problems) else read(name).decode("utf-8", errors="replace")


def _csv_rows(text: str, name: str, problems: list[str], delimiter: str = ",") -> list[dict[str, str]]:
    try:
        return list(csv.DictReader(io.StringIO(text), delimiter=delimiter))
    except csv.Error as exc:
        problems.append(f"{name}: not a readable table ({exc})")
        return []


def _disagreement(where: str, path: str, entry: Mapping[str, Any], listed: Mapping[str, Mapping[str, Any]],
                  size_key: str, size_of: Any) -> list[str]:
    if path not in listed:
        return [f"{where}: describes {path[:200]}, which the bundle does not hold"]
    problems = []
    if "sha256" in entry and entry["sha256"] != listed[path]["sha256"]:
        problems.append(f"{where}: SHA-256 of {path} is {str(entry['sha256'])[:16]}..., the file's is "
                        f"{listed[path]['sha256'][:16]}...")
    if size_key in entry and size_of(entry[size_key]) != listed[path]["size"]:
        problems.append(f"{where}: size of {path} is {str(entry[size_key])[:40]!r}, the file has "
                        f"{listed[path]['size']} bytes")
    return problems


def _crate_problems(crate: Any, listed: Mapping[str, Mapping[str, Any]]) -> list[str]:
    if crate is None:
        return []
    graph = crate.get("@graph") if isinstance(crate, dict) else None
    if not isinstance(graph, list) or not all(isinstance(e, dict) for e in graph):
        return [f"{RO_CRATE}: no @graph of entities"]
    problems = []
    files = {}
    for entity in graph:
        if entity.get("@type") in ("File", ["File"]):
            if not isinstance(entity.get("@id"), str):
                problems.append(f"{RO_CRATE}: a File entity without a text @id")
                continue
            files[entity["@id"]] = entity
    for path, entry in files.items():
        problems += _disagreement(RO_CRATE, path, entry, listed, "contentSize", _int_or_none)
    problems += [f"{RO_CRATE}: does not describe {path}" for path in sorted(listed)
                 if path not in files and path != RO_CRATE]
    return problems


def _croissant_problems(description: Any, listed: Mapping[str, Mapping[str, Any]]) -> list[str]:
    if description is None:
        return []
    distribution = description.get("distribution") if isinstance(description, dict) else None
    if not isinstance(distribution, list):
        return [f"{CROISSANT}: no distribution list"]
    problems = []
    for entry in distribution:
        if isinstance(entry, dict) and entry.get("@type") == "cr:FileObject":
            problems += _disagreement(CROISSANT, str(entry.get("contentUrl")), entry, listed, "contentSize",
                                      lambda text: _int_or_none(str(text).removesuffix(" B")))
    return problems


def _int_or_none(value: Any) -> int | None:
    try:
        return int(value)
    except (TypeError, ValueError, OverflowError):
        return None


def _package_problems(package: Any, staged: set[str], listed: Mapping[str, Mapping[str, Any]],
                      read: Any) -> list[str]:
    if package is None:
        return []
    resources = package.get("resources") if isinstance(package, dict) else None
    if not isinstance(resources, list):
        return [f"{DATAPACKAGE}: no resources list"]
    problems: list[str] = []
    seen: set[str] = set()
    for resource in resources:
        path = resource.get("path") if isinstance(resource, dict) else None
        if not isinstance(path, str) or path not in staged or path not in TABLES or path in seen:
            problems.append(f"{DATAPACKAGE}: resource {str(path)[:200]!r} is not a table of the bundle "
                            "(or is listed twice)")
            continue
        seen.add(path)
        stats = resource.get("stats")
        rows = stats.get("rows") if isinstance(stats, dict) else None
        actual = _rows_of(_text(read, path, listed, problems), path, problems)
        if rows is not None and rows != actual:
            problems.append(f"{DATAPACKAGE}: {path} has {actual} rows, the package says {str(rows)[:40]}")
    return problems


def _rows_of(text: str, name: str, problems: list[str]) -> int:
    try:
        return _rows(text)
    except csv.Error as exc:
        problems.append(f"{name}: not a readable table ({exc})")
        return 0


def _scans_problems(text: str, manifest: Mapping[str, Any]) -> list[str]:
    problems: list[str] = []
    ids = [str(row.get("scan_id")) for row in _csv_rows(text, SCANS_CSV, problems)]
    expected = [str(scan.get("scan_id")) for scan in manifest["scans"] if isinstance(scan, dict)]
    if problems or sorted(ids) == sorted(expected):
        return problems
    extra = sorted(set(ids) - set(expected))
    return [f"{SCANS_CSV}: {len(ids)} scans, the manifest lists {len(expected)}"
            + (f" (not in the manifest: {', '.join(e[:64] for e in extra[:5])})" if extra else "")]


def _unit_problems(name: str, text: str, units: Mapping[str, str], holder: str) -> list[str]:
    problems: list[str] = []
    for row in _csv_rows(text, name, problems, "\t"):
        variable, unit = row.get("variable"), row.get("units")
        if variable not in units:
            problems.append(f"{name}: channel {str(row.get('name'))[:64]!r} names variable {str(variable)[:64]!r}, "
                            f"which the {holder} do not hold")
        elif unit != units[variable]:
            problems.append(f"{name}: channel {row.get('name')} in {str(unit)[:32]!r}, but the {holder} store "
                            f"{variable} in {units[variable]!r}")
    return problems
