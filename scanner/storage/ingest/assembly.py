"""Recordings assembled from a folder of files as a mapping describes them: names, labels,
train/test split, image patches, and a report of every file that could not be used.
"""

from __future__ import annotations

import csv
import hashlib
import io
import os
import re
import unicodedata
from collections.abc import Callable, Iterable, Mapping, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from scanner.scan import Recording, ScanError, Trace, role_key
from scanner.storage.ingest.alignment import align
from scanner.storage.ingest.mapping import FileMap, IngestError, IngestMapping, shown
from scanner.storage.ingest.readers import Note, Stream, read_streams


@dataclass
class IngestReport:
    """The recordings made and the problems met: ``skipped`` holds one line per bad file or recording,
    ``notes`` what was done to usable data (:func:`summarise_notes` condenses them)."""

    recordings: list[Recording] = field(default_factory=list)
    skipped: list[str] = field(default_factory=list)
    notes: list[Note] = field(default_factory=list)
    files: int = 0
    made: list[Made] = field(default_factory=list)
    """What every recording made was (also those handed to a ``sink`` and not kept in ``recordings``)."""


@dataclass(frozen=True)
class Made:
    """A recording the import made, without its data: its name, channel roles and train/test part."""

    name: str
    roles: tuple[str, ...]
    split: str | None
    label: str = ""

    @classmethod
    def of(cls, recording: Recording) -> Made:
        return cls(recording.name, tuple(recording.roles), recording.meta.get("split"), str(recording.label))


def nfc(text: str) -> str:
    """``text`` in Unicode normal form C: a name typed on one system (``è``, NFC) and copied from another
    (``e`` + a combining grave accent, NFD, as macOS file systems store it) is one name."""
    return unicodedata.normalize("NFC", text)


def stem_of(path: Path, spec: FileMap) -> str | None:
    """The recording stem of a file, in NFC (:func:`nfc`): the ``stem`` group of ``stem_pattern`` searched in
    its name (None if it does not match), else its name without ``suffix`` (default: without the
    extension)."""
    name = nfc(path.name)
    if spec.stem_pattern is not None:
        match = spec.stem_pattern.search(name)
        return match["stem"] if match and match["stem"] else None
    if spec.suffix is not None:
        suffix = nfc(spec.suffix)
        return name[:-len(suffix)] if suffix and name.endswith(suffix) else name
    return nfc(path.stem)


def outside_line(path: Path, root: Path) -> str | None:
    """A problem line if ``path`` (a link, or a file below a linked folder) leads out of the folder
    ``root``, else None: an import reads only files inside the folder it was given."""
    real = path.resolve()
    if real.is_relative_to(root.resolve()):
        return None
    return f"{path}: a link to {real}, outside the ingested folder: not read"


def _matched(root: Path, mapping: IngestMapping,
             report: IngestReport | None = None) -> dict[Path, list[tuple[Path, FileMap]]]:
    """Files of every [[files]] entry, grouped by recording key: the folder plus the stem. A file whose
    name the entry's ``stem_pattern`` does not match is reported in ``report.skipped``."""
    groups: dict[Path, list[tuple[Path, FileMap]]] = {}
    skipped = report.skipped if report is not None else []
    for spec in mapping.files:
        for path in _globbed(root, spec.glob):
            if spec.suffix and not nfc(path.name).endswith(nfc(spec.suffix)):
                continue
            outside = outside_line(path, root)
            if outside is not None:
                skipped.append(outside)
                continue
            stem = stem_of(path, spec)
            if stem is None:  # only with a stem_pattern
                pattern = spec.stem_pattern.pattern if spec.stem_pattern else ""
                skipped.append(f"{path}: name does not match stem_pattern {pattern!r}")
                continue
            files = groups.setdefault(path.parent / stem, [])
            first = next((seen for seen, kind in files if kind is spec), None)
            if first is not None:  # names equal in NFC (or in the stem a suffix leaves)
                skipped.append(f"{path}: the same recording and files entry as {first.name} (the same name in "
                               "Unicode NFC): not read")
                continue
            files.append((path, spec))
    return groups


def _globbed(root: Path, glob: str) -> list[Path]:
    """The files ``glob`` matches under ``root``, sorted; an IngestError naming it if they cannot be listed."""
    try:
        return sorted(p for p in root.glob(glob) if p.is_file())
    except OSError as exc:  # a name longer than the file system allows, a folder that cannot be read
        raise IngestError(f"{root}: cannot list the files of glob {shown(glob)} ({exc.strerror or exc})") from None


def recording_names(keys: Sequence[Path], root: Path) -> dict[Path, str]:
    """A distinct, stable name for every recording key (folder + stem), derived from its path.

    The stem where no other recording has it; otherwise the folders below ``root`` and the stem joined by
    ``_`` (``train/cork/r01`` -> ``train_cork_r01``); a name still shared, or longer than 64 characters,
    ends in 8 hex digits of the SHA-256 of the relative path.
    """
    stems: dict[str, int] = {}
    for key in keys:
        stems[safe_name(key.name)] = stems.get(safe_name(key.name), 0) + 1
    names = {}
    for key in keys:
        relative = key.relative_to(root)
        long = re.sub(r"[^A-Za-z0-9._-]", "_", nfc("_".join(relative.parts))).lstrip("._-") or "recording"
        names[key] = safe_name(key.name) if stems[safe_name(key.name)] == 1 else long
    shared: dict[str, int] = {}
    for name in names.values():
        shared[name] = shared.get(name, 0) + 1
    for key, name in names.items():
        if shared[name] > 1 or len(name) > 64:
            digest = hashlib.sha256(key.relative_to(root).as_posix().encode()).hexdigest()[:8]
            names[key] = f"{name[:55]}-{digest}"
    return names


def _label_table(root: Path, mapping: IngestMapping) -> dict[str, dict[str, str]]:
    if mapping.label_from != "csv" or mapping.label_csv is None:
        return {}
    path = root / mapping.label_csv  # relative, without '..' (parse_mapping)
    outside = outside_line(path, root) if path.exists() else None
    if outside is not None:
        raise IngestError(outside)
    try:
        text = nfc(path.read_text(encoding="utf-8-sig"))
    except (OSError, UnicodeDecodeError) as exc:
        raise IngestError(f"{path}: cannot read the label table ({exc})") from None
    rows = list(csv.DictReader(io.StringIO(text)))
    needed = [mapping.label_key, mapping.label_column, *mapping.label_levels]
    missing = [c for c in needed if rows and c not in rows[0]]
    if not rows or missing:
        raise IngestError(f"{path}: the label table needs the column(s) {', '.join(missing or needed)}")
    return {row[mapping.label_key].strip(): {k: (v or "").strip() for k, v in row.items() if k}
            for row in rows}


def _label(key: Path, root: Path, mapping: IngestMapping, table: Mapping[str, Mapping[str, str]],
           groups: Mapping[str, str]) -> tuple[str, dict[str, str]]:
    """The label and coarser levels of a recording; an IngestError if there is none."""
    if mapping.label_from == "pattern":
        return groups["label"], {}
    if mapping.label_from == "csv":
        row = table.get(key.name)
        if row is None or not row.get(mapping.label_column):
            raise IngestError(f"no label for {key.name!r} in {mapping.label_csv}")
        return row[mapping.label_column], {level: row[level] for level in mapping.label_levels}
    relative = [nfc(folder) for folder in key.relative_to(root).parts[:-1]]
    if len(relative) < mapping.label_depth:
        raise IngestError(f"{key.name}: no folder {mapping.label_depth} level(s) up to take the label from "
                          "(put each class in a folder of its own, or take the labels from the file names "
                          "with --label-pattern '(?P<label>...)')")
    return relative[-mapping.label_depth], {}


def _split_part(value: str, mapping: IngestMapping) -> str | None:
    lowered = nfc(value).lower()
    return next((part for part, names in mapping.split_names.items() if lowered in names), None)


def split_of(key: Path, root: Path, mapping: IngestMapping, groups: Mapping[str, str]) -> str | None:
    """``train`` or ``test`` from a folder of the recording's path or the pattern's ``split`` group; None
    if the mapping has no split (or, by default, no folder names one). IngestError if the mapping asks for a
    split the recording does not have."""
    if mapping.split_from == "none":
        return None
    if mapping.split_from == "pattern":
        value = groups.get("split", "")
        part = _split_part(value, mapping)
        if part is None:
            names = mapping.split_names
            raise IngestError(f"{key.name}: split {value!r} is neither train ({', '.join(names['train'])}) "
                              f"nor test ({', '.join(names['test'])})")
        return part
    parts = [p for p in (_split_part(folder, mapping) for folder in key.relative_to(root).parts[:-1]) if p]
    if len(set(parts)) > 1:
        raise IngestError(f"{key.relative_to(root)}: folders name both a training and a test part")
    if not parts and mapping.split_from == "folder":
        raise IngestError(f"{key.relative_to(root)}: no train or test folder in the path")
    return parts[0] if parts else None


def safe_name(text: str) -> str:
    """A recording name usable as a file name: other characters become '_' (1-64 characters)."""
    name = re.sub(r"[^A-Za-z0-9._-]", "_", text).lstrip("._-")[:64]
    return name or "recording"


def patches(image: np.ndarray, grid: tuple[int, int]) -> list[tuple[int, int, np.ndarray]]:
    """``(row, column, patch)`` of a rows x columns grid of equal patches, centred: the image's last
    ``h mod rows`` rows and ``w mod columns`` columns are split between the two sides and left out."""
    rows, columns = grid
    h, w = image.shape[:2]
    ph, pw = h // rows, w // columns
    if ph < 1 or pw < 1:
        raise IngestError(f"an image of {w}x{h} px cannot be cut into {rows}x{columns} patches")
    top, left = (h - rows * ph) // 2, (w - columns * pw) // 2
    return [(r, c, image[top + r * ph:top + (r + 1) * ph, left + c * pw:left + (c + 1) * pw])
            for r in range(rows) for c in range(columns)]


@dataclass(frozen=True)
class _Parts:
    """Everything read for one recording key."""

    streams: dict[str, Stream]
    images: dict[str, np.ndarray]
    roles: dict[str, str]
    files: dict[str, str]
    grid: tuple[int, int] | None


def failure_line(path: Path, exc: BaseException) -> str:
    """One line naming ``path`` and an unexpected failure reading it (a library's error, MemoryError)."""
    text = str(exc).strip().splitlines()[0] if str(exc).strip() else ""
    what = "out of memory" if isinstance(exc, MemoryError) else type(exc).__name__
    return f"{path}: cannot be read ({what}{': ' + text[:200] if text else ''})"


def _read_parts(key: Path, files: list[tuple[Path, FileMap]], root: Path, mapping: IngestMapping,
                report: IngestReport) -> _Parts | None:
    streams: dict[str, Stream] = {}
    images: dict[str, np.ndarray] = {}
    roles: dict[str, str] = {}
    origin: dict[str, str] = {}
    grid = None
    for path, spec in files:
        try:
            read, pictures, notes = read_streams(path, spec, mapping.missing)
        except Exception as exc:  # noqa: BLE001 (any failure of one file, a library's MemoryError too, skips it)
            report.skipped.append(str(exc) if isinstance(exc, IngestError) else failure_line(path, exc))
            report.skipped.append(f"{key.relative_to(root)}: recording skipped, {path.name} is unusable")
            return None
        report.notes.extend(notes)
        streams.update(read)
        images.update(pictures)
        origin.update(dict.fromkeys([*read, *pictures], path.name))
        for channel in spec.channels:
            if channel.role or channel.name in pictures:
                roles[role_key(channel.role, channel.name) if channel.role else "photo"] = channel.name
            elif channel.name in read:  # mapped without a role: a generic channel, never dropped silently
                roles[role_key("signal", channel.name)] = channel.name
                report.notes.append(Note("role", path.name, 1.0, f"{path.name}: channel {channel.name} has no "
                                         f"role: read as the generic role signal ({role_key('signal', channel.name)})"
                                         "; give it role = ... in the mapping to say otherwise"))
        grid = spec.grid or grid
    return _Parts(streams, images, roles, origin, grid)


def _recordings(key: Path, name: str, files: list[tuple[Path, FileMap]], root: Path, mapping: IngestMapping,
                table: Mapping[str, Mapping[str, str]], report: IngestReport) -> list[Recording]:
    """The recording of one key (one per patch when its image is cut into a grid)."""
    groups: dict[str, str] = {}
    if mapping.pattern is not None:
        match = mapping.pattern.search(key.name)
        if match is None:
            report.skipped.extend(f"{path}: name does not match groups.pattern" for path, _ in files)
            return []
        groups = {k: v for k, v in match.groupdict().items() if v is not None}
    try:
        label, levels = _label(key, root, mapping, table, groups)
    except IngestError as exc:
        report.skipped.append(f"{key.relative_to(root)}: recording skipped: {exc}")
        return []
    parts = _read_parts(key, files, root, mapping, report)
    if parts is None:
        return []
    try:
        aligned = align(parts.streams, parts.files, mapping.missing)
        split = split_of(key, root, mapping, groups)
        meta = {**mapping.meta, "label_level": mapping.label_level, "levels": levels,
                "source": [str(path.relative_to(root)) for path, _ in files]}
        if split is not None:
            meta["split"] = split
        if aligned.info:
            meta["time_base"] = aligned.info
        group = {k: v for k, v in groups.items() if k not in ("label", "split")}
        if parts.grid is None:
            recordings = [Recording(name, aligned.traces, parts.roles, label, group, meta, parts.images)]
        else:
            recordings = _patched(name, parts, aligned.traces, label, group, meta)
    except (IngestError, ScanError) as exc:
        report.skipped.append(f"{key.relative_to(root)}: recording skipped: {exc}")
        return []
    except Exception as exc:  # noqa: BLE001 (one recording's failure, whatever it is, spares the others)
        report.skipped.append(f"{key.relative_to(root)}: recording skipped: {failure_line(files[0][0], exc)}")
        return []
    report.notes.extend(aligned.notes)
    return recordings


def _patched(name: str, parts: _Parts, traces: Mapping[str, Trace], label: str, group: Mapping[str, str],
             meta: Mapping[str, Any]) -> list[Recording]:
    """One recording per patch of the grid, sharing the group ``photo`` (and the sampled channels)."""
    assert parts.grid is not None
    (image_name, image), = parts.images.items()  # an image file is one channel
    return [Recording(f"{name}_r{r}c{c}", traces, parts.roles, label,
                      {**group, "photo": name, "row": str(r), "column": str(c)},
                      {**meta, "patch": [r, c], "grid": list(parts.grid)}, {image_name: patch})
            for r, c, patch in patches(image, parts.grid)]


REPEAT_BLOCK = 64
"""Samples per block when recordings are compared for repeated samples (:class:`Repeats`): 0.64 s at 100 Hz,
10 s at 6.5 Hz. Real sensor samples repeat block for block only where a file holds a copy of another's."""
REPEAT_BLOCKS_KEPT = 1024
"""Blocks of a channel compared at most (its first 65,536 samples): the digests kept stay under 100 kB per
channel however long the recording; a longer repeat is reported as at least that long."""


def block_digests(data: np.ndarray, block: int = REPEAT_BLOCK) -> list[bytes]:
    """A digest of each whole block of ``block`` samples (rows) of ``data``, from the first sample; none when
    the first block is constant (a channel at rest, or an unplugged one, starts alike in unrelated recordings)."""
    rows = np.ascontiguousarray(data)
    if len(rows) < block or np.ptp(rows[:block], axis=0).max(initial=0) == 0:
        return []
    whole = min(len(rows) // block, REPEAT_BLOCKS_KEPT)
    return [hashlib.blake2b(rows[i * block:(i + 1) * block].tobytes(), digest_size=16).digest() for i in range(whole)]


def _common_start(a: Sequence[bytes], b: Sequence[bytes]) -> int:
    same = 0
    for x, y in zip(a, b, strict=False):
        if x != y:
            break
        same += 1
    return same


class Repeats:
    """Recordings that begin with another recording's samples: a file that holds a copy of an earlier run
    followed by more (two runs concatenated and saved again, say).

    Windows of both would otherwise fall in training and test as different groups and share samples. A
    recording whose every channel that both have (with at least one whole :data:`REPEAT_BLOCK` of samples
    that is not constant) begins with the same samples as an earlier recording's gets the group ``repeats``
    naming the first recording of the chain (so that the automatic fold grouping keeps them together,
    :func:`features.recordings.fold_group`) and a note saying how many seconds of which channels repeat.
    Only repeats from the first sample are found; memory is a digest per block of each recording.
    """

    def __init__(self) -> None:
        self._starts: dict[tuple[str, bytes], list[str]] = {}
        self._blocks: dict[str, dict[str, tuple[list[bytes], float]]] = {}
        self._root: dict[str, str] = {}

    def place(self, recordings: Sequence[Recording]) -> tuple[list[Recording], Note | None]:
        """``recordings`` (those of one recording key: a photo's patches share their channels) with the group
        ``repeats`` where their channels begin as an earlier recording's, and the note saying so."""
        if not recordings:
            return list(recordings), None
        first = recordings[0]
        blocks = {name: (digests, trace.fs) for name, trace in first.channels.items()
                  if (digests := block_digests(trace.data))}
        candidates = {other for name, (digests, _) in blocks.items()
                      for other in self._starts.get((name, digests[0]), ())
                      if self._repeats(blocks, self._blocks[other])}
        for name, (digests, _) in blocks.items():
            self._starts.setdefault((name, digests[0]), []).append(first.name)
        self._blocks[first.name] = blocks
        if not candidates:
            return list(recordings), None
        earlier = max(sorted(candidates), key=lambda other: self._seconds(blocks, self._blocks[other]))
        root = self._root.setdefault(first.name, self._root.get(earlier, earlier))
        seconds = self._seconds(blocks, self._blocks[earlier])
        shared = ", ".join(sorted(set(blocks) & set(self._blocks[earlier])))
        note = Note("repeats", first.name, seconds,
                    f"recording {first.name}: at least its first {seconds:.1f} s ({shared}) are the samples of "
                    f"recording {earlier}: one cross-validation group with it (group repeats = {root})")
        return [replace(r, group={**r.group, "repeats": root}) for r in recordings], note

    @staticmethod
    def _seconds(blocks: Mapping[str, tuple[list[bytes], float]],
                 other: Mapping[str, tuple[list[bytes], float]]) -> float:
        """How long both begin alike, in whole blocks: the fastest channel tells it best."""
        return max(_common_start(blocks[name][0], other[name][0]) * REPEAT_BLOCK / blocks[name][1]
                   for name in set(blocks) & set(other))

    @staticmethod
    def _repeats(blocks: Mapping[str, tuple[list[bytes], float]],
                 other: Mapping[str, tuple[list[bytes], float]]) -> bool:
        shared = set(blocks) & set(other)
        return bool(shared) and all(blocks[name][0][0] == other[name][0][0] for name in shared)


def lacking_roles(recordings: Sequence[Recording | Made], first: int = 3) -> list[Note]:
    """A note per role that some recordings have and others lack (a file of the recording missing, say):
    how many lack it and the first few; the feature families that need the role are NaN there."""
    notes = []
    roles = dict.fromkeys(role for r in recordings for role in r.roles)
    for role in roles:
        without = [r.name for r in recordings if role not in r.roles]
        if without:
            shown = ", ".join(without[:first]) + (f" and {len(without) - first} more" if len(without) > first else "")
            notes.append(Note("roles", without[0], len(without), f"{len(without)} of {len(recordings)} "
                              f"recording(s) lack the role {role} that the others have: {shown}"))
    return notes


def _label_of(key: Path, root: Path, mapping: IngestMapping, table: Mapping[str, Mapping[str, str]]) -> str | None:
    """The label of a recording key, or None where it has none (reported when the recording is made)."""
    groups = {}
    if mapping.pattern is not None:
        match = mapping.pattern.search(key.name)
        groups = {k: v for k, v in match.groupdict().items() if v is not None} if match else {}
    try:
        return _label(key, root, mapping, table, groups)[0]
    except (IngestError, KeyError):
        return None


def without_excluded(matched: dict[Path, list[tuple[Path, FileMap]]], root: Path, mapping: IngestMapping,
                     table: Mapping[str, Mapping[str, str]],
                     report: IngestReport) -> dict[Path, list[tuple[Path, FileMap]]]:
    """The recording keys whose class the mapping does not leave out (``[labels] exclude``); one note per
    class left out, counting its files, which are not read."""
    if not mapping.exclude:
        return matched
    kept: dict[Path, list[tuple[Path, FileMap]]] = {}
    left: dict[str, list[Path]] = {}
    for key, files in matched.items():
        label = _label_of(key, root, mapping, table)
        if label in mapping.exclude:
            left.setdefault(label, []).extend(path for path, _ in files)
        else:
            kept[key] = files
    for label, paths in left.items():
        report.files += len(paths)  # matched by the mapping, as the files of the recordings made
        shown = ", ".join(str(p.relative_to(root)) for p in paths[:3]) + (" and more" if len(paths) > 3 else "")
        report.notes.append(Note("excluded", label, len(paths), f"class {label}: {len(paths)} file(s) not read "
                                 f"({shown}), as asked"))
    return kept


def unpaired(matched: dict[Path, list[tuple[Path, FileMap]]], root: Path, mapping: IngestMapping,
             report: IngestReport) -> dict[Path, list[tuple[Path, FileMap]]]:
    """The recording keys that have a file of every ``required`` [[files]] entry; the files of the others
    are reported by name in ``report.skipped`` (an IMU file without its wheel file, say) and not read."""
    required = [spec for spec in mapping.files if spec.required]
    kept = {}
    for key, files in matched.items():
        absent = [spec for spec in required if not any(kind is spec for _, kind in files)]
        if not absent:
            kept[key] = files
            continue
        globs = ", ".join(repr(spec.glob) for spec in absent)
        report.skipped.extend(f"{path.relative_to(root)}: unpaired: no file of the required [[files]] {globs} "
                              f"with the stem {key.name!r} in its folder; not read" for path, _ in files)
    return kept


def classes_lacking_roles(made: Sequence[Made]) -> list[Note]:
    """A note per class none of whose recordings has a role that every other class has (a folder holding
    only the wheel files of a set of IMU and wheel recordings, say): its features are NaN there."""
    by_class: dict[str, list[Made]] = {}
    for recording in made:
        by_class.setdefault(recording.label, []).append(recording)
    if len(by_class) < 2:
        return []
    notes = []
    for label, members in by_class.items():
        own = {role for r in members for role in r.roles}
        others = [{role for r in rows for role in r.roles} for name, rows in by_class.items() if name != label]
        common = set.intersection(*others) - own
        if common:
            notes.append(Note("class_roles", label, len(common), f"class {label}: none of its {len(members)} "
                              f"recording(s) has the role(s) {', '.join(sorted(common))} that every other class "
                              f"has; leave it out with [labels] exclude = [{label!r}] or --exclude-label {label}"))
    return notes


def ingest(path: str | os.PathLike[str], mapping: IngestMapping,
           progress: Callable[[Iterable[Any]], Iterable[Any]] = iter, sink: Sink | None = None) -> IngestReport:
    """Recordings from the files under ``path`` as ``mapping`` describes them.

    Files with the same stem in the same folder form one recording; its timestamped streams are put on a
    common time base (:func:`align`). A file that cannot be read as mapped (wrong format, missing column,
    bad token, no rate, ...) is reported in ``skipped`` with its name and reason, and its recording is
    skipped; the import goes on with the others. Names come from the paths (:func:`recording_names`);
    an image file with a ``grid`` gives one recording per patch. ``progress`` wraps the iteration over
    the recordings (e.g. a tqdm bar). With a ``sink`` (a :class:`~scanner.storage.ingest.SetWriter`) each
    recording is handed to it as soon as it is made and not kept (``report.made`` still lists it), so the
    import's memory does not grow with the number of files.

    Raises
    ------
    IngestError
        If ``path`` is not a folder or the label table cannot be read (nothing could be labelled).
    """
    root = Path(path)
    if not root.is_dir():
        raise IngestError(f"{root}: not a folder")
    table = _label_table(root, mapping)
    report = IngestReport()
    matched = unpaired(without_excluded(_matched(root, mapping, report), root, mapping, table, report), root,
                       mapping, report)
    names = recording_names(list(matched), root)
    repeats = Repeats()
    for key, files in progress(list(matched.items())):
        report.files += len(files)
        made, repeated = repeats.place(_recordings(key, names[key], files, root, mapping, table, report))
        if repeated is not None:
            report.notes.append(repeated)
        for recording in made:
            report.made.append(Made.of(recording))
            if sink is None:
                report.recordings.append(recording)
            else:
                sink.add(recording)  # written now: memory does not grow with the number of files
    report.notes.extend(lacking_roles(report.made))
    report.notes.extend(classes_lacking_roles(report.made))
    splits = {made.split for made in report.made}
    if mapping.split_from == "auto" and splits != {"train", "test"} and splits != {None}:
        # Folders named train or test hold only some recordings, or one part: not a split of the set.
        report.made = [replace(made, split=None) for made in report.made]
        if sink is None:
            report.recordings = [_without_split(r) for r in report.recordings]
        else:
            sink.rewrite(_without_split)
    return report


def _without_split(recording: Recording) -> Recording:
    return replace(recording, meta={k: v for k, v in recording.meta.items() if k != "split"})


class Sink(Protocol):
    """Where :func:`ingest` hands each recording as it is made (:class:`~scanner.storage.ingest.SetWriter`)."""

    def add(self, recording: Recording) -> None: ...

    def rewrite(self, change: Callable[[Recording], Recording]) -> None: ...

