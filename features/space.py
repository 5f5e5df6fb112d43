"""The feature space X0 (SPEC section 8): rows = scans, named feature columns, label and group columns.

Files:

- CSV: header ``scan_id,sample_id,label,C,S,M,P,X,<feature columns...>``; one row per scan; ``NaN`` for
  undefined values; floats written with full precision (``repr``), so a round trip is exact.
- ``.mat``: ``X`` (n x f double), ``columns`` (1 x f cell of names), ``labels`` (n x 5 double: C, S, M, P, X),
  ``label`` (n x 1 cell of label text), ``scan_id`` and ``sample_id`` (n x 1 cells).
"""

from __future__ import annotations

import csv
import io
import math
import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import scipy.io

from taxonomy.labels import Label, check_level

MODALITIES = ("tactum", "image", "audio", "other")
"""Column groups by the first part of the feature name."""

_ID_COLUMNS = ("scan_id", "sample_id", "label")
_LABEL_PARTS = ("C", "S", "M", "P", "X")


class FeatureSpaceError(ValueError):
    """A feature space or feature file is inconsistent; the message names what is wrong."""


@dataclass(frozen=True)
class FeatureSpace:
    """Feature matrix ``X`` (n scans x f features) with its column names, scan ids, labels and groups.

    ``groups`` are the sample ids: scans of one sample must stay in one cross-validation fold.
    ``failed`` lists ``(scan_id, reason)`` for scans that could not be extracted (they have no row).
    """

    X: np.ndarray
    columns: tuple[str, ...]
    scan_ids: tuple[str, ...]
    label_text: tuple[str, ...]
    groups: tuple[str, ...]
    failed: tuple[tuple[str, str], ...] = field(default=())

    def __post_init__(self) -> None:
        X = np.array(self.X, dtype=np.float64)
        if X.ndim != 2:
            raise FeatureSpaceError(f"X must be 2-D (scans x features), got shape {X.shape}")
        n, f = X.shape
        if len(self.columns) != f:
            raise FeatureSpaceError(f"{len(self.columns)} column names for {f} feature columns")
        if len(set(self.columns)) != f:
            raise FeatureSpaceError("column names are not unique")
        for name, values in (("scan_ids", self.scan_ids), ("label_text", self.label_text), ("groups", self.groups)):
            if len(values) != n:
                raise FeatureSpaceError(f"{len(values)} {name} for {n} rows")
        if np.isinf(X).any():
            raise FeatureSpaceError("X contains inf; undefined features must be NaN")
        X.flags.writeable = False
        object.__setattr__(self, "X", X)
        for name in ("columns", "scan_ids", "label_text", "groups"):
            object.__setattr__(self, name, tuple(str(v) for v in getattr(self, name)))
        object.__setattr__(self, "failed", tuple((str(a), str(b)) for a, b in self.failed))

    def __len__(self) -> int:
        return self.X.shape[0]

    @property
    def labels(self) -> np.ndarray:
        """(n, 5) integer array of the label parts C, S, M, P, X."""
        return np.array([Label.parse(text).numbers() for text in self.label_text], dtype=np.int64).reshape(-1, 5)

    def y(self, level: str = "fine") -> np.ndarray:
        """Class of every row at ``level`` ("coarse" = C, "medium" = C+S, "fine" = full label)."""
        level = check_level(level)
        return np.array([Label.parse(text).at(level) for text in self.label_text])

    def modality(self, name: str) -> FeatureSpace:
        """The columns of one modality: ``tactum``, ``image``, ``audio`` or ``other``."""
        if name not in MODALITIES:
            raise FeatureSpaceError(f"unknown modality {name!r} (known: {', '.join(MODALITIES)})")
        return self.subset([c for c in self.columns if c.split(".", 1)[0] == name])

    def subset(self, columns: Sequence[str]) -> FeatureSpace:
        """A feature space with only ``columns`` (in that order)."""
        index = {name: i for i, name in enumerate(self.columns)}
        missing = [c for c in columns if c not in index]
        if missing:
            raise FeatureSpaceError(f"no such feature column(s): {', '.join(missing[:5])}")
        picked = [index[c] for c in columns]
        return FeatureSpace(self.X[:, picked], tuple(columns), self.scan_ids, self.label_text, self.groups,
                            self.failed)

    # -- files -------------------------------------------------------------------------------------

    def to_csv(self, path: str | os.PathLike[str]) -> Path:
        """Write the CSV described in the module docstring, atomically."""
        from scanner.files import atomic_write_bytes

        buffer = io.StringIO()
        writer = csv.writer(buffer, lineterminator="\n")
        writer.writerow([*_ID_COLUMNS, *_LABEL_PARTS, *self.columns])
        parts = _label_parts(self.label_text)
        for i in range(len(self)):
            writer.writerow([self.scan_ids[i], self.groups[i], self.label_text[i], *parts[i],
                             *(_format_float(v) for v in self.X[i])])
        atomic_write_bytes(path, buffer.getvalue().encode("utf-8"))
        return Path(path)

    @classmethod
    def from_csv(cls, path: str | os.PathLike[str]) -> FeatureSpace:
        """Read a CSV written by :meth:`to_csv`; errors name the file, line and column."""
        path = Path(path)
        try:
            text = path.read_text(encoding="utf-8")
        except (OSError, UnicodeDecodeError) as exc:
            raise FeatureSpaceError(f"{path}: cannot read ({exc})") from None
        rows = list(csv.reader(io.StringIO(text)))
        if not rows:
            raise FeatureSpaceError(f"{path}: empty file")
        header = rows[0]
        first = len(_ID_COLUMNS) + len(_LABEL_PARTS)
        if tuple(header[:first]) != (*_ID_COLUMNS, *_LABEL_PARTS):
            raise FeatureSpaceError(f"{path}: line 1: header must start with {','.join((*_ID_COLUMNS, *_LABEL_PARTS))}")
        columns = header[first:]
        ids, groups, labels, values = [], [], [], []
        for line, row in enumerate(rows[1:], start=2):
            if not row:
                continue
            if len(row) != len(header):
                raise FeatureSpaceError(f"{path}: line {line}: {len(row)} fields, header has {len(header)}")
            ids.append(row[0])
            groups.append(row[1])
            labels.append(row[2])
            try:
                values.append([float(v) for v in row[first:]])
            except ValueError as exc:
                raise FeatureSpaceError(f"{path}: line {line}: {exc}") from None
        X = np.array(values, dtype=np.float64).reshape(len(values), len(columns))
        return cls(X, tuple(columns), tuple(ids), tuple(labels), tuple(groups))

    def to_mat(self, path: str | os.PathLike[str]) -> Path:
        """Write ``X``, ``columns``, ``labels``, ``label``, ``scan_id``, ``sample_id`` as MATLAB v5, atomically."""
        from scanner.files import atomic_write_bytes

        buffer = io.BytesIO()
        scipy.io.savemat(buffer, {
            "X": self.X,
            "columns": _cell(self.columns).reshape(1, -1),
            "labels": _label_parts(self.label_text).astype(np.float64),
            "label": _cell(self.label_text).reshape(-1, 1),
            "scan_id": _cell(self.scan_ids).reshape(-1, 1),
            "sample_id": _cell(self.groups).reshape(-1, 1),
        }, long_field_names=True, do_compression=True)
        atomic_write_bytes(path, buffer.getvalue())
        return Path(path)

    @classmethod
    def from_mat(cls, path: str | os.PathLike[str]) -> FeatureSpace:
        path = Path(path)
        try:
            data = scipy.io.loadmat(path, simplify_cells=True)
        except Exception as exc:  # scipy raises many types for foreign files
            raise FeatureSpaceError(f"{path}: not a readable .mat feature file ({exc})") from None
        missing = [k for k in ("X", "columns", "label", "scan_id", "sample_id") if k not in data]
        if missing:
            raise FeatureSpaceError(f"{path}: missing variable(s) {', '.join(missing)}")
        columns = _as_strings(data["columns"])
        X = np.asarray(data["X"], dtype=np.float64).reshape(-1, len(columns))
        return cls(X, columns, _as_strings(data["scan_id"]), _as_strings(data["label"]),
                   _as_strings(data["sample_id"]))


def _label_parts(label_text: Sequence[str]) -> np.ndarray:
    """C, S, M, P, X of each label; -1 for labels outside the taxonomy format (generic recordings)."""
    parts = []
    for text in label_text:
        try:
            parts.append(Label.parse(text).numbers())
        except ValueError:
            parts.append((-1,) * 5)
    return np.array(parts, dtype=np.int64).reshape(-1, 5)


def _format_float(value: float) -> str:
    return "NaN" if math.isnan(value) else repr(float(value))


def _cell(values: Sequence[str]) -> np.ndarray:
    cell = np.empty(len(values), dtype=object)
    cell[:] = list(values)
    return cell


def _as_strings(value: object) -> tuple[str, ...]:
    if isinstance(value, str):
        return (value,)
    return tuple(str(v) for v in np.asarray(value, dtype=object).ravel())
